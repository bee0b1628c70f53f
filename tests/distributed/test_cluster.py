"""A simulated 2-node Ray cluster (ray.cluster_utils.Cluster) runs the same configuration and, after a
node is removed mid-run, completes with the rows of the single-machine run."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest
from distributed_runs import drive_to_end, event_kinds, new_run, rows, tiny_toml

pytestmark = [pytest.mark.cluster, pytest.mark.slow]

HERE = Path(__file__).resolve().parent


def test_two_node_cluster_losing_a_node_gives_identical_rows(tmp_path, ray_local):
    reference = tmp_path / "reference"
    new_run(reference, tiny_toml())
    drive_to_end(reference)

    run_dir = tmp_path / "on-cluster"
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(HERE), os.environ.get("PYTHONPATH", "")]),
               RAY_USAGE_STATS_ENABLED="0")
    proc = subprocess.run([sys.executable, str(HERE / "cluster_run.py"), str(run_dir)], env=env,
                          capture_output=True, text=True, timeout=400, start_new_session=True)
    assert proc.returncode == 0, proc.stderr[-3000:]
    report = json.loads(proc.stdout.strip().splitlines()[-1])
    assert report["status"] == "complete", report
    assert report["nodes_before"] == 2 and report["nodes_after"] == 1
    assert report["removed_at"] == [3]
    assert report["recoveries"] >= 1, report["log"]
    assert "recovery" in event_kinds(run_dir)
    assert rows(run_dir) == rows(reference)
