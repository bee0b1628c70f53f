"""Run the tiny configuration on a simulated 2-node Ray cluster and remove a node mid-run.

    python tests/distributed/cluster_run.py RUN_DIR

Started by test_cluster.py in its own process (one Ray per process: the test session already has
one). Prints one JSON line: the run's status, recoveries and where the islands' hosts ran.
"""

from __future__ import annotations

import io
import json
import sys


def main(run_dir: str) -> int:
    import ray
    from distributed_runs import new_run, tiny_toml
    from ray.cluster_utils import Cluster

    from genr8_dist.distributed.session import RunOptions, drive
    from genr8_dist.store import RunStore

    cluster = Cluster(initialize_head=True, head_node_args={"num_cpus": 2})
    worker = cluster.add_node(num_cpus=2)
    try:
        ray.init(address=cluster.address, log_to_driver=False, logging_level="ERROR")
        cluster.wait_for_nodes()
        nodes_before = sum(1 for n in ray.nodes() if n["Alive"])
        new_run(run_dir, tiny_toml())
        removed: list[int] = []

        def remove_worker(coordinator, generation):
            if generation == 3 and not removed:
                removed.append(generation)
                cluster.remove_node(worker)

        out = io.StringIO()
        summary = drive(RunStore.open(run_dir), RunOptions(quiet=False, max_hosts=4), out=out,
                        on_generation=remove_worker)
        nodes_after = sum(1 for n in ray.nodes() if n["Alive"])
        print(json.dumps({"status": summary.status, "recoveries": summary.recoveries,
                          "hosts": summary.hosts, "removed_at": removed, "nodes_before": nodes_before,
                          "nodes_after": nodes_after, "log": out.getvalue()}))
    finally:
        ray.shutdown()
        cluster.shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1]))
