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

The parts live beside this module: ``rules`` (the compiled rewrite system), ``halfedge`` (the map),
``branches`` (the pending branches), ``joining`` (branch joining), ``budget`` (the caps) and
``_kernels`` (when the compiled kernels of ``_growth_compiled`` run instead of the numpy reference:
both grow the same surfaces bit for bit).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from types import ModuleType

import numpy as np

from genr8_dist.environment import Environment
from genr8_dist.errors import GrowthError
from genr8_dist.hemls._kernels import KernelSwitch
from genr8_dist.hemls.branches import Pending, PendingBranches
from genr8_dist.hemls.budget import WORK_BATCH, WORK_PAIRS, Budget, Capped
from genr8_dist.hemls.halfedge import frames, seed_map
from genr8_dist.hemls.joining import TIE, BranchJoining
from genr8_dist.hemls.language import RewriteSystem
from genr8_dist.hemls.rules import Group, compile_system
from genr8_dist.hemls.surface import Surface
from genr8_dist.hemls.turtle import AT_END, LEFT, RIGHT, Template, sector_side
from genr8_dist.rng import stream

__all__ = ["TIE", "WORK_BATCH", "WORK_PAIRS", "GrowthResult", "StepStats", "grow", "seed_surface"]




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
    seed, ``history[i]`` the surface after step i). ``fired``: per rule of the system, whether it
    rewrote an edge (a rule that never did is read only for its predecessor, contexts and
    condition: its successors could change and the growth would not)."""

    surface: Surface
    steps: list[StepStats]
    capped: str | None = None
    history: list[Surface] = field(default_factory=list)
    work: int = 0   # edge-steps spent (what ``max_work`` caps); see ``WORK_PAIRS``
    fired: tuple[bool, ...] = ()

    @property
    def seconds(self) -> float:
        """Total seconds spent in derivation steps."""
        return sum(s.seconds for s in self.steps)



def _check_kernels(module: ModuleType) -> None:
    assert (module.LEFT, module.RIGHT) == (LEFT, RIGHT)


#: The compiled kernels load once a process has grown this many edge-steps (``GrowthResult.work``)
#: with the reference code: ~0.4 s CPU, about what loading them costs.
KERNELS = KernelSwitch("genr8_dist.hemls._growth_compiled", 200_000, _check_kernels)
_load_kernels = KERNELS.load
_kernels = KERNELS.kernels


def seed_surface(system: RewriteSystem, env: Environment | None = None) -> Surface:
    """The seed polygon of ``system`` in ``env`` as a surface (before any derivation step)."""
    env = Environment() if env is None else env
    return seed_map(compile_system(system), env).surface()


class _Grower(BranchJoining):
    """One growth: the map, the compiled system, the environment, the random stream and the caps."""

    kernels: ModuleType | None = None   # the compiled kernels (``KERNELS``) this growth uses, if any

    def __init__(self, system: RewriteSystem, env: Environment, rng: np.random.Generator,
                 deadline: float) -> None:
        self.c = compile_system(system)
        self.env = env
        self.rng = rng
        self.m = seed_map(self.c, env)
        self.kernels = self.m.kernels = _kernels()
        self.budget = Budget(int(env.max_edges), int(getattr(env, "max_work", 0) or 0), deadline)
        self.cone = getattr(env, "branch_join", "orientation") == "cone"
        self.ties = getattr(env, "branch_ties", "crossing")
        self._stop_later: list[np.ndarray] = []  # vertices drawn between two stopped ones
        self._keys: np.ndarray | None = None
        self.fired = [False] * len(system.rules)   # per rule: chosen for an edge (``GrowthResult``)

    # -- step ------------------------------------------------------------------------------------
    def step(self, step: int) -> None:
        m = self.m
        self.budget.spend(m.n_alive())
        inc = self.env.increase_size(m.pos[:m.nv].copy(), step=step, masses=m.mass[:m.nv].copy(),
                                     stopped=m.stopped[:m.nv].copy(), perimeter=m.perimeter_mask(),
                                     edges=m.edge_array(), rng=self.rng)
        m.pos[:m.nv] = inc.positions
        m.stopped[:m.nv] = inc.stopped
        max_dist = self.env.max_branch_distance(step)
        pending = PendingBranches()
        try:
            for group in self.c.groups:
                self.budget.check_time()
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
        result: np.ndarray = count - own > 0
        return result

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
        result: np.ndarray = count[m.ev[idx, 1]] - own > 0
        return result

    def _rewrite_group(self, group: Group, pending: PendingBranches) -> None:
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
            self.fired[rule.index] = True
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
        if grow_edges > self.budget.room(m.n_alive()):
            raise Capped("edges")
        self.budget.spend(grow_edges + WORK_BATCH * len(batches))
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

    def _rewrite(self, idx: np.ndarray, tpl: Template, areas: np.ndarray, pending: PendingBranches) -> None:
        if self.kernels is not None:
            self._rewrite_compiled(self.kernels, idx, tpl, areas, pending)
            return
        m = self.m
        n, k = len(idx), tpl.n_segments
        s, t, p, length, h, left, up = frames(m, idx, areas, left=k > 1 or tpl.n_branches > 0)
        nv0, ne0 = m.nv, m.ne
        nv1, ne1 = nv0 + n * (k - 1), ne0 + n * k
        if nv1 > len(m.pos) or ne1 > len(m.ev):
            m.reserve(nv1, ne1)
        chain = np.empty((n, k + 1), dtype=np.int64)  # the vertices along each new main line
        chain[:, 0] = s
        chain[:, k] = t
        if k > 1:
            assert left is not None     # asked for above
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
        assert left is not None         # asked for above
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

    def _rewrite_compiled(self, kernels: ModuleType, idx: np.ndarray, tpl: Template, areas: np.ndarray,
                          pending: PendingBranches) -> None:
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

    def _add_branches(self, pending: PendingBranches, tpl: Template, n: int, idx: np.ndarray,
                      bvert: np.ndarray, corner: np.ndarray, heading: np.ndarray, up: np.ndarray,
                      first: np.ndarray, last: np.ndarray) -> None:
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
        pending.add(Pending(bvert.ravel(), corner.ravel(), blabels, bages, heading.reshape(-1, 3),
                            _repeat_row(tpl.branch_reversed, n), np.repeat(up, nb, axis=0)))

    def _corner_at(self, h0: int, heading: np.ndarray, normal: np.ndarray) -> int:
        """The half-edge leaving the vertex of ``h0`` into the region ``heading`` points into."""
        m = self.m
        v = int(m.origin(h0))
        helper = np.array([1.0, 0.0, 0.0]) if abs(normal[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
        e1 = np.cross(normal, helper)
        e1 /= np.linalg.norm(e1)
        e2 = np.cross(normal, e1)

        def flat(vec: np.ndarray) -> np.ndarray:
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

def _repeat_row(row: np.ndarray, n: int) -> np.ndarray:
    """``row`` repeated ``n`` times, flat (``np.tile`` without its Python overhead)."""
    out = np.empty((n, len(row)), dtype=row.dtype)
    out[:] = row
    return out.ravel()


def grow(system: RewriteSystem, env: Environment | None = None, *, steps: int | None = None,
         seed: int | None = None, keep_steps: bool = False) -> GrowthResult:
    """Grow ``system`` in ``env`` (default: the empty environment) for ``steps`` derivation steps
    (default ``env.steps``) from ``seed`` (default ``env.seed``). Growth stops early, with
    ``capped`` set, when the map would exceed ``env.max_edges`` or time passes ``env.max_seconds``;
    the surface is then the valid map reached so far."""
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
        except Capped as cap:
            capped = cap.what
        m = grower.m
        n_regions = m.nf - 1  # faces are only ever split, never merged
        stats.append(StepStats(step, m.nv, m.ne, n_regions, time.perf_counter() - t0))
        if keep_steps:
            history.append(m.surface())
        if capped:
            break
    surface = history[-1] if keep_steps else grower.m.surface()
    spent = grower.budget.spent
    if grower.kernels is None:
        KERNELS.count(spent)
    return GrowthResult(surface, stats, capped, history, spent, tuple(grower.fired))
