"""Compiled kernels of growth (``genr8_dist.hemls.growth``), with numba.

Optional, as ``genr8_dist.hemls._compiled`` is for the triangulation: ``growth`` imports this module
the first time a growth needs it, only when numba imports (the ``fast`` extra) and ``GENR8_COMPILED``
is not ``0``; otherwise the numpy reference code in ``growth`` runs. A rewrite of a few edges is a
hundred numpy calls on arrays of a few elements, so most of its time was call overhead; here it is one
call. Each kernel performs the same IEEE operations in the same order as the reference it replaces (no
fastmath): a dot product of 3-vectors is ``(a0 b0 + a2 b2) + a1 b1 + 0.0``, the order in which
``np.einsum("ij,ij->i")`` adds (its products in vector lanes 0-3, lane 3 zero), so the surfaces are the
same bit for bit.

``face_areas``: the area vector of every face (``_Map.face_areas``). ``rewrite``: one successor
placed on a batch of edges (``_Grower._rewrite`` up to the branches' corners at the main line's ends).
``pair_aim``: which branch pairs may join and how well they aim (``_Grower._pair_aim``). ``new_faces``:
the faces a round of joins makes (``_Grower._new_faces_one_by_one``). ``centre_on_left``: the direction
of each new edge (``_Grower._centre_on_left``). ``cycles``: the walk round every face (``_Map.cycles``).
``split``: the new edges and faces of a round of joins (``_Grower._split``, before the pending branches'
corners move). ``compact``: ``_Map.compact``. ``ties``: the tied pairs of a round (``_settle_ties``).
``cycle_places``: where tied pairs' corners lie along their face's cycle (``_Grower._cycle_places``).
``tie_side`` and ``clashes``: which tied pairs conflict (``_Grower._conflicts``), the angles of its
``_in_sweep`` tests left to numpy's ``arctan2`` between the two (``tie_side`` gives their arguments).

Compiled code is cached on disk (``_compiled._jit``); where no cache directory is writable the kernels
are compiled in memory instead.
"""

from __future__ import annotations

import math

import numpy as np

from genr8_dist.hemls._compiled import _jit, _np_max  # numba.njit, cached on disk; np.maximum

__all__ = ["centre_on_left", "clashes", "compact", "cycle_places", "cycles", "face_areas", "new_faces",
           "pair_aim", "rewrite", "split", "tie_side", "ties"]

# ``turtle.LEFT`` and ``turtle.RIGHT`` (asserted equal in ``growth``, where this module is imported)
LEFT = 1
RIGHT = -1


@_jit
def _dot(a0: float, a1: float, a2: float, b0: float, b1: float, b2: float) -> float:
    return ((a0 * b0 + a2 * b2) + a1 * b1) + 0.0


@_jit
def face_areas(pos, ev, alive, face, ne, nf):
    """Area vector of every face: half the sum, over its half-edges in the order 2e (e ascending),
    then 2e + 1, of origin x destination (Newell); zero for the outside (``np.bincount``'s order)."""
    out = np.zeros((nf, 3))
    for side in range(2):
        for e in range(ne):
            if not alive[e]:
                continue
            a, b = ev[e, 0], ev[e, 1]
            a0, a1, a2 = pos[a, 0], pos[a, 1], pos[a, 2]
            b0, b1, b2 = pos[b, 0], pos[b, 1], pos[b, 2]
            c0 = a1 * b2 - a2 * b1
            c1 = a2 * b0 - a0 * b2
            c2 = a0 * b1 - a1 * b0
            f = face[2 * e + side]
            if side == 0:
                out[f, 0] += c0
                out[f, 1] += c1
                out[f, 2] += c2
            else:
                out[f, 0] += -c0
                out[f, 1] += -c1
                out[f, 2] += -c2
    for f in range(nf):
        for c in range(3):
            out[f, c] = 0.5 * out[f, c]
    out[0, 0] = 0.0
    out[0, 1] = 0.0
    out[0, 2] = 0.0
    return out


@_jit
def rewrite(pos, mass, stopped, ev, label, age, alive, up, nxt, prv, face, idx, areas, nv0, ne0,
            vertex_mass, points, labels, main_ages, main_timed, main_reversed, branch_vertex,
            branch_heading, branch_side):
    """Replace each edge ``idx[r]`` by the successor's main line drawn on its frame (``_frames``):
    new vertices from ``nv0``, new edges from ``ne0`` (``labels``: theirs, row by row), half-edges
    relinked. Returns each edge's surface normal (n, 3), whether both its ends were stopped, the
    half-edge map of the replaced halves (``repl``), the main line's first and last half-edges, and
    the branches' vertices, headings (n * b, 3) and corners (-1 where growth finds them)."""
    n = len(idx)
    k = len(main_reversed)
    nb = len(branch_vertex)
    ne1 = ne0 + n * k
    upn = np.empty((n, 3))
    both = np.zeros(n, dtype=np.bool_)
    first = np.empty(n, dtype=np.int64)
    last = np.empty(n, dtype=np.int64)
    bvert = np.empty(n * nb, dtype=np.int64)
    heading = np.empty((n * nb, 3))
    corner = np.full(n * nb, -1, dtype=np.int64)
    repl = np.arange(2 * ne1)
    chain = np.empty(k + 1, dtype=np.int64)
    for r in range(n):
        e = idx[r]
        s, t = ev[e, 0], ev[e, 1]
        p0, p1, p2 = pos[s, 0], pos[s, 1], pos[s, 2]
        d0, d1, d2 = pos[t, 0] - p0, pos[t, 1] - p1, pos[t, 2] - p2
        length = math.sqrt(_dot(d0, d1, d2, d0, d1, d2))
        safe = length if length > 1e-300 else 1.0
        h0, h1, h2 = d0 / safe, d1 / safe, d2 / safe
        if length <= 1e-300:
            h0, h1, h2 = 1.0, 0.0, 0.0
        fa, fb = face[2 * e], face[2 * e + 1]
        n0, n1, n2 = areas[fa, 0] + areas[fb, 0], areas[fa, 1] + areas[fb, 1], areas[fa, 2] + areas[fb, 2]
        size = math.sqrt(_dot(n0, n1, n2, n0, n1, n2))
        weak = size <= 1e-9 * safe * safe
        scale = 1.0 if weak else size
        n0, n1, n2 = n0 / scale, n1 / scale, n2 / scale
        if weak:
            n0, n1, n2 = up[e, 0], up[e, 1], up[e, 2]
        for attempt in range(4):
            c = _dot(n0, n1, n2, h0, h1, h2)
            u0, u1, u2 = n0 - c * h0, n1 - c * h1, n2 - c * h2
            un = math.sqrt(_dot(u0, u1, u2, u0, u1, u2))
            if attempt == 3 or not un < 1e-6:
                break
            if attempt == 0:
                n0, n1, n2 = up[e, 0], up[e, 1], up[e, 2]
            elif attempt == 1:
                n0, n1, n2 = 0.0, 0.0, 1.0
            else:
                n0, n1, n2 = 0.0, 1.0, 0.0
        unit = un if un > 1e-300 else 1.0
        u0, u1, u2 = u0 / unit, u1 / unit, u2 / unit
        l0, l1, l2 = u1 * h2 - u2 * h1, u2 * h0 - u0 * h2, u0 * h1 - u1 * h0   # left = up x heading
        upn[r, 0], upn[r, 1], upn[r, 2] = u0, u1, u2
        # the main line's vertices
        chain[0] = s
        chain[k] = t
        for i in range(1, k):
            v = nv0 + r * (k - 1) + (i - 1)
            x, y, z = points[i, 0], points[i, 1], points[i, 2]
            pos[v, 0] = p0 + length * ((x * h0 + y * l0) + z * u0)
            pos[v, 1] = p1 + length * ((x * h1 + y * l1) + z * u1)
            pos[v, 2] = p2 + length * ((x * h2 + y * l2) + z * u2)
            mass[v] = vertex_mass
            stopped[v] = False
            chain[i] = v
        both[r] = stopped[s] and stopped[t]
        # its edges
        old_age = age[e]
        for i in range(k):
            f = ne0 + r * k + i
            if main_reversed[i]:
                ev[f, 0], ev[f, 1] = chain[i + 1], chain[i]
            else:
                ev[f, 0], ev[f, 1] = chain[i], chain[i + 1]
            label[f] = labels[r * k + i]
            a = old_age + main_ages[i] if main_timed[i] else main_ages[i]
            age[f] = a if a > 0 else 0
            alive[f] = True
            up[f, 0], up[f, 1], up[f, 2] = u0, u1, u2
        first[r] = 2 * (ne0 + r * k) + main_reversed[0]
        last[r] = (2 * (ne0 + r * k + k - 1) + main_reversed[k - 1]) ^ 1
        repl[2 * e] = first[r]
        repl[2 * e + 1] = last[r]
        # its branches
        for b in range(nb):
            j = branch_vertex[b]
            bvert[r * nb + b] = chain[j]
            x, y, z = branch_heading[b, 0], branch_heading[b, 1], branch_heading[b, 2]
            heading[r * nb + b, 0] = (x * h0 + y * l0) + z * u0
            heading[r * nb + b, 1] = (x * h1 + y * l1) + z * u1
            heading[r * nb + b, 2] = (x * h2 + y * l2) + z * u2
            if branch_side[b] == LEFT:
                corner[r * nb + b] = 2 * (ne0 + r * k + j) + main_reversed[j]
            elif branch_side[b] == RIGHT:
                corner[r * nb + b] = (2 * (ne0 + r * k + j - 1) + main_reversed[j - 1]) ^ 1
    # the half-edges: the halves before each replaced one lead into its new main line (read before
    # any link changes), the main lines link through, the replaced halves die
    before = np.empty(2 * n, dtype=np.int64)
    next_ho = np.empty(n, dtype=np.int64)
    next_ht = np.empty(n, dtype=np.int64)
    for r in range(n):
        e = idx[r]
        before[r] = prv[2 * e]
        before[n + r] = prv[2 * e + 1]
        next_ho[r] = nxt[2 * e]
        next_ht[r] = nxt[2 * e + 1]
    for r in range(n):
        nxt[before[r]] = first[r]
    for r in range(n):
        nxt[before[n + r]] = last[r]
    for r in range(n):
        e = idx[r]
        fo, ft = face[2 * e], face[2 * e + 1]
        base = ne0 + r * k
        for i in range(k):
            fw = 2 * (base + i) + main_reversed[i]
            bw = fw ^ 1
            if i == k - 1:
                nxt[fw] = repl[next_ho[r]]
            else:
                nxt[fw] = 2 * (base + i + 1) + main_reversed[i + 1]
            if i == 0:
                nxt[bw] = repl[next_ht[r]]
            else:
                nxt[bw] = (2 * (base + i - 1) + main_reversed[i - 1]) ^ 1
            face[fw] = fo
            face[bw] = ft
    for r in range(n):
        alive[idx[r]] = False
    for r in range(n):
        nxt[2 * idx[r]] = -1
        nxt[2 * idx[r] + 1] = -1
    for j in range(2 * n):
        h = before[j]
        if alive[h >> 1]:
            prv[nxt[h]] = h
    for r in range(n):
        for i in range(k):
            fw = 2 * (ne0 + r * k + i) + main_reversed[i]
            prv[nxt[fw]] = fw
    for r in range(n):
        for i in range(k):
            bw = (2 * (ne0 + r * k + i) + main_reversed[i]) ^ 1
            prv[nxt[bw]] = bw
    return upn, both, repl, first, last, bvert, heading, corner


@_jit
def pair_aim(pi, pj, points, heading, normal, max_dist, cos_cone, cone):
    """``_Grower._pair_aim``: whether each branch pair (pi, pj) may join, and its (ci, cj, dist)."""
    count = len(pi)
    ok = np.empty(count, dtype=np.bool_)
    ci = np.empty(count)
    cj = np.empty(count)
    dist = np.empty(count)
    for r in range(count):
        a, b = pi[r], pj[r]
        d0, d1, d2 = points[b, 0] - points[a, 0], points[b, 1] - points[a, 1], points[b, 2] - points[a, 2]
        dd = math.sqrt(_dot(d0, d1, d2, d0, d1, d2))
        n0, n1, n2 = normal[a, 0] + normal[b, 0], normal[a, 1] + normal[b, 1], normal[a, 2] + normal[b, 2]
        size = math.sqrt(_dot(n0, n1, n2, n0, n1, n2))
        scale = _np_max(size, 1e-300)
        n0, n1, n2 = n0 / scale, n1 / scale, n2 / scale
        if not size > 1e-6:
            n0, n1, n2 = 0.0, 0.0, 0.0
        # d and both headings projected on the plane and normalised
        c = _dot(d0, d1, d2, n0, n1, n2)
        u0, u1, u2 = d0 - c * n0, d1 - c * n1, d2 - c * n2
        x0, x1, x2 = heading[a, 0], heading[a, 1], heading[a, 2]
        c = _dot(x0, x1, x2, n0, n1, n2)
        x0, x1, x2 = x0 - c * n0, x1 - c * n1, x2 - c * n2
        y0, y1, y2 = heading[b, 0], heading[b, 1], heading[b, 2]
        c = _dot(y0, y1, y2, n0, n1, n2)
        y0, y1, y2 = y0 - c * n0, y1 - c * n1, y2 - c * n2
        s = _np_max(math.sqrt(_dot(u0, u1, u2, u0, u1, u2)), 1e-300)
        u0, u1, u2 = u0 / s, u1 / s, u2 / s
        s = _np_max(math.sqrt(_dot(x0, x1, x2, x0, x1, x2)), 1e-300)
        x0, x1, x2 = x0 / s, x1 / s, x2 / s
        s = _np_max(math.sqrt(_dot(y0, y1, y2, y0, y1, y2)), 1e-300)
        y0, y1, y2 = y0 / s, y1 / s, y2 / s
        toward_i = _dot(x0, x1, x2, u0, u1, u2)
        toward_j = -_dot(y0, y1, y2, u0, u1, u2)
        opposite = -_dot(x0, x1, x2, y0, y1, y2)
        good = dd > 1e-12 and dd <= max_dist
        if cone:
            good = good and toward_i >= cos_cone and toward_j >= cos_cone
        else:
            good = good and opposite >= cos_cone and toward_i > 1e-9 and toward_j > 1e-9
        ok[r] = good
        ci[r] = toward_i
        cj[r] = toward_j
        dist[r] = dd
    return ok, ci, cj, dist


@_jit
def new_faces(nxt, face, x, y, new_face):
    """``_Grower._new_faces_one_by_one``: of the two cycles through each new edge's halves x and y, the
    shorter (x's on a tie) becomes ``new_face``."""
    for r in range(len(x)):
        xr, yr = x[r], y[r]
        px, py = nxt[xr], nxt[yr]
        while px != xr and py != yr:
            px, py = nxt[px], nxt[py]
        h0 = xr if px == xr else yr
        face[h0] = new_face[r]
        h = nxt[h0]
        while h != h0:
            face[h] = new_face[r]
            h = nxt[h]


@_jit
def cycles(nxt, starts, offsets, count):
    """``_Map.cycles``' walk: the half-edges of each face cycle from its start, face after face."""
    order = np.empty(count, dtype=np.int64)
    for f in range(len(starts)):
        h = starts[f]
        for i in range(offsets[f], offsets[f + 1]):
            order[i] = h
            h = nxt[h]
    return order


@_jit
def centre_on_left(a, b, vert, pos, normal, centre):
    """``_Grower._centre_on_left``: join pairs (a, b) reordered so that the new edge has the map's
    centre on its left about the branches' surface normal."""
    first = a.copy()
    second = b.copy()
    c0, c1, c2 = centre[0], centre[1], centre[2]
    for r in range(len(a)):
        u, w = vert[a[r]], vert[b[r]]
        a0, a1, a2 = pos[w, 0] - pos[u, 0], pos[w, 1] - pos[u, 1], pos[w, 2] - pos[u, 2]
        t0, t1, t2 = c0 - pos[u, 0], c1 - pos[u, 1], c2 - pos[u, 2]
        na, nb = normal[a[r]], normal[b[r]]
        n0, n1, n2 = na[0] + nb[0], na[1] + nb[1], na[2] + nb[2]
        x0, x1, x2 = a1 * t2 - a2 * t1, a2 * t0 - a0 * t2, a0 * t1 - a1 * t0
        side = _dot(x0, x1, x2, n0, n1, n2)
        scale = math.sqrt(_dot(a0, a1, a2, a0, a1, a2) * _dot(t0, t1, t2, t0, t1, t2)
                          * _dot(n0, n1, n2, n0, n1, n2))
        if side < -1e-9 * scale:
            first[r], second[r] = b[r], a[r]
    return first, second


@_jit
def split(ev, label, age, alive, up, nxt, prv, face, a, b, vert, corner, blabel, bage, rev, normal, ne0, nf):
    """``_Grower._split`` up to the pending branches' corners: a new edge for each join pair (a, b),
    from ``ne0``, linked into its face, and the faces ``nf``, ``nf + 1``, ... it makes
    (``new_faces``; each pair lies in another face). Returns the new edges' half-edges from a's vertex
    to b's (x) and back (y)."""
    j = len(a)
    x = np.empty(j, dtype=np.int64)
    y = np.empty(j, dtype=np.int64)
    new_face = np.empty(j, dtype=np.int64)
    for r in range(j):
        e = ne0 + r
        u, w = vert[a[r]], vert[b[r]]
        flip = rev[a[r]]
        if flip:
            ev[e, 0], ev[e, 1] = w, u
        else:
            ev[e, 0], ev[e, 1] = u, w
        label[e] = blabel[a[r]]
        age[e] = bage[a[r]]
        up[e, 0], up[e, 1], up[e, 2] = normal[a[r], 0], normal[a[r], 1], normal[a[r], 2]
        alive[e] = True
        xr = 2 * e + flip
        yr = xr ^ 1
        ha, hb = corner[a[r]], corner[b[r]]
        pa, pb = prv[ha], prv[hb]
        f = face[ha]
        nxt[pa] = xr
        prv[xr] = pa
        nxt[xr] = hb
        prv[hb] = xr
        nxt[pb] = yr
        prv[yr] = pb
        nxt[yr] = ha
        prv[ha] = yr
        face[xr] = f
        face[yr] = f
        x[r], y[r] = xr, yr
        new_face[r] = nf + r
    new_faces(nxt, face, x, y, new_face)
    return x, y


@_jit
def compact(ev, label, age, alive, up, nxt, prv, face, ne):
    """``_Map.compact``: the living edges renumbered 0, 1, ... in order, their half-edges' links
    mapped, dead slots cleared; returns how many live."""
    hmap = np.full(2 * ne, -1, dtype=np.int64)
    m = 0
    for e in range(ne):
        if alive[e]:
            hmap[2 * e] = 2 * m
            hmap[2 * e + 1] = 2 * m + 1
            m += 1
    j = 0
    for e in range(ne):
        if alive[e]:
            ev[j, 0], ev[j, 1] = ev[e, 0], ev[e, 1]
            label[j] = label[e]
            age[j] = age[e]
            up[j, 0], up[j, 1], up[j, 2] = up[e, 0], up[e, 1], up[e, 2]
            for s in range(2):
                nxt[2 * j + s] = hmap[nxt[2 * e + s]]
                face[2 * j + s] = face[2 * e + s]
            j += 1
    for e in range(m):
        alive[e] = True
    for e in range(m, ne):
        alive[e] = False
    for h in range(2 * m, 2 * ne):
        nxt[h] = -1
    for h in range(2 * m):
        prv[nxt[h]] = h
    return m


@_jit
def ties(at, fa, lead, score, gap, tie):
    """``_Grower._settle_ties``' first pass: which live pairs are as good as their face's best (within
    ``tie``), and the faces (ascending) with more than one such pair."""
    count = len(at)
    close = np.empty(count, dtype=np.bool_)
    top = 0
    for i in range(count):
        if fa[i] + 1 > top:
            top = fa[i] + 1
    counts = np.zeros(top, dtype=np.int64)
    for i in range(count):
        near = abs(score[at[i]] - score[lead[i]]) <= tie and abs(gap[at[i]] - gap[lead[i]]) <= tie
        close[i] = near
        if near:
            counts[fa[i]] += 1
    many = 0
    for f in range(top):
        if counts[f] > 1:
            many += 1
    faces = np.empty(many, dtype=np.int64)
    many = 0
    for f in range(top):
        if counts[f] > 1:
            faces[many] = f
            many += 1
    return close, faces


@_jit
def cycle_places(nxt, origin, ha, hb):
    """``_Grower._cycle_places``: the length of the cycle through ``origin`` and the place of each
    half-edge of ``ha`` and ``hb`` along it, counted forward from ``origin``."""
    place = np.full(len(nxt), -1, dtype=np.int64)
    h = origin
    size = 0
    while True:
        place[h] = size
        size += 1
        h = nxt[h]
        if h == origin:
            break
    at_ha = np.empty(len(ha), dtype=np.int64)
    at_hb = np.empty(len(hb), dtype=np.int64)
    for i in range(len(ha)):
        at_ha[i] = place[ha[i]]
    for i in range(len(hb)):
        at_hb[i] = place[hb[i]]
    return size, at_ha, at_hb


@_jit
def sweep_terms(pos, ev, vert, corner, heading, normal, branch, a, b, r, c, at_a):
    """``_Grower._conflicts``' arguments of ``_in_sweep`` for the branches ``branch[c]`` at the
    corners of joins (``a[r]``, ``b[r]``), and the ``arctan2`` arguments of its two ``rel`` calls:
    (y, x) of the sweep from the branch's edge to the join's other end, and of the sweep from that
    edge to the branch's heading, each y = (p x q) . n and x = p . q as ``np.einsum`` adds them."""
    k = len(r)
    out = np.empty((4, k))
    for i in range(k):
        own = branch[c[i]]
        here = vert[own]
        h = corner[own]
        dest = ev[h >> 1, 1 - (h & 1)]
        far = vert[b[r[i]]] if at_a[i] else vert[a[r[i]]]
        x, y, z = pos[here, 0], pos[here, 1], pos[here, 2]
        p0, p1, p2 = pos[dest, 0] - x, pos[dest, 1] - y, pos[dest, 2] - z
        n0, n1, n2 = normal[own, 0], normal[own, 1], normal[own, 2]
        for j in range(2):
            if j == 0:
                q0, q1, q2 = pos[far, 0] - x, pos[far, 1] - y, pos[far, 2] - z
            else:
                q0, q1, q2 = heading[own, 0], heading[own, 1], heading[own, 2]
            c0 = p1 * q2 - p2 * q1
            c1 = p2 * q0 - p0 * q2
            c2 = p0 * q1 - p1 * q0
            out[2 * j, i] = _dot(c0, c1, c2, n0, n1, n2)
            out[2 * j + 1, i] = _dot(p0, p1, p2, q0, q1, q2)
    return out


@_jit
def tie_side(pos, ev, vert, corner, heading, normal, branch, a, b, place, at_ha, at_hb, size):
    """``_Grower._conflicts`` for one end (``branch``, ``a`` or ``b``) of the tied joins (``a[i]``,
    ``b[i]``): on which side of row i's join column j's branch falls, by its place along the face's
    cycle; and, for the branches at a row's own corners (row-major, as ``np.nonzero``), their rows,
    columns, whether at the row's ``a`` corner, and ``sweep_terms`` to decide them with."""
    t = len(a)
    side = np.empty((t, t), dtype=np.bool_)
    count = 0
    for i in range(t):
        span = (at_hb[i] - at_ha[i]) % size
        ha, hb = corner[a[i]], corner[b[i]]
        for j in range(t):
            side[i, j] = (place[j] - at_ha[i]) % size >= span
            hc = corner[branch[j]]
            if (hc == ha) | (hc == hb):
                count += 1
    r = np.empty(count, dtype=np.int64)
    c = np.empty(count, dtype=np.int64)
    at_a = np.empty(count, dtype=np.bool_)
    k = 0
    for i in range(t):
        ha, hb = corner[a[i]], corner[b[i]]
        for j in range(t):
            hc = corner[branch[j]]
            if (hc == ha) | (hc == hb):
                r[k], c[k], at_a[k] = i, j, hc == ha
                k += 1
    return side, r, c, at_a, sweep_terms(pos, ev, vert, corner, heading, normal, branch, a, b, r, c, at_a)


@_jit
def clashes(a, b, vert, first_side, side):
    """``_Grower._conflicts``' answer: whether each tied join shares a branch or a vertex pair with
    another, or crosses it (a branch of one on different sides of the other from its partner)."""
    t = len(a)
    out = np.zeros(t, dtype=np.bool_)
    for i in range(t):
        vai, vbi = min(vert[a[i]], vert[b[i]]), max(vert[a[i]], vert[b[i]])
        for j in range(t):
            if j == i:
                continue
            vaj, vbj = min(vert[a[j]], vert[b[j]]), max(vert[a[j]], vert[b[j]])
            if (a[i] == a[j] or a[i] == b[j] or b[i] == a[j] or b[i] == b[j] or (vai == vaj and vbi == vbj)
                    or first_side[i, j] != side[i, j] or first_side[j, i] != side[j, i]):
                out[i] = True
                break
    return out
