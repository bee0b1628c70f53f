"""`ray job submit` of a run with a plugin universe, through cluster/local_cluster.sh: the job finds the
plugin in its working directory, the run carries it to the nodes, and the rows equal the local run's.
The submit line the script prints is the one that works (with the cluster's RAY_AUTH_MODE)."""

from __future__ import annotations

import json
import os
import re
import shlex
import subprocess
import sys
import time
from pathlib import Path

import pytest
from distributed_runs import rows
from plugin_universe import make_plugin

pytestmark = [pytest.mark.cluster, pytest.mark.slow]

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[1]
SCRIPT = ROOT / "cluster" / "local_cluster.sh"
PORT, DASHBOARD = "6396", "8296"

CONFIG = """\
universe = "plugins/selfsim"
seed = 4

[genome]
length = 40
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


def _dashboard_installed() -> bool:
    try:
        from ray._private.utils import get_dashboard_dependency_error
    except ImportError:
        return False
    return get_dashboard_dependency_error() is None


@pytest.mark.skipif(not _dashboard_installed(), reason="`ray job submit` needs Ray's dashboard: install "
                    "the `cluster` extra (ray[default])")
def test_a_plugin_run_submitted_as_a_ray_job(tmp_path):
    bindir = Path(sys.executable).parent
    env = {k: v for k, v in os.environ.items() if k not in ("RAY_ADDRESS", "GENR8_PLUGINS")}
    env.update(GENR8_RAY_PORT=PORT, GENR8_DASHBOARD="1", GENR8_DASHBOARD_PORT=DASHBOARD,
               GENR8_CLUSTER_DIR=str(tmp_path / "state"), RAY=str(bindir / "ray"), PYTHON=sys.executable,
               RAY_USAGE_STATS_ENABLED="0", PATH=f"{bindir}{os.pathsep}{env.get('PATH', '')}",
               PYTHONPATH=str(ROOT), GENR8_TRUST_FILE=str(tmp_path / "trust"))
    job = tmp_path / "job"
    make_plugin(job / "plugins")
    (job / "run.toml").write_text(CONFIG)
    local = subprocess.run([sys.executable, "-m", "genr8_dist.cli", "run", "run.toml", "--run-dir",
                            str(tmp_path / "local"), "--cpus", "2", "--quiet", "--trust-hooks"],
                           cwd=job, env=env, capture_output=True, text=True, timeout=300)
    assert local.returncode == 0, local.stderr[-2000:]   # the user's consent, remembered for the job

    started = subprocess.run(["bash", str(SCRIPT), "start", "1"], env=env, capture_output=True, text=True,
                             timeout=300)
    try:
        assert started.returncode == 0, started.stderr[-2000:] + started.stdout[-2000:]
        (line,) = [x for x in started.stdout.splitlines() if x.startswith("or submit:")]
        words = shlex.split(line[len("or submit:"):])
        auth = env.get("RAY_AUTH_MODE") or (
            "token" if Path(env.get("RAY_AUTH_TOKEN_PATH", Path.home() / ".ray" / "auth_token")).is_file()
            else None)
        if auth:   # the line to copy says how `ray job submit` must authenticate
            assert words[0] == f"RAY_AUTH_MODE={auth}"
        assignments = dict(w.split("=", 1) for w in words if re.fullmatch(r"[A-Z_]+=\S*", w))
        rest = words[len(assignments):]
        assert rest[:3] == ["ray", "job", "submit"] and rest[3:5] == ["--address", f"http://127.0.0.1:{DASHBOARD}"]
        runtime = {"env_vars": {"PYTHONPATH": str(ROOT), "GENR8_TRUST_FILE": str(tmp_path / "trust"),
                                "RAY_USAGE_STATS_ENABLED": "0"}}
        submit = [str(bindir / "ray"), *rest[1:5], "--working-dir", str(job), "--runtime-env-json",
                  json.dumps(runtime), "--", sys.executable, "-m", "genr8_dist.cli", "run", "run.toml",
                  "--run-dir", str(tmp_path / "on-cluster"), "--quiet"]
        job_env = dict(env, **assignments)
        for _ in range(24):   # the head's job agent registers a few seconds after the dashboard answers
            done = subprocess.run(submit, env=job_env, capture_output=True, text=True, timeout=400)
            if "No available agent to submit job" not in done.stdout + done.stderr:
                break
            time.sleep(5)
        assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-2000:]
        assert "run complete: generations 0..3 of 2 island(s)" in done.stdout
    finally:
        subprocess.run(["bash", str(SCRIPT), "stop"], env=env, capture_output=True, text=True, timeout=120)
    cluster_rows = rows(tmp_path / "on-cluster")
    assert len(cluster_rows) == 2 * 6 * 4
    assert all("Angle 45" in r["text"] for r in cluster_rows if r["text"])
    assert cluster_rows == rows(tmp_path / "local")
