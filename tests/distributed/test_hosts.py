"""Sizing the island hosts: one per free CPU whatever the islands (hosts with no island help the
others); islands may outnumber CPUs; no free CPU is refused, not left waiting."""

from __future__ import annotations

import pytest

from genr8_dist.distributed.hosts import plan_hosts
from genr8_dist.errors import RunError


def test_one_host_per_cpu_even_with_fewer_islands():
    plan = plan_hosts(3, free_cpus=8)
    assert (plan.hosts, plan.num_cpus) == (8, 1.0)


def test_islands_outnumbering_cpus_share_hosts():
    plan = plan_hosts(8, free_cpus=2)
    assert (plan.hosts, plan.num_cpus) == (2, 1.0)


def test_less_than_one_free_cpu_reserves_a_fraction():
    plan = plan_hosts(4, free_cpus=0.5)
    assert (plan.hosts, plan.num_cpus) == (1, 0.5)


def test_max_hosts_caps_the_pool():
    assert plan_hosts(4, free_cpus=16, max_hosts=1).hosts == 1


def test_no_free_cpu_is_refused_with_a_message():
    with pytest.raises(RunError, match="no free CPU for 3 island"):
        plan_hosts(3, free_cpus=0)


def test_a_run_asking_a_cluster_for_more_cpus_than_are_free_waits_then_uses_what_is_free(monkeypatch):
    """``cpus`` beyond the free CPUs: the autoscaler is asked for them, the pool waits, then sizes
    itself to what is free (here nothing comes: no autoscaler)."""
    import ray

    from genr8_dist.distributed import hosts

    asked = []
    monkeypatch.setattr(ray, "available_resources", lambda: {"CPU": 3.0})
    monkeypatch.setattr(hosts.time, "sleep", lambda s: asked.append(s))
    clock = iter(range(0, 1000, 10))
    monkeypatch.setattr(hosts.time, "monotonic", lambda: next(clock))
    assert hosts.HostPool._ask_for(16, timeout=30.0) == 3.0
    assert len(asked) >= 2   # it waited (seconds of the fake clock) before giving up


def test_hosts_of_several_cpus_each_evaluate_that_many_at_once():
    plan = plan_hosts(256, free_cpus=64, host_cpus=8)
    assert (plan.hosts, plan.num_cpus, plan.slots) == (8, 8.0, 8)
    assert plan_hosts(4, free_cpus=3, host_cpus=4) == plan_hosts(4, free_cpus=3, host_cpus=3)
    with pytest.raises(RunError, match="host_cpus=0"):
        plan_hosts(4, free_cpus=8, host_cpus=0)
