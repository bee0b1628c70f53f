"""The island: one population of genomes evolving generation by generation, in plain Python.

A generation is a pure function of (configuration, previous generation, migrants, injected individuals,
generation number): every random draw comes from ``rng.stream(seed, "island", i, "generation", g,
purpose)``, so generation g can be recomputed exactly from generation g-1 as the run store keeps it, and
a run resumed from its store draws what an uninterrupted run draws. Ray only wraps it
(``genr8_dist.distributed``).

Generation g is filled in this order, indices 0, 1, 2, ...:

1. migrants (evaluated individuals of other islands, chosen by the coordinator): origin ``migrant``,
   parent their id, fitness kept (re-evaluated when their ``config_version`` differs);
2. injected individuals (a genome, a hand-written rewrite system inverted through the universe, or a
   copy of an existing ``Individual``): origin ``injected``, evaluated;
3. elites: the best ``ea.elites`` of generation g-1 with finite fitness, copied (origin ``elite``)
   (by ``search.mode``: see ``operators.selection``; in ``map-elites`` mode the whole archive);
4. offspring until the population is full (``generation_size``: in ``map-elites`` mode at least
   ``search.offspring`` of ``ea.population`` after the archive, so a generation may be larger): two
   parents by tournament (by ``search.mode``), one-point
   crossover with
   probability ``ea.crossover_rate``, then int-flip mutation of each codon with probability
   ``ea.mutation_rate`` (a child that was not crossed over is mutated at least once, so no offspring is a
   silent copy). Origin ``crossover``, ``mutation`` or ``crossover+mutation``; parents the ids used.
   With ``ea.within_used`` the cut and the flips fall within the codons the mapper read. A universe
   that brings its own operators (``evolution.variation``: ``hooks.VARIATION``, ``ea.variation``)
   breeds by them instead (``operators.recombination``): one child per recombination or mutation of texts.

No evaluation is spent on a copy (``ea.unique_retries`` > 0): the second parent is drawn again (up to
5 times) while it is the first one or has its text; an offspring whose rewrite system repeats a
parent's or an earlier member's of the generation, or that maps to none, is mutated again before it is
evaluated, and one that is invalid (its growth capped) or whose phenotype (its digest) repeats a
parent's or an earlier member's after it, each up to ``ea.unique_retries`` times (draws from the
generation's ``revary`` streams; each redraws at least one codon the mapper read, since a copy's read
codons are what make it a copy); one still wasted after them is replaced by a newcomer (a founder's
draw, origin ``random``, no parents), up to ``ea.unique_redraws`` times. Generation 0 likewise redraws a
founder that is trivial or repeats an earlier founder's phenotype (``evolution.founders``).
No growth is spent where the text already shows the waste (the phenotype's ``screen``; surfaces:
``hemls.splitting``): a founder or offspring whose rewrite system has no rule that can fire drawing
a branch (no region can ever split: trivial), or whose *effective* text (the rules that can fire)
repeats a parent's or an earlier member's, is drawn or varied again from its text alone
(``IslandStats.screened``); under ``ea.screen = 2`` also one whose growth, replayed on its edges'
labels and ends, can never join two branches (``hemls.splitting.can_join``), and an offspring
whose text shows it trivial is varied again in every mode, not only ``weighted``; under
``ea.screen = 3`` also one whose edges multiply so fast that every growth of it would be capped
(``hemls.budget.least_work`` past the environment's ``max_work``).
In ``weighted`` mode an offspring that grows trivial is varied again
too, from its first parent (its own variation broke what made the parent split its regions, so
its neighbourhood is mostly trivial), as is one whose growth was capped; trivial again after
``_TRIVIAL_RETRIES`` such re-variations, it is kept (``IslandStats.kept_trivial``): a parent whose
neighbourhood is mostly trivial would cost growth after growth (quick.toml in shell.toml: 1.24
evaluations per stored individual with no bound, 1.11 with one re-variation, 3-4% of offspring kept
trivial).
Whether a founder is drawn again or an offspring varied again is decided by what its growth found
(text, phenotype digest, sizes, capped), so one discarded is never measured (``Evaluator.preview``):
only the individuals kept are scored (measuring may still fail one, which is then varied again).
An offspring whose text the phenotype shows to develop into the phenotype of a valid parent or
an earlier member of its generation (``Phenotype.copies``: a surface's text that differs from the
other's only where that one's growth read nothing, ``hemls.splitting.same_growth``; a table's whose
final word fills the same cells) is not developed at all: its development would find that one's
phenotype (its digest, and that one's sizes, steps and capped stand in: it is developed only if it
is kept), so it is varied again as a repeated phenotype is, and the rows are the ones the island
builds when it develops such copies (``IslandStats.copied``; no evaluation spent).
Under ``ea.repeat_growths`` = n an offspring whose n-th development repeats a phenotype is kept as
it is (``IslandStats.kept_repeat``): where most variations repeat a phenotype in ways the text
cannot show (the paper's tables: moves that retrace), varying it again would cost development
after development; tries known to copy still cost none.
``IslandStats`` counts what each of these saved and what it cost.

A designer's hand-set fitness (``hand``) replaces the computed one of a marked individual for the
choice of elites and parents of generation g; a marked individual not of generation g-1 joins the pool.

Individuals of generation g-1 evaluated under another ``config_version`` (the fitness, the environment
or the universe changed: an intervention) are re-evaluated before selection, so they compete under the
configuration now in force. When only the fitness changed (the island's ``config_of`` gives their
version, with the same universe, genome settings and ``development_key``), they are judged again
from their stored raw criteria (``evaluate.rescore``) instead of being grown again: the same result.
Identical genomes are evaluated once (``Evaluator``'s cache).

A generation is built in two parts: ``breed`` draws every genome with its origin and parents (cheap,
sequential, seeded), then ``complete`` evaluates the genomes not yet evaluated and makes the
individuals. Evaluation is a pure function of (genome, configuration), so the genomes ``pending``
evaluation may be evaluated anywhere (an island host shares them with idle hosts) and passed to
``complete``: the generation is the same as ``step`` builds alone.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Container, Iterator, Mapping, Sequence
from dataclasses import dataclass, replace
from functools import partial
from itertools import islice
from typing import TYPE_CHECKING, Any

from genr8_dist.errors import ConfigError
from genr8_dist.evolution.evaluate import Evaluation, Evaluator, Preview, development_key, rescore
from genr8_dist.evolution.founders import Founders, is_trivial, settled
from genr8_dist.evolution.individual import Individual
from genr8_dist.evolution.operators import (
    Child,
    Genome,
    Look,
    crossover,
    int_flip_mutation,
    mutation,
    parent_picker,
    recombination,
    screened,
    select_matings,
    selection,
)
from genr8_dist.evolution.pareto import pareto_objectives
from genr8_dist.evolution.variation import Variation, genome_of, text_genome, variation_for
from genr8_dist.rng import stream

if TYPE_CHECKING:
    import numpy as np

    from genr8_dist.config import RunConfig
    from genr8_dist.phenotype import Phenotype

__all__ = ["Birth", "Injected", "Island", "IslandStats", "is_trivial", "pareto_objectives"]

# What a user may inject: a genome, a rewrite system's text, or an existing individual (a copy).
Injected = Sequence[int] | str | Individual


@dataclass(slots=True)
class IslandStats:
    """Counts of the last generation built by an island (for progress displays and benchmarks)."""

    generation: int = -1
    individuals: int = 0
    evaluated: int = 0       # genomes mapped this generation (the rest were kept or cache hits)
    grown: int = 0           # distinct texts grown this generation
    cache_hits: int = 0
    invalid: int = 0
    founders_redrawn: int = 0   # founder draws replaced (trivial or a repeated phenotype)
    mates_redrawn: int = 0      # second parents drawn again (the first one, or its text)
    revaried_text: int = 0      # offspring varied again because their text repeated another's
    revaried_phenotype: int = 0  # offspring varied again because their phenotype repeated another's
    revaried_invalid: int = 0   # offspring varied again because they were invalid (unmappable or capped)
    redrawn: int = 0            # offspring replaced by a newcomer after every re-variation failed
    unresolved: int = 0         # offspring or founders still repeating after every retry
    revaried_trivial: int = 0   # offspring varied again because their surface was trivial (one region)
    screened: int = 0           # drawn or varied again from the text alone, never developed
    copied: int = 0             # offspring known to repeat a parent's or member's phenotype, never developed
    kept_trivial: int = 0       # offspring kept trivial after _TRIVIAL_RETRIES trivial re-variations
    kept_repeat: int = 0        # offspring kept repeating after ea.repeat_growths developed repeats


@dataclass(frozen=True, slots=True)
class Birth:
    """An individual of a generation before evaluation: its genome, how it came to be, and its
    evaluation when already known (a migrant or elite kept as it was), else ``None``."""

    genome: tuple[int, ...]
    origin: str
    parents: tuple[str, ...] = ()
    evaluation: Evaluation | None = None
    avoid: frozenset[str] = frozenset()   # the parents' texts and phenotype digests (copies to avoid)
    source: tuple[tuple[int, ...], int] | None = None   # the first parent's genome and codons read
    kin: tuple[Kin, ...] = ()   # the valid parents, to know a copy of one before growth (``Island._copy``)


@dataclass(frozen=True, slots=True)
class Kin:
    """A valid parent or member of a generation as an offspring's copy of it is known: its text, what
    its development read (``Evaluator.reads``) and what that development found (digest, sizes,
    steps, capped)."""

    text: str
    reads: str | None
    digest: str
    sizes: tuple[tuple[str, int], ...]
    steps_done: int
    capped: str | None


_OFFSPRING = ("crossover", "mutation", "crossover+mutation")
_MATE_RETRIES = 5
# A trivial offspring is varied again from its first parent this many times; one trivial again
# after them is kept (its parent's neighbourhood is mostly trivial: more growths there are wasted).
_TRIVIAL_RETRIES = 1
_SCREENS = 20   # genomes drawn or varied again, from their text alone, before one is grown


def _first_parent(pool: Sequence[Individual], child: Child) -> tuple[Genome, int] | None:
    """The genome and codons read of ``child``'s first parent, where it is valid (``None``: not)."""
    first = pool[child.parents[0]]
    return (tuple(first.genome), first.codons_used) if first.valid else None


def _keys(ind: Individual | Evaluation) -> set[str]:
    keys = set()
    if ind.text is not None:
        keys.add(ind.text)
    if ind.valid and ind.phenotype_digest is not None:
        keys.add(ind.phenotype_digest)
    return keys


class Island:
    """One island of a run: ``initial()`` builds generation 0, ``step()`` each next generation."""

    def __init__(self, config: RunConfig, island_index: int, config_version: int = 1, *,
                 evaluator: Evaluator | None = None,
                 config_of: Callable[[int], RunConfig | None] | None = None) -> None:
        if isinstance(island_index, bool) or not isinstance(island_index, int) or island_index < 0:
            raise ConfigError(f"island index must be a non-negative integer, got {island_index!r}")
        if island_index >= config.islands.count:
            raise ConfigError(
                f"island index {island_index} is outside islands.count = {config.islands.count}"
            )
        self.config = config
        self.index = island_index
        self.config_version = int(config_version)
        self.evaluator = evaluator if evaluator is not None and evaluator.config is config \
            else Evaluator(config)
        self.config_of = config_of   # configuration version -> its configuration (None: unknown)
        self.stats = IslandStats()
        self._bred_at: tuple[int, int, int] | None = None   # the evaluator's counters when breeding began
        self.hooks: list[Callable[[list[Individual]], None]] = []
        # The universe's own operators (``evolution.variation``), or None: GE's.
        self.variation: Variation | None = variation_for(config, self.evaluator.universe)
        self.founders = Founders(config, self.evaluator, self.variation, partial(self.rng, 0), self._screened,
                                 self._count)

    # -- random streams -----------------------------------------------------------------------

    def rng(self, generation: int, purpose: str, *keys: int) -> np.random.Generator:
        """The generator for ``purpose`` (and ``keys``) in ``generation`` of this island."""
        return stream(self.config.seed, "island", self.index, "generation", generation, purpose, *keys)

    def _mapped(self, genome: Genome) -> tuple[str | None, int]:
        """The rewrite system ``genome`` maps to (``None`` when invalid) and the codons read."""
        result = self.evaluator.mapped(genome)
        return result.text, result.codons_used

    @property
    def _varies_trivial(self) -> bool:
        """Whether a trivial offspring is varied again: in ``weighted`` mode, where it only costs
        the fitness it lacks; under ``ea.screen = 1`` not in the other modes (a Pareto front or a
        MAP-Elites archive may want its extremes: one region is the most symmetric surface, the
        emptiest cell), under 2 in every mode (one trivial again after its re-variation is still
        kept, and elites keep the best of them)."""
        return self.config.search.mode == "weighted" or self.config.ea.screen >= 2

    def _screen(self, text: str | None) -> tuple[bool, str | None]:
        """What ``text`` (``None``: the genome maps to none) shows before growth: whether it is
        wasted for sure (no text, or trivial or capped as the phenotype's ``screen`` says) and its key (equal
        keys, equal phenotypes: a copy known without growing it)."""
        return (True, None) if text is None else self.evaluator.screen(text)

    def _screened(self, draw: Callable[[], Genome], avoid: Container[str | None] = ()) -> Genome:
        """A genome from ``draw`` (called again while the last one's text is wasted for sure or its
        key is in ``avoid``, at most ``_SCREENS`` times: mapping and reading a text costs no growth),
        the last one drawn if all were."""
        genome = draw()
        for _ in range(_SCREENS):
            wasted, key = self._screen(self._mapped(genome)[0])
            if not wasted and key not in avoid:
                break
            self.stats.screened += 1
            genome = draw()
        return genome

    def _revary(self, rng: np.random.Generator, genome: Genome, codons: int) -> Genome:
        """``genome`` mutated again, at least one of the ``codons`` the mapper read redrawn (a copy is
        a copy because its read codons are: flipping an unread one would change nothing); under a
        universe's variation, its mutation of the text."""
        if self.variation is not None:
            return text_genome(self.variation.mutate(rng, "".join(map(chr, genome))))
        return int_flip_mutation(rng, genome, self.config.ea.mutation_rate, self.config.genome.codon_max,
                                 at_least_one=True, within=codons if codons > 0 else None)[0]

    # -- building individuals -----------------------------------------------------------------

    def evaluate(self, genome: Sequence[int]) -> Evaluation:
        """The evaluation of ``genome`` under this island's configuration (cached)."""
        return self.evaluator.evaluate(genome)

    def _make(self, generation: int, index: int, genome: Sequence[int], origin: str,
              parents: tuple[str, ...], evaluation: Evaluation,
              extra: dict[str, Any] | None = None) -> Individual:
        return Individual(island=self.index, generation=generation, index=index,
                          genome=tuple(int(c) for c in genome), origin=origin, parents=parents,
                          config_version=self.config_version, extra=extra if extra is not None else {},
                          **evaluation.as_fields())

    def _kept(self, individual: Individual) -> Evaluation:
        """The evaluation of an individual carried over: kept when made under this configuration,
        judged again from its raw criteria when only the fitness changed since, else evaluated."""
        fields = {name: getattr(individual, name) for name in Evaluation.__dataclass_fields__}
        if individual.config_version == self.config_version:
            return Evaluation(**fields).untimed()
        if self._only_fitness_changed(individual.config_version) and individual.stage != "map":
            judged = rescore(Evaluation(**fields), self.config)
            if judged is not None:
                return judged.untimed()
        return self.evaluate(individual.genome)

    def _only_fitness_changed(self, version: int) -> bool:
        """Whether configuration ``version`` maps genomes to the texts this island's does and grows
        and measures them as it does (it may differ in fitness, EA or islands)."""
        earlier = self.config_of(version) if self.config_of is not None else None
        if earlier is None:
            return False
        return (earlier.universe == self.config.universe and earlier.genome == self.config.genome
                and development_key(earlier) == self.evaluator.development_key)

    def _now(self, individual: Individual) -> Individual:
        """``individual`` as it competes under this island's configuration."""
        if individual.config_version == self.config_version:
            return individual
        return self._make(individual.generation, individual.index, individual.genome, individual.origin,
                          individual.parents, self._kept(individual))

    def _finish(self, generation: int, population: list[Individual], before: tuple[int, int, int]
                ) -> list[Individual]:
        ev = self.evaluator
        self.stats = replace(
            self.stats,   # the tallies the pipeline counted as it went, with the generation's totals
            generation=generation,
            individuals=len(population),
            evaluated=ev.evaluations - before[0],
            grown=ev.growths - before[1],
            cache_hits=ev.cache_hits - before[2],
            invalid=sum(1 for ind in population if not ind.valid),
        )
        for hook in self.hooks:
            hook(population)
        return population

    def _counters(self) -> tuple[int, int, int]:
        ev = self.evaluator
        return (ev.evaluations, ev.growths, ev.cache_hits)

    # -- generations --------------------------------------------------------------------------

    def initial(self) -> list[Individual]:
        """Generation 0: ``ea.population`` random genomes, evaluated (origin ``random``)."""
        return self.complete(0, self.breed(0))

    def step(self, previous: Sequence[Individual], generation: int,
             migrants: Sequence[Individual] = (), injected: Sequence[Injected] = (),
             hand: Sequence[tuple[Individual, float]] = ()) -> list[Individual]:
        """Generation ``generation`` from generation ``generation - 1`` (``previous``), the
        ``migrants`` arriving now, the ``injected`` individuals and the ``hand``-scored parents; see
        the module docstring."""
        if generation < 1:
            raise ValueError(f"step builds generation >= 1; use initial() for generation 0, got {generation}")
        return self.complete(generation, self.breed(generation, previous, migrants, injected, hand))

    def _injected(self, item: Injected) -> Birth:
        """The birth of an injected individual: a copy of an ``Individual``, a text inverted through
        the universe, or a genome."""
        if isinstance(item, Individual):
            return Birth(tuple(item.genome), "injected", (item.id,))
        if isinstance(item, str):
            return Birth(genome_of(self.config, self.evaluator.universe, item), "injected")
        return Birth(tuple(int(c) for c in item), "injected")

    def breed(self, generation: int, previous: Sequence[Individual] = (),
              migrants: Sequence[Individual] = (), injected: Sequence[Injected] = (),
              hand: Sequence[tuple[Individual, float]] = ()) -> list[Birth]:
        """The genomes of ``generation`` in index order, unevaluated where new: generation 0 random,
        a later one from ``previous`` (generation ``generation - 1``), ``migrants`` and ``injected``.
        ``hand`` pairs an individual with the fitness a designer gave it: it competes for elite places
        and tournaments with that fitness (added to the pool when it is not of ``previous``)."""
        self._bred_at = self._counters()
        self.stats = IslandStats(generation=generation)
        ea = self.config.ea
        if generation == 0:
            founders = self.founders.genomes(ea.population, lambda g: self._screen(self._mapped(g)[0])[1])
            return [Birth(genome, "random") for genome in founders]
        if not previous:
            raise ValueError(f"generation {generation} needs a non-empty previous generation")
        if len(migrants) + len(injected) > ea.population:
            raise ConfigError(
                f"{len(migrants)} migrants and {len(injected)} injected individuals do not fit in a "
                f"population of {ea.population} (ea.population)"
            )
        births = [Birth(tuple(m.genome), "migrant", (m.id,), self._kept(m)) for m in migrants]
        births += [self._injected(item) for item in injected]
        pool, parent_ids, fitnesses = self._pool(previous, hand)
        scores, elites, mates = selection(self.config, pool, fitnesses, ea.population - len(births))
        births += [Birth(tuple(pool[i].genome), "elite", (parent_ids[i],), self._kept(pool[i]))
                   for i in elites]
        room = self.generation_size(len(births)) - len(births)
        return births + list(islice(self._offspring(generation, births, pool, parent_ids, scores, mates),
                                    max(room, 0)))

    def _pool(self, previous: Sequence[Individual], hand: Sequence[tuple[Individual, float]]
              ) -> tuple[list[Individual], list[str], list[float]]:
        """Generation g-1 as it competes now (re-evaluated where its configuration was another one),
        its ids and fitnesses, with the ``hand``-scored individuals' fitness a designer gave them
        (one not of ``previous`` joins the pool)."""
        pool = [self._now(p) for p in previous]
        parent_ids = [p.id for p in previous]
        fitnesses = [p.fitness for p in pool]
        for marked, fitness in hand:
            if marked.id in parent_ids:
                fitnesses[parent_ids.index(marked.id)] = float(fitness)
                continue
            pool.append(self._now(marked))
            parent_ids.append(marked.id)
            fitnesses.append(float(fitness))
        return pool, parent_ids, fitnesses

    def _offspring(self, generation: int, births: Sequence[Birth], pool: Sequence[Individual],
                   parent_ids: Sequence[str], scores: Sequence[float], mates: Sequence[int]
                   ) -> Iterator[Birth]:
        """The offspring of ``generation``, without end, bred by the pipeline of
        ``evolution.operators``: selection, variation (GE's, or the universe's own operators), the
        screen before evaluation (copies of ``births``' and the parents' texts, and texts that show
        their growth wasted, varied again), births. Each stage draws from its own stream."""
        ea, variation = self.config.ea, self.variation
        retries = max(ea.unique_retries, 0)
        mate_retries = _MATE_RETRIES if retries else 0
        pick = parent_picker(scores, mates, ea.tournament)
        select_rng, revary_rng = self.rng(generation, "selection"), self.rng(generation, "revary")
        revary = partial(self._revary, revary_rng)
        if variation is None:   # GE: a mate's text equal to the first parent's is a copy
            matings = select_matings(pick, select_rng, retries=mate_retries, count=self._count,
                                     same=lambda a, b: b == a or (pool[a].text is not None
                                                                  and pool[b].text == pool[a].text))
            children = crossover(matings, self.rng(generation, "crossover"), ea.crossover_rate,
                                 genome=lambda i: pool[i].genome, read=lambda i: pool[i].codons_used,
                                 within_used=ea.within_used)
            children = mutation(children, self.rng(generation, "mutation"), ea.mutation_rate,
                                self.config.genome.codon_max, within_used=ea.within_used)
            taken = {self._screen(b.evaluation.text)[1] for b in births
                     if b.evaluation is not None and b.evaluation.text is not None}
            children = screened(children, look=self._look, revary=revary, taken=taken, retries=retries,
                                avoid=partial(self._avoid, pool) if retries else lambda _: set(),
                                count=self._count,
                                restart=partial(_first_parent, pool) if self.config.ea.screen >= 2 else None)
        else:   # the universe's own operators: a mate only for a recombination
            vary_rng = self.rng(generation, "variation")
            matings = select_matings(pick, select_rng, retries=mate_retries, count=self._count,
                                     crossed=lambda: bool(vary_rng.random() < ea.crossover_rate),
                                     same=lambda a, b: b == a or pool[b].text == pool[a].text)
            children = recombination(matings, vary_rng, variation, lambda i: str(pool[i].text))
            taken = {b.evaluation.text for b in births if b.evaluation is not None}
            children = screened(children, look=self._look_text, revary=revary, taken=taken, retries=retries,
                                avoid=lambda picked: {k for i in picked for k in _keys(pool[i])},
                                count=self._count)
        for child in children:
            first = pool[child.parents[0]] if variation is None else None
            source = (tuple(first.genome), first.codons_used) if first is not None and first.valid else None
            yield Birth(tuple(int(c) for c in child.genome), child.origin,
                        tuple(parent_ids[i] for i in child.parents), None, child.avoid, source,
                        self._kin(pool, child.parents))

    def _kin(self, pool: Sequence[Individual], parents: Sequence[int]) -> tuple[Kin, ...]:
        """The ``parents`` (indices into ``pool``) that a child may be known to copy (``_kin_of``)."""
        return tuple(kin for i in dict.fromkeys(parents) if (kin := self._kin_of(pool[i])) is not None)

    def _kin_of(self, ind: Individual | Evaluation) -> Kin | None:
        """``ind`` as an offspring's copy of it is known, where it is valid and the phenotype can tell
        (it overrides ``Phenotype.copies``; what its development read where the phenotype says it,
        ``Phenotype.says_reads``); else ``None``."""
        from genr8_dist.phenotype import Phenotype

        if getattr(type(self.phenotype), "copies", Phenotype.copies) is Phenotype.copies:
            return None
        if not ind.valid or ind.text is None or ind.phenotype_digest is None:
            return None
        reads = self.evaluator.reads(ind.text) if getattr(self.phenotype, "says_reads", False) else None
        return Kin(ind.text, reads, ind.phenotype_digest, tuple(ind.sizes.items()), ind.steps_done,
                   ind.capped)

    def _preview(self, birth: Birth, genome: Genome, members: Sequence[Kin] = ()) -> Evaluation:
        """``Evaluator.preview`` of ``genome``, an offspring of ``birth``'s parents, or what it would
        find where the offspring is known to copy a parent or one of ``members`` (the generation's
        so far): ``_copy``, counted, never developed."""
        copy = self._known_copy(birth, genome, members)
        if copy is None:
            return self.evaluator.preview(genome)
        self.stats.copied += 1
        return copy

    def _known_copy(self, birth: Birth, genome: Genome, members: Sequence[Kin]) -> Preview | None:
        """``_copy`` of ``genome`` among ``birth``'s parents, then among ``members``."""
        return self._copy(birth.kin, genome) or self._copy(members, genome)

    def _copy(self, kin: Sequence[Kin], genome: Genome) -> Preview | None:
        """What developing ``genome`` would find, where its text is known to develop into the
        phenotype of one of ``kin`` (``Phenotype.copies``): that one's development with this text and
        mapping, never developed (``None``: not known)."""
        if not kin:
            return None
        mapped = self.evaluator.mapped(genome)
        text = mapped.text
        if not mapped.valid or text is None:
            return None
        for one in kin:
            if text != one.text and self.phenotype.copies(text, one.text, one.reads, self.config):
                failed = one.capped is not None and self.phenotype.capped_is_invalid
                return Preview(text=text, valid=not failed, sizes=dict(one.sizes), steps_done=one.steps_done,
                               capped=one.capped, phenotype_digest=one.digest,
                               codons_used=int(mapped.codons_used), wraps=int(mapped.wraps))
        return None

    def _count(self, counter: str, n: int) -> None:
        """Adds ``n`` to the ``IslandStats`` counter named ``counter`` (the pipeline's tally)."""
        setattr(self.stats, counter, getattr(self.stats, counter) + n)

    def _avoid(self, pool: Sequence[Individual], parents: tuple[int, ...]) -> set[str]:
        """The keys a child of ``parents`` must not have: their texts, phenotype digests and screen keys."""
        avoid: set[str] = set()
        for i in parents:
            avoid |= _keys(pool[i])
            if pool[i].text is not None:
                avoid.add(str(self._screen(pool[i].text)[1]))
        return avoid

    def _look(self, genome: Genome) -> Look:
        """What ``genome`` shows before growth (``_screen`` of its text): wasted for sure when it maps
        to no text or, where a trivial child is varied again, when its text shows it trivial."""
        text, read = self._mapped(genome)
        trivial, key = self._screen(text)
        wasted = trivial and (text is None or self._varies_trivial)
        reason = "revaried_invalid" if text is None else "screened" if wasted else "revaried_text"
        return Look(wasted, key, read, reason)

    @staticmethod
    def _look_text(genome: Genome) -> Look:
        """What a text genome (a universe's own variation) shows: its text, the key of a copy."""
        return Look(False, "".join(map(chr, genome)), len(genome))

    def generation_size(self, kept: int) -> int:
        """How many individuals a generation holds when ``kept`` of them (migrants, injected, elites)
        are placed before the offspring: ``ea.population``; in ``map-elites`` mode at least
        ``search.offspring`` of it bred anew besides the archive, whose capacity is the grid."""
        ea, search = self.config.ea, self.config.search
        if search.mode != "map-elites":
            return ea.population
        return max(ea.population, kept + math.ceil(search.offspring * ea.population))

    def _varied_again(self, origin: str) -> bool:
        """Whether an offspring of ``origin`` that repeats a phenotype or fails is varied again
        (``ea.unique_retries``): then one known to copy needs no development."""
        return origin in _OFFSPRING and self.config.ea.unique_retries > 0

    def pending(self, births: Sequence[Birth]) -> list[tuple[int, ...]]:
        """The distinct genomes of ``births`` that need an evaluation this island has not cached (an
        offspring known to copy a parent needs none: ``_copy``)."""
        return list(dict.fromkeys(b.genome for b in births
                                  if b.evaluation is None and not self.evaluator.holds(b.genome)
                                  and not (self._varied_again(b.origin)
                                           and self._copy(b.kin, b.genome) is not None)))

    def complete(self, generation: int, births: Sequence[Birth],
                 evaluated: Mapping[tuple[int, ...], Evaluation] | None = None) -> list[Individual]:
        """Generation ``generation``: ``births`` evaluated (by ``evaluated`` where it has the genome,
        computed elsewhere; here otherwise) and made individuals, index by index."""
        if self._bred_at is None:
            self.stats = IslandStats(generation=generation)
        before, self._bred_at = self._bred_at or self._counters(), None
        fresh = dict(evaluated or {})
        for genome, made in fresh.items():
            if not self.evaluator.holds(genome):   # evaluated by another host, not here
                self.evaluator.adopt(genome, made)
        members: list[tuple[Genome, str, tuple[str, ...], Evaluation]] = []
        seen: set[str] = set()   # the phenotype digests of this generation so far
        known: list[Kin] = []    # the members so far that a later offspring may be known to copy
        if generation == 0:
            self.founders.restart()
        for index, birth in enumerate(births):
            kept = birth.evaluation
            # The first use of an evaluation made elsewhere keeps its timings, as a local one would.
            genome, origin = birth.genome, birth.origin
            founder = generation == 0 and origin == "random" and self.config.ea.founder_retries > 0
            offspring = self._varied_again(origin)
            # A founder or an offspring that may be drawn or varied again is measured only once
            # what its development found keeps it (Evaluator.preview).
            evaluation = kept if kept is not None else (
                fresh.pop(birth.genome) if birth.genome in fresh else
                self._preview(birth, birth.genome, known) if offspring else
                self.evaluator.preview(birth.genome) if founder else self.evaluate(birth.genome))
            if founder:
                genome, evaluation = self.founders.redraw(index, genome, evaluation, seen)
            elif offspring:
                genome, evaluation, origin = self._revary_offspring(generation, index, birth, evaluation,
                                                                    seen, known)
            if evaluation.valid and evaluation.phenotype_digest is not None:
                seen.add(evaluation.phenotype_digest)
                kin = self._kin_of(evaluation)
                if kin is not None:
                    known.append(kin)
            parents = () if origin == "random" else birth.parents
            members.append((genome, origin, parents, evaluation))
        places = self._placed([evaluation for *_, evaluation in members])
        population = [self._make(generation, index, genome, origin, parents, evaluation, extra)
                      for index, ((genome, origin, parents, evaluation), extra)
                      in enumerate(zip(members, places, strict=True))]
        return self._finish(generation, population, before)

    def _placed(self, evaluations: Sequence[Evaluation]) -> list[dict[str, Any]]:
        """Each member's place in the generation (``evaluations``, index by index), its individual's
        ``extra``: its Pareto front among them (over ``pareto_objectives``) and, in ``map-elites``
        mode, its archive cell."""
        from genr8_dist.evolution.pareto import non_dominated_ranks, objectives_of

        names = pareto_objectives(self.config)
        ranks = non_dominated_ranks(objectives_of([e.criteria for e in evaluations],
                                                  [e.valid for e in evaluations], self.config.fitness,
                                                  names)) if names else [0] * len(evaluations)
        grid = None
        if self.config.search.mode == "map-elites":
            from genr8_dist.evolution.archive import Grid

            grid = Grid.from_settings(self.config.search)
        places = []
        for e, r in zip(evaluations, ranks, strict=True):
            extra: dict[str, Any] = {"pareto_rank": int(r)}
            cell = grid.cell(e) if grid is not None else None
            if cell is not None:
                extra["cell"] = cell
            places.append(extra)
        return places

    @property
    def phenotype(self) -> Phenotype:
        """The phenotype of this island's universe (``genr8_dist.phenotype``)."""
        return self.evaluator.phenotype

    def _revary_offspring(self, generation: int, index: int, birth: Birth, evaluation: Evaluation,
                          seen: set[str], known: Sequence[Kin] = ()) -> tuple[Genome, Evaluation, str]:
        """An offspring that is invalid (its growth capped, say) or whose phenotype repeats a parent's or
        an earlier member's, varied again; still so after ``ea.unique_retries``, replaced by a
        newcomer (origin ``random``, no parents) up to ``ea.unique_redraws`` times."""
        genome, origin = birth.genome, birth.origin

        phenotype = self.phenotype

        def trivial(ev: Evaluation) -> bool:
            measured = not isinstance(ev, Preview) or phenotype.trivial_from_sizes
            return self._varies_trivial and ev.valid and measured and is_trivial(ev, phenotype)

        def wasted(ev: Evaluation) -> bool:
            return not ev.valid or ev.phenotype_digest in seen or ev.phenotype_digest in birth.avoid \
                or trivial(ev)

        def developed_repeat(ev: Evaluation) -> bool:   # decided by the texts, wherever ev was made
            return ev.valid and not trivial(ev) and self._known_copy(birth, genome, known) is None

        rng = None
        trivials = 0   # trivial growths of this offspring so far
        repeats, limit = 0, self.config.ea.repeat_growths   # its developments that repeated a phenotype
        for _ in range(self.config.ea.unique_retries):
            evaluation = settled(self.evaluator, genome, evaluation, wasted)
            if not wasted(evaluation):
                return genome, evaluation, origin
            if limit and developed_repeat(evaluation):
                repeats += 1
                if repeats >= limit:   # its neighbourhood mostly repeats: more growths are wasted
                    self.stats.kept_repeat += 1
                    return genome, self.evaluator.measure(genome, evaluation), origin
            if trivial(evaluation) and evaluation.phenotype_digest not in seen \
                    and evaluation.phenotype_digest not in birth.avoid:
                trivials += 1
                if trivials > _TRIVIAL_RETRIES:   # its first parent's neighbourhood is mostly trivial
                    self.stats.kept_trivial += 1
                    return genome, self.evaluator.measure(genome, evaluation), origin
            if trivial(evaluation):
                self.stats.revaried_trivial += 1
            elif evaluation.valid:
                self.stats.revaried_phenotype += 1
            else:
                self.stats.revaried_invalid += 1
            rng = rng or self.rng(generation, "revary", index)
            base, codons = genome, evaluation.codons_used
            if (trivial(evaluation) or not evaluation.valid) and birth.source is not None:
                # the variation broke what made the parent grow (it no longer splits a region, or
                # its growth ran away): vary the parent anew rather than the broken child
                base, codons = birth.source
            genome = self._screened(partial(self._revary, rng, base, codons), birth.avoid)
            evaluation = self._preview(birth, genome, known)
            if origin == "crossover":
                origin = "crossover+mutation"
        # Still wasted (its neighbourhood all fails or repeats, as round the bare axiom): a newcomer,
        # drawn as a founder is, with no parents.
        evaluation = settled(self.evaluator, genome, evaluation, wasted)
        fresh = None
        for _ in range(self.config.ea.unique_redraws if wasted(evaluation) else 0):
            fresh = fresh or self.rng(generation, "redraw", index)
            genome = tuple(self._screened(partial(self.founders.one, fresh, index)))
            evaluation = settled(self.evaluator, genome, self._preview(birth, genome, known), wasted)
            origin = "random"
            self.stats.redrawn += 1
            if not wasted(evaluation):
                break
        evaluation = self.evaluator.measure(genome, evaluation)
        if wasted(evaluation):
            self.stats.unresolved += 1
        return genome, evaluation, origin

    def run(self, generations: int | None = None) -> list[list[Individual]]:
        """Generations 0..``generations`` (default ``ea.generations``) of this island alone, no
        migration: a convenience for tests, benchmarks and single-island experiments."""
        last = self.config.ea.generations if generations is None else generations
        history = [self.initial()]
        for g in range(1, last + 1):
            history.append(self.step(history[-1], g))
        return history
