"""Point-to-triangle-mesh queries for mesh boundaries: exact closest points and inside/outside.

A k-d tree over the triangles' centroids (scipy) narrows each query to the triangles that can hold
the closest point: if the nearest centroid's triangle is at distance ``u``, the closest triangle's
centroid is within ``u + R`` (R the largest centroid-to-corner distance). The closest point on each
candidate is exact (Ericson, *Real-Time Collision Detection* 5.1.5), and which side a point is on
comes from the angle-weighted pseudo-normal of the closest feature (face, edge or vertex; Bærentzen
and Aanæs 2005), which is exact for a closed, consistently oriented mesh.
"""

from __future__ import annotations

import numpy as np

__all__ = ["TriangleMesh"]

# Ericson's Voronoi regions, in the order the closest-point test checks them
_VERTEX_A, _VERTEX_B, _EDGE_AB, _VERTEX_C, _EDGE_AC, _EDGE_BC, _FACE = range(7)
_K = 16  # nearest centroids fetched per point before falling back to a ball query


def _closest_pairs(p: np.ndarray, a: np.ndarray, b: np.ndarray, c: np.ndarray
                   ) -> tuple[np.ndarray, np.ndarray]:
    """Closest point on triangle (a_k, b_k, c_k) to p_k for aligned (P, 3) arrays, and its region."""
    ab = b - a
    ac = c - a
    ap = p - a
    bp = p - b
    cp = p - c
    d1 = np.einsum("ij,ij->i", ab, ap)
    d2 = np.einsum("ij,ij->i", ac, ap)
    d3 = np.einsum("ij,ij->i", ab, bp)
    d4 = np.einsum("ij,ij->i", ac, bp)
    d5 = np.einsum("ij,ij->i", ab, cp)
    d6 = np.einsum("ij,ij->i", ac, cp)
    vc = d1 * d4 - d3 * d2
    vb = d5 * d2 - d1 * d6
    va = d3 * d6 - d5 * d4
    region = np.full(len(p), _FACE, dtype=np.int8)
    conditions = [
        (d1 <= 0) & (d2 <= 0),
        (d3 >= 0) & (d4 <= d3),
        (vc <= 0) & (d1 >= 0) & (d3 <= 0),
        (d6 >= 0) & (d5 <= d6),
        (vb <= 0) & (d2 >= 0) & (d6 <= 0),
        (va <= 0) & ((d4 - d3) >= 0) & ((d5 - d6) >= 0),
    ]
    for code in range(5, -1, -1):  # the first matching condition wins
        region[conditions[code]] = code
    with np.errstate(divide="ignore", invalid="ignore"):
        t_ab = d1 / (d1 - d3)
        t_ac = d2 / (d2 - d6)
        t_bc = (d4 - d3) / ((d4 - d3) + (d5 - d6))
        denom = va + vb + vc
        v = vb / denom
        w = vc / denom
    out = a + ab * v[:, None] + ac * w[:, None]
    for code, point in ((_VERTEX_A, a), (_VERTEX_B, b), (_VERTEX_C, c),
                        (_EDGE_AB, a + ab * t_ab[:, None]), (_EDGE_AC, a + ac * t_ac[:, None]),
                        (_EDGE_BC, b + (c - b) * t_bc[:, None])):
        pick = region == code
        out[pick] = point[pick]
    return out, region


class TriangleMesh:
    """A triangle mesh prepared for closest-point and side queries.

    ``vertices`` (V, 3) and ``faces`` (T, 3) must have no degenerate triangles; for a closed mesh
    the faces should wind counter-clockwise seen from outside (the normals point out).
    """

    def __init__(self, vertices: np.ndarray, faces: np.ndarray) -> None:
        from scipy.spatial import cKDTree

        self.vertices = np.asarray(vertices, dtype=np.float64)
        self.faces = np.asarray(faces, dtype=np.int64)
        tri = self.vertices[self.faces]
        self.triangles = tri
        normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        self.face_normals = normal / np.linalg.norm(normal, axis=1, keepdims=True)
        # angle-weighted vertex pseudo-normals
        vertex_normals = np.zeros_like(self.vertices)
        for k in range(3):
            e1 = tri[:, (k + 1) % 3] - tri[:, k]
            e2 = tri[:, (k + 2) % 3] - tri[:, k]
            cos = np.einsum("ij,ij->i", e1, e2) / (np.linalg.norm(e1, axis=1) * np.linalg.norm(e2, axis=1))
            angle = np.arccos(np.clip(cos, -1.0, 1.0))
            weighted = angle[:, None] * self.face_normals
            for axis in range(3):
                vertex_normals[:, axis] += np.bincount(self.faces[:, k], weights=weighted[:, axis],
                                                       minlength=len(self.vertices))
        self.vertex_normals = vertex_normals
        # edge pseudo-normals: the sum of the normals of the faces sharing the edge, per face edge
        # (face edge 0 = ab, 1 = bc, 2 = ca)
        pairs = np.stack([self.faces[:, [0, 1]], self.faces[:, [1, 2]], self.faces[:, [2, 0]]], axis=1)
        keys = np.sort(pairs.reshape(-1, 2), axis=1)
        _, inverse = np.unique(keys, axis=0, return_inverse=True)
        inverse = inverse.reshape(-1)
        repeated = np.repeat(self.face_normals, 3, axis=0)
        sums = np.stack([np.bincount(inverse, weights=repeated[:, axis]) for axis in range(3)], axis=1)
        self.edge_normals = sums[inverse].reshape(-1, 3, 3)
        self.centroids = tri.mean(axis=1)
        self.reach = float(np.max(np.linalg.norm(tri - self.centroids[:, None, :], axis=2)))
        self._tree = cKDTree(self.centroids)

    def _best_of(self, points: np.ndarray, todo: np.ndarray, owner: np.ndarray, candidates: np.ndarray,
                 closest: np.ndarray, dist2: np.ndarray, face: np.ndarray, feature: np.ndarray) -> None:
        """Set, for each point in ``todo``, the nearest of its candidate triangles (``owner`` says whose
        candidate each is, grouped by point in ``todo`` order). Ties go to the lower triangle index."""
        tri = self.triangles[candidates]
        cand, region = _closest_pairs(points[owner], tri[:, 0], tri[:, 1], tri[:, 2])
        d2 = np.sum((cand - points[owner]) ** 2, axis=1)
        order = np.lexsort((candidates, d2, owner))
        first = np.ones(len(order), dtype=bool)
        first[1:] = owner[order][1:] != owner[order][:-1]
        best = order[first]
        who = owner[best]
        closest[who] = cand[best]
        dist2[who] = d2[best]
        face[who] = candidates[best]
        feature[who] = region[best]

    def query(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """For each point: the closest point of the mesh, the distance, and whether it is inside.

        "Inside" is the side the pseudo-normal at the closest point faces away from.
        """
        points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        n = len(points)
        closest = np.zeros((n, 3))
        dist2 = np.full(n, np.inf)
        face = np.zeros(n, dtype=np.int64)
        feature = np.zeros(n, dtype=np.int8)
        todo = np.arange(n)
        k = min(_K, len(self.triangles))
        # round 1: the k nearest centroids. The best of their triangles is exact once no other triangle
        # can be closer, i.e. once the k-th centroid is farther than that distance plus ``reach``.
        near_d, near = self._tree.query(points, k=k)
        near_d = near_d.reshape(n, k)
        near = near.reshape(n, k)
        tri = self.triangles[near.reshape(-1)]
        owner = np.repeat(todo, k)
        cand, region = _closest_pairs(points[owner], tri[:, 0], tri[:, 1], tri[:, 2])
        d2 = np.sum((cand - points[owner]) ** 2, axis=1).reshape(n, k)
        pick = np.argmin(d2, axis=1)  # ties: the nearer centroid (the tree's order) wins
        flat = np.arange(n) * k + pick
        closest[:] = cand[flat]
        dist2[:] = d2[np.arange(n), pick]
        face[:] = near[np.arange(n), pick]
        feature[:] = region[flat]
        settled = (np.sqrt(dist2) <= near_d[:, -1] - self.reach) | (k == len(self.triangles))
        todo = todo[~settled]
        if len(todo):
            # round 2, for points far from the mesh: every centroid within (best so far + reach)
            radius = np.sqrt(dist2[todo]) + self.reach
            lists = self._tree.query_ball_point(points[todo], radius * (1.0 + 1e-9) + 1e-12,
                                                return_sorted=True)
            counts = np.fromiter((len(x) for x in lists), dtype=np.int64, count=len(todo))
            candidates = np.fromiter((t for x in lists for t in x), dtype=np.int64, count=int(counts.sum()))
            self._best_of(points, todo, np.repeat(todo, counts), candidates, closest, dist2, face, feature)
        pseudo = self.face_normals[face].copy()
        corner = self.faces[face]
        for code, j in ((_VERTEX_A, 0), (_VERTEX_B, 1), (_VERTEX_C, 2)):
            chosen = feature == code
            pseudo[chosen] = self.vertex_normals[corner[chosen, j]]
        for code, j in ((_EDGE_AB, 0), (_EDGE_BC, 1), (_EDGE_AC, 2)):
            chosen = feature == code
            pseudo[chosen] = self.edge_normals[face[chosen], j]
        inside = np.einsum("ij,ij->i", points - closest, pseudo) < 0.0
        return closest, np.sqrt(dist2), inside
