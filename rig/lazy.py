"""Modules loaded on first use, so that a command which never decodes (`slrig --help`, `slrig
devices`) does not pay for machinery it does not run: the numba kernels import numba, which takes
most of a second."""

from __future__ import annotations

import importlib
import threading
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
