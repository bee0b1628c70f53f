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
3. elites: the best ``ea.elites`` of generation g-1 with finite fitness, copied (origin ``elite``);
4. offspring until the population is full: two parents by tournament, one-point crossover with
   probability ``ea.crossover_rate``, then int-flip mutation of each codon with probability
   ``ea.mutation_rate`` (a child that was not crossed over is mutated at least once, so no offspring is a
   silent copy). Origin ``crossover``, ``mutation`` or ``crossover+mutation``; parents the ids used.

A designer's hand-set fitness (``hand``) replaces the computed one of a marked individual for the
choice of elites and parents of generation g; a marked individual not of generation g-1 joins the pool.

Individuals of generation g-1 evaluated under another ``config_version`` (the fitness, the environment
or the universe changed: an intervention) are re-evaluated before selection, so they compete under the
configuration now in force. Identical genomes are evaluated once (``Evaluator``'s cache).

A generation is built in two parts: ``breed`` draws every genome with its origin and parents (cheap,
sequential, seeded), then ``complete`` evaluates the genomes not yet evaluated and makes the
individuals. Evaluation is a pure function of (genome, configuration), so the genomes ``pending``
evaluation may be evaluated anywhere (an island host shares them with idle hosts) and passed to
``complete``: the generation is the same as ``step`` builds alone.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from genr8_dist.errors import ConfigError
from genr8_dist.evolution.evaluate import Evaluation, Evaluator
from genr8_dist.evolution.individual import Individual
from genr8_dist.evolution.operators import (
    int_flip_mutation,
    one_point_crossover,
    random_genome,
    select_elites,
    tournament_select,
)
from genr8_dist.rng import stream

__all__ = ["Birth", "Injected", "Island", "IslandStats"]

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


@dataclass(frozen=True, slots=True)
class Birth:
    """An individual of a generation before evaluation: its genome, how it came to be, and its
    evaluation when already known (a migrant or elite kept as it was), else ``None``."""

    genome: tuple[int, ...]
    origin: str
    parents: tuple[str, ...] = ()
    evaluation: Evaluation | None = None


class Island:
    """One island of a run: ``initial()`` builds generation 0, ``step()`` each next generation."""

    def __init__(self, config: Any, island_index: int, config_version: int = 1, *,
                 evaluator: Evaluator | None = None) -> None:
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
        self.stats = IslandStats()
        self._bred_at: tuple[int, int, int] | None = None   # the evaluator's counters when breeding began
        self.hooks: list[Callable[[list[Individual]], None]] = []

    # -- random streams -----------------------------------------------------------------------

    def rng(self, generation: int, purpose: str):
        """The generator for ``purpose`` in ``generation`` of this island."""
        return stream(self.config.seed, "island", self.index, "generation", generation, purpose)

    # -- building individuals -----------------------------------------------------------------

    def evaluate(self, genome: Sequence[int]) -> Evaluation:
        """The evaluation of ``genome`` under this island's configuration (cached)."""
        return self.evaluator.evaluate(genome)

    def _make(self, generation: int, index: int, genome: Sequence[int], origin: str,
              parents: tuple[str, ...], evaluation: Evaluation) -> Individual:
        return Individual(island=self.index, generation=generation, index=index,
                          genome=tuple(int(c) for c in genome), origin=origin, parents=parents,
                          config_version=self.config_version, **evaluation.as_fields())

    def _kept(self, individual: Individual) -> Evaluation:
        """The evaluation of an individual carried over: kept when made under this configuration."""
        if individual.config_version == self.config_version:
            fields = {name: getattr(individual, name) for name in Evaluation.__dataclass_fields__}
            return Evaluation(**fields).untimed()
        return self.evaluate(individual.genome)

    def _finish(self, generation: int, population: list[Individual], before: tuple[int, int, int]
                ) -> list[Individual]:
        ev = self.evaluator
        self.stats = IslandStats(
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

    def _injected_genome(self, item: Injected) -> tuple[tuple[int, ...], tuple[str, ...]]:
        if isinstance(item, Individual):
            return tuple(item.genome), (item.id,)
        if isinstance(item, str):
            genome = self.evaluator.universe.invert(item, max_depth=self.config.genome.max_depth)
            return tuple(int(c) for c in genome), ()
        return tuple(int(c) for c in item), ()

    def breed(self, generation: int, previous: Sequence[Individual] = (),
              migrants: Sequence[Individual] = (), injected: Sequence[Injected] = (),
              hand: Sequence[tuple[Individual, float]] = ()) -> list[Birth]:
        """The genomes of ``generation`` in index order, unevaluated where new: generation 0 random,
        a later one from ``previous`` (generation ``generation - 1``), ``migrants`` and ``injected``.
        ``hand`` pairs an individual with the fitness a designer gave it: it competes for elite places
        and tournaments with that fitness (added to the pool when it is not of ``previous``)."""
        self._bred_at = self._counters()
        ea = self.config.ea
        g = self.config.genome
        if generation == 0:
            rng = self.rng(0, "genomes")
            return [Birth(tuple(random_genome(rng, g.length, g.codon_max)), "random")
                    for _ in range(ea.population)]
        if not previous:
            raise ValueError(f"generation {generation} needs a non-empty previous generation")
        if len(migrants) + len(injected) > ea.population:
            raise ConfigError(
                f"{len(migrants)} migrants and {len(injected)} injected individuals do not fit in a "
                f"population of {ea.population} (ea.population)"
            )
        births = [Birth(tuple(m.genome), "migrant", (m.id,), self._kept(m)) for m in migrants]
        for item in injected:
            genome, parents = self._injected_genome(item)
            births.append(Birth(genome, "injected", parents))

        # Generation g-1 as it competes now: re-evaluated where its configuration was another one.
        pool = [p if p.config_version == self.config_version
                else self._make(p.generation, p.index, p.genome, p.origin, p.parents, self.evaluate(p.genome))
                for p in previous]
        parent_ids = [p.id for p in previous]
        fitnesses = [p.fitness for p in pool]
        for marked, fitness in hand:
            if marked.id in parent_ids:
                fitnesses[parent_ids.index(marked.id)] = float(fitness)
                continue
            pool.append(marked if marked.config_version == self.config_version
                        else self._make(marked.generation, marked.index, marked.genome, marked.origin,
                                        marked.parents, self.evaluate(marked.genome)))
            parent_ids.append(marked.id)
            fitnesses.append(float(fitness))

        room = ea.population - len(births)
        for i in select_elites(fitnesses, min(ea.elites, room)):
            births.append(Birth(tuple(pool[i].genome), "elite", (parent_ids[i],), self._kept(pool[i])))

        select_rng = self.rng(generation, "selection")
        cross_rng = self.rng(generation, "crossover")
        mutate_rng = self.rng(generation, "mutation")
        while len(births) < ea.population:
            a = tournament_select(select_rng, fitnesses, ea.tournament)
            b = tournament_select(select_rng, fitnesses, ea.tournament)
            crossed = bool(cross_rng.random() < ea.crossover_rate)
            if crossed:
                children = one_point_crossover(cross_rng, pool[a].genome, pool[b].genome)
                lineage = ((parent_ids[a], parent_ids[b]), (parent_ids[b], parent_ids[a]))
            else:
                children = (pool[a].genome, pool[b].genome)
                lineage = ((parent_ids[a],), (parent_ids[b],))
            for child, parents in zip(children, lineage, strict=True):
                if len(births) >= ea.population:
                    break
                genome, flipped = int_flip_mutation(mutate_rng, child, ea.mutation_rate, g.codon_max,
                                                    at_least_one=not crossed)
                origin = ("crossover+mutation" if flipped else "crossover") if crossed else "mutation"
                births.append(Birth(tuple(int(c) for c in genome), origin, parents))
        return births

    def pending(self, births: Sequence[Birth]) -> list[tuple[int, ...]]:
        """The distinct genomes of ``births`` that need an evaluation this island has not cached."""
        return list(dict.fromkeys(b.genome for b in births
                                  if b.evaluation is None and not self.evaluator.holds(b.genome)))

    def complete(self, generation: int, births: Sequence[Birth],
                 evaluated: Mapping[tuple[int, ...], Evaluation] | None = None) -> list[Individual]:
        """Generation ``generation``: ``births`` evaluated (by ``evaluated`` where it has the genome,
        computed elsewhere; here otherwise) and made individuals, index by index."""
        before, self._bred_at = self._bred_at or self._counters(), None
        fresh = dict(evaluated or {})
        for genome, evaluation in fresh.items():
            if not self.evaluator.holds(genome):   # evaluated by another host, not here
                self.evaluator.adopt(genome, evaluation)
        population = []
        for index, birth in enumerate(births):
            evaluation = birth.evaluation
            if evaluation is None:
                # The first use of an evaluation made elsewhere keeps its timings, as a local one would.
                evaluation = fresh.pop(birth.genome, None) or self.evaluate(birth.genome)
            population.append(self._make(generation, index, birth.genome, birth.origin, birth.parents,
                                         evaluation))
        return self._finish(generation, population, before)

    def run(self, generations: int | None = None) -> list[list[Individual]]:
        """Generations 0..``generations`` (default ``ea.generations``) of this island alone, no
        migration: a convenience for tests, benchmarks and single-island experiments."""
        last = self.config.ea.generations if generations is None else generations
        history = [self.initial()]
        for g in range(1, last + 1):
            history.append(self.step(history[-1], g))
        return history
