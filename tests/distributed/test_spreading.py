"""Every CPU used: a run has one host per CPU whatever its islands, and the hosts that hold no island
evaluate genomes of the others' generations without changing a row."""

from __future__ import annotations

import time

import pytest
from distributed_runs import drive_to_end, new_run, rows, tiny_toml

pytestmark = pytest.mark.usefixtures("ray_local")


def _wait_for_both_cpus(timeout: float = 30.0) -> None:
    """The hosts of the tests before this one may hold a CPU a moment after their pool shut down; a
    pool sized then would start 1 host, not the 2 this test is about."""
    import ray

    deadline = time.monotonic() + timeout
    while ray.available_resources().get("CPU", 0.0) < 2 and time.monotonic() < deadline:
        time.sleep(0.1)


def test_one_island_spread_over_two_hosts_has_the_rows_of_one_host(tmp_path):
    """A 1-island run on the session's 2 CPUs starts 2 hosts: the one holding no island evaluates
    batches of the other's generations; the rows equal those one host computes alone."""
    from genr8_dist.distributed.actors import IslandHost
    from genr8_dist.distributed.coordinator import parse_config
    from genr8_dist.distributed.hosts import HostPool

    toml = tiny_toml(islands=1, generations=4)
    spread = tmp_path / "spread"
    new_run(spread, toml)
    _wait_for_both_cpus()
    pool = HostPool(str(spread), 1)
    try:
        assert pool.size == 2 and pool.islands_on(1) == []
        summary, _ = drive_to_end(spread, pool)
        assert summary.status == "complete"
        assert pool.helped() > 0
    finally:
        pool.shutdown()

    alone = tmp_path / "alone"
    store = new_run(alone, toml)
    host = IslandHost(str(alone))
    config = parse_config(toml, "tiny")
    for g in range(5):
        done = host.advance(0, g, config if g == 0 else None, 1, write=True)
        store.commit_parts([done.part])
    assert rows(spread) == rows(alone)
