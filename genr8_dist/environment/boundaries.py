"""Boundaries (thesis 2.7.3): planes, boxes, spheres and any triangle mesh trimesh reads.

Every boundary splits space into an *inside* (the solid: behind a plane's normal, within a box or a
sphere, enclosed by a mesh) and an *outside*. One of the two is the **allowed side**: the one given by
``inside = true/false``, or, when ``inside`` is left out, the side the seed starts on (the seed's
centre, i.e. the start position or the centre of a user seed polygon; exactly on the surface counts
as outside). A vertex on the other side *violates* the boundary.

What happens when a derivation step would move a vertex from ``p`` to a violating ``q`` depends on
the boundary's **behaviour**:

- ``slide`` (Genr8's default): the vertex goes to the point of the boundary closest to ``q``, just on
  the allowed side, so the part of the move along the wall is kept and the part into it is lost
  (the surface slides along the wall, as it drapes a sphere under gravity).
- ``cut-off``: the vertex stops dead where the segment ``p -> q`` meets the boundary and never moves
  again for the rest of the growth.
- ``reflect``: the vertex is mirrored back through the wall: ``q' = 2 c - q`` with ``c`` the boundary
  point closest to ``q`` (the penetration depth becomes a distance back into the allowed side); if
  the mirror image still violates (corners, strong curvature) it slides instead.
- ``soft``: the vertex passes through; ``Environment.count_soft_violations`` counts the vertices on
  the wrong side, and the fitness's soft-boundary criterion penalises them.

Each behaviour is one ``Behaviour`` entry of ``BEHAVIOURS`` (its constraint, hard or soft, whether it
stops the vertex), as each boundary kind is one class; the physics looks the behaviour up and an
unknown name is refused when a boundary is built.
"""

from __future__ import annotations

import abc
import copy
import dataclasses
import math
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from genr8_dist.environment._meshgeom import TriangleMesh
from genr8_dist.errors import ConfigError, GrowthError
from genr8_dist.fields import (
    fail,
    read_choice,
    read_float,
    read_optional_bool,
    read_vec3,
    reject_unknown,
)

__all__ = [
    "BEHAVIOURS",
    "Behaviour",
    "Boundary",
    "BoxBoundary",
    "MeshBoundary",
    "PlaneBoundary",
    "SphereBoundary",
    "boundary_from_dict",
]

Resolve = Callable[["Boundary", np.ndarray, np.ndarray, float], np.ndarray]


@dataclass(frozen=True)
class Behaviour:
    """What a boundary does to a vertex whose move ``p -> q`` ends on its wrong side: ``hard`` ones
    constrain the move (``resolve(boundary, p, q, extent)`` gives where it ends instead, ``stops``:
    the vertex never moves again); a soft one lets it pass and the fitness counts it."""

    name: str
    hard: bool
    resolve: Resolve
    stops: bool = False


def _slide(b: Boundary, p: np.ndarray, q: np.ndarray, extent: float) -> np.ndarray:
    return b.project(q, extent)


def _cut_off(b: Boundary, p: np.ndarray, q: np.ndarray, extent: float) -> np.ndarray:
    start_ok = b.violation(p) <= 0.0
    return np.where(start_ok[:, None], b.first_contact(p, q), b.project(q, extent))


def _pass(b: Boundary, p: np.ndarray, q: np.ndarray, extent: float) -> np.ndarray:
    return q


def _reflect(b: Boundary, p: np.ndarray, q: np.ndarray, extent: float) -> np.ndarray:
    mirrored = 2.0 * b.closest_points(q) - q
    still = b.violation(mirrored) > 0.0
    if np.any(still):
        mirrored[still] = b.project(mirrored[still], extent)
    result: np.ndarray = mirrored
    return result


#: Every boundary behaviour by name (the ``behaviour`` key of a boundary's table); an unknown name is
#: refused when the environment is read.
BEHAVIOURS: dict[str, Behaviour] = {
    b.name: b for b in (
        Behaviour("slide", hard=True, resolve=_slide),
        Behaviour("cut-off", hard=True, resolve=_cut_off, stops=True),
        Behaviour("reflect", hard=True, resolve=_reflect),
        Behaviour("soft", hard=False, resolve=_pass),
    )
}


@dataclass(frozen=True, kw_only=True)
class Boundary(abc.ABC):
    """Common part of every boundary: its behaviour and which side is allowed.

    Subclasses give ``outside_distance`` (signed: > 0 outside the solid, < 0 inside) and
    ``closest_points`` (the nearest point of the boundary's surface).
    """

    kind: ClassVar[str] = ""
    #: a kind without an extent of its own (a plane): its outline is as wide as the scene drawn
    unbounded: ClassVar[bool] = False
    #: a picture draws this kind's outline lighter (a mesh: many edges)
    faint: ClassVar[bool] = False
    behaviour: str = "slide"
    inside: bool | None = None
    #: the allowed side once resolved against the seed's centre (set by the Environment)
    allowed_inside: bool | None = field(default=None, compare=False, repr=False)

    def __post_init__(self) -> None:
        read_choice(self.behaviour, self._where(), "behaviour", tuple(BEHAVIOURS))
        read_optional_bool(self.inside, self._where(), "inside")
        if self.allowed_inside is None and self.inside is not None:
            object.__setattr__(self, "allowed_inside", self.inside)

    def _where(self) -> str:
        return f"{self.kind} boundary"

    @property
    def rule(self) -> Behaviour:
        """This boundary's behaviour (its constraint, hard or soft)."""
        return BEHAVIOURS[self.behaviour]

    @property
    def hard(self) -> bool:
        """Whether the boundary constrains moves (every behaviour but ``soft``)."""
        return self.rule.hard

    # -- geometry, per subclass ------------------------------------------------------------------------
    @abc.abstractmethod
    def outside_distance(self, points: np.ndarray) -> np.ndarray:
        """Signed distance of each point to the boundary's surface: > 0 outside the solid, < 0 inside."""

    @abc.abstractmethod
    def closest_points(self, points: np.ndarray) -> np.ndarray:
        """The point of the boundary's surface nearest each point."""

    @abc.abstractmethod
    def outline(self, centre: np.ndarray, size: float) -> np.ndarray:
        """(S, 2, 3) line segments drawing the boundary as a wireframe in a picture of the scene
        around ``centre``, ``size`` wide each way (an unbounded kind's outline spans that; a bounded
        one ignores both)."""

    def reach(self) -> np.ndarray:
        """(P, 3) points a picture must hold to show the boundary whole (none: it need not grow the
        picture, an unbounded or a mesh boundary)."""
        return np.zeros((0, 3))

    def sketch(self) -> dict[str, Any]:
        """What the studio draws (JSON): the ``kind``, the outline's ``segments`` and ``reach``; an
        unbounded kind's outline is drawn one unit wide around ``anchor`` (its point nearest the
        origin), which the studio scales to each design's size."""
        anchor = self.closest_points(np.zeros((1, 3)))[0] if self.unbounded else np.zeros(3)
        out: dict[str, Any] = {"kind": self.kind,
                               "segments": np.round(self.outline(anchor, 0.5), 4).tolist(),
                               "reach": [[float(v) for v in p] for p in self.reach()]}
        if self.unbounded:
            out["anchor"] = [float(v) for v in anchor]
        return out

    # -- shared ----------------------------------------------------------------------------------------
    def resolved(self, seed_centre: tuple[float, float, float]) -> Boundary:
        """A copy whose allowed side is fixed: ``inside`` if given, else the side ``seed_centre`` is on."""
        if self.inside is not None:
            allowed = self.inside
        else:
            allowed = bool(self.outside_distance(np.asarray([seed_centre], dtype=np.float64))[0] < 0.0)
        resolved = copy.copy(self)  # shallow: a mesh's loaded triangles are shared, not re-read
        object.__setattr__(resolved, "allowed_inside", allowed)
        return resolved

    @property
    def _allowed(self) -> bool:
        if self.allowed_inside is None:
            raise ConfigError(f"{self._where()}: allowed side unknown (set 'inside' or use an Environment)")
        return self.allowed_inside

    def violation(self, points: np.ndarray) -> np.ndarray:
        """How far each point is on the wrong side (> 0 violates; <= 0 is allowed)."""
        d = self.outside_distance(points)
        return d if self._allowed else -d

    def project(self, points: np.ndarray, scale: float = 1.0) -> np.ndarray:
        """Move violating points onto the boundary, a hair (1e-9 x ``scale``) on the allowed side."""
        points = np.asarray(points, dtype=np.float64)
        closest = self.closest_points(points)
        away = closest - points
        norm = np.linalg.norm(away, axis=1, keepdims=True)
        with np.errstate(invalid="ignore", divide="ignore"):
            unit = np.where(norm > 0, away / np.where(norm > 0, norm, 1.0), 0.0)
        return closest + unit * (1e-9 * max(scale, 1.0))

    def first_contact(self, start: np.ndarray, end: np.ndarray, iterations: int = 40) -> np.ndarray:
        """Where each segment start -> end (start allowed, end violating) first reaches the boundary.

        Bisection on the violation along the segment; the returned point is on the allowed side.
        """
        lo = np.zeros(len(start))
        hi = np.ones(len(start))
        delta = end - start
        for _ in range(iterations):
            mid = 0.5 * (lo + hi)
            bad = self.violation(start + mid[:, None] * delta) > 0.0
            hi = np.where(bad, mid, hi)
            lo = np.where(bad, lo, mid)
        result: np.ndarray = start + lo[:, None] * delta
        return result

    def to_dict(self) -> dict[str, Any]:
        """The TOML table of this boundary (``kind`` first; ``inside`` only when given)."""
        out: dict[str, Any] = {"kind": self.kind}
        for f in dataclasses.fields(self):
            if f.name in ("allowed_inside",) or f.name.startswith("_"):
                continue
            value = getattr(self, f.name)
            if value is None:
                continue
            out[f.name] = [list(v) if isinstance(v, tuple) else v for v in value] \
                if isinstance(value, tuple) else value
        return out


@dataclass(frozen=True, kw_only=True)
class PlaneBoundary(Boundary):
    """An infinite plane through ``point`` with unit ``normal``; its inside is behind the normal."""

    kind: ClassVar[str] = "plane"
    unbounded: ClassVar[bool] = True
    point: tuple[float, float, float] = (0.0, 0.0, 0.0)
    normal: tuple[float, float, float] = (0.0, 0.0, 1.0)

    def __post_init__(self) -> None:
        super().__post_init__()
        where = self._where()
        object.__setattr__(self, "point", read_vec3(self.point, where, "point"))
        normal = np.asarray(read_vec3(self.normal, where, "normal"))
        length = float(np.linalg.norm(normal))
        if length == 0.0:
            raise fail(where, "normal", "must not be the zero vector")
        object.__setattr__(self, "normal", tuple(float(v) for v in normal / length))

    def outside_distance(self, points: np.ndarray) -> np.ndarray:
        offsets = np.asarray(points, dtype=np.float64) - np.asarray(self.point)
        result: np.ndarray = offsets @ np.asarray(self.normal)
        return result

    def closest_points(self, points: np.ndarray) -> np.ndarray:
        points = np.asarray(points, dtype=np.float64)
        result: np.ndarray = points - self.outside_distance(points)[:, None] * np.asarray(self.normal)
        return result

    def outline(self, centre: np.ndarray, size: float) -> np.ndarray:
        """A 7 x 7 grid of lines in the plane, ``size`` each way around ``centre``'s foot on it."""
        n = np.asarray(self.normal)
        helper = np.array([1.0, 0.0, 0.0]) if abs(n[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
        e1 = np.cross(n, helper)
        e1 /= np.linalg.norm(e1)
        e2 = np.cross(n, e1)
        centre = np.asarray(centre, dtype=np.float64)
        foot = centre - n * float(np.dot(centre - np.asarray(self.point), n))
        lines = []
        for t in np.linspace(-size, size, 7):
            lines.append([foot + e1 * t - e2 * size, foot + e1 * t + e2 * size])
            lines.append([foot + e2 * t - e1 * size, foot + e2 * t + e1 * size])
        return np.asarray(lines, dtype=np.float64)


@dataclass(frozen=True, kw_only=True)
class BoxBoundary(Boundary):
    """An axis-aligned box from corner ``min`` to corner ``max``."""

    kind: ClassVar[str] = "box"
    min: tuple[float, float, float] = (-1.0, -1.0, -1.0)
    max: tuple[float, float, float] = (1.0, 1.0, 1.0)

    def __post_init__(self) -> None:
        super().__post_init__()
        where = self._where()
        lo = read_vec3(self.min, where, "min")
        hi = read_vec3(self.max, where, "max")
        if any(h <= low for low, h in zip(lo, hi, strict=True)):
            raise fail(where, "max", f"must exceed 'min' on every axis, got min {list(lo)} max {list(hi)}")
        object.__setattr__(self, "min", lo)
        object.__setattr__(self, "max", hi)

    def outside_distance(self, points: np.ndarray) -> np.ndarray:
        points = np.asarray(points, dtype=np.float64)
        lo = np.asarray(self.min)
        hi = np.asarray(self.max)
        centre = 0.5 * (lo + hi)
        half = 0.5 * (hi - lo)
        q = np.abs(points - centre) - half
        outside = np.linalg.norm(np.maximum(q, 0.0), axis=1)
        inside = np.minimum(np.max(q, axis=1), 0.0)
        result: np.ndarray = outside + inside
        return result

    def closest_points(self, points: np.ndarray) -> np.ndarray:
        points = np.asarray(points, dtype=np.float64)
        lo = np.asarray(self.min)
        hi = np.asarray(self.max)
        out = np.clip(points, lo, hi)
        inner = np.all((points > lo) & (points < hi), axis=1)
        if np.any(inner):
            p = points[inner]
            gaps = np.concatenate([p - lo, hi - p], axis=1)  # distances to the six faces
            face = np.argmin(gaps, axis=1)
            axis = face % 3
            value = np.where(face < 3, lo[axis], hi[axis])
            snapped = p.copy()
            snapped[np.arange(len(p)), axis] = value
            out[inner] = snapped
        result: np.ndarray = out
        return result

    def outline(self, centre: np.ndarray, size: float) -> np.ndarray:
        """The box's 12 edges."""
        (x0, y0, z0), (x1, y1, z1) = self.min, self.max
        corners = np.array([[x, y, z] for x in (x0, x1) for y in (y0, y1) for z in (z0, z1)])
        return np.asarray([corners[[i, j]] for i in range(8) for j in range(i + 1, 8)
                           if np.sum(corners[i] != corners[j]) == 1], dtype=np.float64)

    def reach(self) -> np.ndarray:
        return np.asarray([self.min, self.max], dtype=np.float64)


@dataclass(frozen=True, kw_only=True)
class SphereBoundary(Boundary):
    """A sphere of ``radius`` around ``centre``."""

    kind: ClassVar[str] = "sphere"
    centre: tuple[float, float, float] = (0.0, 0.0, 0.0)
    radius: float = 1.0

    def __post_init__(self) -> None:
        super().__post_init__()
        where = self._where()
        object.__setattr__(self, "centre", read_vec3(self.centre, where, "centre"))
        object.__setattr__(self, "radius", read_float(self.radius, where, "radius", minimum=0.0,
                                                      strict_minimum=True))

    def outside_distance(self, points: np.ndarray) -> np.ndarray:
        points = np.asarray(points, dtype=np.float64)
        result: np.ndarray = np.linalg.norm(points - np.asarray(self.centre), axis=1) - self.radius
        return result

    def closest_points(self, points: np.ndarray) -> np.ndarray:
        points = np.asarray(points, dtype=np.float64)
        centre = np.asarray(self.centre)
        r = points - centre
        norm = np.linalg.norm(r, axis=1, keepdims=True)
        up = np.array([0.0, 0.0, 1.0])
        unit = np.where(norm > 0, r / np.where(norm > 0, norm, 1.0), up)
        return centre + self.radius * unit

    def outline(self, centre: np.ndarray, size: float) -> np.ndarray:
        """24 meridians and 12 parallels' segments."""
        u, v = np.mgrid[0:2 * np.pi:24j, 0:np.pi:12j]
        c, r = np.asarray(self.centre), self.radius
        grid = np.stack([c[0] + r * np.cos(u) * np.sin(v), c[1] + r * np.sin(u) * np.sin(v),
                         c[2] + r * np.cos(v)], axis=-1)
        along_v = np.stack([grid[:, :-1], grid[:, 1:]], axis=2).reshape(-1, 2, 3)
        along_u = np.stack([grid[:-1, :], grid[1:, :]], axis=2).reshape(-1, 2, 3)
        return np.concatenate([along_v, along_u])

    def reach(self) -> np.ndarray:
        c = np.asarray(self.centre, dtype=np.float64)
        return np.asarray([c - self.radius, c + self.radius])


@dataclass(frozen=True, kw_only=True)
class MeshBoundary(Boundary):
    """A triangle mesh read by trimesh from ``path`` (OBJ, STL, PLY, GLB, OFF...), scaled then translated.

    A watertight mesh has an inside (its faces are re-oriented outwards if they wind the other way);
    an open mesh (a terrain, a wall) has the side its face normals point to as the outside. Queries
    are exact (closest point, angle-weighted pseudo-normals) and use a k-d tree, so meshes of many
    thousands of triangles are fine.
    """

    kind: ClassVar[str] = "mesh"
    faint: ClassVar[bool] = True
    path: str = ""
    scale: float = 1.0
    translate: tuple[float, float, float] = (0.0, 0.0, 0.0)
    # The mesh as read (before scale and translate), filled in from ``path`` when the boundary is
    # built; a run stores them, so it no longer needs the file (given, ``path`` is not read).
    vertices: tuple[tuple[float, float, float], ...] | None = field(default=None, repr=False)
    faces: tuple[tuple[int, int, int], ...] | None = field(default=None, repr=False)
    _mesh: TriangleMesh | None = field(default=None, init=False, compare=False, repr=False)
    _watertight: bool = field(default=False, init=False, compare=False, repr=False)

    def __post_init__(self) -> None:
        super().__post_init__()
        where = self._where()
        inline = self.vertices is not None or self.faces is not None
        if not isinstance(self.path, (str, Path)) or not (str(self.path) or inline):
            raise fail(where, "path", f"must be the file name of a mesh, got {self.path!r}")
        object.__setattr__(self, "path", str(self.path))
        object.__setattr__(self, "scale", read_float(self.scale, where, "scale", minimum=0.0,
                                                     strict_minimum=True))
        object.__setattr__(self, "translate", read_vec3(self.translate, where, "translate"))
        if inline:
            try:
                vertices = np.asarray(self.vertices, dtype=np.float64)
                faces = np.asarray(self.faces, dtype=np.int64)
            except (TypeError, ValueError):
                raise fail(where, "vertices", "vertices must be [[x, y, z], ...] and faces "
                                              "[[i, j, k], ...]") from None
            if vertices.ndim != 2 or vertices.shape[1:] != (3,) or faces.ndim != 2 \
                    or faces.shape[1:] != (3,) or not len(faces) or faces.min() < 0 \
                    or faces.max() >= len(vertices) or not np.isfinite(vertices).all():
                raise fail(where, "faces", f"must index the {len(vertices)} vertices in triples "
                                           "[[i, j, k], ...]")
        self._load()

    def _load(self) -> None:
        import trimesh

        if self.vertices is not None and self.faces is not None:
            mesh = trimesh.Trimesh(np.asarray(self.vertices, dtype=np.float64),
                                   np.asarray(self.faces, dtype=np.int64), process=False)
        else:
            mesh = self._read_file(trimesh)
        faces = getattr(mesh, "faces", None)
        if faces is None or len(faces) == 0:
            raise GrowthError(f"{self.path}: boundary mesh has no triangles")
        mesh.update_faces(mesh.nondegenerate_faces())
        mesh.remove_unreferenced_vertices()
        if len(mesh.faces) == 0:
            raise GrowthError(f"{self.path}: boundary mesh has only degenerate triangles")
        watertight = bool(mesh.is_watertight)
        faces = np.asarray(mesh.faces, dtype=np.int64)
        object.__setattr__(self, "vertices", tuple(map(tuple, np.asarray(mesh.vertices, dtype=np.float64)
                                                       .tolist())))
        object.__setattr__(self, "faces", tuple(map(tuple, faces.tolist())))
        if watertight and float(mesh.volume) < 0.0:
            faces = faces[:, ::-1]  # normals pointed inwards
        vertices = np.asarray(mesh.vertices, dtype=np.float64) * self.scale + np.asarray(self.translate)
        object.__setattr__(self, "_mesh", TriangleMesh(vertices, faces))
        object.__setattr__(self, "_watertight", watertight)

    def _read_file(self, trimesh: Any) -> Any:
        path = Path(self.path)
        if not path.is_file():
            raise GrowthError(f"{self.path}: boundary mesh file not found")
        try:
            return trimesh.load(str(path), force="mesh")
        except Exception as exc:  # trimesh raises many kinds for unreadable files
            raise GrowthError(f"{self.path}: cannot read boundary mesh: {exc}") from None

    @property
    def mesh(self) -> TriangleMesh:
        """The prepared triangle mesh, in scene coordinates."""
        if self._mesh is None:  # pragma: no cover - __post_init__ always loads it
            self._load()
        assert self._mesh is not None
        return self._mesh

    @property
    def triangles(self) -> np.ndarray:
        """The mesh's triangles (T, 3, 3) in scene coordinates."""
        return self.mesh.triangles

    @property
    def watertight(self) -> bool:
        """True when the mesh is closed (it then has an inside)."""
        return self._watertight

    def outside_distance(self, points: np.ndarray) -> np.ndarray:
        _, distance, inside = self.mesh.query(points)
        return np.where(inside, -distance, distance)

    def closest_points(self, points: np.ndarray) -> np.ndarray:
        return self.mesh.query(points)[0]

    def outline(self, centre: np.ndarray, size: float) -> np.ndarray:
        """The edges of the mesh's triangles (of every k-th one past 4,000 triangles)."""
        tri = self.triangles
        tri = tri[:: max(1, math.ceil(len(tri) / 4000))]
        return np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]])


_KINDS: dict[str, type[Boundary]] = {
    cls.kind: cls for cls in (PlaneBoundary, BoxBoundary, SphereBoundary, MeshBoundary)
}


def boundary_from_dict(data: Any, source: str, where: str, base_dir: Path | None = None) -> Boundary:
    """Build a boundary from its TOML table; ``where`` names it in messages (e.g. ``boundaries[1]``).

    A relative mesh ``path`` is taken relative to ``base_dir`` (the environment file's folder).
    """
    if not isinstance(data, dict):
        raise fail(source, where, f"must be a table, got {data!r}")
    kind = data.get("kind")
    if kind is None:
        raise fail(source, f"{where}.kind", f"missing (one of {', '.join(repr(k) for k in _KINDS)})")
    read_choice(kind, source, f"{where}.kind", tuple(_KINDS))
    cls = _KINDS[kind]
    known = [f.name for f in dataclasses.fields(cls) if f.init and f.name != "allowed_inside"]
    reject_unknown(data, ["kind", *known], source, where)
    kwargs = {k: v for k, v in data.items() if k != "kind"}
    if cls is MeshBoundary and isinstance(kwargs.get("path"), str) and base_dir is not None:
        path = Path(kwargs["path"]).expanduser()
        kwargs["path"] = str(path if path.is_absolute() else (base_dir / path))
    try:
        return cls(**kwargs)
    except ConfigError as exc:
        # re-word "sphere boundary: field 'radius'" as "source: field 'boundaries[0].radius'"
        message = str(exc)
        prefix = f"{cls.kind} boundary: field '"
        if message.startswith(prefix):
            message = f"{source}: field '{where}." + message[len(prefix):]
        raise ConfigError(message) from None
