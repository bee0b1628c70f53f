"""Part 1 of a derivation step (journal 4.3, step 1): increase size, forces, internal forces, boundaries.

For vertex i at ``p_i`` with mass ``m_i``, the surface centre ``c`` (mean of all vertex positions) and
the per-axis scale ``s``, in this order:

1. growth: ``r_i = (p_i - c) * (s - 1)`` (per axis; s < 1 shrinks);
2. external forces: ``f_i`` = Σ attractors/repellers (``c·d^-e/m`` or the bounded law, measured at
   ``p_i``) + gravity (the same vector for every vertex);
3. repelling points (if on): an inverse-square push between every pair of vertices (the thesis;
   ``repelling_radius`` -1, by Barnes–Hut with opening angle ``repelling_theta``), or between the
   vertices closer than ``repelling_radius`` mean edge lengths;
4. position noise (if on): a normal draw per axis, standard deviation ``position_noise`` x the mean
   edge length, from the growth's random generator;
5. constraints: cut-off (stopped) vertices do not move at all; with ``fixed_perimeter`` neither do
   perimeter vertices; with ``fixed_centre`` the mean displacement is taken back from the moving
   vertices, so the centre of the surface stays where it was and forces stretch it instead of moving it;
6. boundaries, in the order listed, resolve the move ``p_i -> q_i`` (see environment.boundaries);
   a final pass puts any vertex still on the wrong side of a hard boundary back at ``p_i`` (when
   ``p_i`` was allowed), so no vertex this part moves crosses a hard boundary.

Vertices that rewriting puts on the wrong side of a hard boundary (a new vertex on an edge that is a
chord through a sphere) are moved to the nearest allowed point of that boundary (and stopped there if
it is cut-off) by ``repair`` at the end of the derivation step (hemls.growth calls
``Environment.constrain``); ``increase_size`` repairs its input the same way first, for callers that
hand it such vertices.
"""

from __future__ import annotations

from typing import NamedTuple, Protocol

import numpy as np

from genr8_dist.environment.boundaries import Boundary
from genr8_dist.errors import GrowthError

__all__ = ["EnvironmentLike", "SizeIncrease", "increase_size", "mean_edge_length", "neighbour_average",
           "relax_cells", "repair"]

class EnvironmentLike(Protocol):
    """What the derivation step's physics reads of an environment (``genr8_dist.environment.model
    .Environment`` has it, and calls these functions from its methods)."""

    @property
    def scale(self) -> tuple[float, float, float]: ...

    @property
    def position_noise(self) -> float: ...

    @property
    def fixed_perimeter(self) -> bool: ...

    @property
    def fixed_centre(self) -> bool: ...

    @property
    def uniform_cells(self) -> bool: ...

    @property
    def uniform_iterations(self) -> int: ...

    @property
    def repelling_points(self) -> float: ...

    @property
    def boundaries(self) -> tuple[Boundary, ...]: ...

    def characteristic_length(self, step: int) -> float: ...

    def total_force(self, positions: np.ndarray, masses: np.ndarray) -> np.ndarray: ...

    def repelling(self, positions: np.ndarray, masses: np.ndarray, length: float) -> np.ndarray: ...


class SizeIncrease(NamedTuple):
    """What ``Environment.increase_size`` returns: the moved positions and the cumulative stop mask."""

    positions: np.ndarray
    stopped: np.ndarray


def mean_edge_length(positions: np.ndarray, edges: np.ndarray, fallback: float) -> float:
    """Mean length of the edges (``fallback`` when there are none or all have length 0)."""
    if len(edges) == 0:
        return fallback
    lengths = np.linalg.norm(positions[edges[:, 0]] - positions[edges[:, 1]], axis=1)
    mean = float(lengths.mean())
    return mean if mean > 0.0 and np.isfinite(mean) else fallback


def neighbour_average(positions: np.ndarray, edges: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Mean position of each vertex's edge neighbours, and how many neighbours it has."""
    n = len(positions)
    a, b = edges[:, 0], edges[:, 1]
    degree = np.bincount(a, minlength=n) + np.bincount(b, minlength=n)
    total = np.empty_like(positions)
    for axis in range(3):
        total[:, axis] = (np.bincount(a, weights=positions[b, axis], minlength=n)
                          + np.bincount(b, weights=positions[a, axis], minlength=n))
    safe = np.maximum(degree, 1)[:, None]
    return total / safe, degree


def _check(name: str, array: np.ndarray, shape: tuple[int, ...]) -> None:
    if array.shape != shape:
        raise GrowthError(f"increase_size: '{name}' has shape {array.shape}, expected {shape}")


def increase_size(env: EnvironmentLike, positions: np.ndarray, *, step: int, masses: np.ndarray,
                  stopped: np.ndarray, perimeter: np.ndarray, edges: np.ndarray,
                  rng: np.random.Generator) -> SizeIncrease:
    """Move every vertex for derivation step ``step``; returns new positions and the cumulative stop mask.

    Inputs are not modified. ``positions`` (V, 3), ``masses`` (V,), ``stopped`` and ``perimeter``
    bool (V,), ``edges`` (E, 2) vertex indices.
    """

    p = np.asarray(positions, dtype=np.float64)
    n = len(p)
    _check("positions", p, (n, 3))
    masses = np.asarray(masses, dtype=np.float64)
    stopped = np.asarray(stopped, dtype=bool)
    perimeter = np.asarray(perimeter, dtype=bool)
    edges = np.asarray(edges, dtype=np.int64).reshape(-1, 2)
    _check("masses", masses, (n,))
    _check("stopped", stopped, (n,))
    _check("perimeter", perimeter, (n,))
    if n == 0:
        return SizeIncrease(p.copy(), stopped.copy())

    stopped = stopped.copy()
    if env.boundaries:
        p = repair(env, p, stopped)
    centre = p.mean(axis=0)
    move = (p - centre) * (np.asarray(env.scale) - 1.0)
    length = 0.0
    if env.repelling_points > 0.0 or env.position_noise > 0.0:
        length = mean_edge_length(p, edges, env.characteristic_length(max(step - 1, 0)))
    move += env.total_force(p, masses)
    if env.repelling_points > 0.0:
        move += env.repelling(p, masses, length)
    if env.position_noise > 0.0:
        move += rng.normal(0.0, env.position_noise * length, size=p.shape)

    frozen = stopped.copy()
    if env.fixed_perimeter:
        frozen |= perimeter
    move[frozen] = 0.0
    if env.fixed_centre:
        moving = ~frozen
        count = int(moving.sum())
        if count:
            move[moving] -= move.sum(axis=0) / count
    q = p + move

    new_stopped = stopped.copy()
    if env.boundaries:
        q, new_stopped = _apply_boundaries(env, p, q, new_stopped)
    q[stopped] = p[stopped]
    return SizeIncrease(q, new_stopped)


def relax_cells(env: EnvironmentLike, positions: np.ndarray, *, edges: np.ndarray, perimeter: np.ndarray,
                stopped: np.ndarray) -> np.ndarray:
    """Uniform cells (thesis 2.7.2: "after each growth step, all the vertices on the perimeter are
    fixed" and the others move to even out their cells): at the end of a derivation step, with the
    perimeter and the stopped vertices held, each other vertex moves halfway towards the mean of its
    edge neighbours, ``uniform_iterations`` times. Returns new positions (the input is not modified)."""
    q = np.array(positions, dtype=np.float64, copy=True)
    edges = np.asarray(edges, dtype=np.int64).reshape(-1, 2)
    if not env.uniform_cells or len(edges) == 0:
        return q
    free = ~(np.asarray(perimeter, dtype=bool) | np.asarray(stopped, dtype=bool))
    for _ in range(env.uniform_iterations):
        average, degree = neighbour_average(q, edges)
        relax = free & (degree > 0)
        q[relax] += 0.5 * (average[relax] - q[relax])
    return q


def repair(env: EnvironmentLike, p: np.ndarray, stopped: np.ndarray) -> np.ndarray:
    """Bring vertices that start on the wrong side of a hard boundary back to its nearest allowed point.

    Rewriting places new vertices along the turtle's lines, and a new edge between two vertices that
    slid along a curved wall cuts through it (a chord of a sphere): its new vertex is then inside.
    Such a vertex goes to the nearest point of the wall (the way it is most likely to have come
    in); against a cut-off wall it also stops there. ``stopped`` is updated in place; vertices
    already stopped never move.
    """
    hard = [b for b in env.boundaries if b.hard]
    if not hard:
        return p
    p = p.copy()
    extent = float(np.max(np.abs(p)))
    for _ in range(2 if len(hard) > 1 else 1):  # a second pass settles vertices between two walls
        for b in hard:
            bad = np.flatnonzero((b.violation(p) > 0.0) & ~stopped)
            if len(bad):
                p[bad] = b.project(p[bad], extent)
                if b.rule.stops:
                    stopped[bad] = True
    return p


def _apply_boundaries(env: EnvironmentLike, p: np.ndarray, q: np.ndarray, stopped: np.ndarray
                      ) -> tuple[np.ndarray, np.ndarray]:
    """Resolve each vertex's move p -> q against the boundaries (slide, cut-off, reflect; soft passes)."""
    extent = float(np.max(np.abs(q))) if len(q) else 1.0
    hard = [b for b in env.boundaries if b.hard]
    touched = np.zeros(len(q), dtype=bool)
    for b in hard:
        bad = np.flatnonzero(b.violation(q) > 0.0)
        if len(bad) == 0:
            continue
        touched[bad] = True
        rule = b.rule
        q[bad] = rule.resolve(b, p[bad], q[bad], extent)
        if rule.stops:
            stopped[bad] = True
    idx = np.flatnonzero(touched)
    if len(idx):
        # A later boundary may have pushed a vertex across an earlier one (or rounding left it a hair
        # outside): put it back where it was when that was allowed. Untouched vertices are fine.
        wrong = np.zeros(len(idx), dtype=bool)
        for b in hard:
            wrong |= b.violation(q[idx]) > 0.0
        if np.any(wrong):
            idx = idx[wrong]
            start_ok = np.ones(len(idx), dtype=bool)
            for b in hard:
                start_ok &= b.violation(p[idx]) <= 0.0
            q[idx[start_ok]] = p[idx[start_ok]]
    return q, stopped
