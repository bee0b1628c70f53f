"""The fitness of a grown surface: six criteria, each with a target and a weight (thesis 4.3.1, journal 5.3).

A *criterion* is a raw measurement of the surface (its size, how smooth it is, ...). The designer sets a
*target* and a *weight* for each one; the fitness is the weighted sum of the deviations from the targets,
so **lower is better** and 0 means every target is met::

    F_tot = sum_i  w_i * |F_i - t_i| / s_i

where ``F_i`` is the raw value, ``t_i`` the target, ``w_i >= 0`` the weight and ``s_i`` the criterion's
*scale*: by default ``max(1, |t_i|)``, so a deviation is relative to the target when the target is larger
than 1 (a size of 12 against a target of 10 costs 0.2) and absolute otherwise (a symmetry of 0.8
against 1 costs 0.2; a soft-boundary count of 3 against 0 costs 3). A scale can be set per criterion.
Every raw value is kept next to the total, so a run's history can be re-weighted afterwards.

The criteria, in the order ``CRITERIA`` lists them (V vertices with positions (x, y, z), E edges):

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

Genr8's own default targets and weights are not in the sources we have; ``DEFAULT_CRITERIA`` holds
ours, chosen for the default environment (start length 1, scale 1.5, 4 steps: a seed of side 1 grows
to about 5 by 5, so size ~10): a flat (smoothness 0, undulation 0), moderately subdivided (0.5),
balanced (symmetry 1) surface of size 10 that stays inside its soft boundaries.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np

from genr8_dist.errors import ConfigError

__all__ = [
    "CRITERIA",
    "DEFAULT_CRITERIA",
    "Criterion",
    "FitnessSpec",
    "score_surface",
    "size",
    "smoothness",
    "soft_boundary",
    "subdivisions",
    "symmetry",
    "undulation",
]

CRITERIA: tuple[str, ...] = ("size", "smoothness", "undulation", "subdivisions", "symmetry", "soft_boundary")
_ALLOWED = ", ".join(CRITERIA)


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
        return e
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


def soft_boundary(vertices: Any, env: Any = None) -> float:
    """The number of vertices on the wrong side of the environment's soft boundaries (0 without any)."""
    if env is None:
        return 0.0
    return float(env.count_soft_violations(_positions(vertices)))


def score_surface(surface: _SurfaceLike, env: Any = None) -> dict[str, float]:
    """The raw value of every criterion of ``surface`` grown in ``env``, keyed as ``CRITERIA`` orders them.

    ``surface`` needs ``vertices`` (V, 3) and ``edges`` (E, 2); ``env`` needs
    ``count_soft_violations(positions)`` (``None``: no soft boundaries). A surface without vertices or
    edges has NaN for the criteria that need them.
    """
    pos = _positions(surface.vertices)
    edges = np.asarray(surface.edges, dtype=np.int64).reshape(-1, 2)
    return {
        "size": size(pos),
        "smoothness": smoothness(pos, edges),
        "undulation": undulation(pos),
        "subdivisions": subdivisions(len(pos), len(edges)),
        "symmetry": symmetry(pos),
        "soft_boundary": soft_boundary(pos, env),
    }


# --------------------------------------------------------------------------------------------------
# Targets and weights.


def _number(value: Any, where: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ConfigError(f"field '{where}': must be a number, got {value!r}")
    value = float(value)
    if not math.isfinite(value):
        raise ConfigError(f"field '{where}': must be finite, got {value!r}")
    return value


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


DEFAULT_CRITERIA: dict[str, dict[str, float]] = {
    "size": {"target": 10.0, "weight": 1.0},
    "smoothness": {"target": 0.0, "weight": 1.0},
    "undulation": {"target": 0.0, "weight": 1.0},
    "subdivisions": {"target": 0.5, "weight": 1.0},
    "symmetry": {"target": 1.0, "weight": 1.0},
    "soft_boundary": {"target": 0.0, "weight": 1.0},
}


def _default(name: str) -> Criterion:
    return Criterion(name=name, **DEFAULT_CRITERIA[name])


@dataclass(frozen=True, slots=True)
class FitnessSpec:
    """Per criterion a target and a weight; ``evaluate`` turns raw criteria into the total (lower is
    better)."""

    size: Criterion = field(default_factory=lambda: _default("size"))
    smoothness: Criterion = field(default_factory=lambda: _default("smoothness"))
    undulation: Criterion = field(default_factory=lambda: _default("undulation"))
    subdivisions: Criterion = field(default_factory=lambda: _default("subdivisions"))
    symmetry: Criterion = field(default_factory=lambda: _default("symmetry"))
    soft_boundary: Criterion = field(default_factory=lambda: _default("soft_boundary"))

    def __post_init__(self) -> None:
        for name in CRITERIA:
            value = getattr(self, name)
            if not isinstance(value, Criterion):
                raise ConfigError(f"field 'fitness.{name}': expected a Criterion, got {value!r}")
            if value.name != name:
                object.__setattr__(self, name, Criterion(value.target, value.weight, value.scale, name=name))

    def __getitem__(self, name: str) -> Criterion:
        if name not in CRITERIA:
            raise KeyError(name)
        return getattr(self, name)

    def deviations(self, raw: Mapping[str, float]) -> dict[str, float]:
        """The weighted deviation of each criterion (``CRITERIA`` order); a missing raw value is an error."""
        missing = [name for name in CRITERIA if name not in raw]
        if missing:
            raise ValueError(f"raw criteria lack {', '.join(missing)}")
        return {name: self[name].deviation(raw[name]) for name in CRITERIA}

    def evaluate(self, raw: Mapping[str, float]) -> float:
        """``sum_i w_i * |raw_i - target_i| / scale_i``: 0 when every target is met, lower is better."""
        return float(math.fsum(self.deviations(raw).values()))

    @classmethod
    def from_dict(cls, data: Mapping[str, Any] | None, *, source: str | None = None) -> FitnessSpec:
        """Build from ``{criterion: {target, weight, scale}}``; criteria and keys left out keep defaults.

        Errors are ``ConfigError`` naming the field (and ``source``, a file name, when given).
        """
        try:
            return cls._from_dict({} if data is None else data)
        except ConfigError as exc:
            if source is None:
                raise
            raise ConfigError(f"{source}: {exc}") from None

    @classmethod
    def _from_dict(cls, data: Mapping[str, Any]) -> FitnessSpec:
        if not isinstance(data, Mapping):
            raise ConfigError(f"field 'fitness': must be a table, got {data!r}")
        unknown = [k for k in data if k not in CRITERIA]
        if unknown:
            raise ConfigError(f"field 'fitness.{unknown[0]}': unknown criterion; allowed: {_ALLOWED}")
        kwargs = {}
        for name, table in data.items():
            if not isinstance(table, Mapping):
                raise ConfigError(f"field 'fitness.{name}': must be a table (target, weight), got {table!r}")
            bad = [k for k in table if k not in ("target", "weight", "scale")]
            if bad:
                raise ConfigError(
                    f"field 'fitness.{name}.{bad[0]}': unknown key; allowed: target, weight, scale"
                )
            merged = {**DEFAULT_CRITERIA[name], **table}
            kwargs[name] = Criterion(name=name, **merged)
        return cls(**kwargs)

    def to_dict(self) -> dict[str, dict[str, float]]:
        """``{criterion: {target, weight[, scale]}}`` for every criterion (TOML-ready)."""
        return {name: self[name].to_dict() for name in CRITERIA}

    def replace(self, changes: Mapping[str, Any]) -> FitnessSpec:
        """A copy with ``{criterion: {target/weight/scale: value}}`` merged in (an intervention)."""
        current = self.to_dict()
        for name, table in changes.items():
            if name not in CRITERIA:
                raise ConfigError(f"field 'fitness.{name}': unknown criterion; allowed: {_ALLOWED}")
            if isinstance(table, Criterion):
                current[name] = table.to_dict()
            elif isinstance(table, Mapping):
                current[name] = {**current[name], **table}
            else:
                raise ConfigError(f"field 'fitness.{name}': must be a table (target, weight), got {table!r}")
        return FitnessSpec.from_dict(current)
