"""A plugin universe reaches a cluster with the run: on a simulated 2-node cluster whose workers run in
another directory without ``GENR8_PLUGINS``, the run completes with the rows of the local run."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest
from distributed_runs import rows
from plugin_universe import make_plugin

pytestmark = [pytest.mark.cluster, pytest.mark.slow]

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent.parent

CONFIG = """\
universe = "selfsim"
seed = 11

[genome]
length = 40
max_depth = 4

[ea]
population = 6
generations = 4
tournament = 2

[environment]
steps = 2

[islands]
count = 2
migration_interval = 2
migrants = 1
"""


def _env(**extra: str) -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if k not in ("GENR8_PLUGINS", "RAY_ADDRESS")}
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT), str(HERE)])
    env["RAY_USAGE_STATS_ENABLED"] = "0"
    env.update(extra)
    return env


def test_a_plugin_universe_runs_on_nodes_that_never_saw_it(tmp_path):
    driver = tmp_path / "driver"
    make_plugin(driver / "myplugins")
    (driver / "run.toml").write_text(CONFIG)
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()

    local = subprocess.run(
        [sys.executable, "-m", "genr8_dist.cli", "run", "run.toml", "--run-dir", str(tmp_path / "local"),
         "--cpus", "2", "--quiet"],
        cwd=driver, env=_env(GENR8_PLUGINS="myplugins", GENR8_TRUST_FILE=str(tmp_path / "trust")),
        capture_output=True, text=True, timeout=300)
    assert local.returncode == 0, local.stderr[-2000:]

    proc = subprocess.run([sys.executable, str(HERE / "plugin_cluster_run.py"), str(tmp_path)],
                          cwd=elsewhere, env=_env(), capture_output=True, text=True, timeout=500,
                          start_new_session=True)
    assert proc.returncode == 0, proc.stderr[-3000:]
    report = json.loads(proc.stdout.strip().splitlines()[-1])
    assert report["status"] == 0, report["stderr"][-2000:]
    assert "run complete: generations 0..4 of 2 island(s)" in report["stdout"]
    assert report["nodes"] == 2 and report["workers"]
    for cwd, plugins in report["workers"]:   # the islands' hosts: another directory, no plugin path
        assert plugins is None
        assert Path(cwd).resolve() != driver.resolve()
    cluster_rows = rows(tmp_path / "on-cluster")
    assert len(cluster_rows) == 2 * 6 * 5
    assert all("Angle 45" in r["text"] for r in cluster_rows if r["text"])   # the plugin's hook ran
    assert cluster_rows == rows(tmp_path / "local")
