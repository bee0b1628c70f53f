"""Intervention (thesis 4.2): change a stopped run's configuration and put individuals into it.

An edit becomes a new configuration version in force from the generation after the last committed one,
recorded atomically with an ``intervention`` event that lists what changed and the genomes injected.
``genr8 resume`` then uses the new version from that generation on, and the coordinator hands the
injected genomes to their island at that generation (provenance ``injected``). Everything is checked
before anything is written: a wrong key, a text the universe cannot invert or an unknown individual is
a one-line error and the run directory is left as it was.

A run that is running (its driver holds the run's lock, ``store/pending.py``) is not written to: the
edit is checked, then queued in the run directory, and the coordinator records it exactly so (a
configuration version and its ``intervention`` event) without stopping Ray (``take_queued``): from the
first second of the run, before anything is committed. It takes effect at the first generation it can:
one no island has started yet, taken as the generations of an epoch complete (``take_queued(during=G)``),
or before the next epoch for an edit that changes the epochs themselves (``islands.*``, the run's
length) and for ``pause``/``continue``. A run with nothing committed is edited from generation 0.

Besides configuration changes and injections, an edit may *favour* individuals (copies join the next
generation on their own island, as ``--inject-copy``) and *hand-set a fitness* (the thesis' interactive
option): the ``hand_fitness`` entries of the event put the marked individuals into their island's
parent pool for the generation the edit takes effect at, with the designer's fitness in place of the
computed one, for the choice of elites and tournament parents there. Stored rows keep the computed
fitness; the event keeps both.

Keys (``--set KEY=VALUE``, VALUE in TOML syntax, bare words taken as strings) are the configuration's
own: ``fitness.size.weight=2``, ``ea.mutation_rate=0.05``, ``environment.scale=[1.5, 1.5, 1.2]``,
``islands.topology=random``. ``fitness.weights.NAME`` and ``fitness.targets.NAME`` are accepted for
``fitness.NAME.weight`` and ``fitness.NAME.target``. ``islands.count`` cannot change during a run.
"""

from __future__ import annotations

import math
import tomllib
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

from genr8_dist.errors import ConfigError, StoreError
from genr8_dist.evolution.individual import parse_id

if TYPE_CHECKING:
    from genr8_dist.config import RunConfig
    from genr8_dist.evolution.individual import Individual
    from genr8_dist.store import RunStore

__all__ = ["Edit", "EditResult", "apply_edit", "parse_assignment", "record_edit", "take_queued"]

FROZEN_KEYS: tuple[str, ...] = ("islands.count",)


@dataclass(frozen=True)
class Edit:
    """What a user asks to change; empty fields change nothing."""

    assignments: Sequence[str] = ()            # "KEY=VALUE"
    inject_copy: Sequence[str] = ()            # individual ids of this run
    inject_text: Sequence[str] = ()            # files holding a rewrite system
    inject_from: Sequence[str] = ()            # "OTHER_RUN:ID"
    island: int | None = None                  # island the injections go to (default: see apply_edit)
    generations: int | None = None             # this many more generations after the last committed
    trust_hooks: bool = False                  # run the universe's stored Python code (--inject-text)
    inject_systems: Sequence[tuple[str, str]] = ()   # (label, rewrite-system text) written by hand
    favour: Sequence[str] = ()                 # ids whose copies join the next generation (studio)
    hand_fitness: Sequence[tuple[str, float]] = ()   # (id, fitness the designer gives it)

    def request(self) -> dict[str, Any]:
        """This edit as queue data: plain JSON, the files of ``inject_text`` read now."""
        systems = [list(pair) for pair in self.inject_systems]
        for name in self.inject_text:
            systems.append([f"text {name}", _read_text(name)])
        return {"kind": "edit", "edit": {
            "assignments": list(self.assignments), "inject_copy": list(self.inject_copy),
            "inject_from": list(self.inject_from), "island": self.island, "generations": self.generations,
            "inject_systems": systems, "favour": list(self.favour),
            "hand_fitness": [[str(i), float(f)] for i, f in self.hand_fitness]}}

    @classmethod
    def from_request(cls, data: Mapping[str, Any]) -> Edit:
        """The edit a queued request holds (``request()``'s inverse); ``ConfigError`` if malformed."""
        try:
            return cls(assignments=tuple(str(a) for a in data.get("assignments") or ()),
                       inject_copy=tuple(str(a) for a in data.get("inject_copy") or ()),
                       inject_from=tuple(str(a) for a in data.get("inject_from") or ()),
                       island=None if data.get("island") is None else int(data["island"]),
                       generations=None if data.get("generations") is None else int(data["generations"]),
                       inject_systems=tuple((str(a), str(b)) for a, b in data.get("inject_systems") or ()),
                       favour=tuple(str(a) for a in data.get("favour") or ()),
                       hand_fitness=tuple((str(a), float(b)) for a, b in data.get("hand_fitness") or ()))
        except (TypeError, ValueError) as exc:
            raise ConfigError(f"a queued intervention is malformed: {exc}") from None


@dataclass(frozen=True)
class EditResult:
    """The new configuration version and what the edit did; ``queued`` names the queue entry when
    the run was running (then ``version`` and ``effective_generation`` are what it would be now)."""

    version: int
    effective_generation: int
    changes: dict[str, Any] = field(default_factory=dict)
    injected: list[dict[str, Any]] = field(default_factory=list)
    last_generation: int = 0
    hand_fitness: list[dict[str, Any]] = field(default_factory=list)
    queued: str | None = None
    set_aside: list[tuple[str, str]] = field(default_factory=list)   # users' files moved (store/foreign.py)


def _read_text(name: str) -> str:
    try:
        return Path(name).read_text(encoding="utf-8")
    except UnicodeDecodeError:
        raise ConfigError(f"--inject-text {name}: not a UTF-8 text file") from None


def _value(text: str) -> Any:
    try:
        return tomllib.loads(f"v = {text}")["v"]
    except tomllib.TOMLDecodeError:
        return text.strip()


def parse_assignment(text: str) -> tuple[tuple[str, ...], Any]:
    """``"fitness.size.weight=2"`` -> ``(("fitness", "size", "weight"), 2)``."""
    key, sep, value = text.partition("=")
    key = key.strip()
    if not sep or not key or any(not part for part in key.split(".")):
        raise ConfigError(f"--set {text!r}: expected KEY=VALUE, e.g. fitness.size.weight=2")
    parts = tuple(p.strip() for p in key.split("."))
    if len(parts) == 3 and parts[0] == "fitness" and parts[1] in ("weights", "targets"):
        parts = ("fitness", parts[2], parts[1][:-1])
    return parts, _value(value)


def _assign(table: dict[str, Any], path: tuple[str, ...], value: Any) -> None:
    old: Any = table
    for part in path:
        old = old.get(part) if isinstance(old, dict) else None
    if isinstance(old, dict) and not isinstance(value, dict):   # `--set ea=1`: a table's name, not a key
        keys = ", ".join(sorted(old)[:6]) + (", ..." if len(old) > 6 else "")
        key = ".".join(path)
        raise ConfigError(f"--set {key}={value!r}: '{key}' is a table of settings ({keys}), not a key; "
                          f"set one of them, e.g. --set {key}.{sorted(old)[0] if old else 'KEY'}=VALUE")
    at = table
    for depth, part in enumerate(path[:-1]):
        nxt = at.get(part)
        if nxt is None:
            nxt = at[part] = {}
        elif not isinstance(nxt, dict):
            where = ".".join(path[: depth + 1])
            raise ConfigError(f"--set {'.'.join(path)}: '{where}' is a value, not a table")
        at = nxt
    at[path[-1]] = value


def _individual(store: RunStore, ident: str, what: str) -> Individual:
    parsed = parse_id(ident.strip())
    if parsed is None:
        raise ConfigError(f"{what} {ident!r}: an individual id is ISLAND-GENERATION-INDEX, e.g. 0-12-3")
    island, generation, index = parsed
    try:
        population = store.load_generation(island, generation)
    except StoreError:
        raise StoreError(f"{what} {ident}: no such individual in {store.path}") from None
    if index >= len(population):
        raise StoreError(f"{what} {ident}: no such individual in {store.path} "
                         f"(generation {generation} of island {island} has {len(population)})")
    return population[index]


def apply_edit(run_dir: str, edit: Edit, *, source: str = "edit") -> EditResult:
    """Check ``edit`` against the run in ``run_dir`` and record it; see the module docstring. When the
    run is running (a driver holds its lock) the edit is checked now and queued for its next epoch."""
    from genr8_dist.store import RunStore

    store = RunStore.open(run_dir)
    lock = store.lock("edit")
    if not lock.acquire():
        request = dict(edit.request(), source=source)
        _, _, result = _prepare(store, Edit.from_request(request["edit"]))
        item = store.enqueue(request)
        return EditResult(result.version, result.effective_generation, result.changes, result.injected,
                          result.last_generation, result.hand_fitness, queued=item.name)
    with lock:
        store.refresh()
        result = record_edit(store, edit, source=source)
    return replace(result, set_aside=list(store.set_aside))


def record_edit(store: RunStore, edit: Edit, *, source: str = "edit",
                request_id: str | None = None, effective: int | None = None) -> EditResult:
    """Record ``edit`` in ``store`` (held by its one writer): a configuration version in force from
    ``effective`` (default: the generation after the last committed one, 0 when none is), with its
    ``intervention`` event."""
    from genr8_dist.store import Event

    config, detail, result = _prepare(store, edit, effective=effective)
    detail["source"] = source
    if request_id is not None:
        detail["queued"] = request_id
    event = Event("intervention", result.effective_generation, None, detail)
    store.add_config(config.to_toml(), result.effective_generation, events=[event])
    return result


def _prepare(store: RunStore, edit: Edit, *,
             effective: int | None = None) -> tuple[RunConfig, dict[str, Any], EditResult]:
    """Everything ``edit`` would record, checked: the new configuration, the event detail, the result."""
    from genr8_dist.config import RunConfig
    from genr8_dist.store import RunStore

    if effective is None:   # versions take effect in order: not before one taken inside an epoch
        effective = max(max(store.committed_generations().values(), default=-1) + 1,
                        int(store.configs()[-1].effective_generation))
    current = store.config(store.configs()[-1])
    data = current.to_dict()
    changes: dict[str, Any] = {}
    for text in edit.assignments:
        path, value = parse_assignment(text)
        key = ".".join(path)
        if key in FROZEN_KEYS:
            raise ConfigError(f"--set {key}: cannot change during a run (it has {current.islands.count} "
                              "islands); start a new run instead")
        _assign(data, path, value)
        if key == "universe":
            data.pop("stored_universe", None)  # another universe: looked up now, then stored
        changes[key] = value
    if edit.generations is not None:
        if edit.generations < 1:
            raise ConfigError(f"--generations {edit.generations}: must be >= 1")
        clash = [key for key in changes if key in ("ea", "ea.generations")]
        if clash:
            raise ConfigError(f"--set {clash[0]} and --generations {edit.generations} both set the run's "
                              "length; give one of them")
        if not isinstance(data.get("ea"), dict):
            raise ConfigError("ea: must be a table of settings")
        data["ea"]["generations"] = effective - 1 + edit.generations
        changes["ea.generations"] = data["ea"]["generations"]
    config = RunConfig.from_dict(data, source="--set", criteria=store.criteria)
    if config.ea.generations < effective:
        raise ConfigError(
            f"ea.generations = {config.ea.generations}: the run has committed generation {effective - 1} "
            f"already; use --generations N to add N more"
        )

    n = config.islands.count
    if edit.island is not None and not 0 <= edit.island < n:
        raise ConfigError(f"--island {edit.island}: the run has islands 0..{n - 1}")
    injected: list[dict[str, Any]] = []
    for ident in edit.inject_copy:
        source = _individual(store, ident, "--inject-copy")
        island = edit.island if edit.island is not None else source.island % n
        injected.append({"island": island, "genome": list(source.genome), "copy_of": source.id,
                         "source": f"copy of {source.id}"})
    for ident in edit.favour:
        source = _individual(store, ident, "favour")
        injected.append({"island": source.island % n, "genome": list(source.genome), "copy_of": source.id,
                         "source": f"favoured {source.id}", "favoured": True})
    systems = [*edit.inject_systems, *((f"text {name}", _read_text(name)) for name in edit.inject_text)]
    if systems:
        from genr8_dist.evolution.evaluate import universe_for
        from genr8_dist.evolution.variation import genome_of
        from genr8_dist.grammar.discovery import consent_for_stored

        consent_for_stored([config.universe_source], trust_flag=edit.trust_hooks,
                           command=f"edit {store.path}")
        universe = universe_for(config)
        for label, text in systems:
            genome = genome_of(config, universe, text)   # GE's inversion, or a text genome
            injected.append({"island": edit.island or 0, "genome": [int(c) for c in genome],
                             "copy_of": None, "source": label})
    for ref in edit.inject_from:
        other_dir, sep, ident = ref.rpartition(":")
        if not sep or not other_dir:
            raise ConfigError(f"--inject-from {ref!r}: expected OTHER_RUN:ID, e.g. runs/a:0-12-3")
        other = RunStore.open(other_dir)
        source = _individual(other, ident, "--inject-from")
        injected.append({"island": edit.island or 0, "genome": list(source.genome), "copy_of": None,
                         "source": f"{other_dir}:{source.id}"})
    per_island: dict[int, int] = {}
    for item in injected:
        per_island[item["island"]] = per_island.get(item["island"], 0) + 1
    room = config.ea.population - config.islands.migrants
    for island, count in per_island.items():
        if count > room:
            raise ConfigError(f"{count} individuals injected into island {island} do not fit: a generation "
                              f"of {config.ea.population} holds at most {room} besides its migrants")
    hand: list[dict[str, Any]] = []
    for ident, value in edit.hand_fitness:
        if not math.isfinite(value) or value < 0:
            raise ConfigError(f"hand fitness {value!r} for {ident}: a fitness is a finite number >= 0 "
                              "(lower is better)")
        source = _individual(store, ident, "hand fitness")
        if not source.valid:
            raise ConfigError(f"hand fitness for {ident}: it failed at {source.stage} ({source.error}) "
                              "and has no phenotype to judge; favour or score a valid design")
        hand.append({"id": source.id, "island": source.island % n, "fitness": float(value),
                     "computed": float(source.fitness)})

    version = len(store.configs()) + 1
    detail: dict[str, Any] = {"config_version": version, "changes": _jsonable(changes), "injected": injected}
    if hand:
        detail["hand_fitness"] = hand
    result = EditResult(version=version, effective_generation=effective, changes=changes, injected=injected,
                        last_generation=config.ea.generations, hand_fitness=hand)
    return config, detail, result


def changes_epochs(edit: Edit) -> bool:
    """Whether ``edit`` changes what an epoch is (migration, islands, the run's last generation): such
    an edit is taken between epochs only."""
    keys = [".".join(parse_assignment(a)[0]) for a in edit.assignments]
    return edit.generations is not None or any(
        k in ("ea", "islands", "ea.generations") or k.startswith("islands.") for k in keys)


def take_queued(store: RunStore, *, during: int | None = None) -> list[tuple[str, Any]]:
    """Record the running run's pending interventions in queue order (the coordinator calls this
    between epochs, as the run's one writer). Returns ``(kind, outcome)`` per request taken: ``edit``
    with its ``EditResult``, ``pause``/``continue``, or ``refused`` with the one-line reason (also
    recorded as a ``refused`` event). A request already recorded (its ``id`` in an event) is dropped.

    ``during=G``: the coordinator is inside an epoch and no island has started generation ``G``; the
    queue's leading edits are recorded in force from ``G``, up to the first request that must wait for
    the epoch's end (``pause``/``continue``, an edit that ``changes_epochs``)."""
    from genr8_dist.errors import Genr8Error
    from genr8_dist.store import Event

    items = store.queued()
    if not items:
        return []
    import json

    done = set()
    for detail in store.events().column("detail").to_pylist():
        queued_id = json.loads(detail or "{}").get("queued")
        if queued_id:
            done.add(queued_id)
    out: list[tuple[str, Any]] = []
    for item in items:
        request = item.request
        if request["id"] in done:
            store.dequeue(item)
            continue
        kind = request.get("kind")
        generation = max(store.committed_generations().values(), default=-1) + 1 if during is None else during
        source = str(request.get("source") or "queue")
        if during is not None and not _takes_now(request):
            break
        try:
            if kind == "edit":
                edit = Edit.from_request(request.get("edit") or {})
                out.append(("edit", record_edit(store, edit, source=source, request_id=request["id"],
                                                effective=during)))
            elif kind in ("pause", "continue"):
                store.record_event(kind, generation=generation, detail={"queued": request["id"],
                                                                        "source": source})
                out.append((kind, generation))
            else:
                raise ConfigError(f"unknown intervention kind {kind!r}")
        except Genr8Error as exc:
            reason = str(exc).splitlines()[0]
            store.commit([], [Event("refused", generation, None, {"queued": request["id"], "reason": reason,
                                                                  "request": request})])
            out.append(("refused", reason))
        store.dequeue(item)
    return out


def _takes_now(request: Mapping[str, Any]) -> bool:
    """Whether a queued request may be taken inside an epoch (an edit that leaves the epochs alone)."""
    if request.get("kind") != "edit":
        return False
    try:
        return not changes_epochs(Edit.from_request(request.get("edit") or {}))
    except ConfigError:
        return True   # malformed: refused at once, whenever it is taken


def _jsonable(value: Any) -> Any:
    if isinstance(value, Mapping):
        return {str(k): _jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_jsonable(v) for v in value]
    if isinstance(value, (str, int, float, bool)) or value is None:
        return value
    return str(value)
