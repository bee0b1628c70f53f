"""A run of the tables plugin universe (a phenotype that is not a surface, evolved by its own genome
and operators: Hornby & Pollack's) through the whole engine: islands on local Ray and on a simulated
2-node cluster, interrupt-and-resume and kill-and-resume equality, and the history commands
regrowing, exporting and drawing its tables."""

from __future__ import annotations

import contextlib
import io
import itertools
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from distributed_runs import drive_to_end, rows, stop_at

pytestmark = [pytest.mark.slow, pytest.mark.usefixtures("ray_local")]

HERE = Path(__file__).resolve().parent
TABLES_TOML = """\
universe = "tables"
seed = 3

[genome]
length = 120

[ea]
population = 6
generations = 4
tournament = 2
elites = 2
crossover_rate = 0.5

[islands]
count = 2
migration_interval = 2
migrants = 1
"""


def new_tables_run(run_dir, toml: str):
    """A new run directory of ``toml`` (as ``genr8 run`` creates it: the store takes its phenotype's
    criteria and sizes from the configuration)."""
    from genr8_dist.config import RunConfig
    from genr8_dist.store import RunStore

    config = RunConfig.from_toml(toml)
    store = RunStore.create(run_dir, config.to_toml())
    store.record_event("start", generation=0)
    return store


@pytest.fixture(scope="module")
def reference(tmp_path_factory, ray_local):
    run_dir = tmp_path_factory.mktemp("tables") / "run"
    new_tables_run(run_dir, TABLES_TOML)
    summary, _ = drive_to_end(run_dir)
    assert summary.status == "complete"
    return run_dir


def test_a_tables_run_stores_the_voxel_criteria_and_the_negated_paper_fitness(reference):
    got = rows(reference)
    assert len(got) == 2 * 6 * 5
    assert {k for k in got[0] if k.startswith("crit_")} == {
        "crit_height", "crit_surface", "crit_stability", "crit_excess", "crit_voxels"}
    assert {k for k in got[0] if k.startswith("size_")} == {"size_commands", "size_modules"}
    assert not {k for k in got[0] if k.startswith(("n_", "surface"))}
    valid = [r for r in got if r["valid"]]
    from genr8_dist.grammar import load_universe

    voxels = load_universe("tables").hooks.voxels
    for r in valid[:6]:   # the stored digest and sizes are the development's
        table = voxels.develop(r["text"])
        assert (r["phenotype_digest"], r["size_commands"], r["size_modules"]) == (
            table.digest(), table.commands, table.modules)
    assert any(r["size_commands"] > 0 for r in valid)
    # the paper's variation (ea.variation = "auto"): every genome is its text's characters
    assert all(r["genome"] == [ord(c) for c in r["text"]] for r in got)
    assert {"mutation", "crossover"} & {r["origin"] for r in got}
    assert valid and all(r["fitness"] <= 0 for r in valid)
    for r in valid:
        paper = (r["crit_height"] * r["crit_surface"] * r["crit_stability"] / r["crit_excess"]
                 if r["crit_excess"] else 0.0)
        assert r["fitness"] == pytest.approx(-paper)
    # elitism 2: the best table of a generation is never worse than the one before
    for island in (0, 1):
        best = [min(r["fitness"] for r in valid if r["island"] == island and r["generation"] == g)
                for g in range(5)]
        assert all(b <= a for a, b in itertools.pairwise(best))


def test_interrupted_and_resumed_equals_uninterrupted(reference, tmp_path):
    run_dir = tmp_path / "run"
    new_tables_run(run_dir, TABLES_TOML)
    first, _ = drive_to_end(run_dir, on_generation=stop_at(2))
    assert first.status == "interrupted"
    second, _ = drive_to_end(run_dir)
    assert second.status == "complete"
    assert rows(run_dir) == rows(reference)


def test_a_killed_genr8_run_resumed_equals_the_uninterrupted_one(reference, tmp_path):
    """``genr8 run`` in its own process, SIGKILLed once generation 2 is committed, then resumed."""
    from genr8_dist.distributed.session import RunOptions, resume_run
    from genr8_dist.errors import StoreError
    from genr8_dist.store import RunStore

    config, run_dir = tmp_path / "tables.toml", tmp_path / "run"
    config.write_text(TABLES_TOML)
    env = dict(os.environ, RAY_USAGE_STATS_ENABLED="0")
    env.pop("RAY_ADDRESS", None)
    proc = subprocess.Popen([sys.executable, "-m", "genr8_dist.cli", "run", str(config), "--run-dir",
                             str(run_dir), "--cpus", "2"], stdout=subprocess.DEVNULL,
                            stderr=subprocess.PIPE, text=True, env=env, start_new_session=True)

    def committed() -> int:
        try:
            done = RunStore.open(run_dir).committed_generations()
        except StoreError:
            return -1
        return min(done.values()) if len(done) == 2 else -1

    try:
        deadline = time.monotonic() + 240
        while committed() < 2:
            assert proc.poll() is None, proc.stderr.read()[-2000:] if proc.stderr else ""
            assert time.monotonic() < deadline, "the run did not reach generation 2 in time"
            time.sleep(0.05)
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait(timeout=30)
    finally:
        with contextlib.suppress(ProcessLookupError, PermissionError):
            os.killpg(proc.pid, signal.SIGKILL)
        proc.wait(timeout=30)
    assert proc.returncode == -signal.SIGKILL
    summary = resume_run(str(run_dir), RunOptions(quiet=True), out=io.StringIO())
    assert summary.status == "complete"
    assert rows(run_dir) == rows(reference)


def test_a_two_node_cluster_gives_the_same_rows(reference, tmp_path):
    run_dir = tmp_path / "on-cluster"
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(HERE), os.environ.get("PYTHONPATH", "")]),
               RAY_USAGE_STATS_ENABLED="0")
    proc = subprocess.run([sys.executable, str(HERE / "tables_cluster_run.py"), str(run_dir)], env=env,
                          capture_output=True, text=True, timeout=400, start_new_session=True)
    assert proc.returncode == 0, proc.stderr[-3000:]
    report = json.loads(proc.stdout.strip().splitlines()[-1])
    assert report["status"] == "complete" and report["nodes"] == 2, report
    assert rows(run_dir) == rows(reference)


def test_show_regrows_a_table_bit_identically_and_the_report_shows_tables(reference, tmp_path):
    import trimesh

    from genr8_dist.cli import main
    from genr8_dist.history import top
    from genr8_dist.history.report import write_report

    best = top(reference, 1)["id"][0].as_py()
    for name in ("a", "b"):
        assert main(["show", str(reference), best, "-o", str(tmp_path / f"{name}.stl"),
                     "--png", str(tmp_path / f"{name}.png")]) == 0
    first, second = (tmp_path / "a.stl").read_bytes(), (tmp_path / "b.stl").read_bytes()
    assert first == second
    row = next(r for r in rows(reference) if r["id"] == best)
    mesh = trimesh.load(tmp_path / "a.stl")
    assert mesh.is_watertight and mesh.volume == pytest.approx(row["crit_voxels"])
    assert (tmp_path / "a.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    page = write_report(reference, tmp_path / "report.html").read_text()
    assert "The best tables of generation 4" in page and "table.obj" in page
