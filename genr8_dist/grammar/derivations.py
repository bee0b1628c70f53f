"""Random derivation trees of a universe, written straight into genomes (sensible initialisation).

GE's *sensible initialisation* (Ryan and Azad 2003; PonyGE2, GRAPE) draws founders as derivation trees
rather than as random codons: half of them *grow* (any alternative that still fits the depth limit),
half are *full* (the deepest alternatives that fit, so every branch reaches the limit), with the
limit ramped from shallow to ``max_depth`` across the population. A random genome, by contrast, picks
the terminating alternative as often as the recursive one, and most founders come out small.

This module walks a universe's compiled grammar exactly as the GE mapper reads codons
(:mod:`genr8_dist.grammar.mapper`: a codon per rule expansion and per inline choice, ``codon mod
n`` among the alternatives eligible at the *mapper's* ``max_depth``; a codon per option and per
repetition round; a codon per edge label drawn), choosing each alternative by the tree's own policy and
writing the codon that makes the mapper take it (``index + n * r``, ``r`` random, so the codons
look like any others); numbers and edge labels take a random codon, as a random genome would. The
derivation is followed by random codons up to the genome's length (a repair rule, if the universe
has one, reads them). It needs nothing but the grammar: it works for every universe, built-in or
plugin. A ``DerivationSample`` keeps the tokens the sampler meant, so tests check that the mapper
reads the genome the same way.

``bushy_genome`` draws a *bushy* grown tree: every repetition takes at least a number of rounds drawn
from ``0..rounds``, and no edge label is born (every edge takes one of the two labels a derivation
starts with). More rules, items and branches over fewer labels make branches that can join far more
likely: it is what the island falls back on when a founder's plain redraws stay trivial
(``evolution.island``); in ``gecco``, whose random genomes subdivide about once in a thousand, 30% of
bushy trees subdivide, each into a different surface.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from genr8_dist.grammar.compiler import Alternatives, Node
from genr8_dist.grammar.mapper import eligible
from genr8_dist.grammar.universe import Universe

__all__ = ["DerivationSample", "bushy_genome", "ramped_genomes", "sample_derivation"]

METHODS = ("grow", "full")


@dataclass(slots=True)
class DerivationSample:
    """One sampled derivation: the codons that produce it and the tokens it emits (main derivation,
    repair not included)."""

    codons: list[int] = field(default_factory=list)
    tokens: list[str] = field(default_factory=list)
    height: int = 0


class _Sampler:
    def __init__(self, universe: Universe, rng: np.random.Generator, max_depth: int, limit: int,
                 method: str, codon_max: int, births: bool = True, rounds: int = 0) -> None:
        self.cg = universe.grammar
        self.rng = rng
        self.maxd = max_depth
        self.limit = min(limit, max_depth)
        self.full = method == "full"
        self.births = births
        self.rounds = rounds
        self.codon_max = codon_max
        self.out = DerivationSample()
        self.count = 2
        self.tables = [t for t in self.cg.templates]
        self.budget = 20_000   # codons: a derivation longer than this is cut (the mapper would wrap)

    # -- codons ------------------------------------------------------------------------------

    def write(self, residue: int, modulus: int) -> int:
        """Append a codon ``c`` with ``c % modulus == residue`` (uniform among those <= codon_max)."""
        top = (self.codon_max - residue) // modulus
        codon = residue + modulus * int(self.rng.integers(0, top, endpoint=True)) if top > 0 else residue
        self.out.codons.append(int(codon))
        self.budget -= 1
        if self.budget < 0:
            raise OverflowError("derivation too long")
        return codon

    def any_codon(self) -> int:
        codon = int(self.rng.integers(0, self.codon_max, endpoint=True))
        self.out.codons.append(codon)
        self.budget -= 1
        return codon

    # -- the walk ----------------------------------------------------------------------------

    def pick(self, alts: Alternatives, depth: int) -> Node:
        """Choose among ``alts`` at ``depth`` and write the codon the mapper reads for it."""
        if len(alts) == 1:
            self.any_codon()
            return alts[0]
        reads = eligible(self.cg, alts, depth, self.maxd)
        mine = eligible(self.cg, alts, depth, self.limit)
        if self.full:
            deepest = max(self.cg.alt_need(alts[i]) for i in mine)
            mine = tuple(i for i in mine if self.cg.alt_need(alts[i]) == deepest)
        options = [i for i in mine if i in reads] or list(reads)
        chosen = options[int(self.rng.integers(0, len(options)))]
        self.write(reads.index(chosen), len(reads))
        return alts[chosen]

    def rule(self, name: str, depth: int) -> None:
        self.out.height = max(self.out.height, depth)
        alt = self.pick(self.cg.rules[name], depth)
        self.node(alt, depth, {})

    def fits(self, node: Node, depth: int, limit: int) -> bool:
        need = self.cg.alt_need(node)
        return need == 0 or depth + need <= limit

    def label(self) -> int:
        if not self.births:   # one of the labels there are: the mapper's codon mod (count + 1) < count
            return self.write(int(self.rng.integers(0, self.count)), self.count + 1) % (self.count + 1)
        lab = self.any_codon() % (self.count + 1)
        if lab == self.count:
            self.count += 1
        return lab

    def node(self, node: Node, depth: int, scope: dict[str, int]) -> None:
        kind = node[0]
        if kind == "lit":
            self.out.tokens.append(node[1])
        elif kind == "edge":
            _, mode, template, letter = node
            if mode in ("P", "C"):
                lab = self.any_codon() % self.count
            elif mode == "L":
                lab = self.label()
            else:
                if letter not in scope:
                    scope[letter] = self.label()
                lab = scope[letter]
            self.out.tokens.append(self.tables[template].text(lab))
        elif kind == "num":
            values = node[1]
            self.out.tokens.append(values[self.any_codon() % len(values)])
        elif kind == "rule":
            self.rule(node[1], depth + 1)
        elif kind == "seq":
            for item in node[1]:
                self.node(item, depth, scope)
        elif kind == "choice":
            self.node(self.pick(node[1], depth), depth, scope)
        elif kind == "opt":
            if not self.fits(node[1], depth, self.maxd):
                self.any_codon()
                return
            emit = self.fits(node[1], depth, self.limit) and (self.full or bool(self.rng.integers(0, 2)))
            self.write(int(emit), 2)
            if emit:
                self.node(node[1], depth, scope)
        elif kind == "rep":
            inner, x, plus = node[1], node[2], node[3]
            if plus:
                self.node(inner, depth, scope)
            if not self.fits(inner, depth, self.maxd):
                self.any_codon()
                return
            mine = self.fits(inner, depth, self.limit)
            # A bushy tree takes at least ``least`` rounds, then goes on by the natural chance.
            bushy = self.rounds and mine and not self.full
            least = int(self.rng.integers(0, self.rounds + 1)) if bushy else 0
            c = 0
            while True:
                m = c + x
                if c < least and c < self.codon_max:
                    self.write(int(self.rng.integers(c + 1, min(m, self.codon_max + 1))), m)   # another round
                    self.node(inner, depth, scope)
                    c += 1
                    continue
                # A grown tree takes another round by the natural chance (m - c - 1) / m; a full
                # one takes at least X rounds.
                # No codon above codon_max exists: past round codon_max every codon stops the repetition.
                if not mine or (self.full and c < x and c >= self.codon_max):
                    self.write(int(self.rng.integers(0, min(c, self.codon_max) + 1)), m)   # stop
                    break
                if self.full and c < x:
                    self.write(int(self.rng.integers(c + 1, min(m, self.codon_max + 1))), m)   # another round
                elif self.any_codon() % m <= c:
                    break
                self.node(inner, depth, scope)
                c += 1
        else:  # pragma: no cover - the compiler makes no other kind
            raise AssertionError(kind)


def sample_derivation(universe: Universe, rng: np.random.Generator, *, max_depth: int, limit: int,
                      method: str, codon_max: int, births: bool = True, rounds: int = 0
                      ) -> DerivationSample:
    """One derivation of ``universe`` drawn by ``method`` (``"grow"`` or ``"full"``) with its depth
    limited to ``limit`` (at most ``max_depth``, the mapper's), as codons for a mapper at ``max_depth``.
    With ``births=False`` no edge label is born; with ``rounds`` (grow) every repetition takes at least
    a number of rounds drawn from ``0..rounds``."""
    if method not in METHODS:
        raise ValueError(f"method must be one of {', '.join(METHODS)}, got {method!r}")
    sampler = _Sampler(universe, rng, max_depth, limit, method, codon_max, births, rounds)
    sampler.rule(sampler.cg.start, 1)
    return sampler.out


def _padded(universe: Universe, rng: np.random.Generator, *, length: int, codon_max: int,
            max_depth: int, limit: int, method: str, births: bool = True, rounds: int = 0
            ) -> tuple[int, ...]:
    """One derivation's codons followed by random codons up to ``length`` (a derivation too long to
    sample leaves only the random codons)."""
    try:
        codons = sample_derivation(universe, rng, max_depth=max_depth, limit=limit, method=method,
                                   codon_max=codon_max, births=births, rounds=rounds).codons
    except OverflowError:
        codons = []
    tail = max(0, length - len(codons))
    return tuple(codons + [int(c) for c in rng.integers(0, codon_max, size=tail, endpoint=True)])


BUSHY_ROUNDS = 8


def bushy_genome(universe: Universe, rng: np.random.Generator, *, length: int, codon_max: int,
                 max_depth: int, rounds: int = BUSHY_ROUNDS) -> tuple[int, ...]:
    """A genome of a grown tree at ``max_depth`` whose every repetition takes at least a number of
    rounds drawn from ``0..rounds`` and in which no edge label is born, followed by random codons up
    to ``length`` (a longer derivation keeps its own length). Every draw from ``rng``."""
    return _padded(universe, rng, length=length, codon_max=codon_max, max_depth=max_depth,
                   limit=max_depth, method="grow", births=False, rounds=rounds)


def ramped_genomes(universe: Universe, rng: np.random.Generator, count: int, *, length: int,
                   codon_max: int, max_depth: int, first: int = 0) -> list[tuple[int, ...]]:
    """``count`` genomes of ramped half-and-half derivations: the depth limit cycles from the
    shallowest the grammar allows to ``max_depth``, and at each limit alternately grow and full
    (``first``: the position in that cycle of the first genome).
    Each derivation is followed by random codons up to ``length``; one longer than ``length`` keeps
    its own length. Every draw comes from ``rng``."""
    lowest = min(max_depth, universe.grammar.min_depth.get(universe.grammar.start, 1))
    limits = list(range(max(1, lowest), max_depth + 1))
    genomes = []
    for i in range(first, first + count):
        limit = limits[(i // 2) % len(limits)]
        genomes.append(_padded(universe, rng, length=length, codon_max=codon_max, max_depth=max_depth,
                               limit=limit, method=METHODS[i % 2]))
    return genomes
