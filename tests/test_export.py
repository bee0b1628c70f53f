"""Export: meshes load back in trimesh with the right counts, scaffolds keep every edge, PNGs are pictures."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pytest

from genr8_dist.environment import Environment, PointForce, SphereBoundary
from genr8_dist.errors import ConfigError
from genr8_dist.export import export_mesh, export_scaffold, render_png


@dataclass
class GridSurface:
    """A plain map with the Surface contract: the four-sided tiles' n-step grid (quads as regions)."""

    vertices: np.ndarray
    edges: np.ndarray
    labels: np.ndarray
    regions: list = field(default_factory=list)

    def triangles(self) -> np.ndarray:
        return np.array([[r[0], r[i], r[i + 1]] for r in self.regions for i in range(1, len(r) - 1)],
                        dtype=np.int64).reshape(-1, 3)


def tiles(steps: int) -> GridSurface:
    m = 2 ** steps
    xs = np.linspace(-1.5, 1.5, m + 1)
    x, y = np.meshgrid(xs, xs, indexing="ij")
    vertices = np.column_stack([x.ravel(), y.ravel(), 0.2 * np.sin(x.ravel()) * np.cos(y.ravel())])
    idx = np.arange((m + 1) ** 2).reshape(m + 1, m + 1)
    edges = np.concatenate([np.column_stack([idx[:-1, :].ravel(), idx[1:, :].ravel()]),
                            np.column_stack([idx[:, :-1].ravel(), idx[:, 1:].ravel()])])
    regions = [np.array([idx[i, j], idx[i + 1, j], idx[i + 1, j + 1], idx[i, j + 1]])
               for i in range(m) for j in range(m)]
    return GridSurface(vertices, edges, np.arange(len(edges)) % 2, regions)


@pytest.mark.parametrize("suffix", ["obj", "ply", "stl", "glb"])
def test_mesh_formats_load_back(tmp_path, suffix):
    import trimesh

    surface = tiles(3)
    path = export_mesh(surface, tmp_path / f"tiles.{suffix}")
    mesh = trimesh.load(path, force="mesh")
    assert len(mesh.faces) == 128  # 64 quads
    assert len(mesh.vertices) == 81
    assert mesh.area == pytest.approx(trimesh.Trimesh(surface.vertices, surface.triangles()).area)
    assert not list(tmp_path.glob(".*tmp")), "no temporary file left behind"


def test_obj_keeps_vertex_order(tmp_path):
    import trimesh

    surface = tiles(2)
    mesh = trimesh.load(export_mesh(surface, tmp_path / "t.obj"), force="mesh", process=False)
    np.testing.assert_allclose(mesh.vertices, surface.vertices)


def test_unknown_suffix_is_a_config_error(tmp_path):
    with pytest.raises(ConfigError, match=r"tiles\.fbx.*\.obj"):
        export_mesh(tiles(1), tmp_path / "tiles.fbx")
    with pytest.raises(ConfigError, match="scaffold"):
        export_scaffold(tiles(1), tmp_path / "tiles.stl")
    assert list(tmp_path.iterdir()) == []


def test_missing_folder_is_a_config_error(tmp_path):
    with pytest.raises(ConfigError, match="does not exist"):
        export_mesh(tiles(1), tmp_path / "nowhere" / "t.obj")


def test_scaffold_obj_has_every_edge(tmp_path):
    surface = tiles(3)
    text = export_scaffold(surface, tmp_path / "s.obj").read_text()
    lines = [line.split() for line in text.splitlines()]
    vs = [line for line in lines if line[0] == "v"]
    ls = [line for line in lines if line[0] == "l"]
    assert len(vs) == 81 and len(ls) == len(surface.edges) == 144
    got = sorted(tuple(sorted((int(a) - 1, int(b) - 1))) for _, a, b in ls)
    assert got == sorted(tuple(sorted(e)) for e in surface.edges.tolist())
    assert {line[1] for line in lines if line[0] == "g"} == {"label0", "label1"}


def test_scaffold_ply_and_dxf(tmp_path):
    surface = tiles(2)
    ply_path = export_scaffold(surface, tmp_path / "s.ply")
    ply = ply_path.read_text()
    assert "element edge 40" in ply and "element vertex 25" in ply
    body = ply.split("end_header\n")[1].splitlines()
    written = np.array([list(map(float, row.split())) for row in body[:25]])
    np.testing.assert_array_equal(written, surface.vertices)
    assert [list(map(int, r.split()))[:2] for r in body[25:]] == surface.edges.tolist()
    dxf = export_scaffold(surface, tmp_path / "s.dxf").read_text().splitlines()
    assert dxf.count("LINE") == 40 and dxf[-1] == "EOF"
    assert {dxf[i + 2] for i, v in enumerate(dxf) if v == "LINE"} == {"label0", "label1"}


def test_png_is_a_picture(tmp_path):
    from PIL import Image

    env = Environment(gravity=0.2, boundaries=(SphereBoundary(centre=(0, 0, -2.5), radius=2.0),),
                      repellers=(PointForce(position=(1, 1, -1)),))
    path = render_png(tiles(4), tmp_path / "t.png", title="four-sided tiles, 4 steps", env=env)
    bare = render_png(tiles(4), tmp_path / "bare.png", title="four-sided tiles, 4 steps")

    def colourful(png):
        image = np.asarray(Image.open(png).convert("RGB")).astype(int)
        assert image.shape[0] > 400 and image.shape[1] > 400
        spread = np.abs(image[:, :, 0] - image[:, :, 1]) + np.abs(image[:, :, 1] - image[:, :, 2])
        return (spread > 60).mean()

    assert colourful(bare) > 0.15, "the shaded surface fills a good part of the picture"
    assert 0.02 < colourful(path) < colourful(bare), "the environment is in view, so the surface is smaller"
    with pytest.raises(ConfigError, match="png"):
        render_png(tiles(1), tmp_path / "t.jpg", title="x")


def test_png_without_regions_draws_the_edges(tmp_path):
    surface = tiles(2)
    surface.regions = []
    path = render_png(surface, tmp_path / "curve.png", title="curve")
    assert path.stat().st_size > 5000


def test_grown_four_sided_tiles_round_trip_through_obj(tmp_path):
    import trimesh

    from genr8_dist.hemls import grow, load_system

    surface = grow(load_system("four_sided_tiles"), Environment(steps=3)).surface
    mesh = trimesh.load(export_mesh(surface, tmp_path / "tiles.obj"), force="mesh")
    assert len(mesh.faces) == 128 and len(mesh.vertices) == 81
    assert mesh.area == pytest.approx(surface.n_regions * (1.5 ** 3 / 8) ** 2)  # 64 squares of side 1.5^3/8
    lines = export_scaffold(surface, tmp_path / "tiles-scaffold.obj").read_text().splitlines()
    assert sum(line.startswith("l ") for line in lines) == 144


def test_every_surface_format_of_the_table_writes_its_file(tmp_path):
    from genr8_dist.export import MESH_FORMATS, SURFACE_FORMATS, export_surface, surface_bytes
    from genr8_dist.phenotype import SURFACES

    assert SURFACES.export_formats == tuple(SURFACE_FORMATS)
    assert MESH_FORMATS == ("obj", "ply", "stl", "glb")
    surface = tiles(2)
    for suffix, found in SURFACE_FORMATS.items():
        if suffix == "3dm":
            pytest.importorskip("rhino3dm")
        path = export_surface(surface, tmp_path / f"t.{suffix}", name="t")
        assert path.stat().st_size > 0 and found.suffix == suffix
        download = surface_bytes(surface, suffix, name="t")
        if suffix != "3dm":     # a Rhino file holds the time it was written and fresh object ids
            assert download == path.read_bytes()
        assert len(download) > 0
    with pytest.raises(ConfigError, match=r"unknown surface format '\.dxf'; use one of \.obj"):
        export_surface(surface, tmp_path / "t.dxf")


def test_pictures_blend_the_shading_across_each_triangle():
    """A picture draws each triangle as its four midpoint triangles, coloured from the corners'
    height and light, so neighbouring polygons differ by a fraction of a facet's step."""
    import matplotlib

    from genr8_dist.export import _face_colours

    points = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 1.0], [1.0, 1.0, 1.0]])
    faces = np.array([[0, 1, 2], [1, 3, 2]])
    polygons, colours = _face_colours(points, faces, matplotlib.colormaps["viridis"])
    assert polygons.shape == (8, 3, 3) and colours.shape == (8, 4)

    def area(t):
        return np.linalg.norm(np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0]), axis=1).sum() / 2

    assert area(polygons) == pytest.approx(area(points[faces]))      # the same surface drawn
    low, high = colours[:, :3].sum(axis=1).min(), colours[:, :3].sum(axis=1).max()
    assert len({tuple(c) for c in colours.round(6)}) > 2 and high > low  # shades vary within a face
