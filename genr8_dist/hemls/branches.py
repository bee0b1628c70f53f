"""The branches a derivation step has drawn and not yet joined (journal 4.3: branch joining)."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

__all__ = ["Pending", "PendingBranches"]


class Pending(NamedTuple):
    """The pending branches as one value, a row each: the vertex a branch starts at; its corner, the
    half-edge leaving the vertex into the region the branch points into (-1 when it points nowhere);
    its label and age; its heading; whether it is reversed (``~``); the surface normal it was drawn
    with. ``corner`` is updated in place as joins split corners."""

    vertex: np.ndarray
    corner: np.ndarray
    label: np.ndarray
    age: np.ndarray
    heading: np.ndarray
    reversed: np.ndarray
    normal: np.ndarray


_NONE = Pending(np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0, np.int64),
                np.zeros((0, 3)), np.zeros(0, bool), np.zeros((0, 3)))


class PendingBranches:
    """Pending branches of the current step, gathered batch by batch and read as one ``Pending``."""

    def __init__(self) -> None:
        self.parts: list[Pending] = []
        self._cat: Pending | None = None
        # branches [0, checked) have met each other in a join already: positions and headings do
        # not change within a step and faces only split, so such pairs never need testing again
        self.checked = 0
        self.size = 0

    def add(self, batch: Pending) -> None:
        """Add the branches of one batch of rewritten edges."""
        if len(batch.vertex):
            self._flush_cat()
            self.parts.append(batch)
            self.size += len(batch.vertex)

    def _flush_cat(self) -> None:
        if self._cat is not None:
            self.parts = [self._cat]
            self._cat = None

    def arrays(self) -> Pending:
        """Every pending branch, in the order they were drawn."""
        if self._cat is None:
            if not self.parts:
                self._cat = _NONE
            else:
                self._cat = Pending(*(np.concatenate(column) for column in zip(*self.parts, strict=True)))
            self.parts = []
        return self._cat

    def keep(self, mask: np.ndarray) -> None:
        """Keep the branches where ``mask`` holds; all of them count as checked from now on."""
        self._cat = Pending(*(a[mask] for a in self.arrays()))
        self.checked = self.size = len(self._cat.vertex)

    def remap_corners(self, repl: np.ndarray) -> None:
        """Corners through half-edges a rewrite replaced now name their replacements (``repl``)."""
        if not self.size:
            return
        pending = self.arrays()
        c = pending.corner
        ok = c >= 0
        c = c.copy()
        c[ok] = repl[c[ok]]
        self._cat = pending._replace(corner=c)

    def __len__(self) -> int:
        return self.size
