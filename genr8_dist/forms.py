"""What a person sees of a surface in a gallery tile, as numbers: the descriptors that tell the kinds
of form of a run apart (``history.clusters``, the report's and the studio's kinds of form).

Three blocks, each independent of the surface's size and position and each varying continuously
with the vertices (a form a hair away has descriptors a hair away):

* outline: how far from the centre of the bounding square a ray in each of 24 directions leaves the
  perimeter, over the farthest;
* height field: the mean height above the surface's mean on an 8 x 8 grid over the bounding square
  (bilinear: each point shared between its four nearest cells), over the square's side;
* curvature: the regions' share of area per 15 degrees of tilt from level (each shared between its
  two nearest steps), and the share of area facing down (folds).
"""

from __future__ import annotations

from typing import Any

import numpy as np

__all__ = ["form_descriptors"]

_RAYS = 24           # outline: where rays in 24 directions leave the perimeter
_GRID = 8            # height field: mean height on an 8 x 8 grid over the bounding square
_TILTS = 6           # curvature: area share of the regions per 15 degrees of tilt from level


def form_descriptors(surface: Any) -> list[np.ndarray] | None:
    """The outline (24), height-field (64) and curvature (7) blocks of ``surface`` (see the module
    docstring); ``None`` for a value that is not a surface, or a surface without regions."""
    if not all(hasattr(surface, a) for a in ("vertices", "regions", "perimeter")):
        return None
    v = np.asarray(surface.vertices, dtype=np.float64)
    regions = surface.regions
    if len(v) < 3 or not len(regions):
        return None
    lo, hi = v.min(axis=0), v.max(axis=0)
    side = float(max(hi[0] - lo[0], hi[1] - lo[1]))
    if not side > 0:
        return None
    centre = (lo + hi) / 2
    # outline: where a ray from the centre in each of 24 directions leaves the perimeter, the farthest
    loop = v[np.asarray(surface.perimeter(), dtype=np.int64)][:, :2] - centre[:2]
    angle = np.arange(_RAYS) * (2 * np.pi / _RAYS)
    ray = np.column_stack([np.cos(angle), np.sin(angle)])
    p, e = loop, np.roll(loop, -1, axis=0) - loop
    cross = ray[:, None, 0] * e[None, :, 1] - ray[:, None, 1] * e[None, :, 0]       # (rays, sides)
    safe = np.where(np.abs(cross) > 1e-12, cross, 1.0)
    t = (p[None, :, 0] * e[None, :, 1] - p[None, :, 1] * e[None, :, 0]) / safe      # along the ray
    u = (p[None, :, 0] * ray[:, None, 1] - p[None, :, 1] * ray[:, None, 0]) / safe  # along the side
    hit = (np.abs(cross) > 1e-12) & (u >= 0) & (u <= 1) & (t > 0)
    outline = np.where(hit, t, 0.0).max(axis=1)
    outline /= max(float(outline.max()), 1e-12)
    # height field: the vertices and the regions' centres, spread bilinearly over the grid's cells
    areas, normals, centres = [], [], []
    for cycle in regions:
        q = v[cycle]
        n = np.cross(q, np.roll(q, -1, axis=0)).sum(axis=0) / 2   # Newell: area times unit normal
        areas.append(float(np.linalg.norm(n)))
        normals.append(n)
        centres.append(q.mean(axis=0))
    area = np.asarray(areas)
    normal = np.asarray(normals) / np.maximum(area, 1e-300)[:, None]
    points = np.vstack([v, np.asarray(centres)])
    z = (points[:, 2] - points[:, 2].mean()) / side
    total, count = np.zeros(_GRID * _GRID), np.zeros(_GRID * _GRID)
    g = np.clip((points[:, :2] - (centre[:2] - side / 2)) / side * _GRID - 0.5, 0.0, _GRID - 1.0)
    i0 = np.minimum(np.floor(g).astype(np.int64), _GRID - 2)
    f = g - i0
    for dx in (0, 1):
        for dy in (0, 1):
            w = (f[:, 0] if dx else 1 - f[:, 0]) * (f[:, 1] if dy else 1 - f[:, 1])
            cell = (i0[:, 0] + dx) * _GRID + i0[:, 1] + dy
            total += np.bincount(cell, w * z, _GRID * _GRID)
            count += np.bincount(cell, w, _GRID * _GRID)
    height = np.where(count > 1e-9, total / np.maximum(count, 1e-9), 0.0)
    # curvature: the spread of the regions' tilts (a sheet: all level; a dome or a fold: many),
    # each region shared between the two nearest of the 15-degree steps
    weight = area / max(float(area.sum()), 1e-300)
    step = np.degrees(np.arccos(np.clip(np.abs(normal[:, 2]), 0.0, 1.0))) / 15
    low = np.minimum(np.floor(step).astype(np.int64), _TILTS - 1)
    up = np.clip(step - low, 0.0, 1.0)
    tilts = (np.bincount(low, weight * (1 - up), _TILTS)
             + np.bincount(np.minimum(low + 1, _TILTS - 1), weight * up, _TILTS))
    down = float(weight[normal[:, 2] < 0].sum())
    return [outline, height, np.append(tilts, min(down, 1 - down))]
