"""A package face that loads its modules on first use of one of their names (PEP 562): the commands
read settings from light modules (no torch) through the same face as the heavy ones."""
from __future__ import annotations

import importlib
from typing import Any, Callable

__all__ = ["lazy_face"]


def lazy_face(package: str, home: dict[str, tuple[str, ...]], space: dict[str, Any]
              ) -> tuple[list[str], Callable[[str], Any], Callable[[], list[str]]]:
    """(``__all__``, ``__getattr__``, ``__dir__``) of ``package`` whose names live in the modules ``home``
    gives ({module: names}); ``space`` is the package's globals (a loaded name is kept there)."""
    module_of = {name: module for module, names in home.items() for name in names}
    names = [name for names in home.values() for name in names]

    def getattr_(name: str) -> Any:
        if name not in module_of:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        value = getattr(importlib.import_module(f"{package}.{module_of[name]}"), name)
        space[name] = value
        return value

    return names, getattr_, lambda: sorted(set(space) | set(names))
