"""The scaffold as B-spline lines (genr8_dist.scaffold), the smoothed and .3dm exports, and pictures
drawn without triangle edges."""

from __future__ import annotations

import numpy as np
import pytest

from genr8_dist.environment import Environment
from genr8_dist.export import draw_surface, export_3dm, export_mesh, mesh_of
from genr8_dist.hemls import grow, load_system
from genr8_dist.scaffold import sample_line, scaffold_lines


@pytest.fixture(scope="module")
def tiles():
    return grow(load_system("four-sided-tiles"), Environment(steps=3)).surface


def test_every_edge_in_exactly_one_line_and_straight_runs_joined(tiles):
    lines = scaffold_lines(tiles.vertices, tiles.edges)
    used = sorted(tuple(sorted(p)) for ids, closed in lines
                  for p in zip(ids, [*ids[1:], ids[0]] if closed else ids[1:], strict=False))
    assert used == sorted(tuple(sorted(e)) for e in tiles.edges.tolist())
    assert len(lines) == 18       # an 8 x 8 grid: 9 straight lines each way


def test_a_b_spline_line_starts_and_ends_at_its_ends():
    p = np.array([[0.0, 0, 0], [1, 1, 0], [2, 0, 0], [3, 1, 0], [4, 0, 0]])
    curve = sample_line(p, False)
    assert np.allclose(curve[0], p[0]) and np.allclose(curve[-1], p[-1])
    assert curve[:, 1].max() < 1.0     # it smooths the zigzag (control points, not interpolation)


@pytest.mark.parametrize("steps", [1, 2])
def test_smooth_multiplies_the_faces_by_four_per_step(tiles, tmp_path, steps):
    import trimesh

    faces = len(mesh_of(tiles).faces)
    out = trimesh.load(export_mesh(tiles, tmp_path / "s.ply", smooth=steps), force="mesh", process=False)
    assert len(out.faces) == faces * 4 ** steps


def test_3dm_holds_the_scaffold_as_nurbs_curves(tiles, tmp_path):
    rhino3dm = pytest.importorskip("rhino3dm")
    model = rhino3dm.File3dm.Read(str(export_3dm(tiles, tmp_path / "t.3dm", name="tiles")))
    layers = {layer.Name: i for i, layer in enumerate(model.Layers)}
    curves = [o.Geometry for o in model.Objects
              if o.Attributes.LayerIndex == layers["genr8 scaffold curves"]]
    assert len(curves) == 18
    assert all(isinstance(c, rhino3dm.NurbsCurve) and c.Degree == 3 for c in curves)


def test_pictures_draw_no_triangle_edge(tiles):
    pytest.importorskip("matplotlib")
    from mpl_toolkits.mplot3d.art3d import Line3DCollection, Poly3DCollection

    from genr8_dist.export import pyplot as _pyplot

    plt = _pyplot()
    fig = plt.figure()
    ax = fig.add_subplot(projection="3d")
    draw_surface(ax, tiles)
    polys = [c for c in ax.collections if isinstance(c, Poly3DCollection)]
    lines = [c for c in ax.collections if isinstance(c, Line3DCollection)]
    assert len(polys) == 1
    # triangle edges take their face's colour (hidden); the dark lines are the 18 scaffold curves
    assert np.allclose(polys[0].get_edgecolor(), polys[0].get_facecolor())
    assert len(lines) == 1 and len(lines[0]._segments3d) == 18
    plt.close(fig)
