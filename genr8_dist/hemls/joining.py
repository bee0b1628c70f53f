"""Branch joining (journal 4.3, thesis 2.5.1): pending branches that point at each other join into new
edges that split their region; ties between mirror-image joins are settled without looking at the
order the branches were drawn in (``branch_ties``).

``BranchJoining`` is the joining half of a growth (``hemls.growth``): it works on the growth's map
(``m``), compiled system (``c``), kernels, budget and join settings (``cone``, ``ties``).
"""

from __future__ import annotations

import functools
import math
from types import ModuleType

import numpy as np

from genr8_dist.hemls.branches import Pending, PendingBranches
from genr8_dist.hemls.budget import Budget, Capped
from genr8_dist.hemls.halfedge import HalfEdgeMap, cross
from genr8_dist.hemls.rules import CompiledSystem

__all__ = ["TIE", "BranchJoining"]

#: Join pairs whose alignment and distance (each rounded to 1e-9) differ by no more than this are
#: tied (``branch_ties``): mirror images, computed in floating point, may round one step apart.
TIE = 1.5e-9
Arr = np.ndarray    # the pairs' and branches' columns: index and value arrays


class BranchJoining:
    """Joining of a growth's pending branches; mixed into the grower, which sets the attributes."""

    m: HalfEdgeMap
    c: CompiledSystem
    budget: Budget
    kernels: ModuleType | None
    cone: bool      # ``branch_join = "cone"``: each branch points at the other within the cone
    ties: str       # ``branch_ties``: "crossing", "none" or "first"

    def _join(self, pending: PendingBranches, max_dist: float) -> None:
        if len(pending) < 2:
            return
        m = self.m
        br = pending.arrays()
        vert, corner, label, heading, normal = br.vertex, br.corner, br.label, br.heading, br.normal
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
            self.budget.spend(pairs=len(pi))
            pi_all.append(pi)
            pj_all.append(pj)
        for g in (sizes > 48).nonzero()[0]:
            members = cand[starts[g]:starts[g] + sizes[g]]
            new = members[members >= old]
            if not len(new):
                continue
            rows = max(1, 1_000_000 // len(new))
            for r0 in range(0, len(members), rows):
                self.budget.check_time()
                block = members[r0:r0 + rows]
                self.budget.spend(pairs=len(block) * len(new))
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
            self.budget.check_time()
            self.budget.spend(pairs=len(pi))
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
                                           pj, br)
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
            room = self.budget.room(m.n_alive())
            capped = len(chosen) > room
            if capped:
                chosen, a, b = chosen[:room], a[:room], b[:room]
            if len(chosen):
                used[a] = True
                used[b] = True
                live[chosen] = False
                self._split(a, b, br, used)
            if capped:
                pending.keep(~used)
                raise Capped("edges")
        pending.keep(~used)

    def _settle_ties(self, chosen: Arr, at: Arr, fi: Arr, fa: Arr, lead: Arr, score: Arr, gap: Arr, live: Arr,
                     settled: Arr, pi: Arr, pj: Arr, br: Pending) -> Arr:
        """Settle ties without looking at the order branches were drawn in (``branch_ties``).

        A face's tied pairs are its live pairs as good as its best (alignment and distance within
        ``TIE``): on a symmetric map, a join and its mirror image. ``"crossing"`` (the default) makes
        every tied pair that conflicts with no other, and none of those that do (``_conflicts``);
        ``"none"`` makes none of them. Pairs left out are marked dead, pairs left in ``settled``;
        returns the chosen pairs, a face whose best pair was left out choosing its first tied pair
        left in (the others follow in later rounds, in any order: none crosses another)."""
        close: Arr
        tied_faces: Arr
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
                near = self._adjacent(br.corner[pi[tied]], br.vertex[pj[tied]])  # would be dropped anyway
                live[tied[near]] = False
                tied = tied[~near]
                out = self._conflicts(tied, pi, pj, br)
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

    def _centre_on_left(self, a: Arr, b: Arr, vert: Arr, normal: Arr, centre: Arr) -> tuple[Arr, Arr]:
        """Join pairs (a, b) reordered so that the new edge, from a's vertex to b's, has the map's
        centre on its left (about the branches' surface normal); left as drawn where the centre is
        on the line (within 1e-9 of a radian).

        The edge's direction decides which side the drawing of its successor takes in the next
        step; a rule that only looks at the geometry gives a symmetric map's mirror-image joins
        mirror-image directions (the mirror edge of an edge runs the other way), where the order
        the branches were drawn in need not."""
        m = self.m
        if self.kernels is not None:
            pair: tuple[Arr, Arr] = self.kernels.centre_on_left(a, b, vert, m.pos, normal, centre)
            return pair
        u, w = m.pos[vert[a]], m.pos[vert[b]]
        along, to_centre = w - u, centre - u
        n = normal[a] + normal[b]
        side = np.einsum("ij,ij->i", cross(along, to_centre), n)
        scale = np.sqrt(np.einsum("ij,ij->i", along, along) * np.einsum("ij,ij->i", to_centre, to_centre)
                        * np.einsum("ij,ij->i", n, n))
        swap = side < -1e-9 * scale
        return np.where(swap, b, a), np.where(swap, a, b)

    def _conflicts(self, tied: Arr, pi: Arr, pj: Arr, br: Pending) -> Arr:
        """Which of the join pairs ``tied`` (all in one face) conflict with another of them: they
        share a branch or a vertex pair, or one, made first, would leave the other's two branches in
        different regions (they cross), as ``_split`` decides it: a join from corner ha to corner hb
        splits the face's cycle into the part from ha round to hb and the rest, and a branch at ha's
        or hb's own corner goes by where its heading points (``_in_sweep``)."""
        m = self.m
        vert, corner, heading, normal = br.vertex, br.corner, br.heading, br.normal
        t = len(tied)
        if t < 2:   # the others were already joined by an edge
            return np.zeros(t, dtype=bool)
        self.budget.spend(pairs=t * t)
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
            result: np.ndarray = self.kernels.clashes(a, b, vert, sides[0], sides[1])
            return result
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
        result = clash.any(axis=1)
        return result

    def _cycle_places(self, ha: np.ndarray, hb: np.ndarray) -> tuple[int, np.ndarray, np.ndarray]:
        """The length of the face cycle through half-edge ``ha[0]`` and the place of each half-edge of
        ``ha`` and ``hb`` (all on that cycle) along it, counted forward from ``ha[0]``.

        The reference ranks the face's living half-edges by pointer doubling (log-many array passes
        rather than a Python step per half-edge of a face that grows with the map); where the face's
        half-edges are not exactly one cycle through ``ha[0]`` it walks the cycle."""
        m = self.m
        origin = int(ha[0])
        if self.kernels is not None:
            places: tuple[int, np.ndarray, np.ndarray] = self.kernels.cycle_places(m.nxt, origin, ha, hb)
            return places
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

    def _prefilter(self, rows: Arr, cols: Arr, points: Arr, heading: Arr, max_dist: float
                   ) -> tuple[Arr, ...]:
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
    def _aim(pi: Arr, pj: Arr, points: Arr, heading: Arr, normal: Arr) -> tuple[Arr, Arr, Arr, Arr]:
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

    def _pair_ok(self, pi: Arr, pj: Arr, points: Arr, heading: Arr, normal: Arr, max_dist: float) -> Arr:
        """Branch pairs whose orientations fit (``Environment.branch_join``) within the distance limit.

        ``orientation`` (the thesis, 2.5.1; journal 4.3): the dot product of the two headings is at
        most -cos(BranchAngle), i.e. they are opposite within BranchAngle, and they face each other
        (each heading has a positive component towards the other vertex). ``cone``: each heading
        points at the other vertex within BranchAngle. Both are judged in the surface's tangent
        plane (``_aim``)."""
        result: np.ndarray = self._pair_aim(pi, pj, points, heading, normal, max_dist)[0]
        return result

    def _pair_aim(self, pi: Arr, pj: Arr, points: Arr, heading: Arr, normal: Arr, max_dist: float
                  ) -> tuple[Arr, tuple[Arr, Arr, Arr]]:
        """``_pair_ok`` and the (ci, cj, dist) of ``_aim`` it judged by (joining ranks the pairs
        that pass by them)."""
        cos_cone = self.c.cos_cone - 1e-9
        if self.kernels is not None:
            ok: Arr
            ci: Arr
            cj: Arr
            dist: Arr
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

    def _split(self, a: Arr, b: Arr, br: Pending, used: Arr) -> None:
        """Join branch pairs (a, b): a new edge between their vertices splits each one's face; the
        other pending branches at those corners move to the part of the corner they point into."""
        m = self.m
        vert, corner, label, age, rev, normal = br.vertex, br.corner, br.label, br.age, br.reversed, br.normal
        j = len(a)
        ne0 = m.ne
        m.reserve(m.nv, ne0 + j)
        if self.kernels is not None:
            x, y = self.kernels.split(m.ev, m.label, m.age, m.alive, m.up, m.nxt, m.prv, m.face, a, b, vert,
                                      corner, label, age, rev, normal, ne0, m.nf)
            m.ne = ne0 + j
            m.nf += j
            self._move_corners(a, b, x, y, br, used)
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
        self._move_corners(a, b, x, y, br, used)

    def _move_corners(self, a: Arr, b: Arr, x: Arr, y: Arr, br: Pending, used: Arr) -> None:
        """After joins (a, b) made edges with halves x (a's vertex to b's) and y: the other pending
        branches at a split corner keep it (the sector from its direction round to the new edge)
        or move to the new edge's half leaving the same vertex."""
        m = self.m
        vert, corner, heading, normal = br.vertex, br.corner, br.heading, br.normal
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


@functools.lru_cache(maxsize=64)
def _triu(size: int) -> tuple[np.ndarray, np.ndarray]:
    """``np.triu_indices(size, 1)``, computed once per size (joining asks for the same few)."""
    ti, tj = np.triu_indices(size, 1)
    ti.setflags(write=False)
    tj.setflags(write=False)
    return ti, tj


def _in_sweep(a: np.ndarray, b: np.ndarray, v: np.ndarray, n: np.ndarray) -> np.ndarray:
    """Whether v lies strictly inside the counter-clockwise (about n) sweep from a to b, row-wise."""
    return _swept(np.einsum("ij,ij->i", cross(a, b), n), np.einsum("ij,ij->i", a, b),
                  np.einsum("ij,ij->i", cross(a, v), n), np.einsum("ij,ij->i", a, v))


def _swept(sweep_y: np.ndarray, sweep_x: np.ndarray, y: np.ndarray, x: np.ndarray) -> np.ndarray:
    """``_in_sweep`` from the arguments of its two angles: whether the angle of (x, y) lies strictly
    inside (0, angle of (sweep_x, sweep_y)), both taken in [0, 2 pi)."""
    two_pi = 2.0 * np.pi
    sweep = np.mod(np.arctan2(sweep_y, sweep_x), two_pi)
    ang = np.mod(np.arctan2(y, x), two_pi)
    result: np.ndarray = (ang > 1e-9) & (ang < sweep - 1e-9)
    return result
