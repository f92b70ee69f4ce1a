"""Modules loaded on first use, so that a command which never decodes (`slrig --help`, `slrig
devices`) does not pay for machinery it does not run: the numba kernels import numba, which takes
most of a second."""

from __future__ import annotations

import importlib
import sys
import threading
from collections.abc import Callable, Mapping
from types import ModuleType
from typing import Any


class LazyModule:
    """Stands for the module `name` and imports it when one of its attributes is first read. Safe
    from several threads at once (the kernels' first calls come from the worker pool), unlike the
    standard library's LazyLoader before Python 3.13, whose half-loaded module another thread can see."""

    def __init__(self, name: str) -> None:
        self._name = name
        self._lock = threading.Lock()
        self._module: ModuleType | None = None

    def __getattr__(self, attribute: str) -> Any:
        module = self._module
        if module is None:
            with self._lock:
                if self._module is None:
                    self._module = importlib.import_module(self._name)
                module = self._module
        return getattr(module, attribute)


def lazy_module(name: str) -> Any:
    """The module `name`, imported when first used."""
    return LazyModule(name)


def face(package: str, names: Mapping[str, str]) -> tuple[Callable[[str], Any], Callable[[], list[str]]]:
    """A package's face (PEP 562 `__getattr__` and `__dir__`): each public name, `names` mapping it
    to the submodule that defines it, imported from there when first read and kept. Importing the
    package loads none of its submodules: `from rig.pipeline import run_scan` costs what
    `from rig.pipeline.scan import run_scan` did."""

    def attribute(name: str) -> Any:
        if name not in names:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        value = getattr(importlib.import_module(f"{package}.{names[name]}"), name)
        setattr(sys.modules[package], name, value)
        return value

    def listing() -> list[str]:
        return sorted(set(names) | set(vars(sys.modules[package])))

    return attribute, listing
