"""The map as growable half-edge arrays: vertices, edges, their labels and ages, and the faces.

Edge e has half-edges 2e (start to end) and 2e+1 (end to start); ``nxt``/``prv`` link the half-edges
around each face, faces lying to the left of their half-edges (face 0 is the outside). Every
operation is vectorized over all edges, so a derivation step costs a bounded number of passes.
"""

from __future__ import annotations

import math
from types import ModuleType
from typing import overload

import numpy as np

from genr8_dist.environment import Environment
from genr8_dist.errors import GrowthError
from genr8_dist.hemls.rules import CompiledSystem
from genr8_dist.hemls.surface import Surface

__all__ = ["HalfEdgeMap", "cross", "frames", "regular_polygon", "seed_map"]


def cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise cross product of two (n, 3) arrays (np.cross costs more than the work on small maps)."""
    out = np.empty(a.shape)
    out[:, 0] = a[:, 1] * b[:, 2] - a[:, 2] * b[:, 1]
    out[:, 1] = a[:, 2] * b[:, 0] - a[:, 0] * b[:, 2]
    out[:, 2] = a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]
    return out


_XYZ = np.arange(3)
_PAIR = np.arange(2)


class HalfEdgeMap:
    """Growable half-edge arrays; see the module docstring."""

    def __init__(self, positions: np.ndarray, masses: np.ndarray, labels: np.ndarray,
                 reversed_: np.ndarray) -> None:
        n = len(positions)
        cap_v, cap_e = max(64, 4 * n), max(64, 4 * n)
        self.pos = np.zeros((cap_v, 3))
        self.mass = np.zeros(cap_v)
        self.stopped = np.zeros(cap_v, dtype=bool)
        self.pos[:n] = positions
        self.mass[:n] = masses
        self.nv = n
        self.ev = np.zeros((cap_e, 2), dtype=np.int64)
        self.label = np.zeros(cap_e, dtype=np.int64)
        self.age = np.zeros(cap_e, dtype=np.int64)
        self.alive = np.zeros(cap_e, dtype=bool)
        self.up = np.zeros((cap_e, 3))  # the surface normal each edge was drawn with (a fallback)
        self.nxt = np.full(2 * cap_e, -1, dtype=np.int64)
        self.prv = np.full(2 * cap_e, -1, dtype=np.int64)
        self.face = np.zeros(2 * cap_e, dtype=np.int64)
        self.ne = n
        k = np.arange(n)
        a, b = k, (k + 1) % n
        self.ev[:n, 0] = np.where(reversed_, b, a)
        self.ev[:n, 1] = np.where(reversed_, a, b)
        self.label[:n] = labels
        self.alive[:n] = True
        centre = positions.mean(axis=0)
        following = np.concatenate([positions[1:], positions[:1]])   # np.roll(positions, -1, axis=0)
        normal = cross(positions - centre, following - centre).sum(axis=0)
        norm = float(np.linalg.norm(normal))
        self.up[:n] = normal / norm if norm > 1e-300 else (0.0, 0.0, 1.0)
        path = 2 * k + reversed_.astype(np.int64)  # half-edges along the polygon (counter-clockwise)
        back = path ^ 1
        self.nxt[path] = np.concatenate([path[1:], path[:1]])
        self.nxt[back] = np.concatenate([back[-1:], back[:-1]])
        self.face[path] = 1
        self.face[back] = 0
        self._relink_prev()
        self.nf = 2  # face 0 = outside, face 1 = the seed polygon
        self.kernels: ModuleType | None = None  # the compiled kernels its growth uses, if any

    # -- capacity ------------------------------------------------------------------------------
    def reserve(self, nv: int, ne: int) -> None:
        if nv > len(self.pos):
            cap = max(nv, 2 * len(self.pos))
            for name in ("pos", "mass", "stopped"):
                old = getattr(self, name)
                new = np.zeros((cap, *old.shape[1:]), dtype=old.dtype)
                new[:self.nv] = old[:self.nv]
                setattr(self, name, new)
        if ne > len(self.ev):
            cap = max(ne, 2 * len(self.ev))
            for name in ("ev", "label", "age", "alive", "up"):
                old = getattr(self, name)
                new = np.zeros((cap, *old.shape[1:]), dtype=old.dtype)
                new[:self.ne] = old[:self.ne]
                setattr(self, name, new)
            for name, fill in (("nxt", -1), ("prv", -1), ("face", 0)):
                old = getattr(self, name)
                new = np.full(2 * cap, fill, dtype=np.int64)
                new[:2 * self.ne] = old[:2 * self.ne]
                setattr(self, name, new)

    # -- derived ---------------------------------------------------------------------------------
    @overload
    def origin(self, h: int) -> np.int64: ...

    @overload
    def origin(self, h: np.ndarray) -> np.ndarray: ...

    def origin(self, h: int | np.ndarray) -> np.int64 | np.ndarray:
        """The vertex half-edge(s) ``h`` leave."""
        found: np.int64 | np.ndarray = self.ev[h >> 1, h & 1]
        return found

    @overload
    def dest(self, h: int) -> np.int64: ...

    @overload
    def dest(self, h: np.ndarray) -> np.ndarray: ...

    def dest(self, h: int | np.ndarray) -> np.int64 | np.ndarray:
        """The vertex half-edge(s) ``h`` reach."""
        found: np.int64 | np.ndarray = self.ev[h >> 1, 1 - (h & 1)]
        return found

    def alive_halves(self) -> np.ndarray:
        e = self.alive[:self.ne].nonzero()[0]
        return np.concatenate([2 * e, 2 * e + 1])

    def _relink_prev(self) -> None:
        h = self.alive_halves()
        self.prv[self.nxt[h]] = h

    def n_alive(self) -> int:
        return int(np.count_nonzero(self.alive[:self.ne]))

    def face_areas(self) -> np.ndarray:
        """Area vector of every face (Newell: half the sum of p_i x p_i+1; zero for the outside)."""
        if self.kernels is not None:
            result: np.ndarray = self.kernels.face_areas(self.pos, self.ev, self.alive, self.face, self.ne,
                                                         self.nf)
            return result
        e = self.alive[:self.ne].nonzero()[0]
        ends = self.ev[e]
        c = cross(self.pos[ends[:, 0]], self.pos[ends[:, 1]])
        cr = np.concatenate([c, -c])  # half-edges 2e (start to end), then 2e + 1 (end to start)
        f = self.face[:2 * self.ne].reshape(-1, 2)[e].T.ravel()
        key = (3 * f)[:, None] + _XYZ  # one bincount for the three axes: the same sums, in order
        out = 0.5 * np.bincount(key.ravel(), weights=cr.ravel(), minlength=3 * self.nf).reshape(-1, 3)
        out[0] = 0.0
        return out

    def perimeter_mask(self) -> np.ndarray:
        h = self.alive_halves()
        mask = np.zeros(self.nv, dtype=bool)
        mask[self.origin(h[self.face[h] == 0])] = True
        return mask

    def edge_array(self) -> np.ndarray:
        return self.ev[:self.ne][self.alive[:self.ne]]

    # -- compaction and export --------------------------------------------------------------------
    def compact(self) -> None:
        """Drop dead edges and renumber, keeping the order of the living ones."""
        alive = self.alive[:self.ne]
        keep = alive.nonzero()[0]
        if len(keep) == self.ne:
            return
        if self.kernels is not None:
            self.ne = self.kernels.compact(self.ev, self.label, self.age, self.alive, self.up, self.nxt,
                                           self.prv, self.face, self.ne)
            return
        old_h = (2 * keep[:, None] + _PAIR).ravel()   # the halves 2e, 2e + 1 of each edge kept
        hmap = np.full(2 * self.ne, -1, dtype=np.int64)
        hmap[old_h] = np.arange(2 * len(keep))
        nxt = hmap[self.nxt[old_h]]
        face = self.face[old_h]
        m = len(keep)
        self.ev[:m] = self.ev[keep]
        self.label[:m] = self.label[keep]
        self.age[:m] = self.age[keep]
        self.up[:m] = self.up[keep]
        self.alive[:m] = True
        self.alive[m:self.ne] = False
        self.nxt[:2 * m] = nxt
        self.face[:2 * m] = face
        self.nxt[2 * m:2 * self.ne] = -1
        self.ne = m
        self._relink_prev()

    def cycles(self, halves: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Walk the face cycles through ``halves``: (face of each cycle, offsets, origin vertices)."""
        nxt = self.nxt
        order = np.empty(len(halves), dtype=np.int64)
        # pointer walk in lockstep from each face's smallest half-edge
        face = self.face[halves]
        order_f = np.argsort(face, kind="stable")
        hs = halves[order_f]
        fs = face[order_f]
        first = np.ones(len(hs), dtype=bool)
        first[1:] = fs[1:] != fs[:-1]
        starts = hs[first]
        faces = fs[first]
        sizes = np.bincount(fs, minlength=self.nf)[faces]
        offsets = np.zeros(len(starts) + 1, dtype=np.int64)
        np.cumsum(sizes, out=offsets[1:])
        if self.kernels is not None:
            return faces, offsets, self.origin(self.kernels.cycles(nxt, starts, offsets, len(halves)))
        short = sizes <= 64
        cur = starts[short].copy()
        base = offsets[:-1][short]
        lengths = sizes[short]
        for i in range(int(lengths.max()) if len(lengths) else 0):
            active = i < lengths
            order[base[active] + i] = cur[active]
            cur[active] = nxt[cur[active]]
        long_faces = (~short).nonzero()[0]
        if len(long_faces):  # a few long cycles: a plain walk beats thousands of array passes
            links = nxt.tolist()
            for f in long_faces:
                h = int(starts[f])
                walk = []
                for _ in range(int(sizes[f])):
                    walk.append(h)
                    h = links[h]
                order[offsets[f]:offsets[f + 1]] = walk
        return faces, offsets, self.origin(order)

    def surface(self) -> Surface:
        h = self.alive_halves()
        faces, offsets, verts = self.cycles(h)
        inner = faces != 0
        sizes = np.diff(offsets)
        region_sizes = sizes[inner]
        region_offsets = np.zeros(len(region_sizes) + 1, dtype=np.int64)
        np.cumsum(region_sizes, out=region_offsets[1:])
        mask = np.repeat(inner, sizes)
        region_vertices = verts[mask]
        outer = verts[np.repeat(~inner, sizes)]
        perimeter = outer[::-1].copy()  # the outside face runs clockwise
        alive = self.alive[:self.ne]
        return Surface(self.pos[:self.nv].copy(), self.ev[:self.ne][alive], self.label[:self.ne][alive],
                       self.age[:self.ne][alive], region_offsets, region_vertices, perimeter,
                       masses=self.mass[:self.nv].copy(), stopped=self.stopped[:self.nv].copy())


def regular_polygon(n: int, length: float, centre: tuple[float, float, float]) -> np.ndarray:
    """A regular n-gon of side ``length``: first side along +x, counter-clockwise, centred."""
    turns = np.arange(n) * (2.0 * math.pi / n)
    steps = np.stack([np.cos(turns), np.sin(turns), np.zeros(n)], axis=1) * length
    pts = np.vstack([np.zeros(3), np.cumsum(steps, axis=0)[:-1]])
    result: np.ndarray = pts - pts.mean(axis=0) + np.asarray(centre, dtype=np.float64)
    return result


def seed_map(compiled: CompiledSystem, env: Environment) -> HalfEdgeMap:
    n = len(compiled.axiom_labels)
    if env.seed_polygon is not None:
        pts = np.asarray(env.seed_polygon, dtype=np.float64)
        if len(pts) != n:
            raise GrowthError(f"{env.source}: seed_polygon has {len(pts)} points but the axiom has "
                              f"{n} edges; give one point per axiom edge")
    else:
        pts = regular_polygon(n, env.start_length, env.start_position)
    masses = np.full(n, env.vertex_mass)
    if getattr(env, "seed_masses", None) is not None:
        masses = np.asarray(env.seed_masses, dtype=np.float64)
    return HalfEdgeMap(pts, masses, compiled.axiom_labels, compiled.axiom_reversed)


#: An edge frame (``frames``): start, end, start position, length, heading, left (or None), up.
Frames = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray | None, np.ndarray]


def frames(m: HalfEdgeMap, idx: np.ndarray, areas: np.ndarray, left: bool = True) -> Frames:
    """Start, length and (heading, left, up) of edges ``idx`` (left None unless asked for).

    Up is the surface normal: the sum of the area vectors of the regions on both sides of the edge
    (so it agrees with the map's orientation, and tiny regions count little); where that sum is
    negligible or along the edge, the normal the edge was drawn with."""
    ends = m.ev[idx]
    s, t = ends[:, 0], ends[:, 1]
    p, q = m.pos[s], m.pos[t]
    d = q - p
    length = np.sqrt(np.einsum("ij,ij->i", d, d))
    long = length > 1e-300
    safe = np.where(long, length, 1.0)
    h = d / safe[:, None]
    if not long.all():
        h[length <= 1e-300] = (1.0, 0.0, 0.0)
    sides = m.face[:2 * m.ne].reshape(-1, 2)[idx]   # the faces of half-edges 2e and 2e + 1
    n = areas[sides[:, 0]] + areas[sides[:, 1]]
    size = np.sqrt(np.einsum("ij,ij->i", n, n))
    weak = size <= 1e-9 * safe * safe
    n = n / np.where(weak, 1.0, size)[:, None]
    if weak.any():
        n[weak] = m.up[idx[weak]]
    for fallback in (None, (0.0, 0.0, 1.0), (0.0, 1.0, 0.0)):
        u = n - np.einsum("ij,ij->i", n, h)[:, None] * h
        un = np.sqrt(np.einsum("ij,ij->i", u, u))
        bad = un < 1e-6
        if not bad.any():
            break
        n = n.copy()
        n[bad] = m.up[idx[bad]] if fallback is None else fallback
    else:
        u = n - np.einsum("ij,ij->i", n, h)[:, None] * h
        un = np.sqrt(np.einsum("ij,ij->i", u, u))
    u = u / np.where(un > 1e-300, un, 1.0)[:, None]
    return s, t, p, length, h, cross(u, h) if left else None, u
