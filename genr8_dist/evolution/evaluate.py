"""Evaluate one genome: map it with the universe, develop the text into its phenotype, score it.

Failure is data: whatever goes wrong (the genome wraps too often, the text does not parse, growth raises
or hits a cap, the phenotype is degenerate) comes back as an ``Evaluation`` with ``valid=False``, the
``stage`` that failed, the ``error`` and the worst fitness (``inf``); nothing raises for an int genome.

An ``Evaluator`` keeps two caches for one configuration: genome -> evaluation, and rewrite-system text
-> developed and scored phenotype (many genomes map to the same text, since GE genomes carry unread codons);
and, for an island's screen before growth, genome -> mapping and text -> what the phenotype's
``screen`` reads in it, so that screening a child and then evaluating it maps it once.
Every Evaluator of a process (an island host) also shares a bounded cache keyed by (text,
``development_key``): growing and measuring a text depends on the universe and the environment only,
so a text grown for one configuration is not grown again for another that differs in its fitness
(an edit, another island's version, a helper's share): ``rescore`` judges it again from its raw
criteria. Evaluation is a pure function of (genome, configuration), so the caches change timings,
never results. ``Evaluator.preview`` develops a genome without measuring it (a ``Preview``) and
``Evaluator.measure`` finishes it: an island measures only what it keeps. What each development
read of its text (``Developed.reads``) is kept beside the shared growths (``Evaluator.reads``), so
an island can tell a child that copies a parent before developing it (``Phenotype.copies``).
"""

from __future__ import annotations

import hashlib
import json
import math
import time
from collections import OrderedDict
from collections.abc import Sequence
from dataclasses import dataclass, replace
from functools import lru_cache
from typing import TYPE_CHECKING, Any, Protocol, TypeVar, cast

from genr8_dist.errors import GenomeError, Genr8Error
from genr8_dist.evolution.individual import Evaluation
from genr8_dist.evolution.variation import map_genome

if TYPE_CHECKING:
    from genr8_dist.config import RunConfig
    from genr8_dist.grammar.universe import MapResult, Universe
    from genr8_dist.phenotype import Developed, Phenotype


__all__ = [
    "Evaluation",
    "Evaluator",
    "Preview",
    "development_key",
    "evaluate_genome",
    "evaluate_text",
    "rescore",
    "steps_of",
    "universe_for",
]


K = TypeVar("K")
V = TypeVar("V")


class Stepped(Protocol):
    """A development's result with its derivation steps: a count, or per-step statistics."""

    @property
    def steps(self) -> int | Sequence[object]: ...


@dataclass(frozen=True, slots=True, kw_only=True)
class Preview(Evaluation):
    """What evaluating a genome finds before its criteria are measured (``Evaluator.preview``): its
    mapping, text, sizes, steps, capped and phenotype digest, no criteria and the worst fitness;
    ``valid`` says only that nothing has failed it yet (a capped development fails it; measuring may
    still). Never stored: ``Evaluator.measure`` turns it into the evaluation."""

    def untimed(self) -> Preview:
        return Preview(**self.untimed_fields())


def universe_for(config: RunConfig | str) -> Universe:
    """The universe of ``config`` (a ``RunConfig``), built from the files it carries (once per process),
    never looked up again by name: a Ray host on any machine builds the driver's universe. A plain
    name is looked up (the Python API's shorthand)."""
    source = getattr(config, "universe_source", None)
    if source is None:
        return _named_universe(str(config))
    from genr8_dist.grammar.universe import build_universe

    return build_universe(source, check=False)


@lru_cache(maxsize=16)
def _named_universe(name: str) -> Universe:
    from genr8_dist.grammar import load_universe

    return load_universe(name)


def _describe(exc: BaseException) -> str:
    text = str(exc).strip().splitlines()[0] if str(exc).strip() else ""
    return f"{type(exc).__name__}: {text}" if text else type(exc).__name__


def _check_genome(genome: Sequence[int]) -> tuple[int, ...]:
    try:
        values = tuple(map(int, genome))
    except (TypeError, ValueError):
        raise GenomeError(f"a genome is a sequence of non-negative integers, got {genome!r}") from None
    if not values:
        raise GenomeError("a genome needs at least one codon")
    if min(values) < 0:
        raise GenomeError(f"codons must be non-negative, got {min(values)}")
    return values


def steps_of(result: Stepped) -> int:
    """How many derivation steps a ``GrowthResult`` ran (its ``steps`` is the per-step statistics)."""
    steps = result.steps
    return len(steps) if isinstance(steps, Sequence) else int(steps)


def _grow_and_score(text: str, config: RunConfig) -> Evaluation:
    """Develop ``text`` into the universe's phenotype and score it (no mapping fields set).

    The phenotype (:func:`genr8_dist.phenotype.phenotype_of`: a HEMLS surface unless the universe
    brings its own) develops the text, measures its criteria and combines them into the fitness.
    ``grow_seconds`` is the time to develop the text (parsing included); ``score_seconds`` the
    criteria's and the fitness's."""
    grown, developed = _develop(text, config)
    return grown if developed is None else _measure(grown, developed, config)


def _develop(text: str, config: RunConfig,
             phenotype: Phenotype | None = None) -> tuple[Evaluation, Developed | None]:
    """``text`` developed, not yet measured: the evaluation so far (its text, sizes, steps, capped,
    digest and ``grow_seconds``; criteria empty, not judged) and the ``Developed`` phenotype; or the
    finished evaluation of a failed development and ``None``. ``phenotype``: ``config``'s (an
    ``Evaluator`` holds it; else looked up)."""
    phenotype = phenotype if phenotype is not None else _phenotype(config)
    t0 = time.perf_counter()  # grow_seconds counts parsing the text too
    try:
        developed = phenotype.develop(text, config)
    except Exception as exc:  # failure is data, whatever development raised
        return Evaluation(text=text, stage=getattr(exc, "genr8_stage", phenotype.stage), error=_describe(exc),
                          grow_seconds=time.perf_counter() - t0), None
    sizes = {name: int(developed.counts.get(name, 0)) for name in phenotype.sizes}
    grown = Evaluation(text=text, sizes=sizes, steps_done=int(developed.steps), capped=developed.capped,
                       grow_seconds=time.perf_counter() - t0, phenotype_digest=developed.digest)
    return grown, developed


def _measure(grown: Evaluation, developed: Developed, config: RunConfig,
             phenotype: Phenotype | None = None) -> Evaluation:
    """``grown`` (what ``_develop`` found) measured and judged: its criteria, ``score_seconds``, the
    verdict and the fitness."""
    phenotype = phenotype if phenotype is not None else _phenotype(config)
    if grown.capped and phenotype.capped_is_invalid:
        return _judge(grown, config, phenotype)   # invalid whatever it measures: the largest surfaces
    t1 = time.perf_counter()
    try:
        criteria = phenotype.measure(developed, config)
    except Exception as exc:  # failure is data
        return replace(grown, stage="score", error=_describe(exc), score_seconds=time.perf_counter() - t1)
    return _judge(grown, config, phenotype, criteria=criteria, score_seconds=time.perf_counter() - t1)


def _phenotype(config: RunConfig) -> Phenotype:
    return _phenotype_of(universe_for(config))


def _phenotype_of(universe: Universe) -> Phenotype:
    """The phenotype of ``universe`` (imported here: it imports the surfaces)."""
    from genr8_dist.phenotype import phenotype_of

    return phenotype_of(universe)


def _judge(grown: Evaluation, config: RunConfig, phenotype: Phenotype | None = None,
           **measured: Any) -> Evaluation:
    """The verdict on a developed and measured text (``grown``: what ``_grow_and_score`` found, its
    ``criteria`` the raw values ``config`` asks for) under ``config``: valid or why not, and the
    fitness, as the universe's phenotype decides; the rules that make an individual valid, in one
    place (``genr8 score`` reports them too). A pure function of those stored fields: ``rescore``
    calls it again after an edit. ``measured``: fields ``grown`` takes first (``criteria`` and
    ``score_seconds`` as ``_measure`` found them), set with the verdict in one copy."""
    phenotype = phenotype if phenotype is not None else _phenotype(config)
    criteria = measured.get("criteria", grown.criteria)
    if grown.capped and phenotype.capped_is_invalid:
        error = f"growth capped ({grown.capped}) in derivation step {grown.steps_done}"
        return replace(grown, **measured, stage=phenotype.stage, error=error)
    counts = {**grown.sizes, "steps_done": grown.steps_done}
    problem = phenotype.problem(counts, criteria)
    if problem:
        return replace(grown, **measured, stage="score", error=problem)
    try:
        fitness = phenotype.fitness(criteria, config)
    except Exception as exc:  # failure is data
        return replace(grown, **measured, stage="score", error=_describe(exc))
    if not math.isfinite(fitness):
        return replace(grown, **measured, stage="score", error="fitness is not finite")
    return replace(grown, **measured, valid=True, fitness=fitness)


# The grown and measured texts of this process, shared by its Evaluators: (development_key, text) ->
# the evaluation made for some configuration with that key (see the module docstring).
_DEVELOPED: OrderedDict[tuple[str, str], Evaluation] = OrderedDict()
DEVELOPED_CACHE_SIZE = 8192
# What each of those developments read (``Developed.reads``), kept alike: (development_key, text) ->
# reads; ``Evaluator.reads`` develops a text again when it is not here.
_READS: OrderedDict[tuple[str, str], str | None] = OrderedDict()


def _keep(cache: OrderedDict[K, V], key: K, value: V) -> None:
    """``value`` at ``key`` in one of the process's shared caches, the least recently used entry
    dropped past ``DEVELOPED_CACHE_SIZE``."""
    cache[key] = value
    cache.move_to_end(key)
    if len(cache) > DEVELOPED_CACHE_SIZE:
        cache.popitem(last=False)


# The fields of an evaluation that growing and measuring its text produced (rescore keeps them).
_GROWN_FIELDS = ("text", "sizes", "steps_done", "capped", "phenotype_digest", "grow_seconds",
                 "score_seconds")


def development_key(config: RunConfig) -> str:
    """What growing and measuring a text depends on besides the text: the universe (whose phenotype
    it is) and the environment. Configurations with the same key develop every text into the same
    phenotype and measure the same raw criteria; their fitness may differ."""
    env = config.environment
    table = env.to_dict() if hasattr(env, "to_dict") else env
    blob = json.dumps([config.universe, table], sort_keys=True, default=repr)
    return hashlib.blake2b(blob.encode(), digest_size=16).hexdigest()


def rescore(evaluation: Evaluation, config: RunConfig) -> Evaluation | None:
    """``evaluation`` of a text, made under a configuration with ``config``'s ``development_key``,
    judged again under ``config`` from its raw criteria, without growing the text; what evaluating it
    under ``config`` gives (timings aside). None when it lacks a raw value ``config`` asks for
    (the text must be grown and measured again)."""
    if not evaluation.criteria and evaluation.stage in ("parse", "grow"):
        return evaluation   # it failed before any criterion was measured: the fitness plays no part
    names = tuple(config.fitness.names)
    if not all(name in evaluation.criteria for name in names):
        return None
    grown: dict[str, Any] = {name: getattr(evaluation, name) for name in _GROWN_FIELDS}
    grown["criteria"] = {name: evaluation.criteria[name] for name in names}
    return replace(_judge(Evaluation(**grown), config), codons_used=evaluation.codons_used,
                   wraps=evaluation.wraps,
                   map_seconds=evaluation.map_seconds, eval_seconds=evaluation.eval_seconds)


class Evaluator:
    """Evaluates genomes for one configuration, each distinct genome and each distinct text once
    (bounded caches of ``cache_size`` entries, least recently used dropped first), and no text
    grown in this process for a configuration of the same ``development_key`` grown again.

    ``preview`` maps and develops a genome but leaves measuring it for later: an island that decides
    from what growth found (a repeated phenotype, a capped growth, a trivial founder) to vary it
    again never measures it; ``measure`` finishes a preview it keeps, from the developed phenotype
    (the last ``DEVELOPED_KEPT`` are held; an older one is developed again)."""

    DEVELOPED_KEPT = 16

    def __init__(self, config: RunConfig, *, cache_size: int = 4096) -> None:
        self.config = config
        self.universe = universe_for(config)
        self.phenotype = _phenotype_of(self.universe)
        self.cache_size = cache_size
        self._genomes: OrderedDict[tuple[int, ...], Evaluation] = OrderedDict()
        self._texts: OrderedDict[str, Evaluation] = OrderedDict()
        self._previews: OrderedDict[tuple[int, ...], Preview] = OrderedDict()   # genome -> not measured
        self._unmeasured: OrderedDict[str, Evaluation] = OrderedDict()   # text -> developed, not measured
        self._developed: OrderedDict[str, Developed] = OrderedDict()   # text -> its Developed (the last few)
        self._mappings: OrderedDict[tuple[int, ...], tuple[MapResult, float]] = OrderedDict()
        self._screens: OrderedDict[str, tuple[bool, str | None]] = OrderedDict()
        self.evaluations = 0     # genomes actually mapped
        self.growths = 0         # texts actually grown
        self.cache_hits = 0
        self.rescored = 0        # texts judged again from a growth made for another configuration
        self._development_key: str | None = None

    @property
    def development_key(self) -> str:
        """``development_key(self.config)``, computed once."""
        if self._development_key is None:
            self._development_key = development_key(self.config)
        return self._development_key

    def _share(self, text: str, evaluation: Evaluation) -> None:
        _keep(_DEVELOPED, (self.development_key, text), evaluation)

    def _grown(self, text: str, defer: bool = False) -> Evaluation:
        """``text`` grown and scored under this configuration: from this Evaluator's cache, judged
        again from the process's growth of it for another configuration, or grown now. ``defer``:
        a text grown now (or grown before and not measured) comes back as a ``Preview``, its
        measuring left to ``measure``."""
        cached = self._texts.get(text)
        if cached is not None:
            self._texts.move_to_end(text)
            return cached.untimed()
        shared = _DEVELOPED.get((self.development_key, text))
        judged = rescore(shared, self.config) if shared is not None else None
        if judged is not None:
            self.rescored += 1
            judged = judged.untimed()
        else:
            grown = self._unmeasured.get(text)
            if grown is not None:   # developed before, not measured: a hit, as one in _texts is
                grown = grown.untimed()
                developed = self._developed.pop(text, None)
                if defer:
                    return self._defer(grown, developed)
                if developed is None:   # no longer held: develop it again
                    grown, developed = self._develop(text)
            else:
                grown, developed = self._develop(text)
                if developed is not None and defer:
                    return self._defer(grown, developed)
            self._unmeasured.pop(text, None)
            judged = grown if developed is None else _measure(grown, developed, self.config, self.phenotype)
            self._share(text, judged)
        self._remember(self._texts, text, judged)
        return judged

    def _develop(self, text: str) -> tuple[Evaluation, Developed | None]:
        """``text`` developed now (``_develop``), counted, and what its development read kept."""
        self.growths += 1
        grown, developed = _develop(text, self.config, self.phenotype)
        self.learn_reads(text, None if developed is None else developed.reads)
        return grown, developed

    def learn_reads(self, text: str, reads: str | None) -> None:
        """Keep what developing ``text`` read (``Developed.reads``), here or in another process
        (a helper's answer carries it: ``reads`` then need not develop it again)."""
        _keep(_READS, (self.development_key, text), reads)

    def reads(self, text: str) -> str | None:
        """What developing ``text`` read (``Developed.reads``; ``None``: not said): kept from a
        development of it in this process or a helper's, else developed again now (one made
        before a resume, say). A pure function of the text and the development key, like the rest."""
        key = (self.development_key, text)
        if key in _READS:
            return _READS[key]
        developed = self._develop(text)[1]
        return None if developed is None else developed.reads

    def said_reads(self, text: str | None) -> str | None:
        """What this process's development of ``text`` read, where it is kept (``None``: not kept,
        or not said); never develops it."""
        return None if text is None else _READS.get((self.development_key, text))

    def _defer(self, grown: Evaluation, developed: Developed | None) -> Preview:
        """``grown`` (not measured) as a preview, its ``developed`` phenotype (``None``: not held)
        held for ``measure``."""
        text = str(grown.text)
        self._remember(self._unmeasured, text, grown.untimed())
        if developed is not None:
            self._developed[text] = developed
            if len(self._developed) > self.DEVELOPED_KEPT:
                self._developed.popitem(last=False)
        failed = grown.capped is not None and self.phenotype.capped_is_invalid
        return Preview(**{**grown.as_fields(), "valid": not failed})

    def _remember(self, cache: OrderedDict[K, V], key: K, value: V) -> None:
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
            self._share(evaluation.text, evaluation)
        self._previews.pop(key, None)
        self._remember(self._genomes, key, evaluation)

    def evaluate(self, genome: Sequence[int]) -> Evaluation:
        """The evaluation of ``genome``; a repeat of a cached genome comes back with zero timings."""
        return self._evaluate(genome, defer=False)

    def preview(self, genome: Sequence[int]) -> Evaluation:
        """What evaluating ``genome`` finds before measuring it: a ``Preview`` when its text developed
        and is not measured yet (``measure`` finishes it), else the evaluation itself (cached, or a
        failure of mapping or development, which nothing is measured for)."""
        return self._evaluate(genome, defer=True)

    def measure(self, genome: Sequence[int], evaluation: Evaluation) -> Evaluation:
        """``evaluation`` of ``genome`` measured, when it is a ``Preview``: exactly what ``evaluate``
        gives, its timings those of the preview plus the measuring; else ``evaluation`` as it is. A
        preview that no development made (an offspring known to copy: ``Island._copy``) and that is
        developed here counts as an evaluation, as its development would have."""
        if not isinstance(evaluation, Preview):
            return evaluation
        key = _check_genome(genome)
        start = time.perf_counter()
        counted = self._previews.pop(key, None) is not None   # its preview counted an evaluation
        growths = self.growths
        judged = self._grown(str(evaluation.text))
        if not counted and self.growths > growths:   # a copy known without developing it, kept after all
            self.evaluations += 1
        result = replace(judged, codons_used=evaluation.codons_used, wraps=evaluation.wraps,
                         map_seconds=evaluation.map_seconds,
                         grow_seconds=evaluation.grow_seconds + judged.grow_seconds,
                         eval_seconds=evaluation.eval_seconds + time.perf_counter() - start)
        self._remember(self._genomes, key, result)
        return result

    def _evaluate(self, genome: Sequence[int], defer: bool) -> Evaluation:
        key = _check_genome(genome)
        hit = self._genomes.get(key)
        if hit is not None:
            self._genomes.move_to_end(key)
            self.cache_hits += 1
            return hit.untimed()
        previewed = self._previews.get(key)
        if previewed is not None:
            self.cache_hits += 1
            self._previews.move_to_end(key)
            return previewed.untimed() if defer else self.measure(key, previewed.untimed())
        self.evaluations += 1
        start = time.perf_counter()
        try:
            mapped, map_seconds = self._mapping(key)
        except Exception as exc:  # the mapper should not raise for int genomes; if it does, it is data
            result = Evaluation(stage="map", error=_describe(exc), map_seconds=time.perf_counter() - start)
            result = replace(result, eval_seconds=result.map_seconds)
            self._remember(self._genomes, key, result)
            return result
        if not mapped.valid:
            result = Evaluation(text=mapped.text or None, stage="map",
                                error=str(mapped.reason or "mapping failed"))
        else:
            result = self._grown(cast(str, mapped.text), defer)   # valid: a text
        result = replace(result, codons_used=int(mapped.codons_used), wraps=int(mapped.wraps),
                         map_seconds=map_seconds, eval_seconds=time.perf_counter() - start)
        if isinstance(result, Preview):
            self._remember(self._previews, key, result)
        else:
            self._remember(self._genomes, key, result)
        return result

    def mapped(self, genome: Sequence[int]) -> MapResult:
        """``genome`` mapped as this configuration maps it (``map_genome``), each distinct genome once:
        an island's screen maps a child before growth, and its evaluation reuses that mapping."""
        return self._mapping(_check_genome(genome))[0]

    def screen(self, text: str) -> tuple[bool, str | None]:
        """What the phenotype's ``screen`` reads in ``text`` before growth (whether it is trivial for
        sure, and its key: equal keys, equal phenotypes), each distinct text once; without a
        ``screen``, ``(False, text)``."""
        found = self._screens.get(text)
        if found is None:
            screen = getattr(self.phenotype, "screen", None)
            found = screen(text, self.config) if screen is not None else (False, text)
            self._remember(self._screens, text, found)
        return found

    def _mapping(self, key: tuple[int, ...]) -> tuple[MapResult, float]:
        """``key``'s mapping and the seconds it took (when it was made)."""
        found = self._mappings.get(key)
        if found is not None:
            self._mappings.move_to_end(key)
            return found
        start = time.perf_counter()
        made = map_genome(self.config, self.universe, key)
        found = (made, time.perf_counter() - start)
        self._remember(self._mappings, key, found)
        return found

    def evaluate_text(self, text: str) -> Evaluation:
        """Grow and score a rewrite system written by hand (no mapping: codons_used and wraps are 0)."""
        if text in self._texts:
            self.cache_hits += 1
            return self._texts[text].untimed()
        start = time.perf_counter()
        result = self._grown(text)
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
