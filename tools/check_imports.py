"""Fails when the modules of the Rust core import each other in a circle.

Reads every `crate::...` and `super::...` path in the code of crates/flexmbd-core/src (use
lines and paths in code alike; comments, where documentation links live, are left out), maps
each to the module (file) it names, and looks for cycles in the graph of
module dependencies: file-level (one file needs another that needs the first, directly or
through others) and folder-level (the stages of a step: a lower folder never needs a higher
one). Test modules (`#[cfg(test)]` blocks at the end of a file, and files declared as
`#[cfg(test)] mod name;`) are left out: tests may use anything.

    python tools/check_imports.py            # prints the cycles, exit status 1 if any
    python tools/check_imports.py --graph    # also prints the folder-level graph
"""

from __future__ import annotations

import argparse
import re
import sys
from pathlib import Path

SOURCE = Path(__file__).resolve().parents[1] / "crates" / "flexmbd-core" / "src"
PATH = re.compile(r"\b(crate|super)((?:::\w+)+)")


def module_of(path: Path, source: Path) -> tuple[str, ...]:
    parts = list(path.relative_to(source).with_suffix("").parts)
    if parts[-1] in ("mod", "lib"):
        parts.pop()
    return tuple(parts)


TEST_MODULE = r"^#\[cfg\(test\)\]\s*\n\s*(?:pub(?:\(crate\))?\s+)?mod\s+(\w+)\s*"


def strip_tests(text: str) -> str:
    """The file without its inline `#[cfg(test)] mod name { ... }` (the tests at its end)."""
    match = re.search(TEST_MODULE + r"\{", text, re.M)
    return text if match is None else text[: match.start()]


def test_files(source: Path) -> set[tuple[str, ...]]:
    """Modules declared as `#[cfg(test)] mod name;`: files that hold only tests."""
    found = set()
    for path in source.rglob("*.rs"):
        here = module_of(path, source)
        # `mod name;` in a/b.rs or a/b/mod.rs names the file a/b/name.rs: module a::b::name.
        for name in re.findall(TEST_MODULE + ";", path.read_text(), re.M):
            found.add(here + (name,))
    return found


def dependencies(source: Path) -> dict[tuple[str, ...], set[tuple[str, ...]]]:
    """Module -> the modules its code (tests left out) names, for every file under `source`."""
    tests = test_files(source)
    modules = {module_of(p, source) for p in source.rglob("*.rs")}
    graph: dict[tuple[str, ...], set[tuple[str, ...]]] = {m: set() for m in modules - tests}
    for path in source.rglob("*.rs"):
        here = module_of(path, source)
        if here in tests:
            continue
        is_mod_file = path.stem in ("mod", "lib")
        # Code only: paths in comments (documentation links) are no dependencies.
        text = re.sub(r"//[^\n]*", "", strip_tests(path.read_text()))
        for root, rest in PATH.findall(text):
            names = tuple(rest.split("::")[1:])
            if root == "crate":
                target = names
            else:
                # `super` of a file module is its folder; of a mod.rs, the folder's parent.
                base = here[:-1] if not is_mod_file else here[:-1]
                target = base + names
            # The longest prefix that is a module (the rest are items in it).
            while target and target not in modules:
                target = target[:-1]
            if target and target != here and not here[: len(target)] == target:
                graph[here].add(target)
    return graph


def cycles(graph: dict[tuple[str, ...], set[tuple[str, ...]]]) -> list[list[tuple[str, ...]]]:
    """Strongly connected components of more than one node (Tarjan)."""
    index: dict = {}
    low: dict = {}
    stack: list = []
    on_stack: set = set()
    found: list = []
    counter = [0]

    def visit(node):
        index[node] = low[node] = counter[0]
        counter[0] += 1
        stack.append(node)
        on_stack.add(node)
        for other in sorted(graph.get(node, ())):
            if other not in index:
                visit(other)
                low[node] = min(low[node], low[other])
            elif other in on_stack:
                low[node] = min(low[node], index[other])
        if low[node] == index[node]:
            component = []
            while True:
                top = stack.pop()
                on_stack.discard(top)
                component.append(top)
                if top == node:
                    break
            if len(component) > 1:
                found.append(sorted(component))

    sys.setrecursionlimit(10000)
    for node in sorted(graph):
        if node not in index:
            visit(node)
    return found


def folder_graph(files: dict[tuple[str, ...], set[tuple[str, ...]]]) -> dict:
    """The top-level folders' graph: folder -> the other folders its files use."""
    folders: dict[tuple[str, ...], set[tuple[str, ...]]] = {}
    for node, targets in files.items():
        top = node[:1]
        folders.setdefault(top, set())
        for target in targets:
            if target[:1] != top:
                folders[top].add(target[:1])
    return folders


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--graph", action="store_true", help="print the folder-level graph")
    parser.add_argument("--source", type=Path, default=SOURCE, help="the crate's src folder")
    args = parser.parse_args()
    files = dependencies(args.source)
    folders = folder_graph(files)
    if args.graph:
        for node in sorted(folders):
            names = ", ".join("::".join(t) for t in sorted(folders[node])) or "-"
            print(f"{'::'.join(node) or 'lib'} -> {names}")
    failed = False
    for level, graph in (("file", files), ("folder", folders)):
        for component in cycles(graph):
            failed = True
            names = " <-> ".join("::".join(m) or "lib" for m in component)
            print(f"import cycle between {level}s: {names}")
            for node in component:
                for target in sorted(graph[node]):
                    if target in component:
                        print(f"    {'::'.join(node)} uses {'::'.join(target)}")
    if not failed:
        print(f"no import cycles among {len(files)} modules")
    return 1 if failed else 0


if __name__ == "__main__":
    raise SystemExit(main())
