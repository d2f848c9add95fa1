"""Package facades that import on first use: ``from softflow.control import Controller`` works,
while ``import softflow.report`` stays light (no torch) because nothing is loaded until asked."""

from __future__ import annotations

import importlib


def facade(package: str, exports: dict[str, list[str]], submodules: list[str]):
    """``__getattr__`` and ``__dir__`` for ``package``: each name of ``exports`` ({module: names})
    comes from ``package.module``; each of ``submodules`` is a module of the package."""
    where = {name: module for module, names in exports.items() for name in names}

    def __getattr__(name: str):
        if name in where:
            return getattr(importlib.import_module(f"{package}.{where[name]}"), name)
        if name in submodules:
            return importlib.import_module(f"{package}.{name}")
        raise AttributeError(f"module {package!r} has no attribute {name!r}")

    def __dir__():
        return sorted([*where, *submodules])

    return __getattr__, __dir__, sorted([*where, *submodules])
