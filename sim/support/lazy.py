"""A package's public face whose names load on first use (PEP 562): ``import pkg`` stays cheap, and
``pkg.Name`` imports the module that defines it the first time it is asked for.

    _LAZY = {"Simulator": "sim.step", ...}            # public name -> the module that defines it
    __getattr__, __dir__ = lazy_face(__name__, _LAZY)

The table is named ``_LAZY`` in every package: tests/test_import_graph.py reads its values as imports.
"""
from __future__ import annotations

import importlib
import sys
from collections.abc import Callable, Mapping
from typing import Any

__all__ = ["lazy_face"]


def lazy_face(package: str, names: Mapping[str, str]) -> tuple[Callable[[str], Any], Callable[[], list[str]]]:
    """``(__getattr__, __dir__)`` for ``package`` whose public ``names`` come from the modules they map to. A name
    once loaded is kept in the package's namespace (later lookups do not come here)."""

    def __getattr__(name: str) -> Any:
        module = names.get(name)
        if module is None:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        value = getattr(importlib.import_module(module), name)
        setattr(sys.modules[package], name, value)
        return value

    def __dir__() -> list[str]:
        return sorted(set(vars(sys.modules[package])) | set(names))

    return __getattr__, __dir__
