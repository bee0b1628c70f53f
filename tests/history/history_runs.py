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


# A real run: genomes mapped, grown and scored by the island (plain Python), committed to the store
# generation by generation, with migration and an intervention that changes the environment.
REAL = {
    "universe": "default",
    "seed": 5,
    "genome": {"length": 60, "max_wraps": 2},
    "ea": {"population": 10, "generations": 3, "elites": 1, "tournament": 2},
    "fitness": {"size": {"target": 6.0}, "subdivisions": {"target": 0.5, "weight": 2.0},
                "undulation": {"target": 1.0}, "smoothness": {"target": 0.0, "weight": 0.0}},
    "environment": {"steps": 3, "scale": 1.5, "seed": 3,
                    "attractors": [{"position": [0.0, 0.0, 2.0], "constant": 4.0, "exponent": 2.0}]},
    "islands": {"count": 2, "migration_interval": 1, "migrants": 1},
}
REAL_INTERVENTION_AT = 2


def build_real_run(path: Path) -> RunStore:
    """Two islands x 4 generations (0..3) x 10 individuals of real evolution; from generation 2 the
    environment's attractor is stronger (configuration version 2); one migrant per island per
    generation along the ring; in generation 3 a copy of generation 1's best is injected into
    island 0."""
    from genr8_dist.config import RunConfig
    from genr8_dist.evolution.island import Island

    config = RunConfig.from_dict(REAL, source="history_runs.REAL")
    store = RunStore.create(path, config.to_toml())
    islands = [Island(config, i) for i in range(2)]
    populations = [island.initial() for island in islands]
    store.commit([ind for pop in populations for ind in pop], [Event("start", 0, None, {"islands": 2})])
    for generation in range(1, config.ea.generations + 1):
        events = [Event("migration", generation - 1, None, {"topology": "ring"})]
        if generation == REAL_INTERVENTION_AT:
            changes = {"environment": {"attractors": [
                {"position": [0.0, 0.0, 2.0], "constant": 6.0, "exponent": 2.0}]}}
            config = config.replace(**changes)
            store.add_config(config.to_toml(), generation, events=[
                Event("intervention", generation, None, {"version": 2, "changes": changes})])
            islands = [Island(config, i, config_version=2) for i in range(2)]
        best = [min(pop, key=lambda ind: (ind.fitness, ind.index)) for pop in populations]
        if generation == 1:
            champion = best[0]
        injected = [champion] if generation == 3 else []
        populations = [island.step(populations[i], generation, migrants=[best[(i - 1) % 2]],
                                   injected=injected if i == 0 else [])
                       for i, island in enumerate(islands)]
        store.commit([ind for pop in populations for ind in pop], events)
    return store
