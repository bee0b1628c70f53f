"""The progress display: a refreshing table in a terminal, one line per generation elsewhere.

When its output is not a terminal (``ray job logs``, a CI log, a pipe) it prints plain lines, one per
generation completed by every island, with no cursor movement::

    gen   12/50  best 0.4123  median 1.2030  | i0 0.412/1.203  i1 0.519/1.410 | 38.2 ind/s  1m05s left

``best`` and ``median`` are over all islands; each ``iN`` shows that island's best/median fitness.
Invalid individuals (fitness ``inf``) count as worst.

In a terminal (``out.isatty()``) it keeps a table at the bottom, redrawn in place as each island
completes a generation, as Ray Tune shows its trials: a head line (the generation every island has
completed, the rate, the time left, the best) and a row per island with its current generation, best
and mean fitness (of the valid) and the individuals it has evaluated. Messages print above the table.
"""

from __future__ import annotations

import math
import statistics
import sys
import time
from collections.abc import Callable, Mapping, Sequence
from typing import Any, TextIO

__all__ = ["ProgressDisplay", "format_duration", "format_fitness"]

_UP_AND_CLEAR = "\x1b[{n}F\x1b[J"   # to the start of the line n lines up, then clear to the end


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


def _mean(values: Sequence[float]) -> float:
    """The mean of the finite values (the valid individuals'); ``inf`` when there are none."""
    finite = [v for v in values if math.isfinite(v)]
    return math.fsum(finite) / len(finite) if finite else math.inf


def _is_terminal(out: TextIO) -> bool:
    isatty = getattr(out, "isatty", None)
    try:
        return bool(isatty()) if isatty is not None else False
    except ValueError:   # a closed stream
        return False


class ProgressDisplay:
    """Shows each generation every island has completed (a line, or a refreshing table in a
    terminal: ``table``, default ``out.isatty()``), and the run's messages."""

    def __init__(self, *, total_generations: int, out: TextIO | None = None, quiet: bool = False,
                 clock: Callable[[], float] = time.monotonic, table: bool | None = None) -> None:
        self.total_generations = total_generations
        self.out = out if out is not None else sys.stdout
        self.quiet = quiet
        self.table = (_is_terminal(self.out) if table is None else table) and not quiet
        self._clock = clock
        self._started = clock()
        self._individuals = 0
        self._generations = 0
        self._islands: dict[int, dict[str, float]] = {}   # island -> generation, best, mean, evaluations
        self._drawn = 0          # lines of the table now on screen (0: none)
        self._head = "waiting for the first generation"

    def attach(self, hooks: Any) -> None:
        """Subscribe to a coordinator's ``Hooks``: a row per island's generation, a line per
        generation every island has completed, the run's messages."""
        hooks.subscribe(on_island=lambda run, island, generation, done: self.island(island, generation, done),
                        on_generation=self._generation_done,
                        on_message=lambda run, text: self.message(text))

    def _generation_done(self, run: Any, generation: int) -> None:
        """``on_generation``: the line of ``generation`` (``run``: the coordinator, whose last
        generation an edit may have moved)."""
        self.total_generations = run.last
        self.generation(generation, run.populations(generation), remaining=run.last - generation)

    def message(self, text: str) -> None:
        """A free-form line (start, migration, recovery, interrupt), unless quiet; above the table."""
        if self.quiet:
            return
        if self.table:
            self._erase()
            print(text, file=self.out)
            self._draw()
        else:
            print(text, file=self.out, flush=True)

    def island(self, island: int, generation: int, population: Any) -> None:
        """``island`` completed ``generation`` (its individuals, or its host's report): its row of
        the table (redrawn in a terminal)."""
        fitness = _fitness_of(population)
        row = self._islands.setdefault(island, {"generation": -1, "best": math.inf, "mean": math.inf,
                                                "evaluations": 0})
        row["generation"] = generation
        row["best"] = min(fitness, default=math.inf)
        row["mean"] = _mean(fitness)
        row["evaluations"] += len(fitness)
        if self.table:
            self._erase()
            self._draw()

    def rows(self) -> list[str]:
        """The table as lines: the head line, the column names, a row per island."""
        width = len(str(self.total_generations))
        lines = [self._head, f"{'island':>6}  {'generation':>{max(10, 2 * width + 1)}}  {'best':>10}  "
                             f"{'mean':>10}  {'evaluations':>11}"]
        for i, row in sorted(self._islands.items()):
            gen = f"{int(row['generation'])}/{self.total_generations}"
            lines.append(f"{i:>6}  {gen:>{max(10, 2 * width + 1)}}  {format_fitness(row['best']):>10}  "
                         f"{format_fitness(row['mean']):>10}  {int(row['evaluations']):>11,}")
        return lines

    def _erase(self) -> None:
        if self._drawn:
            self.out.write(_UP_AND_CLEAR.format(n=self._drawn))
            self._drawn = 0

    def _draw(self) -> None:
        lines = self.rows()
        self.out.write("\n".join(lines) + "\n")
        self.out.flush()
        self._drawn = len(lines)

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
        if self.table:
            self._head = (f"generation {generation}/{self.total_generations} completed by every island"
                          f" · best {format_fitness(min(everyone, default=math.inf))}"
                          f" · {rate:.1f} ind/s · {format_duration(left)} left")
            self._erase()
            self._draw()
        elif not self.quiet:
            print(line, file=self.out, flush=True)
        return line

    @property
    def individuals_per_second(self) -> float:
        """Individuals evaluated per second since the display started."""
        return self._individuals / max(self._clock() - self._started, 1e-9)
