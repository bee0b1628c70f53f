"""A plugin universe on a simulated 2-node Ray cluster whose nodes have never seen the plugin.

    python tests/distributed/plugin_cluster_run.py WORK_DIR

Started by test_plugin_cluster.py with its working directory elsewhere and no ``GENR8_PLUGINS``: this
process starts a ``ray.cluster_utils.Cluster`` (a head with no CPU for islands, a worker node with 2),
so every Ray worker inherits that environment. The driver, ``genr8 run --address``, runs in
``WORK_DIR/driver`` where the plugin lives (``GENR8_PLUGINS=myplugins``, a relative path). Prints one
JSON line: the driver's exit status and output, and each node's working directory and
``GENR8_PLUGINS`` as its Ray workers see them.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path


def main(work: str) -> int:
    os.environ["RAY_AUTH_MODE"] = "disabled"   # the same for the cluster and the driver
    import ray
    from ray.cluster_utils import Cluster
    from ray.util.scheduling_strategies import NodeAffinitySchedulingStrategy

    driver_dir = Path(work) / "driver"
    cluster = Cluster(initialize_head=True, head_node_args={"num_cpus": 0})
    cluster.add_node(num_cpus=2)
    try:
        cluster.wait_for_nodes()
        env = dict(os.environ, GENR8_PLUGINS="myplugins", GENR8_TRUST_FILE=str(Path(work) / "trust"))
        proc = subprocess.run(
            [sys.executable, "-m", "genr8_dist.cli", "run", "run.toml", "--run-dir",
             str(Path(work) / "on-cluster"), "--address", cluster.address, "--quiet"],
            cwd=driver_dir, env=env, capture_output=True, text=True, timeout=300)

        ray.init(address=cluster.address, log_to_driver=False, logging_level="ERROR")

        @ray.remote(num_cpus=1)
        def where() -> tuple[str, str | None]:
            return os.getcwd(), os.environ.get("GENR8_PLUGINS")

        nodes = [n for n in ray.nodes() if n["Alive"] and n["Resources"].get("CPU", 0) > 0]
        seen = [ray.get(where.options(scheduling_strategy=NodeAffinitySchedulingStrategy(
            n["NodeID"], soft=False)).remote()) for n in nodes]
        print(json.dumps({"status": proc.returncode, "stdout": proc.stdout, "stderr": proc.stderr,
                          "workers": seen, "nodes": len(ray.nodes())}))
    finally:
        ray.shutdown()
        cluster.shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1]))
