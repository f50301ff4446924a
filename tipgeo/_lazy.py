"""Names of a package that load on first access (PEP 562): the one helper
behind the ``__getattr__`` and ``__dir__`` of :mod:`tipgeo` and
:mod:`tipgeo.inspect`. No units."""

from __future__ import annotations

import importlib
from collections.abc import Callable, Mapping
from typing import Any

__all__ = ["lazy_attributes"]


def lazy_attributes(package: str, namespace: dict[str, Any], names: Mapping[str, str],
                    modules: tuple[str, ...] = ()
                    ) -> tuple[Callable[[str], Any], Callable[[], list[str]]]:
    """``(__getattr__, __dir__)`` for the package ``package`` whose globals
    are ``namespace``: each of its submodules ``modules`` and each name of
    ``names`` (name → the submodule that defines it) imported on first
    access and kept in ``namespace`` (no second lookup)."""

    def getattr_(name: str) -> Any:
        if name in modules:
            value = importlib.import_module(f".{name}", package)
        elif name in names:
            value = getattr(importlib.import_module(f".{names[name]}", package), name)
        else:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        namespace[name] = value
        return value

    def dir_() -> list[str]:
        return sorted(set(namespace) | set(modules) | set(names))

    return getattr_, dir_
