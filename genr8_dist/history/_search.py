"""The search modes' views of a run: its Pareto front, its MAP-Elites archive, its clusters of forms.

Each takes a run (directory or open ``RunStore``) and returns an Arrow table of distinct phenotypes
(the best individual of each phenotype digest), with the columns ``top`` returns plus what the view adds:

* ``pareto_front``: the non-dominated phenotypes over the Pareto objectives of the configuration in
  force at the run's end (``search.objectives``, or every criterion with weight > 0), each objective's
  weighted deviation as ``dev_<name>``;
* ``archive``: the MAP-Elites archive after a generation (the best of each cell of the grid of
  ``[search]``), with ``cell`` and one ``bin_<descriptor>`` per axis;
* ``clusters``: the kinds of form among the best distinct designs, told apart by what a person
  sees (a surface's outline, height field, curvature: ``genr8_dist.forms``), each kind's
  representative as far from the others as the pool allows, with ``cluster`` and ``members``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any, cast

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc

from genr8_dist.history._run import (
    HistoryError,
    RunLike,
    as_numpy,
    criteria_of,
    dataset,
    open_run,
    parse_id,
    run_label,
)
from genr8_dist.history._tables import _resolve_generation, _rows_by_ids, form_ids
from genr8_dist.store.schema import (
    criterion_column,
    criterion_of,
    listed_columns,
    size_column,
    size_of,
    sizes_of,
)

__all__ = ["archive", "cluster_ranges", "clusters", "format_range", "pareto_front", "weighted_criteria"]


def _newest_config(store: Any) -> Any:
    return store.config(store.configs()[-1])


def _distinct(store: Any, generation: int | None, island: int | None, extra: list[str]) -> pa.Table:
    """The valid rows (of ``generation``, ``island``), one per form (``form_ids``; the lowest fitness,
    ties to the earliest), sorted by fitness."""
    if generation is None or generation < 0:
        data = dataset(store)
        generation = _resolve_generation(data, generation)
    else:   # one generation: only the files holding it are read (and checked)
        data = dataset(store, (int(generation), int(generation)))
    crits = criteria_of(data.schema)
    filt = pc.field("valid") == True  # noqa: E712  (an Arrow expression)
    if generation is not None:
        filt &= pc.field("generation") == int(generation)
    if island is not None:
        filt &= pc.field("island") == int(island)
    columns = ["id", "generation", "island", "index", "fitness", "phenotype_digest",
               *[size_column(s) for s in sizes_of(data.schema.names)], *[criterion_column(c) for c in crits]]
    columns += [c for c in extra if c in data.schema.names and c not in columns]
    table = data.to_table(columns=columns, filter=filt)
    if table.num_rows == 0:
        raise HistoryError(f"{run_label(store)}: no valid individual"
                           + (f" in generation {generation}" if generation is not None else ""))
    order = np.lexsort((as_numpy(table["index"], 0), as_numpy(table["island"], 0),
                        as_numpy(table["generation"], 0), as_numpy(table["fitness"], math.inf)))
    table = table.take(pa.array(order, pa.int64()))
    _, first = np.unique(form_ids(table), return_index=True)
    return table.take(pa.array(np.sort(first), pa.int64()))


def _with_top_columns(store: Any, ids: list[str]) -> pa.Table:
    parsed = [parse_id(i) for i in ids]
    gens = [p[1] for p in parsed if p is not None]
    data = dataset(store, (min(gens), max(gens)) if gens and len(gens) == len(ids) else None)
    columns = listed_columns(criteria_of(data.schema), sizes=sizes_of(data.schema.names),
                             available=data.schema.names)
    return _rows_by_ids(data, ids, columns)


def pareto_front(run: RunLike, *, generation: int | None = None, island: int | None = None) -> pa.Table:
    """The non-dominated distinct phenotypes of the run (or of ``generation``, ``island``), by fitness."""
    from genr8_dist.evolution.island import pareto_objectives
    from genr8_dist.evolution.pareto import non_dominated_ranks

    store = open_run(run)
    config = _newest_config(store)
    names = [n for n in pareto_objectives(config) if n in criteria_of(dataset(store).schema)]
    if len(names) < 2:
        raise HistoryError(f"{run_label(store)}: a Pareto front needs 2 objectives; the configuration "
                           f"has {len(names)} (set [search] objectives or weights above 0)")
    table = _distinct(store, generation, island, [])
    devs = np.column_stack([
        [config.fitness[n].deviation(v) if v is not None else math.inf
         for v in table[criterion_column(n)].to_pylist()] for n in names])
    front = np.flatnonzero(non_dominated_ranks(devs) == 0)
    rows = _with_top_columns(store, [table["id"][int(i)].as_py() for i in front])
    for j, n in enumerate(names):
        rows = rows.append_column(f"dev_{n}", pa.array(devs[front, j], pa.float64()))
    return rows


def archive(run: RunLike, *, generation: int | None = -1, island: int | None = None) -> pa.Table:
    """The MAP-Elites archive after ``generation`` (default the last; ``None``: the whole run) of the
    grid of the run's ``[search]`` settings: each occupied cell's best individual, by fitness."""
    from genr8_dist.evolution.archive import Grid

    store = open_run(run)
    config = _newest_config(store)
    grid = Grid.from_settings(config.search)
    table = _distinct(store, generation, island, [])
    held: dict[int, tuple[float, str, list[int]]] = {}
    for row in table.to_pylist():
        view = _Row(row)
        cell = grid.cell(view)
        if cell is not None and cell not in held:   # rows come best first
            held[cell] = (row["fitness"], row["id"], list(grid.coordinates(cell)))
    cells = sorted(held, key=lambda c: (held[c][0], c))
    rows = _with_top_columns(store, [held[c][1] for c in cells])
    if "cell" in rows.column_names:   # as stored: the grid in force then; this is the newest grid
        rows = rows.drop_columns(["cell"])
    rows = rows.append_column("cell", pa.array(cells, pa.int32()))
    for j, name in enumerate(grid.descriptors):
        rows = rows.append_column(f"bin_{name}", pa.array([held[c][2][j] for c in cells], pa.int32()))
        rows = rows.append_column(f"value_{name}", pa.array(
            [_value(table, held[c][1], name) for c in cells], pa.float64()))
    return rows


def _value(table: pa.Table, ident: str, name: str) -> float:
    from genr8_dist.evolution.archive import descriptor_value

    row = table.filter(pc.field("id") == ident).to_pylist()[0]
    return descriptor_value(_Row(row), name)


class _Row:
    """A stored row seen as the fields ``Grid`` reads (valid, criteria, sizes)."""

    def __init__(self, row: dict[str, Any]) -> None:
        self.valid = True
        self.fitness = row["fitness"]
        self.sizes = {s: (0 if v is None else v) for k, v in row.items() if (s := size_of(k)) is not None}
        self.criteria = {c: (math.nan if v is None else v)
                         for k, v in row.items() if (c := criterion_of(k)) is not None}


POOL_PER_KIND = 10   # the kinds of form are found among the run's best 10 * k distinct designs


def _farthest(x: np.ndarray, k: int) -> list[int]:
    """``k`` rows of ``x`` (sorted best first) chosen one by one, each the farthest from those already
    chosen (the first: the best); ties to the better."""
    chosen = [0]
    nearest = ((x - x[0]) ** 2).sum(axis=1)
    while len(chosen) < min(k, len(x)):
        i = int(np.argmax(nearest))       # argmax: the first, so the better of equals
        if not nearest[i] > 0:            # every form left is a copy of one chosen
            break
        chosen.append(i)
        nearest = np.minimum(nearest, ((x - x[i]) ** 2).sum(axis=1))
    return chosen


def _criteria_features(table: pa.Table) -> np.ndarray:
    """A phenotype without a surface's descriptors: its standardised criteria and log sizes."""
    crits = criteria_of(table.schema)
    features = [as_numpy(table[criterion_column(c)], math.nan).astype(np.float64) for c in crits]
    features += [np.log1p(as_numpy(table[size_column(s)], 0).astype(np.float64))
                 for s in sizes_of(table.column_names)]
    x = np.column_stack(features)
    x = np.where(np.isfinite(x), x, np.nan)
    fill = np.nanmedian(np.where(np.isnan(x).all(axis=0), 0.0, x), axis=0) if len(x) else 0.0
    x = np.where(np.isnan(x), fill, x)
    spread = x.std(axis=0)
    return cast(np.ndarray, (x - x.mean(axis=0)) / np.where(spread > 0, spread, 1.0))


def _form_features(store: Any, table: pa.Table) -> np.ndarray:
    """What each row looks like (its phenotype's ``looks``, its text developed again under its
    configuration), each block of descriptors scaled to one unit of spread over the rows so that each
    counts alike; the criteria's features when a phenotype has no ``looks``."""
    from genr8_dist.history._run import config_of, phenotype_for

    rows = table.select(["text", "config_version"]).to_pylist()
    configs: dict[int, tuple[Any, Any]] = {}
    found: list[list[np.ndarray]] = []
    for row in rows:
        version = int(row["config_version"])
        if version not in configs:
            config = config_of(store, version)
            configs[version] = (config, phenotype_for(store, config))
        config, phenotype = configs[version]
        try:
            looks = phenotype.looks(phenotype.develop(row["text"], config))
        except Exception:       # a plugin's phenotype may fail again as it failed then
            looks = None
        if looks is None:
            return _criteria_features(table)
        found.append([np.asarray(b, dtype=np.float64).reshape(-1) for b in looks])
    blocks = []
    for j in range(len(found[0])):
        x = np.vstack([f[j] for f in found])
        spread = float(np.sqrt(x.var(axis=0).sum()))
        blocks.append((x - x.mean(axis=0)) / (spread if spread > 0 else 1.0))
    return np.hstack(blocks)


def told_apart_by(run: RunLike) -> str:
    """In words, what ``clusters`` tells the run's kinds of form apart by: a surface's outline, height
    field and curvature; a plugin phenotype's own ``looks``; else its criteria and sizes."""
    from genr8_dist.history._run import phenotype_for
    from genr8_dist.phenotype import Phenotype, SurfacePhenotype

    store = open_run(run)
    phenotype = phenotype_for(store, _newest_config(store))
    if isinstance(phenotype, SurfacePhenotype):
        return "outline, height field and curvature"
    if type(phenotype).looks is not Phenotype.looks:
        return f"what a {phenotype.noun} looks like"
    return "criteria and sizes"


def clusters(run: RunLike, k: int = 12, *, generation: int | None = None,
             island: int | None = None) -> pa.Table:
    """``k`` kinds of form among the run's best ``10 k`` distinct phenotypes (of ``generation``,
    ``island``), chosen by what a person sees: each kind's representative is the design farthest, in
    what it looks like (the phenotype's ``looks``: a surface's outline, height field and curvature,
    ``genr8_dist.forms``), from the kinds already chosen, the first being the best; every design of
    the pool belongs to the kind it looks most like. Per kind: its ``cluster`` number, how many
    ``members`` it has (largest first), their ids (``member_ids``, each form's best) and the range of
    each criterion and of the fitness over them (``min_<name>``, ``max_<name>``; ``cluster_ranges``
    reads them). A phenotype that is not a surface is told apart by its standardised criteria and the
    logs of its sizes. Deterministic: no random draw."""
    if k < 1:
        raise HistoryError(f"clusters: k must be at least 1, got {k}")
    store = open_run(run)
    table = _distinct(store, generation, island, ["text", "config_version"])
    table = table.slice(0, POOL_PER_KIND * k)    # best first
    x = _form_features(store, table)
    picks = _farthest(x, k)
    centres = x[picks]
    labels = np.argmin(((x[:, None, :] - centres[None]) ** 2).sum(axis=2), axis=1)
    labels[picks] = np.arange(len(picks))     # a representative is in its own kind, even among copies
    sizes = [int((labels == c).sum()) for c in range(len(picks))]
    ids = [[table["id"][int(m)].as_py() for m in np.flatnonzero(labels == c)] for c in range(len(picks))]
    raw = {"fitness": as_numpy(table["fitness"], math.nan).astype(np.float64)}
    raw.update({c: as_numpy(table[criterion_column(c)], math.nan).astype(np.float64)
                for c in criteria_of(table.schema)})
    ranges = [{name: _finite_range(values[labels == c]) for name, values in raw.items()}
              for c in range(len(picks))]
    order = sorted(range(len(picks)), key=lambda i: (-sizes[i], picks[i]))
    rows = _with_top_columns(store, [table["id"][picks[i]].as_py() for i in order])
    rows = rows.append_column("cluster", pa.array(list(range(1, len(order) + 1)), pa.int32()))
    rows = rows.append_column("members", pa.array([sizes[i] for i in order], pa.int32()))
    rows = rows.append_column("member_ids", pa.array([ids[i] for i in order], pa.list_(pa.string())))
    for name in raw:
        for end, side in (("min", 0), ("max", 1)):
            rows = rows.append_column(f"{end}_{name}", pa.array([ranges[i][name][side] for i in order],
                                                                pa.float64()))
    return rows


def weighted_criteria(run: RunLike) -> list[str]:
    """The criteria the run's newest configuration weighs (weight above 0), in its order."""
    fitness = _newest_config(open_run(run)).fitness
    return [n for n in fitness.names if fitness[n].weight > 0]


def format_range(low: float | None, high: float | None) -> str:
    """``0.412–1.2`` (4 significant digits), one value when they are equal, ``-`` for none."""
    if low is None or high is None:
        return "-"
    return f"{low:.4g}" if f"{low:.4g}" == f"{high:.4g}" else f"{low:.4g}–{high:.4g}"


def _finite_range(values: np.ndarray) -> tuple[float | None, float | None]:
    finite = values[np.isfinite(values)]
    return (float(finite.min()), float(finite.max())) if finite.size else (None, None)


def cluster_ranges(kinds: pa.Table, names: Sequence[str] | None = None) -> list[dict[str, Any]]:
    """The per-cluster statistics of a ``clusters`` table: per cluster its number, size, the design
    representative and ``ranges``: fitness and each criterion (of ``names``, default all) ->
    ``(min, max)`` over its members (``None`` where no member has a finite value)."""
    kept = None if names is None else {"fitness", *names}
    columns = set(kinds.column_names)
    names = [c[4:] for c in kinds.column_names
             if c.startswith("min_") and f"max_{c[4:]}" in columns and (kept is None or c[4:] in kept)]
    out = []
    for r in kinds.select(["cluster", "members", "id", *[f"{e}_{n}" for n in names for e in ("min", "max")]]
                          ).to_pylist():
        out.append({"cluster": r["cluster"], "members": r["members"], "id": r["id"],
                    "ranges": {n: (r[f"min_{n}"], r[f"max_{n}"]) for n in names}})
    return out
