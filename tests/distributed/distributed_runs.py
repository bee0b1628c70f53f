"""Helpers for the distributed-run tests: a tiny configuration, running a store to its end, its rows.

Imported by the tests of this folder (pytest puts the folder on ``sys.path``) and by the subprocess
scripts they start."""

from __future__ import annotations

import io
import math

TINY = """\
universe = "default"
seed = 7

[genome]
length = 30
max_depth = 4

[ea]
population = 6
generations = {generations}
tournament = 2
elites = 1

[environment]
steps = 2

[islands]
count = {islands}
migration_interval = 2
migrants = 1
topology = "{topology}"
"""


def tiny_toml(*, islands: int = 3, generations: int = 6, topology: str = "ring") -> str:
    """A run of a few seconds: ``islands`` islands of 6, 2 derivation steps, a migration every 2."""
    return TINY.format(islands=islands, generations=generations, topology=topology)


def _plain(value):
    if isinstance(value, float) and math.isnan(value):
        return "nan"
    if isinstance(value, list):
        return [_plain(v) for v in value]
    return value


def rows(run_dir) -> list[dict]:
    """Every individual of a run without its timing columns and run id, ordered by id, NaN comparable."""
    from genr8_dist.store import TIMING_COLUMNS, RunStore

    table = RunStore.open(run_dir).individuals()
    table = table.drop_columns([*TIMING_COLUMNS, "run_id"])
    table = table.sort_by([("island", "ascending"), ("generation", "ascending"), ("index", "ascending")])
    return [{k: _plain(v) for k, v in row.items()} for row in table.to_pylist()]


def event_kinds(run_dir) -> list[str]:
    from genr8_dist.store import RunStore

    return RunStore.open(run_dir).events().column("kind").to_pylist()


def new_run(run_dir, toml: str):
    """A new run directory holding ``toml`` as its configuration (what ``genr8 run`` creates)."""
    from genr8_dist.store import RunStore

    store = RunStore.create(run_dir, toml)
    store.record_event("start", generation=0)
    return store


def drive_to_end(run_dir, hosts=None, **hooks):
    """Run (or go on with) the run in ``run_dir`` on the session's Ray until it ends or a hook stops it;
    on ``hosts`` (a ``HostPool``, rebound to this run) when given, else on hosts of its own."""
    from genr8_dist.distributed.session import RunOptions, drive, latest_config
    from genr8_dist.store import RunStore

    out = io.StringIO()
    store = RunStore.open(run_dir)
    if hosts is not None:
        hosts.rebind(str(store.path), latest_config(store).islands.count)
    summary = drive(store, RunOptions(quiet=False), out=out, hosts=hosts, **hooks)
    return summary, out.getvalue()


def stop_at(generation: int):
    """An ``on_generation`` hook that asks the run to stop once every island completed ``generation``."""
    def hook(coordinator, g):
        if g >= generation:
            coordinator.stop.set("test")
    return hook
