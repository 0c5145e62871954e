"""The type stubs of flexmbd._core describe what the extension exports, method by method."""

import ast
import inspect
from pathlib import Path

import flexmbd
from flexmbd import _core

STUB = Path(flexmbd.__file__).with_name("_core.pyi")


def stub_classes():
    tree = ast.parse(STUB.read_text())
    classes = {}
    functions = set()
    for node in tree.body:
        if isinstance(node, ast.ClassDef):
            members = set()
            for item in node.body:
                if isinstance(item, ast.FunctionDef):
                    members.add(item.name)
                elif isinstance(item, ast.AnnAssign) and isinstance(item.target, ast.Name):
                    members.add(item.target.id)
            classes[node.name] = members
        elif isinstance(node, ast.FunctionDef):
            functions.add(node.name)
    return classes, functions


def test_every_public_name_of_the_extension_is_in_the_stub():
    classes, functions = stub_classes()
    exported = {n for n in dir(_core) if not n.startswith("_")}
    stubbed = set(classes) | functions
    assert exported == stubbed


def test_every_public_member_is_in_the_stub_and_exists():
    classes, _ = stub_classes()
    for name, members in classes.items():
        cls = getattr(_core, name)
        public = {m for m in vars(cls) if not m.startswith("_")}
        assert public <= members, f"{name}: missing in the stub: {public - members}"
        private = {m for m in members if m.startswith("_") and not m.startswith("__")}
        for m in private:
            assert hasattr(cls, m), f"{name}.{m} is in the stub but not in the extension"
        stubbed = members - private - {"__init__", "__call__", "__int__"}
        assert stubbed <= public | {"derivatives"}, name


def test_public_classes_have_docstrings():
    for name in dir(_core):
        obj = getattr(_core, name)
        if inspect.isclass(obj) or callable(obj):
            if not name.startswith("_"):
                assert obj.__doc__, name
