"""Regrowing individuals of a real (small) evolution run: bit-identical surfaces, exports that load
back, the gallery and the report (opened in a real headless chromium)."""

from __future__ import annotations

import re
import shutil
import subprocess
import sys
import tomllib
from pathlib import Path

import numpy as np
import pyarrow.compute as pc
import pytest
from history_runs import REAL_INTERVENTION_AT, build_real_run

from genr8_dist import cli, history
from genr8_dist.errors import Genr8Error
from genr8_dist.history import HistoryError


@pytest.fixture(scope="module")
def real_run(tmp_path_factory):
    path = tmp_path_factory.mktemp("real") / "run"
    build_real_run(path)
    return path


@pytest.fixture(scope="module")
def real_rows(real_run):
    import pyarrow as pa
    import pyarrow.parquet as pq

    from genr8_dist.store import RunStore

    return pa.concat_tables([pq.read_table(f) for f in RunStore.open(real_run).individual_files()])


def _valid_ids(rows, generation=None):
    table = rows.filter(rows["valid"])
    if generation is not None:
        table = table.filter(pc.equal(table["generation"], generation))
    return table["id"].to_pylist()


def _independent_surface(row, toml_text):
    """Grow the row's text in the environment of ``toml_text`` without the history module."""
    from genr8_dist.config import RunConfig
    from genr8_dist.hemls import grow, parse

    config = RunConfig.from_dict(tomllib.loads(toml_text))
    return grow(parse(row["text"]), config.environment).surface


def _check_regrowth(real_run, real_rows, ids):
    from genr8_dist.store import RunStore

    store = RunStore.open(real_run)
    tomls = {c.version: c.toml for c in store.configs()}
    by_id = {r["id"]: r for r in real_rows.to_pylist()}
    for ident in ids:
        result = history.regrow(store, ident)
        row = by_id[ident]
        assert result.digest == row["phenotype_digest"]
        assert len(result.value.vertices) == row["size_vertices"]
        assert len(result.value.edges) == row["size_edges"]
        assert result.steps == row["steps_done"]
        assert result.text_matches or row["origin"] == "injected"
        again = _independent_surface(row, tomls[row["config_version"]])
        assert np.array_equal(again.vertices, result.value.vertices)


def test_individuals_of_every_kind_regrow_bit_identically(real_run, real_rows):
    """One valid individual per generation and per way of being made (migrants, the injected copy)."""
    seen, ids = set(), []
    for r in real_rows.filter(real_rows["valid"]).to_pylist():
        if (r["generation"], r["origin"]) not in seen:
            seen.add((r["generation"], r["origin"]))
            ids.append(r["id"])
    origins = {o for _, o in seen}
    assert {"random", "migrant", "injected", "elite"} <= origins
    _check_regrowth(real_run, real_rows, ids)


@pytest.mark.slow
def test_every_valid_individual_regrows_bit_identically(real_run, real_rows):
    ids = _valid_ids(real_rows)
    assert len(ids) >= 60
    _check_regrowth(real_run, real_rows, ids)


def test_the_configuration_version_in_force_is_used(real_run, real_rows):
    """After the intervention (a stronger attractor), regrowing under version 1 would differ."""
    from genr8_dist.store import RunStore

    store = RunStore.open(real_run)
    late = [r for r in real_rows.to_pylist()
            if r["valid"] and r["generation"] >= REAL_INTERVENTION_AT and r["origin"] != "migrant"]
    row = late[0]
    assert row["config_version"] == 2
    result = history.regrow(store, row["id"])
    v1 = _independent_surface(row, store.configs()[0].toml)
    assert not np.array_equal(v1.vertices, result.value.vertices)
    assert result.config.environment.attractors[0].constant == 6.0


def test_a_surface_that_differs_from_the_record_is_refused(real_run, real_rows, monkeypatch):
    from genr8_dist.history import _tables

    ident = _valid_ids(real_rows)[0]
    original = _tables.individual

    def altered(run, id, columns=None):
        table = original(run, id, columns)
        index = table.schema.get_field_index("phenotype_digest")
        return table.set_column(index, "phenotype_digest", pc.cast(pc.utf8_upper(table["phenotype_digest"]),
                                                                 table.schema.field(index).type))

    monkeypatch.setattr(_tables, "individual", altered)
    with pytest.raises(HistoryError, match="did not reproduce the recorded surface"):
        history.regrow(real_run, ident)


@pytest.mark.parametrize("suffix", ["obj", "ply", "stl", "glb"])
def test_exports_load_back_in_trimesh(real_run, real_rows, tmp_path, suffix):
    import trimesh

    ident = _valid_ids(real_rows, generation=3)[0]
    result = history.regrow(real_run, ident)
    path = history.export(result, tmp_path / f"s.{suffix}")
    mesh = trimesh.load(path, force="mesh", process=False)
    triangles = len(result.value.mesh().triangles)      # the run's meshing (2: points added)
    assert len(mesh.faces) == triangles > 0
    if suffix == "stl":  # STL keeps no shared vertices: three per triangle
        assert len(mesh.vertices) == 3 * triangles
    else:
        assert len(mesh.vertices) == len(result.value.mesh().points)
        assert np.allclose(mesh.vertices[:result.value.n_vertices], result.value.vertices, atol=1e-6)


def test_3dm_export_loads_back_in_rhino3dm(real_run, real_rows, tmp_path):
    import rhino3dm

    ident = _valid_ids(real_rows, generation=3)[0]
    result = history.regrow(real_run, ident)
    history.export(result, tmp_path / "s.3dm")
    model = rhino3dm.File3dm.Read(str(tmp_path / "s.3dm"))
    meshes = [o.Geometry for o in model.Objects if isinstance(o.Geometry, rhino3dm.Mesh)]
    lines = [o for o in model.Objects if isinstance(o.Geometry, rhino3dm.LineCurve)]
    assert len(meshes) == 1
    assert len(meshes[0].Vertices) == len(result.value.mesh().points)
    assert len(meshes[0].Faces) == len(result.value.mesh().triangles)
    assert len(lines) == len(result.value.edges)
    assert [layer.Name for layer in model.Layers] == ["genr8 surface", "genr8 scaffold",
                                                      "genr8 scaffold curves"]
    assert {o.Attributes.Name for o in model.Objects if isinstance(o.Geometry, rhino3dm.Mesh)} == {ident}


def test_missing_extras_name_the_extra(real_run, real_rows, tmp_path, monkeypatch):
    result = history.regrow(real_run, _valid_ids(real_rows)[0])
    monkeypatch.setitem(sys.modules, "rhino3dm", None)
    with pytest.raises(Genr8Error, match=r"genr8-dist\[rhino\]"):   # the surface phenotype's export
        history.export(result, tmp_path / "s.3dm")
    monkeypatch.setitem(sys.modules, "duckdb", None)
    with pytest.raises(HistoryError, match=r"genr8-dist\[sql\]"):
        history.query(real_run, "select 1")
    monkeypatch.setitem(sys.modules, "matplotlib", None)
    with pytest.raises(HistoryError, match=r"genr8-dist\[viz\]"):
        history.pictures.curves_png(real_run, tmp_path / "c.png")
    assert list(tmp_path.iterdir()) == []


def _png_ok(path: Path, min_std: float = 0.05) -> None:
    import matplotlib.image as mpimg

    image = mpimg.imread(path)
    assert image.shape[0] > 200 and image.shape[1] > 200
    rgb = image[..., :3]
    assert float(rgb.std()) > min_std
    assert float((rgb.mean(axis=2) < 0.9).mean()) > 0.02  # something is drawn, not a blank page


def test_show_cli_writes_everything(real_run, real_rows, tmp_path, capsys):
    ident = _valid_ids(real_rows, generation=3)[0]
    row = real_rows.filter(pc.equal(real_rows["id"], ident)).to_pylist()[0]
    code = cli.main(["show", str(real_run), ident, "-o", str(tmp_path / "s.obj"), "-o",
                     str(tmp_path / "s.3dm"), "--png", str(tmp_path / "s.png"), "--grammar",
                     str(tmp_path / "g.txt"), "--genome", str(tmp_path / "genome.txt")])
    out = capsys.readouterr().out
    assert code == 0
    assert f"regrown: {row['size_vertices']} vertices, {row['size_edges']} edges" in out
    assert f"digest {row['phenotype_digest']} matches the recorded one" in out
    assert (tmp_path / "g.txt").read_text().rstrip("\n") == row["text"].rstrip("\n")
    assert [int(c) for c in (tmp_path / "genome.txt").read_text().split()] == row["genome"]
    _png_ok(tmp_path / "s.png")
    for statement in row["text"].splitlines():   # a rule that rewrote no edge is marked
        assert re.search(rf"^    {re.escape(statement)}(    # never fired)?$", out, re.M), statement


def test_show_of_an_invalid_individual(tmp_path, capsys):
    """An individual that failed before growth shows its failure; exporting it is a one-line error."""
    from history_runs import REAL

    from genr8_dist.config import RunConfig
    from genr8_dist.evolution.individual import Individual
    from genr8_dist.store import RunStore

    store = RunStore.create(tmp_path / "run", RunConfig.from_dict(REAL).to_toml())
    store.commit([Individual(0, 0, 0, (3, 1, 4), "random", stage="map",
                             error="genome ran out of codons after 2 wraps")])
    assert cli.main(["show", str(tmp_path / "run"), "0-0-0", "--genome", str(tmp_path / "g.txt")]) == 0
    out = capsys.readouterr().out
    assert "invalid at map: genome ran out of codons after 2 wraps" in out
    assert (tmp_path / "g.txt").read_text() == "3 1 4\n"
    assert cli.main(["show", str(tmp_path / "run"), "0-0-0", "-o", str(tmp_path / "x.obj")]) == 2
    err = capsys.readouterr().err
    assert err == "genr8: error: 0-0-0 has no surface to export: it failed at map " \
                  "(genome ran out of codons after 2 wraps)\n"
    assert not (tmp_path / "x.obj").exists()
    assert cli.main(["show", str(tmp_path / "run"), "0-0-0", "-o", str(tmp_path / "x.dwg")]) == 2
    assert "unknown format '.dwg'" in capsys.readouterr().err


def test_gallery_cli(real_run, tmp_path, capsys):
    code = cli.main(["gallery", str(real_run), "-k", "6", "-o", str(tmp_path / "g.png")])
    assert code == 0
    assert "6 surfaces of generation 3" in capsys.readouterr().out
    _png_ok(tmp_path / "g.png")
    code = cli.main(["gallery", str(real_run), "--generation", "1", "-k", "3", "--per-island", "-o",
                     str(tmp_path / "p.png")])
    assert code == 0
    _png_ok(tmp_path / "p.png")


def test_report_is_self_contained(real_run, tmp_path):
    path = history.report.write_report(real_run, tmp_path / "r.html", k=5, gallery_k=6)
    page = path.read_text(encoding="utf-8")
    assert page.startswith("<!DOCTYPE html>")
    assert not re.search(r"(src|href)=\"(https?:)?//", page), "the page must not fetch anything"
    assert not re.search(r"<script[^>]*\bsrc=", page) and "fetch(" not in page   # inline, offline
    # the curves, the gallery, the kinds of form (clusters), the ancestry
    assert page.count('src="data:image/png;base64,') == 4
    assert "Kinds of form the run found" in page and "No clusters" not in page
    best = history.top(real_run, 5, systems=True, distinct=True)   # one row per form
    for ident in best["id"].to_pylist():
        assert f"<code>{ident}</code>" in page
    assert f"The {best.num_rows} best forms of the run" in page
    assert "environment.attractors" in page  # what the intervention changed
    assert "No gallery" not in page


@pytest.mark.slow
@pytest.mark.skipif(shutil.which("chromium") is None, reason="chromium is not installed (CI installs it)")
def test_report_renders_in_headless_chromium(real_run, tmp_path):
    page = history.report.write_report(real_run, tmp_path / "r.html")
    shot = tmp_path / "shot.png"
    subprocess.run(
        ["chromium", "--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
         "--disable-component-update", "--disable-sync", "--no-first-run",
         f"--user-data-dir={tmp_path / 'profile'}", "--window-size=1400,2000", "--hide-scrollbars",
         "--virtual-time-budget=5000",
         f"--screenshot={shot}", page.resolve().as_uri()],
        check=True, capture_output=True, timeout=120)
    _png_ok(shot)
