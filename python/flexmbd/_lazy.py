"""Lazy attributes of a package (PEP 562): its public names are imported from their submodules
on first access, so that importing the package loads none of them (nor numpy, scipy, h5py)."""

from __future__ import annotations

import importlib
import importlib.util
from collections.abc import Callable
from typing import Any


def lazy_attributes(
    package: str, origin: dict[str, str], namespace: dict[str, Any]
) -> tuple[Callable[[str], Any], Callable[[], list[str]]]:
    """(``__getattr__``, ``__dir__``) of `package`: a name in `origin` (name -> the submodule
    that defines it, "" for a submodule itself) is imported on first access and kept in
    `namespace` (the package's globals); any other submodule is imported on first access."""

    def getattr_(name: str) -> Any:
        where = origin.get(name)
        if where is None:
            if name.startswith("__") or importlib.util.find_spec(f"{package}.{name}") is None:
                raise AttributeError(f"module {package!r} has no attribute {name!r}")
            return importlib.import_module(f".{name}", package)
        module = importlib.import_module(f".{where or name}", package)
        value = module if where == "" else getattr(module, name)
        namespace[name] = value
        return value

    def dir_() -> list[str]:
        return sorted(set(namespace) | set(origin))

    return getattr_, dir_
