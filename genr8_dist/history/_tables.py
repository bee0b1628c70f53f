"""The history of a run as Arrow tables: fitness per generation and island, the best individuals, one
individual's row, its ancestry, the events, and SQL over all of it.

Everything reads the committed Parquet files alone, through column projection and filters pushed
down to the files, so a history of a million individuals answers in well under a second; genomes
and rewrite-system texts are read only for the rows that are shown.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any, cast

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc

from genr8_dist.fitness import SURFACE, criterion_names
from genr8_dist.history._run import (
    HistoryError,
    RunLike,
    as_numpy,
    criteria_of,
    dataset,
    deviation,
    open_run,
    parse_id,
    run_label,
    targets_by_version,
)
from genr8_dist.store.schema import criterion_column, listed_columns, size_column, sizes_of

if TYPE_CHECKING:
    from genr8_dist.store import RunStore

__all__ = [
    "configs",
    "events",
    "individual",
    "interventions",
    "lineage",
    "per_generation",
    "query",
    "top",
]



def _groups(key: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Start offsets and sizes of the runs of equal values in the sorted ``key``."""
    if not len(key):
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    starts = np.flatnonzero(np.r_[True, key[1:] != key[:-1]])
    counts = np.diff(np.r_[starts, len(key)])
    return starts, counts


def per_generation(run: RunLike, *, island: int | None = None) -> pa.Table:
    """Per generation and island: how many individuals (``n``, ``n_valid``), the best, median, worst
    and mean total fitness of the valid ones, the best individual's id, and for every criterion the
    raw value closest to its target under the configuration version then in force (``closest_<name>``:
    the value nearest the target among the generation's individuals, not necessarily the best one's).

    Rows are sorted by generation, then island; a group without a valid individual has nulls.
    """
    store = open_run(run)
    data = dataset(store)
    crits = criteria_of(data.schema)
    columns = ["generation", "island", "index", "fitness", "valid", "config_version"]
    columns += [criterion_column(c) for c in crits]
    filt = None if island is None else pc.field("island") == int(island)
    table = data.to_table(columns=columns, filter=filt)
    if table.num_rows == 0:
        raise HistoryError(f"{run_label(store)}: no island {island} in this run")

    gen = as_numpy(table["generation"], -1).astype(np.int64)
    isl = as_numpy(table["island"], -1).astype(np.int64)
    fit = as_numpy(table["fitness"], math.inf).astype(np.float64)
    valid = pc.fill_null(table["valid"], False).to_numpy(zero_copy_only=False)
    fit = np.where(valid & np.isfinite(fit), fit, np.inf)

    key = gen * (int(isl.max()) + 1) + isl
    order = pc.sort_indices(pa.table({"k": key, "f": fit}),
                            sort_keys=[("k", "ascending"), ("f", "ascending")]).to_numpy()
    starts, counts = _groups(key[order])
    fs = fit[order]
    n_valid = np.add.reduceat(np.isfinite(fs).astype(np.int64), starts)
    has = n_valid > 0
    last = starts + np.maximum(n_valid, 1) - 1
    lo = starts + np.maximum(n_valid - 1, 0) // 2
    hi = starts + n_valid // 2
    hi = np.where(has, hi, starts)
    sums = np.add.reduceat(np.where(np.isfinite(fs), fs, 0.0), starts)
    first_rows = order[starts]

    def masked(values: np.ndarray) -> pa.Array:
        return pa.array(values, type=pa.float64(), mask=~has)

    index = as_numpy(table["index"], -1).astype(np.int64)
    best_ids = [f"{i}-{g}-{n}" if ok else None
                for i, g, n, ok in zip(isl[first_rows], gen[first_rows], index[first_rows], has,
                                       strict=True)]
    out: dict[str, Any] = {
        "generation": pa.array(gen[first_rows], pa.int32()),
        "island": pa.array(isl[first_rows], pa.int32()),
        "n": pa.array(counts, pa.int64()),
        "n_valid": pa.array(n_valid, pa.int64()),
        "best": masked(fs[starts]),
        "median": masked((fs[lo] + fs[hi]) / 2.0),
        "worst": masked(fs[last]),
        "mean": masked(sums / np.maximum(n_valid, 1)),
        "best_id": pa.array(best_ids, pa.string()),
    }
    if crits:
        targets = targets_by_version(store, crits)
        versions = as_numpy(table["config_version"], -1).astype(np.int64)
        for name in crits:
            raw = as_numpy(table[criterion_column(name)], math.nan).astype(np.float64, copy=False)
            dev = deviation(raw, versions, name, targets)[order]
            mins = np.minimum.reduceat(dev, starts)
            hit = np.flatnonzero(dev == np.repeat(mins, counts))
            first = hit[np.searchsorted(hit, starts)]
            out[f"closest_{name}"] = pa.array(raw[order[first]], pa.float64(), mask=~np.isfinite(mins))
    return pa.table(out)


def _last_generation(data: Any) -> int:
    return int(pc.max(data.to_table(columns=["generation"])["generation"]).as_py())


def _resolve_generation(data: Any, generation: int | None) -> int | None:
    """``None`` stays ``None``; a negative generation counts back from the last (-1 is the last)."""
    if generation is None or generation >= 0:
        return generation
    last = _last_generation(data)
    resolved = last + 1 + int(generation)
    if resolved < 0:
        raise HistoryError(f"generation {generation}: the run has only {last + 1} generations")
    return resolved


def _rows_by_ids(data: Any, ids: list[str], columns: list[str]) -> pa.Table:
    """The rows with these ids, in the order given, reading only the generations they name."""
    parsed = [parse_id(i) for i in ids]
    gens = sorted({p[1] for p in parsed if p is not None})
    filt = pc.field("id").isin(ids)
    if gens and all(p is not None for p in parsed):
        filt = pc.field("generation").isin(gens) & filt
    found = data.to_table(columns=columns, filter=filt)
    position = {value: n for n, value in enumerate(found["id"].to_pylist())}
    take = [position[i] for i in ids if i in position]
    return found.take(pa.array(take, pa.int64()))


def form_ids(table: pa.Table) -> np.ndarray:
    """One integer per row of ``table`` naming its *form*: rows with equal sizes and raw criteria (to
    9 significant digits) are one form, whatever their digest. An elite and its copies are one form,
    and so are mirror images (a rule text differing only by ``&``/``^``), which every criterion and
    size measures alike and a designer sees as the same design. Without size or criterion columns
    the digest decides."""
    columns = [c for c in table.column_names if c.startswith(("crit_", "size_"))]
    if not columns:
        digests = table["phenotype_digest"].to_pylist()
        return np.unique(np.array([str(d) for d in digests]), return_inverse=True)[1]
    values = np.column_stack([as_numpy(table[c], math.nan).astype(np.float64) for c in columns])
    finite = np.isfinite(values)
    magnitude = np.floor(np.log10(np.where(finite & (values != 0), np.abs(values), 1.0)))
    scale = 10.0 ** (8 - magnitude)
    rounded = np.where(finite, np.round(values * scale) / scale, np.nan_to_num(values, nan=-1e300))
    return np.unique(rounded, axis=0, return_inverse=True)[1].reshape(-1)


def top(run: RunLike, k: int = 10, *, generation: int | None = None, island: int | None = None,
        criterion: str | None = None, systems: bool = False, under: int | None = None,
        distinct: bool = False) -> pa.Table:
    """The ``k`` best valid individuals (lowest total fitness, or with ``criterion`` the raw value
    closest to that criterion's target), optionally only of one ``generation`` (negative counts back
    from the last) and ``island``. Ties are broken by generation, island and index.

    ``fitness`` is what the run stored: the fitness under the configuration version that scored the
    individual (``config_version``). After an edit of the fitness, individuals scored under different
    versions do not compare; with ``under=V`` every one is rescored from its stored raw criteria with
    version V's targets and weights, ranked by that, and the column ``fitness_v<V>`` holds it.

    Columns: ``rank``, then those the stored row declares for ``top`` (the id and position,
    ``fitness``, every ``crit_<name>``, how it was made and its growth statistics); ``deviation``
    when ranking by a criterion; ``fitness_v<V>`` with ``under``; ``text`` (its rewrite system) when
    ``systems``.

    With ``distinct``, only the best individual of each form (``form_ids``) is listed, and the column
    ``copies`` says how many valid individuals in scope share its form.
    """
    if k < 1:
        raise HistoryError(f"k: must be at least 1, got {k}")
    store = open_run(run)
    data = dataset(store)
    crits = criteria_of(data.schema)
    if criterion is not None and criterion not in crits:
        raise HistoryError(f"criterion {criterion!r}: unknown; the run records {', '.join(crits)}")
    generation = _resolve_generation(data, generation)

    filt = pc.field("valid") == True  # noqa: E712  (an Arrow expression, not a Python test)
    if generation is not None:
        filt &= pc.field("generation") == int(generation)
    if island is not None:
        filt &= pc.field("island") == int(island)
    rank_cols = ["generation", "island", "index", "fitness", "config_version"]
    if criterion is not None:
        rank_cols.append(criterion_column(criterion))
    elif under is not None:
        rank_cols += [criterion_column(c) for c in crits]
    if distinct:
        rank_cols += [c for c in [*(criterion_column(c) for c in crits),
                                  *(size_column(s) for s in sizes_of(data.schema.names))]
                      if c not in rank_cols] + ["phenotype_digest"]
    table = data.to_table(columns=rank_cols, filter=filt)
    if table.num_rows == 0:
        where = []
        if generation is not None:
            where.append(f"generation {generation}")
        if island is not None:
            where.append(f"island {island}")
        scope = " of " + ", ".join(where) if where else ""
        raise HistoryError(f"{run_label(store)}: no valid individual{scope}")

    if criterion is None and under is not None:
        score = rescored(store, table, crits, under)
    elif criterion is None:
        score = as_numpy(table["fitness"], math.inf).astype(np.float64)
    else:
        targets = targets_by_version(store, crits)
        score = deviation(as_numpy(table[criterion_column(criterion)], math.nan).astype(np.float64),
                          as_numpy(table["config_version"], -1).astype(np.int64), criterion, targets)
    score = np.where(np.isnan(score), np.inf, score)
    copies = None
    if distinct:
        forms = form_ids(table)
        order = np.lexsort((as_numpy(table["index"], -1), as_numpy(table["island"], -1),
                            as_numpy(table["generation"], -1), score))
        _, first = np.unique(forms[order], return_index=True)
        keep = order[np.sort(first)]   # each form's best row, in rank order
        counts = np.bincount(forms)
        copies = counts[forms[keep]]
        table, score = table.take(pa.array(keep, pa.int64())), score[keep]
    if len(score) > k:
        threshold = np.partition(score, k - 1)[k - 1]
        candidates = np.flatnonzero(score <= threshold)
    else:
        candidates = np.arange(len(score))
    gen = as_numpy(table["generation"], -1)[candidates]
    isl = as_numpy(table["island"], -1)[candidates]
    idx = as_numpy(table["index"], -1)[candidates]
    chosen = np.lexsort((idx, isl, gen, score[candidates]))[:k]
    ids = [f"{i}-{g}-{n}" for i, g, n in zip(isl[chosen], gen[chosen], idx[chosen], strict=True)]

    columns = listed_columns(crits, sizes=sizes_of(data.schema.names), available=data.schema.names)
    if systems:
        columns.append("text")
    rows = _rows_by_ids(data, ids, columns)
    rows = rows.add_column(0, "rank", pa.array(np.arange(1, rows.num_rows + 1), pa.int32()))
    if copies is not None:
        rows = rows.append_column("copies", pa.array(copies[candidates][chosen], pa.int64()))
    if criterion is not None:
        rows = rows.append_column("deviation", pa.array(score[candidates][chosen], pa.float64()))
    elif under is not None:
        rows = rows.append_column(f"fitness_v{under}", pa.array(score[candidates][chosen], pa.float64()))
    return rows


def rescored(store: RunStore, table: pa.Table, crits: list[str], version: int) -> np.ndarray:
    """The total fitness of each row of ``table`` (valid rows with their ``crit_<name>`` columns) under
    configuration ``version``'s targets and weights: ``sum w * |raw - target| / unit``, as the run
    scores (``FitnessSpec.evaluate``); ``inf`` where a weighted raw value is missing. A universe whose
    phenotype combines its criteria otherwise (``genr8_dist.phenotype``) is rescored by its
    phenotype's ``fitness``."""
    chosen = [cv for cv in store.configs() if int(cv.version) == int(version)]
    if not chosen:
        raise HistoryError(f"{run_label(store)}: no configuration version {version}")
    if not set(store.criteria) <= set(criterion_names(SURFACE)):
        from genr8_dist.history._run import config_of, phenotype_for

        config = config_of(store, version)
        phenotype = phenotype_for(store, config)
        columns = {c: as_numpy(table[criterion_column(c)], math.nan).astype(np.float64) for c in crits}
        return np.array([phenotype.fitness({c: float(v[i]) for c, v in columns.items()}, config)
                         for i in range(table.num_rows)], dtype=np.float64)
    spec = store.fitness(chosen[0])
    total = np.zeros(table.num_rows)
    for c in spec.criteria:
        if c.weight == 0.0:
            continue
        if c.name not in crits:
            raise HistoryError(f"{run_label(store)}: version {version} weighs criterion {c.name!r}, "
                               "which the run does not record")
        raw = as_numpy(table[criterion_column(c.name)], math.nan).astype(np.float64)
        with np.errstate(invalid="ignore"):
            dev = c.weight * np.abs(raw - c.target) / c.unit
        total += np.where(np.isfinite(raw), dev, np.inf)
    return total


def individual(run: RunLike, id: str, columns: list[str] | None = None) -> pa.Table:
    """The row of individual ``id`` (all columns, or ``columns``) as a one-row table."""
    store = open_run(run)
    parsed = parse_id(str(id))   # an id names its generation: only the files holding it are read
    data = dataset(store, None if parsed is None else (parsed[1], parsed[1]))
    if columns is not None and "id" not in columns:
        columns = ["id", *columns]
    rows = _rows_by_ids(data, [str(id)], columns or data.schema.names)
    if rows.num_rows == 0:
        raise HistoryError(f"{run_label(store)}: no individual with id {id!r} in this run")
    return rows.slice(0, 1)


def _parse_ids(ids: pa.Array | pa.ChunkedArray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``"I-G-N"`` strings -> (island, generation, index) int64 arrays; -1 where a string is not an
    id of this form (e.g. an individual injected from another run)."""
    parts = pc.split_pattern(ids, "-")
    ok = pc.fill_null(pc.equal(pc.list_value_length(parts), 3), False)
    out = []
    for k in range(3):
        part = pc.list_element(pc.if_else(ok, parts, pa.scalar(["x", "x", "x"], parts.type)), k)
        digits = pc.fill_null(pc.match_substring_regex(part, r"^[0-9]{1,9}$"), False)
        ok = pc.and_(ok, digits)
        out.append(part)
    okn = ok.to_numpy(zero_copy_only=False)
    arrays = []
    for part in out:
        clean = pc.if_else(ok, part, pa.scalar("0"))
        values = pc.cast(clean, pa.int64()).to_numpy(zero_copy_only=False).copy()
        values[~okn] = -1
        arrays.append(values)
    return arrays[0], arrays[1], arrays[2]


def lineage(run: RunLike, id: str, *, depth: int | None = None) -> pa.Table:
    """The ancestry of individual ``id``: itself and every ancestor back to the first generation (or
    ``depth`` generations back), with how each was made (``origin``) and from whom (``parents``).

    ``main_line`` marks the chain that follows each individual's first parent (the one its genome
    starts from); ``missing`` lists parent ids the run does not hold (e.g. injected from another
    run). Rows are sorted by generation (latest first), then island and index. The walk is
    vectorised over whole generations, so even an ancestry of a million individuals takes seconds.
    """
    if depth is not None and depth < 0:
        raise HistoryError(f"depth: must be 0 or more generations back, got {depth}")
    store = open_run(run)
    start = individual(store, id, ["generation"])
    g0 = int(start["generation"][0].as_py())
    lowest = 0 if depth is None else max(0, g0 - int(depth))
    data = dataset(store, (lowest, g0))
    columns = ["id", "generation", "island", "index", "origin", "parents", "fitness", "valid"]
    filt = (pc.field("generation") <= g0) & (pc.field("generation") >= lowest)
    table = data.to_table(columns=columns, filter=filt)
    table = table.take(pc.sort_indices(table, sort_keys=[("generation", "ascending"),
                                                         ("island", "ascending"),
                                                         ("index", "ascending")]))
    n = table.num_rows
    gen = as_numpy(table["generation"], -1).astype(np.int64)
    isl = as_numpy(table["island"], -1).astype(np.int64)
    idx = as_numpy(table["index"], -1).astype(np.int64)
    n_isl, n_idx = int(isl.max()) + 1, int(idx.max()) + 1

    def key(i: np.ndarray, g: np.ndarray, k: np.ndarray) -> np.ndarray:
        return cast(np.ndarray, ((g - lowest) * n_isl + i) * n_idx + k)

    lookup = np.full((g0 - lowest + 1) * n_isl * n_idx, -1, dtype=np.int64)
    lookup[key(isl, gen, idx)] = np.arange(n)

    parents = table["parents"].combine_chunks()
    offsets = parents.offsets.to_numpy().astype(np.int64)
    offsets = offsets - offsets[0]
    flat = parents.flatten()
    p_isl, p_gen, p_idx = _parse_ids(flat)
    inside = (p_gen >= lowest) & (p_gen <= g0) & (p_isl >= 0) & (p_isl < n_isl) & (p_idx >= 0) & (
        p_idx < n_idx)
    parent_row = np.full(len(flat), -1, dtype=np.int64)
    parent_row[inside] = lookup[key(p_isl[inside], p_gen[inside], p_idx[inside])]
    beyond = (p_gen >= 0) & (p_gen < lowest)  # older than asked for: not missing, just not shown
    missing_flat = (parent_row < 0) & ~beyond

    starts, counts = _groups(gen)
    start_row = int(np.flatnonzero(pc.equal(table["id"], str(id)).to_numpy(zero_copy_only=False))[0])
    marked = np.zeros(n, dtype=bool)
    marked[start_row] = True
    for s, c in zip(starts[::-1], counts[::-1], strict=True):
        lo, hi = int(offsets[s]), int(offsets[s + c])
        owner = np.repeat(np.arange(s, s + c), np.diff(offsets[s:s + c + 1]))
        while True:  # parents in the same generation (if any) are marked before moving on
            chosen = parent_row[lo:hi][marked[owner]]
            chosen = chosen[chosen >= 0]
            fresh = chosen[~marked[chosen]]
            if not len(fresh):
                break
            marked[fresh] = True
            if not np.any((fresh >= s) & (fresh < s + c)):
                break

    line = np.zeros(n, dtype=bool)
    current = start_row
    while current >= 0 and not line[current]:
        line[current] = True
        first = offsets[current]
        current = int(parent_row[first]) if offsets[current + 1] > first else -1

    rows = np.flatnonzero(marked)
    order = np.lexsort((idx[rows], isl[rows], -gen[rows]))
    rows = rows[order]
    result = table.take(pa.array(rows, pa.int64()))
    result = result.append_column("main_line", pa.array(line[rows], pa.bool_()))
    owner_all = np.repeat(np.arange(n), np.diff(offsets))
    missing_rows = np.unique(owner_all[missing_flat & marked[owner_all]])
    flat_text = flat.to_pylist() if len(missing_rows) else []
    missing: dict[int, list[str]] = {int(r): [flat_text[j] for j in range(offsets[r], offsets[r + 1])
                                              if missing_flat[j]] for r in missing_rows}
    result = result.append_column("missing", pa.array(
        [missing.get(int(r), []) for r in rows], pa.list_(pa.string())))
    return result


def events(run: RunLike, kind: str | None = None) -> pa.Table:
    """The run's events (start, migration, intervention, interrupt, resume, recovery), or one kind."""
    store = open_run(run)
    table = store.events()
    if kind is not None:
        table = table.filter(pc.equal(table["kind"], kind))
    return table


def interventions(run: RunLike) -> pa.Table:
    """The interventions: each edit of the run with the generation it took effect and its detail."""
    return events(run, "intervention")


def configs(run: RunLike) -> pa.Table:
    """The configuration versions: ``version``, ``effective_generation``, ``toml``, ``created``."""
    store = open_run(run)
    rows = list(store.configs())
    return pa.table({
        "version": pa.array([int(c.version) for c in rows], pa.int32()),
        "effective_generation": pa.array([int(c.effective_generation) for c in rows], pa.int32()),
        "toml": pa.array([c.toml for c in rows], pa.string()),
        "created": pa.array([str(c.created) for c in rows], pa.string()),
    })


def _one_line(message: str) -> str:
    lines = [line.strip() for line in str(message).splitlines() if line.strip()]
    if not lines:
        return "error"
    head, rest = lines[0], [line for line in lines[1:] if not set(line) <= {"^", " "}]
    return head + (f" ({'; '.join(rest)})" if rest else "")


QUERY_TIMEOUT = 60.0
"""Seconds a ``query`` statement may run before it is interrupted (``genr8 query --timeout``)."""

_SANDBOX = {
    "enable_external_access": False,      # no files, no network: read_csv, COPY, ATTACH, INSTALL...
    "python_enable_replacements": False,  # no Python variables as tables, only the three registered
    "autoinstall_known_extensions": False,
    "autoload_known_extensions": False,
    "temp_directory": "",                 # never spill to disk: query writes nothing anywhere
    "lock_configuration": True,           # and no SET can undo any of it
}


def query(run: RunLike, sql: str, *, timeout: float = QUERY_TIMEOUT, as_of: int | None = None) -> pa.Table:
    """The result of ``sql`` (DuckDB's dialect) over the tables ``individuals``, ``events`` and
    ``configs`` of the run (a run of store schema 1 or 2 has its surface-named columns under both
    names: ``surface_digest`` and ``phenotype_digest``, ``n_regions`` and ``size_regions``...).
    Read-only and confined: the tables are the run's files as the store reads
    them (each checked against the manifest's sha256), registered in an in-memory database that can
    reach no file, network or extension and cannot be reconfigured; nothing is written anywhere. A
    statement running over ``timeout`` seconds is interrupted. A malformed or refused statement is a
    ``HistoryError`` with DuckDB's one-line reason. ``as_of=G`` reads the run as it was when
    generation ``G`` was committed (time travel, ``genr8 query --as-of G``): the individuals of
    generations up to ``G``, the events recorded at them, the configuration versions in force by
    then; commits only append generations, so this holds for any ``G``. Needs the ``sql`` extra
    (``pip install 'genr8-dist[sql]'``)."""
    import threading

    try:
        import duckdb
    except ImportError:
        raise HistoryError("query needs DuckDB: pip install 'genr8-dist[sql]'") from None
    if not str(sql).strip():
        raise HistoryError("query: the SQL statement is empty")
    if not (isinstance(timeout, (int, float)) and 0 < timeout < 1e9):
        raise HistoryError(f"query: the timeout must be a positive number of seconds, got {timeout!r}")
    if as_of is not None and (isinstance(as_of, bool) or not isinstance(as_of, int) or as_of < 0):
        raise HistoryError(f"query: --as-of takes a generation (an integer >= 0), got {as_of!r}")
    store = open_run(run)
    individuals = dataset(store)
    renamed = getattr(individuals, "renamed", {})   # a schema 1 or 2 run: a view adds the new names
    stored = getattr(individuals, "stored", individuals)
    events_t, configs_t = store.events(), configs(store)
    if as_of is not None:
        stored = stored.filter(pc.field("generation") <= as_of)
        events_t = events_t.filter(pc.less_equal(events_t["generation"], as_of))
        configs_t = configs_t.filter(pc.less_equal(configs_t["effective_generation"], as_of))
    tables = {"stored_individuals" if renamed else "individuals": stored, "events": events_t,
              "configs": configs_t}
    con = duckdb.connect(":memory:", config=dict(_SANDBOX))  # type: ignore[arg-type]
    timer = threading.Timer(float(timeout), con.interrupt)
    try:
        for name, table in tables.items():
            con.register(name, table)
        if renamed:
            aliases = ", ".join(f'"{old}" AS "{new}"' for old, new in renamed.items())
            con.execute(f"CREATE VIEW individuals AS SELECT *, {aliases} FROM stored_individuals")
        timer.start()
        try:
            relation = con.sql(sql)
            if relation is None:   # nothing but ';' or comments, or a statement that yields no table
                shown = " ".join(str(sql).split())[:60]
                raise HistoryError(f"query: {shown!r} is no statement that answers with rows; write a "
                                   "SELECT over individuals, events or configs")
            return relation.to_arrow_table()
        except duckdb.InterruptException:
            raise HistoryError(f"query: stopped after {timeout:g} s, the statement timeout "
                               "(--timeout SECONDS allows more)") from None
        except duckdb.PermissionException as exc:
            raise HistoryError(f"query: refused: {_one_line(str(exc))} (query reads only the run's "
                               "tables individuals, events and configs)") from None
        except duckdb.Error as exc:
            raise HistoryError(f"query: {_one_line(str(exc))}") from None
    finally:
        timer.cancel()
        con.close()
