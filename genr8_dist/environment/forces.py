"""External forces (thesis 2.7.1) and the repelling-points internal force (2.7.2), vectorised over vertices.

Each law returns a *displacement* per derivation step (Genr8's forces act directly on positions, as
journal section 4.7 has it: the force vector is added to the growth displacement).

Attractors and repellers are point charges with a constant ``c >= 0`` and an exponent ``e >= 0``;
for a vertex of mass ``m`` at distance ``d`` the displacement's magnitude is

- ``law = "inverse"`` (Genr8's default): ``f = c · d^-e / m``, singular at ``d = 0``; with the
  default ``e = 2`` it is the inverse-square law of the journal;
- ``law = "bounded"`` (thesis 2.7.1's function without the singularity): ``f = c · d^-e / m`` for
  ``d > 1`` and ``f = c · d`` for ``d <= 1`` (the mass is not in the near part, as the thesis writes
  it), so it rises linearly from 0 at the charge to ``c`` at distance 1; it is continuous there when
  ``m = 1`` (the default vertex mass).

An attractor moves the vertex towards itself, a repeller away from itself. Gravity is a uniform
displacement vector, the same for every vertex whatever its mass or position.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from genr8_dist.fields import fail, read_choice, read_float, read_vec3, reject_unknown

__all__ = ["LAWS", "PointForce", "point_force_displacement", "repelling_displacement"]

LAWS = ("inverse", "bounded")


@dataclass(frozen=True)
class PointForce:
    """An attractor or a repeller: ``position``, ``constant`` c, ``exponent`` e, and the ``law``."""

    position: tuple[float, float, float] = (0.0, 0.0, 0.0)
    constant: float = 1.0
    exponent: float = 2.0
    law: str = "inverse"

    def __post_init__(self) -> None:
        where = "point force"
        object.__setattr__(self, "position", read_vec3(self.position, where, "position"))
        object.__setattr__(self, "constant", read_float(self.constant, where, "constant", minimum=0.0))
        object.__setattr__(self, "exponent", read_float(self.exponent, where, "exponent", minimum=0.0))
        read_choice(self.law, where, "law", LAWS)

    def magnitude(self, distance: np.ndarray, mass: np.ndarray) -> np.ndarray:
        """``f(d, m)`` of this charge's law (see the module docstring), elementwise."""
        d = np.asarray(distance, dtype=np.float64)
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            far = self.constant * np.power(d, -self.exponent) / mass
            if self.law == "bounded":
                result: np.ndarray = np.where(d > 1.0, far, self.constant * d * np.ones_like(mass))
                return result
            return np.where(d > 0.0, far, 0.0)

    def to_dict(self) -> dict[str, Any]:
        """The TOML table of this charge."""
        return {"position": list(self.position), "constant": self.constant, "exponent": self.exponent,
                "law": self.law}

    @classmethod
    def from_dict(cls, data: Any, source: str, where: str) -> PointForce:
        """Build from a TOML table; messages name ``source`` and ``where`` (e.g. ``repellers[0]``)."""
        if not isinstance(data, dict):
            raise fail(source, where, f"must be a table, got {data!r}")
        reject_unknown(data, [f.name for f in dataclasses.fields(cls)], source, where)
        checked: dict[str, Any] = {}
        if "position" in data:
            checked["position"] = read_vec3(data["position"], source, f"{where}.position")
        if "constant" in data:
            checked["constant"] = read_float(data["constant"], source, f"{where}.constant", minimum=0.0)
        if "exponent" in data:
            checked["exponent"] = read_float(data["exponent"], source, f"{where}.exponent", minimum=0.0)
        if "law" in data:
            checked["law"] = read_choice(data["law"], source, f"{where}.law", LAWS)
        return cls(**checked)


def point_force_displacement(points: np.ndarray, masses: np.ndarray, force: PointForce,
                             sign: float) -> np.ndarray:
    """The displacement (V, 3) of each vertex from one charge; ``sign`` +1 attracts, -1 repels."""
    towards = np.asarray(force.position) - points
    distance = np.linalg.norm(towards, axis=1)
    magnitude = force.magnitude(distance, masses)
    with np.errstate(divide="ignore", invalid="ignore"):
        unit = np.where(distance[:, None] > 0, towards / np.where(distance > 0, distance, 1.0)[:, None], 0.0)
    out = sign * magnitude[:, None] * unit
    return np.where(np.isfinite(out), out, 0.0)


def _pairs_within(points: np.ndarray, radius: float) -> tuple[np.ndarray, np.ndarray]:
    """Index pairs (i < j) of points closer than ``radius``, in lexicographic order (a k-d tree)."""
    from scipy.spatial import cKDTree

    empty = np.zeros(0, dtype=np.int64)
    if len(points) < 2 or radius <= 0.0:
        return empty, empty
    pairs = cKDTree(points).query_pairs(radius, output_type="ndarray").astype(np.int64).reshape(-1, 2)
    pairs.sort(axis=1)
    pairs = pairs[np.lexsort((pairs[:, 1], pairs[:, 0]))]  # a fixed order: sums are bit-reproducible
    close = np.sum((points[pairs[:, 0]] - points[pairs[:, 1]]) ** 2, axis=1) < radius * radius
    return pairs[close, 0], pairs[close, 1]


def _push(delta: np.ndarray, length: float, radius: float) -> np.ndarray:
    """Each pair's push (L/d)^2 - (L/R)^2 along ``delta`` (from j to i), as a vector; 0 at d = 0."""
    d2 = np.einsum("ij,ij->i", delta, delta)
    ok = d2 > 0.0
    safe = np.where(ok, d2, 1.0)
    tail = 0.0 if math.isinf(radius) else (length / radius) ** 2
    magnitude = np.where(ok, length * length / safe - tail, 0.0)
    result: np.ndarray = (magnitude / np.sqrt(safe))[:, None] * delta
    return result


def repelling_displacement(points: np.ndarray, masses: np.ndarray, strength: float, radius: float,
                           length: float, block: int = 2_000_000, theta: float = 0.0) -> np.ndarray:
    """Repelling points (thesis 2.7.2): every vertex pushes every other vertex away.

    The displacement of vertex i is ``strength · L · Σ_j ((L / d_ij)^2 - (L / R)^2) · û_ij / m_i``
    (û_ij the unit vector from j to i, L the mean edge length): an inverse-square push, over every
    other vertex when ``radius`` R is infinite (the thesis), else over the vertices closer than R (a
    k-d tree, about O(V log V)), shifted so that it falls to 0 at R instead of stopping short. Every
    other vertex is summed by Barnes–Hut with opening angle ``theta`` (O(V log V),
    genr8_dist.environment.barnes_hut), or exactly with ``theta`` 0 (all pairs, ``block`` at a
    time, O(V^2)).
    """
    out = np.zeros_like(points)
    n = len(points)
    if n < 2:
        return out
    if math.isinf(radius) and theta > 0.0:
        from genr8_dist.environment.barnes_hut import inverse_square_field

        result: np.ndarray = strength * length ** 3 * inverse_square_field(points, theta) / masses[:, None]
        return result
    if math.isinf(radius):
        rows = max(1, block // n)
        for r0 in range(0, n, rows):
            delta = points[r0:r0 + rows, None, :] - points[None, :, :]  # (rows, n, 3): from j to i
            flat = _push(delta.reshape(-1, 3), length, radius).reshape(delta.shape)
            out[r0:r0 + rows] = flat.sum(axis=1)
        result = strength * length * out / masses[:, None]
        return result
    i, j = _pairs_within(points, radius)
    if len(i) == 0:
        return out
    push = _push(points[i] - points[j], length, radius)
    for axis in range(3):
        out[:, axis] += np.bincount(i, weights=push[:, axis], minlength=n)
        out[:, axis] -= np.bincount(j, weights=push[:, axis], minlength=n)
    result = strength * length * out / masses[:, None]
    return result
