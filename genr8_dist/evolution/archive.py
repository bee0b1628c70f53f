"""The MAP-Elites archive (Mouret and Clune 2015): a grid over behaviour descriptors, one elite per cell.

A *descriptor* is a stored value of an individual: a criterion's raw value, or one of its phenotype's
sizes (``size_<name>``: a surface's ``size_vertices``, ``size_edges``, ``size_regions``); the designer
gives each a range and a number of bins, and an individual falls in the cell of its binned descriptors
(values outside a range go to its edge bins). A cell keeps the lowest-fitness valid individual that fell
in it, ties to the earlier one.

The archive of an island is carried in its population: each generation starts with the previous
generation's whole archive (every held cell's elite, origin ``elite``; its capacity is the grid, not
the population, so a generation grows beyond ``ea.population`` when more cells are held), then its
offspring, so the archive after generation g is a pure function of generation g's stored rows
(``Grid.archive``) and no cell once found is lost. It is committed with every epoch as
rows, resumes with them and is equal after a kill and a resume, with no state outside the run store.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Protocol, TypeVar

from genr8_dist.evolution.individual import SCHEMA_2_NAMES

if TYPE_CHECKING:
    from genr8_dist.config import SearchSettings

__all__ = ["Grid", "descriptor_value"]

_SIZE = "size_"


class Described(Protocol):
    """What a cell is found from (an ``Individual``, or a stored row read as one)."""

    @property
    def valid(self) -> bool: ...
    @property
    def sizes(self) -> Mapping[str, int]: ...
    @property
    def criteria(self) -> Mapping[str, float]: ...


class Ranked(Described, Protocol):
    """What an archive's elites are chosen by, besides their cells."""

    @property
    def fitness(self) -> float: ...
    @property
    def index(self) -> int: ...


D = TypeVar("D", bound=Ranked)


def descriptor_value(individual: Described, name: str) -> float:
    """The value of descriptor ``name`` of an individual (one of its sizes, or a criterion's raw value)."""
    name = SCHEMA_2_NAMES.get(name, name)
    if name.startswith(_SIZE) and name[len(_SIZE):] in individual.sizes:
        return float(individual.sizes[name[len(_SIZE):]])
    return float(individual.criteria.get(name, math.nan))


@dataclass(frozen=True, slots=True)
class Grid:
    """The cells of the archive: per descriptor its name, its range ``[lo, hi]`` and its bins."""

    descriptors: tuple[str, ...]
    ranges: tuple[tuple[float, float], ...]
    bins: tuple[int, ...]

    @classmethod
    def from_settings(cls, search: SearchSettings) -> Grid:
        """The grid of a ``[search]`` section (``SearchSettings``)."""
        return cls(tuple(search.descriptors), tuple((lo, hi) for lo, hi in search.ranges), tuple(search.bins))

    @property
    def size(self) -> int:
        """How many cells the grid has."""
        return math.prod(self.bins)

    def cell(self, individual: Described) -> int | None:
        """The cell index of a valid individual (row-major over the descriptors), ``None`` for an
        invalid one or one whose descriptor is not finite."""
        if not individual.valid:
            return None
        index = 0
        for name, (lo, hi), n in zip(self.descriptors, self.ranges, self.bins, strict=True):
            value = descriptor_value(individual, name)
            if not math.isfinite(value):
                return None
            k = int((value - lo) / (hi - lo) * n) if hi > lo else 0
            index = index * n + min(n - 1, max(0, k))
        return index

    def archive(self, individuals: Iterable[D]) -> dict[int, D]:
        """Cell -> its elite among ``individuals`` (lowest fitness, ties to the earlier one)."""
        cells: dict[int, D] = {}
        for ind in individuals:
            c = self.cell(ind)
            if c is None or not math.isfinite(ind.fitness):
                continue
            held = cells.get(c)
            if held is None or ind.fitness < held.fitness:
                cells[c] = ind
        return cells

    def coordinates(self, cell: int) -> tuple[int, ...]:
        """The bin of each descriptor of ``cell``."""
        out = []
        for n in reversed(self.bins):
            out.append(cell % n)
            cell //= n
        return tuple(reversed(out))

    def elites(self, individuals: Sequence[D], room: int) -> list[D]:
        """The archive's elites, best first, at most ``room`` of them (the best cells kept)."""
        held = sorted(self.archive(individuals).values(), key=lambda ind: (ind.fitness, ind.index))
        return held[:room]
