"""The built-in surface phenotype implements the whole phenotype interface (develop, sizes, export,
preview, draw, export_formats), so the history commands call nothing but that interface."""

from __future__ import annotations

import ast
import sys
from pathlib import Path

import numpy as np
import pytest

from genr8_dist.config import RunConfig
from genr8_dist.environment import Environment
from genr8_dist.errors import ConfigError
from genr8_dist.phenotype import SURFACES, Developed

PACKAGE = Path(__file__).resolve().parents[1] / "genr8_dist"


@pytest.fixture(scope="module")
def developed() -> tuple[Developed, RunConfig]:
    from genr8_dist.hemls import load_system

    config = RunConfig(environment=Environment(steps=3))
    return SURFACES.develop(load_system("four_sided_tiles").to_text(), config), config


def test_a_surface_counts_the_sizes_it_declares(developed):
    grown, _ = developed
    surface = grown.value
    assert SURFACES.sizes == ("vertices", "edges", "regions")
    assert dict(grown.counts) == {"vertices": len(surface.vertices), "edges": len(surface.edges),
                                  "regions": len(surface.regions)}
    assert grown.counts["regions"] > 1 and grown.digest == surface.digest()
    assert SURFACES.describe(grown) == (f"{len(surface.vertices)} vertices, {len(surface.edges)} edges, "
                                        f"{len(surface.regions)} regions")


@pytest.mark.parametrize("suffix", ["obj", "ply", "stl", "glb"])
def test_the_surface_exports_every_mesh_format_it_names(developed, tmp_path, suffix):
    import trimesh

    grown, config = developed
    assert suffix in SURFACES.export_formats
    path = SURFACES.export(grown, tmp_path / f"s.{suffix}", config, name="0-1-2")
    mesh = trimesh.load(path, force="mesh", process=False)
    assert len(mesh.faces) == len(grown.value.triangles())
    if suffix in ("obj", "ply"):   # formats that keep every vertex, in the surface's order
        assert np.allclose(mesh.vertices, grown.value.vertices, atol=1e-6)


def test_the_surface_exports_a_rhino_file_with_its_mesh_named_and_its_scaffold(developed, tmp_path):
    rhino3dm = pytest.importorskip("rhino3dm")
    grown, config = developed
    path = SURFACES.export(grown, tmp_path / "s.3dm", config, name="3-4-5")
    model = rhino3dm.File3dm.Read(str(path))
    meshes = [o for o in model.Objects if isinstance(o.Geometry, rhino3dm.Mesh)]
    lines = [o for o in model.Objects if isinstance(o.Geometry, rhino3dm.LineCurve)]
    assert len(meshes) == 1 and meshes[0].Attributes.Name == "3-4-5"
    assert len(meshes[0].Geometry.Faces) == len(grown.value.triangles())
    assert len(lines) == len(grown.value.edges)


def test_a_missing_rhino_names_the_extra_and_writes_nothing(developed, tmp_path, monkeypatch):
    grown, config = developed
    monkeypatch.setitem(sys.modules, "rhino3dm", None)
    with pytest.raises(ConfigError, match=r"genr8-dist\[rhino\]"):
        SURFACES.export(grown, tmp_path / "s.3dm", config)
    assert list(tmp_path.iterdir()) == []


def test_the_surface_previews_and_draws_a_picture(developed, tmp_path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    grown, config = developed
    path = SURFACES.preview(grown, tmp_path / "s.png", title="a surface", config=config)
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    fig = plt.figure()
    ax = fig.add_subplot(projection="3d")
    SURFACES.draw(ax, grown)
    drawn = len(ax.collections)
    plt.close(fig)
    assert drawn == 2   # the shaded regions and the edges


def test_the_history_package_calls_the_phenotype_interface_not_the_surface_one():
    """No module of history draws, exports or previews a surface itself, or asks whether a phenotype is
    the surface one (it may name SURFACES only as the phenotype of a run of a code-free universe)."""
    for path in sorted((PACKAGE / "history").glob("*.py")):
        tree = ast.parse(path.read_text(encoding="utf-8"))
        names = {n.id for n in ast.walk(tree) if isinstance(n, ast.Name)}
        names |= {n.attr for n in ast.walk(tree) if isinstance(n, ast.Attribute)}
        names |= {a.name for n in ast.walk(tree) if isinstance(n, ast.ImportFrom) for a in n.names}
        assert not names & {"draw_surface", "render_png", "export_mesh", "export_3dm", "surface"}, path.name
        compared = [ast.unparse(n) for n in ast.walk(tree) if isinstance(n, ast.Compare)
                    and "SURFACES" in ast.unparse(n)]
        assert compared == [], (path.name, compared)


def test_a_phenotype_without_pictures_or_exports_says_so_in_a_one_line_error(tmp_path):
    """A plugin phenotype that implements only develop, measure and fitness: asking for its picture
    or a file is an error the command line reports in one line (a Genr8Error), naming the phenotype."""
    from genr8_dist.errors import Genr8Error
    from genr8_dist.phenotype import Phenotype

    class Bare(Phenotype):
        name = "bare"

        def develop(self, text, config):
            return Developed(value=text, digest="0")

        def measure(self, developed, config):
            return {}

        def fitness(self, raw, config):
            return 0.0

    bare, developed = Bare(), Developed(value="x", digest="0")
    with pytest.raises(Genr8Error, match="phenotype bare exports nothing"):
        bare.export(developed, tmp_path / "x.obj", None)
    with pytest.raises(Genr8Error, match="phenotype bare draws no preview"):
        bare.preview(developed, tmp_path / "x.png", title="x", config=None)
    with pytest.raises(Genr8Error, match="phenotype bare draws no preview"):
        bare.draw(None, developed)
