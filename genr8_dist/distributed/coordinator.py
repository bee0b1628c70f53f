"""The coordinator: runs a run's generations on the island hosts and commits every epoch to the store.

An *epoch* is the generations after one migration generation (a multiple of
``islands.migration_interval``) up to the next, or to the run's last generation. One actor call asks
for an island's generations to the end of the epoch, answered early once the island has had its share
of the driver's answers (``ANSWERS_PER_SECOND``): the driver's cost is per call, so a run of hundreds of
islands asks for whole epochs, while a run of a few still hears of every generation as it completes.
An interrupt waits for no more than what is already complete: at a stop, each host writes the
generations it completed, those of a call under way included, and they are committed. No row
comes back to the driver: at the end of an epoch each island's host writes the epoch's rows as a part
file (``store.parts``) and returns it with the generation's fitness values and emigrant candidates
(``actors.Generated``); once every island has completed the epoch, the coordinator commits all its
parts and events at once (one manifest: ``commit_parts``), in a thread of its own.

There is no barrier but migration's own (``Pipeline``): an island starts its next generation as soon as
it has completed one, and after a migration generation as soon as the islands its migrants come from
have completed it (``migration.migrants_for``, from the candidates in memory: the commit is not
awaited), no more than one epoch ahead of the oldest epoch not yet committed. So the commit of epoch
``k`` overlaps the evaluation of epoch ``k + 1``, and an island that finishes early goes on. A crash
leaves whole epochs: each is one manifest, and whatever was not committed is recomputed. On a stop,
hosts flush what they completed, so that it is committed. ``on_island`` sees each island's generation
as it completes (a ``Generated``; with ``live``, the hosts also write it to the studio's live view,
``store/live.py``).

Generation ``g`` uses the configuration version in effect at ``g`` (``store.config_for(g)``), and the
individuals a user injected for ``g`` (recorded in the ``intervention`` event). Everything an island
computes is a pure function of the committed history, so the rows are the same whatever the order the
islands ran in, and:

- interrupted (``Ctrl-C``, ``SIGTERM``, or a killed driver) and resumed, a run produces the rows an
  uninterrupted one produces: whatever was not committed is recomputed identically;
- when a host dies (its process, or its node), its islands restart from their last committed
  generation on a new host (``recovery`` event) and the run's rows are those of a fault-free run.

A run has one host per CPU (``hosts``), so when islands are fewer than CPUs some hosts hold none, and
islands develop phenotypes of different cost, so some hosts run out of work early. A host with no
generation of its own under way is lent to one generation at a time: named as a helper of the first
generation submitted, or offered to one under way (the one with the fewest helpers, then the island
with the most generations left). The owner deals it genomes in small batches as it asks for them
(``actors.IslandHost``), which changes where the work is done, never what it computes.

Interventions queued while the run runs (``genr8 edit`` on a running run, the studio) are taken before
the run starts and, as each generation completes, in force from the first generation no island has
started, and recorded as ``genr8 edit`` records them (``intervene.take_queued``). A request that must
wait for an epoch's end (a ``pause``, an edit of the epochs themselves) holds the run: no island starts
a generation after the end of the epoch under way, and when everything up to it is committed the
request is taken there; a ``pause`` holds the run, with Ray up, until a ``continue``.

A run is watched through its ``Hooks`` (EvoTorch's ``before_step``/``after_step``/``log``): ``on_island``
(one island's generation, before its commit), ``on_generation`` (every island completed one),
``on_commit`` (an epoch is durable) and ``on_message`` (a line for the user). The progress display
subscribes to them (``ProgressDisplay.attach``), so do the session's live view (``store/live.py``) and
the tests that inject faults; the coordinator calls none of them by name.
"""

from __future__ import annotations

import contextlib
import itertools
import json
import threading
import time
from collections.abc import Callable, Mapping, Sequence
from concurrent.futures import wait as wait_futures
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

from genr8_dist.distributed.actors import OFFERS
from genr8_dist.distributed.migration import destinations, is_migration_generation, migrants_for, sources
from genr8_dist.errors import Genr8Error, RunError
from genr8_dist.evolution.individual import Individual

if TYPE_CHECKING:
    import pyarrow as pa

    from genr8_dist.config import RunConfig
    from genr8_dist.distributed.hosts import HostPool
    from genr8_dist.distributed.progress import ProgressDisplay
    from genr8_dist.store import RunStore

__all__ = [
    "Coordinator",
    "Hooks",
    "Pipeline",
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
# The rows of a file the coordinator's compaction writes (``RunStore.compact``'s ``target_rows``).
COMPACT_ROWS = 100_000
# Offers of help kept unanswered before the answered ones are let go (``Pipeline.lend``).
OFFERS_KEPT = 64
# The islands' answers the driver receives per second at most, all together: each costs it about 1.5 ms
# (a submission and an answer), so that 8 a second keep it near 1% of its time. An island's call spans
# its generations to the end of the epoch, answered early once ``islands / ANSWERS_PER_SECOND``
# seconds have gone in it: a run of a few islands still shows each generation as it completes, one of
# hundreds asks for whole epochs.
ANSWERS_PER_SECOND = 8


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


def stored_events(table: pa.Table) -> list[StoredEvent]:
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


IslandHook = Callable[["Coordinator", int, int, Any], None]   # (coordinator, island, generation, Generated)
GenerationHook = Callable[["Coordinator", int], None]         # (coordinator, generation)
CommitHook = Callable[["Coordinator", Mapping[int, int]], None]   # (coordinator, island -> committed)
MessageHook = Callable[["Coordinator", str], None]            # (coordinator, a line for the user)


@dataclass
class Hooks:
    """Who watches a run, called in the order they subscribed, in the driver's thread: ``island``
    when one island completes a generation (not durable yet), ``generation`` when every island has
    completed one, ``commit`` when an epoch is durable, ``message`` for a line the user should see."""

    island: list[IslandHook] = field(default_factory=list)
    generation: list[GenerationHook] = field(default_factory=list)
    commit: list[CommitHook] = field(default_factory=list)
    message: list[MessageHook] = field(default_factory=list)

    def subscribe(self, *, on_island: IslandHook | None = None, on_generation: GenerationHook | None = None,
                  on_commit: CommitHook | None = None, on_message: MessageHook | None = None) -> None:
        """Add the hooks given (``None``: none of that kind)."""
        if on_island is not None:
            self.island.append(on_island)
        if on_generation is not None:
            self.generation.append(on_generation)
        if on_commit is not None:
            self.commit.append(on_commit)
        if on_message is not None:
            self.message.append(on_message)

    def island_done(self, coordinator: Coordinator, island: int, generation: int, done: Any) -> None:
        for hook in self.island:
            hook(coordinator, island, generation, done)

    def generation_done(self, coordinator: Coordinator, generation: int) -> None:
        for hook in self.generation:
            hook(coordinator, generation)

    def committed(self, coordinator: Coordinator, after: Mapping[int, int]) -> None:
        for hook in self.commit:
            hook(coordinator, after)

    def say(self, coordinator: Coordinator, text: str) -> None:
        for hook in self.message:
            hook(coordinator, text)


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
    or until ``stop`` is set. ``progress`` (a display) and the ``on_*`` hooks subscribe to ``hooks``,
    in that order; more may subscribe before ``run``."""

    def __init__(
        self,
        store: RunStore,
        hosts: HostPool,
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
        self.hooks = Hooks()
        self.live = live   # hosts write each completed generation to the live view (store/live.py)
        self.poll_seconds = poll_seconds
        self._created = time.perf_counter()
        self._writing = threading.RLock()   # the store: the driver's thread or the commit thread
        # Compaction reads small files' rows in the driver: done here, once they hold a whole merged
        # file's rows (each row is then read once, not at every commit), not by every commit.
        self._compacts = bool(store.compact_every)
        self._small_rows = self._count_small_rows() if self._compacts else 0
        self.summary = RunSummary(hosts=hosts.size)
        self._versions = self._load_versions()
        latest = self._versions[-1][2]
        self.n_islands = int(latest.islands.count)
        self.interval = int(latest.islands.migration_interval)
        self.last = last_generation(latest)
        self.summary.last_generation = self.last
        self.progress = progress
        if progress is not None:
            progress.total_generations = self.last
            progress.attach(self.hooks)
        self.hooks.subscribe(on_island=on_island, on_generation=on_generation, on_commit=on_commit)
        history = self._events()
        self._injections = self._load_injections(history)
        self.paused = False
        self._migrated = {e.generation for e in history if e.kind == "migration"}
        self._completed = any(e.kind == "complete" and e.generation == self.last for e in history)
        # generation -> island -> (the (k, mode) they were chosen for, emigrant candidates): what the
        # next migration needs, from the hosts' answers; only the newest committed generation is kept
        self._candidates: dict[int, dict[int, tuple[Any, tuple[Individual, ...]]]] = {}
        self._pending_events: list[Any] = []
        # (host, configuration version) pairs where the host has answered a generation of that version,
        # so it holds the configuration. Until then every call to it carries the configuration, because
        # a host with several slots may start a later call before the one that carried it.
        self._configured: set[tuple[int, int]] = set()
        self._hand = self._load_hand(history)
        self._now: Pipeline | None = None   # the generations under way

    # -- reading the store ----------------------------------------------------------------------

    def _timed_store(self, fn: Callable[..., Any], *args: Any, **kwargs: Any) -> Any:
        """``fn(...)`` on the store, timed, one at a time with the commit thread's commits."""
        t = time.perf_counter()
        try:
            with self._writing:
                return fn(*args, **kwargs)
        finally:
            self.summary.store_seconds += time.perf_counter() - t

    def _events(self) -> list[StoredEvent]:
        return stored_events(self._timed_store(self.store.events))

    def _load_versions(self) -> list[tuple[int, int, RunConfig]]:
        """(version, effective generation, config), by effective generation then version."""
        out = [(int(v.version), int(v.effective_generation),
                self.store.config(v))
               for v in self._timed_store(self.store.configs)]
        if not out:
            raise RunError(f"{self.store.path}: the run has no configuration")
        return sorted(out, key=lambda v: (v[1], v[0]))

    def config_for(self, generation: int) -> tuple[int, RunConfig]:
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
                self._say(f"intervention: configuration version {outcome.version} in force from "
                                      f"generation {outcome.effective_generation}")
            elif kind == "refused":
                self._say(f"intervention refused: {outcome}")
            else:
                self.paused = kind == "pause"
                self._say(f"{'paused' if self.paused else 'continuing'} before generation "
                                      f"{outcome}")
        if any(kind == "edit" for kind, _ in taken):
            self._versions = self._load_versions()
            latest = self._versions[-1][2]
            self.interval = int(latest.islands.migration_interval)
            self.last = self.summary.last_generation = last_generation(latest)
            history = self._events()
            self._injections = self._load_injections(history)
            self._hand = self._load_hand(history)

    def _say(self, text: str) -> None:
        """A line for the user (``on_message``: the progress display prints it)."""
        self.hooks.say(self, text)

    def populations(self, generation: int) -> dict[int, Any]:
        """Island -> its ``Generated`` of ``generation``, for the islands whose generation is held in
        memory (not committed yet): what ``on_generation``'s subscribers may read of it."""
        results = self._now.results if self._now is not None else {}
        return {i: r[generation] for i, r in results.items() if generation in r}

    def _population(self, island: int, generation: int) -> list[Individual]:
        return list(self._timed_store(self.store.load_generation, island, generation))

    def _emigrant_pool(self, island: int, generation: int, spec: tuple[int, str],
                       done: Any = None) -> list[Individual]:
        """What ``island``'s emigrants after ``generation`` are chosen from: the candidates its host
        returned when they were chosen for ``spec`` (``(k, mode)``; ``done``: its ``Generated``, not
        committed yet), else the stored generation."""
        if done is not None and getattr(done, "emigrants", None) is not None and done.emigrants_for == spec:
            return list(done.emigrants)
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
        """Run the generations until the last one is committed or a stop is requested.

        ``wall_seconds`` counts from this coordinator's creation (its reads of the store included) to
        its last write; ``wait_seconds`` is the time spent waiting for islands, ``store_seconds`` the
        time in the store (in the driver's own thread: a commit made while islands run is not counted),
        and ``coordinator_seconds`` the rest."""
        committed = self.committed()
        try:
            while not self.stop:
                self._take_interventions()
                while self.paused and not self.stop:
                    time.sleep(self.poll_seconds)
                    self._take_interventions()
                if self.stop or min(committed.values()) >= self.last:
                    break
                committed = self._pipeline(committed)
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

    def migrants_for(self, island: int, generation: int, pools: Mapping[int, Sequence[Individual]],
                     config: RunConfig) -> list[Individual]:
        """The migrants ``island`` receives after ``generation``, from ``pools`` (its sources'
        emigrant candidates: ``sources_of``)."""
        islands = config.islands
        return migrants_for(island, pools, self.n_islands, islands.topology, int(islands.migrants),
                            int(config.seed), generation, islands.emigrants)

    def sources_of(self, island: int, generation: int, config: RunConfig) -> tuple[int, ...]:
        """The islands whose generation ``generation`` ``island``'s migrants after it come from (its
        own included for novel emigrants, which depend on the destination)."""
        islands = config.islands
        if not islands.migrants or self.n_islands < 2:
            return ()
        found = sources(islands.topology, self.n_islands, int(config.seed), generation)[island]
        return tuple(sorted({*found, island})) if islands.emigrants == "novel" else found

    def destinations_of(self, island: int, generation: int, config: RunConfig) -> tuple[int, ...]:
        """The islands whose migrants after ``generation`` come (partly) from ``island``: those whose
        ``sources_of`` hold it."""
        islands = config.islands
        if not islands.migrants or self.n_islands < 2:
            return ()
        return destinations(islands.topology, self.n_islands, int(config.seed), generation)[island]

    def migration_event(self, generation: int, config: RunConfig,
                        moves: Mapping[int, Sequence[Individual]]) -> Any:
        """The ``migration`` event after ``generation`` (``moves``: every island's migrants), once."""
        islands = config.islands
        if self.n_islands > 1 and islands.migrants:
            self._say(f"migration after generation {generation}: {islands.migrants} "
                                  f"migrant(s) per island, {islands.topology} topology")
        if generation in self._migrated:
            return None
        self._migrated.add(generation)
        detail = {str(dest): [m.id for m in moves[dest]] for dest in sorted(moves)}
        return self._event("migration", generation, None, {"topology": islands.topology, "moves": detail})

    @staticmethod
    def _event(kind: str, generation: int, island: int | None, detail: dict[str, Any]) -> Any:
        from genr8_dist.store import Event

        return Event(kind=kind, generation=max(0, generation), island=island, detail=detail)

    def _pipeline(self, committed: dict[int, int]) -> dict[int, int]:
        self._now = Pipeline(self, committed)
        try:
            return self._now.run()
        finally:
            self._now = None

    def _island_done(self, island: int, generation: int, done: Any) -> None:
        """One island completed one generation (``done``: the host's ``Generated``; not committed
        yet): ``on_island``. Once a call's generations are all received, the pipeline takes the edits
        queued meanwhile (``_take_during``)."""
        self.hooks.island_done(self, island, generation, done)

    def _take_during(self) -> None:
        """The edits queued meanwhile, in force from the first generation no island has started
        (``intervene.take_queued``'s ``during``), once the calls under way that asked for several
        generations have answered with those they started (``Pipeline.cut``); a request that must wait
        for an epoch's end (a pause, an edit of the epochs) holds the run at the end of the epoch under
        way."""
        pipeline = self._now
        if pipeline is None or pipeline.hold is not None or not self.store.queued():
            return
        if pipeline.cut():   # calls asked for generations they have not started: they answer first
            return
        first = pipeline.first_unstarted()
        if first <= self.last:
            self._take_interventions(during=first)
        if self.store.queued():
            pipeline.hold_at(first - 1)

    @staticmethod
    def _settled(offers: Sequence[Any]) -> list[Any]:
        """The offers of help not answered yet (the answers of the others collected)."""
        import ray

        done, left = ray.wait(list(offers), num_returns=len(offers), timeout=0)
        for ref in done:
            with contextlib.suppress(ray.exceptions.RayError):
                ray.get(ref)
        return list(left)

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
        """Every island has completed ``generation`` (its ``Generated`` in ``results``, which
        ``populations`` reads): ``on_generation``."""
        self.summary.generations += 1
        self.hooks.generation_done(self, generation)

    def _parts(self, committed: Mapping[int, int], results: Mapping[int, Mapping[int, Any]],
               upto: int | None = None) -> tuple[list[Any], dict[int, int]]:
        """The part files the hosts wrote for ``results`` (island -> generation -> ``Generated``)
        that follow ``committed``, up to generation ``upto``; and the committed generations after
        them."""
        parts = []
        after = dict(committed)
        for i in sorted(results):
            for g in sorted(results[i]):
                if upto is not None and g > upto:
                    break
                part = getattr(results[i][g], "part", None)
                if part is None:
                    continue
                span = part.islands.get(str(i))
                if span is not None and span[0] == after[i] + 1:
                    parts.append(part)
                    after[i] = span[1]
        return parts, after

    def _commit(self, parts: Sequence[Any], events: Sequence[Any], after: Mapping[int, int]) -> bool:
        """Commit ``parts`` and ``events`` in one manifest (the run's ``complete`` event too when
        ``after`` reaches its last generation); whether anything was committed. Runs in the commit
        thread while islands go on (``Pipeline``), or in the driver's own at a stop."""
        events = list(events)
        if not self._completed and min(after.values()) >= self.last:   # the run ends with this commit
            events.append(self._event("complete", self.last, None,
                                      {"committed": {str(i): g for i, g in after.items()}}))
            self._completed = True
        if not parts and not events:
            return False
        with self._writing:
            every, self.store.compact_every = self.store.compact_every, None
            try:
                self.store.commit_parts(parts, events=events)
            finally:
                self.store.compact_every = every
        self._small_rows += sum(p.rows for p in parts)
        self.summary.individuals += sum(p.rows for p in parts)
        return True

    def _compact(self) -> bool:
        """Compact the run once its small files hold a merged file's rows (a commit of its own,
        after an epoch's); whether it did."""
        if not self._compacts or self._small_rows < COMPACT_ROWS:
            return False
        with self._writing:
            self.store.compact(COMPACT_ROWS)
            self._small_rows = self._count_small_rows()
        return True

    def _commit_epoch(self, parts: Sequence[Any], events: Sequence[Any], after: Mapping[int, int]) -> bool:
        """The commit thread's work for one epoch: its commit, then compaction when due."""
        done = self._commit(parts, events, after)
        self._compact()
        return done

    def _count_small_rows(self) -> int:
        """The rows of the run's individuals files smaller than a compacted one."""
        return sum(int(e["rows"]) for e in self.store.manifest["individuals"]
                   if int(e["rows"]) < COMPACT_ROWS)


def _answers(refs: Sequence[Any]) -> dict[Any, Any]:
    """The values of ``refs`` (done), fetched at once; none when one of them failed (each is then
    fetched alone, and its error met where it is handled)."""
    import ray

    if len(refs) < 2:
        return {}
    try:
        return dict(zip(refs, ray.get(list(refs)), strict=True))
    except ray.exceptions.RayError:
        return {}


def _with_part(done: Any, part: Any) -> Any:
    """``done`` (a ``Generated``) with ``part``, the file holding it and the generations before it."""
    import dataclasses

    return dataclasses.replace(done, part=part)


class Pipeline:
    """The run's generations from the committed ones on, with no barrier but migration's own: each
    island advances as soon as it may (a host call to the epoch's end: ``submit``), idle hosts are
    lent to generations under way, lost hosts' islands restart, and each epoch is committed (one
    manifest) in a thread of its own once every island has completed it, while the next epoch runs.

    An island may start generation ``g + 1`` when it has completed ``g`` and, after a migration
    generation, when the islands its migrants come from have completed ``g`` (their emigrant
    candidates are in memory, not yet durable: a commit is not awaited); and no more than one epoch
    beyond the oldest epoch not yet committed (what the hosts buffer stays bounded). Everything an
    island computes is a pure function of committed or recomputable history, so the rows are the
    same whatever the order. A crash leaves the epochs committed before it, whole: an epoch's parts
    and events are one manifest. Its bookkeeping is plain data, so each step (``submit``, ``release``,
    ``lend``, ``recover``, ``receive``) can be exercised alone; ``run`` is the loop that waits on Ray."""

    def __init__(self, coordinator: Coordinator, committed: Mapping[int, int]) -> None:
        self.run_ = coordinator
        self.committed = dict(committed)  # durable
        self.cursor = dict(committed)     # island -> its newest generation done (committed or not)
        self.results: dict[int, dict[int, Any]] = {i: {} for i in committed}
        self.pending: dict[Any, tuple[int, int]] = {}   # ref of a call under way -> (island, its last g)
        self.firsts: dict[Any, int] = {}    # ref of a call under way -> its first generation
        self.cutting: set[Any] = set()      # calls asked to answer early: nothing is submitted meanwhile
        self.busy: set[int] = set()         # the islands of ``pending``
        self.tickets: dict[Any, int] = {}
        self.lent: dict[int, Any] = {}      # idle host -> the generation (its ref) it helps
        self.helpers: dict[Any, int] = {}   # ref of a generation under way -> hosts lent to it
        self.offers: list[Any] = []
        self.migrants_after: dict[int, dict[int, list[Individual]]] = {}
        self.events: dict[int, list[Any]] = {}   # epoch end -> events committed with it
        self.shown = min(committed.values())
        self.hold: int | None = None        # no generation after this one is started (a drain)
        self.inflight: Any = None           # the commit under way: (future, epoch end, after)
        self._commits: Any = None           # its thread

    # -- epochs ---------------------------------------------------------------------------------

    def boundary(self, generation: int) -> int:
        """The end of the epoch holding ``generation``."""
        return epoch_end(generation - 1, self.run_.interval, self.run_.last)

    def oldest(self) -> int:
        """The end of the oldest epoch not committed (nor being committed)."""
        low = min(self.committed.values())
        if self.inflight is not None:
            low = max(low, self.inflight[1])
        return epoch_end(low, self.run_.interval, self.run_.last)

    def first_unstarted(self) -> int:
        """The first generation no island has been asked for."""
        return max([*self.cursor.values(), *(g for _, g in self.pending.values())]) + 1

    def cut(self) -> bool:
        """A request is queued: ask every call under way that spans several generations to answer
        after the one it is computing (``IslandHost.cut``), and submit nothing until they have, so
        that the request is in force from the first generation no island has started, as if every
        call had asked for one. Whether calls are still to answer."""
        cut = self.cutting & set(self.pending)
        for ref, (island, last) in self.pending.items():
            if ref not in self.cutting and last > self.firsts[ref]:
                host = self.run_.hosts.host_of(island)
                self.offers.append(host.cut.options(concurrency_group=OFFERS).remote(self.tickets[ref]))
                cut.add(ref)
        self.cutting = cut
        return bool(cut)

    def hold_at(self, started: int) -> None:
        """Start nothing after the end of the epoch holding generation ``started`` (a request
        queued for an epoch's end is taken there, when everything before it is committed)."""
        self.hold = self.boundary(max(started, 0))

    def limit(self) -> int:
        """The newest generation an island may start now."""
        oldest = self.oldest()
        ahead = epoch_end(oldest, self.run_.interval, self.run_.last)
        return min(ahead, self.hold) if self.hold is not None else ahead

    # -- islands --------------------------------------------------------------------------------

    def busy_islands(self) -> set[int]:
        """The islands with a generation under way."""
        return self.busy

    def free(self) -> list[int]:
        """The hosts with no generation of their own under way and not lent already."""
        return [n for n in self.run_.hosts.idle(self.busy_islands()) if n not in self.lent]

    def migrants(self, island: int, g: int, config: RunConfig) -> list[Individual] | None:
        """The migrants ``island`` receives after generation ``g`` (a migration generation), or
        ``None`` while an island they come from has not completed ``g``."""
        run = self.run_
        held = self.migrants_after.setdefault(g, {})
        if island in held:
            return held[island]
        spec = run.emigrant_spec(config)
        pools = {}
        for source in run.sources_of(island, g, config):
            if self.cursor[source] < g:
                return None
            pools[source] = run._emigrant_pool(source, g, spec, self.results[source].get(g))
        held[island] = run.migrants_for(island, g, pools, config)
        if len(held) == run.n_islands:   # every island's: the migration is recorded with the epoch
            event = run.migration_event(g, config, held)
            if event is not None:
                self.events.setdefault(self.boundary(g + 1), []).append(event)
        return held[island]

    def ready(self, island: int, limit: int | None = None) -> tuple[Any, ...] | None:
        """What ``island``'s next generation is submitted with, if it may start now (``limit``:
        ``limit()``, when the caller has it)."""
        run = self.run_
        g = self.cursor[island] + 1
        if g > min(run.last, self.limit() if limit is None else limit) or island in self.busy:
            return None
        version, config = run.config_for(g)
        migrants: Sequence[Individual] = ()
        if is_migration_generation(g - 1, run.interval):
            found = self.migrants(island, g - 1, config)
            if found is None:
                return None
            migrants = found
        return g, version, config, migrants

    def submit(self, island: int, limit: int | None = None) -> bool:
        """Ask ``island``'s host for its next generations if it may start: one call up to the end of
        the epoch (or the hold, or the look-ahead's limit), answered early once the island has had its
        share of the driver's answers (``ANSWERS_PER_SECOND``); free hosts are named its helpers.
        Whether it was submitted."""
        from genr8_dist.distributed.actors import Step

        run = self.run_
        limit = self.limit() if limit is None else limit
        prepared = self.ready(island, limit)
        if prepared is None:
            return False
        first, version, config, migrants = prepared
        end = min(self.boundary(first), limit)   # the limit holds the hold
        host = run.hosts.host_of(island)
        steps = []
        sent: set[int] = set()
        for g in range(first, end + 1):
            if g > first:
                version, config = run.config_for(g)
            send = (id(host), version) not in run._configured and version not in sent
            sent.add(version)
            emigrants = None
            if is_migration_generation(g, run.interval) and g < run.last:
                emigrants = run.emigrant_spec(run.config_for(g + 1)[1])
            steps.append(Step(g, version, config if send else None, tuple(migrants) if g == first else (),
                              tuple(run._injections.get((g, island), ())),
                              tuple(run._hand.get((g, island), ())),
                              g == self.boundary(g) or g == self.hold, emigrants))
        # The first generation under way gets one helper at once; ``lend`` spreads the free hosts
        # over the generations under way right after.
        own = run.hosts.placement_of(island)
        helpers = [n for n in self.free() if n != own][:1] if not self.pending else []
        ticket = next(_TICKETS)
        ref = host.advance_steps.remote(island, steps, [run.hosts.handle(n) for n in helpers], ticket,
                                        bool(getattr(run, "live", False)), run.n_islands / ANSWERS_PER_SECOND)
        self.pending[ref] = (island, end)
        self.firsts[ref] = first
        self.busy.add(island)
        self.tickets[ref] = ticket
        self.helpers[ref] = len(helpers)
        self.lent.update(dict.fromkeys(helpers, ref))
        return True

    def submit_ready(self, islands: Any = None) -> bool:
        """Submit the next generation of every island (of ``islands``) that may start; whether it
        looked (not while calls are cut for a queued request: the caller keeps ``islands``)."""
        if any(ref in self.pending for ref in self.cutting):
            return False
        limit = self.limit()
        for island in sorted(self.cursor if islands is None else islands):
            if island not in self.busy and self.cursor[island] < limit:
                self.submit(island, limit)
        return True

    def affected(self, island: int, g: int) -> set[int]:
        """The islands that may start now that ``island`` completed ``g``: itself, and after a
        migration generation the islands its emigrants go to."""
        run = self.run_
        out = {island}
        if is_migration_generation(g, run.interval):
            out.update(run.destinations_of(island, g, run.config_for(g + 1)[1]))
        return out

    def release(self, ref: Any) -> tuple[int, int]:
        """Forget the generation ``ref`` (done or lost) and free the hosts lent to it."""
        for n in [n for n, r in self.lent.items() if r == ref]:
            del self.lent[n]
        self.helpers.pop(ref, None)
        self.tickets.pop(ref, None)
        self.firsts.pop(ref, None)
        found = self.pending.pop(ref)
        self.busy.discard(found[0])
        return found

    def lend(self) -> None:
        """Offer each free host to a generation under way: the one with the fewest helpers, then
        the island with the most generations left before the hold or the run's end."""
        run = self.run_
        if len(self.offers) > OFFERS_KEPT:   # answered offers are let go: the list stays short
            self.offers = run._settled(self.offers)
        free = self.free()
        if not free or not self.pending:
            return
        end = self.hold if self.hold is not None else run.last
        running: dict[int, Any] = {}   # host -> its generation under way: the first submitted to it
        for ref, (island, _) in self.pending.items():
            n = run.hosts.placement_of(island)
            if n not in running or self.tickets[ref] < self.tickets[running[n]]:
                running[n] = ref
        for n in free:
            ref = min(running.values(), key=lambda r: (self.helpers[r], self.cursor[self.pending[r][0]] - end,
                                                       self.pending[r][0]))
            owner = run.hosts.host_of(self.pending[ref][0])
            self.offers.append(owner.offer.options(concurrency_group=OFFERS).remote(
                self.tickets[ref], run.hosts.handle(n)))
            self.lent[n] = ref
            self.helpers[ref] += 1

    def recover(self, island: int, exc: BaseException) -> None:
        """``island``'s host was lost: every island it held restarts from its committed generation
        (the commit under way is awaited first: it may hold their parts)."""
        run = self.run_
        self.collect(wait=True)
        moved = run.hosts.replace(island)
        for isl in moved:
            for ref in [r for r, (i, _) in self.pending.items() if i == isl]:
                self.release(ref)
            self.results[isl].clear()
            self.cursor[isl] = self.committed[isl]
            run.summary.recoveries += 1
            self.events.setdefault(self.oldest(), []).append(run._event(
                "recovery", self.committed[isl] + 1, isl,
                {"reason": f"{type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else ''}",
                 "restarted_from": self.committed[isl]}))
            run._say(
                f"island {isl}: its host was lost; rebuilt from generation {self.committed[isl]}")

    def receive(self, island: int, g: int, population: Any) -> None:
        """Generation ``g`` of ``island`` is done (``population``: the host's ``Generated``): keep it
        and show every generation all islands have now reached."""
        self.results[island][g] = population
        self.cursor[island] = g
        self.run_._configured.add((id(self.run_.hosts.host_of(island)), self.run_.config_for(g)[0]))
        self.run_._island_done(island, g, population)
        low = min(self.cursor.values())
        while self.shown < low:
            self.shown += 1
            self.run_._show(self.shown, self.results)

    # -- commits --------------------------------------------------------------------------------

    def due(self) -> bool:
        """Whether the run is at its end or its hold, or the oldest epoch can be committed."""
        end = min(self.run_.last, self.hold) if self.hold is not None else self.run_.last
        return min(self.cursor.values()) >= min(end, self.oldest())

    def commit_due(self) -> None:
        """Commit the oldest epoch in the commit thread once every island has completed it."""
        if self.inflight is not None:
            return
        end = self.oldest()
        if min(self.committed.values()) >= self.run_.last or min(self.cursor.values()) < end:
            return
        parts, after = self.run_._parts(self.committed, self.results, upto=end)
        if min(after.values()) < end:   # a part is missing (a host lost after its generation)
            return
        events = [e for b in sorted(self.events) if b <= end for e in self.events.pop(b)]
        if self._commits is None:
            from concurrent.futures import ThreadPoolExecutor

            self._commits = ThreadPoolExecutor(1, thread_name_prefix="genr8-commit")
        self.inflight = (self._commits.submit(self.run_._commit_epoch, parts, events, after), end, after)

    def collect(self, wait: bool = False) -> bool:
        """The commit under way, if done (``wait``: once done): its islands' generations are
        durable, what the next migration needs is kept and the rest dropped, ``on_commit`` sees it.
        Whether one was collected."""
        if self.inflight is None:
            return False
        future, _, after = self.inflight
        if not wait and not future.done():
            return False
        self.inflight = None
        t = time.perf_counter()
        try:
            committed = future.result()
        finally:
            if wait:
                self.run_.summary.store_seconds += time.perf_counter() - t
        self._committed(after, committed)
        return True

    def _committed(self, after: Mapping[int, int], committed: bool = True) -> None:
        run = self.run_
        before = self.committed
        self.committed = dict(after)
        kept: dict[int, dict[int, tuple[Any, tuple[Individual, ...]]]] = {}
        for i, gens in self.results.items():
            for g in [g for g in gens if g <= after[i]]:
                done = gens.pop(g)
                if g == after[i] and after[i] > before[i] and getattr(done, "emigrants", None) is not None:
                    kept.setdefault(g, {})[i] = (done.emigrants_for, done.emigrants)
        run._candidates = {g: c for g, c in run._candidates.items() if g >= min(after.values())}
        for g, found in kept.items():
            run._candidates.setdefault(g, {}).update(found)
        low = min(after.values())
        for g in [g for g in self.migrants_after if g < low and len(self.migrants_after[g]) == run.n_islands]:
            del self.migrants_after[g]
        run._migrated = {g for g in run._migrated if g >= low}   # no island migrates before low again
        if committed:
            run.hooks.committed(run, dict(after))

    def finish(self) -> None:
        """At a stop, an error or the end: await the commit under way; at a stop, each island's host
        writes the generations it completed since its last part and they are committed, with the
        events pending."""
        try:
            self.collect(wait=True)
        finally:
            if self._commits is not None:
                self._commits.shutdown(wait=True)
        run = self.run_
        if not run.stop and min(self.cursor.values()) < run.last and self.hold is None:
            return
        if run.stop:
            self.flush()
        parts, after = run._parts(self.committed, self.results)
        events = [e for b in sorted(self.events) for e in self.events.pop(b)]
        if run._timed_store(run._commit, parts, events, after):
            self._committed(after)

    def run(self) -> dict[int, int]:
        """Run until every island completed the run (or the hold) and it is committed, or a stop;
        returns the committed generations."""
        import ray

        run = self.run_
        end = min(run.last, self.hold) if self.hold is not None else run.last
        try:
            self.submit_ready()
            dirty: set[int] | None = set()   # the islands that may start since (None: any)
            polled = time.perf_counter()      # when queued requests were last looked for
            while not run.stop:
                if self.collect():
                    dirty = None   # a commit: the look-ahead moved on
                self.commit_due()
                end = min(run.last, self.hold) if self.hold is not None else run.last
                if not self.pending and self.inflight is None and (
                        min(self.committed.values()) >= end or min(self.cursor.values()) >= end):
                    break
                self.lend()
                t = time.perf_counter()
                ready: list[Any] = []
                if self.pending:
                    waits = list(self.pending)
                    ready, _ = ray.wait(waits, num_returns=1, timeout=run.poll_seconds)
                    if ready and len(waits) > 1:   # and every other one done meanwhile, at once
                        ready, _ = ray.wait(waits, num_returns=len(waits), timeout=0)
                elif self.inflight is not None:   # nothing may start before this commit
                    wait_futures([self.inflight[0]], timeout=run.poll_seconds)
                run.summary.wait_seconds += time.perf_counter() - t
                answers = _answers(ready)
                for ref in ready:
                    if ref not in self.pending:
                        continue
                    first = self.firsts[ref]
                    island, g = self.release(ref)
                    try:
                        generated = answers[ref] if ref in answers else ray.get(ref)
                    except (ray.exceptions.RayActorError, ray.exceptions.ObjectLostError) as exc:
                        self.recover(island, exc)
                        dirty = None
                        continue
                    except ray.exceptions.RayTaskError as exc:
                        cause = getattr(exc, "cause", None)
                        if isinstance(cause, Genr8Error):
                            raise cause from None
                        what = f"{type(cause).__name__}: {cause}" if cause is not None else str(exc)
                        at = f"generation {g}" if g == first else f"generations {first}..{g}"
                        raise RunError(f"island {island} failed at {at} on its host: "
                                       f"{what.strip().splitlines()[0]}") from exc
                    for done in generated:
                        self.receive(island, done.generation, done)
                        if dirty is not None:
                            dirty |= self.affected(island, done.generation)
                if ready or time.perf_counter() - polled >= run.poll_seconds:
                    # requests queued meanwhile: looked for at each answer, and while calls run long
                    polled = time.perf_counter()
                    run._take_during()
                if not run.stop and self.submit_ready(dirty):
                    dirty = set()
                    if not self.pending and self.inflight is None and not self.due():
                        raise RunError(f"the run cannot go on from generations {self.cursor} (committed: "
                                       f"{self.committed}); resume it")
        finally:
            run._settle(self.offers)
            self.finish()
        return self.committed

    def flush(self) -> None:
        """Stopping: each island's host writes the generations it completed since its last part
        (served beside a call under way, whose completed generations it holds too), so that what is
        complete is committed."""
        import ray

        from genr8_dist.distributed.actors import Generated

        asked = {}
        for island, gens in self.results.items():
            if island in self.busy or (gens and getattr(gens[max(gens)], "part", None) is None):
                host = self.run_.hosts.host_of(island)
                asked[island] = host.flush.options(concurrency_group=OFFERS).remote(island)
        for island, ref in asked.items():
            try:
                part = ray.get(ref)
            except ray.exceptions.RayError:   # its host is gone: those generations are recomputed
                continue
            if part is None:
                continue
            gens = self.results[island]
            span = part.islands.get(str(island))
            if gens and getattr(gens[max(gens)], "part", None) is None:
                # it may hold generations completed since (then committed too)
                newest = max(gens)
                gens[newest] = _with_part(gens[newest], part)
            elif span is not None and span[1] > max(gens, default=self.committed[island]):
                # generations of the call under way, which the driver has not heard of
                gens[span[1]] = Generated(island, span[1], (), part)
