"""`genr8 run`, `genr8 resume` and `genr8 edit` in-process: outcomes a user sees, and bad input that is
refused with one line, a non-zero exit and the run directory exactly as it was."""

from __future__ import annotations

import hashlib
import os
from pathlib import Path

import pytest

from genr8_dist.cli import main

CONFIG = """\
universe = "default"
seed = 3

[genome]
length = 30
max_depth = 4

[ea]
population = 6
generations = 3
tournament = 2

[environment]
steps = 2

[islands]
count = 2
migration_interval = 2
migrants = 1
"""


def _snapshot(root: Path) -> dict[str, str]:
    """Every file under ``root`` with its content hash (to show a directory is unchanged)."""
    return {str(p.relative_to(root)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(root.rglob("*")) if p.is_file()}


@pytest.fixture(scope="module")
def finished_run(tmp_path_factory, ray_local):
    """A complete 2-island run made with `genr8 run`, and what it printed."""
    root = tmp_path_factory.mktemp("cli")
    config = root / "run.toml"
    config.write_text(CONFIG)
    run_dir = root / "run"
    capture = root / "out.txt"
    import contextlib
    import signal

    handlers = {sig: signal.getsignal(sig) for sig in (signal.SIGINT, signal.SIGTERM)}
    with open(capture, "w") as out, contextlib.redirect_stdout(out):
        status = main(["run", str(config), "--run-dir", str(run_dir)])
    # called with its arguments, not as the process's command: the signal handlers are left as they
    # were (the process's own `genr8 run` leaves them ignored once its run returns, since it exits)
    assert {sig: signal.getsignal(sig) for sig in handlers} == handlers
    return status, run_dir, capture.read_text(), config


def test_run_completes_and_says_where_the_results_are(finished_run):
    status, run_dir, out, _ = finished_run
    assert status == 0
    assert "gen 3/3" in out
    assert "run complete" in out and f"results: {run_dir}" in out
    from genr8_dist.store import RunStore

    store = RunStore.open(run_dir)
    assert store.committed_generations() == {0: 3, 1: 3}
    assert store.individuals().num_rows == 2 * 6 * 4


def test_run_refuses_to_overwrite_a_run(finished_run, capsys):
    _, run_dir, _, config = finished_run
    before = _snapshot(run_dir)
    assert main(["run", str(config), "--run-dir", str(run_dir), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("genr8: error:") and "already holds a run" in err and len(err.splitlines()) == 1
    assert _snapshot(run_dir) == before


def test_resume_of_a_complete_run_changes_nothing(finished_run, capsys):
    _, run_dir, _, _ = finished_run
    before = _snapshot(run_dir)
    assert main(["resume", str(run_dir)]) == 0
    assert "nothing to resume" in capsys.readouterr().out
    assert _snapshot(run_dir) == before


def test_resume_of_a_directory_that_is_not_a_run(tmp_path, capsys):
    (tmp_path / "notes.txt").write_text("hello")
    before = _snapshot(tmp_path)
    assert main(["resume", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert "not a run directory" in err and len(err.splitlines()) == 1
    assert _snapshot(tmp_path) == before


@pytest.mark.parametrize("extra", [[], ["--generations", "1"]])
def test_edit_setting_a_table_to_a_value_names_the_key(finished_run, capsys, extra):
    _, run_dir, _, _ = finished_run
    before = _snapshot(run_dir)
    assert main(["edit", str(run_dir), "--set", "ea=1", *extra]) == 2
    err = capsys.readouterr().err
    assert err.startswith("genr8: error: --set ea=1: 'ea' is a table of settings (")
    assert len(err.splitlines()) == 1
    assert "not a key; set one of them, e.g. --set ea." in err and "--generations" not in err
    assert _snapshot(run_dir) == before


def test_edit_with_an_unknown_key_names_it(finished_run, capsys):
    _, run_dir, _, _ = finished_run
    before = _snapshot(run_dir)
    assert main(["edit", str(run_dir), "--set", "ea.mutaton_rate=0.1"]) == 2
    err = capsys.readouterr().err
    assert "ea.mutaton_rate" in err and len(err.splitlines()) == 1
    assert _snapshot(run_dir) == before


def test_edit_injecting_text_the_universe_cannot_invert(finished_run, tmp_path, capsys):
    _, run_dir, _, _ = finished_run
    text = tmp_path / "system.hemls"
    text.write_text("this is not a rewrite system\n")
    before = _snapshot(run_dir)
    assert main(["edit", str(run_dir), "--inject-text", str(text)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("genr8: error:") and len(err.splitlines()) == 1
    assert _snapshot(run_dir) == before


def test_edit_records_a_version_then_resume_runs_it(finished_run, tmp_path, capsys):
    import shutil

    _, run_dir, _, _ = finished_run
    copy = tmp_path / "copy"
    shutil.copytree(run_dir, copy)
    assert main(["edit", str(copy), "--set", "fitness.size.weight=3", "--generations", "1",
                 "--inject-copy", "0-3-0"]) == 0
    out = capsys.readouterr().out
    assert "configuration version 2 in force from generation 4" in out
    assert f"genr8 resume {copy}" in out
    assert main(["resume", str(copy), "--quiet"]) == 0
    from genr8_dist.store import RunStore

    store = RunStore.open(copy)
    assert store.committed_generations() == {0: 4, 1: 4}
    table = store.individuals(columns=["generation", "origin", "config_version"]).to_pylist()
    assert {r["config_version"] for r in table if r["generation"] == 4} == {2}
    assert sum(1 for r in table if r["origin"] == "injected") == 1


def test_address_that_answers_nothing(tmp_path, capsys):
    config = tmp_path / "run.toml"
    config.write_text(CONFIG)
    run_dir = tmp_path / "run"
    status = main(["run", str(config), "--run-dir", str(run_dir), "--address", "127.0.0.1:9"])
    err = capsys.readouterr().err
    assert status == 2 and "127.0.0.1:9" in err and len(err.splitlines()) == 1
    assert not run_dir.exists()


def test_missing_configuration_file(tmp_path, capsys):
    assert main(["run", str(tmp_path / "nope.toml"), "--run-dir", str(tmp_path / "r")]) == 2
    assert "nope.toml" in capsys.readouterr().err
    assert not os.path.exists(tmp_path / "r")
