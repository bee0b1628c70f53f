"""The island host: a Ray actor that keeps one or several islands and advances them generation by generation.

``IslandHost`` is a plain class (testable without Ray); ``remote_host_class()`` wraps it as a Ray actor.
An actor holds each island's latest generation and the configuration versions it was sent, so they are
not sent back and forth: one call (``advance_steps``) asks for one or several consecutive generations of
an island within an epoch, each a ``Step``: the generation number, the configuration version in force
(the configuration itself only the first time), the incoming migrants and any injected individuals;
the answer is a ``Generated`` per generation (fitness values, emigrant candidates, the part file the
host wrote; never rows or phenotypes). A host
that lacks the generation before the one asked for (it was just created to replace a dead actor, or
it adopted an island from one) reads it from the run store: per-generation traffic stays small, and a
restarted actor rebuilds its state from the last commit. Because ``Island.step`` is a pure function of
its inputs, the rebuilt island produces exactly what the lost one would have.

Every host lends its CPU to generations of other hosts' islands when it has none of its own to advance
(a run starts one host per CPU, so a run with fewer islands than CPUs has hosts that only help): the
coordinator names idle hosts as the ``helpers`` of a generation it submits, or ``offer``s one to a
generation under way (the offer is served by a thread of its own while ``advance`` runs). The owner of
the generation deals its genomes out as they are needed (work stealing at the genome level): a thread
of the owner keeps each helper busy with a small batch of the genomes not yet taken (``evaluate``,
served beside ``advance``), smaller as fewer are left, while the owner evaluates the others one by one,
so a slow evaluation holds only the host evaluating it. Evaluation is a pure function of (genome,
configuration), so the generation is the one the owner would have built alone; a helper that dies
meanwhile only means its batch is evaluated by the owner.

A host has ``slots`` CPUs (1 by default; ``RunOptions.host_cpus``): it evaluates up to ``slots`` genomes
at once, whoever they are for (threads of one process: a phenotype whose development waits for
something outside Python, or releases the GIL, keeps them all busy; one process then carries Ray's
per-process costs for ``slots`` CPUs). It advances up to ``slots`` of its islands at once, and a
generation's genomes are spread over its free slots (*lanes*, each with an ``Evaluator`` of its own,
whose evaluations the island adopts as it adopts a helper's), so that a host's CPUs are not idle
while one of its islands waits for its slowest genome.
"""

from __future__ import annotations

import functools
import math
import os
import socket
import threading
import time
from collections import deque
from collections.abc import Sequence
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from genr8_dist.evolution.individual import Individual

if TYPE_CHECKING:
    from genr8_dist.config import RunConfig
    from genr8_dist.evolution.evaluate import Evaluator
    from genr8_dist.evolution.island import Island
    from genr8_dist.store import Part, RunStore

__all__ = ["HELPING", "OFFERS", "Generated", "IslandHost", "Step", "remote_host_class"]

# The actor's concurrency groups serving ``offer`` and ``evaluate`` (for other hosts) while ``advance``
# runs in the default one.
OFFERS = "offers"
HELPING = "helping"
# At most this many genomes go to a helper at once (fewer as fewer are left: ``_Deal.batch``).
BATCH = 8
# Seconds the owner's dealing thread waits for a helper's answer before it looks for offers again.
DEAL_POLL = 0.02


@dataclass(frozen=True, slots=True)
class Step:
    """One generation the coordinator asks of an island's host (``IslandHost.advance_steps``).

    ``config`` is configuration version ``config_version``; the coordinator sends it until the host
    has answered a generation of that version, and ``None`` afterwards (the host keeps it; a host
    with several slots may start a later call first). ``migrants``: the individuals arriving after
    a migration generation; ``injected``: what a user injected; ``hand``: individuals with the
    fitness a designer gave them, parents of this generation (``Island.breed``). ``write``: write
    the island's rows not yet in a part (this generation's included) as a part file; ``emigrants``:
    ``(k, mode)``, return the generation's emigrant candidates."""

    generation: int
    config_version: int
    config: RunConfig | None = None
    migrants: tuple[Individual, ...] = ()
    injected: tuple[Any, ...] = ()
    hand: tuple[tuple[Individual, float], ...] = ()
    write: bool = False
    emigrants: tuple[int, str] | None = None


@dataclass(frozen=True, slots=True)
class Generated:
    """What the driver receives for one generation of one island: never its rows.

    ``fitness``: every individual's fitness, by index (progress); ``emigrants``: after a migration
    generation, the candidates ``emigrants_for`` asked for (the best ``k``, or the whole generation
    for novel emigrants, which depend on the destination); ``part``: the part file the host wrote,
    holding this island's generations since its last part up to this one (``None``: still buffered
    on the host)."""

    island: int
    generation: int
    fitness: tuple[float, ...]
    part: Part | None = None
    emigrants: tuple[Individual, ...] | None = None
    emigrants_for: tuple[int, str] | None = None

    def __len__(self) -> int:
        return len(self.fitness)


class IslandHost:
    """Hosts islands of one run; ``run_dir`` is where it reads a generation it does not hold."""

    def __init__(self, run_dir: str, slots: int = 1) -> None:
        """``slots``: the genomes this host evaluates at once (its CPUs)."""
        if slots < 1:
            raise ValueError(f"an island host needs at least one slot, got {slots}")
        self.slots = int(slots)
        self._offers: deque[Any] = deque()   # helpers offered while a generation is under way
        self._offered = threading.Event()     # set by ``offer``: the dealing thread looks at once
        self._helped = 0                      # genomes evaluated for other hosts' islands
        self._cpu = threading.BoundedSemaphore(self.slots)   # ``slots`` evaluations at once, whoever for
        self._running: set[int] = set()       # tickets of the generations under way here
        self._cuts: set[int] = set()          # tickets of calls to answer after their generation under way
        self._lanes = (ThreadPoolExecutor(self.slots - 1, thread_name_prefix="genr8-lane")
                       if self.slots > 1 else None)
        self._lane = threading.local()        # each lane's evaluators
        self._opening = threading.Lock()      # the store, opened once
        self.bind(run_dir)

    def bind(self, run_dir: str) -> None:
        """Serve the run in ``run_dir`` from now on, forgetting everything held of another run."""
        self.run_dir = run_dir
        self._islands: dict[tuple[int, int], Island] = {}
        self._configs: dict[int, RunConfig] = {}
        self._latest: dict[int, tuple[int, list[Individual]]] = {}
        self._evaluators: dict[int, Evaluator] = {}   # configuration version -> Evaluator, for helping
        self._store: RunStore | None = None
        self._bound = object()   # the lanes' evaluators are this binding's
        self._unwritten: dict[int, list[Individual]] = {}   # island -> rows computed, no part yet
        self._written: dict[int, Part] = {}                  # island -> the last part written
        self._writing = threading.Lock()   # a stopping driver's flush runs beside advance

    def ready(self) -> dict[str, Any]:
        """Where this host runs (answers once the actor is scheduled and started). Arrow's first
        conversion of Python values imports pandas (seconds of CPU): done here, while the pool
        starts, not in the first part write of the run, where it made every host a straggler."""
        import pyarrow as pa

        pa.array([0])
        return {"host": socket.gethostname(), "pid": os.getpid()}

    def _island(self, island: int, config: RunConfig | None, config_version: int) -> Island:
        from genr8_dist.evolution.island import Island

        if config is not None:
            self._configs[config_version] = config
        key = (island, config_version)
        found = self._islands.get(key)
        if found is None:
            if config_version not in self._configs:
                raise RuntimeError(f"island host was not sent configuration version {config_version}")
            found = Island(self._configs[config_version], island, config_version=config_version,
                           config_of=self._config_of)
            self._islands[key] = found
        return found

    def _config_of(self, version: int) -> RunConfig | None:
        """Configuration ``version`` of the run: as sent, else read from the run store (None when the
        store cannot say): an island judges rows made under it again without regrowing them."""
        found = self._configs.get(version)
        if found is None:
            try:
                found = self._store_of().config(version)
            except Exception:
                return None
        return found

    def _store_of(self) -> RunStore:
        with self._opening:
            if self._store is None:
                from genr8_dist.store import RunStore

                self._store = RunStore.open(self.run_dir)
            return self._store

    def _previous(self, island: int, generation: int) -> list[Individual]:
        held = self._latest.get(island)
        if held is not None and held[0] == generation:
            return held[1]
        return list(self._store_of().load_generation(island, generation))

    def advance(
        self,
        island: int,
        generation: int,
        config: RunConfig | None,
        config_version: int,
        migrants: Sequence[Individual] = (),
        injected: Sequence[Any] = (),
        helpers: Sequence[Any] = (),
        ticket: int | None = None,
        hand: Sequence[tuple[Individual, float]] = (),
        write: bool = False,
        emigrants: tuple[int, str] | None = None,
        live: bool = False,
    ) -> Generated:
        """Compute ``island``'s ``generation`` (0: the initial population) and keep it as the latest:
        ``advance_steps`` with one ``Step`` (its fields say what the arguments mean)."""
        step = Step(generation, config_version, config, tuple(migrants), tuple(injected), tuple(hand), write,
                    emigrants)
        return self.advance_steps(island, [step], helpers, ticket, live)[0]

    def advance_steps(
        self,
        island: int,
        steps: Sequence[Step],
        helpers: Sequence[Any] = (),
        ticket: int | None = None,
        live: bool = False,
        answer_after: float = math.inf,
    ) -> list[Generated]:
        """Compute ``island``'s generations ``steps`` (consecutive, within one epoch) one after the
        other, each kept as the latest; their ``Generated``, in order.

        One call for several generations: the driver's cost is per call (a submission and an answer),
        so a run of many islands asks for an epoch at a time. ``answer_after``: answer once this many
        seconds have gone in the call, with the generations done so far (at least one), so that the
        driver hears of an island often enough to show its progress. ``helpers`` (Ray handles of idle
        hosts) evaluate a share of every generation's genomes, and so do the helpers offered with this
        ``ticket`` (they stay with the call: the coordinator lent them to it). ``live``: write each
        generation to the run's live view for the studio (``store/live.py``; local runs only)."""
        started = time.perf_counter()
        crew = [_helping(h) for h in helpers]
        out: list[Generated] = []
        if ticket is not None:
            self._running.add(ticket)
        try:
            for k, step in enumerate(steps):
                out.append(self._step(island, step, crew, ticket, live))
                if k + 1 < len(steps) and (ticket in self._cuts
                                           or time.perf_counter() - started >= answer_after):
                    break
        finally:
            self._running.discard(ticket)
            self._cuts.discard(ticket)
        return out

    def cut(self, ticket: int) -> bool:
        """Answer the call of ``ticket`` after the generation it is computing, or after its first if
        it has not started (served beside it): a user's request waits for the generations no island
        has started. Whether that call was under way (a ticket of a call already answered is kept:
        a few integers per request)."""
        self._cuts.add(ticket)
        return ticket in self._running

    def _step(self, island: int, step: Step, crew: list[Any], ticket: int | None, live: bool) -> Generated:
        """One generation of ``island`` (``advance_steps``)."""
        generation = step.generation
        model = self._island(island, step.config, step.config_version)
        held = self._latest.get(island)
        if held is None or held[0] != generation - 1:
            self._unwritten.pop(island, None)   # its parents come from the store: committed already
        if generation == 0:
            births = model.breed(0)
        else:
            previous = self._previous(island, generation - 1)
            births = model.breed(generation, previous, migrants=tuple(step.migrants),
                                 injected=tuple(step.injected), hand=tuple(step.hand))
        evaluated = self._evaluate(model, model.pending(births), crew, ticket)
        population = model.complete(generation, births, evaluated)
        self._latest[island] = (generation, population)
        with self._writing:
            self._unwritten.setdefault(island, []).extend(population)
        if live:
            self._store_of().live().write(island, generation, population)
        candidates = None
        if step.emigrants is not None:
            from genr8_dist.distributed.migration import select_emigrants

            k, mode = step.emigrants
            candidates = tuple(population if mode == "novel" else select_emigrants(population, k))
        return Generated(island, generation, tuple(float(ind.fitness) for ind in population),
                         self.flush(island) if step.write else None, candidates, step.emigrants)

    def flush(self, island: int) -> Part | None:
        """Write ``island``'s rows computed since its last part as a new part file of the run and
        return its ``Part``; with none to write, the last part written (the driver may not have
        received it: a generation that ended an epoch as the run was stopped), or ``None``."""
        from genr8_dist.store.parts import write_part
        from genr8_dist.store.schema import individuals_table

        with self._writing:
            rows = self._unwritten.pop(island, None)
            if not rows:
                return self._written.get(island)
            store = self._store_of()
            table = individuals_table(rows, store.run_id, store.criteria, store.schema)
            gens = [ind.generation for ind in rows]
            part = self._written[island] = write_part(
                store, table, stem=f"part-{island:06d}-{min(gens):06d}-{max(gens):06d}")
            return part

    def latest(self, island: int) -> list[Individual]:
        """The newest generation this host computed of ``island`` (tests, and a caller that wants the
        rows without reading the store)."""
        return list(self._latest[island][1])

    def offer(self, ticket: int, helper: Any) -> bool:
        """Offer ``helper`` (an idle host) to the generation submitted with ``ticket``. Tickets grow
        in the order the coordinator submits, which is the order a host starts its generations in,
        so an offer for a generation already done is dropped (its helper may be busy again by then)."""
        self._offers.append((ticket, _helping(helper)))
        self._offered.set()
        return True

    def _taken_offers(self, ticket: int | None) -> list[Any]:
        """The helpers offered to the generation of ``ticket``; offers for later ones, and for the
        other generations under way here, are kept."""
        mine, later = [], []
        running = set(self._running)
        while self._offers:
            offered_for, helper = self._offers.popleft()
            if ticket is not None and offered_for == ticket:
                mine.append(helper)
            elif ticket is None or offered_for > ticket or offered_for in running:
                later.append((offered_for, helper))
        self._offers.extend(later)
        return mine

    def _lane_evaluator(self, config_version: int, config: RunConfig) -> Evaluator:
        """The calling lane's evaluator of configuration ``config_version`` (each lane has its own:
        an ``Evaluator`` serves one thread at a time)."""
        from genr8_dist.evolution.evaluate import Evaluator

        held: tuple[Any, dict[int, Evaluator]] | None = getattr(self._lane, "evaluators", None)
        if held is None or held[0] is not self._bound:
            held = (self._bound, {})
            self._lane.evaluators = held
        found = held[1].get(config_version)
        if found is None:
            found = held[1][config_version] = Evaluator(config)
        return found

    def _work(self, deal: _Deal, evaluate: Any, wait: Any) -> None:
        """Evaluate genomes of ``deal`` one at a time (a slot each) until none is left to take."""
        while True:
            genome = deal.take_one(wait=wait)
            if genome is None:
                return
            with self._cpu:
                evaluation = evaluate(genome)
            deal.put(genome, evaluation)

    def _spread(self, deal: _Deal, config_version: int, config: RunConfig) -> list[Future[None]]:
        """Lanes of this host that take genomes of ``deal`` beside the calling thread (none for one
        slot); each ends when none is left to take."""
        if self._lanes is None or len(deal.todo) < 2:
            return []

        def lane() -> None:
            self._work(deal, lambda g: self._lane_evaluator(config_version, config).evaluate(g),
                       wait=_never)

        return [self._lanes.submit(lane) for _ in range(min(self.slots - 1, len(deal.todo) - 1))]

    @staticmethod
    def _join(lanes: list[Future[None]]) -> None:
        """Wait for the lanes that started; those still queued (the lanes were busy) are cancelled."""
        for lane in lanes:
            if not lane.cancel():
                lane.result()

    def _evaluate(self, model: Any, genomes: list[tuple[int, ...]], crew: list[Any],
                  ticket: int | None) -> dict[tuple[int, ...], Any]:
        """``genomes`` evaluated, here and by the call's helpers (``crew``: their ``evaluate``, which
        the helpers offered meanwhile join): a thread deals batches to the helpers (``_deal``) while
        this one evaluates what is left, one at a time; a batch whose helper failed goes back to be
        evaluated by whoever takes it next. An evaluation here that raises abandons the rest: nothing
        more is dealt, and the dealing thread ends once the batches already dealt are back."""
        deal = _Deal(genomes)
        dealer = threading.Thread(target=self._deal, name="genr8-deal", daemon=True,
                                  args=(model, deal, crew, ticket))
        dealer.start()
        lanes = self._spread(deal, model.config_version, model.config)
        try:
            self._work(deal, model.evaluate, wait=dealer.is_alive)
        except BaseException:
            deal.abandon()
            raise
        finally:
            self._join(lanes)
            dealer.join()
        if deal.error is not None:
            raise deal.error
        return deal.out

    def _deal(self, model: Any, deal: _Deal, crew: list[Any], ticket: int | None) -> None:
        """The dealing thread of one generation: keep each helper of the call (``crew``, which the
        helpers offered meanwhile join for the call's later generations) busy with one batch until no
        genome is left untaken, collect the answers; ends when every batch dealt has come back. A
        helper that failed leaves the crew."""
        import ray

        try:
            idle = list(crew)
            out: dict[Any, tuple[Any, list[tuple[int, ...]]]] = {}
            while True:
                offered = self._taken_offers(ticket)
                crew.extend(offered)
                idle.extend(offered)
                while idle:
                    batch = deal.take(deal.batch(len(idle) + len(out) + 1))
                    if not batch:
                        break
                    helper = idle.pop()
                    ref = helper.remote(model.config_version, model.config, batch)
                    out[ref] = (helper, batch)
                if not out:
                    if deal.finished():
                        return
                    self._offered.wait(DEAL_POLL)
                    self._offered.clear()
                    continue
                done, _ = ray.wait(list(out), num_returns=1, timeout=DEAL_POLL)
                for ref in done:
                    helper, batch = out.pop(ref)
                    try:
                        found, reads = ray.get(ref)
                    except ray.exceptions.RayError:   # the helper died or failed: its batch goes back
                        deal.give_back(batch)
                        if helper in crew:
                            crew.remove(helper)
                        continue
                    for evaluation, read in zip(found, reads, strict=True):
                        if evaluation.text is not None and read is not None:
                            model.evaluator.learn_reads(evaluation.text, read)
                    deal.done(zip(batch, found, strict=True))
                    idle.append(helper)
        except Exception as exc:   # met again by the owner's thread
            deal.error = exc
        finally:
            deal.close()

    def evaluate(self, config_version: int, config: RunConfig,
                 genomes: Sequence[Sequence[int]]) -> tuple[list[Any], list[str | None]]:
        """The evaluations of ``genomes`` under configuration version ``config_version`` (``config``),
        for the host of another island (served beside this host's own ``advance``, within its slots),
        in their order; and what each development read (``Evaluator.said_reads``), which the island
        checks its next children against without developing its parents again."""
        from genr8_dist.evolution.evaluate import Evaluator

        evaluator = self._evaluators.get(config_version)
        if evaluator is None:
            evaluator = self._evaluators[config_version] = Evaluator(config)
        self._helped += len(genomes)
        keys = [tuple(int(c) for c in genome) for genome in genomes]
        deal = _Deal(list(dict.fromkeys(keys)))
        lanes = self._spread(deal, config_version, config)
        try:
            self._work(deal, evaluator.evaluate, wait=_never)
        finally:
            self._join(lanes)
        found = [deal.out[key] for key in keys]
        return found, [evaluator.said_reads(evaluation.text) for evaluation in found]

    def helped(self) -> int:
        """How many genomes this host has evaluated for other hosts' islands."""
        return self._helped

    def forget(self, island: int) -> None:
        """Drop what this host holds of ``island`` (it moved to another host)."""
        self._latest.pop(island, None)
        self._unwritten.pop(island, None)
        self._written.pop(island, None)
        for key in [k for k in self._islands if k[0] == island]:
            del self._islands[key]


@functools.lru_cache(maxsize=8)
def remote_host_class(num_cpus: float, slots: int = 1) -> Any:
    """``IslandHost`` as a Ray actor class reserving ``num_cpus`` (fractions allowed), spread over the
    cluster's nodes (a lost node takes few islands with it), never restarted by Ray itself: the
    coordinator replaces a dead host and reloads its islands from the store. ``slots``: the
    generations it advances at once (start it with the same ``slots``). One class per CPU
    reservation: Ray exports a class once (pickling its code), not once per host."""
    import ray

    actor = ray.remote(concurrency_groups={OFFERS: 1, HELPING: 1})(IslandHost)
    return actor.options(num_cpus=num_cpus, max_restarts=0, max_task_retries=0, scheduling_strategy="SPREAD",
                         max_concurrency=slots)


def _never() -> bool:
    """A lane's ``wait``: it never waits for genomes to come back (the owner does)."""
    return False


def _helping(helper: Any) -> Any:
    """A helper's ``evaluate``, served beside its own ``advance`` (resolved in the thread that got the
    handle: a handle's methods are not found from another thread of an actor)."""
    return helper.evaluate.options(concurrency_group=HELPING)


class _Deal:
    """The genomes of one generation being evaluated by its owner and helpers (two threads)."""

    def __init__(self, genomes: Sequence[tuple[int, ...]]) -> None:
        self.todo: deque[tuple[int, ...]] = deque(genomes)
        self.out: dict[tuple[int, ...], Any] = {}
        self.away = 0                  # genomes dealt to helpers, not back yet
        self.error: Exception | None = None
        self.open = True               # the dealing thread runs
        self.abandoned = False         # the owner gave up (``abandon``)
        self._cond = threading.Condition()

    def batch(self, workers: int) -> int:
        """How many genomes a helper takes now: a share of what is left, at most ``BATCH``."""
        return max(1, min(BATCH, len(self.todo) // (2 * max(1, workers))))

    def take(self, n: int) -> list[tuple[int, ...]]:
        """Up to ``n`` genomes for a helper."""
        with self._cond:
            batch = [self.todo.popleft() for _ in range(min(n, len(self.todo)))]
            self.away += len(batch)
            return batch

    def take_one(self, wait: Any) -> tuple[int, ...] | None:
        """The next genome for the owner; ``None`` when none is left and none can come back."""
        with self._cond:
            while not self.todo:
                if not self.open or not wait():
                    return None
                self._cond.wait(DEAL_POLL)
            return self.todo.popleft()

    def put(self, genome: tuple[int, ...], evaluation: Any) -> None:
        """A genome taken here (``take_one``) evaluated."""
        with self._cond:
            self.out[genome] = evaluation

    def done(self, pairs: Any) -> None:
        with self._cond:
            for genome, evaluation in pairs:
                self.out[genome] = evaluation
                self.away -= 1

    def give_back(self, batch: list[tuple[int, ...]]) -> None:
        with self._cond:
            if not self.abandoned:
                self.todo.extendleft(reversed(batch))
            self.away -= len(batch)
            self._cond.notify_all()

    def abandon(self) -> None:
        """Nobody evaluates what is left (the owner's evaluation raised): the untaken genomes are
        dropped, and a batch that comes back failed is not dealt again."""
        with self._cond:
            self.abandoned = True
            self.todo.clear()
            self._cond.notify_all()

    def finished(self) -> bool:
        with self._cond:
            return not self.todo and not self.away

    def close(self) -> None:
        with self._cond:
            self.open = False
            self._cond.notify_all()
