"""The coordinator's pipeline alone, on stand-in hosts (no Ray): what is submitted with what and when,
which hosts are lent to which generation, what a lost host restarts, when generations are shown and
epochs committed."""

from __future__ import annotations

import threading
from types import SimpleNamespace

from genr8_dist.distributed.coordinator import Coordinator, Hooks, Pipeline, RunSummary


class _Call:
    def __init__(self, log: list, what: tuple) -> None:
        self.log, self.what = log, what

    def remote(self, *args):
        ref = ("ref", len(self.log))
        self.log.append((*self.what, args, ref))
        return ref

    def options(self, **_):
        return self


class _Hosts:
    """Host n holds island n."""

    def __init__(self, n: int) -> None:
        self.log: list = []
        self.size = n
        self.replaced: list[int] = []
        self._hosts = [SimpleNamespace(advance_steps=_Call(self.log, ("advance", i)),
                                       offer=_Call(self.log, ("offer", i))) for i in range(n)]

    def idle(self, busy):
        return [n for n in range(self.size) if n not in busy]

    def host_of(self, island):
        return self._hosts[island]

    def placement_of(self, island):
        return island

    def handle(self, n):
        return f"host{n}"

    def replace(self, island):
        self.replaced.append(island)
        return [island]


def _run(n_islands: int = 2, interval: int = 10, last: int = 1000):
    shown: list[int] = []
    messages: list[str] = []
    commits: list = []
    run = SimpleNamespace(
        hosts=_Hosts(n_islands), interval=interval, config_for=lambda g: (1, f"config@{g}"),
        n_islands=n_islands, sources_of=lambda i, g, config: ((i - 1) % n_islands,),
        migrants_for=lambda i, g, pools, config: [f"migrant-{g}-{i}-from-{sorted(pools)}"],
        _emigrant_pool=lambda s, g, spec, done=None: [f"pool-{s}-{g}"],
        migration_event=lambda g, config, moves: Coordinator._event("migration", g, None, {}),
        _injections={}, _hand={}, _configured=set(), summary=RunSummary(hosts=n_islands),
        _event=Coordinator._event, _candidates={}, _migrated=set(), hooks=Hooks(), stop=None,
        _say=messages.append,
        _show=lambda g, results: shown.append(g), _island_done=lambda island, g, done: None,
        last=last, emigrant_spec=lambda config: (2, "best"),
        _parts=lambda committed, results, upto=None: Coordinator._parts(None, committed, results, upto),
        _commit_epoch=lambda parts, events, after: run._commit(parts, events, after),
        _commit=lambda parts, events, after: commits.append((parts, events, dict(after))) or True)
    return run, shown, messages, commits


def _advances(run):
    """(island, arguments) of each call asked of a host."""
    return [(entry[1], entry[2]) for entry in run.hosts.log if entry[0] == "advance"]


def _asked(run):
    """(island, the generations asked) of each call."""
    return [(i, [step.generation for step in args[1]]) for i, args in _advances(run)]


def _done(island, g, part=None):
    return SimpleNamespace(island=island, generation=g, part=part, emigrants=None)


def _part(island, lo, hi):
    return SimpleNamespace(islands={str(island): [lo, hi]}, rows=hi - lo + 1)


def test_submit_sends_a_configuration_once_per_host_and_lends_a_free_host():
    run, _, _, _ = _run(interval=2)
    pipeline = Pipeline(run, {0: 0, 1: 3})          # island 1 is ahead: its host is free
    assert pipeline.submit(0)
    (island, args), = _advances(run)
    assert island == 0 and args[2] == ["host1"]
    assert [(s.generation, s.config_version, s.config) for s in args[1]] == [(1, 1, "config@1"), (2, 1, None)]
    assert [s.write for s in args[1]] == [False, True]   # the epoch's end writes the part
    assert args[1][-1].emigrants == (2, "best")          # and returns the emigrant candidates
    assert list(pipeline.pending.values()) == [(0, 2)] and pipeline.lent == {1: next(iter(pipeline.pending))}
    pipeline.release(next(iter(pipeline.pending)))
    pipeline.receive(0, 1, _done(0, 1))
    pipeline.receive(0, 2, _done(0, 2))
    assert pipeline.submit(0)                       # next epoch: no configuration sent again
    assert [(s.generation, s.config) for s in _advances(run)[-1][1][1]] == [(3, None), (4, None)]
    assert _advances(run)[-1][1][1][0].migrants == ("migrant-2-0-from-[1]",)


def test_a_call_spans_the_epoch_and_is_answered_within_the_islands_share_of_the_driver():
    from genr8_dist.distributed.coordinator import ANSWERS_PER_SECOND

    run, _, _, _ = _run(n_islands=4, interval=5, last=12)
    run.sources_of = lambda i, g, config: ()
    pipeline = Pipeline(run, {0: -1, 1: 4, 2: 7, 3: 10})
    pipeline.submit_ready()
    # to each epoch's end, and no more than one epoch beyond the oldest not committed (0..5): island 3 waits
    assert _asked(run) == [(0, [0, 1, 2, 3, 4, 5]), (1, [5]), (2, [8, 9, 10])]
    assert {args[5] for _, args in _advances(run)} == {4 / ANSWERS_PER_SECOND}
    # an answer with fewer generations than asked: the rest is asked again
    ref = next(r for r, (i, _) in pipeline.pending.items() if i == 2)
    pipeline.release(ref)
    pipeline.receive(2, 8, _done(2, 8))
    assert pipeline.submit(2) and _asked(run)[-1] == (2, [9, 10])


def test_every_call_to_a_host_carries_the_configuration_until_it_answered_one():
    # One host with several slots holds both islands: it may start island 1's call before island 0's,
    # so island 1's call must carry the configuration too (the headline scale bench, 8 slots a host,
    # failed with "island host was not sent configuration version 1").
    run, _, _, _ = _run(last=3)
    shared = run.hosts._hosts[0]
    run.hosts._hosts[1] = shared
    pipeline = Pipeline(run, {0: 0, 1: 0})
    assert pipeline.submit(0) and pipeline.submit(1)
    assert [args[1][0].config for _, args in _advances(run)] == ["config@1", "config@1"]
    ref = next(r for r, (island, _) in pipeline.pending.items() if island == 0)
    pipeline.release(ref)
    pipeline.receive(0, 1, _done(0, 1))
    assert pipeline.submit(0)
    assert [(s.generation, s.config) for s in _advances(run)[-1][1][1]] == [(2, None), (3, None)]


def test_release_frees_the_hosts_lent_to_a_generation():
    run, _, _, _ = _run(last=3)
    pipeline = Pipeline(run, {0: 0, 1: 3})
    pipeline.submit(0)
    ref = next(iter(pipeline.pending))
    assert pipeline.release(ref) == (0, 3)
    assert pipeline.pending == {} and pipeline.lent == {} and pipeline.free() == [0, 1]


def test_lend_offers_free_hosts_to_the_generation_with_fewest_helpers():
    run, _, _, _ = _run(n_islands=4, last=5)
    pipeline = Pipeline(run, {0: 4, 1: 1, 2: 5, 3: 5})   # islands 2 and 3 done: their hosts are free
    pipeline.submit(0)
    pipeline.submit(1)
    pipeline.lent.clear()                                 # the helpers named at submission are back
    pipeline.helpers = dict.fromkeys(pipeline.helpers, 0)
    pipeline.lend()
    offers = [(o[1], o[2][1]) for o in run.hosts.log if o[0] == "offer"]
    assert sorted(offers) == [(0, "host3"), (1, "host2")]  # one each; the most generations left first
    assert pipeline.pending[pipeline.lent[2]] == (1, 5)


def test_an_island_starts_after_a_migration_once_its_source_has_completed_it():
    run, _, _, _ = _run(n_islands=2, interval=2)
    pipeline = Pipeline(run, {0: 2, 1: 1})     # ring: island 0 receives from island 1, 1 from 0
    pipeline.submit_ready()
    assert _asked(run) == [(1, [2])]   # island 0 waits for island 1
    pipeline.release(next(iter(pipeline.pending)))
    pipeline.receive(1, 2, _done(1, 2, _part(1, 2, 2)))
    pipeline.submit_ready()
    sent = {i: args[1] for i, args in _advances(run)[1:]}
    assert [s.generation for s in sent[0]] == [3, 4] and sent[0][0].migrants == ("migrant-2-0-from-[1]",)
    assert [s.generation for s in sent[1]] == [3, 4] and sent[1][0].migrants == ("migrant-2-1-from-[0]",)
    assert sent[0][1].migrants == ()                 # only the generation after the migration
    (event,) = pipeline.events[4]                    # recorded with the epoch the migrants enter
    assert (event.kind, event.generation) == ("migration", 2)


def test_no_island_runs_more_than_one_epoch_ahead_of_the_oldest_uncommitted_one():
    run, _, _, _ = _run(n_islands=2, interval=2)
    run.sources_of = lambda i, g, config: ()     # no migrants: only the look-ahead holds islands
    pipeline = Pipeline(run, {0: 4, 1: 0})       # epoch 1..2 is the oldest not committed
    assert pipeline.limit() == 4
    assert not pipeline.submit(0)                # island 0 has done both epochs it may
    assert pipeline.submit(1)


def test_an_epoch_is_committed_while_the_next_one_runs():
    run, _, _, commits = _run(n_islands=2, interval=2)
    run.sources_of = lambda i, g, config: ()
    started, gate = threading.Event(), threading.Event()

    def slow_commit(parts, events, after):
        started.set()
        gate.wait(5)
        commits.append((parts, dict(after)))
        return True

    run._commit = slow_commit
    pipeline = Pipeline(run, {0: 0, 1: 0})
    for g in (1, 2):
        for i in (0, 1):
            pipeline.receive(i, g, _done(i, g, _part(i, 1, 2) if g == 2 else None))
    pipeline.commit_due()
    assert started.wait(5) and pipeline.inflight is not None
    assert pipeline.limit() == 6                 # the next epoch may start, and the one after it
    assert pipeline.submit(0) and _asked(run)[-1] == (0, [3, 4])
    pipeline.collect()
    assert pipeline.committed == {0: 0, 1: 0}    # not yet durable
    gate.set()
    pipeline.collect(wait=True)
    assert pipeline.committed == {0: 2, 1: 2} and [c[1] for c in commits] == [{0: 2, 1: 2}]
    assert pipeline.results == {0: {}, 1: {}}
    pipeline._commits.shutdown()


def test_recover_restarts_a_lost_hosts_islands_from_their_committed_generation():
    run, _, messages, _ = _run()
    pipeline = Pipeline(run, {0: 0, 1: 0})
    pipeline.submit(0)
    pipeline.submit(1)
    lost = next(ref for ref, (i, _) in pipeline.pending.items() if i == 0)
    pipeline.release(lost)
    pipeline.receive(0, 1, _done(0, 1))
    pipeline.submit(0)
    lost = next(ref for ref, (i, _) in pipeline.pending.items() if i == 0)
    pipeline.recover(0, RuntimeError("node died"))
    assert run.hosts.replaced == [0] and lost not in pipeline.pending
    assert pipeline.results[0] == {} and pipeline.cursor[0] == 0
    pipeline.submit_ready()
    assert sorted(pipeline.pending.values()) == [(0, 10), (1, 10)]
    assert sorted(pipeline.firsts.values()) == [1, 1]
    (event,) = pipeline.events[10]
    assert (event.kind, event.generation, event.island) == ("recovery", 1, 0)
    assert event.detail == {"reason": "RuntimeError: node died", "restarted_from": 0}
    assert run.summary.recoveries == 1 and "rebuilt from generation 0" in messages[0]


def test_a_generation_is_shown_once_every_island_has_reached_it():
    run, shown, _, _ = _run()
    pipeline = Pipeline(run, {0: 0, 1: 0})
    pipeline.receive(0, 1, "a")
    pipeline.receive(0, 2, "b")
    assert shown == []
    pipeline.receive(1, 1, "c")
    assert shown == [1]
    pipeline.receive(1, 2, "d")
    assert shown == [1, 2] and pipeline.cursor == {0: 2, 1: 2}
    assert pipeline.results == {0: {1: "a", 2: "b"}, 1: {1: "c", 2: "d"}}
