"""The parts of an epoch alone, on stand-in hosts (no Ray): what is submitted with what, which hosts
are lent to which generation, what a lost host restarts, when generations are shown."""

from __future__ import annotations

from types import SimpleNamespace

from genr8_dist.distributed.coordinator import Coordinator, Epoch, RunSummary


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
        self._hosts = [SimpleNamespace(advance=_Call(self.log, ("advance", i)),
                                       offer=_Call(self.log, ("offer", i))) for i in range(n)]

    def idle(self, busy):
        return [n for n in range(self.size) if n not in busy]

    def host_of(self, island):
        return self._hosts[island]

    def handle(self, n):
        return f"host{n}"

    def replace(self, island):
        self.replaced.append(island)
        return [island]


def _run(n_islands: int = 2, interval: int = 10):
    shown: list[int] = []
    messages: list[str] = []
    run = SimpleNamespace(
        hosts=_Hosts(n_islands), interval=interval, config_for=lambda g: (1, f"config@{g}"),
        _migrants=lambda g, config: {i: [f"migrant-{g}-{i}"] for i in range(n_islands)},
        _injections={}, _hand={}, _sent=set(), summary=RunSummary(hosts=n_islands),
        _pending_events=[], _event=Coordinator._event,
        progress=SimpleNamespace(message=messages.append),
        _show=lambda g, results: shown.append(g), _island_done=lambda island, g, done: None,
        last=1000, emigrant_spec=lambda config: (2, "best"))
    return run, shown, messages


def _advances(run):
    return [(entry[1], entry[2]) for entry in run.hosts.log if entry[0] == "advance"]


def test_submit_sends_a_configuration_once_per_host_and_lends_the_free_hosts():
    run, _, _ = _run()
    epoch = Epoch(run, {0: 0, 1: 3}, end=3)          # island 1 is done: its host is free
    epoch.submit(0)
    (island, args), = _advances(run)
    assert island == 0 and args[:4] == (0, 1, "config@1", 1) and args[6] == ["host1"]
    assert list(epoch.pending.values()) == [(0, 1)] and epoch.lent == {1: next(iter(epoch.pending))}
    epoch.receive(0, 1, ["pop"])                    # next generation: no configuration sent again
    assert _advances(run)[-1][1][:3] == (0, 2, None)
    assert epoch.free() == []                       # host 1 was lent to generation 1, now to 2


def test_release_frees_the_hosts_lent_to_a_generation():
    run, _, _ = _run()
    epoch = Epoch(run, {0: 0, 1: 3}, end=3)
    epoch.submit(0)
    ref = next(iter(epoch.pending))
    assert epoch.release(ref) == (0, 1)
    assert epoch.pending == {} and epoch.lent == {} and epoch.free() == [1]


def test_lend_offers_free_hosts_to_the_island_with_most_generations_left():
    run, _, _ = _run(n_islands=3)
    epoch = Epoch(run, {0: 4, 1: 1, 2: 5}, end=5)   # island 2 done; island 1 has 4 left, island 0 one
    epoch.submit(0)
    epoch.submit(1)
    epoch.lent.clear()                              # the helpers named at submission are back
    epoch.lend()
    offers = [entry for entry in run.hosts.log if entry[0] == "offer"]
    assert [(o[1], o[2][1]) for o in offers] == [(1, "host2")]
    assert epoch.pending[epoch.lent[2]] == (1, 2)


def test_migrants_are_planned_once_per_migration_and_sent_with_the_next_generation():
    run, _, _ = _run(interval=2)
    planned = []
    run._migrants = lambda g, config: planned.append(g) or {0: ["m0"], 1: ["m1"]}
    epoch = Epoch(run, {0: 2, 1: 2}, end=4)
    epoch.submit(0)
    epoch.submit(1)
    assert planned == [2]
    assert [args[4] for _, args in _advances(run)] == [["m0"], ["m1"]]


def test_recover_restarts_a_lost_hosts_islands_from_their_committed_generation():
    run, _, messages = _run()
    epoch = Epoch(run, {0: 0, 1: 0}, end=3)
    epoch.submit(0)
    epoch.submit(1)
    epoch.receive(0, 1, ["done"])
    lost = next(ref for ref, (i, _) in epoch.pending.items() if i == 0)
    epoch.recover(0, RuntimeError("node died"))
    assert run.hosts.replaced == [0] and lost not in epoch.pending
    assert epoch.results[0] == {} and epoch.cursor[0] == 0
    assert sorted(epoch.pending.values()) == [(0, 1), (1, 1)]
    (event,) = run._pending_events
    assert (event.kind, event.generation, event.island) == ("recovery", 1, 0)
    assert event.detail == {"reason": "RuntimeError: node died", "restarted_from": 0}
    assert run.summary.recoveries == 1 and "rebuilt from generation 0" in messages[0]


def test_a_generation_is_shown_once_every_island_has_reached_it():
    run, shown, _ = _run()
    epoch = Epoch(run, {0: 0, 1: 0}, end=2)
    epoch.submit(0)
    epoch.submit(1)
    epoch.receive(0, 1, ["a"])
    epoch.receive(0, 2, ["b"])
    assert shown == []
    epoch.receive(1, 1, ["c"])
    assert shown == [1]
    epoch.receive(1, 2, ["d"])
    assert shown == [1, 2] and epoch.cursor == {0: 2, 1: 2}
    assert epoch.results == {0: {1: ["a"], 2: ["b"]}, 1: {1: ["c"], 2: ["d"]}}
