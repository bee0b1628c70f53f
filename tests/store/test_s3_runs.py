"""Real runs (`genr8 run` in its own process) on a local S3-compatible server: the same rows as the run on a
local disk, a SIGKILLed driver resumed to the same rows, and two drivers on one run: one runs, the other
is refused with one line, and nothing is damaged."""

from __future__ import annotations

import contextlib
import io
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).parents[1] / "distributed"))
from distributed_runs import drive_to_end, event_kinds, new_run, rows, tiny_toml

from genr8_dist.errors import RunError, StoreError
from genr8_dist.store import RunStore

pytestmark = [pytest.mark.slow, pytest.mark.timeout(600)]
pytest.importorskip("boto3")

GENERATIONS = 8


@pytest.fixture(scope="module")
def reference(tmp_path_factory, ray_local):
    run_dir = tmp_path_factory.mktemp("ref") / "run"
    new_run(run_dir, tiny_toml(generations=GENERATIONS))
    drive_to_end(run_dir)
    return rows(run_dir)


def _genr8(*args: str) -> subprocess.Popen:
    env = dict(os.environ, RAY_USAGE_STATS_ENABLED="0")
    env.pop("RAY_ADDRESS", None)
    return subprocess.Popen([sys.executable, "-m", "genr8_dist.cli", *args], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, env=env, start_new_session=True)


def _config(tmp_path) -> str:
    config = tmp_path / "tiny.toml"
    config.write_text(tiny_toml(generations=GENERATIONS))
    return str(config)


def _committed(uri: str) -> int:
    try:
        done = RunStore.open(uri).committed_generations()
    except StoreError:
        return -1
    return min(done.values()) if len(done) == 3 else -1


def _cleanup(proc) -> None:
    """Kill whatever is left of a driver's process group (its local Ray), by the group's id."""
    with contextlib.suppress(ProcessLookupError, PermissionError):
        os.killpg(proc.pid, signal.SIGKILL)
    proc.wait(timeout=30)


def test_a_run_on_s3_equals_the_same_run_on_disk(reference, s3_server, tmp_path):
    uri = s3_server.uri(s3_server.bucket(), "runs/plain")
    proc = _genr8("run", _config(tmp_path), "--run-dir", uri, "--cpus", "2", "--quiet")
    try:
        _, err = proc.communicate(timeout=400)
    finally:
        _cleanup(proc)
    assert proc.returncode == 0, err[-2000:]
    store = RunStore.open(uri)
    assert store.verify() == []
    assert store.running() is None                    # the lease was given back
    assert rows(uri) == reference
    assert len(reference) == 3 * 6 * (GENERATIONS + 1)


def test_a_killed_driver_on_s3_resumes_to_the_same_rows(reference, s3_server, tmp_path, ray_local):
    from genr8_dist.distributed.session import RunOptions, resume_run

    uri = s3_server.uri(s3_server.bucket(), "runs/killed")
    proc = _genr8("run", _config(tmp_path), "--run-dir", uri, "--cpus", "2", "--quiet")
    try:
        deadline = time.monotonic() + 300
        while _committed(uri) < 3:
            assert proc.poll() is None, proc.stderr.read()[-2000:]
            assert time.monotonic() < deadline, "the run did not reach generation 3 in time"
            time.sleep(0.2)
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait(timeout=30)
    finally:
        _cleanup(proc)
    assert RunStore.open(uri).running() is None       # its holder is gone from this machine: free now
    summary = resume_run(uri, RunOptions(quiet=True), out=io.StringIO())
    assert summary.status == "complete"
    assert RunStore.open(uri).verify() == []
    assert rows(uri) == reference
    assert "resume" in event_kinds(uri)


def test_two_drivers_on_one_s3_run_one_is_refused_and_nothing_is_damaged(reference, s3_server, tmp_path,
                                                                        ray_local):
    from genr8_dist.distributed.session import RunOptions, resume_run

    uri = s3_server.uri(s3_server.bucket(), "runs/two")
    config = _config(tmp_path)
    drivers = [_genr8("run", config, "--run-dir", uri, "--cpus", "1", "--quiet") for _ in range(2)]
    try:
        deadline = time.monotonic() + 300
        while _committed(uri) < 0 or RunStore.open(uri).running() is None:
            assert time.monotonic() < deadline, "no driver started in time"
            assert any(d.poll() is None for d in drivers), [d.stderr.read() for d in drivers]
            time.sleep(0.2)
        with pytest.raises(RunError, match="the run is running already") as refused:
            resume_run(uri, RunOptions(quiet=True), out=io.StringIO())   # a third driver, meanwhile
        assert "\n" not in str(refused.value)
        results = [d.communicate(timeout=400) for d in drivers]
    finally:
        for d in drivers:
            _cleanup(d)
    codes = sorted(d.returncode for d in drivers)
    assert codes == [0, 2], [r[1][-2000:] for r in results]
    loser = results[[d.returncode for d in drivers].index(2)][1]
    assert loser.startswith("genr8: error: ") and loser.count("\n") == 1, loser
    store = RunStore.open(uri)
    assert store.verify() == []
    assert store.collect_garbage() == 0               # the loser left no file behind
    assert rows(uri) == reference
    assert event_kinds(uri).count("start") == 1
