"""Growth: the derivation step (journal 4.3) applied to a map held as half-edge arrays.

A derivation step is (1) increase size (``Environment.increase_size``), (2) apply the rewrite rules
and (3) join branches; at its end every vertex, new ones included, is on the allowed side of every
hard boundary (``Environment.constrain``). Rules are grouped by predecessor label and the groups are
applied in the order of their first rule; every edge carrying the label when its group starts
(including edges made earlier in the same step by other labels' rules or by joined branches) is
rewritten by the first rule of the group whose context and condition match, one successor drawn by
weight. The successor's template (genr8_dist.hemls.turtle) is placed on the edge's frame: heading
along the edge, up along the surface normal (the mean normal of the regions on both sides). Branches
join after each group (default) or once after all groups (``Sync``); unjoined branches are dropped
at the end of the step.

The map is a half-edge structure: edge e has half-edges 2e (start to end) and 2e+1 (end to start);
``nxt``/``prv`` link the half-edges around each face, faces lying to the left of their half-edges
(face 0 is the outside). Every operation is vectorized over all edges or joins of one kind, so a
step costs a bounded number of passes over the arrays.
"""

from __future__ import annotations

import functools
import math
import os
import time
from dataclasses import dataclass, field, replace

import numpy as np

from genr8_dist.errors import GrowthError
from genr8_dist.hemls.language import Branch, RewriteSystem, Segment, Successor
from genr8_dist.hemls.surface import Surface
from genr8_dist.hemls.turtle import AT_END, LEFT, RIGHT, Template, draw, sector_side
from genr8_dist.rng import stream

__all__ = ["GrowthResult", "StepStats", "grow", "seed_surface"]


@dataclass(frozen=True)
class StepStats:
    """Size of the map after one derivation step and the seconds the step took."""

    step: int
    n_vertices: int
    n_edges: int
    n_regions: int
    seconds: float


@dataclass(frozen=True)
class GrowthResult:
    """The grown surface, per-step statistics, the cap that stopped growth early (``"edges"`` or
    ``"time"``, else None), and with ``keep_steps`` the surface after each step (``history[0]`` is the
    seed, ``history[i]`` the surface after step i)."""

    surface: Surface
    steps: list[StepStats]
    capped: str | None = None
    history: list[Surface] = field(default_factory=list)
    work: int = 0   # edge-steps spent (what ``max_work`` caps); see ``WORK_PAIRS``

    @property
    def seconds(self) -> float:
        """Total seconds spent in derivation steps."""
        return sum(s.seconds for s in self.steps)


#: Branch pairs tested for joining that count as one edge-step of work (the ``max_work`` cap):
#: testing a pair costs about a fortieth of carrying an edge through a derivation step.
WORK_PAIRS = 40
#: Edge-steps one successor's placement on a batch of edges counts for besides its edges (the fixed
#: cost of a pass over the arrays, which dominates on small maps).
WORK_BATCH = 64
#: Join pairs whose alignment and distance (each rounded to 1e-9) differ by no more than this are
#: tied (``branch_ties``): mirror images, computed in floating point, may round one step apart.
TIE = 1.5e-9


class _Capped(Exception):
    def __init__(self, what: str) -> None:
        super().__init__(what)
        self.what = what


_LOAD_AFTER = 200_000   # edge-steps (``GrowthResult.work``) the reference code grows in a process before
                        # it loads the compiled kernels: ~0.4 s CPU, about what loading them costs
_reference_work = 0     # edge-steps grown by the reference code in this process


@functools.cache
def _load_kernels():
    """The compiled kernels (``genr8_dist.hemls._growth_compiled``, numba), imported on first use;
    None, for the numpy reference code here, when numba is not installed or ``GENR8_COMPILED=0``."""
    if os.environ.get("GENR8_COMPILED") == "0":
        return None
    try:
        from genr8_dist.hemls import _growth_compiled
    except ImportError:
        return None
    assert (_growth_compiled.LEFT, _growth_compiled.RIGHT) == (LEFT, RIGHT)
    return _growth_compiled


def _kernels():
    """The compiled kernels, or None for the reference code: both grow the same surfaces bit for bit.
    A process loads them once it has grown ``_LOAD_AFTER`` edge-steps with the reference code (so a
    short run does not pay for numba), at once with ``GENR8_COMPILED=1``, never with
    ``GENR8_COMPILED=0`` or without numba (the ``fast`` extra)."""
    if _reference_work < _LOAD_AFTER and os.environ.get("GENR8_COMPILED") != "1":
        return None
    return _load_kernels()


# -- compiled rewrite systems -----------------------------------------------------------------------

@dataclass(frozen=True)
class _Group:
    label: int
    rules: tuple[_CompiledRule, ...]


@dataclass(frozen=True)
class _CompiledRule:
    left: int | None
    right: int | None
    chain: tuple[int, ...]
    condition: object
    templates: tuple[Template, ...]
    cumulative: np.ndarray  # cumulative normalized weights

    @property
    def unconditional(self) -> bool:
        """Whether the rule applies to every edge with its predecessor's label (no context, chain
        or condition)."""
        return self.left is None and self.right is None and not self.chain and self.condition is None


@dataclass(frozen=True)
class _Compiled:
    groups: tuple[_Group, ...]
    axiom_labels: np.ndarray
    axiom_reversed: np.ndarray
    labels: np.ndarray  # every label the system uses (for label noise)
    max_label: int
    cos_cone: float
    sync: bool


@functools.lru_cache(maxsize=4096)
def _segments(symbols: tuple) -> tuple[Segment, ...]:
    """The segments in ``symbols`` (brackets included), in order."""
    out: list[Segment] = []
    for sym in symbols:
        if isinstance(sym, Segment):
            out.append(sym)
        elif isinstance(sym, Branch):
            out.extend(_segments(sym.symbols))
    return tuple(out)


def _shape(symbols: tuple, count: list[int]) -> tuple:
    """``symbols`` with the i-th segment (in ``_segments`` order) replaced by the plain segment "i"."""
    out: list = []
    for sym in symbols:
        if isinstance(sym, Segment):
            out.append(Segment(str(count[0])))
            count[0] += 1
        elif isinstance(sym, Branch):
            out.append(Branch(_shape(sym.symbols, count)))
        else:
            out.append(sym)
    return tuple(out)


@functools.lru_cache(maxsize=4096)
def _drawn_shape(shape: tuple, angle: float) -> Template:
    """The template of successors of this shape: labels are segment positions, ages untimed."""
    n = len(_segments(shape))
    return draw(Successor(shape), angle, {str(i): i for i in range(n)})


def _frozen(a: np.ndarray) -> np.ndarray:
    a.setflags(write=False)
    return a


@functools.lru_cache(maxsize=8192)
def _drawn(successor: Successor, angle: float, labels: tuple[int, ...]) -> Template:
    """``draw(successor, angle, ...)``: the turtle walks once per shape (successors that differ only in
    their labels and ages draw the same geometry); labels and ages are read from the segments."""
    shape = _drawn_shape(_shape(successor.symbols, [0]), angle)
    segments = _segments(successor.symbols)
    ids = np.array(labels, dtype=np.int64)
    ages = np.array([0 if s.age is None else s.age for s in segments], dtype=np.int64)
    timed = np.array([s.age is not None for s in segments], dtype=bool)
    main, branch = shape.main_labels, shape.branch_labels
    return replace(shape, main_labels=_frozen(ids[main]), main_ages=_frozen(ages[main]),
                   main_timed=_frozen(timed[main]), branch_labels=_frozen(ids[branch]),
                   branch_ages=_frozen(ages[branch]), branch_timed=_frozen(timed[branch]))


def _template(successor: Successor, angle: float, ids: dict[str, int]) -> Template:
    """``draw(successor, angle, ids)``, drawn once per process for each successor, angle and labels
    (universes write the same successors into many rewrite systems)."""
    return _drawn(successor, angle, tuple(ids[s.name] for s in _segments(successor.symbols)))


_CERTAIN = np.ones(1)   # the cumulative weights of a rule with one successor
_CERTAIN.setflags(write=False)


@functools.lru_cache(maxsize=1024)
def _compile(system: RewriteSystem) -> _Compiled:
    ids = system.label_ids()
    groups: dict[int, list[_CompiledRule]] = {}
    for rule in system.rules:
        templates = tuple(_template(s, system.turn_angle, ids) for s in rule.successors)
        if len(templates) == 1:
            cum = _CERTAIN
        else:
            w = np.array(rule.weights, dtype=np.float64)
            cum = np.cumsum(w / w.sum())
            cum[-1] = 1.0
        groups.setdefault(ids[rule.predecessor.name], []).append(_CompiledRule(
            None if rule.left is None else ids[rule.left.name],
            None if rule.right is None else ids[rule.right.name],
            tuple(ids[c.name] for c in rule.chain),
            rule.condition, templates, cum))
    labels = np.array(sorted(set(ids.values())), dtype=np.int64)
    return _Compiled(
        groups=tuple(_Group(label, tuple(rules)) for label, rules in groups.items()),
        axiom_labels=np.array([ids[e.segment.name] for e in system.axiom], dtype=np.int64),
        axiom_reversed=np.array([e.reversed for e in system.axiom], dtype=bool),
        labels=labels,
        max_label=int(labels.max()) if len(labels) else 0,
        cos_cone=math.cos(math.radians(system.cone_angle)),
        sync=system.sync,
    )


# -- the map ----------------------------------------------------------------------------------------

def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise cross product of two (n, 3) arrays (np.cross costs more than the work on small maps)."""
    out = np.empty(a.shape)
    out[:, 0] = a[:, 1] * b[:, 2] - a[:, 2] * b[:, 1]
    out[:, 1] = a[:, 2] * b[:, 0] - a[:, 0] * b[:, 2]
    out[:, 2] = a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]
    return out


_XYZ = np.arange(3)
_PAIR = np.arange(2)


class _Map:
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
        normal = _cross(positions - centre, following - centre).sum(axis=0)
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
        self.kernels = None  # the compiled kernels this map's growth uses (``_kernels``), if any

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
    def origin(self, h):
        return self.ev[h >> 1, h & 1]

    def dest(self, h):
        return self.ev[h >> 1, 1 - (h & 1)]

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
            return self.kernels.face_areas(self.pos, self.ev, self.alive, self.face, self.ne, self.nf)
        e = self.alive[:self.ne].nonzero()[0]
        ends = self.ev[e]
        c = _cross(self.pos[ends[:, 0]], self.pos[ends[:, 1]])
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


def _regular_polygon(n: int, length: float, centre) -> np.ndarray:
    """A regular n-gon of side ``length``: first side along +x, counter-clockwise, centred."""
    turns = np.arange(n) * (2.0 * math.pi / n)
    steps = np.stack([np.cos(turns), np.sin(turns), np.zeros(n)], axis=1) * length
    pts = np.vstack([np.zeros(3), np.cumsum(steps, axis=0)[:-1]])
    return pts - pts.mean(axis=0) + np.asarray(centre, dtype=np.float64)


def _seed_map(compiled: _Compiled, env) -> _Map:
    n = len(compiled.axiom_labels)
    if env.seed_polygon is not None:
        pts = np.asarray(env.seed_polygon, dtype=np.float64)
        if len(pts) != n:
            raise GrowthError(f"{env.source}: seed_polygon has {len(pts)} points but the axiom has "
                              f"{n} edges; give one point per axiom edge")
    else:
        pts = _regular_polygon(n, env.start_length, env.start_position)
    masses = np.full(n, env.vertex_mass)
    if getattr(env, "seed_masses", None) is not None:
        masses = np.asarray(env.seed_masses, dtype=np.float64)
    return _Map(pts, masses, compiled.axiom_labels, compiled.axiom_reversed)


def seed_surface(system: RewriteSystem, env=None) -> Surface:
    """The seed polygon of ``system`` in ``env`` as a surface (before any derivation step)."""
    from genr8_dist.environment import Environment

    env = Environment() if env is None else env
    return _seed_map(_compile(system), env).surface()


# -- the derivation step ------------------------------------------------------------------------------

class _Branches:
    """Pending branches of the current step: vertex, corner half-edge (leaving the vertex into the
    region the branch points into; -1 when it points nowhere), label, age, heading, reversed, and the
    surface normal it was drawn with."""

    def __init__(self) -> None:
        self.parts: list[tuple[np.ndarray, ...]] = []
        self._cat: tuple[np.ndarray, ...] | None = None
        # branches [0, checked) have met each other in a join already: positions and headings do
        # not change within a step and faces only split, so such pairs never need testing again
        self.checked = 0
        self.size = 0

    def add(self, vertex, corner, label, age, heading, reversed_, normal) -> None:
        if len(vertex):
            self._flush_cat()
            self.parts.append((vertex, corner, label, age, heading, reversed_, normal))
            self.size += len(vertex)

    def _flush_cat(self) -> None:
        if self._cat is not None:
            self.parts = [self._cat]
            self._cat = None

    def arrays(self) -> tuple[np.ndarray, ...]:
        if self._cat is None:
            if not self.parts:
                self._cat = (np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0, np.int64),
                             np.zeros(0, np.int64), np.zeros((0, 3)), np.zeros(0, bool),
                             np.zeros((0, 3)))
            else:
                self._cat = tuple(np.concatenate([p[i] for p in self.parts]) for i in range(7))
            self.parts = []
        return self._cat

    def keep(self, mask: np.ndarray) -> None:
        """Keep the branches where ``mask`` holds; all of them count as checked from now on."""
        self._cat = tuple(a[mask] for a in self.arrays())
        self.checked = self.size = len(self._cat[0])

    def remap_corners(self, repl: np.ndarray) -> None:
        if not self.size:
            return
        arrs = list(self.arrays())
        c = arrs[1]
        ok = c >= 0
        c = c.copy()
        c[ok] = repl[c[ok]]
        arrs[1] = c
        self._cat = tuple(arrs)

    def __len__(self) -> int:
        return self.size


def _frames(m: _Map, idx: np.ndarray, areas: np.ndarray, left: bool = True):
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
    return s, t, p, length, h, _cross(u, h) if left else None, u


class _Grower:
    """One growth: the map, the compiled system, the environment, the random stream and the caps."""

    kernels = None   # the compiled kernels (``_kernels``) this growth uses, if any

    def __init__(self, system: RewriteSystem, env, rng: np.random.Generator, deadline: float) -> None:
        self.c = _compile(system)
        self.env = env
        self.rng = rng
        self.deadline = deadline
        self.m = _seed_map(self.c, env)
        self.kernels = self.m.kernels = _kernels()
        self.max_edges = int(env.max_edges)
        self.max_work = int(getattr(env, "max_work", 0) or 0)   # 0: no work cap
        self.work = 0       # edge-steps: the edges alive at the start of each step, and those it makes
        self.pairs = 0      # branch pairs tested and re-tested for joining
        self.cone = getattr(env, "branch_join", "orientation") == "cone"
        self.ties = getattr(env, "branch_ties", "crossing")
        self._stop_later: list[np.ndarray] = []  # vertices drawn between two stopped ones
        self._keys: np.ndarray | None = None

    # -- step ------------------------------------------------------------------------------------
    def step(self, step: int) -> None:
        m = self.m
        self._spend(m.n_alive())
        inc = self.env.increase_size(m.pos[:m.nv].copy(), step=step, masses=m.mass[:m.nv].copy(),
                                     stopped=m.stopped[:m.nv].copy(), perimeter=m.perimeter_mask(),
                                     edges=m.edge_array(), rng=self.rng)
        m.pos[:m.nv] = inc.positions
        m.stopped[:m.nv] = inc.stopped
        max_dist = self.env.max_branch_distance(step)
        pending = _Branches()
        try:
            for group in self.c.groups:
                self._check_time()
                self._rewrite_group(group, pending)
                if not self.c.sync:
                    self._join(pending, max_dist)
            if self.c.sync:
                self._join(pending, max_dist)
        finally:
            m.compact()
            if self.env.uniform_cells:
                m.pos[:m.nv] = self.env.relax_cells(m.pos[:m.nv], edges=m.edge_array(),
                                                    perimeter=m.perimeter_mask(), stopped=m.stopped[:m.nv])
            self._constrain()

    def _constrain(self) -> None:
        """Hard boundaries hold at the end of the step: the vertices rewriting placed on the wrong
        side (a new vertex on an edge that is a chord of a sphere) go to the wall's nearest allowed
        point, and stop there at a cut-off wall (``Environment.constrain``); then the vertices drawn
        between two stopped vertices stop."""
        if not self.env.boundaries:
            return
        m = self.m
        fixed = self.env.constrain(m.pos[:m.nv], stopped=m.stopped[:m.nv])
        m.pos[:m.nv] = fixed.positions
        m.stopped[:m.nv] = fixed.stopped
        for frozen in self._stop_later:
            m.stopped[frozen] = True
        self._stop_later = []

    @property
    def spent(self) -> int:
        """The work done so far in edge-steps: every edge alive when a derivation step starts, and
        every edge rewriting makes, counts one; each successor placed on a batch of edges counts
        ``WORK_BATCH`` more; ``WORK_PAIRS`` branch pairs tested for joining count one."""
        return self.work + self.pairs // WORK_PAIRS

    def _spend(self, edges: int = 0, pairs: int = 0) -> None:
        """Count work; past ``max_work`` growth stops (a count, so the same on every machine)."""
        self.work += edges
        self.pairs += pairs
        if self.max_work and self.spent > self.max_work:
            raise _Capped("work")

    def _check_time(self) -> None:
        if time.perf_counter() > self.deadline:
            raise _Capped("time")

    # -- rewriting -------------------------------------------------------------------------------
    def _context_ok(self, idx: np.ndarray, end: int, label: int | None) -> np.ndarray:
        """Whether some other edge at the start (end=0) or end (end=1) vertex of ``idx`` has ``label``."""
        m = self.m
        width = self.c.max_label + 1
        if self._keys is None:  # (vertex, label) of every edge end, sorted; valid for one group
            live = m.alive[:m.ne].nonzero()[0]
            keys = np.concatenate([m.ev[live, 0], m.ev[live, 1]]) * width + np.tile(m.label[live], 2)
            keys.sort()
            self._keys = keys
        keys = self._keys
        v = m.ev[idx, end]
        want = v * width + label
        count = np.searchsorted(keys, want, side="right") - np.searchsorted(keys, want, side="left")
        own = (m.label[idx] == label).astype(np.int64)  # the edge itself sits at that vertex too
        return count - own > 0

    def _chain_ok(self, idx: np.ndarray, chain: tuple[int, ...]) -> np.ndarray:
        """Whether a path of edges labelled ``chain`` continues from the end vertex of each edge."""
        m = self.m
        live = m.alive[:m.ne].nonzero()[0]
        ends = m.ev[live]
        labels = m.label[live]
        rest = np.ones(m.nv, dtype=bool)  # where the remainder of the chain can start
        for lab in reversed(chain[1:]):
            p, q = ends[labels == lab, 0], ends[labels == lab, 1]
            mask = np.zeros(m.nv, dtype=bool)
            mask[p[rest[q]]] = True
            mask[q[rest[p]]] = True
            rest = mask
        lab = chain[0]
        p, q = ends[labels == lab, 0], ends[labels == lab, 1]
        count = (np.bincount(p[rest[q]], minlength=m.nv) + np.bincount(q[rest[p]], minlength=m.nv))
        own = (m.label[idx] == lab) & rest[m.ev[idx, 0]]  # the edge itself, seen from its end
        return count[m.ev[idx, 1]] - own > 0

    def _rewrite_group(self, group: _Group, pending: _Branches) -> None:
        m = self.m
        idx = (m.alive[:m.ne] & (m.label[:m.ne] == group.label)).nonzero()[0]
        if not len(idx):
            return
        self._keys = None
        rules = group.rules
        if len(rules) == 1 and rules[0].unconditional:
            chosen = [(rules[0], idx)]   # every edge with the label takes the one rule
        else:
            choice = np.full(len(idx), -1, dtype=np.int64)
            for r, rule in enumerate(rules):
                free = choice < 0
                if not free.any():
                    break
                ok = free.copy()
                if rule.condition is not None:
                    ok &= rule.condition.holds(m.age[idx])  # type: ignore[attr-defined]
                if rule.left is not None:
                    ok[ok] = self._context_ok(idx[ok], 0, rule.left)
                if rule.right is not None:
                    ok[ok] = self._context_ok(idx[ok], 1, rule.right)
                if rule.chain:
                    ok[ok] = self._chain_ok(idx[ok], rule.chain)
                choice[ok] = r
            chosen = [(rule, idx[choice == r]) for r, rule in enumerate(rules)]
        batches: list[tuple[np.ndarray, Template]] = []
        grow_edges = 0
        for rule, sel in chosen:
            if not len(sel):
                continue
            if len(rule.templates) == 1:
                parts = [(sel, rule.templates[0])]
            else:
                which = np.searchsorted(rule.cumulative, self.rng.random(len(sel)), side="right")
                which = np.minimum(which, len(rule.templates) - 1)
                parts = [(sel[which == j], tpl) for j, tpl in enumerate(rule.templates)]
            for part, tpl in parts:
                if len(part):
                    batches.append((part, tpl))
                    grow_edges += len(part) * (tpl.n_segments - 1)
        if not batches:
            return
        if m.n_alive() + grow_edges > self.max_edges:
            raise _Capped("edges")
        self._spend(grow_edges + WORK_BATCH * len(batches))
        areas = m.face_areas()
        for part, tpl in batches:
            self._rewrite(part, tpl, areas, pending)

    def _noisy(self, row: np.ndarray, n: int) -> np.ndarray:
        """``row`` repeated ``n`` times, flat; with label noise, each label replaced by one the system
        uses with probability ``label_noise``."""
        out = _repeat_row(row, n)
        p = self.env.label_noise
        if p <= 0 or not len(out):
            return out
        hit = self.rng.random(len(out)) < p
        out[hit] = self.rng.choice(self.c.labels, size=int(hit.sum()))
        return out

    def _rewrite(self, idx: np.ndarray, tpl: Template, areas: np.ndarray, pending: _Branches) -> None:
        if self.kernels is not None:
            self._rewrite_compiled(self.kernels, idx, tpl, areas, pending)
            return
        m = self.m
        n, k = len(idx), tpl.n_segments
        s, t, p, length, h, left, up = _frames(m, idx, areas, left=k > 1 or tpl.n_branches > 0)
        nv0, ne0 = m.nv, m.ne
        nv1, ne1 = nv0 + n * (k - 1), ne0 + n * k
        if nv1 > len(m.pos) or ne1 > len(m.ev):
            m.reserve(nv1, ne1)
        chain = np.empty((n, k + 1), dtype=np.int64)  # the vertices along each new main line
        chain[:, 0] = s
        chain[:, k] = t
        if k > 1:
            pts = tpl.points[1:k]  # the vertices drawn between the edge's ends
            world = (p[:, None, :] + length[:, None, None]
                     * (pts[None, :, 0, None] * h[:, None, :] + pts[None, :, 1, None] * left[:, None, :]
                        + pts[None, :, 2, None] * up[:, None, :]))
            m.pos[nv0:nv1] = world.reshape(-1, 3)
            m.mass[nv0:nv1] = self.env.vertex_mass
            m.stopped[nv0:nv1] = False
            # a part of the surface that a cut-off wall stopped does not grow again (thesis 2.7.3): the
            # vertices drawn on an edge whose two ends are stopped stop too, at the end of the step
            both = m.stopped[s] & m.stopped[t]
            if both.any():
                self._stop_later.append(nv0 + np.repeat(both, k - 1).nonzero()[0])
            m.nv = nv1
            chain[:, 1:k] = np.arange(nv0, nv1, dtype=np.int64).reshape(n, k - 1)
        rev = tpl.main_reversed
        a, b = chain[:, :k], chain[:, 1:]
        ev = m.ev[ne0:ne1]
        ev[:, 0] = np.where(rev, b, a).ravel()
        ev[:, 1] = np.where(rev, a, b).ravel()
        if self.env.label_noise > 0:
            m.label[ne0:ne1] = self._noisy(tpl.main_labels, n)
        else:
            m.label[ne0:ne1].reshape(n, k)[:] = tpl.main_labels
        old_age = m.age[idx]
        if tpl.main_timed.any():
            ages = np.where(tpl.main_timed, old_age[:, None] + tpl.main_ages, tpl.main_ages)
            m.age[ne0:ne1] = np.maximum(ages, 0).ravel()
        else:   # untimed segments start at age 0
            m.age[ne0:ne1] = 0
        m.alive[ne0:ne1] = True
        if k == 1:
            m.up[ne0:ne1] = up
        else:
            m.up[ne0:ne1].reshape(n, k, 3)[:] = up[:, None, :]
        m.ne = ne1
        # half-edges along the main line (start to end) and back
        fwd = np.arange(2 * ne0, 2 * ne1, 2, dtype=np.int64).reshape(n, k) + rev
        bwd = fwd ^ 1
        ho = 2 * idx
        ht = ho + 1
        next_ho, next_ht = m.nxt[ho], m.nxt[ht]
        first, last = fwd[:, 0], bwd[:, k - 1]
        repl = np.arange(2 * ne1, dtype=np.int64)
        repl[ho] = first
        repl[ht] = last
        # only the halves before ho and ht lead into the edges replaced (a pass over these, not over
        # the map); one that is itself replaced is relinked below and then dropped
        before = np.concatenate([m.prv[ho], m.prv[ht]])
        m.nxt[before] = np.concatenate([first, last])
        m.nxt[fwd[:, k - 1]] = repl[next_ho]
        m.nxt[bwd[:, 0]] = repl[next_ht]
        if k > 1:
            m.nxt[fwd[:, :-1]] = fwd[:, 1:]
            m.nxt[bwd[:, 1:]] = bwd[:, :-1]
        m.face[fwd] = m.face[ho][:, None]
        m.face[bwd] = m.face[ht][:, None]
        m.alive[idx] = False
        m.nxt[ho] = -1
        m.nxt[ht] = -1
        changed = np.concatenate([before[m.alive[before >> 1]], fwd.ravel(), bwd.ravel()])
        m.prv[m.nxt[changed]] = changed
        pending.remap_corners(repl)
        # branches
        nb = tpl.n_branches
        if nb == 0:
            return
        j = tpl.branch_vertex
        bvert = chain[:, j]  # (n, nb)
        hd = tpl.branch_heading
        heading = (hd[None, :, 0, None] * h[:, None, :] + hd[None, :, 1, None] * left[:, None, :]
                   + hd[None, :, 2, None] * up[:, None, :])
        corner = np.full((n, nb), -1, dtype=np.int64)
        side = tpl.branch_side
        for br in range(nb):
            if side[br] == LEFT:
                corner[:, br] = fwd[:, j[br]]
            elif side[br] == RIGHT:
                corner[:, br] = bwd[:, j[br] - 1]
        self._add_branches(pending, tpl, n, idx, bvert, corner, heading, up, first, last)

    def _rewrite_compiled(self, kernels, idx: np.ndarray, tpl: Template, areas: np.ndarray,
                          pending: _Branches) -> None:
        """``_rewrite`` with its array work in one compiled call (``_growth_compiled.rewrite``)."""
        m = self.m
        n, k = len(idx), tpl.n_segments
        nv0, ne0 = m.nv, m.ne
        nv1, ne1 = nv0 + n * (k - 1), ne0 + n * k
        if nv1 > len(m.pos) or ne1 > len(m.ev):
            m.reserve(nv1, ne1)
        labels = self._noisy(tpl.main_labels, n)
        up, both, repl, first, last, bvert, heading, corner = kernels.rewrite(
            m.pos, m.mass, m.stopped, m.ev, m.label, m.age, m.alive, m.up, m.nxt, m.prv, m.face, idx, areas,
            nv0, ne0, float(self.env.vertex_mass), tpl.points, labels, tpl.main_ages, tpl.main_timed,
            tpl.main_reversed, tpl.branch_vertex, tpl.branch_heading, tpl.branch_side)
        m.nv, m.ne = nv1, ne1
        if k > 1 and both.any():
            self._stop_later.append(nv0 + np.repeat(both, k - 1).nonzero()[0])
        pending.remap_corners(repl)
        nb = tpl.n_branches
        if nb == 0:
            return
        self._add_branches(pending, tpl, n, idx, bvert, corner.reshape(n, nb), heading.reshape(n, nb, 3),
                           up, first, last)

    def _add_branches(self, pending: _Branches, tpl: Template, n: int, idx: np.ndarray, bvert: np.ndarray,
                      corner: np.ndarray, heading: np.ndarray, up: np.ndarray, first: np.ndarray,
                      last: np.ndarray) -> None:
        """The successor's branches on the ``n`` edges ``idx`` rewritten, pending joining: their
        corners at the main line's ends found (``_corner_at``), labels and ages drawn."""
        nb = tpl.n_branches
        for br in range(nb):
            if tpl.branch_side[br] == AT_END:
                start_half = first if tpl.branch_vertex[br] == 0 else last
                for r in range(n):
                    corner[r, br] = self._corner_at(int(start_half[r]), heading[r, br], up[r])
        old_age = self.m.age[idx]
        blabels = self._noisy(tpl.branch_labels, n).ravel()
        bages = np.maximum(np.where(tpl.branch_timed, old_age[:, None] + tpl.branch_ages,
                                    tpl.branch_ages), 0).ravel()
        pending.add(bvert.ravel(), corner.ravel(), blabels, bages, heading.reshape(-1, 3),
                    _repeat_row(tpl.branch_reversed, n), np.repeat(up, nb, axis=0))

    def _corner_at(self, h0: int, heading: np.ndarray, normal: np.ndarray) -> int:
        """The half-edge leaving the vertex of ``h0`` into the region ``heading`` points into."""
        m = self.m
        v = int(m.origin(h0))
        helper = np.array([1.0, 0.0, 0.0]) if abs(normal[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
        e1 = np.cross(normal, helper)
        e1 /= np.linalg.norm(e1)
        e2 = np.cross(normal, e1)

        def flat(vec):
            return np.array([vec @ e1, vec @ e2])

        hflat = flat(heading)
        here = m.pos[v]
        h = h0
        for _ in range(m.ne * 2):
            forward = flat(m.pos[m.dest(h)] - here)
            backward = flat(m.pos[m.origin(int(m.prv[h]))] - here)
            if sector_side(forward, backward, hflat) == LEFT:
                return h if m.face[h] != 0 else -1
            h = int(m.prv[h]) ^ 1
            if h == h0:
                break
        return -1

    # -- joining -------------------------------------------------------------------------------------
    def _join(self, pending: _Branches, max_dist: float) -> None:
        if len(pending) < 2:
            return
        m = self.m
        vert, corner, label, age, heading, rev, normal = pending.arrays()
        n = len(vert)
        ok = corner >= 0
        face = np.where(ok, m.face[np.maximum(corner, 0)], 0)
        ok &= face != 0
        cand = ok.nonzero()[0]
        old = pending.checked
        if len(cand) < 2 or not (cand >= old).any():
            pending.checked = n
            return
        key = face[cand] * (self.c.max_label + 1) + label[cand]
        order = np.argsort(key, kind="stable")  # within a group, old branches come first
        cand = cand[order]
        key = key[order]
        first = np.ones(len(cand), dtype=bool)
        first[1:] = key[1:] != key[:-1]
        starts = first.nonzero()[0]
        sizes = np.empty(len(starts), dtype=np.int64)
        sizes[:-1] = starts[1:] - starts[:-1]
        sizes[-1] = len(cand) - starts[-1]
        points = m.pos[vert]
        # every pair to test, counted as work group by group, then judged in one pass
        pi_all, pj_all = [], []
        small = (sizes >= 2) & (sizes <= 48)
        for size in np.unique(sizes[small]).tolist():
            gs = starts[small & (sizes == size)]
            ti, tj = _triu(size)
            pi = cand[(gs[:, None] + ti).ravel()]
            pj = cand[(gs[:, None] + tj).ravel()]
            fresh = pj >= old  # pi < pj within a group: a pair is new when pj is
            pi, pj = pi[fresh], pj[fresh]
            self._spend(pairs=len(pi))
            pi_all.append(pi)
            pj_all.append(pj)
        for g in (sizes > 48).nonzero()[0]:
            members = cand[starts[g]:starts[g] + sizes[g]]
            new = members[members >= old]
            if not len(new):
                continue
            rows = max(1, 1_000_000 // len(new))
            for r0 in range(0, len(members), rows):
                self._check_time()
                block = members[r0:r0 + rows]
                self._spend(pairs=len(block) * len(new))
                ri, cj = self._prefilter(block, new, points, heading, max_dist)
                pi_all.append(block[ri])
                pj_all.append(new[cj])
        if not pi_all:
            pending.checked = n
            return
        pi, pj = np.concatenate(pi_all), np.concatenate(pj_all)
        keep, (ci, cj, dist) = self._pair_aim(pi, pj, points, heading, normal, max_dist)
        pi, pj, ci, cj, dist = pi[keep], pj[keep], ci[keep], cj[keep], dist[keep]
        if not len(pi):
            pending.checked = n
            return
        score = -np.round(ci + cj, 9)
        gap = np.round(dist, 9)
        order = np.lexsort((pj, pi, gap, score))
        pi, pj = pi[order], pj[order]
        score, gap = score[order], gap[order]   # pairs equal in both: a tie
        used = np.zeros(n, dtype=bool)
        live = np.ones(len(pi), dtype=bool)
        settled = np.zeros(len(pi), dtype=bool)   # tied pairs found to conflict with none of their ties
        centre = m.pos[:m.nv].mean(axis=0)
        while True:
            self._check_time()
            self._spend(pairs=len(pi))
            fi = m.face[corner[pi]]
            fj = m.face[corner[pj]]
            live &= ~used[pi] & ~used[pj] & (fi == fj) & (fi != 0)
            at = live.nonzero()[0]
            if not len(at):
                break
            if 2 * len(at) < len(pi):   # pairs never come back to life: test only the live ones
                pi, pj, live, fi, settled = pi[at], pj[at], live[at], fi[at], settled[at]
                score, gap = score[at], gap[at]
                at = np.arange(len(pi))
            # one join per face per round (a join splits its face), best pair first: each face's
            # first live pair (a position in ``at``), found in one pass rather than a sort
            fa = fi[at]
            first = np.full(m.nf, len(at), dtype=np.int64)
            np.minimum.at(first, fa, np.arange(len(at)))
            firsts = first[first < len(at)]
            firsts.sort()
            chosen = at[firsts]
            if self.ties != "first":
                chosen = self._settle_ties(chosen, at, fi, fa, at[first[fa]], score, gap, live, settled, pi,
                                           pj, vert, corner, heading, normal)
                if not len(chosen):
                    continue
            a, b = pi[chosen], pj[chosen]
            adjacent = self._adjacent(corner[a], vert[b])
            live[chosen[adjacent]] = False
            chosen, a, b = chosen[~adjacent], a[~adjacent], b[~adjacent]
            if not len(chosen):
                continue
            if self.ties != "first":
                a, b = self._centre_on_left(a, b, vert, normal, centre)
            # one new edge per vertex pair per round
            if len(chosen) > 1:
                u, w = vert[a], vert[b]
                pair_key = np.minimum(u, w) * m.nv + np.maximum(u, w)
                _, uniq = np.unique(pair_key, return_index=True)
                if len(uniq) != len(chosen):
                    keep = np.zeros(len(chosen), dtype=bool)
                    keep[uniq] = True
                    chosen, a, b = chosen[keep], a[keep], b[keep]
            room = self.max_edges - m.n_alive()
            capped = len(chosen) > room
            if capped:
                chosen, a, b = chosen[:room], a[:room], b[:room]
            if len(chosen):
                used[a] = True
                used[b] = True
                live[chosen] = False
                self._split(a, b, vert, corner, label, age, rev, used, heading, normal)
            if capped:
                pending.keep(~used)
                raise _Capped("edges")
        pending.keep(~used)

    def _settle_ties(self, chosen, at, fi, fa, lead, score, gap, live, settled, pi, pj, vert, corner,
                     heading, normal):
        """Settle ties without looking at the order branches were drawn in (``branch_ties``).

        A face's tied pairs are its live pairs as good as its best (alignment and distance within
        ``TIE``): on a symmetric map, a join and its mirror image. ``"crossing"`` (the default) makes
        every tied pair that conflicts with no other, and none of those that do (``_conflicts``);
        ``"none"`` makes none of them. Pairs left out are marked dead, pairs left in ``settled``;
        returns the chosen pairs, a face whose best pair was left out choosing its first tied pair
        left in (the others follow in later rounds, in any order: none crosses another)."""
        if self.kernels is not None:
            close, tied_faces = self.kernels.ties(at, fa, lead, score, gap, TIE)
        else:
            close = (np.abs(score[at] - score[lead]) <= TIE) & (np.abs(gap[at] - gap[lead]) <= TIE)
            tied_faces = np.flatnonzero(np.bincount(fa, weights=close) > 1)
        if not len(tied_faces):
            return chosen
        pick = dict(zip(fi[chosen].tolist(), chosen.tolist(), strict=True))
        for face in tied_faces.tolist():
            tied = at[close & (fa == face)]
            if self.ties == "crossing" and not np.all(settled[tied]):
                near = self._adjacent(corner[pi[tied]], vert[pj[tied]])  # would be dropped anyway
                live[tied[near]] = False
                tied = tied[~near]
                out = self._conflicts(tied, pi, pj, vert, corner, heading, normal)
                live[tied[out]] = False
                tied = tied[~out]
                settled[tied] = True
            elif self.ties == "none":
                live[tied] = False
                tied = tied[:0]
            if len(tied):
                pick[face] = int(tied[0])
            else:
                del pick[face]
        return np.sort(np.array(list(pick.values()), dtype=np.int64))

    def _centre_on_left(self, a, b, vert, normal, centre):
        """Join pairs (a, b) reordered so that the new edge, from a's vertex to b's, has the map's
        centre on its left (about the branches' surface normal); left as drawn where the centre is
        on the line (within 1e-9 of a radian).

        The edge's direction decides which side the drawing of its successor takes in the next
        step; a rule that only looks at the geometry gives a symmetric map's mirror-image joins
        mirror-image directions (the mirror edge of an edge runs the other way), where the order
        the branches were drawn in need not."""
        m = self.m
        if self.kernels is not None:
            return self.kernels.centre_on_left(a, b, vert, m.pos, normal, centre)
        u, w = m.pos[vert[a]], m.pos[vert[b]]
        along, to_centre = w - u, centre - u
        n = normal[a] + normal[b]
        side = np.einsum("ij,ij->i", _cross(along, to_centre), n)
        scale = np.sqrt(np.einsum("ij,ij->i", along, along) * np.einsum("ij,ij->i", to_centre, to_centre)
                        * np.einsum("ij,ij->i", n, n))
        swap = side < -1e-9 * scale
        return np.where(swap, b, a), np.where(swap, a, b)

    def _conflicts(self, tied, pi, pj, vert, corner, heading, normal) -> np.ndarray:
        """Which of the join pairs ``tied`` (all in one face) conflict with another of them: they
        share a branch or a vertex pair, or one, made first, would leave the other's two branches in
        different regions (they cross), as ``_split`` decides it: a join from corner ha to corner hb
        splits the face's cycle into the part from ha round to hb and the rest, and a branch at ha's
        or hb's own corner goes by where its heading points (``_in_sweep``)."""
        m = self.m
        t = len(tied)
        if t < 2:   # the others were already joined by an edge
            return np.zeros(t, dtype=bool)
        self._spend(pairs=t * t)
        a, b = pi[tied], pj[tied]
        ha, hb = corner[a], corner[b]
        size, at_ha, at_hb = self._cycle_places(ha, hb)
        if self.kernels is not None:   # the same decisions, the integer work compiled
            sides = []
            for branch, place in ((a, at_ha), (b, at_hb)):
                side, r, c, at_a, terms = self.kernels.tie_side(m.pos, m.ev, vert, corner, heading, normal,
                                                                branch, a, b, place, at_ha, at_hb, size)
                if len(r):
                    side[r, c] = _swept(*terms) ^ at_a
                sides.append(side)
            return self.kernels.clashes(a, b, vert, sides[0], sides[1])
        start, span = at_ha, (at_hb - at_ha) % size
        cross = np.zeros((t, t), dtype=bool)
        first_side = None
        for branch, place in ((a, at_ha), (b, at_hb)):   # the side of the other pair's (column's)
            hc = corner[branch]                          # branch after the row's join
            side = (place[None, :] - start[:, None]) % size >= span[:, None]
            at_a = hc[None, :] == ha[:, None]
            shared = at_a | (hc[None, :] == hb[:, None])
            r, c = np.nonzero(shared)
            if len(r):
                here = m.pos[vert[branch[c]]]
                along = m.pos[m.dest(hc[c])] - here
                other = m.pos[np.where(at_a[r, c], vert[b[r]], vert[a[r]])] - here
                inside = _in_sweep(along, other, heading[branch[c]], normal[branch[c]])
                side[r, c] = inside ^ at_a[r, c]
            if first_side is None:
                first_side = side
            else:
                cross = first_side != side
        va, vb = np.minimum(vert[a], vert[b]), np.maximum(vert[a], vert[b])
        clash = ((a[:, None] == a[None, :]) | (a[:, None] == b[None, :]) | (b[:, None] == a[None, :])
                 | (b[:, None] == b[None, :]) | ((va[:, None] == va[None, :]) & (vb[:, None] == vb[None, :]))
                 | cross | cross.T)
        np.fill_diagonal(clash, False)
        return clash.any(axis=1)

    def _cycle_places(self, ha: np.ndarray, hb: np.ndarray) -> tuple[int, np.ndarray, np.ndarray]:
        """The length of the face cycle through half-edge ``ha[0]`` and the place of each half-edge of
        ``ha`` and ``hb`` (all on that cycle) along it, counted forward from ``ha[0]``.

        The reference ranks the face's living half-edges by pointer doubling (log-many array passes
        rather than a Python step per half-edge of a face that grows with the map); where the face's
        half-edges are not exactly one cycle through ``ha[0]`` it walks the cycle."""
        m = self.m
        origin = int(ha[0])
        if self.kernels is not None:
            return self.kernels.cycle_places(m.nxt, origin, ha, hb)
        halves = np.flatnonzero(m.face[:2 * m.ne] == m.face[origin])
        halves = halves[m.alive[halves >> 1]]
        size = len(halves)
        link = np.minimum(np.searchsorted(halves, m.nxt[halves]), size - 1)
        if np.array_equal(halves[link], m.nxt[halves]):
            first = int(np.searchsorted(halves, origin))
            link[first] = first
            dist = np.ones(size, dtype=np.int64)   # steps forward to ``origin``
            dist[first] = 0
            for _ in range((size - 1).bit_length()):
                dist = dist + dist[link]
                link = link[link]
            if (link == first).all():   # one cycle: every half-edge reaches the origin
                place = (size - dist) % size
                return size, place[np.searchsorted(halves, ha)], place[np.searchsorted(halves, hb)]
        cycle = [origin]
        h = int(m.nxt[origin])
        while h != origin:
            cycle.append(h)
            h = int(m.nxt[h])
        walk = np.array(cycle, dtype=np.int64)
        order = np.argsort(walk)
        return len(walk), order[np.searchsorted(walk[order], ha)], order[np.searchsorted(walk[order], hb)]

    def _prefilter(self, rows, cols, points, heading, max_dist):
        """(row, col) index pairs, row branch drawn before col branch, that may pass ``_pair_ok``.

        Joining branches have headings at most a from opposite (``orientation``), or, pointing at each
        other within cones of half-angle a, at most 2a (``cone``); so h_i . h_j <= -cos(a or 2a): a
        five-operation test per pair that removes most pairs of a large region before the exact test."""
        hr, hc = heading[rows], heading[cols]
        cone = math.acos(min(max(self.c.cos_cone, -1.0), 1.0))
        spread = 2.0 * cone if self.cone else cone
        limit = -math.cos(min(spread, math.pi)) + 1e-6
        hh = hr[:, 0, None] * hc[None, :, 0]
        hh += hr[:, 1, None] * hc[None, :, 1]
        hh += hr[:, 2, None] * hc[None, :, 2]
        ok = hh <= limit
        ok &= rows[:, None] < cols[None, :]
        return np.nonzero(ok)

    @staticmethod
    def _aim(pi, pj, points, heading, normal):
        """How well branches pi and pj point at each other's start vertex, seen in the surface's
        tangent plane there (normal to the mean of the two branches' surface normals): the cosines of
        the angles between each heading and the direction to the other vertex, all projected on
        that plane, the distance between the vertices (in space), and how opposite the two headings
        are (minus the cosine of the angle between them, in the plane).

        On a bent surface the straight line between two vertices dips below the surface; measured in
        space it would leave the cone of two branches that point at each other along the surface."""
        d = points[pj] - points[pi]
        dist = np.sqrt(np.einsum("ij,ij->i", d, d))
        n = normal[pi] + normal[pj]
        size = np.sqrt(np.einsum("ij,ij->i", n, n))
        # opposite normals (a fold) leave no plane: compare in space, not in the plane of the
        # rounding error's direction
        n /= np.maximum(size, 1e-300)[:, None]
        n[~(size > 1e-6)] = 0.0
        # d and both headings projected on the plane and normalised, the three in one pass each
        v = np.empty((3, *d.shape))
        v[0] = d
        np.take(heading, pi, axis=0, out=v[1])
        np.take(heading, pj, axis=0, out=v[2])
        v -= np.einsum("kij,ij->ki", v, n)[:, :, None] * n
        v /= np.maximum(np.sqrt(np.einsum("kij,kij->ki", v, v)), 1e-300)[:, :, None]
        u, hi, hj = v
        toward = np.einsum("kij,ij->ki", v[1:], u)
        return toward[0], -toward[1], dist, -np.einsum("ij,ij->i", hi, hj)

    def _pair_ok(self, pi, pj, points, heading, normal, max_dist) -> np.ndarray:
        """Branch pairs whose orientations fit (``Environment.branch_join``) within the distance limit.

        ``orientation`` (the thesis, 2.5.1; journal 4.3): the dot product of the two headings is at
        most -cos(BranchAngle), i.e. they are opposite within BranchAngle, and they face each other
        (each heading has a positive component towards the other vertex). ``cone``: each heading
        points at the other vertex within BranchAngle. Both are judged in the surface's tangent
        plane (``_aim``)."""
        return self._pair_aim(pi, pj, points, heading, normal, max_dist)[0]

    def _pair_aim(self, pi, pj, points, heading, normal, max_dist):
        """``_pair_ok`` and the (ci, cj, dist) of ``_aim`` it judged by (joining ranks the pairs
        that pass by them)."""
        cos_cone = self.c.cos_cone - 1e-9
        if self.kernels is not None:
            ok, ci, cj, dist = self.kernels.pair_aim(pi, pj, points, heading, normal, float(max_dist),
                                                       cos_cone, self.cone)
            return ok, (ci, cj, dist)
        ci, cj, dist, opposite = self._aim(pi, pj, points, heading, normal)
        ok = (dist > 1e-12) & (dist <= max_dist)
        if self.cone:
            ok &= (ci >= cos_cone) & (cj >= cos_cone)
        else:
            ok &= (opposite >= cos_cone) & (ci > 1e-9) & (cj > 1e-9)
        return ok, (ci, cj, dist)

    def _adjacent(self, start_halves: np.ndarray, targets: np.ndarray) -> np.ndarray:
        """For each half-edge leaving u, whether u already has an edge to the matching target."""
        m = self.m
        if len(start_halves) <= _FEW_JOINS:   # a few: walk round each vertex in Python
            step, end = m.prv.item, m.ev.item
            out = []
            for h0, target in zip(start_halves.tolist(), targets.tolist(), strict=True):
                h, hit = h0, False
                while not hit:
                    hit = end(h >> 1, 1 - (h & 1)) == target
                    h = step(h) ^ 1
                    if h == h0:
                        break
                out.append(hit)
            return np.array(out, dtype=bool)
        found = np.zeros(len(start_halves), dtype=bool)
        cur = start_halves.copy()
        active = np.ones(len(cur), dtype=bool)
        while active.any():
            c = cur[active]
            found[active] |= m.dest(c) == targets[active]
            nxt = m.prv[c] ^ 1
            cur[active] = nxt
            active[active] = nxt != start_halves[active]
        return found

    def _new_faces_one_by_one(self, x: np.ndarray, y: np.ndarray, new_face: np.ndarray) -> None:
        """Of the two cycles through each new edge's halves x and y, the shorter (x's on a tie)
        becomes ``new_face``: walked pair by pair (a few joins: cheaper than array passes)."""
        m = self.m
        step = m.nxt.item
        for xr, yr, face in zip(x.tolist(), y.tolist(), new_face.tolist(), strict=True):
            px, py = step(xr), step(yr)
            while px != xr and py != yr:
                px, py = step(px), step(py)
            h0 = xr if px == xr else yr
            walk = [h0]
            h = step(h0)
            while h != h0:
                walk.append(h)
                h = step(h)
            m.face[walk] = face

    def _new_faces_lockstep(self, x: np.ndarray, y: np.ndarray, new_face: np.ndarray) -> None:
        """``_new_faces_one_by_one`` for many joins: every pair's cycles walked in lockstep."""
        m = self.m
        j = len(x)
        # walk both new cycles in lockstep; the shorter one becomes the new face
        cx, cy = m.nxt[x], m.nxt[y]
        open_ = np.ones(j, dtype=bool)
        shorter_is_x = np.zeros(j, dtype=bool)
        for _ in range(32):
            done_x = open_ & (cx == x)
            done_y = open_ & (cy == y) & ~done_x
            shorter_is_x |= done_x
            open_ &= ~(done_x | done_y)
            if not open_.any():
                break
            cx = np.where(open_, m.nxt[cx], cx)
            cy = np.where(open_, m.nxt[cy], cy)
        step = m.nxt.item  # scalar reads: cheaper than converting the whole array for a few walks
        for r in open_.nonzero()[0]:  # long cycles on both sides: walk them one by one
            xr, yr, px, py = int(x[r]), int(y[r]), int(cx[r]), int(cy[r])
            while px != xr and py != yr:
                px, py = step(px), step(py)
            shorter_is_x[r] = px == xr
        start = np.where(shorter_is_x, x, y)
        short = ~open_
        cur = start.copy()
        active = short.copy()
        while active.any():
            m.face[cur[active]] = new_face[active]
            cur[active] = m.nxt[cur[active]]
            active &= cur != start
        for r in open_.nonzero()[0]:
            h0 = int(start[r])
            h = h0
            walk = []
            while True:
                walk.append(h)
                h = step(h)
                if h == h0:
                    break
            m.face[walk] = new_face[r]

    def _split(self, a, b, vert, corner, label, age, rev, used, heading, normal) -> None:
        """Join branch pairs (a, b): a new edge between their vertices splits each one's face; the
        other pending branches at those corners move to the part of the corner they point into."""
        m = self.m
        j = len(a)
        ne0 = m.ne
        m.reserve(m.nv, ne0 + j)
        if self.kernels is not None:
            x, y = self.kernels.split(m.ev, m.label, m.age, m.alive, m.up, m.nxt, m.prv, m.face, a, b, vert,
                                      corner, label, age, rev, normal, ne0, m.nf)
            m.ne = ne0 + j
            m.nf += j
            self._move_corners(a, b, x, y, vert, corner, used, heading, normal)
            return
        e = ne0 + np.arange(j, dtype=np.int64)
        u, w = vert[a], vert[b]
        flip = rev[a]
        m.ev[e, 0] = np.where(flip, w, u)
        m.ev[e, 1] = np.where(flip, u, w)
        m.label[e] = label[a]
        m.age[e] = age[a]
        m.up[e] = normal[a]
        m.alive[e] = True
        m.ne = ne0 + j
        x = 2 * e + flip.astype(np.int64)  # u -> w
        y = x ^ 1  # w -> u
        ha, hb = corner[a], corner[b]
        pa, pb = m.prv[ha], m.prv[hb]
        f = m.face[ha]
        m.nxt[pa] = x
        m.prv[x] = pa
        m.nxt[x] = hb
        m.prv[hb] = x
        m.nxt[pb] = y
        m.prv[y] = pb
        m.nxt[y] = ha
        m.prv[ha] = y
        new_face = m.nf + np.arange(j, dtype=np.int64)
        m.nf += j
        m.face[x] = f
        m.face[y] = f
        if j <= _FEW_JOINS:
            self._new_faces_one_by_one(x, y, new_face)
        else:
            self._new_faces_lockstep(x, y, new_face)
        self._move_corners(a, b, x, y, vert, corner, used, heading, normal)

    def _move_corners(self, a, b, x, y, vert, corner, used, heading, normal) -> None:
        """After joins (a, b) made edges with halves x (a's vertex to b's) and y: the other pending
        branches at a split corner keep it (the sector from its direction round to the new edge)
        or move to the new edge's half leaving the same vertex."""
        m = self.m
        j = len(a)
        ha, hb = corner[a], corner[b]
        u, w = vert[a], vert[b]
        split_corners = np.concatenate([ha, hb])
        order = np.argsort(split_corners)
        sorted_corners = split_corners[order]
        waiting = (~used & (corner >= 0)).nonzero()[0]
        at = np.minimum(np.searchsorted(sorted_corners, corner[waiting]), len(sorted_corners) - 1)
        found = sorted_corners[at] == corner[waiting]
        hit = waiting[found]
        if not len(hit):
            return
        slot = order[at[found]]
        at_a = slot < j
        pair = np.where(at_a, slot, slot - j)
        here = m.pos[vert[hit]]
        other = np.where(at_a[:, None], m.pos[w[pair]], m.pos[u[pair]])
        old = corner[hit]
        along = m.pos[m.dest(old)] - here
        inside = _in_sweep(along, other - here, heading[hit], normal[hit])
        corner[hit] = np.where(inside, old, np.where(at_a, x[pair], y[pair]))


#: Joins in one round up to which the new faces' cycles are walked one by one in Python.
_FEW_JOINS = 16


def _repeat_row(row: np.ndarray, n: int) -> np.ndarray:
    """``row`` repeated ``n`` times, flat (``np.tile`` without its Python overhead)."""
    out = np.empty((n, len(row)), dtype=row.dtype)
    out[:] = row
    return out.ravel()


@functools.lru_cache(maxsize=64)
def _triu(size: int) -> tuple[np.ndarray, np.ndarray]:
    """``np.triu_indices(size, 1)``, computed once per size (joining asks for the same few)."""
    ti, tj = np.triu_indices(size, 1)
    ti.setflags(write=False)
    tj.setflags(write=False)
    return ti, tj


def _in_sweep(a: np.ndarray, b: np.ndarray, v: np.ndarray, n: np.ndarray) -> np.ndarray:
    """Whether v lies strictly inside the counter-clockwise (about n) sweep from a to b, row-wise."""
    return _swept(np.einsum("ij,ij->i", _cross(a, b), n), np.einsum("ij,ij->i", a, b),
                  np.einsum("ij,ij->i", _cross(a, v), n), np.einsum("ij,ij->i", a, v))


def _swept(sweep_y: np.ndarray, sweep_x: np.ndarray, y: np.ndarray, x: np.ndarray) -> np.ndarray:
    """``_in_sweep`` from the arguments of its two angles: whether the angle of (x, y) lies strictly
    inside (0, angle of (sweep_x, sweep_y)), both taken in [0, 2 pi)."""
    two_pi = 2.0 * np.pi
    sweep = np.mod(np.arctan2(sweep_y, sweep_x), two_pi)
    ang = np.mod(np.arctan2(y, x), two_pi)
    return (ang > 1e-9) & (ang < sweep - 1e-9)


def grow(system: RewriteSystem, env=None, *, steps: int | None = None, seed: int | None = None,
         keep_steps: bool = False) -> GrowthResult:
    """Grow ``system`` in ``env`` (default: the empty environment) for ``steps`` derivation steps
    (default ``env.steps``) from ``seed`` (default ``env.seed``). Growth stops early, with
    ``capped`` set, when the map would exceed ``env.max_edges`` or time passes ``env.max_seconds``;
    the surface is then the valid map reached so far."""
    from genr8_dist.environment import Environment

    env = Environment() if env is None else env
    n_steps = env.steps if steps is None else int(steps)
    if n_steps < 0:
        raise GrowthError(f"steps must be >= 0, got {n_steps}")
    rng = stream(env.seed if seed is None else int(seed), "growth")
    deadline = time.perf_counter() + env.max_seconds
    grower = _Grower(system, env, rng, deadline)
    history = [grower.m.surface()] if keep_steps else []
    stats: list[StepStats] = []
    capped = None
    for step in range(1, n_steps + 1):
        t0 = time.perf_counter()
        try:
            grower.step(step)
        except _Capped as cap:
            capped = cap.what
        m = grower.m
        n_regions = m.nf - 1  # faces are only ever split, never merged
        stats.append(StepStats(step, m.nv, m.ne, n_regions, time.perf_counter() - t0))
        if keep_steps:
            history.append(m.surface())
        if capped:
            break
    surface = history[-1] if keep_steps else grower.m.surface()
    if grower.kernels is None:
        global _reference_work
        _reference_work += grower.spent
    return GrowthResult(surface, stats, capped, history, grower.spent)
