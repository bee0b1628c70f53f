"""The history API against values computed independently from the Parquet files with pyarrow/numpy."""

from __future__ import annotations

import math
from collections import defaultdict

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc
import pytest
from history_runs import GENERATIONS, INTERVENTION_AT, ISLANDS, POP, targets, units
from hypothesis import given, settings
from hypothesis import strategies as st

from genr8_dist import history
from genr8_dist.errors import Genr8Error, StoreError
from genr8_dist.history import HistoryError

CRITS = ("size", "smoothness", "undulation", "subdivisions", "symmetry", "soft_boundary")


def _rows(table: pa.Table) -> list[dict]:
    return table.to_pylist()


def _expected_per_generation(rows: list[dict]) -> dict[tuple[int, int], dict]:
    groups: dict[tuple[int, int], list[dict]] = defaultdict(list)
    for r in rows:
        groups[(r["generation"], r["island"])].append(r)
    out = {}
    for key, members in groups.items():
        ok = [r for r in members if r["valid"]]
        fit = np.array([r["fitness"] for r in ok])
        best = min(ok, key=lambda r: r["fitness"])
        entry = {"n": len(members), "n_valid": len(ok), "best": fit.min(), "median": float(np.median(fit)),
                 "worst": fit.max(), "mean": fit.mean(), "best_id": best["id"]}
        for c in CRITS:
            scored = [r for r in ok if r[f"crit_{c}"] is not None]
            pick = min(scored, key=lambda r: abs(r[f"crit_{c}"] - targets()[r["config_version"]][c])
                       / units()[r["config_version"]][c])
            entry[f"closest_{c}"] = pick[f"crit_{c}"]
        out[key] = entry
    return out


def test_per_generation_matches_an_independent_computation(history_run, all_rows):
    table = history.per_generation(history_run)
    assert table.num_rows == ISLANDS * GENERATIONS
    got = _rows(table)
    assert [(r["generation"], r["island"]) for r in got] == sorted((g, i) for g in range(GENERATIONS)
                                                                     for i in range(ISLANDS))
    expected = _expected_per_generation(_rows(all_rows))
    for r in got:
        e = expected[(r["generation"], r["island"])]
        assert r["n"] == POP == e["n"]
        assert r["n_valid"] == e["n_valid"]
        assert r["best_id"] == e["best_id"]
        for name in ("best", "median", "worst", "mean", *(f"closest_{c}" for c in CRITS)):
            assert r[name] == pytest.approx(e[name], rel=1e-12), (r["generation"], r["island"], name)


def test_per_generation_of_one_island(history_run):
    whole = history.per_generation(history_run)
    one = history.per_generation(history_run, island=2)
    assert one.num_rows == GENERATIONS
    assert one.equals(whole.filter(pc.equal(whole["island"], 2)).combine_chunks())
    with pytest.raises(HistoryError, match="no island 9"):
        history.per_generation(history_run, island=9)


def test_criterion_best_follows_the_target_in_force(history_run, all_rows):
    """After the intervention the size target is 0.8: the best size is the one closest to 0.8."""
    table = history.per_generation(history_run, island=0)
    row = _rows(table.filter(pc.equal(table["generation"], INTERVENTION_AT)))[0]
    sizes = all_rows.filter(pc.and_(pc.equal(all_rows["generation"], INTERVENTION_AT),
                                    pc.and_(pc.equal(all_rows["island"], 0), all_rows["valid"])))
    values = np.array(sizes["crit_size"].to_pylist())
    assert row["closest_size"] == values[np.argmin(np.abs(values - 0.8))]
    assert row["closest_size"] != values[np.argmin(np.abs(values - 1.5))]


def _valid_sorted(all_rows: pa.Table) -> list[dict]:
    valid = all_rows.filter(all_rows["valid"])
    order = pc.sort_indices(valid, sort_keys=[("fitness", "ascending"), ("generation", "ascending"),
                                              ("island", "ascending"), ("index", "ascending")])
    return _rows(valid.take(order).select(["id", "fitness", "generation", "island", "text"]))


def test_top_is_the_k_lowest_fitness(history_run, all_rows):
    table = history.top(history_run, 10)
    expected = _valid_sorted(all_rows)[:10]
    assert table["id"].to_pylist() == [r["id"] for r in expected]
    assert table["fitness"].to_pylist() == [r["fitness"] for r in expected]
    assert table["rank"].to_pylist() == list(range(1, 11))
    assert "genome" not in table.column_names and "text" not in table.column_names


def test_top_of_a_generation_and_island_with_systems(history_run, all_rows):
    table = history.top(history_run, 5, generation=-1, island=3, systems=True)
    expected = [r for r in _valid_sorted(all_rows)
                if r["generation"] == GENERATIONS - 1 and r["island"] == 3][:5]
    assert table["id"].to_pylist() == [r["id"] for r in expected]
    assert table["text"].to_pylist() == [r["text"] for r in expected]
    assert set(table["generation"].to_pylist()) == {GENERATIONS - 1}
    again = history.top(history_run, 5, generation=GENERATIONS - 1, island=3, systems=True)
    assert again.equals(table)


def test_top_by_criterion_ranks_by_distance_to_its_target(history_run, all_rows):
    table = history.top(history_run, 7, criterion="size")
    rows = [r for r in _rows(all_rows) if r["valid"]]
    dev = [(abs(r["crit_size"] - targets()[r["config_version"]]["size"])
            / units()[r["config_version"]]["size"], r["generation"], r["island"], r["index"], r["id"])
           for r in rows]
    expected = sorted(dev)[:7]
    assert table["id"].to_pylist() == [e[-1] for e in expected]
    assert table["deviation"].to_pylist() == pytest.approx([e[0] for e in expected], rel=1e-12)


def _form(row):
    """A design's look as a designer sees it: its sizes and raw criteria, to 9 significant digits."""
    return tuple(f"{row[c]:.9g}" for c in sorted(row) if c.startswith(("crit_", "size_")))


def test_top_distinct_lists_each_form_once_by_its_best_with_its_copies(history_run, all_rows):
    valid = _valid_sorted(all_rows)
    rows = {r["id"]: r for r in _rows(all_rows)}
    forms: dict[tuple, list[str]] = {}
    for r in valid:
        forms.setdefault(_form(rows[r["id"]]), []).append(r["id"])
    table = history.top(history_run, 10**6, distinct=True)
    assert table.num_rows == len(forms)
    assert sum(table["copies"].to_pylist()) == len(valid)
    best = sorted(forms.values(), key=lambda ids: [r["id"] for r in valid].index(ids[0]))
    assert table["id"].to_pylist() == [ids[0] for ids in best]
    assert table["copies"].to_pylist() == [len(ids) for ids in best]
    assert history.top(history_run, 5, distinct=True)["id"].to_pylist() == [ids[0] for ids in best[:5]]


def test_mirror_images_with_equal_measures_are_one_form_whatever_their_digest():
    import pyarrow as pa

    from genr8_dist.history._tables import form_ids

    table = pa.table({"phenotype_digest": ["a", "b", "c", "d"],
                      "crit_size": [6.75, 6.75 * (1 + 1e-13), 6.75 * (1 + 1e-6), 6.75],
                      "size_regions": [41, 41, 41, 40]})
    ids = form_ids(table).tolist()
    assert ids[0] == ids[1] and len({ids[0], ids[2], ids[3]}) == 3


def test_top_bad_requests(history_run):
    with pytest.raises(HistoryError, match="criterion 'beauty'"):
        history.top(history_run, criterion="beauty")
    with pytest.raises(HistoryError, match="generation -99"):
        history.top(history_run, generation=-99)
    with pytest.raises(HistoryError, match="no valid individual of generation 77"):
        history.top(history_run, generation=77)
    with pytest.raises(HistoryError, match="k: must be at least 1"):
        history.top(history_run, 0)


def test_individual_row_and_unknown_id(history_run, all_rows):
    row = history.individual(history_run, "1-17-4")
    expected = all_rows.filter(pc.equal(all_rows["id"], "1-17-4"))
    assert row.to_pylist() == expected.to_pylist()
    for bad in ("1-17-400", "9-9-9", "not-an-id", ""):
        with pytest.raises(HistoryError, match="no individual with id"):
            history.individual(history_run, bad)


def _expected_ancestry(all_rows: pa.Table, start: str) -> set[str]:
    parents = dict(zip(all_rows["id"].to_pylist(), all_rows["parents"].to_pylist(), strict=True))
    seen, todo = set(), [start]
    while todo:
        current = todo.pop()
        if current in seen:
            continue
        seen.add(current)
        todo.extend(parents[current])
    return seen


def test_lineage_is_the_whole_ancestry(history_run, all_rows):
    start = "2-49-30"
    table = history.lineage(history_run, start)
    assert set(table["id"].to_pylist()) == _expected_ancestry(all_rows, start)
    gens = table["generation"].to_pylist()
    assert gens == sorted(gens, reverse=True) and gens[0] == 49 and gens[-1] == 0
    by_id = {r["id"]: r for r in all_rows.select(["id", "origin", "parents"]).to_pylist()}
    for r in table.to_pylist():
        assert r["origin"] == by_id[r["id"]]["origin"]
        assert r["parents"] == by_id[r["id"]]["parents"]
        assert r["missing"] == []
    # the main line follows first parents from the individual down to a founder
    line, current = [], start
    while True:
        line.append(current)
        first = by_id[current]["parents"]
        if not first:
            break
        current = first[0]
    marked = table.filter(table["main_line"])["id"].to_pylist()
    assert marked == line
    assert by_id[line[-1]]["origin"] == "random"
    origins = set(table["origin"].to_pylist())
    assert "migrant" in origins and "random" in origins


def test_lineage_depth_and_unknown_id(history_run):
    table = history.lineage(history_run, "0-20-5", depth=3)
    assert set(table["generation"].to_pylist()) <= {17, 18, 19, 20}
    assert min(table["generation"].to_pylist()) == 17
    with pytest.raises(HistoryError, match="'0-20-500'"):
        history.lineage(history_run, "0-20-500")


def test_query_group_by_matches_pyarrow(history_run, all_rows):
    table = history.query(history_run, "select generation, count(*) as n, min(fitness) as best "
                                       "from individuals where valid group by generation order by generation")
    valid = all_rows.filter(all_rows["valid"])
    expected = valid.group_by("generation").aggregate([("fitness", "count"), ("fitness", "min")])
    expected = expected.sort_by("generation")
    assert table["generation"].to_pylist() == expected["generation"].to_pylist()
    assert table["n"].to_pylist() == expected["fitness_count"].to_pylist()
    assert table["best"].to_pylist() == expected["fitness_min"].to_pylist()


def test_query_events_and_configs_views(history_run):
    versions = history.query(history_run, "select version, effective_generation from configs order by 1")
    assert versions.to_pylist() == [{"version": 1, "effective_generation": 0},
                                    {"version": 2, "effective_generation": INTERVENTION_AT}]
    kinds = history.query(history_run, "select kind, count(*) as n from events group by kind order by kind")
    counts = dict(zip(kinds["kind"].to_pylist(), kinds["n"].to_pylist(), strict=True))
    assert counts == {"intervention": 1, "migration": GENERATIONS // 10 - 1, "start": 1}
    joined = history.query(history_run, "select count(*) as n from individuals i join configs c "
                                        "on i.config_version = c.version where c.version = 2")
    assert joined["n"][0].as_py() == ISLANDS * POP * (GENERATIONS - INTERVENTION_AT)


@pytest.mark.parametrize("sql", ["selec 1", "select nope from individuals", "select * from nowhere", ""])
def test_malformed_sql_is_one_line(history_run, sql):
    with pytest.raises(HistoryError) as info:
        history.query(history_run, sql)
    message = str(info.value)
    assert message.startswith("query: ") and "\n" not in message


def test_interventions_and_events(history_run):
    table = history.interventions(history_run)
    assert table.num_rows == 1
    assert table["generation"][0].as_py() == INTERVENTION_AT
    assert '"target":0.8' in table["detail"][0].as_py()
    assert history.events(history_run).num_rows == 1 + 1 + GENERATIONS // 10 - 1


def test_missing_and_empty_runs(tmp_path, empty_run):
    with pytest.raises(StoreError, match="no such run directory"):
        history.per_generation(tmp_path / "nothing")
    for call in (history.per_generation, history.top, lambda r: history.query(r, "select 1"),
                 lambda r: history.lineage(r, "0-0-0")):
        with pytest.raises(StoreError, match="no committed generation"):
            call(empty_run)
    not_a_run = tmp_path / "plain"
    not_a_run.mkdir()
    with pytest.raises(Genr8Error, match="not a run directory"):
        history.top(not_a_run)


def test_write_table_round_trips(tmp_path, history_run):
    import pyarrow.csv as pcsv
    import pyarrow.parquet as pq

    table = history.top(history_run, 4)
    history.write_table(table, tmp_path / "top.parquet")
    assert pq.read_table(tmp_path / "top.parquet").equals(table)
    history.write_table(table, tmp_path / "top.csv")
    back = pcsv.read_csv(tmp_path / "top.csv")
    assert back["id"].to_pylist() == table["id"].to_pylist()
    assert back["fitness"].to_pylist() == pytest.approx(table["fitness"].to_pylist())
    assert back["parents"].to_pylist() == [" ".join(p) for p in table["parents"].to_pylist()]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["top.csv", "top.parquet"]


def test_accepts_an_open_store(history_run):
    from genr8_dist.store import RunStore

    store = RunStore.open(history_run)
    assert history.top(store, 3).equals(history.top(history_run, 3))
    assert math.isfinite(history.per_generation(store)["best"][0].as_py())


def test_the_documented_example_queries_run(history_run):
    """Every ```sql block of docs/history.md runs on a real run and returns rows."""
    import re
    from pathlib import Path

    doc = (Path(__file__).resolve().parents[2] / "docs" / "history.md").read_text(encoding="utf-8")
    queries = re.findall(r"```sql\n(.*?)```", doc, re.DOTALL)
    assert len(queries) == 3
    for sql in queries:
        assert history.query(history_run, sql).num_rows > 0, sql


def test_public_names():
    import genr8_dist.history as module

    for name in module.__all__:
        assert getattr(module, name) is not None
    assert callable(module.regrow) and callable(module.export)


def test_a_generation_without_valid_individuals(tmp_path, capsys):
    """Groups where every individual failed have nulls, print as '-', and still draw."""
    from history_runs import TOML_V1

    from genr8_dist import cli
    from genr8_dist.evolution.individual import Individual
    from genr8_dist.store import RunStore

    store = RunStore.create(tmp_path / "run", TOML_V1)
    crit = dict.fromkeys(CRITS, 0.5)
    good = [Individual(0, 0, n, (n + 1,), "random", valid=True, fitness=float(n), criteria=crit,
                       text="Edge0 + Edge1 + Edge2") for n in range(3)]
    bad = [Individual(1, 0, n, (7,), "random", stage="map", error="wrapped too often") for n in range(3)]
    store.commit(good + bad)
    table = history.per_generation(tmp_path / "run")
    rows = table.to_pylist()
    assert rows[0]["best"] == 0.0 and rows[0]["median"] == 1.0 and rows[0]["best_id"] == "0-0-0"
    assert rows[1]["n_valid"] == 0 and rows[1]["best"] is None and rows[1]["best_id"] is None
    assert rows[1]["closest_size"] is None
    assert cli.main(["history", str(tmp_path / "run"), "--png", str(tmp_path / "c.png")]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[2].split()[:8] == ["0", "1", "3", "0", "-", "-", "-", "-"]
    assert (tmp_path / "c.png").stat().st_size > 10_000
    with pytest.raises(HistoryError, match="no valid individual of island 1"):
        history.top(tmp_path / "run", island=1)


def test_a_run_named_by_uri(history_run):
    uri = history_run.resolve().as_uri()
    assert history.top(uri, 3).equals(history.top(history_run, 3))


@settings(max_examples=12, deadline=None)
@given(islands=st.integers(1, 3), generations=st.integers(1, 4), pop=st.integers(5, 9),
       seed=st.integers(0, 2**16), k=st.integers(1, 12))
def test_property_per_generation_and_top_on_any_synthetic_run(tmp_path_factory, islands, generations, pop,
                                                              seed, k):
    import pyarrow.parquet as pq

    from genr8_dist.store import RunStore, write_synthetic_run

    path = tmp_path_factory.mktemp("prop") / "run"
    write_synthetic_run(path, islands, generations, pop, seed, generations_per_commit=2)
    rows = pa.concat_tables([pq.read_table(f) for f in RunStore.open(path).individual_files()])
    assert rows.num_rows == islands * generations * pop
    table = history.per_generation(path)
    assert table.num_rows == islands * generations
    groups: dict[tuple[int, int], list[float]] = defaultdict(list)
    for r in rows.to_pylist():
        if r["valid"]:
            groups[(r["generation"], r["island"])].append(r["fitness"])
    for r in table.to_pylist():
        values = groups.get((r["generation"], r["island"]), [])
        assert r["n_valid"] == len(values)
        if values:
            assert r["best"] == min(values) and r["worst"] == max(values)
            assert r["median"] == pytest.approx(float(np.median(values)), rel=1e-12)
        else:
            assert r["best"] is None
    expected = sorted((r["fitness"], r["generation"], r["island"], r["index"], r["id"])
                      for r in rows.to_pylist() if r["valid"])[:k]
    if expected:
        assert history.top(path, k)["id"].to_pylist() == [e[-1] for e in expected]


def test_top_under_a_version_rescores_every_individual_from_its_raw_criteria(history_run, all_rows):
    """After the size target changed at generation 30, `under=2` ranks the whole run by version 2's
    targets and weights (computed from the stored raw criteria), and says so in `fitness_v2`."""
    import math

    from genr8_dist.history import top
    from genr8_dist.store import RunStore

    store = RunStore.open(history_run)
    spec = store.fitness(store.configs()[-1])
    ranked = top(history_run, 25, under=2).to_pylist()
    assert len(ranked) == 25 and [r["rank"] for r in ranked] == list(range(1, 26))
    for r in ranked:
        raw = {c: r[f"crit_{c}"] for c in spec.names}
        assert math.isclose(r["fitness_v2"], spec.evaluate(raw), rel_tol=1e-9, abs_tol=1e-12)
    assert [r["fitness_v2"] for r in ranked] == sorted(r["fitness_v2"] for r in ranked)
    every = [spec.evaluate({c: row[f"crit_{c}"] for c in spec.names})
             for row in all_rows.to_pylist() if row["valid"]]
    assert math.isclose(ranked[0]["fitness_v2"], min(every), rel_tol=1e-9, abs_tol=1e-12)
    # the stored fitness is kept beside it; as scored, version 1 rows used the old size target
    as_scored = top(history_run, 25).to_pylist()
    assert "fitness_v2" not in as_scored[0]
