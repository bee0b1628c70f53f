"""The run's start event records the Ray cluster it actually joined: the GCS address of a cluster joined
by --address or by RAY_ADDRESS (``ray job submit``), "local" for a Ray the command started itself."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from genr8_dist.distributed.session import joined_address

HERE = Path(__file__).resolve().parent


def test_a_ray_of_its_own_is_recorded_as_local(monkeypatch):
    monkeypatch.delenv("RAY_ADDRESS", raising=False)
    assert joined_address(None) == "local"


@pytest.mark.slow
@pytest.mark.cluster
def test_the_start_event_records_the_cluster_joined(tmp_path):
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(HERE), os.environ.get("PYTHONPATH", "")]),
               RAY_USAGE_STATS_ENABLED="0")
    env.pop("RAY_ADDRESS", None)
    proc = subprocess.run([sys.executable, str(HERE / "address_run.py"), str(tmp_path)], env=env,
                          capture_output=True, text=True, timeout=400, start_new_session=True)
    assert proc.returncode == 0, proc.stderr[-3000:]
    report = json.loads(proc.stdout.strip().splitlines()[-1])
    assert report["status"] == ["complete", "complete"]
    assert report["cluster"] and report["cluster"] != "local"
    assert report["flag"]["address"] == report["cluster"]
    assert report["env"]["address"] == report["cluster"]
