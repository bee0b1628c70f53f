"""The run configuration: one TOML file that says everything a run needs.

::

    universe = "default"          # the BNF the genomes are mapped with
    seed = 1                      # the run seed every random draw derives from

    [genome]                      # length, codon_max, max_depth, max_wraps
    [ea]                          # population, generations, tournament, elites, crossover_rate,
                                  # mutation_rate, init, founder_retries, unique_retries, unique_redraws,
                                  # within_used
    [fitness.size]                # target, weight (and scale) per criterion: see genr8_dist.fitness
    [environment]                 # inline (genr8_dist.environment's format), or
    # environment = "env.toml"    # a path, resolved relative to this file
    [islands]                     # count, migration_interval, migrants, topology, emigrants
    [search]                      # mode (weighted, pareto, map-elites), objectives, descriptors, ranges,
                                  # bins, offspring

Every section is a frozen dataclass validated when it is built; a section or key left out takes its
default; an unknown key, a wrong type, an out-of-range value, an unknown universe or a missing
environment file is a ``ConfigError`` naming the file and the field. ``docs/run-config.md`` lists every
field with its default and meaning.
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any

from genr8_dist.errors import ConfigError, Genr8Error
from genr8_dist.fields import fail, read_bool, read_choice, read_float, read_int
from genr8_dist.fitness import SURFACE, FitnessSpec
from genr8_dist.tomlfile import read_toml

__all__ = [
    "EMIGRANTS",
    "INITS",
    "SEARCH_MODES",
    "TOPOLOGIES",
    "EASettings",
    "GenomeSettings",
    "IslandSettings",
    "RunConfig",
    "SearchSettings",
    "load_config",
]

TOPOLOGIES: tuple[str, ...] = ("ring", "full", "random")
INITS: tuple[str, ...] = ("random", "ramped")
SEARCH_MODES: tuple[str, ...] = ("weighted", "pareto", "map-elites")
EMIGRANTS: tuple[str, ...] = ("best", "novel")


# The field validators are genr8_dist.fields' (one family for every configuration file); a run
# configuration's messages name the field alone, the caller adds the file.
def _fail(path: str, message: str) -> ConfigError:
    return fail("", path, message)


def _int(value: Any, path: str, minimum: int | None = None, maximum: int | None = None) -> int:
    return read_int(value, "", path, minimum=minimum, maximum=maximum)


def _rate(value: Any, path: str) -> float:
    try:
        return read_float(value, "", path, minimum=0.0, maximum=1.0)
    except ConfigError:
        raise _fail(path, f"must be a number in [0, 1], got {value!r}") from None


def _choice(value: Any, path: str, allowed: tuple[str, ...]) -> str:
    return read_choice(value, "", path, allowed)


def _bool(value: Any, path: str) -> bool:
    return read_bool(value, "", path)


def _number(value: Any, path: str) -> float:
    try:
        return read_float(value, "", path)
    except ConfigError:
        raise _fail(path, f"must be a finite number, got {value!r}") from None


def _set(obj: Any, name: str, value: Any) -> None:
    object.__setattr__(obj, name, value)


@dataclass(frozen=True, slots=True)
class GenomeSettings:
    """The integer genomes: how many codons, their range, and how the GE mapper may read them."""

    length: int = 100       # codons in a random genome
    codon_max: int = 255    # codons are drawn from 0..codon_max
    max_depth: int = 5      # the deepest the derivation tree may grow (DESIGN: default 5)
    max_wraps: int = 2      # times the mapper may wrap round the genome before it is invalid

    def __post_init__(self) -> None:
        _set(self, "length", _int(self.length, "genome.length", 1, 100_000))
        _set(self, "codon_max", _int(self.codon_max, "genome.codon_max", 1, 2**31 - 1))
        _set(self, "max_depth", _int(self.max_depth, "genome.max_depth", 1, 100))
        _set(self, "max_wraps", _int(self.max_wraps, "genome.max_wraps", 0, 1000))


@dataclass(frozen=True, slots=True)
class EASettings:
    """The evolutionary algorithm of one island: generational, tournament selection, elitism,
    one-point crossover and int-flip mutation."""

    population: int = 30        # individuals per island per generation
    generations: int = 20       # generations a run goes to (generation 0 is the random one)
    tournament: int = 3         # contestants per tournament
    elites: int = 1             # best individuals copied unchanged into the next generation
    crossover_rate: float = 0.9  # probability a pair of parents is crossed over
    mutation_rate: float = 0.02  # probability each codon of a child is redrawn (int-flip)
    init: str = "random"         # founders: "random" genomes or "ramped" half-and-half derivations
    founder_retries: int = 20    # redraws of a founder that is trivial or repeats another's surface
    unique_retries: int = 10     # re-variations of an offspring that repeats a parent or a sibling
    unique_redraws: int = 3      # newcomers drawn for an offspring still wasted after those
    within_used: bool = False    # crossover and mutation only within the codons the mapper read

    def __post_init__(self) -> None:
        _set(self, "population", _int(self.population, "ea.population", 2, 1_000_000))
        _set(self, "generations", _int(self.generations, "ea.generations", 0))
        _set(self, "tournament", _int(self.tournament, "ea.tournament", 1, self.population))
        _set(self, "elites", _int(self.elites, "ea.elites", 0, self.population - 1))
        _set(self, "crossover_rate", _rate(self.crossover_rate, "ea.crossover_rate"))
        _set(self, "mutation_rate", _rate(self.mutation_rate, "ea.mutation_rate"))
        _set(self, "init", _choice(self.init, "ea.init", INITS))
        _set(self, "founder_retries", _int(self.founder_retries, "ea.founder_retries", 0, 1000))
        _set(self, "unique_retries", _int(self.unique_retries, "ea.unique_retries", 0, 1000))
        _set(self, "unique_redraws", _int(self.unique_redraws, "ea.unique_redraws", 0, 1000))
        _set(self, "within_used", _bool(self.within_used, "ea.within_used"))


@dataclass(frozen=True, slots=True)
class IslandSettings:
    """How many islands, and how individuals migrate between them."""

    count: int = 1               # islands (each one a Ray actor in a distributed run)
    migration_interval: int = 5  # generations between migrations (an epoch)
    migrants: int = 2            # individuals each island sends at a migration (its best)
    topology: str = "ring"       # ring: to the next island; full: to every other; random: to one drawn
    emigrants: str = "novel"     # best: the fittest leave; novel: the fittest of those unlike the destination

    def __post_init__(self) -> None:
        _set(self, "count", _int(self.count, "islands.count", 1, 10_000))
        _set(self, "migration_interval", _int(self.migration_interval, "islands.migration_interval", 1))
        _set(self, "migrants", _int(self.migrants, "islands.migrants", 0))
        if not isinstance(self.topology, str) or self.topology not in TOPOLOGIES:
            allowed = ", ".join(repr(t) for t in TOPOLOGIES)
            raise _fail("islands.topology", f"must be one of {allowed}, got {self.topology!r}")
        _set(self, "emigrants", _choice(self.emigrants, "islands.emigrants", EMIGRANTS))


def _names(value: Any, path: str, allowed: tuple[str, ...] | None, low: int, high: int
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


@dataclass(frozen=True, slots=True)
class SearchSettings:
    """How an island selects: by the weighted fitness, by Pareto fronts (NSGA-II), or into a
    MAP-Elites archive; see ``genr8_dist.evolution.pareto`` and ``genr8_dist.evolution.archive``."""

    mode: str = "weighted"                 # "weighted", "pareto" or "map-elites"
    objectives: tuple[str, ...] = ()       # pareto: criteria as separate objectives (empty: weight > 0)
    descriptors: tuple[str, ...] = ("undulation", "size_regions")   # map-elites: the grid's axes
    ranges: tuple[tuple[float, float], ...] = ((0.0, 2.0), (1.0, 65.0))
    bins: tuple[int, ...] = (4, 8)
    offspring: float = 0.5                 # map-elites: offspring each generation, a share of ea.population

    def __post_init__(self) -> None:
        _set(self, "mode", _choice(self.mode, "search.mode", SEARCH_MODES))
        _set(self, "objectives", _names(self.objectives, "search.objectives", None, 0, 100))
        if self.mode == "pareto" and len(self.objectives) == 1:
            raise _fail("search.objectives", "a Pareto search needs at least 2 objectives")
        _set(self, "descriptors", _names(self.descriptors, "search.descriptors", None, 1, 3))
        n = len(self.descriptors)
        if isinstance(self.ranges, str) or not isinstance(self.ranges, (list, tuple)) \
                or len(self.ranges) != n:
            raise _fail("search.ranges",
                        f"must hold one [low, high] per descriptor ({n}), got {self.ranges!r}")
        ranges = []
        for i, pair in enumerate(self.ranges):
            where = f"search.ranges[{i}]"
            if isinstance(pair, str) or not isinstance(pair, (list, tuple)) or len(pair) != 2:
                raise _fail(where, f"must be [low, high], got {pair!r}")
            lo, hi = (_number(v, where) for v in pair)
            if not lo < hi:
                raise _fail(where, f"low must be below high, got {[lo, hi]!r}")
            ranges.append((lo, hi))
        _set(self, "ranges", tuple(ranges))
        if isinstance(self.bins, str) or not isinstance(self.bins, (list, tuple)) or len(self.bins) != n:
            raise _fail("search.bins", f"must hold one count per descriptor ({n}), got {self.bins!r}")
        _set(self, "bins", tuple(_int(b, f"search.bins[{i}]", 1, 1000) for i, b in enumerate(self.bins)))
        _set(self, "offspring", _rate(self.offspring, "search.offspring"))
        if self.offspring <= 0.0:
            raise _fail("search.offspring", "must be above 0: a generation needs new offspring")


_SECTIONS: dict[str, type] = {"genome": GenomeSettings, "ea": EASettings, "islands": IslandSettings,
                              "search": SearchSettings}
_TOP_KEYS = ("universe", "seed", "meshing", "genome", "ea", "fitness", "environment", "islands", "search",
             "stored_universe")


def _section(cls: type, data: Any, name: str) -> Any:
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


def _default_environment() -> Any:
    from genr8_dist.environment import Environment

    return Environment()


def _resolve_universe(name: Any, base_dir: Path | None) -> tuple[str, Any]:
    """The universe ``name`` (a name, or a path resolved against ``base_dir``) read into a source and
    checked (no plugin code runs): ``(its name, its UniverseSource)``."""
    if not isinstance(name, str) or not name:
        raise _fail("universe", f"must be a universe name or path, got {name!r}")
    from genr8_dist.grammar.discovery import find_source

    try:
        source, _origin = find_source(name, base_dir)
        _check_source(source)
        if not source.code_digest:  # code-free: parse a sample of derivations now (no code runs)
            from genr8_dist.grammar.universe import build_universe

            build_universe(source, check=True)
    except Genr8Error as exc:
        raise _fail("universe", str(exc)) from None
    return source.name, source


def _check_source(source: Any) -> None:
    """Compile the grammar and check the hook names of ``source`` (cached per digest; runs no code)."""
    from genr8_dist.grammar.compiler import compile_grammar

    if source.digest in _CHECKED:
        return
    source.check_hook_names()
    compile_grammar(source.grammar_text, source.where(source.grammar_file))
    _CHECKED.add(source.digest)


_CHECKED: set[str] = set()


def run_phenotype(source: Any) -> Any:
    """The phenotype (``genr8_dist.phenotype.Phenotype``) the universe ``source`` (a
    ``UniverseSource``; ``None``: the default universe) develops into: the built-in surfaces for HEMLS.

    Only a universe's code can say, and code runs only where the trust rule lets it
    (:mod:`genr8_dist.grammar.trust`): an installed plugin's or a remembered digest is consented to
    here; other code is not run and the phenotype read as the built-in surfaces (``genr8 run`` reads
    its file again once the user's universe is consented to)."""
    from genr8_dist.phenotype import SURFACES

    digest = getattr(source, "code_digest", "") if source is not None else ""
    if not digest:
        return SURFACES
    from genr8_dist.grammar.discovery import installed_code_digest
    from genr8_dist.grammar.trust import consent, may_run, remembered

    if not may_run(digest):
        if installed_code_digest(source.name) != digest and digest not in remembered():
            return SURFACES
        consent(digest)
    from genr8_dist.grammar.universe import build_universe
    from genr8_dist.phenotype import phenotype_of

    return phenotype_of(build_universe(source, check=False))


def phenotype_kind(source: Any) -> str:
    """The name of the phenotype ``source`` develops into (``run_phenotype``), under which its
    criteria are registered: ``surface`` for HEMLS."""
    return str(run_phenotype(source).name)


@dataclass(frozen=True, slots=True)
class RunConfig:
    """Everything a run needs: universe, genome, EA, fitness, environment, islands and seed."""

    universe: str = "default"
    seed: int = 0
    meshing: int = 2             # how surfaces are cut into triangles (genr8_dist.hemls.meshing.MESHINGS)
    genome: GenomeSettings = field(default_factory=GenomeSettings)
    ea: EASettings = field(default_factory=EASettings)
    fitness: FitnessSpec = None  # type: ignore[assignment]  # None: the phenotype's defaults
    environment: Any = None      # a genr8_dist.environment.Environment (None: the default one)
    islands: IslandSettings = field(default_factory=IslandSettings)
    search: SearchSettings = field(default_factory=SearchSettings)
    universe_source: Any = None  # the universe's files (a grammar.UniverseSource; None: look it up)

    def __post_init__(self) -> None:
        source = self.universe_source
        if source is None:
            name, source = _resolve_universe(self.universe, None)
            _set(self, "universe", name)
            _set(self, "universe_source", source)
        else:
            from genr8_dist.grammar.source import UniverseSource

            if not isinstance(source, UniverseSource):
                raise _fail("stored_universe", f"must be a UniverseSource, got {type(source).__name__}")
            if self.universe != source.name:
                raise _fail("universe", f"names {self.universe!r} but the stored universe is "
                                        f"{source.name!r}")
            try:
                _check_source(source)
            except Genr8Error as exc:
                raise _fail("stored_universe", str(exc)) from None
        _set(self, "seed", _int(self.seed, "seed", 0, 2**63 - 1))
        from genr8_dist.hemls.meshing import check_meshing

        _set(self, "meshing", check_meshing(self.meshing))
        for name, cls in _SECTIONS.items():
            _set(self, name, _section(cls, getattr(self, name), name))
        if self.fitness is None:
            _set(self, "fitness", FitnessSpec(phenotype=phenotype_kind(self.universe_source)))
        elif isinstance(self.fitness, Mapping):
            kind = phenotype_kind(self.universe_source)
            _set(self, "fitness", FitnessSpec.from_dict(self.fitness, phenotype=kind))
        elif not isinstance(self.fitness, FitnessSpec):
            raise _fail("fitness", f"must be a table, got {self.fitness!r}")
        if self.environment is None:
            _set(self, "environment", _default_environment())
        elif isinstance(self.environment, Mapping):
            from genr8_dist.environment import Environment

            _set(self, "environment", Environment.from_dict(dict(self.environment), source="[environment]"))
        elif not hasattr(self.environment, "to_dict"):
            raise _fail("environment", f"must be a table or a file name, got {self.environment!r}")
        from genr8_dist.evolution.archive import descriptor_sizes

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
                  criteria: Sequence[str] | None = None, meshing: int | None = None) -> RunConfig:
        """Build and validate from TOML text (a run's stored configuration: the environment inline);
        malformed TOML is a ``ConfigError`` naming ``source``. ``meshing``: the version a text that
        names none uses (a run's recorded one, ``RunStore.meshing``); default the current one."""
        import tomllib

        try:
            data = tomllib.loads(text)
        except tomllib.TOMLDecodeError as exc:
            raise ConfigError(f"{source}: not valid TOML: {exc}") from None
        if meshing is not None and "meshing" not in data:
            data["meshing"] = meshing
        return cls.from_dict(data, source=source, criteria=criteria)

    @classmethod
    def _from_dict(cls, data: Mapping[str, Any], source: str, base_dir: Path | None,
                   criteria: Sequence[str] | None = None) -> RunConfig:
        if not isinstance(data, Mapping):
            raise ConfigError(f"the configuration must be a table, got {data!r}")
        for key in data:
            if key not in _TOP_KEYS:
                raise _fail(key, f"unknown key; allowed: {', '.join(_TOP_KEYS)}")
        kwargs: dict[str, Any] = {k: data[k] for k in ("seed", "meshing") if k in data}
        if "stored_universe" in data:
            from genr8_dist.grammar.source import UniverseSource

            try:
                stored = UniverseSource.from_dict(data["stored_universe"], f"{source} [stored_universe]")
            except Genr8Error as exc:
                raise _fail("stored_universe", str(exc)) from None
            kwargs["universe"] = data.get("universe", stored.name)
            kwargs["universe_source"] = stored
        elif "universe" in data:
            kwargs["universe"], kwargs["universe_source"] = _resolve_universe(data["universe"], base_dir)
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
        out: dict[str, Any] = {"universe": self.universe, "seed": self.seed, "meshing": self.meshing}
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
                from genr8_dist.environment import Environment

                merged = _deep_merge(current.to_dict(), value)
                kwargs[key] = Environment.from_dict(merged, source="[environment]")
            else:
                kwargs[key] = value
        return RunConfig(**kwargs)


def _deep_merge(base: Mapping[str, Any], changes: Mapping[str, Any]) -> dict[str, Any]:
    out = dict(base)
    for key, value in changes.items():
        if isinstance(value, Mapping) and isinstance(out.get(key), Mapping):
            out[key] = _deep_merge(out[key], value)
        else:
            out[key] = value
    return out


def _lists(value: Any) -> Any:
    """Tuples as lists (TOML arrays), nested too."""
    if isinstance(value, tuple):
        return [_lists(v) for v in value]
    return value


def _drop_none(value: Any) -> Any:
    """TOML has no null: drop keys whose value is None (readers take the default for a missing key)."""
    if isinstance(value, Mapping):
        return {k: _drop_none(v) for k, v in value.items() if v is not None}
    if isinstance(value, (list, tuple)):
        return [_drop_none(v) for v in value]
    return value


def _read_environment(value: Any, source: str, base_dir: Path | None) -> Any:
    from genr8_dist.environment import Environment, load_environment

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
