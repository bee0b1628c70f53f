"""The fitness of a grown surface: eight criteria, each with a target and a weight: the thesis's six
(4.3.1, journal 5.3) and two of genr8_dist's, ``cells`` and ``slivers``.

A *criterion* is a raw measurement of the surface (its size, how smooth it is, ...). The designer sets a
*target* and a *weight* for each one; the fitness is the weighted sum of the deviations from the targets,
so **lower is better** and 0 means every target is met::

    F_tot = sum_i  w_i * |F_i - t_i| / s_i

where ``F_i`` is the raw value, ``t_i`` the target, ``w_i >= 0`` the weight and ``s_i`` the criterion's
*scale*: by default ``max(1, |t_i|)``, so a deviation is relative to the target when the target is larger
than 1 (a size of 12 against a target of 10 costs 0.2) and absolute otherwise (a symmetry of 0.8
against 1 costs 0.2; a soft-boundary count of 3 against 0 costs 3). A scale can be set per criterion.
Every raw value is kept next to the total, so a run's history can be re-weighted afterwards.

Criteria are declared once, in a registry: ``register_criterion`` takes a name, the function that
measures it, its default target and weight, a short heading and a description; the fitness
specification, scoring, the run store's ``crit_<name>`` columns, the history's headings and the docs
table (``criteria_table``) all iterate over it. A phenotype plugin declares its own criteria the same
way, under its phenotype's name. The built-in surface criteria, in registry order (V vertices with
positions (x, y, z), E edges):

========================  ==================================================================
size                      ``max|x_i - x_j| + max|y_i - y_j|``: the x extent plus the y extent
smoothness                ``1/2 sum_i sum_{j in N(i)} |z_i - z_j|``: local z differences, each
                          pair of neighbours (vertices joined by an edge) counted once
undulation                ``max|z_i - z_j|``: the global z range
subdivisions              ``V / E``: 1 for a polygon, lower the more the surface is subdivided
symmetry                  ``(sym(x) + sym(y)) / 2``; ``sym(x)`` is the ratio (smaller over
                          larger) of the vertex counts either side of the line parallel to the
                          x axis through the centre of the surface; 1 is perfectly balanced
soft_boundary             the number of vertices on the wrong side of the soft boundaries
========================  ==================================================================

Genr8's own default targets and weights are not in the sources we have; the registry holds ours,
chosen for the default environment (start length 1, scale 1.5, 4 steps: a seed of side 1 grows to
about 5 by 5, so size ~10): a flat (smoothness 0, undulation 0), moderately subdivided (0.5),
balanced (symmetry 1) surface of size 10 that stays inside its soft boundaries.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np

from genr8_dist.errors import ConfigError
from genr8_dist.fields import read_float
from genr8_dist.hemls.meshing import triangle_min_angles

__all__ = [
    "CRITERIA",
    "DEFAULT_CRITERIA",
    "SURFACE",
    "Criterion",
    "CriterionInfo",
    "FitnessSpec",
    "criteria_table",
    "criterion_heading",
    "criterion_info",
    "criterion_names",
    "register_criterion",
    "registered",
    "registered_criteria",
    "score",
    "score_surface",
    "size",
    "smoothness",
    "soft_boundary",
    "subdivisions",
    "symmetry",
    "undulation",
    "unregister_criterion",
]

SURFACE = "surface"  # the built-in phenotype: a HEMLS surface (vertices, edges, regions)


class _SurfaceLike(Protocol):
    vertices: Any  # (V, 3) float positions
    edges: Any     # (E, 2) int vertex indices


# --------------------------------------------------------------------------------------------------
# The criteria: one small function each, on plain arrays.


def _positions(vertices: Any) -> np.ndarray:
    pos = np.asarray(vertices, dtype=np.float64)
    if pos.ndim != 2 or pos.shape[1] != 3:
        raise ValueError(f"vertices must be a (V, 3) array, got shape {pos.shape}")
    return pos


def _extent(values: np.ndarray) -> float:
    return float(values.max() - values.min()) if values.size else 0.0


def size(vertices: Any) -> float:
    """``F_size = max_ij |x_i - x_j| + max_ij |y_i - y_j|``: the x extent plus the y extent."""
    pos = _positions(vertices)
    return _extent(pos[:, 0]) + _extent(pos[:, 1])


def _neighbour_pairs(edges: Any) -> np.ndarray:
    """The distinct unordered pairs of vertices joined by at least one edge (self-loops dropped)."""
    e = np.asarray(edges, dtype=np.int64).reshape(-1, 2)
    e = e[e[:, 0] != e[:, 1]]
    if not len(e):
        return np.asarray(e)
    lo, hi = np.minimum(e[:, 0], e[:, 1]), np.maximum(e[:, 0], e[:, 1])
    n = int(hi.max()) + 1
    keys = np.sort(lo * n + hi)  # one int per unordered pair; sorted, repeats are neighbours
    keys = keys[np.concatenate(([True], keys[1:] != keys[:-1]))]
    return np.column_stack([keys // n, keys % n])


def smoothness(vertices: Any, edges: Any) -> float:
    """``F_smooth = 1/2 sum_i sum_{j in N(i)} |z_i - z_j|`` over each vertex's neighbours ``N(i)``.

    Each neighbouring pair appears twice in the double sum, so this is the sum of ``|z_a - z_b|`` over
    the distinct pairs of vertices joined by an edge (parallel edges count once). 0 for a flat surface.
    """
    z = _positions(vertices)[:, 2]
    pairs = _neighbour_pairs(edges)
    if not len(pairs):
        return 0.0
    return float(np.abs(z[pairs[:, 0]] - z[pairs[:, 1]]).sum())


def undulation(vertices: Any) -> float:
    """``F_und = max_ij |z_i - z_j|``: the global z range (0 for a flat surface)."""
    return _extent(_positions(vertices)[:, 2])


def subdivisions(n_vertices: int, n_edges: int) -> float:
    """``V / E``: 1 for a polygon (no internal structure), lower for surfaces with many internal edges."""
    if n_edges <= 0:
        return math.nan
    return n_vertices / n_edges


def _balance(values: np.ndarray, centre: float, tol: float) -> float:
    """The smaller over the larger count of ``values`` either side of ``centre`` (those on it count for
    neither side); 1 when both sides are empty."""
    below = int(np.count_nonzero(values < centre - tol))
    above = int(np.count_nonzero(values > centre + tol))
    larger = max(below, above)
    return 1.0 if larger == 0 else min(below, above) / larger


def symmetry(vertices: Any) -> float:
    """``F_sym = (sym(x) + sym(y)) / 2``, each ``sym`` in [0, 1] (1 = as many vertices either side).

    ``sym(x)`` compares the vertex counts either side of the line parallel to the x axis through the
    centre of the surface (the centre of its x-y bounding box); ``sym(y)`` the same for the y axis.
    Vertices within ``1e-9`` times the extent of the line count for neither side.
    """
    pos = _positions(vertices)
    if not len(pos):
        return math.nan
    out = []
    for axis in (1, 0):  # sym(x): the line parallel to x splits on y; sym(y) splits on x
        v = pos[:, axis]
        lo, hi = float(v.min()), float(v.max())
        tol = 1e-9 * max(1.0, hi - lo, abs(lo), abs(hi))
        out.append(_balance(v, (lo + hi) / 2.0, tol))
    return (out[0] + out[1]) / 2.0


def cells(surface: Any) -> float:
    """The number of regions (cells) of the surface's map (0 for a surface-like without regions)."""
    n = getattr(surface, "n_regions", None)
    if n is None:
        n = len(getattr(surface, "regions", ()))
    return float(n)


SLIVER_DEGREES = 10.0


def sliver_roundness(degrees: float = SLIVER_DEGREES) -> float:
    """The isoperimetric quotient ``4 pi area / perimeter**2`` of the roundest triangle whose smallest
    angle is ``degrees`` (its other two equal): about 0.231 at 10 degrees."""
    half = math.radians(degrees) / 2.0
    area = 0.5 * math.sin(2.0 * half)                 # two sides of length 1 about the small angle
    perimeter = 2.0 + 2.0 * math.sin(half)
    return 4.0 * math.pi * area / perimeter ** 2


def slivers(surface: Any) -> float:
    """The share of thin parts of the surface, by its meshing (``hemls.meshing``; docs/run-config.md):

    - meshing 2 and later (the triangles are well shaped, so they say nothing of the form): the share
      of its regions thinner than a sliver triangle, whose isoperimetric quotient
      (``meshing.region_roundness``) is below ``sliver_roundness()`` (a triangle of smallest angle
      ``SLIVER_DEGREES``): thin strips, slivers and regions folded over themselves;
    - meshing 1 (runs created before meshing was recorded), and a surface-like without a meshing: the
      share of its triangles (``surface.triangles()``) whose smallest angle is below
      ``SLIVER_DEGREES``.

    0 when it has none (no region, or a surface-like without triangles)."""
    if getattr(surface, "meshing", 1) >= 2 and hasattr(surface, "region_offsets"):
        from genr8_dist.hemls.meshing import region_roundness

        roundness = region_roundness(surface)
        return float(np.mean(roundness < sliver_roundness())) if len(roundness) else 0.0
    triangles = surface.triangles() if hasattr(surface, "triangles") else ()
    angles = triangle_min_angles(surface.vertices, triangles)
    return float(np.mean(angles < SLIVER_DEGREES)) if len(angles) else 0.0


def soft_boundary(vertices: Any, env: Any = None) -> float:
    """The number of vertices on the wrong side of the environment's soft boundaries (0 without any)."""
    if env is None:
        return 0.0
    return float(env.count_soft_violations(_positions(vertices)))


# --------------------------------------------------------------------------------------------------
# The registry: every criterion declared once.

Measure = Callable[[Any, Any], float]  # (phenotype, environment or None) -> raw value


@dataclass(frozen=True, slots=True)
class CriterionInfo:
    """A criterion as declared: its ``name`` (the ``crit_<name>`` column), the ``measure`` that takes a
    phenotype and its environment to the raw value, the default ``target`` and ``weight``, a short
    ``heading`` for tables, a one-line ``description`` and the ``phenotype`` kind it measures."""

    name: str
    measure: Measure
    target: float
    weight: float = 1.0
    heading: str = ""
    description: str = ""
    phenotype: str = SURFACE

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name.isidentifier():
            raise ConfigError(f"criterion name {self.name!r}: must be an identifier (it names a column)")
        if not callable(self.measure):
            raise ConfigError(f"criterion {self.name!r}: measure must be callable, got {self.measure!r}")
        checked = Criterion(self.target, self.weight, name=self.name)  # a configuration's checks
        object.__setattr__(self, "target", checked.target)
        object.__setattr__(self, "weight", checked.weight)
        if not self.heading:
            object.__setattr__(self, "heading", self.name)

    def default(self) -> Criterion:
        """The default target and weight of this criterion."""
        return Criterion(self.target, self.weight, name=self.name)


_REGISTRY: dict[str, dict[str, CriterionInfo]] = {}  # phenotype -> name -> criterion, in order


def register_criterion(info: CriterionInfo) -> CriterionInfo:
    """Declare a criterion (one entry: everything else iterates over the registry); returns it.

    A name may be declared once per phenotype. New runs store and score every registered criterion of
    their phenotype; a run keeps the criteria it was created with.
    """
    if not isinstance(info, CriterionInfo):
        raise ConfigError(f"register_criterion takes a CriterionInfo, got {type(info).__name__}")
    table = _REGISTRY.setdefault(info.phenotype, {})
    if info.name in table:
        raise ConfigError(f"criterion {info.name!r} is already registered for {info.phenotype} phenotypes")
    table[info.name] = info
    return info


def unregister_criterion(name: str, phenotype: str = SURFACE) -> None:
    """Remove a registered criterion (a plugin being unloaded, a test)."""
    _REGISTRY.get(phenotype, {}).pop(name, None)


@contextmanager
def registered(info: CriterionInfo) -> Iterator[CriterionInfo]:
    """``register_criterion(info)`` for the duration of a ``with`` block."""
    register_criterion(info)
    try:
        yield info
    finally:
        unregister_criterion(info.name, info.phenotype)


def registered_criteria(phenotype: str = SURFACE) -> tuple[CriterionInfo, ...]:
    """The criteria registered for ``phenotype``, in registration order."""
    return tuple(_REGISTRY.get(phenotype, {}).values())


def criterion_names(phenotype: str = SURFACE) -> tuple[str, ...]:
    """The names of the criteria registered for ``phenotype``, in registration order."""
    return tuple(_REGISTRY.get(phenotype, {}))


def criterion_info(name: str, phenotype: str = SURFACE) -> CriterionInfo:
    """The declaration of criterion ``name``; a ``ConfigError`` naming the registered ones otherwise."""
    info = _REGISTRY.get(phenotype, {}).get(name)
    if info is None:
        allowed = ", ".join(criterion_names(phenotype)) or "none"
        raise ConfigError(f"criterion {name!r} is not registered for {phenotype} phenotypes; "
                          f"registered: {allowed}")
    return info


def criterion_heading(name: str) -> str:
    """The short table heading of criterion ``name`` (``smoothness`` -> ``smooth``); the name itself
    when no phenotype registers it (a criterion of a plugin that is not loaded)."""
    for table in _REGISTRY.values():
        if name in table:
            return table[name].heading
    return name


def criteria_table(phenotype: str = SURFACE) -> str:
    """The registered criteria of ``phenotype`` as a Markdown table (the one in docs/run-config.md)."""
    lines = ["| criterion | raw value (V vertices, E edges) | default target | default weight |",
             "| --- | --- | --- | --- |"]
    lines += [f"| `{c.name}` | {c.description} | `{c.target!r}` | `{c.weight!r}` |"
              for c in registered_criteria(phenotype)]
    return "\n".join(lines)


def score(phenotype: Any, env: Any = None, criteria: Sequence[str] | None = None, *,
          kind: str = SURFACE) -> dict[str, float]:
    """The raw value of each of ``criteria`` (default: every criterion registered for ``kind``)
    measured on ``phenotype`` grown in ``env``, in that order."""
    names = criterion_names(kind) if criteria is None else tuple(criteria)
    return {name: float(criterion_info(name, kind).measure(phenotype, env)) for name in names}


def score_surface(surface: _SurfaceLike, env: Any = None, criteria: Sequence[str] | None = None
                  ) -> dict[str, float]:
    """The raw value of each of ``criteria`` (default: every registered surface criterion) of
    ``surface`` grown in ``env``.

    ``surface`` needs ``vertices`` (V, 3) and ``edges`` (E, 2); ``env`` needs
    ``count_soft_violations(positions)`` (``None``: no soft boundaries). A surface without vertices or
    edges has NaN for the criteria that need them.
    """
    return score(surface, env, criteria, kind=SURFACE)


# --------------------------------------------------------------------------------------------------
# Targets and weights.


def _number(value: Any, where: str) -> float:
    return read_float(value, "", where)


@dataclass(frozen=True, slots=True)
class Criterion:
    """The target and weight of one criterion; ``scale`` (default ``max(1, |target|)``) normalises the
    deviation: ``weight * |raw - target| / scale``."""

    target: float
    weight: float = 1.0
    scale: float | None = None
    name: str = field(default="criterion", compare=False, repr=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "target", _number(self.target, f"fitness.{self.name}.target"))
        weight = _number(self.weight, f"fitness.{self.name}.weight")
        if weight < 0:
            raise ConfigError(f"field 'fitness.{self.name}.weight': must be >= 0, got {weight!r}")
        object.__setattr__(self, "weight", weight)
        if self.scale is not None:
            scale = _number(self.scale, f"fitness.{self.name}.scale")
            if scale <= 0:
                raise ConfigError(f"field 'fitness.{self.name}.scale': must be > 0, got {scale!r}")
            object.__setattr__(self, "scale", scale)

    @property
    def unit(self) -> float:
        """The divisor of the deviation: ``scale`` if set, else ``max(1, |target|)``."""
        return self.scale if self.scale is not None else max(1.0, abs(self.target))

    def deviation(self, raw: float) -> float:
        """``weight * |raw - target| / unit``; ``inf`` when ``raw`` is not finite and the weight is not 0."""
        if self.weight == 0.0:
            return 0.0
        raw = float(raw)
        if not math.isfinite(raw):
            return math.inf
        return self.weight * abs(raw - self.target) / self.unit

    def to_dict(self) -> dict[str, float]:
        out = {"target": self.target, "weight": self.weight}
        if self.scale is not None:
            out["scale"] = self.scale
        return out


def _surface_arrays(surface: Any) -> tuple[np.ndarray, np.ndarray]:
    return _positions(surface.vertices), np.asarray(surface.edges, dtype=np.int64).reshape(-1, 2)


for _info in (
    CriterionInfo("size", lambda s, env: size(s.vertices), 10.0, heading="size",
                  description="x extent + y extent: `max abs(xi - xj) + max abs(yi - yj)`"),
    CriterionInfo("smoothness", lambda s, env: smoothness(*_surface_arrays(s)), 0.0, heading="smooth",
                  description="`1/2 sum_i sum_{j in N(i)} abs(zi - zj)`: z differences between "
                              "neighbours (each pair once)"),
    CriterionInfo("undulation", lambda s, env: undulation(s.vertices), 0.0, heading="undul",
                  description="z range: `max abs(zi - zj)`"),
    CriterionInfo("subdivisions", lambda s, env: subdivisions(*map(len, _surface_arrays(s))), 0.5,
                  heading="subdiv",
                  description="`V / E`: 1 for a polygon, lower as branches join into cells "
                              "(four-sided tiles after 4 steps: 289/544 = 0.53)"),
    CriterionInfo("symmetry", lambda s, env: symmetry(s.vertices), 1.0, heading="symm",
                  description="`(sym(x) + sym(y)) / 2`, `sym` the smaller over the larger vertex count "
                              "either side of the axis through the centre of the x-y bounding box; 1 "
                              "is balanced"),
    CriterionInfo("soft_boundary", lambda s, env: soft_boundary(s.vertices, env), 0.0, heading="soft",
                  description="vertices on the wrong side of the environment's soft boundaries"),
    CriterionInfo("cells", lambda s, env: cells(s), 16.0, weight=0.0, heading="cells",
                  description="regions (cells) of the map: keeps counting as branches join, where "
                              "`V / E` levels off (four-sided tiles after 3 steps: 64)"),
    CriterionInfo("slivers", lambda s, env: slivers(s), 0.0, weight=0.0, heading="sliver",
                  description="share of the regions thinner than a triangle of smallest angle 10 "
                              "degrees (meshing 1 runs: of the triangles): 0 for clean cells, near 1 for "
                              "a crumpled strip"),
):
    register_criterion(_info)

# The built-in surface criteria (runs created before the registry store the first six).
CRITERIA: tuple[str, ...] = criterion_names(SURFACE)


def _defaults() -> dict[str, dict[str, float]]:
    return {c.name: {"target": c.target, "weight": c.weight} for c in registered_criteria(SURFACE)}


DEFAULT_CRITERIA: dict[str, dict[str, float]] = _defaults()  # the built-ins' default target and weight


@dataclass(frozen=True, slots=True, init=False)
class FitnessSpec:
    """Per criterion a target and a weight; ``evaluate`` turns raw criteria into the total (lower is
    better). A spec covers a fixed list of criteria (``names``): by default every registered surface
    criterion, for a run the criteria it was created with. ``spec[name]`` and ``spec.<name>`` are the
    ``Criterion`` of one of them."""

    names: tuple[str, ...]
    criteria: tuple[Criterion, ...]

    def __init__(self, criteria: Mapping[str, Criterion] | None = None, *,
                 names: Sequence[str] | None = None, phenotype: str = SURFACE) -> None:
        given = dict(criteria or {})
        order = tuple(names) if names is not None else criterion_names(phenotype)
        unknown = [name for name in given if name not in order]
        if unknown:
            raise ConfigError(f"field 'fitness.{unknown[0]}': unknown criterion; allowed: "
                              f"{', '.join(order)}")
        out = []
        for name in order:
            value = given.get(name)
            if value is None:
                value = criterion_info(name, phenotype).default()
            elif not isinstance(value, Criterion):
                raise ConfigError(f"field 'fitness.{name}': expected a Criterion, got {value!r}")
            elif value.name != name:
                value = Criterion(value.target, value.weight, value.scale, name=name)
            out.append(value)
        object.__setattr__(self, "names", order)
        object.__setattr__(self, "criteria", tuple(out))

    def __getitem__(self, name: str) -> Criterion:
        try:
            return self.criteria[self.names.index(name)]
        except ValueError:
            raise KeyError(name) from None

    def __getattr__(self, name: str) -> Criterion:
        if name in ("names", "criteria") or name.startswith("_"):
            raise AttributeError(name)
        try:
            return self[name]
        except KeyError:
            raise AttributeError(f"FitnessSpec has no criterion {name!r}") from None

    def __getstate__(self) -> tuple[tuple[str, ...], tuple[Criterion, ...]]:
        return self.names, self.criteria

    def __setstate__(self, state: tuple[tuple[str, ...], tuple[Criterion, ...]]) -> None:
        object.__setattr__(self, "names", state[0])
        object.__setattr__(self, "criteria", state[1])

    def deviations(self, raw: Mapping[str, float]) -> dict[str, float]:
        """The weighted deviation of each criterion (``names`` order); a missing raw value is an error."""
        missing = [name for name in self.names if name not in raw]
        if missing:
            raise ValueError(f"raw criteria lack {', '.join(missing)}")
        return {c.name: c.deviation(raw[c.name]) for c in self.criteria}

    def evaluate(self, raw: Mapping[str, float]) -> float:
        """``sum_i w_i * |raw_i - target_i| / scale_i``: 0 when every target is met, lower is better."""
        return float(math.fsum(self.deviations(raw).values()))

    @classmethod
    def from_dict(cls, data: Mapping[str, Any] | None, *, source: str | None = None,
                  names: Sequence[str] | None = None, phenotype: str = SURFACE) -> FitnessSpec:
        """Build from ``{criterion: {target, weight, scale}}`` over ``names`` (default: every
        registered criterion of ``phenotype``); criteria and keys left out keep their defaults.

        Errors are ``ConfigError`` naming the field (and ``source``, a file name, when given).
        """
        try:
            return cls._from_dict({} if data is None else data, names, phenotype)
        except ConfigError as exc:
            if source is None:
                raise
            raise ConfigError(f"{source}: {exc}") from None

    @classmethod
    def _from_dict(cls, data: Mapping[str, Any], names: Sequence[str] | None,
                   phenotype: str) -> FitnessSpec:
        if not isinstance(data, Mapping):
            raise ConfigError(f"field 'fitness': must be a table, got {data!r}")
        order = tuple(names) if names is not None else criterion_names(phenotype)
        unknown = [k for k in data if k not in order]
        if unknown:
            raise ConfigError(f"field 'fitness.{unknown[0]}': unknown criterion; allowed: "
                              f"{', '.join(order)}")
        kwargs = {}
        for name, table in data.items():
            if not isinstance(table, Mapping):
                raise ConfigError(f"field 'fitness.{name}': must be a table (target, weight), got {table!r}")
            bad = [k for k in table if k not in ("target", "weight", "scale")]
            if bad:
                raise ConfigError(
                    f"field 'fitness.{name}.{bad[0]}': unknown key; allowed: target, weight, scale"
                )
            if "target" in table and "weight" in table:
                merged = dict(table)
            else:
                merged = {**criterion_info(name, phenotype).default().to_dict(), **table}
            kwargs[name] = Criterion(name=name, **merged)
        return cls(kwargs, names=order, phenotype=phenotype)

    def to_dict(self) -> dict[str, dict[str, float]]:
        """``{criterion: {target, weight[, scale]}}`` for every criterion (TOML-ready)."""
        return {c.name: c.to_dict() for c in self.criteria}

    def replace(self, changes: Mapping[str, Any]) -> FitnessSpec:
        """A copy with ``{criterion: {target/weight/scale: value}}`` merged in (an intervention)."""
        current = self.to_dict()
        for name, table in changes.items():
            if name not in self.names:
                raise ConfigError(f"field 'fitness.{name}': unknown criterion; allowed: "
                                  f"{', '.join(self.names)}")
            if isinstance(table, Criterion):
                current[name] = table.to_dict()
            elif isinstance(table, Mapping):
                current[name] = {**current[name], **table}
            else:
                raise ConfigError(f"field 'fitness.{name}': must be a table (target, weight), got {table!r}")
        return FitnessSpec.from_dict(current, names=self.names)
