"""Synthetic run histories, written with the store's own writer, for benchmarks and scale tests.

The rows look like a real run's (fitness improving over generations, about 10% invalid individuals
with their failing stage, elites, crossover and mutation children with their parents, migrants at
every epoch) but nothing is grown: its individuals cannot be regrown from them. Same arguments, same rows.
"""

from __future__ import annotations

import os
from typing import TYPE_CHECKING, Any

from genr8_dist.errors import StoreError
from genr8_dist.evolution.individual import stored_columns
from genr8_dist.rng import stream
from genr8_dist.store.runstore import RunStore
from genr8_dist.store.schema import Event, criterion_column

if TYPE_CHECKING:
    import numpy as np
    import pyarrow as pa
    import pyarrow.fs as pafs

__all__ = ["synthetic_epoch", "write_synthetic_run"]

_ELITES = 2
_MIGRANTS = 2
_TEXT_POOL = 64


def write_synthetic_run(
    path: str | os.PathLike[str],
    n_islands: int,
    n_generations: int,
    pop: int,
    seed: int,
    *,
    generations_per_commit: int = 10,
    genome_length: tuple[int, int] = (16, 128),
    filesystem: pafs.FileSystem | None = None,
) -> RunStore:
    """Create a run at ``path`` holding ``n_islands * n_generations * pop`` synthetic individuals,
    committed ``generations_per_commit`` generations at a time (one epoch per commit) with a migration
    event per epoch, a start and a complete event. Returns the open store."""
    for name, value, least in (("n_islands", n_islands, 1), ("n_generations", n_generations, 1),
                               ("pop", pop, _ELITES + _MIGRANTS + 1),
                               ("generations_per_commit", generations_per_commit, 1)):
        if isinstance(value, bool) or not isinstance(value, int) or value < least:
            raise StoreError(f"write_synthetic_run: {name} must be an integer >= {least}, got {value!r}")
    lo, hi = genome_length
    if not 1 <= lo <= hi:
        raise StoreError(
            f"write_synthetic_run: genome_length must be (lo, hi) with 1 <= lo <= hi, got {genome_length}"
        )
    config = (   # a run configuration (readers such as the studio parse it) of the history's shape
        "# synthetic history written by genr8_dist.store.synthetic; its individuals cannot be regrown\n"
        f'universe = "default"\nseed = {seed}\n\n[ea]\npopulation = {pop}\n'
        f"generations = {n_generations - 1}\n\n[islands]\ncount = {n_islands}\n"
        f"migration_interval = {generations_per_commit}\nmigrants = {min(2, pop - 1)}\n"
    )
    store = RunStore.create(path, config, filesystem=filesystem)
    texts = _text_pool(seed)
    first = 0
    epoch = 0
    while first < n_generations:
        last = min(first + generations_per_commit, n_generations) - 1
        table = synthetic_epoch(store, seed, epoch, first, last, n_islands, pop, genome_length, texts)
        events = []
        if first == 0:
            events.append(Event("start", 0, None, {"islands": n_islands, "synthetic": True}))
        if last + 1 < n_generations:
            events.append(Event("migration", last, None,
                                {"topology": "ring", "migrants_per_island": _MIGRANTS}))
        else:
            events.append(Event("complete", last, None, {"generations": n_generations}))
        store.commit_table(table, events)
        first = last + 1
        epoch += 1
    return store


def _text_pool(seed: int) -> list[str]:
    rng = stream(seed, "synthetic", "texts")
    symbols = ["a", "b", "c", "d"]
    pool = []
    for _ in range(_TEXT_POOL):
        axiom = " ".join(symbols[: int(rng.integers(3, 5))])
        rules = []
        for s in symbols[: int(rng.integers(1, 4))]:
            tokens = [s, "+", "-", "[", "]", "a", "b"]
            succ = " ".join(str(rng.choice(tokens)) for _ in range(int(rng.integers(2, 7))))
            rules.append(f"{s} -> {succ}")
        pool.append(f"Angle {int(rng.integers(10, 90))}\nAxiom {axiom}\n" + "\n".join(rules))
    return pool


def synthetic_epoch(
    store: RunStore,
    seed: int,
    epoch: int,
    first: int,
    last: int,
    n_islands: int,
    pop: int,
    genome_length: tuple[int, int],
    texts: list[str],
) -> pa.Table:
    """The rows of generations ``first..last`` of every island, as a table of ``store.schema``."""
    import numpy as np
    import pyarrow as pa
    import pyarrow.compute as pc

    rng = stream(seed, "synthetic", "epoch", epoch)
    n_gen = last - first + 1
    n = n_islands * n_gen * pop
    island = np.repeat(np.arange(n_islands, dtype=np.int32), n_gen * pop)
    generation = np.tile(np.repeat(np.arange(first, last + 1, dtype=np.int32), pop), n_islands)
    index = np.tile(np.arange(pop, dtype=np.int32), n_islands * n_gen)

    lengths = rng.integers(genome_length[0], genome_length[1] + 1, size=n)
    offsets = np.zeros(n + 1, dtype=np.int32)
    np.cumsum(lengths, out=offsets[1:])
    genome = pa.ListArray.from_arrays(
        pa.array(offsets), pa.array(rng.integers(0, 256, size=int(offsets[-1]), dtype=np.int32))
    )

    valid = rng.random(n) >= 0.1
    stage_pick = rng.random(n) < 0.5
    has_text = valid | ~stage_pick
    text = pa.array(texts).take(pa.array(rng.integers(0, len(texts), size=n)))
    text = pc.if_else(pa.array(has_text), text, pa.scalar(None, pa.string()))
    none = np.full(n, None, dtype=object)
    stage = np.where(valid, none, np.where(stage_pick, "map", "grow"))
    error = np.where(valid, none, np.where(stage_pick, "genome ran out of codons after 3 wraps",
                                           "growth produced no regions"))

    decay = 1.0 + 9.0 * np.exp(-generation / max(1.0, (first + n_gen + 30) / 3.0))
    columns: dict[str, Any] = {}
    crit_sum = np.zeros(n)
    for name in store.criteria:
        value = rng.gamma(2.0, 0.25, size=n) * decay
        crit_sum += value
        columns[criterion_column(name)] = pa.array(value, mask=~valid)
    fitness = np.where(valid, crit_sum, np.inf)

    origin, parents = _provenance(rng, island, generation, index, n_islands, pop)
    n_vertices = np.where(valid, rng.integers(8, 4000, size=n), 0).astype(np.int64)
    digest_bytes = rng.integers(0, 256, size=(n, 16), dtype=np.uint8)
    hex_chars = np.frombuffer(b"0123456789abcdef", dtype=np.uint8)
    digest_hex = np.empty((n, 32), dtype=np.uint8)
    digest_hex[:, 0::2] = hex_chars[digest_bytes >> 4]
    digest_hex[:, 1::2] = hex_chars[digest_bytes & 15]
    digest = pc.if_else(pa.array(valid), pa.array(digest_hex.view("S32").ravel()).cast(pa.string()),
                        pa.scalar(None, pa.string()))
    timing = rng.gamma(2.0, 0.02, size=(4, n))

    ids = pc.binary_join_element_wise(
        *(pc.cast(pa.array(a), pa.string()) for a in (island, generation, index)), "-"
    )
    data: dict[str, Any] = {
        "run_id": pa.array(np.full(n, store.run_id, dtype=object), pa.string()),
        "id": ids,
        "island": island,
        "generation": generation,
        "index": index,
        "genome": genome,
        "text": text,
        "valid": valid,
        "stage": pa.array(stage, pa.string()),
        "error": pa.array(error, pa.string()),
        "fitness": fitness,
        **columns,
        "origin": pa.array(origin, pa.string()),
        "parents": parents,
        "config_version": np.ones(n, dtype=np.int32),
        "codons_used": np.minimum(lengths, rng.integers(4, genome_length[1] + 1, size=n)).astype(np.int32),
        "wraps": rng.integers(0, 3, size=n).astype(np.int32),
        "size_vertices": n_vertices,
        "size_edges": (n_vertices * 2 - np.minimum(n_vertices, 2)).astype(np.int64),
        "size_regions": np.where(valid, n_vertices // 3, 0).astype(np.int64),
        "steps_done": np.where(valid, rng.integers(1, 9, size=n), 0).astype(np.int32),
        "capped": pa.array(np.where(valid & (n_vertices > 3800), "vertices", none), pa.string()),
        "phenotype_digest": digest,
        "eval_seconds": timing.sum(axis=0),
        "map_seconds": timing[0],
        "grow_seconds": timing[1] + timing[2],
        "score_seconds": timing[3],
    }
    return _as_table(data, store.schema, n)


def _as_table(data: dict[str, Any], schema: pa.Schema, n: int) -> pa.Table:
    """The columns of ``schema`` from ``data``; a column it has no values for (one registered by a
    plugin) holds the column's declared default in every row."""
    import pyarrow as pa

    defaults = {c.name: c.default for c in stored_columns()}
    arrays = []
    for f in schema:
        values = data.get(f.name)
        if values is None:
            values = [defaults.get(f.name)] * n
        arrays.append(values.cast(f.type) if isinstance(values, pa.Array) else pa.array(values, f.type))
    return pa.Table.from_arrays(arrays, schema=schema)


def _provenance(
    rng: np.random.Generator, island: np.ndarray, generation: np.ndarray, index: np.ndarray,
    n_islands: int, pop: int,
) -> tuple[np.ndarray, pa.Array]:
    """Each row's origin and parents' ids: elites keep their index, children have one or two parents
    in the previous generation of their island, migrants come from the previous island."""
    import numpy as np
    import pyarrow as pa
    import pyarrow.compute as pc

    n = len(index)
    kind = rng.choice(np.array(["crossover", "mutation", "crossover+mutation"]), size=n, p=[0.3, 0.3, 0.4])
    origin = np.where(index < _ELITES, "elite", kind).astype(object)
    migrant = (index >= pop - _MIGRANTS) & (generation > 0) & (n_islands > 1)
    origin[migrant] = "migrant"
    origin[generation == 0] = "random"
    count = np.where(origin == "random", 0,
                     np.where((origin == "crossover") | (origin == "crossover+mutation"), 2, 1))
    parent_row = np.repeat(np.arange(n), count)
    parent_island = island[parent_row].copy()
    parent_island[migrant[parent_row]] = (parent_island[migrant[parent_row]] - 1) % max(n_islands, 1)
    parent_index = rng.integers(0, pop, size=len(parent_row)).astype(np.int32)
    elite = origin[parent_row] == "elite"
    parent_index[elite] = index[parent_row][elite]
    parent_gen = generation[parent_row] - 1
    if len(parent_row):
        parent_ids = pc.binary_join_element_wise(
            *(pc.cast(pa.array(a), pa.string()) for a in (parent_island, parent_gen, parent_index)), "-"
        )
    else:
        parent_ids = pa.array([], pa.string())
    offsets = np.zeros(n + 1, dtype=np.int32)
    np.cumsum(count, out=offsets[1:])
    return origin, pa.ListArray.from_arrays(pa.array(offsets), parent_ids)
