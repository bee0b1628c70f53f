"""Hosts write their islands' parts; the driver commits the manifest alone: parts that follow the
committed generations become the run's, exactly; a part of a lost epoch stays in _staging/, an
orphan garbage collection sweeps once it is stale; a part that skips generations or lost its file
is refused and nothing changes."""

from __future__ import annotations

import dataclasses
import os
import time

import pytest
from distributed_runs import new_run, tiny_toml

from genr8_dist.distributed.actors import IslandHost
from genr8_dist.distributed.coordinator import parse_config
from genr8_dist.errors import StoreError
from genr8_dist.store import TIMING_COLUMNS, RunStore
from genr8_dist.store.runstore import TMP_STALE_SECONDS


def _untimed(population):
    return [dataclasses.replace(ind, **dict.fromkeys(TIMING_COLUMNS, 0.0)) for ind in population]


def _host_with_generations(run_dir, island: int, last: int) -> tuple[IslandHost, list]:
    config = parse_config(tiny_toml(islands=2), "tiny")
    host = IslandHost(str(run_dir))
    rows = []
    for g in range(last + 1):
        host.advance(island, g, config if g == 0 else None, 1)
        rows += host.latest(island)
    return host, rows


def test_committed_parts_are_the_hosts_rows_and_an_orphan_is_swept(tmp_path):
    run_dir = tmp_path / "run"
    store = new_run(run_dir, tiny_toml(islands=2))
    host, rows = _host_with_generations(run_dir, 1, 2)
    part = host.flush(1)
    assert (part.islands, part.rows) == ({"1": [0, 2]}, 18)
    assert os.path.exists(run_dir / part.staged)
    before = store.manifest["individuals"]
    store.commit_parts([part])
    assert store.committed_generations() == {1: 2}
    assert len(store.manifest["individuals"]) == len(before) + 1
    assert _untimed(store.load_generation(1, 2)) == _untimed(rows[12:])

    # a lost epoch: generation 3 written by the host, never committed (the driver died)
    config_host, _ = _host_with_generations(run_dir, 0, 0)
    orphan = config_host.flush(0)
    assert os.path.exists(run_dir / orphan.staged)
    reopened = RunStore.open(run_dir)
    assert reopened.committed_generations() == {1: 2}          # not the run's: no manifest names it
    reopened.collect_garbage()
    assert os.path.exists(run_dir / orphan.staged)              # fresh: its host may still be writing
    old = time.time() - 2 * TMP_STALE_SECONDS
    os.utime(run_dir / orphan.staged, (old, old))
    assert reopened.collect_garbage() >= 1
    assert not os.path.exists(run_dir / orphan.staged)
    committed = [e["path"] for e in reopened.manifest["individuals"] if e["path"].endswith(part.name)]
    assert len(committed) == 1 and os.path.exists(run_dir / committed[0])
    assert reopened.verify() == []


def test_a_part_that_skips_generations_or_lost_its_file_is_refused(tmp_path):
    run_dir = tmp_path / "run"
    store = new_run(run_dir, tiny_toml(islands=2))
    host, _ = _host_with_generations(run_dir, 0, 1)
    part = host.flush(0)
    late = dataclasses.replace(part, islands={"0": [1, 1]})
    with pytest.raises(StoreError, match="next one to commit is 0"):
        store.commit_parts([late])
    os.remove(run_dir / part.staged)
    with pytest.raises(StoreError, match="missing"):
        store.commit_parts([part])
    assert RunStore.open(run_dir).committed_generations() == {}
