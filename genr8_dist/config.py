"""The run configuration: one TOML file that says everything a run needs.

::

    universe = "default"          # the BNF the genomes are mapped with
    seed = 1                      # the run seed every random draw derives from

    [fitness.size]                # target, weight (and scale) per criterion: see genr8_dist.fitness
    [environment]                 # inline (genr8_dist.environment's format), or
    # environment = "env.toml"    # a path, resolved relative to this file
{sections}

Every section is a frozen dataclass whose fields are declared once (``fields.setting``: default,
range or choices, help) and validated when it is built; a section or key left out takes its default;
an unknown key, a wrong type, an out-of-range value, an unknown universe or a missing environment file
is a ``ConfigError`` naming the file and the field. ``docs/run-config.md`` lists every field with its
default and meaning: its tables are ``section_table(name)``'s (a test keeps them equal).
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypeVar

from genr8_dist.environment import Environment, load_environment
from genr8_dist.errors import ConfigError, Genr8Error
from genr8_dist.fields import check_settings, fail, read_float, read_int, read_rate, setting, settings_table
from genr8_dist.fitness import SURFACE, FitnessSpec
from genr8_dist.grammar.source import UniverseSource
from genr8_dist.meshings import MESHING, check_meshing
from genr8_dist.phenotype import descriptor_sizes
from genr8_dist.run_universe import check_source, phenotype_kind, resolve_universe
from genr8_dist.run_universe import run_phenotype as run_phenotype  # the store's import of it
from genr8_dist.tomlfile import read_toml

if TYPE_CHECKING:
    from _typeshed import DataclassInstance

__all__ = [
    "EMIGRANTS",
    "INITS",
    "SEARCH_MODES",
    "TOPOLOGIES",
    "VARIATIONS",
    "EASettings",
    "GenomeSettings",
    "IslandSettings",
    "RunConfig",
    "SearchSettings",
    "load_config",
    "section_table",
    "top_table",
]

TOPOLOGIES: tuple[str, ...] = ("ring", "full", "random")
INITS: tuple[str, ...] = ("random", "ramped")
VARIATIONS: tuple[str, ...] = ("auto", "ge")   # genr8_dist.evolution.variation
SEARCH_MODES: tuple[str, ...] = ("weighted", "pareto", "map-elites")
EMIGRANTS: tuple[str, ...] = ("best", "novel")


# The field validators are genr8_dist.fields' (one family for every configuration file); a run
# configuration's messages name the field alone, the caller adds the file.
def _fail(path: str, message: str) -> ConfigError:
    return fail("", path, message)


def _number(value: object, path: str) -> float:
    try:
        return read_float(value, "", path)
    except ConfigError:
        raise _fail(path, f"must be a finite number, got {value!r}") from None


def _set(obj: object, name: str, value: object) -> None:
    object.__setattr__(obj, name, value)


@dataclass(frozen=True, slots=True)
class GenomeSettings:
    """The integer genomes: how many codons, their range, and how the GE mapper may read them."""

    length: int = setting(
        100, (
            "codons in a random genome (generation 0); a derivation tree longer than this "
            "(`ea.init = \"ramped\"`, a bushy founder redraw) keeps its own length; crossover keeps"
            " lengths"
        ),
        minimum=1, maximum=100_000)
    codon_max: int = setting(
        255, "codons are drawn from `0..codon_max` (inclusive), at generation 0 and by mutation",
        minimum=1, maximum=2**31 - 1)
    max_depth: int = setting(
        5, (
            "the deepest the GE derivation tree may grow; near it, only alternatives that can "
            "finish are eligible"
        ),
        minimum=1, maximum=100)
    max_wraps: int = setting(
        2, (
            "how often the mapper may wrap around the genome; past that the individual is invalid"
            " (stage `map`)"
        ),
        minimum=0, maximum=1000)

    def __post_init__(self) -> None:
        check_settings(self, "genome")

#: The screen before growth new runs use (``ea.screen``); a run created before it was recorded keeps 1.
SCREEN = 3


@dataclass(frozen=True, slots=True)
class EASettings:
    """The evolutionary algorithm of one island: generational, tournament selection, elitism,
    one-point crossover and int-flip mutation."""

    population: int = setting(
        30, "individuals per island per generation (>= 2)",
        minimum=2, maximum=1_000_000)
    generations: int = setting(20, "the run goes from generation 0 (random) to this generation", minimum=0)
    tournament: int = setting(
        3, (
            "contestants per tournament (1..population); the lowest fitness wins, ties to the "
            "lower index"
        ),
        minimum=1, maximum=lambda ea: ea.population)
    elites: int = setting(
        1, "best valid individuals copied unchanged into the next generation (0..population-1)",
        minimum=0, maximum=lambda ea: ea.population - 1)
    crossover_rate: float = setting(
        0.9, "probability that a pair of parents is crossed over (one-point)",
        rate=True)
    mutation_rate: float = setting(
        0.02, (
            "probability that each codon of a child is redrawn (int-flip); a child that was not "
            "crossed over is always mutated at least once"
        ),
        rate=True)
    init: str = setting(
        "random", (
            "founders of generation 0: `\"random\"` genomes, or `\"ramped\"`: ramped half-and-half "
            "derivation trees of the universe (GE's sensible initialisation: the depth limit "
            "cycles from shallow to `genome.max_depth`, alternately *grow* and *full*), written "
            "into genomes codon for codon; works for every universe"
        ),
        choices=INITS)
    founder_retries: int = setting(
        20, (
            "a founder that is trivial (invalid, or a surface of at most one region: the axiom "
            "polygon left as it was) or whose surface repeats an earlier founder's is drawn again"
            " (one whose text already shows it, with no rule that can fire drawing a branch or "
            "with another founder's effective text, is drawn again before it is grown, up to 20 "
            "times a draw: `IslandStats.screened`, no evaluation spent), up to this many times "
            "(0: never): the first half of them (rounded up) as `init` says; each later one as a "
            "*bushy* derivation tree (every repetition at least 0-8 rounds, drawn uniformly, and "
            "no edge label born: fewer labels and more branches make joins likely) unless plain "
            "draws have given this generation 0 live founders more often so far (Laplace's rule),"
            " so a universe whose random genomes seldom subdivide starts alive too (`gecco`: 0.98"
            " of 200 founders trivial without them, 0.04 with them, 13.6 redraws per founder; "
            "`bench/search.py`) and one where bushy trees fail keeps its plain draws"
        ),
        minimum=0, maximum=1000)
    unique_retries: int = setting(
        10, (
            "an offspring whose rewrite system or surface repeats a parent's or an earlier "
            "member's of its generation, or that is invalid (maps to no rewrite system, or its "
            "growth is capped) or trivial (a surface of one region; under `screen = 1` in "
            "`weighted` mode only: a "
            "Pareto front or a MAP-Elites archive may want it; a child trivial again after one "
            "re-variation is kept), is mutated again (at least one "
            "codon the mapper read; a trivial or capped child's first parent is mutated anew "
            "instead, since its own variation broke what made the parent grow; a text that shows "
            "before growth that it is trivial or a copy, by its effective text, is varied again "
            "without being grown, and one whose text differs from a parent's only where the "
            "parent's growth read nothing, so it would grow the parent's surface, is varied again "
            "as that repeat is, without being grown: `IslandStats.copied`), up to this many times, "
            "so no evaluation is spent on a copy or "
            "a failure that a small change avoids (one still invalid after every retry is kept: "
            "failures are data); the second parent is drawn again (up to 5 times) while it is the"
            " first one or has its text (0: neither)"
        ),
        minimum=0, maximum=1000)
    unique_redraws: int = setting(
        3, (
            "an offspring still invalid or repeating after `unique_retries` re-variations (its "
            "whole neighbourhood fails or repeats, as round a bare axiom) is replaced by a "
            "newcomer drawn as a founder is (origin `random`, no parents), up to this many times "
            "(0, or `unique_retries = 0`: never); `IslandStats.redrawn` counts them"
        ),
        minimum=0, maximum=1000)
    repeat_growths: int = setting(
        0, (
            "the developments an offspring may spend on repeats: once this many of its tries, "
            "developed, repeated a parent's or an earlier member's phenotype, the last one is kept "
            "(a new text with a known phenotype: the neutral drift a generative encoding searches "
            "by); tries known to repeat before development (`Phenotype.copies`, the screen's key) "
            "spend none and are varied again as `unique_retries` says (0: no bound; "
            "examples/tables.toml sets 1 and `unique_redraws = 0`: 1.11 evaluations per stored "
            "table, against 2.6)"
        ),
        minimum=0, maximum=1000)
    screen: int = setting(
        SCREEN, (
            "what a text must show before growth for a founder or offspring to be drawn or varied "
            "again without growing it (`hemls.splitting`; `IslandStats.screened`, no evaluation "
            "spent): `1` no rule that can fire draws a branch (no region can ever split), or its "
            "effective text repeats another's; an offspring that shows or grows trivial is varied "
            "again in `weighted` mode only, one that shows it from itself; `2` also a rewrite "
            "system whose growth, replayed on its edges' labels and ends without geometry, never "
            "holds two branches of one label at two vertices pointing into the seed polygon in one "
            "step (no join can happen: one region in any environment; `tiles` random genomes: 48 "
            "of 134 grown-trivial texts caught, none wrongly); an offspring that shows or grows "
            "trivial is varied again from its first parent, in every mode; `3` also a rewrite "
            "system whose edges multiply so fast that every growth of it spends more than the "
            "environment's `max_work` (`hemls.budget.least_work`: it would be capped). A new run "
            "records the screen it uses; runs created before it was recorded keep 1"
        ),
        minimum=1, maximum=SCREEN)
    within_used: bool = setting(
        False, (
            "crossover cuts and mutation flips only within the codons the mapper read (PonyGE2's "
            "*within used*)"
        ))
    variation: str = setting(
        "auto", (
            "`\"auto\"`: a universe whose `hooks.py` declares its own genome and operators "
            "(`VARIATION`: the tables universes, Hornby & Pollack's structural mutation and "
            "recombination) evolves with them, its genome the text's characters; every other "
            "universe, and any under `\"ge\"`, with GE's (int genomes, one-point crossover, "
            "int-flip). Under a universe's variation each offspring is one child, recombined with "
            "probability `crossover_rate` (the paper: 0.5), else mutated; `mutation_rate`, "
            "`genome.*`, `init` and `within_used` play no part (docs/phenotypes.md)"
        ),
        choices=VARIATIONS)

    def __post_init__(self) -> None:
        check_settings(self, "ea")

@dataclass(frozen=True, slots=True)
class IslandSettings:
    """How many islands, and how individuals migrate between them."""

    count: int = setting(
        1, "islands, each evolving its own population (one Ray actor each in a distributed run)",
        minimum=1, maximum=10_000)
    migration_interval: int = setting(
        5, (
            "generations between migrations: after generation g with g % interval == 0 the best "
            "individuals of g move to the destination's generation g+1"
        ),
        minimum=1)
    migrants: int = setting(
        2, "individuals each island sends at a migration: its best (must be < `ea.population`)",
        minimum=0)
    topology: str = setting(
        "ring", (
            "`ring`: island i sends to i+1; `full`: every island sends to every other and each "
            "keeps the best `migrants` arriving; `random`: a ring through an order of the islands"
            " drawn afresh at each migration from the run seed"
        ),
        choices=TOPOLOGIES)
    emigrants: str = setting(
        "novel", (
            "which individuals leave: `best`, the island's fittest; `novel`, to each destination "
            "the individuals of the better half of the island whose surface the destination does "
            "not hold and that lie farthest from every member of the destination (criteria and "
            "region count, each scaled by its spread), so islands exchange what they lack instead"
            " of converging on one surface"
        ),
        choices=EMIGRANTS)

    def __post_init__(self) -> None:
        check_settings(self, "islands")

def _names(value: object, path: str, allowed: tuple[str, ...] | None, low: int, high: int
           ) -> tuple[str, ...]:
    if isinstance(value, str) or not isinstance(value, (list, tuple)):
        raise _fail(path, f"must be a list of names, got {value!r}")
    if not low <= len(value) <= high:
        raise _fail(path, f"must name {low} to {high} values, got {len(value)}")
    for name in value:
        if not isinstance(name, str) or (allowed is not None and name not in allowed):
            raise _fail(path, f"{name!r} is not one of {', '.join(allowed or ())}")
    if len(set(value)) != len(value):
        raise _fail(path, f"names a value twice: {list(value)!r}")
    return tuple(value)


# Readers of the search settings that are more than a number or a choice (``setting(read=...)``).
def _objectives(value: object, path: str, search: SearchSettings) -> tuple[str, ...]:
    names = _names(value, path, None, 0, 100)
    if search.mode == "pareto" and len(names) == 1:
        raise _fail(path, "a Pareto search needs at least 2 objectives")
    return names


def _descriptors(value: object, path: str, search: SearchSettings) -> tuple[str, ...]:
    return _names(value, path, None, 1, 3)


def _ranges(value: object, path: str, search: SearchSettings) -> tuple[tuple[float, float], ...]:
    n = len(search.descriptors)
    if isinstance(value, str) or not isinstance(value, (list, tuple)) or len(value) != n:
        raise _fail(path, f"must hold one [low, high] per descriptor ({n}), got {value!r}")
    ranges = []
    for i, pair in enumerate(value):
        where = f"{path}[{i}]"
        if isinstance(pair, str) or not isinstance(pair, (list, tuple)) or len(pair) != 2:
            raise _fail(where, f"must be [low, high], got {pair!r}")
        lo, hi = (_number(v, where) for v in pair)
        if not lo < hi:
            raise _fail(where, f"low must be below high, got {[lo, hi]!r}")
        ranges.append((lo, hi))
    return tuple(ranges)


def _bins(value: object, path: str, search: SearchSettings) -> tuple[int, ...]:
    n = len(search.descriptors)
    if isinstance(value, str) or not isinstance(value, (list, tuple)) or len(value) != n:
        raise _fail(path, f"must hold one count per descriptor ({n}), got {value!r}")
    return tuple(read_int(b, "", f"{path}[{i}]", minimum=1, maximum=1000) for i, b in enumerate(value))


def _offspring(value: object, path: str, search: SearchSettings) -> float:
    share = read_rate(value, "", path)
    if share <= 0.0:
        raise _fail(path, "must be above 0: a generation needs new offspring")
    return share


@dataclass(frozen=True, slots=True)
class SearchSettings:
    """How an island selects: by the weighted fitness, by Pareto fronts (NSGA-II), or into a
    MAP-Elites archive; see ``genr8_dist.evolution.pareto`` and ``genr8_dist.evolution.archive``."""

    mode: str = setting(
        "weighted", (
            "`weighted`: tournaments and elites by the fitness (the weighted sum); `pareto`: "
            "NSGA-II, the weighted deviations of `objectives` as separate objectives (tournaments"
            " by front, then crowding distance; the elites are the first front: its best "
            "`ea.elites` by the fitness first, then the least crowded, up to half the "
            "population); `map-elites`: a MAP-Elites archive over `descriptors` (below)"
        ),
        choices=SEARCH_MODES)
    objectives: tuple[str, ...] = setting(
        (), (
            "`pareto`: the criteria whose weighted deviations are the objectives (2 or more); "
            "empty: every criterion with a weight above 0"
        ),
        read=_objectives)
    descriptors: tuple[str, ...] = setting(
        ("undulation", "size_regions"), (
            "`map-elites`: 1 to 3 stored values spanning the archive: a criterion's raw value or "
            "one of the phenotype's sizes, `size_<name>` (surfaces: `size_vertices`, "
            "`size_edges`, `size_regions`; the older spellings `n_vertices`, `n_edges`, "
            "`n_regions` still read)"
        ),
        read=_descriptors)
    ranges: tuple[tuple[float, float], ...] = setting(
        ((0.0, 2.0), (1.0, 65.0)),
        "`map-elites`: `[low, high]` per descriptor; values outside go to the edge cells", read=_ranges)
    bins: tuple[int, ...] = setting((4, 8), "`map-elites`: cells per descriptor", read=_bins)
    offspring: float = setting(
        0.5, (
            "`map-elites`: the offspring bred in each generation besides the archive, as a share "
            "of `ea.population` (at least this many; more while the archive holds fewer cells "
            "than the rest of the population). A generation holds the whole archive, so it grows "
            "beyond `ea.population` once more cells are held than `ea.population` less these "
            "offspring"
        ),
        read=_offspring)

    def __post_init__(self) -> None:
        check_settings(self, "search")


_SECTIONS: dict[str, type] = {"genome": GenomeSettings, "ea": EASettings, "islands": IslandSettings,
                              "search": SearchSettings}


def section_table(name: str) -> str:
    """The documentation table of the section ``[name]`` (docs/run-config.md), from its declarations."""
    return settings_table(_SECTIONS[name])


def _sections_doc() -> str:
    """The module docstring's list of each section's keys, from their declarations."""
    import textwrap

    lines = []
    for name, cls in _SECTIONS.items():
        keys = textwrap.wrap(", ".join(f.name for f in fields(cls)), 70)
        lines.append(f"    {'[' + name + ']':<30}# {keys[0]}")
        lines.extend(f"    {'':<30}# {more}" for more in keys[1:])
    return "\n".join(lines)


if __doc__ is not None:
    __doc__ = __doc__.replace("{sections}", _sections_doc())

S = TypeVar("S", bound="DataclassInstance")   # a settings section


def _section(cls: type[S], data: object, name: str) -> S:
    """Build section ``cls`` from the table ``data``; unknown keys are errors."""
    if isinstance(data, cls):
        return data
    if not isinstance(data, Mapping):
        raise _fail(name, f"must be a table, got {data!r}")
    allowed = [f.name for f in fields(cls)]
    for key in data:
        if key not in allowed:
            raise _fail(f"{name}.{key}", f"unknown key; allowed: {', '.join(allowed)}")
    return cls(**data)


@dataclass(frozen=True, slots=True)
class RunConfig:
    """Everything a run needs: universe, genome, EA, fitness, environment, islands and seed."""

    universe: str = setting(
        "default",
        (
            "the BNF universe genomes are mapped with: a built-in (`default`, `reversible`, `symmetric`, "
            "`probabilistic`), a plugin's name, or a path to a `.lark` file or plugin folder, resolved "
            "relative to this configuration file (a plugin named by path runs its code after a one-line "
            "notice: grammars/README.md, the trust rule)"
        ),
        read=lambda value, path, config: value,   # resolved before the fields are read
    )
    seed: int = setting(
        0,
        (
            "the run seed; every random draw of the run derives from it (`genr8_dist.rng.stream(seed, "
            '"island", i, "generation", g, purpose)`), so the same file gives the same run'
        ),
        minimum=0, maximum=2**63 - 1,
    )
    meshing: int = setting(
        MESHING,
        (
            "how surfaces are cut into triangles for export, pictures and the studio "
            "(`genr8_dist.hemls.meshing`): `8` as 7, but mending's last tries also split the longer "
            "side of a thin triangle's corner at the shorter one's length (a corner of 29.6 degrees cut "
            "in two by an edge inside it becomes one triangle) and try two steps, an edge flipped whatever "
            "that does or a point moved, then what it left mended (a triangle among others just over "
            "15 degrees, which every single step takes under 15); "
            "`7` as 6, but in mending a thin triangle of a region with a "
            "corner under 15 degrees (any mesh of it has one: a needle) counts after those of the other "
            "regions, so a side shared with a needle is split to mend its neighbour (under 6 the thin "
            "triangle the split added to the needle undid the repair), mending goes on until nothing "
            "changes (6 stopped after 4 rounds while repairs still spread), and a point on a side beside a "
            "very short gap may slide or go (under 6 rounding made it look off the side's line); "
            "`6` as 5, then the whole mesh mended across regions "
            "(`hemls.mending`: edges inside a region flipped, added points collapsed, moved or slid along "
            "their side, edges split, in both regions beside a side at once, wherever that leaves fewer "
            "triangles under 15 degrees; every region keeps its outline): under 5 a corner whose two sides "
            "a neighbour had split unevenly kept a thin triangle no mesh of the region alone could mend; "
            "`5` as 4, but each region's triangles are tidied in space "
            "once lifted (edges inside it flipped and its added points moved where that raises the "
            "smallest angle; its sides' points held, so neighbours still meet on them: lifting bent "
            "Triangle's angles across creases and slopes) and two points a pass put on a side within a "
            "hundredth of the gaps beside them are one (under 4 they stayed a billionth of the side "
            "apart, with needle-thin triangles on them); "
            "`4` as 3, but a region that slopes away from its best-fit "
            "plane (the projection keeps less than 90% of its area) is meshed unrolled first (its "
            "meshing-1 triangles laid flat with their side lengths, so its triangles keep their angles in "
            "space), a region meshed in its plane spans its sides as a membrane (not through meshing 1's "
            "creased fan), a region with a corner under a hundredth of a degree whose refinement runs out "
            "of points keeps its sides whole (under 3 it could split them into hundreds of thousands of "
            "points that every neighbour inherited), a region that overlaps itself both in its plane and "
            "unrolled is cut into pieces that do not (under 3 it was cut as in 1) and a long thin region's "
            "point budget grows with its "
            "shape (under 3 it could run out and leave thin triangles); `3` well-shaped triangles "
            "(Triangle's constrained Delaunay refinement of each region in its best-fit plane, or, where "
            "the region crosses itself there, in its meshing-1 triangles unrolled flat; the points on "
            "shared sides settled over passes until no region splits a side; added points lifted onto the "
            "region); `2` the same in the best-fit plane only, sides fixed after one pass, regions "
            "crossing themselves cut as in 1; `1` each region of m vertices cut into m - 2 triangles on "
            "its own vertices. A new run records the meshing it uses in its manifest and regrows with it: "
            "runs created before meshing was recorded keep 1, runs that recorded 2 to 7 keep it bit "
            "for bit. Under 2 to 8 `slivers` measures thin regions, not triangles, so its values are the "
            "same under 2 to 8; under 1 (old runs) it measures the triangles, so their stored values "
            "stay as they were"
        ),
        read=lambda value, path, config: check_meshing(value, path),
    )
    genome: GenomeSettings = field(default_factory=GenomeSettings)
    ea: EASettings = field(default_factory=EASettings)
    fitness: FitnessSpec = None  # type: ignore[assignment]  # None: the phenotype's defaults
    # a declared field, read by its own reader (None: the default environment)
    environment: Environment = setting(  # noqa: RUF009
        None,
        (
            "an inline `[environment]` table, or a path to an environment TOML file, resolved relative to "
            "this configuration file"
        ),
        read=lambda value, path, config: _environment(value, path),
        shown="the default environment",
    )
    islands: IslandSettings = field(default_factory=IslandSettings)
    search: SearchSettings = field(default_factory=SearchSettings)
    universe_source: UniverseSource = None  # type: ignore[assignment]  # its files; None: look it up

    def __post_init__(self) -> None:
        source = self.universe_source
        if source is None:
            name, source = resolve_universe(self.universe, None)
            _set(self, "universe", name)
            _set(self, "universe_source", source)
        else:
            if not isinstance(source, UniverseSource):
                raise _fail("stored_universe", f"must be a UniverseSource, got {type(source).__name__}")
            if self.universe != source.name:
                raise _fail("universe", f"names {self.universe!r} but the stored universe is "
                                        f"{source.name!r}")
            try:
                check_source(source)
            except Genr8Error as exc:
                raise _fail("stored_universe", str(exc)) from None
        check_settings(self, "")
        for name, cls in _SECTIONS.items():
            _set(self, name, _section(cls, getattr(self, name), name))
        if self.fitness is None:
            _set(self, "fitness", FitnessSpec(phenotype=phenotype_kind(self.universe_source)))
        elif isinstance(self.fitness, Mapping):
            kind = phenotype_kind(self.universe_source)
            _set(self, "fitness", FitnessSpec.from_dict(self.fitness, phenotype=kind))
        elif not isinstance(self.fitness, FitnessSpec):
            raise _fail("fitness", f"must be a table, got {self.fitness!r}")
        criteria = tuple(self.fitness.names)
        _names(self.search.objectives, "search.objectives", criteria, 0, len(criteria))
        if self.search.mode == "map-elites":
            sizes = descriptor_sizes(run_phenotype(self.universe_source).sizes)
            _names(self.search.descriptors, "search.descriptors", criteria + sizes, 1, 3)
        if self.islands.migrants >= self.ea.population:
            raise _fail(
                "islands.migrants",
                f"must be < ea.population ({self.ea.population}), got {self.islands.migrants}",
            )

    # -- reading ---------------------------------------------------------------------------------

    @classmethod
    def from_dict(cls, data: Mapping[str, Any], *, source: str = "<config>",
                  base_dir: str | Path | None = None, criteria: Sequence[str] | None = None) -> RunConfig:
        """Build and validate from a parsed TOML table. ``environment`` may be a table or a path
        (resolved against ``base_dir``, default the current directory); the fitness covers
        ``criteria`` (a run's; default every registered criterion). Errors name ``source`` and the
        field."""
        try:
            # no base_dir: relative paths stay relative (the working directory is never asked for:
            # a Ray job's may be gone by the time its stored configurations are read)
            return cls._from_dict(data, source, Path(base_dir) if base_dir is not None else None,
                                  criteria)
        except ConfigError as exc:
            message = str(exc)
            if message.startswith(source):
                raise
            raise ConfigError(f"{source}: {message}") from None

    @classmethod
    def from_toml(cls, text: str, *, source: str = "<config>",
                  criteria: Sequence[str] | None = None, meshing: int | None = None,
                  screen: int | None = None) -> RunConfig:
        """Build and validate from TOML text (a run's stored configuration: the environment inline);
        malformed TOML is a ``ConfigError`` naming ``source``. ``meshing``: the version a text that
        names none uses (a run's recorded one, ``RunStore.meshing``); default the current one.
        ``screen``: likewise the ``ea.screen`` a text that names none uses (``RunStore.screen``)."""
        import tomllib

        try:
            data = tomllib.loads(text)
        except tomllib.TOMLDecodeError as exc:
            raise ConfigError(f"{source}: not valid TOML: {exc}") from None
        if meshing is not None and "meshing" not in data:
            data["meshing"] = meshing
        ea = data.get("ea", {})
        if screen is not None and isinstance(ea, Mapping) and "screen" not in ea:
            data["ea"] = {**ea, "screen": screen}
        return cls.from_dict(data, source=source, criteria=criteria)

    @classmethod
    def _from_dict(cls, data: Mapping[str, Any], source: str, base_dir: Path | None,
                   criteria: Sequence[str] | None = None) -> RunConfig:
        if not isinstance(data, Mapping):
            raise ConfigError(f"the configuration must be a table, got {data!r}")
        for key in data:
            if key not in _TOP_KEYS:
                raise _fail(key, f"unknown key; allowed: {', '.join(_TOP_KEYS)}")
        kwargs: dict[str, Any] = {k: data[k] for k in _PLAIN if k in data}
        if "stored_universe" in data:
            try:
                stored = UniverseSource.from_dict(data["stored_universe"], f"{source} [stored_universe]")
            except Genr8Error as exc:
                raise _fail("stored_universe", str(exc)) from None
            kwargs["universe"] = data.get("universe", stored.name)
            kwargs["universe_source"] = stored
        elif "universe" in data:
            kwargs["universe"], kwargs["universe_source"] = resolve_universe(data["universe"], base_dir)
        for name, section in _SECTIONS.items():
            if name in data:
                kwargs[name] = _section(section, data[name], name)
        if "fitness" in data or criteria is not None:
            # a run's stored configuration names its criteria and sets each in full: no defaults
            kind = phenotype_kind(kwargs.get("universe_source")) if criteria is None else SURFACE
            kwargs["fitness"] = FitnessSpec.from_dict(data.get("fitness"), names=criteria, phenotype=kind)
        if "environment" in data:
            kwargs["environment"] = _read_environment(data["environment"], source, base_dir)
        return cls(**kwargs)

    # -- writing ---------------------------------------------------------------------------------

    def to_dict(self) -> dict[str, Any]:
        """A TOML-ready table (the environment always inline), such that ``from_dict(to_dict())`` is
        equal to this configuration."""
        out: dict[str, Any] = {"universe": self.universe} | {k: getattr(self, k) for k in _PLAIN}
        for name in _SECTIONS:
            section = getattr(self, name)
            out[name] = {f.name: _lists(getattr(section, f.name)) for f in fields(section)}
        out["fitness"] = self.fitness.to_dict()
        out["environment"] = _drop_none(self.environment.to_dict())
        out["stored_universe"] = self.universe_source.to_dict()
        return out

    def to_toml(self) -> str:
        """The configuration as TOML text that ``load_config`` reads back to an equal configuration."""
        import tomli_w

        return tomli_w.dumps(self.to_dict(), multiline_strings=True)

    def replace(self, **changes: Any) -> RunConfig:
        """A validated copy with ``changes`` merged in: top-level values (``seed=3``), or per section a
        table merged into it (``ea={"mutation_rate": 0.05}``, ``fitness={"size": {"weight": 2}}``), or a
        whole section object (``environment=env``). Used for interventions between generations."""
        for key in changes:
            if key not in _TOP_KEYS:
                raise _fail(key, f"unknown key; allowed: {', '.join(_TOP_KEYS)}")
        kwargs: dict[str, Any] = {f.name: getattr(self, f.name) for f in fields(self)}
        if "universe" in changes and changes["universe"] != self.universe:
            kwargs["universe_source"] = None    # another universe: look it up and store it anew
        for key, value in changes.items():
            current = kwargs[key]
            if key in _SECTIONS and isinstance(value, Mapping):
                merged = {f.name: getattr(current, f.name) for f in fields(current)} | dict(value)
                kwargs[key] = _section(_SECTIONS[key], merged, key)
            elif key == "fitness" and isinstance(value, Mapping):
                kwargs[key] = current.replace(value)
            elif key == "environment" and isinstance(value, Mapping):
                merged = _deep_merge(current.to_dict(), value)
                kwargs[key] = Environment.from_dict(merged, source="[environment]")
            else:
                kwargs[key] = value
        return RunConfig(**kwargs)


def _environment(value: object, path: str) -> Environment:
    """The ``environment`` field's value: the default environment for ``None``, an inline table
    read, or an environment as it is."""
    if value is None:
        return Environment()
    if isinstance(value, Mapping):
        return Environment.from_dict(dict(value), source="[environment]")
    if not hasattr(value, "to_dict"):
        raise _fail(path, f"must be a table or a file name, got {value!r}")
    return value  # type: ignore[return-value]  # an Environment, or a stand-in with its interface


#: The top-level keys of a configuration file: the fields, its universe's files as ``stored_universe``.
_TOP_KEYS: tuple[str, ...] = (*(f.name for f in fields(RunConfig) if f.name != "universe_source"),
                              "stored_universe")
#: The top-level settings read as they are written (the universe and the environment are resolved
#: against the file's folder first).
_PLAIN: tuple[str, ...] = tuple(f.name for f in fields(RunConfig) if "setting" in f.metadata
                                and f.name not in ("universe", "environment"))


def top_table() -> str:
    """The documentation table of the top-level keys (docs/run-config.md), from their declarations."""
    return settings_table(RunConfig)


def _deep_merge(base: Mapping[str, Any], changes: Mapping[str, Any]) -> dict[str, Any]:
    out = dict(base)
    for key, value in changes.items():
        if isinstance(value, Mapping) and isinstance(out.get(key), Mapping):
            out[key] = _deep_merge(out[key], value)
        else:
            out[key] = value
    return out


def _lists(value: object) -> object:
    """Tuples as lists (TOML arrays), nested too."""
    if isinstance(value, tuple):
        return [_lists(v) for v in value]
    return value


def _drop_none(value: object) -> object:
    """TOML has no null: drop keys whose value is None (readers take the default for a missing key)."""
    if isinstance(value, Mapping):
        return {k: _drop_none(v) for k, v in value.items() if v is not None}
    if isinstance(value, (list, tuple)):
        return [_drop_none(v) for v in value]
    return value


def _read_environment(value: object, source: str, base_dir: Path | None) -> Environment:
    if isinstance(value, str):
        path = Path(value)
        if not path.is_absolute():
            path = base_dir / path if base_dir is not None else path
        if not path.is_file():
            raise _fail("environment", f"environment file not found: {path}")
        return load_environment(path)
    if isinstance(value, Mapping):
        return Environment.from_dict(dict(value), source=f"{source} [environment]", base_dir=base_dir)
    raise _fail("environment", f"must be a table or a file name, got {value!r}")


def load_config(path: str | os.PathLike[str]) -> RunConfig:
    """Read and validate the run configuration in the TOML file ``path``."""
    file = Path(path)
    data = read_toml(file, "configuration file")
    return RunConfig.from_dict(data, source=str(file), base_dir=file.parent)
