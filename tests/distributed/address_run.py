"""Start a short run on a simulated Ray cluster (ray.cluster_utils.Cluster), joined once by --address and
once by RAY_ADDRESS (what ``ray job submit`` sets), and print what each run's start event recorded.

    python tests/distributed/address_run.py WORK_DIR

Started by test_start_address.py in its own process (one Ray per process). Prints one JSON line.
"""

from __future__ import annotations

import io
import json
import os
import sys
from pathlib import Path


def _start_detail(run_dir: Path) -> dict:
    from genr8_dist.store import RunStore

    events = RunStore.open(run_dir).events()
    for kind, detail in zip(events.column("kind").to_pylist(), events.column("detail").to_pylist(),
                            strict=True):
        if kind == "start":
            return json.loads(detail) if isinstance(detail, str) else dict(detail)
    raise AssertionError("no start event")


def main(work: str) -> int:
    from distributed_runs import tiny_toml
    from ray.cluster_utils import Cluster

    from genr8_dist.distributed.session import RunOptions, start_run

    base = Path(work)
    config = base / "tiny.toml"
    config.write_text(tiny_toml(islands=2, generations=2))
    cluster = Cluster(initialize_head=True, head_node_args={"num_cpus": 2})
    try:
        by_flag = start_run(config, str(base / "by-flag"), RunOptions(address=cluster.address, quiet=True),
                            out=io.StringIO())
        os.environ["RAY_ADDRESS"] = cluster.address
        by_env = start_run(config, str(base / "by-env"), RunOptions(quiet=True), out=io.StringIO())
        print(json.dumps({"cluster": cluster.gcs_address, "status": [by_flag.status, by_env.status],
                          "flag": _start_detail(base / "by-flag"), "env": _start_detail(base / "by-env")}))
    finally:
        cluster.shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1]))
