"""Intervention (thesis 4.2): change a stopped run's configuration and put individuals into it.

An edit becomes a new configuration version in force from the generation after the last committed one,
recorded atomically with an ``intervention`` event that lists what changed and the genomes injected.
``genr8 resume`` then uses the new version from that generation on, and the coordinator hands the
injected genomes to their island at that generation (provenance ``injected``). Everything is checked
before anything is written: a wrong key, a text the universe cannot invert or an unknown individual is
a one-line error and the run directory is left as it was.

Keys (``--set KEY=VALUE``, VALUE in TOML syntax, bare words taken as strings) are the configuration's
own: ``fitness.size.weight=2``, ``ea.mutation_rate=0.05``, ``environment.scale=[1.5, 1.5, 1.2]``,
``islands.topology=random``. ``fitness.weights.NAME`` and ``fitness.targets.NAME`` are accepted for
``fitness.NAME.weight`` and ``fitness.NAME.target``. ``islands.count`` cannot change during a run.
"""

from __future__ import annotations

import tomllib
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from genr8_dist.errors import ConfigError, StoreError

__all__ = ["Edit", "EditResult", "apply_edit", "parse_assignment"]

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


@dataclass(frozen=True)
class EditResult:
    """The new configuration version and what the edit did."""

    version: int
    effective_generation: int
    changes: dict[str, Any] = field(default_factory=dict)
    injected: list[dict[str, Any]] = field(default_factory=list)
    last_generation: int = 0


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


def _individual(store: Any, ident: str, what: str) -> Any:
    parts = ident.strip().split("-")
    if len(parts) != 3 or not all(p.isdigit() for p in parts):
        raise ConfigError(f"{what} {ident!r}: an individual id is ISLAND-GENERATION-INDEX, e.g. 0-12-3")
    island, generation, index = (int(p) for p in parts)
    try:
        population = store.load_generation(island, generation)
    except StoreError:
        raise StoreError(f"{what} {ident}: no such individual in {store.path}") from None
    if index >= len(population):
        raise StoreError(f"{what} {ident}: no such individual in {store.path} "
                         f"(generation {generation} of island {island} has {len(population)})")
    return population[index]


def apply_edit(run_dir: str, edit: Edit) -> EditResult:
    """Check ``edit`` against the run in ``run_dir`` and record it; see the module docstring."""
    from genr8_dist.config import RunConfig
    from genr8_dist.distributed.session import latest_config
    from genr8_dist.store import Event, RunStore

    store = RunStore.open(run_dir)
    committed = store.committed_generations()
    if not committed:
        raise StoreError(f"{run_dir}: no generation is committed yet; there is nothing to edit")
    effective = max(committed.values()) + 1
    current = latest_config(store)
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
        data["ea"]["generations"] = effective - 1 + edit.generations
        changes["ea.generations"] = data["ea"]["generations"]
    config = RunConfig.from_dict(data, source="--set")
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
    if edit.inject_text:
        from genr8_dist.evolution.evaluate import universe_for
        from genr8_dist.grammar.trust import consent_for_stored

        consent_for_stored([config.universe_source], trust_flag=edit.trust_hooks, command=f"edit {run_dir}")
        universe = universe_for(config)
        for name in edit.inject_text:
            try:
                text = Path(name).read_text(encoding="utf-8")
            except UnicodeDecodeError as exc:
                raise ConfigError(f"--inject-text {name}: not UTF-8 text ({exc.reason})") from None
            genome = universe.invert(text, max_depth=config.genome.max_depth)
            injected.append({"island": edit.island or 0, "genome": [int(c) for c in genome],
                             "copy_of": None, "source": f"text {name}"})
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

    version = len(store.configs()) + 1
    detail = {"config_version": version, "changes": _jsonable(changes), "injected": injected}
    event = Event("intervention", effective, None, detail)
    store.add_config(config.to_toml(), effective, events=[event])
    return EditResult(version=version, effective_generation=effective, changes=changes, injected=injected,
                      last_generation=config.ea.generations)


def _jsonable(value: Any) -> Any:
    if isinstance(value, Mapping):
        return {str(k): _jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_jsonable(v) for v in value]
    if isinstance(value, (str, int, float, bool)) or value is None:
        return value
    return str(value)
