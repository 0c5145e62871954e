"""The house checks of tools/: the import-cycle check of the Rust core finds what it must."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest

TOOL = Path(__file__).resolve().parents[1] / "tools" / "check_imports.py"


@pytest.fixture(scope="module")
def check_imports():
    spec = importlib.util.spec_from_file_location("check_imports", TOOL)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def write_tree(root: Path, files: dict[str, str]) -> Path:
    for name, text in files.items():
        path = root / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text)
    return root


def test_the_core_has_no_import_cycles(check_imports):
    files = check_imports.dependencies(check_imports.SOURCE)
    assert check_imports.cycles(files) == []
    assert check_imports.cycles(check_imports.folder_graph(files)) == []


def test_a_folder_cycle_through_a_split_file_is_found(tmp_path, check_imports):
    source = write_tree(
        tmp_path,
        {
            "lib.rs": "pub mod low;\npub mod high;\n",
            "low/mod.rs": "mod part;\n",
            "low/part.rs": "use crate::high::run;\n",
            "high/mod.rs": "use crate::low::part;\npub fn run() {}\n",
        },
    )
    folders = check_imports.folder_graph(check_imports.dependencies(source))
    assert check_imports.cycles(folders) == [[("high",), ("low",)]]


def test_test_files_and_inline_test_modules_are_left_out(tmp_path, check_imports):
    source = write_tree(
        tmp_path,
        {
            "lib.rs": "pub mod low;\npub mod high;\n",
            # A test-only file declared by `#[cfg(test)] mod tests;`; code after it still counts.
            "low/mod.rs": "#[cfg(test)]\nmod tests;\npub fn f() { crate::low::g(); }\n",
            "low/tests.rs": "use crate::high::run;\n",
            "low/other.rs": "pub fn g() {}\n#[cfg(test)]\nmod tests {\n use crate::high::run;\n}\n",
            "high/mod.rs": "use crate::low::f;\npub fn run() {}\n",
        },
    )
    files = check_imports.dependencies(source)
    assert ("low", "tests") not in files
    assert check_imports.cycles(check_imports.folder_graph(files)) == []
    # The same use outside a test module is a cycle.
    (source / "low" / "tests.rs").unlink()
    (source / "low" / "mod.rs").write_text("use crate::high::run;\n")
    folders = check_imports.folder_graph(check_imports.dependencies(source))
    assert check_imports.cycles(folders) == [[("high",), ("low",)]]


def test_the_compiled_model_carries_its_deformable_bodies_as_a_declared_field():
    # Issue 29: no attributes attached to Rust objects from Python (System.compile used to
    # set model._flexible, read back with getattr).
    import flexmbd as fm

    example = fm.examples.EXAMPLES["spin-up"]()
    model = example.system.compile()
    bodies = model.flexible_bodies
    assert list(bodies) == [1] and isinstance(bodies[1], fm.fe.FlexibleBodyData)
    bodies.clear()  # a copy: the model's own stays whole
    assert list(model.flexible_bodies) == [1]
    with pytest.raises(AttributeError):
        model._flexible = {}
    rigid = fm.System()
    rigid.add_point_mass(1.0)
    assert rigid.compile().flexible_bodies == {}


def test_the_tolerance_helper_passes_close_values_and_names_the_worst_entry(assert_close):
    assert_close(1.0 + 1e-10, 1.0, rel=1e-9)
    assert_close([1e-13, 2.0], [0.0, 2.0], abs=1e-12, rel=1e-12)
    with pytest.raises(pytest.fail.Exception, match=r"tip\[1\]: 2.5 against 2: "):
        assert_close([1.0, 2.5, 3.1], [1.0, 2.0, 3.0], rel=0.05, what="tip")
    with pytest.raises(pytest.fail.Exception, match="nan against 1"):
        assert_close(float("nan"), 1.0, rel=1.0, abs=1.0)
