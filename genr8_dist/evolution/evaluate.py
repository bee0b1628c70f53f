"""Evaluate one genome: map it with the universe, parse the rewrite system, grow it, score the surface.

Failure is data: whatever goes wrong (the genome wraps too often, the text does not parse, growth raises
or hits a cap, the surface is degenerate) comes back as an ``Evaluation`` with ``valid=False``, the
``stage`` that failed, the ``error`` and the worst fitness (``inf``); nothing raises for an int genome.

An ``Evaluator`` keeps two caches for one configuration: genome -> evaluation, and rewrite-system text
-> grown and scored surface (many genomes map to the same text, since GE genomes carry unread codons).
Evaluation is a pure function of (genome, configuration), so the caches change timings, never results.
"""

from __future__ import annotations

import math
import time
from collections import OrderedDict
from collections.abc import Sequence
from dataclasses import replace
from functools import lru_cache
from typing import TYPE_CHECKING, Any

from genr8_dist.errors import GenomeError, Genr8Error
from genr8_dist.evolution.individual import Evaluation
from genr8_dist.fitness import FitnessSpec, score_surface

if TYPE_CHECKING:
    from genr8_dist.config import RunConfig

__all__ = [
    "Evaluation",
    "Evaluator",
    "evaluate_genome",
    "evaluate_text",
    "judge",
    "regions_of",
    "steps_of",
    "universe_for",
]


@lru_cache(maxsize=16)
def universe_for(name: str) -> Any:
    """The loaded universe ``name`` (loaded once per process)."""
    from genr8_dist.grammar import load_universe

    return load_universe(name)


def _describe(exc: BaseException) -> str:
    text = str(exc).strip().splitlines()[0] if str(exc).strip() else ""
    return f"{type(exc).__name__}: {text}" if text else type(exc).__name__


def _check_genome(genome: Sequence[int]) -> tuple[int, ...]:
    try:
        values = tuple(int(c) for c in genome)
    except (TypeError, ValueError):
        raise GenomeError(f"a genome is a sequence of non-negative integers, got {genome!r}") from None
    if not values:
        raise GenomeError("a genome needs at least one codon")
    if any(c < 0 for c in values):
        raise GenomeError(f"codons must be non-negative, got {min(values)}")
    return values


def steps_of(result: Any) -> int:
    """How many derivation steps a ``GrowthResult`` ran (its ``steps`` is the per-step statistics)."""
    steps = result.steps
    return len(steps) if isinstance(steps, (list, tuple)) else int(steps)


def regions_of(surface: Any) -> int:
    """The number of regions of ``surface`` (without building the cycles when it can say)."""
    n = getattr(surface, "n_regions", None)
    return int(n) if n is not None else len(surface.regions)


def judge(text: str, result: Any, env: Any, fitness: FitnessSpec, *, grow_seconds: float = 0.0
          ) -> Evaluation:
    """Score a grown ``result`` (a ``GrowthResult`` of ``text``) under ``fitness`` in ``env``: the
    rules that make an individual valid (not capped, not degenerate, every criterion and the total
    finite) in one place, for runs and ``genr8 score``."""
    surface = result.surface
    raw_capped = result.capped
    capped = (raw_capped if isinstance(raw_capped, str) else "cap") if raw_capped else None
    steps_done = steps_of(result)
    grown = Evaluation(text=text, n_vertices=len(surface.vertices), n_edges=len(surface.edges),
                       n_regions=regions_of(surface), steps_done=steps_done, capped=capped,
                       grow_seconds=grow_seconds)
    t1 = time.perf_counter()
    try:
        digest = surface.digest()
        criteria = score_surface(surface, env, fitness.names)
    except Exception as exc:  # failure is data
        return replace(grown, stage="score", error=_describe(exc), score_seconds=time.perf_counter() - t1)
    grown = replace(grown, surface_digest=digest, criteria=criteria,
                    score_seconds=time.perf_counter() - t1)
    if capped:
        return replace(grown, stage="grow", error=f"growth capped ({capped}) in derivation step {steps_done}")
    if not grown.n_vertices or not grown.n_edges:
        return replace(grown, stage="score", error="degenerate surface: no vertices or no edges")
    bad = [name for name in criteria if not math.isfinite(criteria[name])]
    if bad:
        return replace(grown, stage="score", error=f"degenerate surface: {', '.join(bad)} not finite")
    total = fitness.evaluate(criteria)
    if not math.isfinite(total):
        return replace(grown, stage="score", error="fitness is not finite")
    return replace(grown, valid=True, fitness=total)


def _grow_and_score(text: str, config: RunConfig) -> Evaluation:
    """Parse, grow and score ``text`` in ``config``'s environment (no mapping fields set).

    ``grow_seconds`` is the time to parse the text and grow it; ``score_seconds`` the criteria's."""
    from genr8_dist.hemls import grow, parse

    t0 = time.perf_counter()  # grow_seconds counts parsing the text too
    try:
        system = parse(text)
    except Exception as exc:  # failure is data: a text that does not parse is an invalid individual
        return Evaluation(text=text, stage="parse", error=_describe(exc),
                          grow_seconds=time.perf_counter() - t0)
    try:
        result = grow(system, config.environment)
    except Exception as exc:  # failure is data, whatever growth raised
        return Evaluation(text=text, stage="grow", error=_describe(exc),
                          grow_seconds=time.perf_counter() - t0)
    return judge(text, result, config.environment, config.fitness, grow_seconds=time.perf_counter() - t0)


class Evaluator:
    """Evaluates genomes for one configuration, each distinct genome and each distinct text once
    (bounded caches of ``cache_size`` entries, least recently used dropped first)."""

    def __init__(self, config: RunConfig, *, cache_size: int = 4096) -> None:
        self.config = config
        self.universe = universe_for(config.universe)
        self.cache_size = cache_size
        self._genomes: OrderedDict[tuple[int, ...], Evaluation] = OrderedDict()
        self._texts: OrderedDict[str, Evaluation] = OrderedDict()
        self.evaluations = 0     # genomes actually mapped
        self.growths = 0         # texts actually grown
        self.cache_hits = 0

    def _remember(self, cache: OrderedDict[Any, Evaluation], key: Any, value: Evaluation) -> None:
        cache[key] = value
        if len(cache) > self.cache_size:
            cache.popitem(last=False)

    def holds(self, genome: Sequence[int]) -> bool:
        """Whether ``genome``'s evaluation is cached (evaluating it again costs nothing)."""
        return tuple(genome) in self._genomes

    def adopt(self, genome: Sequence[int], evaluation: Evaluation) -> None:
        """Cache ``evaluation``, made elsewhere under this configuration, as ``genome``'s own."""
        key = _check_genome(genome)
        self.evaluations += 1
        if evaluation.text is not None and evaluation.stage != "map":
            self.growths += 1
            self._remember(self._texts, evaluation.text, evaluation)
        self._remember(self._genomes, key, evaluation)

    def evaluate(self, genome: Sequence[int]) -> Evaluation:
        """The evaluation of ``genome``; a repeat of a cached genome comes back with zero timings."""
        key = _check_genome(genome)
        hit = self._genomes.get(key)
        if hit is not None:
            self._genomes.move_to_end(key)
            self.cache_hits += 1
            return hit.untimed()
        self.evaluations += 1
        start = time.perf_counter()
        genome_settings = self.config.genome
        try:
            mapped = self.universe.map(list(key), max_depth=genome_settings.max_depth,
                                       max_wraps=genome_settings.max_wraps)
        except Exception as exc:  # the mapper should not raise for int genomes; if it does, it is data
            result = Evaluation(stage="map", error=_describe(exc), map_seconds=time.perf_counter() - start)
            result = replace(result, eval_seconds=result.map_seconds)
            self._remember(self._genomes, key, result)
            return result
        codons_used, wraps = int(mapped.codons_used), int(mapped.wraps)
        map_seconds = time.perf_counter() - start
        if not mapped.valid:
            result = Evaluation(text=mapped.text or None, stage="map",
                                error=str(mapped.reason or "mapping failed"))
        else:
            grown = self._texts.get(mapped.text)
            if grown is not None:
                self._texts.move_to_end(mapped.text)
                grown = grown.untimed()
            else:
                self.growths += 1
                grown = _grow_and_score(mapped.text, self.config)
                self._remember(self._texts, mapped.text, grown)
            result = grown
        result = replace(result, codons_used=codons_used, wraps=wraps, map_seconds=map_seconds,
                         eval_seconds=time.perf_counter() - start)
        self._remember(self._genomes, key, result)
        return result

    def evaluate_text(self, text: str) -> Evaluation:
        """Grow and score a rewrite system written by hand (no mapping: codons_used and wraps are 0)."""
        cached = self._texts.get(text)
        if cached is not None:
            self.cache_hits += 1
            return cached.untimed()
        start = time.perf_counter()
        self.growths += 1
        result = _grow_and_score(text, self.config)
        self._remember(self._texts, text, result)
        return replace(result, eval_seconds=time.perf_counter() - start)


def evaluate_genome(genome: Sequence[int], config: RunConfig, *,
                    evaluator: Evaluator | None = None) -> Evaluation:
    """Map, parse, grow and score one genome under ``config`` (a ``RunConfig``); never raises for a
    sequence of non-negative ints (``GenomeError`` otherwise). Pass an ``Evaluator`` to share caches."""
    if evaluator is None or evaluator.config is not config:
        evaluator = Evaluator(config, cache_size=1)
    return evaluator.evaluate(genome)


def evaluate_text(text: str, config: RunConfig) -> Evaluation:
    """Grow and score a hand-written rewrite system under ``config`` (what ``genr8 score`` does)."""
    if not isinstance(text, str):
        raise Genr8Error(f"a rewrite system is text, got {type(text).__name__}")
    return Evaluator(config, cache_size=1).evaluate_text(text)
