"""The 3D turtle (thesis Table 2.1): a successor drawn once into a template in the edge's own frame.

A successor is drawn from the origin with heading +x, left +y and up +z, one unit per segment:
``+``/``-`` turn left/right about up (left is counter-clockwise seen from +z), ``&``/``^`` pitch
down/up about left, ``/``/``\\`` roll left/right about the heading, ``~`` reverses the direction of
the next edge (the turtle's path is unchanged), ``[``/``]`` push and pop the turtle's state. The main
line (segments outside brackets) is then fitted by the smallest rotation and a uniform scale so that
it runs from (0, 0, 0) to (1, 0, 0). Growth places the template on an edge with the frame
(heading along the edge, up along the surface normal) and the edge's length, so every edge that
uses the same successor costs a few array operations, not a turtle walk.

A branch is the first segment inside a bracket, drawn from the main-line vertex where the outermost
open bracket began; anything after that segment inside the same brackets is ignored (the turtle is
then at a branch tip, which is not a vertex).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from genr8_dist.hemls.language import Branch, Segment, Successor, Symbol

__all__ = ["AT_END", "LEFT", "NO_SIDE", "RIGHT", "Template", "draw", "rotation_between"]

LEFT = 1  # the branch points into the region on the left of the main line
RIGHT = -1  # ... on the right
NO_SIDE = 0  # it points along the main line or along the normal: it never joins
AT_END = 2  # it starts at the main line's first or last vertex: growth finds its region

_EPS = 1e-9


@dataclass(frozen=True)
class Template:
    """A successor drawn in the unit frame: the main line from (0,0,0) to (1,0,0) and its branches.

    points (k+1, 3): main-line vertices (first at the origin, last at (1, 0, 0) unless the main line
    returns to its start, when the chord cannot be fitted); main_labels, main_ages, main_timed,
    main_reversed (k,): one per main-line segment; branch_vertex (b,) index into points;
    branch_heading (b, 3) unit vectors; branch_labels, branch_ages, branch_timed, branch_reversed,
    branch_side (LEFT, RIGHT, NO_SIDE or AT_END).
    """

    points: np.ndarray
    main_labels: np.ndarray
    main_ages: np.ndarray
    main_timed: np.ndarray
    main_reversed: np.ndarray
    branch_vertex: np.ndarray
    branch_heading: np.ndarray
    branch_labels: np.ndarray
    branch_ages: np.ndarray
    branch_timed: np.ndarray
    branch_reversed: np.ndarray
    branch_side: np.ndarray

    @property
    def n_segments(self) -> int:
        """Number of main-line segments (edges that replace the predecessor)."""
        return len(self.main_labels)

    @property
    def n_branches(self) -> int:
        """Number of branches the successor draws."""
        return len(self.branch_labels)


def rotation_between(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The smallest rotation taking unit vector ``a`` to unit vector ``b`` (180 degrees about +z,
    or about +y when ``a`` lies on the z axis, for opposite vectors)."""
    a = np.asarray(a, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    (a0, a1, a2), (b0, b1, b2) = a.tolist(), b.tolist()
    v = np.array([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0])  # np.cross(a, b)
    c = float(np.dot(a, b))
    s = float(np.linalg.norm(v))
    if s < 1e-12:
        if c > 0:
            return np.eye(3)
        axis = np.array([0.0, 0.0, 1.0])
        if abs(a[2]) > 0.9:
            axis = np.array([0.0, 1.0, 0.0])
        axis = axis - np.dot(axis, a) * a
        axis /= np.linalg.norm(axis)
        return 2.0 * np.outer(axis, axis) - np.eye(3)
    k = v / s
    kx = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    result: np.ndarray = np.eye(3) + s * kx + (1.0 - c) * (kx @ kx)
    return result


def _rotate(h: np.ndarray, lft: np.ndarray, u: np.ndarray, op: str, ca: float, sa: float
            ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    if op == "+":  # turn left about up
        return h * ca + lft * sa, -h * sa + lft * ca, u
    if op == "-":
        return h * ca - lft * sa, h * sa + lft * ca, u
    if op == "&":  # pitch down about left
        return h * ca - u * sa, lft, h * sa + u * ca
    if op == "^":
        return h * ca + u * sa, lft, -h * sa + u * ca
    if op == "/":  # roll left about heading
        return h, lft * ca + u * sa, -lft * sa + u * ca
    if op == "\\":
        return h, lft * ca - u * sa, lft * sa + u * ca
    raise ValueError(f"unknown turtle operator {op!r}")


def draw(successor: Successor, angle: float, labels: dict[str, int]) -> Template:
    """Draw ``successor`` with turn angle ``angle`` (degrees); ``labels`` maps names to label ids."""
    rad = math.radians(angle)
    ca, sa = math.cos(rad), math.sin(rad)
    pos = np.zeros(3)
    h, lft, u = np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0]), np.array([0.0, 0.0, 1.0])
    points = [pos.copy()]
    main: list[tuple[int, int, bool, bool]] = []
    branches: list[tuple[int, np.ndarray, int, int, bool, bool]] = []

    def age_of(seg: Segment) -> tuple[int, bool]:
        return (0, False) if seg.age is None else (seg.age, True)

    # state: heading frame, pending reverse flag; inside brackets also the branch origin vertex
    def walk(symbols: tuple[Symbol, ...], h: np.ndarray, lft: np.ndarray, u: np.ndarray, reverse: bool,
             in_branch: bool, origin: int) -> bool:
        nonlocal pos
        tip = False
        for sym in symbols:
            if tip:
                continue  # after a branch's segment the turtle is not at a vertex
            if isinstance(sym, str):
                if sym == "~":
                    reverse = not reverse
                else:
                    h, lft, u = _rotate(h, lft, u, sym, ca, sa)
            elif isinstance(sym, Segment):
                age, timed = age_of(sym)
                if in_branch:
                    branches.append((origin, h / np.linalg.norm(h), labels[sym.name], age, timed,
                                     reverse))
                    tip = True
                else:
                    pos = pos + h
                    points.append(pos.copy())
                    main.append((labels[sym.name], age, timed, reverse))
                reverse = False
            elif isinstance(sym, Branch):
                start = origin if in_branch else len(points) - 1
                walk(sym.symbols, h.copy(), lft.copy(), u.copy(), reverse, True, start)
        return reverse

    walk(successor.symbols, h, lft, u, False, False, 0)

    pts = np.array(points, dtype=np.float64)
    chord = pts[-1] - pts[0]
    length = float(np.linalg.norm(chord))
    k = len(main)
    if length > _EPS:
        rot = rotation_between(chord / length, np.array([1.0, 0.0, 0.0]))
        scale = 1.0 / length
    else:  # the main line returns to its start: keep its orientation, unit total size
        rot = np.eye(3)
        scale = 1.0 / max(k, 1)
    pts = (pts @ rot.T) * scale
    if length > _EPS:
        pts[-1] = (1.0, 0.0, 0.0)
    heads = np.array([b[1] for b in branches], dtype=np.float64).reshape(-1, 3) @ rot.T
    bvert = np.array([b[0] for b in branches], dtype=np.int64)
    sides = np.array([_side(pts, int(j), hd) for j, hd in zip(bvert, heads, strict=True)],
                     dtype=np.int8)

    def arr(values: object, dtype: type) -> np.ndarray:
        a: np.ndarray = np.array(values, dtype=dtype)
        a.setflags(write=False)
        return a

    pts.setflags(write=False)
    heads.setflags(write=False)
    return Template(
        points=pts,
        main_labels=arr([m[0] for m in main], np.int64),
        main_ages=arr([m[1] for m in main], np.int64),
        main_timed=arr([m[2] for m in main], bool),
        main_reversed=arr([m[3] for m in main], bool),
        branch_vertex=arr(bvert, np.int64),
        branch_heading=heads,
        branch_labels=arr([b[2] for b in branches], np.int64),
        branch_ages=arr([b[3] for b in branches], np.int64),
        branch_timed=arr([b[4] for b in branches], bool),
        branch_reversed=arr([b[5] for b in branches], bool),
        branch_side=arr(sides, np.int8),
    )


def _angle(v: np.ndarray) -> float:
    return math.atan2(float(v[1]), float(v[0]))


def sector_side(forward: np.ndarray, backward: np.ndarray, heading: np.ndarray) -> int:
    """LEFT when ``heading`` (projected on the xy plane) lies strictly inside the counter-clockwise
    sweep from ``forward`` to ``backward``, RIGHT when strictly inside the rest, else NO_SIDE."""
    if math.hypot(heading[0], heading[1]) < 1e-9:
        return NO_SIDE
    two_pi = 2.0 * math.pi
    a_f = _angle(forward)
    sweep = (_angle(backward) - a_f) % two_pi
    a_h = (_angle(heading) - a_f) % two_pi
    if 1e-9 < a_h < sweep - 1e-9:
        return LEFT
    if sweep + 1e-9 < a_h < two_pi - 1e-9:
        return RIGHT
    return NO_SIDE


def _side(points: np.ndarray, j: int, heading: np.ndarray) -> int:
    if j == 0 or j == len(points) - 1:
        return AT_END
    forward = points[j + 1] - points[j]
    backward = points[j - 1] - points[j]
    return sector_side(forward, backward, heading)
