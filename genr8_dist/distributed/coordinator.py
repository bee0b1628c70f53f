"""The coordinator: runs a run's epochs on the island hosts and commits every generation to the store.

An *epoch* takes every island from its last committed generation to the next migration generation
(a multiple of ``islands.migration_interval``, or the run's last generation). Each island advances one
generation per actor call, so an interrupt waits for no more than what is already complete. No row
comes back to the driver: at the end of an epoch each island's host writes the epoch's rows as a part
file (``store.parts``) and returns it with the generation's fitness values and emigrant candidates
(``actors.Generated``); the coordinator commits all parts at once (one manifest: ``commit_parts``), then
computes the migrants from the candidates of each island's last generation
(``migration.plan_migration``; the stored generation after a resume or an edit of the migration
settings) and sends them with the first generation of the next epoch. On a stop, hosts flush what
they completed, so that it is committed. ``on_island`` sees each island's generation as it completes
(a ``Generated``; with ``live``, the hosts also write it to the studio's live view, ``store/live.py``).

Generation ``g`` uses the configuration version in effect at ``g`` (``store.config_for(g)``), and the
individuals a user injected for ``g`` (recorded in the ``intervention`` event). Everything an island
computes is a pure function of the committed history, so:

- interrupted (``Ctrl-C``, ``SIGTERM``, or a killed driver) and resumed, a run produces the rows an
  uninterrupted one produces: whatever was not committed is recomputed identically;
- when a host dies (its process, or its node), its islands restart from their last committed
  generation on a new host (``recovery`` event) and the run's rows are those of a fault-free run.

Islands develop phenotypes of different cost, so some hosts finish an epoch early. A host with no island
left to advance in the epoch is lent to one generation at a time: named as a helper of the next
generation submitted, or offered to one under way (the island with the most generations left). It
evaluates a share of that generation's genomes (``actors.IslandHost``), which changes where the work
is done, never what it computes.

Interventions queued while the run runs (``genr8 edit`` on a running run, the studio) are taken
before each epoch and, as each generation completes, inside one (in force from the first generation no
island has started), and recorded as ``genr8 edit`` records them (``intervene.take_queued``); a queued
``pause`` holds the run between epochs, with Ray up, until a ``continue``.

Hooks (``on_generation``, ``on_commit``, ``on_island``: one island's generation, before its commit) let
a caller watch the run (tests use them to inject faults; the studio's live view, ``store/live.py``).
"""

from __future__ import annotations

import contextlib
import itertools
import json
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

from genr8_dist.distributed.actors import OFFERS
from genr8_dist.distributed.migration import is_migration_generation, plan_migration
from genr8_dist.distributed.progress import ProgressDisplay
from genr8_dist.errors import Genr8Error, RunError
from genr8_dist.evolution.individual import Individual

if TYPE_CHECKING:
    from genr8_dist.config import RunConfig
    from genr8_dist.store import RunStore

__all__ = [
    "Coordinator",
    "Epoch",
    "RunSummary",
    "StopRequest",
    "StoredEvent",
    "epoch_end",
    "last_generation",
    "parse_config",
    "stored_events",
]


# Submission tickets: increasing in submission order within this process (see ``IslandHost.offer``).
_TICKETS = itertools.count(1)


def last_generation(config: RunConfig) -> int:
    """The last generation of a run: ``ea.generations`` (generation 0 is the random one)."""
    return int(config.ea.generations)


def epoch_end(low: int, interval: int, last: int) -> int:
    """The generation an epoch that starts after ``low`` ends at: the next multiple of ``interval``
    above ``low`` (the first epoch is generations ``0..interval``), or ``last``. Epochs end where
    migrants leave, the only points where islands must wait for each other."""
    return min(last, (max(low, 0) // interval + 1) * interval)


@dataclass(frozen=True, slots=True)
class StoredEvent:
    """An event as read back from the store (``detail`` parsed from its JSON)."""

    kind: str
    generation: int
    island: int | None
    detail: dict[str, Any]


def stored_events(table: Any) -> list[StoredEvent]:
    """The rows of the store's events table as ``StoredEvent`` records, in order."""
    rows = table.select(["kind", "generation", "island", "detail"]).to_pylist()
    return [StoredEvent(r["kind"], int(r["generation"]), r["island"], json.loads(r["detail"] or "{}"))
            for r in rows]


def parse_config(toml_text: str, source: str) -> RunConfig:
    """A configuration's TOML text as a ``RunConfig`` (a run's own versions: ``RunStore.config``)."""
    from genr8_dist.config import RunConfig

    return RunConfig.from_toml(toml_text, source=source)


class StopRequest:
    """Set (by a signal handler, or a test) to ask the coordinator to stop after what is complete."""

    def __init__(self) -> None:
        self.reason: str | None = None

    def set(self, reason: str) -> None:
        if self.reason is None:
            self.reason = reason

    def __bool__(self) -> bool:
        return self.reason is not None


@dataclass
class RunSummary:
    """What a coordinator session did, and where its time went."""

    status: str = "running"                     # "complete" or "interrupted"
    committed: dict[int, int] = field(default_factory=dict)   # island -> last committed generation
    last_generation: int = 0
    generations: int = 0                        # generations every island completed in this session
    individuals: int = 0                        # individuals evaluated and committed in this session
    recoveries: int = 0
    hosts: int = 0
    wall_seconds: float = 0.0                   # the epoch loop, from the first call to the last commit
    wait_seconds: float = 0.0                   # waiting for islands (the work itself)
    store_seconds: float = 0.0                  # commits and reads of the run store
    coordinator_seconds: float = 0.0            # everything else: traffic, migration, bookkeeping
    checkpoint_bytes: int = 0                   # bytes the store holds after the run (if it says)

    @property
    def finished(self) -> bool:
        return self.status == "complete"


class Coordinator:
    """Runs the epochs of the run in ``store`` on ``hosts`` (a ``HostPool``) until its last generation,
    or until ``stop`` is set."""

    def __init__(
        self,
        store: RunStore,
        hosts: Any,
        *,
        progress: ProgressDisplay | None = None,
        stop: StopRequest | None = None,
        on_generation: Callable[[Coordinator, int], None] | None = None,
        on_commit: Callable[[Coordinator, Mapping[int, int]], None] | None = None,
        on_island: Callable[[Coordinator, int, int, Any], None] | None = None,
        live: bool = False,
        poll_seconds: float = 0.2,
    ) -> None:
        self.store = store
        self.hosts = hosts
        self.stop = stop if stop is not None else StopRequest()
        self.on_generation = on_generation
        self.on_commit = on_commit
        self.on_island = on_island
        self.live = live   # hosts write each completed generation to the live view (store/live.py)
        self.poll_seconds = poll_seconds
        self._created = time.perf_counter()
        self.summary = RunSummary(hosts=hosts.size)
        self._versions = self._load_versions()
        latest = self._versions[-1][2]
        self.n_islands = int(latest.islands.count)
        self.interval = int(latest.islands.migration_interval)
        self.last = last_generation(latest)
        self.summary.last_generation = self.last
        self.progress = progress or ProgressDisplay(total_generations=self.last, quiet=True)
        history = self._events()
        self._injections = self._load_injections(history)
        self.paused = False
        self._migrated = {e.generation for e in history if e.kind == "migration"}
        self._completed = any(e.kind == "complete" and e.generation == self.last for e in history)
        # generation -> island -> (the (k, mode) they were chosen for, emigrant candidates): what the
        # next migration needs, from the hosts' answers; only the newest committed generation is kept
        self._candidates: dict[int, dict[int, tuple[Any, tuple[Individual, ...]]]] = {}
        self._pending_events: list[Any] = []
        self._sent: set[tuple[int, int]] = set()   # (host, configuration version) already sent
        self._hand = self._load_hand(history)
        self._now: Epoch | None = None   # the epoch under way

    # -- reading the store ----------------------------------------------------------------------

    def _timed_store(self, fn: Callable[..., Any], *args: Any, **kwargs: Any) -> Any:
        t = time.perf_counter()
        try:
            return fn(*args, **kwargs)
        finally:
            self.summary.store_seconds += time.perf_counter() - t

    def _events(self) -> list[StoredEvent]:
        return stored_events(self._timed_store(self.store.events))

    def _load_versions(self) -> list[tuple[int, int, Any]]:
        """(version, effective generation, config), by effective generation then version."""
        out = [(int(v.version), int(v.effective_generation),
                self.store.config(v))
               for v in self._timed_store(self.store.configs)]
        if not out:
            raise RunError(f"{self.store.path}: the run has no configuration")
        return sorted(out, key=lambda v: (v[1], v[0]))

    def config_for(self, generation: int) -> tuple[int, Any]:
        """The configuration version in effect at ``generation`` and the configuration."""
        chosen = self._versions[0]
        for version in self._versions:
            if version[1] <= generation:
                chosen = version
        return chosen[0], chosen[2]

    @staticmethod
    def _load_injections(history: Sequence[StoredEvent]) -> dict[tuple[int, int], list[Any]]:
        """(generation, island) -> the individuals a user injected, from the intervention events."""
        out: dict[tuple[int, int], list[Any]] = {}
        for event in history:
            if event.kind != "intervention":
                continue
            for item in event.detail.get("injected", ()):
                key = (int(event.generation), int(item["island"]))
                genome = tuple(int(c) for c in item["genome"])
                copy_of = item.get("copy_of")
                if copy_of:  # a copy keeps its original as parent
                    island, generation, index = (int(p) for p in str(copy_of).split("-"))
                    out.setdefault(key, []).append(Individual(
                        island=island, generation=generation, index=index, genome=genome, origin="injected"))
                else:
                    out.setdefault(key, []).append(genome)
        return out

    def _load_hand(self, history: Sequence[StoredEvent]) -> dict[tuple[int, int], list[Any]]:
        """(generation, island) -> (individual, fitness) pairs a designer scored by hand, from the
        intervention events (``intervene`` module docstring)."""
        out: dict[tuple[int, int], list[Any]] = {}
        for event in history:
            if event.kind != "intervention":
                continue
            for item in event.detail.get("hand_fitness", ()):
                island, generation, index = (int(p) for p in str(item["id"]).split("-"))
                marked = self._population(island, generation)[index]
                out.setdefault((int(event.generation), int(item["island"])), []).append(
                    (marked, float(item["fitness"])))
        return out

    def _take_interventions(self, during: int | None = None) -> None:
        """Record the interventions queued while the run runs (``intervene.take_queued``) and take
        them into account from the next generation (``during``: from that one, inside an epoch): new
        configuration versions, injections, hand fitness, a longer run; ``pause`` and ``continue`` set
        ``paused``."""
        from genr8_dist.distributed.intervene import take_queued

        taken = self._timed_store(take_queued, self.store, during=during)
        if not taken:
            return
        for kind, outcome in taken:
            if kind == "edit":
                self.progress.message(f"intervention: configuration version {outcome.version} in force from "
                                      f"generation {outcome.effective_generation}")
            elif kind == "refused":
                self.progress.message(f"intervention refused: {outcome}")
            else:
                self.paused = kind == "pause"
                self.progress.message(f"{'paused' if self.paused else 'continuing'} before generation "
                                      f"{outcome}")
        if any(kind == "edit" for kind, _ in taken):
            self._versions = self._load_versions()
            latest = self._versions[-1][2]
            self.interval = int(latest.islands.migration_interval)
            self.last = self.summary.last_generation = last_generation(latest)
            self.progress.total_generations = self.last
            history = self._events()
            self._injections = self._load_injections(history)
            self._hand = self._load_hand(history)

    def _population(self, island: int, generation: int) -> list[Individual]:
        return list(self._timed_store(self.store.load_generation, island, generation))

    def _emigrant_pool(self, island: int, generation: int, spec: tuple[int, str]) -> list[Individual]:
        """What ``island``'s emigrants after ``generation`` are chosen from: the candidates its host
        returned when they were chosen for ``spec`` (``(k, mode)``), else the stored generation."""
        held = self._candidates.get(generation, {}).get(island)
        if held is not None and held[0] == spec:
            return list(held[1])
        return self._population(island, generation)

    @staticmethod
    def emigrant_spec(config: RunConfig) -> tuple[int, str]:
        """``(k, mode)``: how many emigrants leave each island and how they are chosen."""
        return int(config.islands.migrants), str(config.islands.emigrants)

    # -- the run ----------------------------------------------------------------------------------

    def committed(self) -> dict[int, int]:
        """Island -> its last committed generation (-1: none yet)."""
        found = self._timed_store(self.store.committed_generations)
        return {i: int(found.get(i, -1)) for i in range(self.n_islands)}

    def run(self) -> RunSummary:
        """Run epochs until the last generation is committed or a stop is requested.

        ``wall_seconds`` counts from this coordinator's creation (its reads of the store included) to
        its last write; ``wait_seconds`` is the time spent waiting for islands, ``store_seconds`` the
        time in the store, and ``coordinator_seconds`` the rest."""
        committed = self.committed()
        try:
            while not self.stop:
                self._take_interventions()
                while self.paused and not self.stop:
                    time.sleep(self.poll_seconds)
                    self._take_interventions()
                if self.stop or min(committed.values()) >= self.last:
                    break
                end = epoch_end(min(committed.values()), self.interval, self.last)
                committed = self._epoch(committed, end)
        finally:
            self.summary.committed = committed
            self._close_books()
        low = min(committed.values())
        if low >= self.last:
            self.summary.status = "complete"
            if not self._completed:
                self._timed_store(self.store.record_event, "complete", generation=self.last,
                                  detail={"committed": {str(i): g for i, g in committed.items()}})
                self._completed = True
        else:
            self.summary.status = "interrupted"
            detail = {"reason": self.stop.reason or "stopped",
                      "committed": {str(i): g for i, g in committed.items()}}
            self._timed_store(self.store.record_event, "interrupt", generation=max(0, low), detail=detail)
        self._close_books()
        return self.summary

    def _close_books(self) -> None:
        s = self.summary
        s.wall_seconds = time.perf_counter() - self._created
        s.coordinator_seconds = max(0.0, s.wall_seconds - s.wait_seconds - s.store_seconds)

    def _migrants(self, generation: int, config: RunConfig) -> dict[int, list[Individual]]:
        """The migrants that move after ``generation`` (from its committed populations)."""
        spec = self.emigrant_spec(config)
        populations = {i: self._emigrant_pool(i, generation, spec) for i in range(self.n_islands)}
        islands = config.islands
        plan = plan_migration(populations, islands.topology, int(islands.migrants), int(config.seed),
                              generation, islands.emigrants)
        if self.n_islands > 1 and islands.migrants:
            self.progress.message(f"migration after generation {generation}: {islands.migrants} "
                                  f"migrant(s) per island, {islands.topology} topology")
        if generation not in self._migrated:
            self._migrated.add(generation)
            moves = {str(dest): [m.id for m in migrants] for dest, migrants in plan.items()}
            self._pending_events.append(self._event(
                "migration", generation, None, {"topology": islands.topology, "moves": moves}))
        return plan

    @staticmethod
    def _event(kind: str, generation: int, island: int | None, detail: dict[str, Any]) -> Any:
        from genr8_dist.store import Event

        return Event(kind=kind, generation=max(0, generation), island=island, detail=detail)

    def _epoch(self, committed: dict[int, int], end: int) -> dict[int, int]:
        self._now = Epoch(self, committed, end)
        try:
            return self._now.run()
        finally:
            self._now = None

    def _island_done(self, island: int, generation: int, done: Any) -> None:
        """One island completed one generation (``done``: the host's ``Generated``; not committed
        yet): the progress table's row, ``on_island``, then the edits queued meanwhile are taken."""
        self.progress.island(island, generation, done)
        if self.on_island is not None:
            self.on_island(self, island, generation, done)
        self._take_during_epoch()

    def _take_during_epoch(self) -> None:
        """The edits queued meanwhile, in force from the first generation of the epoch under way that
        no island has started (``intervene.take_queued``'s ``during``)."""
        epoch = self._now
        if epoch is None or not self._timed_store(self.store.queued):
            return
        first = max([*epoch.cursor.values(), *(g for _, g in epoch.pending.values())]) + 1
        if first <= epoch.end:
            self._take_interventions(during=first)

    @staticmethod
    def _settle(offers: Sequence[Any]) -> None:
        """Collect the answers to offers of help (an offer to a host that died meanwhile fails)."""
        import ray

        if not offers:
            return
        done, _ = ray.wait(list(offers), num_returns=len(offers), timeout=1.0)
        for ref in done:
            with contextlib.suppress(ray.exceptions.RayError):
                ray.get(ref)

    def _show(self, generation: int, results: Mapping[int, Mapping[int, Any]]) -> None:
        """Every island has completed ``generation``: the progress line, then ``on_generation``."""
        populations = {i: r[generation] for i, r in results.items() if generation in r}
        self.summary.generations += 1
        self.progress.generation(generation, populations, remaining=self.last - generation)
        if self.on_generation is not None:
            self.on_generation(self, generation)

    def _commit(self, committed: dict[int, int], results: Mapping[int, Mapping[int, Any]]) -> dict[int, int]:
        """Commit the part files the hosts wrote for ``results`` (island -> generation -> ``Generated``)
        and the pending events, in one manifest; returns the committed generations after it."""
        parts = []
        after = dict(committed)
        for i in sorted(results):
            for g in sorted(results[i]):
                part = getattr(results[i][g], "part", None)
                if part is None:
                    continue
                span = part.islands.get(str(i))
                if span is not None and span[0] == after[i] + 1:
                    parts.append(part)
                    after[i] = span[1]
        events = list(self._pending_events)
        if not self._completed and min(after.values()) >= self.last:   # the run ends with this commit
            events.append(self._event("complete", self.last, None,
                                      {"committed": {str(i): g for i, g in after.items()}}))
            self._completed = True
        if not parts and not events:
            return committed
        self._timed_store(self.store.commit_parts, parts, events=events)
        self._pending_events.clear()
        self.summary.individuals += sum(p.rows for p in parts)
        # Keep only what the next migration needs in memory: the newest generation's candidates.
        self._candidates = {}
        for i, gens in results.items():
            done = gens.get(after[i])
            if done is not None and after[i] > committed[i] and getattr(done, "emigrants", None) is not None:
                self._candidates.setdefault(after[i], {})[i] = (done.emigrants_for, done.emigrants)
        if self.on_commit is not None:
            self.on_commit(self, after)
        return after


def _with_part(done: Any, part: Any) -> Any:
    """``done`` (a ``Generated``) with ``part``, the file holding it and the generations before it."""
    import dataclasses

    return dataclasses.replace(done, part=part)


class Epoch:
    """One epoch: every island advanced, one generation per host call, from its committed generation
    to ``end``, idle hosts lent to generations under way, lost hosts' islands restarted; then one
    commit. Its bookkeeping (which generation each island is at, what is under way, which hosts are
    lent) is plain data, so each step (``submit``, ``release``, ``lend``, ``recover``, ``receive``)
    can be exercised alone; ``run`` is the loop that waits on Ray."""

    def __init__(self, coordinator: Coordinator, committed: Mapping[int, int], end: int) -> None:
        self.run_ = coordinator
        self.committed = dict(committed)
        self.end = end
        self.cursor = dict(committed)     # island -> its newest generation done (committed or not)
        self.results: dict[int, dict[int, list[Individual]]] = {i: {} for i in committed}
        self.pending: dict[Any, tuple[int, int]] = {}   # ref of a generation under way -> (island, g)
        self.tickets: dict[Any, int] = {}
        self.lent: dict[int, Any] = {}      # idle host -> the generation (its ref) it helps
        self.offers: list[Any] = []
        self.migrants_after: dict[int, dict[int, list[Individual]]] = {}
        self.shown = min(committed.values())

    def free(self) -> list[int]:
        """The hosts with no island left to advance in this epoch and not lent already."""
        busy = {i for i, c in self.cursor.items() if c < self.end}
        return [n for n in self.run_.hosts.idle(busy) if n not in self.lent]

    def submit(self, island: int) -> None:
        """Ask ``island``'s host for its next generation, naming the free hosts as its helpers."""
        run = self.run_
        g = self.cursor[island] + 1
        version, config = run.config_for(g)
        migrants: Sequence[Individual] = ()
        if is_migration_generation(g - 1, run.interval):
            if g - 1 not in self.migrants_after:
                self.migrants_after[g - 1] = run._migrants(g - 1, config)
            migrants = self.migrants_after[g - 1][island]
        injected = run._injections.get((g, island), ())
        hand = run._hand.get((g, island), ())
        emigrants = None
        if is_migration_generation(g, run.interval) and g < run.last:
            emigrants = run.emigrant_spec(run.config_for(g + 1)[1])
        host = run.hosts.host_of(island)
        send = (id(host), version) not in run._sent
        run._sent.add((id(host), version))
        helpers = self.free()
        ticket = next(_TICKETS)
        ref = host.advance.remote(island, g, config if send else None, version, migrants, injected,
                                  [run.hosts.handle(n) for n in helpers], ticket, hand, g == self.end,
                                  emigrants, bool(getattr(run, "live", False)))
        self.pending[ref] = (island, g)
        self.tickets[ref] = ticket
        self.lent.update(dict.fromkeys(helpers, ref))

    def release(self, ref: Any) -> tuple[int, int]:
        """Forget the generation ``ref`` (done or lost) and free the hosts lent to it."""
        for n in [n for n, r in self.lent.items() if r == ref]:
            del self.lent[n]
        return self.pending.pop(ref)

    def lend(self) -> None:
        """Offer each free idle host to a generation under way, most generations left first."""
        run = self.run_
        targets = sorted(self.pending, key=lambda r: (self.cursor[self.pending[r][0]] - self.end,
                                                      self.pending[r][0]))
        for n, ref in zip(self.free(), targets, strict=False):
            owner = run.hosts.host_of(self.pending[ref][0])
            self.offers.append(owner.offer.options(concurrency_group=OFFERS).remote(
                self.tickets[ref], run.hosts.handle(n)))
            self.lent[n] = ref

    def recover(self, island: int, exc: BaseException) -> None:
        """``island``'s host was lost: every island it held restarts from its committed generation."""
        run = self.run_
        moved = run.hosts.replace(island)
        for isl in moved:
            for ref in [r for r, (i, _) in self.pending.items() if i == isl]:
                self.release(ref)
            self.results[isl].clear()
            self.cursor[isl] = self.committed[isl]
            run.summary.recoveries += 1
            run._pending_events.append(run._event(
                "recovery", self.committed[isl] + 1, isl,
                {"reason": f"{type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else ''}",
                 "restarted_from": self.committed[isl]}))
            run.progress.message(
                f"island {isl}: its host was lost; rebuilt from generation {self.committed[isl]}")
            if self.cursor[isl] < self.end:
                self.submit(isl)

    def receive(self, island: int, g: int, population: Any) -> None:
        """Generation ``g`` of ``island`` is done (``population``: the host's ``Generated``): keep it,
        ask for the next one, and show every generation all islands have now reached."""
        self.results[island][g] = population
        self.cursor[island] = g
        self.run_._island_done(island, g, population)
        if g < self.end:
            self.submit(island)
        low = min(self.cursor.values())
        while self.shown < low:
            self.shown += 1
            self.run_._show(self.shown, self.results)

    def run(self) -> dict[int, int]:
        """Run the epoch to its end (or a stop), commit what is complete, return the committed
        generations."""
        import ray

        run = self.run_
        for island in sorted(self.cursor):
            if self.cursor[island] < self.end:
                self.submit(island)
        committed = self.committed
        try:
            while self.pending and not run.stop:
                self.lend()
                t = time.perf_counter()
                ready, _ = ray.wait(list(self.pending), num_returns=1, timeout=run.poll_seconds)
                run.summary.wait_seconds += time.perf_counter() - t
                for ref in ready:
                    if ref not in self.pending:
                        continue
                    island, g = self.release(ref)
                    try:
                        population = ray.get(ref)
                    except (ray.exceptions.RayActorError, ray.exceptions.ObjectLostError) as exc:
                        self.recover(island, exc)
                        continue
                    except ray.exceptions.RayTaskError as exc:
                        cause = getattr(exc, "cause", None)
                        if isinstance(cause, Genr8Error):
                            raise cause from None
                        what = f"{type(cause).__name__}: {cause}" if cause is not None else str(exc)
                        raise RunError(f"island {island} failed at generation {g} on its host: "
                                       f"{what.strip().splitlines()[0]}") from exc
                    self.receive(island, g, population)
        finally:
            run._settle(self.offers)
            if run.stop:
                self.flush()
            committed = run._commit(self.committed, self.results)
        return committed

    def flush(self) -> None:
        """Stopping mid-epoch: each island's host writes the generations it completed since its
        last part (served beside a generation under way), so that what is complete is committed."""
        import ray

        asked = {}
        for island, gens in self.results.items():
            if gens and getattr(gens[max(gens)], "part", None) is None:
                host = self.run_.hosts.host_of(island)
                asked[island] = host.flush.options(concurrency_group=OFFERS).remote(island)
        for island, ref in asked.items():
            try:
                part = ray.get(ref)
            except ray.exceptions.RayError:   # its host is gone: those generations are recomputed
                continue
            if part is not None:   # it may hold a generation completed since (then committed too)
                newest = max(self.results[island])
                self.results[island][newest] = _with_part(self.results[island][newest], part)
