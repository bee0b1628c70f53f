"""The island host without Ray: it advances islands, keeps configurations it was sent, and a new host
rebuilds an island from the run store exactly."""

from __future__ import annotations

import dataclasses

import pytest
from distributed_runs import new_run, tiny_toml

from genr8_dist.distributed.actors import IslandHost
from genr8_dist.distributed.coordinator import parse_config
from genr8_dist.store import TIMING_COLUMNS, RunStore


def _untimed(population):
    return [dataclasses.replace(ind, **dict.fromkeys(TIMING_COLUMNS, 0.0)) for ind in population]


def test_a_new_host_rebuilds_an_island_from_the_store(tmp_path):
    run_dir = tmp_path / "run"
    store = new_run(run_dir, tiny_toml(islands=2))
    config = parse_config(tiny_toml(islands=2), "tiny")
    host = IslandHost(str(run_dir))
    gen0 = host.advance(1, 0, config, 1)
    assert [ind.id for ind in gen0] == [f"1-0-{i}" for i in range(6)]
    store.commit(gen0)
    gen1 = host.advance(1, 1, None, 1)            # the host kept the configuration and generation 0
    assert {ind.generation for ind in gen1} == {1}

    fresh = IslandHost(str(run_dir))              # lost everything: reads generation 0 from the store
    with pytest.raises(RuntimeError, match="configuration version 1"):
        fresh.advance(1, 1, None, 1)
    again = fresh.advance(1, 1, config, 1)
    assert _untimed(again) == _untimed(gen1)
    assert RunStore.open(run_dir).committed_generations() == {1: 0}
