"""Runs the history tests read: a synthetic 4 islands x 50 generations x 50 individuals history written
through the store's own writer, with an intervention (a new fitness target) at generation 30.

Also loaded by tests/cli/test_history.py (by path), so both read the same run.
"""

from __future__ import annotations

from pathlib import Path

from genr8_dist.store import Event, RunStore
from genr8_dist.store.synthetic import synthetic_epoch

ISLANDS, GENERATIONS, POP = 4, 50, 50
INTERVENTION_AT = 30
SEED = 11
TOML_V1 = "[fitness.size]\ntarget = 1.5\nweight = 1.0\n[fitness.symmetry]\ntarget = 0.5\nweight = 2.0\n"
TOML_V2 = "[fitness.size]\ntarget = 0.8\nweight = 1.0\n[fitness.symmetry]\ntarget = 0.5\nweight = 2.0\n"
TEXTS = [f"Edge0 + Edge1 + Edge{n % 3}\nEdge0 -> Edge0 [ + Edge1 ] Edge{n % 2}\nAngle {30 + n}"
         for n in range(20)]


def build_history_run(path: Path) -> RunStore:
    """Create the run at ``path``: epochs of 10 generations, a migration after each epoch, a new
    configuration version (size target 1.5 -> 0.8) in force from generation 30."""
    import pyarrow as pa

    store = RunStore.create(path, TOML_V1)
    for epoch, first in enumerate(range(0, GENERATIONS, 10)):
        last = first + 9
        if first == INTERVENTION_AT:
            store.add_config(TOML_V2, INTERVENTION_AT, events=[
                Event("intervention", INTERVENTION_AT, None,
                      {"version": 2, "changes": {"fitness": {"size": {"target": 0.8}}}})])
        table = synthetic_epoch(store, SEED, epoch, first, last, ISLANDS, POP, (16, 64), TEXTS)
        if first >= INTERVENTION_AT:
            n = table.num_rows
            table = table.set_column(table.schema.get_field_index("config_version"),
                                     table.schema.field("config_version"),
                                     pa.array([2] * n, pa.int32()))
        events = [Event("start", 0, None, {"islands": ISLANDS})] if first == 0 else []
        if last + 1 < GENERATIONS:
            events.append(Event("migration", last, None, {"topology": "ring"}))
        store.commit_table(table, events)
    return store


def targets() -> dict[int, dict[str, float]]:
    """The criterion targets of each configuration version (the defaults for the criteria not set)."""
    from genr8_dist.fitness import DEFAULT_CRITERIA

    base = {name: spec["target"] for name, spec in DEFAULT_CRITERIA.items()}
    return {1: {**base, "size": 1.5, "symmetry": 0.5}, 2: {**base, "size": 0.8, "symmetry": 0.5}}


def units() -> dict[int, dict[str, float]]:
    """The deviation unit of each criterion per version: ``max(1, |target|)`` (no scale set)."""
    return {v: {name: max(1.0, abs(t)) for name, t in table.items()} for v, table in targets().items()}
