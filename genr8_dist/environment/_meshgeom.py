"""Point-to-triangle-mesh geometry in plain numpy: closest points and inside tests.

trimesh's own proximity and containment queries need rtree or embree, which genr8_dist does not
require; boundary meshes are small (hundreds to a few thousand triangles), so a chunked brute force
over (points x triangles) is fast enough and has no extra dependency.
"""

from __future__ import annotations

import numpy as np

__all__ = ["closest_on_triangles", "winding_numbers"]

_CHUNK = 250_000  # points x triangles handled per block (bounds the temporary arrays to ~100 MB)


def _closest_block(p: np.ndarray, a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """Closest points (n, T, 3) on every triangle (a, b, c: (T, 3)) to every point p (n, 3).

    Ericson, *Real-Time Collision Detection*, 5.1.5, over all pairs at once.
    """
    p = p[:, None, :]
    ab = b - a
    ac = c - a
    ap = p - a
    d1 = np.einsum("tk,ntk->nt", ab, ap)
    d2 = np.einsum("tk,ntk->nt", ac, ap)
    bp = p - b
    d3 = np.einsum("tk,ntk->nt", ab, bp)
    d4 = np.einsum("tk,ntk->nt", ac, bp)
    cp = p - c
    d5 = np.einsum("tk,ntk->nt", ab, cp)
    d6 = np.einsum("tk,ntk->nt", ac, cp)
    vc = d1 * d4 - d3 * d2
    vb = d5 * d2 - d1 * d6
    va = d3 * d6 - d5 * d4
    with np.errstate(divide="ignore", invalid="ignore"):
        v_ab = d1 / (d1 - d3)
        w_ac = d2 / (d2 - d6)
        w_bc = (d4 - d3) / ((d4 - d3) + (d5 - d6))
        denom = va + vb + vc
        v_in = vb / denom
        w_in = vc / denom
    shape = d1.shape
    conditions = [
        (d1 <= 0) & (d2 <= 0),
        (d3 >= 0) & (d4 <= d3),
        (vc <= 0) & (d1 >= 0) & (d3 <= 0),
        (d6 >= 0) & (d5 <= d6),
        (vb <= 0) & (d2 >= 0) & (d6 <= 0),
        (va <= 0) & ((d4 - d3) >= 0) & ((d5 - d6) >= 0),
    ]
    out = np.empty((*shape, 3))
    for k in range(3):
        ak = np.broadcast_to(a[None, :, k], shape)
        bk = np.broadcast_to(b[None, :, k], shape)
        ck = np.broadcast_to(c[None, :, k], shape)
        choices = [
            ak,
            bk,
            ak + v_ab * ab[None, :, k],
            ck,
            ak + w_ac * ac[None, :, k],
            bk + w_bc * (ck - bk),
        ]
        interior = ak + ab[None, :, k] * v_in + ac[None, :, k] * w_in
        out[..., k] = np.select(conditions, choices, default=interior)
    return out


def closest_on_triangles(points: np.ndarray, triangles: np.ndarray
                         ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """For each point, the closest point on the triangle soup ``triangles`` (T, 3, 3).

    Returns ``(closest (N, 3), distance (N,), triangle index (N,))``.
    """
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    n = len(points)
    closest = np.empty((n, 3))
    distance = np.empty(n)
    index = np.empty(n, dtype=np.int64)
    if n == 0:
        return closest, distance, index
    a, b, c = triangles[:, 0], triangles[:, 1], triangles[:, 2]
    step = max(1, _CHUNK // max(1, len(triangles)))
    for start in range(0, n, step):
        block = points[start:start + step]
        cand = _closest_block(block, a, b, c)
        d2 = np.sum((cand - block[:, None, :]) ** 2, axis=2)
        best = np.argmin(d2, axis=1)
        rows = np.arange(len(block))
        closest[start:start + step] = cand[rows, best]
        distance[start:start + step] = np.sqrt(d2[rows, best])
        index[start:start + step] = best
    return closest, distance, index


def winding_numbers(points: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """The generalised winding number of a closed triangle mesh around each point (about ±1 inside, 0 out).

    Van Oosterom and Strackee's solid angle of each triangle, summed and divided by 4π; robust for
    watertight meshes whatever the orientation of their faces (use the absolute value).
    """
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    out = np.empty(len(points))
    step = max(1, _CHUNK // max(1, len(triangles)))
    for start in range(0, len(points), step):
        block = points[start:start + step][:, None, :]
        a = triangles[None, :, 0] - block
        b = triangles[None, :, 1] - block
        c = triangles[None, :, 2] - block
        la = np.linalg.norm(a, axis=2)
        lb = np.linalg.norm(b, axis=2)
        lc = np.linalg.norm(c, axis=2)
        numer = np.einsum("ntk,ntk->nt", a, np.cross(b, c))
        denom = (la * lb * lc + np.einsum("ntk,ntk->nt", a, b) * lc
                 + np.einsum("ntk,ntk->nt", a, c) * lb + np.einsum("ntk,ntk->nt", b, c) * la)
        out[start:start + step] = np.sum(np.arctan2(numer, denom), axis=1) / (2.0 * np.pi)
    return out
