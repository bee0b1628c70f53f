"""The individual: one genome and everything learned about it, the row the run store keeps.

The stored row is declared once, here: every field of ``Evaluation`` (what evaluating a genome finds)
and of ``Individual`` (an evaluation plus where it sits in the run) carries a ``Column`` in its metadata
(its Arrow type, nullability, whether it is a timing, whether ``genr8 top`` lists it), and
``register_column`` adds a column a plugin computes (its values travel in ``Individual.extra``). Two
fields stand for several columns each, named by the run's phenotype (``genr8_dist.phenotype``):
``criteria`` one ``crit_<name>`` float column per criterion, ``sizes`` one ``size_<name>`` integer
column per size the phenotype declares (a surface: vertices, edges, regions). The store's schema, the
timing columns, the synthetic writer, the history's column order and ``top``'s display are all derived
from ``stored_columns()``.

Failure is data: an individual that cannot be mapped, parsed, grown or scored is still an
``Individual``, with ``valid=False``, the ``stage`` that failed, the ``error``, and the worst fitness
(``math.inf``). Columns marked *timing* are measurements and are excluded from determinism checks;
every other column is a pure function of the run's configuration, seed and history.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field, fields, replace
from typing import Any

from genr8_dist.phenotype import SCHEMA_2_NAMES

__all__ = [
    "ORIGINS",
    "SCHEMA_2_NAMES",
    "Column",
    "Evaluation",
    "Individual",
    "individual_id",
    "parse_id",
    "register_column",
    "registered_column",
    "stored_columns",
    "timing_columns",
    "unregister_column",
]

# How an individual came to be (the ``origin`` column).
ORIGINS: tuple[str, ...] = (
    "random",     # generation 0, or a random immigrant
    "elite",      # copied unchanged from the previous generation
    "crossover",  # one-point crossover of two parents, not mutated
    "mutation",   # int-flip mutation of one parent (no crossover)
    "crossover+mutation",
    "migrant",    # arrived from another island at a migration
    "injected",   # put in by a user's intervention (copy, hand-written system, another run)
)

# The Arrow types a column may have, by name (the store turns them into pyarrow types).
ARROW_TYPES: tuple[str, ...] = ("bool", "int32", "int64", "float64", "string", "list<int32>", "list<string>")
CRITERIA_KIND = "criteria"  # the field that stands for one ``crit_<name>`` float64 column per criterion
SIZES_KIND = "sizes"        # the field that stands for one ``size_<name>`` int64 column per size
EXTRA_KIND = "extra"        # the field that stands for the registered columns

# SCHEMA_2_NAMES (the columns schemas 1 and 2 named after surfaces) is the phenotype's: genr8_dist.phenotype.


@dataclass(frozen=True, slots=True)
class Column:
    """One stored column: its ``name``, Arrow ``arrow`` type (one of ``ARROW_TYPES``), whether it may be
    null, whether it is a ``timing`` (a measurement, not a result), its place among the columns
    ``history.top`` returns (``top``; 0: not returned) and ``genr8 top`` prints (``shown``, under
    ``heading``; 0: not printed; ties keep declaration order), the schema version that
    introduced it (``since``; 0 for a registered column, which a run has only if created with it) and
    the ``default`` a row without a value gets."""

    name: str
    arrow: str
    nullable: bool = True
    timing: bool = False
    top: int = 0
    shown: int = 0
    heading: str = ""
    since: int = 1
    default: Any = None

    def __post_init__(self) -> None:
        if not self.name.isidentifier():
            raise ValueError(f"column name {self.name!r}: must be an identifier")
        if self.arrow not in ARROW_TYPES and self.arrow not in (CRITERIA_KIND, SIZES_KIND, EXTRA_KIND):
            raise ValueError(f"column {self.name!r}: Arrow type {self.arrow!r} is not one of "
                             f"{', '.join(ARROW_TYPES)}")
        if not self.heading:
            object.__setattr__(self, "heading", self.name)


def _meta(**column: Any) -> dict[str, Any]:
    """Field metadata declaring a column (``Column`` keywords; the name is the field's)."""
    return {"column": column}


def _col(default: Any = None, **column: Any) -> Any:
    """A dataclass field with ``default`` (none for a non-nullable column without one) whose metadata
    declares its column."""
    if default is None and column.get("nullable", True) is False:
        return field(metadata=_meta(**column))
    return field(default=default, metadata=_meta(**column))


def individual_id(island: int, generation: int, index: int) -> str:
    """The id of the ``index``-th individual of ``island`` in ``generation``: ``"I-G-N"``."""
    return f"{island}-{generation}-{index}"


def parse_id(text: str) -> tuple[int, int, int] | None:
    """``"I-G-N"`` -> ``(island, generation, index)``; ``None`` when ``text`` is not of that form (e.g. an
    individual injected from another run)."""
    parts = str(text).split("-")
    if len(parts) != 3 or not all(p.isdigit() for p in parts):
        return None
    return int(parts[0]), int(parts[1]), int(parts[2])


@dataclass(frozen=True, slots=True, kw_only=True)
class Evaluation:
    """What evaluating one genome (or text) finds: the evaluated columns of the stored row."""

    text: str | None = _col(arrow="string")                 # the rewrite system the genome maps to
    valid: bool = _col(False, arrow="bool", nullable=False)
    stage: str | None = _col(arrow="string")                # where it failed: map, parse, grow, score
    error: str | None = _col(arrow="string")
    fitness: float = _col(math.inf, arrow="float64", nullable=False, top=5, shown=4)  # lower is better
    # the raw value of every criterion: one crit_<name> column each
    criteria: dict[str, float] = field(default_factory=dict,
                                       metadata=_meta(arrow=CRITERIA_KIND, top=6, shown=5))
    codons_used: int = _col(0, arrow="int32", nullable=False)
    wraps: int = _col(0, arrow="int32", nullable=False)
    # the phenotype's sizes (``Phenotype.sizes``; 0 when not developed): one size_<name> column each
    sizes: dict[str, int] = field(default_factory=dict, metadata=_meta(arrow=SIZES_KIND, top=9))
    steps_done: int = _col(0, arrow="int32", nullable=False, top=12)
    capped: str | None = _col(arrow="string", top=13)     # which growth cap cut it short, if any
    # the phenotype's digest (equal digests, equal phenotypes; a surface's: blake2b of its vertices)
    phenotype_digest: str | None = _col(arrow="string", top=15)
    eval_seconds: float = _col(0.0, arrow="float64", nullable=False, timing=True)
    map_seconds: float = _col(0.0, arrow="float64", nullable=False, timing=True)
    grow_seconds: float = _col(0.0, arrow="float64", nullable=False, timing=True)
    score_seconds: float = _col(0.0, arrow="float64", nullable=False, timing=True)

    def as_fields(self) -> dict[str, Any]:
        """The evaluated fields (those of ``Evaluation``) as keyword arguments for ``Individual``."""
        return {name: getattr(self, name) for name in _EVALUATED}

    def evaluation(self) -> Evaluation:
        """The evaluated part alone (of an ``Individual``, its evaluation)."""
        return Evaluation(**self.as_fields())

    def untimed(self) -> Evaluation:
        """The evaluation with every timing set to 0 (a cache hit costs nothing)."""
        return Evaluation(**self.untimed_fields())

    def untimed_fields(self) -> dict[str, Any]:
        """``as_fields`` with every timing 0 (what ``untimed`` builds, for a subclass's own)."""
        values = self.as_fields()
        values.update(_UNTIMED)
        return values


# The names of the evaluated fields, and the timings zeroed (one evaluation built per cache hit:
# ``fields()`` walked each time cost ~5% of a host's CPU).
_EVALUATED: tuple[str, ...] = tuple(f.name for f in fields(Evaluation))
_UNTIMED: dict[str, float] = {f.name: 0.0 for f in fields(Evaluation) if f.metadata["column"].get("timing")}


@dataclass(frozen=True, slots=True)
class Individual(Evaluation):
    """One evaluated genome of one island in one generation (``Individual(island, generation, index,
    genome, origin, ...)``, the evaluated fields by keyword)."""

    island: int = _col(arrow="int32", nullable=False, top=3, shown=3, heading="isl")
    generation: int = _col(arrow="int32", nullable=False, top=2, shown=2, heading="gen")
    index: int = _col(arrow="int32", nullable=False, top=4)
    genome: tuple[int, ...] = _col(arrow="list<int32>", nullable=False)
    origin: str = _col(arrow="string", nullable=False, top=7, shown=6)
    parents: tuple[str, ...] = _col((), arrow="list<string>", nullable=False, top=8)
    config_version: int = _col(1, arrow="int32", nullable=False, top=14)
    # the values of registered columns
    extra: dict[str, Any] = field(default_factory=dict, metadata=_meta(arrow=EXTRA_KIND))

    @property
    def id(self) -> str:
        return individual_id(self.island, self.generation, self.index)


# --------------------------------------------------------------------------------------------------
# The columns, derived from the declarations above (and the registered ones).

_RUN_COLUMNS = (  # the run's id and the individual's, stored ahead of the fields
    Column("run_id", "string", nullable=False),
    Column("id", "string", nullable=False, top=1, shown=1),
)
_REGISTERED: dict[str, Column] = {}


def _field_columns(cls: type) -> list[Column]:
    own = [f for f in fields(cls) if cls is Evaluation or f.name not in Evaluation.__dataclass_fields__]
    return [Column(f.name, **f.metadata["column"]) for f in own]


def _declared() -> tuple[Column, ...]:
    # identity (Individual's own fields) first, then what evaluation found, then registered columns
    return (*_RUN_COLUMNS, *_field_columns(Individual), *_field_columns(Evaluation))


_DECLARED = _declared()


def stored_columns() -> tuple[Column, ...]:
    """Every column of the stored row, in stored order: ``run_id``, ``id``, the fields of ``Individual``
    and ``Evaluation`` (the ``criteria`` column standing for the ``crit_<name>`` columns), then the
    registered columns (where ``extra`` stands)."""
    out: list[Column] = []
    for column in _DECLARED:
        if column.arrow == EXTRA_KIND:
            continue
        out.append(column)
    return (*out, *_REGISTERED.values())


def timing_columns() -> tuple[str, ...]:
    """The names of the timing columns (measurements, excluded from determinism checks)."""
    return tuple(c.name for c in stored_columns() if c.timing)


def register_column(column: Column) -> Column:
    """Declare a column a plugin or a search mode computes (one entry: the schema of new runs, the
    writers and readers, ``top`` follow). Its value is ``Individual.extra[name]`` (``default`` if
    absent); runs created before it was registered do not have it and read it as null."""
    if not isinstance(column, Column) or column.arrow in (CRITERIA_KIND, SIZES_KIND, EXTRA_KIND):
        raise ValueError(f"register_column takes a Column of an Arrow type, got {column!r}")
    if column.name in _REGISTERED or any(c.name == column.name for c in _DECLARED) \
            or column.name.startswith(("crit_", "size_")) or column.name in SCHEMA_2_NAMES:
        raise ValueError(f"column {column.name!r} is already declared (or is a criterion's or a size's)")
    registered = replace(column, since=0)
    _REGISTERED[column.name] = registered
    return registered


def unregister_column(name: str) -> None:
    """Remove a registered column (a plugin being unloaded, a test)."""
    _REGISTERED.pop(name, None)


@contextmanager
def registered_column(column: Column) -> Iterator[Column]:
    """``register_column(column)`` for the duration of a ``with`` block."""
    registered = register_column(column)
    try:
        yield registered
    finally:
        unregister_column(column.name)


# The search modes' columns, registered as a plugin's would be (values in ``Individual.extra``):
# ``pareto_rank``, an individual's front among its island's generation over the Pareto objectives
# (0: non-dominated; every mode); ``cell``, its MAP-Elites archive cell (``map-elites`` mode only).
PARETO_RANK = register_column(Column("pareto_rank", "int32", top=16, shown=7, heading="front"))
ARCHIVE_CELL = register_column(Column("cell", "int32", top=17))
