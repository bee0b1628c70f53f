"""Run the tables configuration of test_tables_run.py on a simulated 2-node Ray cluster.

    python tests/distributed/tables_cluster_run.py RUN_DIR

Started by test_tables_run.py in its own process (one Ray per process). Prints one JSON line: the
run's status and how many nodes the cluster had.
"""

from __future__ import annotations

import io
import json
import sys


def main(run_dir: str) -> int:
    import ray
    from ray.cluster_utils import Cluster
    from test_tables_run import TABLES_TOML, new_tables_run

    from genr8_dist.distributed.session import RunOptions, drive
    from genr8_dist.store import RunStore

    cluster = Cluster(initialize_head=True, head_node_args={"num_cpus": 1})
    cluster.add_node(num_cpus=1)
    try:
        ray.init(address=cluster.address, log_to_driver=False, logging_level="ERROR")
        cluster.wait_for_nodes()
        nodes = sum(1 for n in ray.nodes() if n["Alive"])
        new_tables_run(run_dir, TABLES_TOML)
        out = io.StringIO()
        summary = drive(RunStore.open(run_dir), RunOptions(quiet=False, max_hosts=2), out=out)
        print(json.dumps({"status": summary.status, "nodes": nodes, "hosts": summary.hosts}))
    finally:
        ray.shutdown()
        cluster.shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1]))
