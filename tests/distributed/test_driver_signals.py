"""The driver as a user runs it (`genr8 run` in its own process): SIGINT and SIGTERM stop it cleanly
(exit 0, an interrupt event, a line saying how to resume); SIGKILL at any moment loses nothing that was
committed. Resumed, each run has exactly the rows of the uninterrupted run."""

from __future__ import annotations

import contextlib
import io
import os
import signal
import subprocess
import sys
import time

import pytest
from distributed_runs import drive_to_end, event_kinds, new_run, rows, tiny_toml

pytestmark = pytest.mark.slow

GENERATIONS = 12


@pytest.fixture(scope="module")
def reference(tmp_path_factory, ray_local):
    run_dir = tmp_path_factory.mktemp("ref") / "run"
    new_run(run_dir, tiny_toml(generations=GENERATIONS))
    drive_to_end(run_dir)
    return rows(run_dir)


def _start(tmp_path):
    config = tmp_path / "tiny.toml"
    config.write_text(tiny_toml(generations=GENERATIONS))
    run_dir = tmp_path / "run"
    env = dict(os.environ, RAY_USAGE_STATS_ENABLED="0")
    env.pop("RAY_ADDRESS", None)
    proc = subprocess.Popen(
        [sys.executable, "-m", "genr8_dist.cli", "run", str(config), "--run-dir", str(run_dir),
         "--cpus", "2"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env, start_new_session=True)
    return proc, run_dir


def _committed(run_dir) -> int:
    from genr8_dist.errors import StoreError
    from genr8_dist.store import RunStore

    try:
        done = RunStore.open(run_dir).committed_generations()
    except StoreError:
        return -1
    return min(done.values()) if len(done) == 3 else -1


def _wait_until(proc, run_dir, generation: int, timeout: float = 240.0) -> None:
    deadline = time.monotonic() + timeout
    while _committed(run_dir) < generation:
        assert proc.poll() is None, f"the run ended early: {proc.stderr.read()[-2000:]}"
        assert time.monotonic() < deadline, "the run did not reach the generation in time"
        time.sleep(0.05)


def _cleanup(proc) -> None:
    """Kill whatever is left of the driver's process group (its local Ray), by the group's id."""
    with contextlib.suppress(ProcessLookupError, PermissionError):
        os.killpg(proc.pid, signal.SIGKILL)
    proc.wait(timeout=30)


def _resume(run_dir) -> str:
    from genr8_dist.distributed.session import RunOptions, resume_run

    out = io.StringIO()
    summary = resume_run(str(run_dir), RunOptions(quiet=True), out=out)
    assert summary.status == "complete"
    return out.getvalue()


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_signal_stops_cleanly_and_resume_completes(reference, tmp_path, ray_local, sig):
    proc, run_dir = _start(tmp_path)
    try:
        _wait_until(proc, run_dir, 3)
        proc.send_signal(sig)
        out, err = proc.communicate(timeout=120)
    finally:
        _cleanup(proc)
    assert proc.returncode == 0, err[-2000:]
    assert f"genr8 resume {run_dir}" in out
    assert "interrupted" in out
    assert "interrupt" in event_kinds(run_dir)
    assert _committed(run_dir) < GENERATIONS
    _resume(run_dir)
    assert rows(run_dir) == reference


@pytest.mark.parametrize("at", [0, 4, 9])
def test_sigkill_of_the_driver_then_resume_gives_the_same_rows(reference, tmp_path, ray_local, at):
    proc, run_dir = _start(tmp_path)
    try:
        _wait_until(proc, run_dir, at)
        assert proc.poll() is None
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait(timeout=30)
    finally:
        _cleanup(proc)
    assert proc.returncode == -signal.SIGKILL
    _resume(run_dir)
    assert rows(run_dir) == reference
    assert "resume" in event_kinds(run_dir)


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_a_signal_after_the_last_commit_leaves_a_complete_run_and_exit_0(tmp_path, ray_local, sig):
    proc, run_dir = _start(tmp_path)
    try:
        _wait_until(proc, run_dir, GENERATIONS)
        proc.send_signal(sig)  # while the command shuts Ray down
        out, err = proc.communicate(timeout=120)
    finally:
        _cleanup(proc)
    assert proc.returncode == 0, err[-2000:]
    assert "run complete" in out and "Traceback" not in err



def test_a_signal_once_the_run_has_reported_leaves_exit_0(tmp_path, ray_local):
    """After "run complete" the command only exits (Ray's atexit shutdown, the interpreter's); a
    SIGTERM then changes nothing. Before the handlers were left ignored it killed the process: exit
    -15 in 3 of 3 tries."""
    proc, _ = _start(tmp_path)
    try:
        for line in proc.stdout:
            if "run complete" in line:
                proc.send_signal(signal.SIGTERM)
                break
        _, err = proc.communicate(timeout=120)
    finally:
        _cleanup(proc)
    assert proc.returncode == 0, err[-2000:]

def test_a_signal_during_start_up_stops_before_the_first_epoch(tmp_path, ray_local):
    from genr8_dist.distributed.reaper import _descendants, _table

    proc, run_dir = _start(tmp_path)
    try:
        deadline = time.monotonic() + 120
        while len(_descendants({proc.pid}, _table())) < 3 and time.monotonic() < deadline:
            time.sleep(0.02)  # until Ray's processes are starting (the reaper is the first child)
        proc.send_signal(signal.SIGTERM)
        out, err = proc.communicate(timeout=120)
    finally:
        _cleanup(proc)
    # stopped cleanly whenever it landed: during Ray's start-up (one line, 130: nothing was written),
    # or later (0, the run says how far it got)
    assert proc.returncode in (0, 130), err[-2000:]
    assert "Traceback" not in err
    assert "committed up to generation -1" not in out
    if proc.returncode == 130:
        assert err.strip() == "genr8: interrupted" and not run_dir.exists()
    else:
        assert "interrupted" in out or "run complete" in out
