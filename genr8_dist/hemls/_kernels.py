"""When a process runs the compiled kernels (numba, the ``fast`` extra) instead of the numpy reference.

Growth (``_growth_compiled``) and the triangulation (``_compiled``) each have kernels that repeat
their reference code operation for operation, so switching changes no result. Loading numba costs
about 0.4 s of CPU, so a process switches only once its reference code has done about that much work:
``GENR8_COMPILED=1`` switches at once, ``GENR8_COMPILED=0`` (or no numba) never.
"""

from __future__ import annotations

import functools
import importlib
import os
from collections.abc import Callable
from types import ModuleType

__all__ = ["KernelSwitch"]


class KernelSwitch:
    """The switch of one stage: ``kernels()`` is the compiled module, or None for the reference code.

    ``count(work)`` adds the reference code's work (in the stage's own unit); once it reaches
    ``load_after`` the kernels are loaded. ``check`` asserts that the kernel module's constants are
    the reference's."""

    def __init__(self, module: str, load_after: int,
                 check: Callable[[ModuleType], None] | None = None) -> None:
        self.module = module
        self.load_after = load_after
        self.reference_work = 0
        self._check = check
        self.load = functools.cache(self._load)

    def _load(self) -> ModuleType | None:
        """The compiled module, imported on first use; None when numba is missing or
        ``GENR8_COMPILED=0``."""
        if os.environ.get("GENR8_COMPILED") == "0":
            return None
        try:
            module = importlib.import_module(self.module)
        except ImportError:
            return None
        if self._check is not None:
            self._check(module)
        return module

    def kernels(self) -> ModuleType | None:
        """The kernels if this process has switched to them, else None."""
        if self.reference_work < self.load_after and os.environ.get("GENR8_COMPILED") != "1":
            return None
        return self.load()

    def count(self, work: int) -> None:
        """Record ``work`` done by the reference code."""
        self.reference_work += work
