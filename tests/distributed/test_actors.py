"""The island host: it advances islands, keeps configurations it was sent, a new host rebuilds an
island from the run store exactly, and idle hosts (Ray actors) evaluate batches of a generation's
genomes without changing it."""

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
    done = host.advance(1, 0, config, 1, write=True)   # the host writes generation 0's part itself
    gen0 = host.latest(1)
    assert [ind.id for ind in gen0] == [f"1-0-{i}" for i in range(6)]
    assert done.fitness == tuple(ind.fitness for ind in gen0)
    assert (done.part.islands, done.part.rows) == ({"1": [0, 0]}, 6)
    store.commit_parts([done.part])                     # the driver's commit: the manifest alone
    assert _untimed(store.load_generation(1, 0)) == _untimed(gen0)
    assert host.advance(1, 1, None, 1).part is None     # the host kept the configuration and generation 0
    gen1 = host.latest(1)
    assert {ind.generation for ind in gen1} == {1}

    fresh = IslandHost(str(run_dir))              # lost everything: reads generation 0 from the store
    with pytest.raises(RuntimeError, match="configuration version 1"):
        fresh.advance(1, 1, None, 1)
    fresh.advance(1, 1, config, 1)
    assert _untimed(fresh.latest(1)) == _untimed(gen1)
    assert RunStore.open(run_dir).committed_generations() == {1: 0}


def test_one_call_for_an_epoch_builds_what_a_call_a_generation_builds(tmp_path):
    from genr8_dist.distributed.actors import Step

    run_dir = tmp_path / "run"
    new_run(run_dir, tiny_toml(islands=2))
    config = parse_config(tiny_toml(islands=2), "tiny")
    single = IslandHost(str(run_dir))
    expected = [single.advance(0, g, config if g == 0 else None, 1, write=g == 2) for g in range(3)]
    rows = _untimed(single.latest(0))

    epoch = IslandHost(str(run_dir))
    steps = [Step(0, 1, config), Step(1, 1), Step(2, 1, write=True, emigrants=(2, "best"))]
    got = epoch.advance_steps(0, steps)
    assert [d.generation for d in got] == [0, 1, 2]
    assert [d.fitness for d in got] == [d.fitness for d in expected]
    assert _untimed(epoch.latest(0)) == rows
    assert got[-1].part.islands == {"0": [0, 2]} and got[-1].part.rows == 18 and got[0].part is None
    assert len(got[-1].emigrants) == 2 and got[-1].emigrants_for == (2, "best")

    early = IslandHost(str(run_dir))   # answered once the time it was given has gone: one generation
    (first,) = early.advance_steps(0, steps, answer_after=0.0)
    assert (first.generation, first.fitness) == (0, expected[0].fitness)
    rest = early.advance_steps(0, steps[1:])   # the rest asked again: the same generations
    assert [d.fitness for d in rest] == [d.fitness for d in expected[1:]]
    assert _untimed(early.latest(0)) == rows


@pytest.fixture
def two_hosts(ray_local, tmp_path):
    """Two island hosts as Ray actors, serving a new 2-island run."""
    from genr8_dist.distributed.actors import remote_host_class

    run_dir = tmp_path / "run"
    new_run(run_dir, tiny_toml(islands=2))
    actor = remote_host_class(0.5)
    hosts = [actor.remote(str(run_dir)) for _ in range(2)]
    yield run_dir, hosts
    for host in hosts:
        ray_local.kill(host, no_restart=True)


def test_a_helper_evaluates_a_share_of_a_generation_and_changes_nothing(two_hosts, ray_local):
    run_dir, (owner, helper) = two_hosts
    config = parse_config(tiny_toml(islands=2), "tiny")
    alone = IslandHost(str(run_dir))
    alone.advance(0, 0, config, 1)
    gen0 = alone.latest(0)
    assert len({ind.genome for ind in gen0}) == 6
    ray_local.get(owner.advance.remote(0, 0, config, 1, (), (), [helper]))
    assert _untimed(ray_local.get(owner.latest.remote(0))) == _untimed(gen0)
    assert ray_local.get(helper.helped.remote()) >= 1          # it took batches of the 6 new genomes

    ray_local.kill(helper, no_restart=True)                     # a dead helper: the owner does it all
    ray_local.get(owner.advance.remote(0, 1, None, 1, (), (), [helper]))
    alone.advance(0, 1, None, 1)
    assert _untimed(ray_local.get(owner.latest.remote(0))) == _untimed(alone.latest(0))


def test_an_offer_helps_its_own_generation_only(two_hosts, ray_local):
    run_dir, (stale, later) = two_hosts
    config = parse_config(tiny_toml(islands=2), "tiny")
    owner = IslandHost(str(run_dir))
    owner.offer(3, stale)          # for a generation already done: dropped
    owner.offer(9, later)          # for a generation queued behind the next one: kept for it
    owner.advance(1, 0, config, 1, ticket=5)
    assert ray_local.get([stale.helped.remote(), later.helped.remote()]) == [0, 0]
    owner.advance(1, 1, None, 1, ticket=9)
    assert ray_local.get(stale.helped.remote()) == 0
    assert ray_local.get(later.helped.remote()) > 0


def test_a_host_of_several_slots_evaluates_genomes_at_once_and_builds_the_same_rows(tmp_path, monkeypatch):
    from genr8_dist.evolution import evaluate as evaluate_module

    run_dir = tmp_path / "run"
    new_run(run_dir, tiny_toml(islands=2))
    config = parse_config(tiny_toml(islands=2), "tiny")
    alone = IslandHost(str(run_dir))
    for g in range(3):
        alone.advance(0, g, config if g == 0 else None, 1)
    expected = _untimed(alone.latest(0))

    import threading
    import time

    real = evaluate_module.Evaluator.evaluate
    lock, now, most = threading.Lock(), [0], [0]

    def slow(self, genome):   # every evaluation lasts a while, as a waiting phenotype's does
        with lock:
            now[0] += 1
            most[0] = max(most[0], now[0])
        try:
            time.sleep(0.01)
            return real(self, genome)
        finally:
            with lock:
                now[0] -= 1

    monkeypatch.setattr(evaluate_module.Evaluator, "evaluate", slow)
    wide = IslandHost(str(run_dir), slots=3)
    for g in range(3):
        wide.advance(0, g, config if g == 0 else None, 1)
    assert _untimed(wide.latest(0)) == expected
    assert most[0] == 3                                   # three at once, never more
    genomes = [ind.genome for ind in expected][::-1]   # a helper's batch, answered in its order
    (found, reads), (alone, alone_reads) = (wide.evaluate(1, config, genomes),
                                            IslandHost(str(run_dir)).evaluate(1, config, genomes))
    assert [h.fitness for h in found] == [h.fitness for h in alone]
    assert reads == alone_reads and all(r is not None and set(r) <= {"0", "1"} for r in reads)


def test_an_evaluation_that_raises_ends_the_generations_dealing_thread(tmp_path, monkeypatch):
    """An evaluation on the owning host that raises (not a failure as data: the evaluator itself
    broke) reaches the caller, and the generation's dealing thread ends with it instead of waiting
    on the genomes nobody will take."""
    import threading

    from genr8_dist.evolution import evaluate as evaluate_module

    run_dir = tmp_path / "run"
    new_run(run_dir, tiny_toml(islands=1))
    config = parse_config(tiny_toml(islands=1), "tiny")
    host = IslandHost(str(run_dir))
    host.advance(0, 0, config, 1)
    calls = [0]

    def broken(self, genome):
        calls[0] += 1
        raise MemoryError("the evaluator broke")

    monkeypatch.setattr(evaluate_module.Evaluator, "evaluate", broken)
    with pytest.raises(MemoryError, match="the evaluator broke"):
        host.advance(0, 1, None, 1)
    assert calls[0] == 1                                   # the rest was abandoned, not evaluated
    assert not [t for t in threading.enumerate() if t.name == "genr8-deal" and t.is_alive()]
