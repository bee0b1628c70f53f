"""The progress display: one line per generation completed by every island.

Lines are plain text (no cursor movement), so they read the same in a terminal, in ``ray job logs``
and in a CI log::

    gen   12/50  best 0.4123  median 1.2030  | i0 0.412/1.203  i1 0.519/1.410 | 38.2 ind/s  1m05s left

``best`` and ``median`` are over all islands; each ``iN`` shows that island's best/median fitness.
Invalid individuals (fitness ``inf``) count as worst.
"""

from __future__ import annotations

import math
import statistics
import sys
import time
from collections.abc import Mapping, Sequence
from typing import Any, TextIO

__all__ = ["ProgressDisplay", "format_duration", "format_fitness"]


def format_duration(seconds: float) -> str:
    """``3h02m``, ``1m05s`` or ``12s``."""
    if not math.isfinite(seconds) or seconds < 0:
        return "?"
    s = round(seconds)
    if s >= 3600:
        return f"{s // 3600}h{(s % 3600) // 60:02d}m"
    if s >= 60:
        return f"{s // 60}m{s % 60:02d}s"
    return f"{s}s"


def format_fitness(value: float) -> str:
    """A fitness value in 4 significant digits; ``inf`` for invalid."""
    if math.isnan(value):
        return "nan"
    if math.isinf(value):
        return "inf"
    return f"{value:.4g}"


def _fitness_of(population: Any) -> Sequence[float]:
    """The fitness values of an island's generation: a host's report, or the individuals'."""
    reported = getattr(population, "fitness", None)
    if reported is not None:
        return list(reported)
    return [ind.fitness for ind in population]


def _median(values: Sequence[float]) -> float:
    finite = [v for v in values if not math.isnan(v)]
    return statistics.median_low(finite) if finite else math.inf


class ProgressDisplay:
    """Prints a line for each generation every island has completed, and the run's start and end."""

    def __init__(self, *, total_generations: int, out: TextIO | None = None, quiet: bool = False,
                 clock=time.monotonic) -> None:
        self.total_generations = total_generations
        self.out = out if out is not None else sys.stdout
        self.quiet = quiet
        self._clock = clock
        self._started = clock()
        self._individuals = 0
        self._generations = 0

    def message(self, text: str) -> None:
        """A free-form line (start, migration, recovery, interrupt), unless quiet."""
        if not self.quiet:
            print(text, file=self.out, flush=True)

    def generation(self, generation: int, populations: Mapping[int, Any], *, remaining: int) -> str:
        """Record that every island completed ``generation``; print and return its line.
        ``populations``: island -> its individuals, or what its host reported (``fitness`` values)."""
        fitness = {i: _fitness_of(pop) for i, pop in populations.items()}
        self._generations += 1
        self._individuals += sum(len(f) for f in fitness.values())
        elapsed = max(self._clock() - self._started, 1e-9)
        rate = self._individuals / elapsed
        left = elapsed / self._generations * remaining
        everyone = [f for values in fitness.values() for f in values]
        islands = "  ".join(
            f"i{i} {format_fitness(min(values, default=math.inf))}/{format_fitness(_median(values))}"
            for i, values in sorted(fitness.items())
        )
        width = len(str(self.total_generations))
        line = (
            f"gen {generation:>{width}}/{self.total_generations}"
            f"  best {format_fitness(min(everyone, default=math.inf))}"
            f"  median {format_fitness(_median(everyone))}"
            f"  | {islands} |"
            f" {rate:.1f} ind/s  {format_duration(left)} left"
        )
        if not self.quiet:
            print(line, file=self.out, flush=True)
        return line

    @property
    def individuals_per_second(self) -> float:
        """Individuals evaluated per second since the display started."""
        return self._individuals / max(self._clock() - self._started, 1e-9)
