"""cluster/local_cluster.sh: a head and a worker node on this machine, a run joining them with --address,
and stop removing exactly the nodes it started."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest
from distributed_runs import tiny_toml

pytestmark = [pytest.mark.cluster, pytest.mark.slow]

SCRIPT = Path(__file__).resolve().parents[2] / "cluster" / "local_cluster.sh"
PORT = "6397"


def test_start_run_on_it_and_stop(tmp_path):
    bindir = Path(sys.executable).parent
    env = dict(os.environ, GENR8_RAY_PORT=PORT, GENR8_CLUSTER_DIR=str(tmp_path / "state"),
               RAY=str(bindir / "ray"), PYTHON=sys.executable, RAY_USAGE_STATS_ENABLED="0",
               PATH=f"{bindir}{os.pathsep}{os.environ.get('PATH', '')}")
    env.pop("RAY_ADDRESS", None)
    started = subprocess.run(["bash", str(SCRIPT), "start", "1"], env=env, capture_output=True, text=True,
                             timeout=300)
    pids = [int(p.read_text()) for p in sorted((tmp_path / "state").glob("*.pid"))]
    try:
        assert started.returncode == 0, started.stderr[-2000:]
        assert f"address: 127.0.0.1:{PORT}" in started.stdout
        assert len(pids) == 2 and all(_alive(pid) for pid in pids)
        config = tmp_path / "tiny.toml"
        config.write_text(tiny_toml(islands=2, generations=3))
        run = subprocess.run([sys.executable, "-m", "genr8_dist.cli", "run", str(config), "--run-dir",
                              str(tmp_path / "run"), "--address", f"127.0.0.1:{PORT}", "--quiet"],
                             env=env, capture_output=True, text=True, timeout=300)
        assert run.returncode == 0, run.stderr[-2000:]
        assert "run complete" in run.stdout
    finally:
        stopped = subprocess.run(["bash", str(SCRIPT), "stop"], env=env, capture_output=True, text=True,
                                 timeout=120)
    assert stopped.returncode == 0 and "stopped 2 Ray node(s)" in stopped.stdout
    assert not any(_alive(pid) for pid in pids)
    assert not list((tmp_path / "state").glob("*.pid"))


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    return True
