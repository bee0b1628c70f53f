"""Generation 0 of an island: founders drawn, screened from their text, and redrawn where wasted.

Founders are random genomes or, with ``ea.init = "ramped"``, ramped half-and-half derivation trees
(``grammar.derivations``); under a universe's own variation, its founder texts. With
``ea.founder_retries`` a founder whose text shows it trivial or a copy of an earlier founder (the
phenotype's ``screen``) is drawn again from its text alone, never grown; one that grows trivial
(invalid, or trivial as its phenotype says: a surface of at most one region, the axiom left as it
was) or repeats an earlier founder's phenotype is drawn again, up to ``ea.founder_retries`` times.
Past the first half of a founder's redraws they are bushy trees (every repetition at least a few
rounds, no edge label born) while those have given live founders at least as often as plain draws
in this generation 0, so a universe whose random genomes seldom subdivide (``gecco``) still starts
alive. Every draw comes from a named stream of generation 0 (``genomes``, ``screen``, ``founders``).
"""

from __future__ import annotations

from collections.abc import Callable, Container
from functools import partial
from typing import TYPE_CHECKING

from genr8_dist.evolution.evaluate import Evaluation, Evaluator, Preview
from genr8_dist.evolution.operators import Genome, Tally, random_genome
from genr8_dist.evolution.variation import Variation, text_genome

if TYPE_CHECKING:
    import numpy as np

    from genr8_dist.config import RunConfig
    from genr8_dist.phenotype import Phenotype

__all__ = ["Founders", "is_trivial", "settled"]

# Draws again from ``draw`` while the text shows the genome wasted or its key is in ``avoid``.
Screened = Callable[[Callable[[], Genome], Container[str | None]], Genome]
# The generator of generation 0 for a purpose and keys (``Island.rng`` at generation 0).
Streams = Callable[..., "np.random.Generator"]


def is_trivial(evaluation: Evaluation, phenotype: Phenotype | None = None) -> bool:
    """Whether an evaluation is not worth a founder's place: invalid, or trivial as its universe's
    ``phenotype`` says (default the surfaces': at most one region, the axiom polygon as it was or
    grown without a subdivision)."""
    from genr8_dist.phenotype import SURFACES

    return not evaluation.valid or (phenotype or SURFACES).trivial(evaluation)


def settled(evaluator: Evaluator, genome: Genome, evaluation: Evaluation,
            wasted: Callable[[Evaluation], bool]) -> Evaluation:
    """``evaluation`` of ``genome`` measured, unless it is a preview that what its development
    found already wastes (``wasted`` of a preview never says no where the measured evaluation
    would say yes: a preview's ``valid`` only lacks what measuring may still fail)."""
    if isinstance(evaluation, Preview) and not wasted(evaluation):
        return evaluator.measure(genome, evaluation)
    return evaluation


def _rate(tally: list[int]) -> float:
    """Laplace's estimate of the share of live founders among ``[draws, live]``."""
    return (tally[1] + 1) / (tally[0] + 2)


class _Draws:
    """``first``, then what ``more`` draws: a founder as drawn, then its redraws."""

    def __init__(self, first: Genome, more: Callable[[], Genome]) -> None:
        self.first: Genome | None = first
        self.more = more

    def __call__(self) -> Genome:
        if self.first is not None:
            first, self.first = self.first, None
            return first
        return self.more()


class Founders:
    """The founders of one island: drawn (``draw``, ``genomes``) and redrawn (``redraw``), with the
    tally of plain and bushy draws of the generation 0 being completed."""

    def __init__(self, config: RunConfig, evaluator: Evaluator, variation: Variation | None,
                 rng: Streams, screened: Screened, count: Tally) -> None:
        self.config = config
        self.evaluator = evaluator
        self.variation = variation
        self.rng = rng            # (purpose, *keys) -> generation 0's stream
        self.screened = screened  # the island's screen before growth
        self.count = count        # adds to an ``IslandStats`` counter
        self.tally: dict[str, list[int]] = {}
        self.restart()

    def restart(self) -> None:
        """Forgets the draws counted so far: a generation 0 begins."""
        self.tally = {"plain": [0, 0], "bushy": [0, 0]}

    def draw(self, rng: np.random.Generator, count: int, first: int = 0) -> list[Genome]:
        """``count`` founder genomes drawn from ``rng`` (``ea.init``); ``first``: the position of the
        first in the ramp of depth limits."""
        g = self.config.genome
        if self.variation is not None:
            return [text_genome(self.variation.founder(rng)) for _ in range(count)]
        if self.config.ea.init == "ramped":
            from genr8_dist.grammar.derivations import ramped_genomes

            return ramped_genomes(self.evaluator.universe, rng, count, length=g.length,
                                  codon_max=g.codon_max, max_depth=g.max_depth, first=first)
        return [random_genome(rng, g.length, g.codon_max) for _ in range(count)]

    def one(self, rng: np.random.Generator, index: int) -> Genome:
        """One founder genome drawn from ``rng`` at position ``index`` of generation 0."""
        return self.draw(rng, 1, first=index)[0]

    def genomes(self, count: int, key: Callable[[Genome], str | None]) -> list[Genome]:
        """Generation 0's genomes: ``count`` founders (``ea.init``); with ``ea.founder_retries``,
        one whose text shows it trivial or a copy of an earlier founder (``key``: its screen key) is
        drawn again from its text alone (each founder's own stream ``screen``), never grown."""
        drawn = self.draw(self.rng("genomes"), count)
        if self.config.ea.founder_retries <= 0:
            return [tuple(genome) for genome in drawn]
        genomes: list[Genome] = []
        keys: set[str | None] = set()
        for index, first in enumerate(drawn):
            rest = _Draws(first, partial(self.one, self.rng("screen", index), index))
            genome = tuple(int(c) for c in self.screened(rest, keys))
            keys.add(key(genome))
            genomes.append(genome)
        return genomes

    def redraw(self, index: int, genome: Genome, evaluation: Evaluation, seen: set[str]
               ) -> tuple[Genome, Evaluation]:
        """A founder that is trivial or repeats an earlier founder's phenotype, drawn again: the first
        half of ``ea.founder_retries`` (rounded up) as ``ea.init`` says; each later one as a bushy
        derivation tree (``grammar.derivations.bushy_genome``: longer repetitions, no edge label born)
        unless plain draws have so far given this generation 0 live founders more often (Laplace's rule
        over the draws of the founders before, so a universe where bushy trees fail keeps its plain
        draws). Bushy trees cost more growth, so they come only where plain draws keep failing."""
        phenotype = self.evaluator.phenotype

        def wasted(ev: Evaluation) -> bool:
            if isinstance(ev, Preview) and not phenotype.trivial_from_sizes:
                return not ev.valid or ev.phenotype_digest in seen
            return is_trivial(ev, phenotype) or ev.phenotype_digest in seen

        rng = None
        retries = self.config.ea.founder_retries
        plain = (retries + 1) // 2
        tally = self.tally   # kind -> [draws, live ones] in this generation 0 so far
        kind = "plain"       # the founder as born is a plain draw
        for attempt in range(retries):
            evaluation = settled(self.evaluator, genome, evaluation, wasted)
            tally[kind][0] += 1
            if not wasted(evaluation):
                tally[kind][1] += 1
                return genome, evaluation
            rng = rng or self.rng("founders", index)
            kind = "plain" if attempt < plain or _rate(tally["plain"]) > _rate(tally["bushy"]) \
                or self.variation is not None else "bushy"
            if kind == "plain":
                genome = tuple(self.screened(partial(self.one, rng, index), ()))
            else:   # plain draws keep failing: bushy trees over the labels a derivation starts with
                from genr8_dist.grammar.derivations import bushy_genome

                g = self.config.genome
                genome = tuple(self.screened(partial(
                    bushy_genome, self.evaluator.universe, rng, length=g.length, codon_max=g.codon_max,
                    max_depth=g.max_depth), ()))
            evaluation = self.evaluator.preview(genome)
            self.count("founders_redrawn", 1)
        evaluation = self.evaluator.measure(genome, evaluation)
        tally[kind][0] += 1
        if wasted(evaluation):
            self.count("unresolved", 1)
        else:
            tally[kind][1] += 1
        return genome, evaluation
