"""``genr8 grow`` in-process: the per-step table, exports, --each-step, stdin, and one-line errors."""

from __future__ import annotations

import io

import numpy as np
import pytest

from genr8_dist.cli import main


def run(argv, capsys):
    status = main(argv)
    captured = capsys.readouterr()
    return status, captured.out, captured.err


def test_table_and_exports(tmp_path, capsys):
    import trimesh

    obj, png, scaffold = tmp_path / "t.obj", tmp_path / "t.png", tmp_path / "s.obj"
    status, out, err = run(["grow", "four-sided-tiles", "--steps", "3", "-o", str(obj), "--png", str(png),
                            "--scaffold", str(scaffold)], capsys)
    assert status == 0, err
    rows = [line.split() for line in out.splitlines() if line.split() and line.split()[0].isdigit()]
    assert [[int(v) for v in row[:4]] for row in rows] == [[1, 9, 12, 4], [2, 25, 40, 16], [3, 81, 144, 64]]
    mesh = trimesh.load(obj, force="mesh")
    assert len(mesh.faces) == 128 and len(mesh.vertices) == 81
    assert png.stat().st_size > 10_000 and png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert sum(line.startswith("l ") for line in scaffold.read_text().splitlines()) == 144
    assert f"wrote {obj}" in out


def test_each_step_writes_one_file_per_step(tmp_path, capsys):
    import trimesh

    status, out, err = run(["grow", "square", "--steps", "3", "--each-step", "-o", str(tmp_path / "sq.ply")],
                           capsys)
    assert status == 0, err
    assert f"wrote {tmp_path / 'sq-step3.ply'}" in out
    faces = [len(trimesh.load(tmp_path / f"sq-step{k}.ply", force="mesh").faces) for k in (1, 2, 3)]
    assert faces == [8, 32, 128]
    assert not (tmp_path / "sq.ply").exists()


def test_environment_file_and_seed(tmp_path, capsys):
    import trimesh

    env = tmp_path / "env.toml"
    env.write_text("steps = 2\ngravity = 0.5\nposition_noise = 0.1\n")
    outs = []
    for seed in ("1", "1", "2"):
        path = tmp_path / f"g{len(outs)}.obj"
        status, _, err = run(["grow", "square", "--env", str(env), "--seed", seed, "-o", str(path)], capsys)
        assert status == 0, err
        outs.append(trimesh.load(path, force="mesh", process=False).vertices)
    assert np.array_equal(outs[0], outs[1]) and not np.array_equal(outs[0], outs[2])
    assert outs[0][:, 2].mean() < -0.5  # gravity pulled it down


def test_stdin(monkeypatch, tmp_path, capsys):
    text = "Edge0 + Edge1 + Edge0 + Edge1\nEdge0 -> Edge0 [ [ + Edge1 ] - Edge1 ] Edge0\n" \
           "Edge1 -> Edge1 [ [ + Edge0 ] - Edge0 ] Edge1\nAngle 90\n"
    monkeypatch.setattr("sys.stdin", io.StringIO(text))
    status, out, err = run(["grow", "-", "--steps", "2"], capsys)
    assert status == 0, err
    assert any(line.split()[:4] == ["2", "25", "40", "16"] for line in out.splitlines())


def test_edge_cap_is_reported(tmp_path, capsys):
    env = tmp_path / "env.toml"
    env.write_text("max_edges = 100\n")
    status, out, err = run(["grow", "four-sided-tiles", "--env", str(env), "--steps", "5"], capsys)
    assert status == 0, err
    assert "growth stopped at step" in out and "max_edges = 100" in out


@pytest.mark.parametrize(("argv", "message"), [
    (["grow", "no-such-system"], "no-such-system"),
    (["grow", "square", "-o", "out.fbx"], "out.fbx"),
    (["grow", "square", "--png", "out.jpg"], "out.jpg"),
    (["grow", "square", "--steps", "-2"], "--steps"),
])
def test_errors_are_one_line_exit_2(argv, message, capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    status, _, err = run(argv, capsys)
    assert status == 2
    assert err.startswith("genr8: error:") and message in err and err.count("\n") == 1
    assert list(tmp_path.iterdir()) == []


def test_malformed_system_file(tmp_path, capsys):
    bad = tmp_path / "bad.hemls"
    bad.write_text("Edge0 + Edge1 + Edge0\nEdge0 -> Edge0 [ + Edge1\n")
    status, _, err = run(["grow", str(bad)], capsys)
    assert status == 2 and "bad.hemls:2" in err and err.count("\n") == 1


def test_bad_environment_field(tmp_path, capsys):
    env = tmp_path / "env.toml"
    env.write_text("gravity = 0.5\nwind = 3\n")
    status, _, err = run(["grow", "square", "--env", str(env)], capsys)
    assert status == 2 and "env.toml" in err and "'wind'" in err


def test_unreadable_boundary_mesh(tmp_path, capsys):
    (tmp_path / "wall.stl").write_text("not a mesh at all")
    env = tmp_path / "env.toml"
    env.write_text('[[boundaries]]\nkind = "mesh"\npath = "wall.stl"\n')
    status, _, err = run(["grow", "square", "--env", str(env)], capsys)
    assert status == 2 and "wall.stl" in err and err.count("\n") == 1


def test_a_rule_that_can_never_fire_is_a_warning_and_growth_goes_on(tmp_path, capsys):
    path = tmp_path / "two.hemls"
    path.write_text("A + A + A + A\nA -> A [ [ + A ] - A ] A\nA -> A A\nAngle 90\n")
    status, out, err = run(["grow", str(path), "--steps", "2"], capsys)
    assert status == 0
    assert err.strip() == ("genr8: warning: two: line 3: the rule for A can never fire: the rule on line 2 "
                           "rewrites every such edge first (for a random choice write the successors in "
                           "one rule, or 'p =' on each)")
    # the four branches meet at the centre: the two joins tie and cross, so neither is made
    # (branch_ties = "crossing", docs/fidelity.md)
    assert "   2         16         16          1" in out


@pytest.mark.parametrize("levels", [500, 5000])
def test_grow_of_brackets_nested_too_deep_is_one_line(tmp_path, capsys, levels):
    path = tmp_path / "deep.hemls"
    path.write_text("Edge1 + Edge1 + Edge1 + Edge1\nEdge1 -> Edge1 " + "[ " * levels + "+ Edge1 "
                    + "] " * levels + "\n")
    status, out, err = run(["grow", str(path), "--steps", "2"], capsys)
    assert status == 2 and out == ""
    assert err == f"genr8: error: {path}:2:216: brackets nest deeper than 100 levels (the limit of a " \
                  "rewrite system, docs/hemls.md)\n"
