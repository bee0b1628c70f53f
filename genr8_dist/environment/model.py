"""The Environment: Genr8's growth parameters, forces and boundaries as one frozen, validated value.

Every field has Genr8's default (manual ``genr8`` flags, thesis 2.7.4); docs/environment.md lists
them with their TOML spelling. ``increase_size`` is part 1 of a derivation step (journal 4.3): each
vertex moves away from the surface's centre by the per-axis scale, plus the forces' displacement,
then internal forces and boundaries have their say.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from genr8_dist.environment.boundaries import Boundary, boundary_from_dict
from genr8_dist.environment.forces import PointForce, point_force_displacement, repelling_displacement
from genr8_dist.environment.physics import SizeIncrease, increase_size, repair
from genr8_dist.errors import ConfigError
from genr8_dist.fields import (
    fail,
    read_bool,
    read_choice,
    read_float,
    read_int,
    read_vec3,
    reject_unknown,
)
from genr8_dist.tomlfile import read_toml

__all__ = ["BRANCH_JOINS", "BRANCH_TIES", "Environment", "SizeIncrease", "load_environment"]

#: How two branches' orientations are compared when they join (docs/environment.md, docs/fidelity.md):
#: "orientation" (the thesis: opposite within BranchAngle, facing each other), "cone" (each points at
#: the other's vertex within BranchAngle).
BRANCH_JOINS = ("orientation", "cone")

#: What a region does when its best join ties with others (docs/environment.md), whatever order the
#: branches were drawn in: "crossing" makes every tied join that conflicts with no other (crosses it,
#: or shares a branch) and none of those that do, so mirror-image joins keep a symmetric surface
#: symmetric; "none" makes none of them; "first" (before issue 14) joins the branch drawn first.
BRANCH_TIES = ("crossing", "none", "first")

_AXES = {"x": 0, "y": 1, "z": 2}


def _read_gravity(value: Any, source: str) -> tuple[float, float, float]:
    """Gravity as a number (magnitude pulling towards -z), [x, y, z], or {direction, magnitude}."""
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        g = read_float(value, source, "gravity")
        return (0.0, 0.0, -g)
    if isinstance(value, dict):
        reject_unknown(value, ["direction", "magnitude"], source, "gravity")
        magnitude = read_float(value.get("magnitude", 1.0), source, "gravity.magnitude")
        direction = value.get("direction", "-z")
        if isinstance(direction, str):
            text = direction.strip().lower()
            negative = text.startswith("-")
            axis = text.lstrip("+-")
            if axis not in _AXES:
                raise fail(source, "gravity.direction",
                           f"must be 'x', 'y', 'z' (optionally signed) or [x, y, z], got {direction!r}")
            vec = np.zeros(3)
            vec[_AXES[axis]] = -1.0 if negative else 1.0
        else:
            vec = np.asarray(read_vec3(direction, source, "gravity.direction"))
            norm = float(np.linalg.norm(vec))
            if norm == 0.0:
                raise fail(source, "gravity.direction", "must not be the zero vector")
            vec = vec / norm
        x, y, z = (float(v) for v in vec * magnitude)
        return (x, y, z)
    return read_vec3(value, source, "gravity")


def _read_polygon(value: Any, source: str) -> tuple[tuple[float, float, float], ...]:
    if isinstance(value, (str, bytes, dict)) or not isinstance(value, (list, tuple, np.ndarray)):
        raise fail(source, "seed_polygon", f"must be a list of points [[x, y, z], ...], got {value!r}")
    points = tuple(read_vec3(p, source, f"seed_polygon[{i}]") for i, p in enumerate(value))
    if len(points) < 3:
        raise fail(source, "seed_polygon", f"needs at least 3 points, got {len(points)}")
    return points


@dataclass(frozen=True)
class Environment:
    """Where a surface grows: growth parameters, forces, internal forces, boundaries, noise and caps.

    Build it directly (``Environment(steps=5, scale=1.2)``), from a TOML file (``load_environment``)
    or from a dict (``Environment.from_dict``); every field is checked when the value is built and a
    bad one raises ``ConfigError`` naming it. docs/environment.md describes each field.
    """

    steps: int = 4
    scale: tuple[float, float, float] = (1.5, 1.5, 1.5)
    start_length: float = 1.0
    start_position: tuple[float, float, float] = (0.0, 0.0, 0.0)
    seed: int = 0
    seed_polygon: tuple[tuple[float, float, float], ...] | None = None
    seed_masses: tuple[float, ...] | None = None
    branch_length: float = -1.0
    branch_join: str = "orientation"
    branch_ties: str = "crossing"
    label_noise: float = 0.0
    position_noise: float = 0.0
    vertex_mass: float = 1.0
    max_edges: int = 200_000
    max_work: int = 8_000   # bounds the tail of a run's cost; docs/environment.md says how it was chosen
    max_seconds: float = 60.0
    fixed_perimeter: bool = False
    fixed_centre: bool = False
    uniform_cells: bool = False
    uniform_iterations: int = 20
    repelling_points: float = 0.0
    repelling_radius: float = -1.0
    repelling_theta: float = 0.5
    gravity: tuple[float, float, float] = (0.0, 0.0, 0.0)
    attractors: tuple[PointForce, ...] = ()
    repellers: tuple[PointForce, ...] = ()
    boundaries: tuple[Boundary, ...] = ()
    source: str = field(default="<environment>", compare=False, repr=False)

    # -- validation ------------------------------------------------------------------------------------
    def __post_init__(self) -> None:
        src = self.source
        put = object.__setattr__
        put(self, "steps", read_int(self.steps, src, "steps", minimum=0, maximum=64))
        put(self, "scale", read_vec3(self.scale, src, "scale", allow_scalar=True, minimum=0.0,
                                     strict_minimum=True))
        put(self, "start_length", read_float(self.start_length, src, "start_length", minimum=0.0,
                                             strict_minimum=True))
        put(self, "start_position", read_vec3(self.start_position, src, "start_position"))
        put(self, "seed", read_int(self.seed, src, "seed", minimum=0))
        if self.seed_polygon is not None:
            put(self, "seed_polygon", _read_polygon(self.seed_polygon, src))
        if self.seed_masses is not None:
            masses = self.seed_masses
            if isinstance(masses, (str, bytes, dict)) or not isinstance(masses, (list, tuple, np.ndarray)):
                raise fail(src, "seed_masses", f"must be a list of positive numbers, got {masses!r}")
            masses = tuple(read_float(m, src, f"seed_masses[{i}]", minimum=0.0, strict_minimum=True)
                           for i, m in enumerate(masses))
            if self.seed_polygon is None:
                raise fail(src, "seed_masses", "needs a seed_polygon (one mass per seed vertex)")
            if len(masses) != len(self.seed_polygon):
                raise fail(src, "seed_masses",
                           f"needs one mass per seed_polygon point ({len(self.seed_polygon)}), "
                           f"got {len(masses)}")
            put(self, "seed_masses", masses)
        branch = read_float(self.branch_length, src, "branch_length")
        if branch != -1.0 and branch <= 0.0:
            raise fail(src, "branch_length", f"must be -1 (unlimited) or > 0, got {self.branch_length!r}")
        put(self, "branch_length", branch)
        read_choice(self.branch_join, src, "branch_join", BRANCH_JOINS)
        read_choice(self.branch_ties, src, "branch_ties", BRANCH_TIES)
        put(self, "label_noise", read_float(self.label_noise, src, "label_noise", minimum=0.0, maximum=1.0))
        put(self, "position_noise", read_float(self.position_noise, src, "position_noise", minimum=0.0))
        put(self, "vertex_mass", read_float(self.vertex_mass, src, "vertex_mass", minimum=0.0,
                                            strict_minimum=True))
        put(self, "max_edges", read_int(self.max_edges, src, "max_edges", minimum=3))
        put(self, "max_work", read_int(self.max_work, src, "max_work", minimum=0))
        put(self, "max_seconds", read_float(self.max_seconds, src, "max_seconds", minimum=0.0,
                                            strict_minimum=True))
        for name in ("fixed_perimeter", "fixed_centre", "uniform_cells"):
            put(self, name, read_bool(getattr(self, name), src, name))
        put(self, "uniform_iterations", read_int(self.uniform_iterations, src, "uniform_iterations",
                                                 minimum=1, maximum=1000))
        put(self, "repelling_points", read_float(self.repelling_points, src, "repelling_points", minimum=0.0))
        radius = read_float(self.repelling_radius, src, "repelling_radius")
        if radius != -1.0 and radius <= 0.0:
            raise fail(src, "repelling_radius",
                       f"must be -1 (every vertex, the thesis) or > 0, got {self.repelling_radius!r}")
        put(self, "repelling_radius", radius)
        put(self, "repelling_theta", read_float(self.repelling_theta, src, "repelling_theta", minimum=0.0,
                                                maximum=1.0))
        put(self, "gravity", _read_gravity(self.gravity, src))
        for name in ("attractors", "repellers"):
            items = getattr(self, name)
            if isinstance(items, PointForce):
                items = (items,)
            if not isinstance(items, (list, tuple)):
                raise fail(src, name, f"must be a list of point forces, got {items!r}")
            checked = []
            for i, item in enumerate(items):
                if isinstance(item, dict):
                    item = PointForce.from_dict(item, src, f"{name}[{i}]")
                if not isinstance(item, PointForce):
                    raise fail(src, f"{name}[{i}]", f"must be a PointForce or a table, got {item!r}")
                checked.append(item)
            put(self, name, tuple(checked))
        bounds = self.boundaries
        if isinstance(bounds, Boundary):
            bounds = (bounds,)
        if not isinstance(bounds, (list, tuple)):
            raise fail(src, "boundaries", f"must be a list of boundaries, got {bounds!r}")
        resolved = []
        for i, b in enumerate(bounds):
            if isinstance(b, dict):
                b = boundary_from_dict(b, src, f"boundaries[{i}]")
            if not isinstance(b, Boundary):
                raise fail(src, f"boundaries[{i}]", f"must be a Boundary or a table, got {b!r}")
            resolved.append(b.resolved(self.seed_centre))
        put(self, "boundaries", tuple(resolved))

    # -- derived values --------------------------------------------------------------------------------
    @property
    def seed_centre(self) -> tuple[float, float, float]:
        """Where the seed starts: the start position, or the centre of the user's seed polygon."""
        if self.seed_polygon is not None:
            x, y, z = (float(v) for v in np.mean(np.asarray(self.seed_polygon), axis=0))
            return (x, y, z)
        return self.start_position

    def characteristic_length(self, step: int) -> float:
        """Start length times the (mean per-axis) scale for each of ``step`` derivation steps (manual -bl)."""
        return self.start_length * float(np.mean(self.scale)) ** step

    def max_branch_distance(self, step: int) -> float:
        """The largest distance at which two branches may join during ``step`` (``inf`` when unlimited)."""
        if self.branch_length < 0:
            return math.inf
        return self.branch_length * self.characteristic_length(step)

    @property
    def is_empty(self) -> bool:
        """True when only scaling moves the vertices (no forces, boundaries, noise or constraints)."""
        return not (self.attractors or self.repellers or self.boundaries or any(self.gravity)
                    or self.repelling_points or self.position_noise or self.fixed_perimeter
                    or self.fixed_centre or self.uniform_cells)

    # -- TOML ------------------------------------------------------------------------------------------
    @classmethod
    def from_dict(cls, data: dict[str, Any], source: str = "<dict>", base_dir: Path | None = None
                  ) -> Environment:
        """Build from a plain dict (TOML's tables); unknown keys and wrong types raise ConfigError.

        ``base_dir`` is where relative boundary-mesh paths are looked up (the TOML file's folder).
        """
        if not isinstance(data, dict):
            raise ConfigError(f"{source}: an environment must be a table of fields, got {data!r}")
        known = [f.name for f in dataclasses.fields(cls) if f.name != "source"]
        reject_unknown(data, known, source)
        kwargs = dict(data)
        if "boundaries" in kwargs:
            items = kwargs["boundaries"]
            if not isinstance(items, list):
                raise fail(source, "boundaries", f"must be an array of tables [[boundaries]], got {items!r}")
            kwargs["boundaries"] = tuple(boundary_from_dict(b, source, f"boundaries[{i}]", base_dir)
                                         for i, b in enumerate(items))
        for name in ("attractors", "repellers"):
            if name in kwargs:
                items = kwargs[name]
                if not isinstance(items, list):
                    raise fail(source, name, f"must be an array of tables [[{name}]], got {items!r}")
                kwargs[name] = tuple(PointForce.from_dict(p, source, f"{name}[{i}]")
                                     for i, p in enumerate(items))
        for name in ("seed_polygon", "seed_masses"):
            if name in kwargs and isinstance(kwargs[name], list):
                kwargs[name] = tuple(kwargs[name])
        return cls(**kwargs, source=source)

    def to_dict(self) -> dict[str, Any]:
        """The TOML-ready dict of every field (None fields left out); ``from_dict`` reads it back equal."""
        out: dict[str, Any] = {}
        for f in dataclasses.fields(self):
            if f.name == "source":
                continue
            value = getattr(self, f.name)
            if value is None:
                continue
            if f.name in ("attractors", "repellers", "boundaries"):
                out[f.name] = [item.to_dict() for item in value]
            elif f.name == "seed_polygon":
                out[f.name] = [list(p) for p in value]
            elif isinstance(value, tuple):
                out[f.name] = list(value)
            else:
                out[f.name] = value
        return out

    # -- derivation step, part 1 -----------------------------------------------------------------------
    def increase_size(self, positions: np.ndarray, *, step: int, masses: np.ndarray, stopped: np.ndarray,
                      perimeter: np.ndarray, edges: np.ndarray, rng: np.random.Generator) -> SizeIncrease:
        """Move every vertex for derivation step ``step`` (1-based); see genr8_dist.environment.physics."""
        return increase_size(self, positions, step=step, masses=masses, stopped=stopped, perimeter=perimeter,
                             edges=edges, rng=rng)

    def relax_cells(self, positions: np.ndarray, *, edges: np.ndarray, perimeter: np.ndarray,
                    stopped: np.ndarray) -> np.ndarray:
        """Uniform cells at the end of a derivation step; see genr8_dist.environment.physics.relax_cells."""
        from genr8_dist.environment.physics import relax_cells

        return relax_cells(self, positions, edges=edges, perimeter=perimeter, stopped=stopped)

    def constrain(self, positions: np.ndarray, *, stopped: np.ndarray) -> SizeIncrease:
        """Bring vertices on the wrong side of a hard boundary to its nearest allowed point.

        ``increase_size`` does this first thing each step; call it after rewriting too when the
        surface must honour the boundaries exactly (new vertices on an edge that is a chord of a
        curved wall lie inside it). Against a cut-off wall the vertex also stops. Returns the new
        positions and the cumulative stop mask; inputs are not modified.
        """
        points = np.asarray(positions, dtype=np.float64).reshape(-1, 3)
        mask = np.asarray(stopped, dtype=bool).copy()
        if not self.boundaries or len(points) == 0:
            return SizeIncrease(points.copy(), mask)
        return SizeIncrease(repair(self, points, mask), mask)

    def count_soft_violations(self, positions: np.ndarray) -> int:
        """How many vertices lie on the wrong side of at least one soft boundary (the fitness uses it)."""
        points = np.asarray(positions, dtype=np.float64).reshape(-1, 3)
        wrong = np.zeros(len(points), dtype=bool)
        for b in self.boundaries:
            if not b.hard:
                wrong |= b.violation(points) > 0.0
        return int(wrong.sum())

    def point_forces(self) -> list[tuple[PointForce, float]]:
        """Every attractor (+1) and repeller (-1) with its sign."""
        return [(a, 1.0) for a in self.attractors] + [(r, -1.0) for r in self.repellers]

    def total_force(self, positions: np.ndarray, masses: np.ndarray) -> np.ndarray:
        """Sum of the attractors', repellers' and gravity's displacements at each position."""
        points = np.asarray(positions, dtype=np.float64)
        out = np.zeros_like(points)
        for force, sign in self.point_forces():
            out += point_force_displacement(points, masses, force, sign)
        if any(self.gravity):
            out += np.asarray(self.gravity)
        return out

    def repelling(self, positions: np.ndarray, masses: np.ndarray, length: float) -> np.ndarray:
        """The repelling-points displacement (zero when ``repelling_points`` is 0)."""
        if self.repelling_points <= 0.0:
            return np.zeros_like(positions)
        radius = math.inf if self.repelling_radius == -1.0 else self.repelling_radius * length
        return repelling_displacement(positions, masses, self.repelling_points, radius, length,
                                      theta=self.repelling_theta)


def load_environment(path: str | Path) -> Environment:
    """Read an environment TOML file; every problem raises ConfigError naming the file and the field."""
    path = Path(path)
    data = read_toml(path, "environment file")
    return Environment.from_dict(data, source=str(path), base_dir=path.resolve().parent)
