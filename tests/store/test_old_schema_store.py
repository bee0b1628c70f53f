"""Runs keep their own schema: the checked-in runs written by store schema versions 1 and 2
(tests/data/run-schema-v1, run-schema-v2) open, answer history queries and take commits in their own
schema; their surface-named columns (``surface_digest``, ``n_vertices``...) read under the current
names (``phenotype_digest``, ``size_vertices``...)."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from genr8_dist import history
from genr8_dist.cli import main
from genr8_dist.store import SCHEMA_VERSION, RunStore

FIXTURE = Path(__file__).resolve().parents[1] / "data" / "run-schema-v1"
FIXTURE_V2 = Path(__file__).resolve().parents[1] / "data" / "run-schema-v2"
RENAMED = {"surface_digest": "phenotype_digest", "n_vertices": "size_vertices", "n_edges": "size_edges",
           "n_regions": "size_regions"}
V1_COLUMNS = ["run_id", "id", "island", "generation", "index", "genome", "text", "valid", "stage", "error",
              "fitness", "crit_size", "crit_smoothness", "crit_undulation", "crit_subdivisions",
              "crit_symmetry", "crit_soft_boundary", "origin", "parents", "config_version", "codons_used",
              "wraps", "n_vertices", "n_edges", "n_regions", "steps_done", "capped", "surface_digest",
              "eval_seconds", "map_seconds", "grow_seconds", "score_seconds"]


@pytest.fixture
def old_run(tmp_path):
    """A writable copy of the version-1 run."""
    return Path(shutil.copytree(FIXTURE, tmp_path / "run"))


def test_an_old_run_is_read_with_the_schema_it_was_written_with():
    store = RunStore.open(FIXTURE)
    assert store.schema_version == 1 < SCHEMA_VERSION
    assert sorted(store.schema.names) == sorted(V1_COLUMNS)
    assert store.verify() == []
    assert store.committed_generations() == {0: 1, 1: 2}
    table = store.individuals()
    assert table.num_rows == 6 * (2 + 3)
    assert store.config(1).ea.generations == 4
    assert store.screen == 1 and store.config(1).ea.screen == 1   # bred as it was: no screen recorded


def test_an_old_run_answers_history_queries(capsys):
    per_gen = history.per_generation(FIXTURE)
    assert [(r["generation"], r["island"]) for r in per_gen.to_pylist()] == [
        (0, 0), (0, 1), (1, 0), (1, 1), (2, 1)]
    best = history.top(FIXTURE, 3)
    assert best.num_rows == 3 and best["rank"].to_pylist() == [1, 2, 3]
    tree = history.lineage(FIXTURE, best["id"][0].as_py())
    assert tree.num_rows >= 1
    counted = history.query(FIXTURE, "select count(*) as n from individuals")
    assert counted["n"].to_pylist() == [30]
    assert main(["top", str(FIXTURE), "-k", "2"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0].split()[:5] == ["rank", "id", "gen", "isl", "fitness"] and len(out) == 3


def test_an_old_run_takes_commits_in_its_own_schema_and_compacts(old_run):
    store = RunStore.open(old_run)
    more = store.load_generation(0, 1)
    from dataclasses import replace

    store.commit([replace(ind, generation=2) for ind in more])
    store.compact(target_rows=10_000)
    again = RunStore.open(old_run)
    assert again.schema_version == 1 and again.verify() == []
    assert len(again.individual_files()) == 1  # the old file and the new one merged
    assert again.committed_generations() == {0: 2, 1: 2}
    assert [i.genome for i in again.load_generation(0, 2)] == [i.genome for i in more]
    # the run keeps its own columns (on disk too); columns declared since (the search modes'
    # registered ones) read as nulls, and the surface-named ones under their current names
    assert sorted(again.schema.names) == sorted(V1_COLUMNS)
    import pyarrow.parquet as pq

    assert sorted(pq.read_schema(again.individual_files()[0]).names) == sorted(V1_COLUMNS)
    read = again.individuals()
    current = {RENAMED.get(name, name) for name in V1_COLUMNS}
    assert set(read.column_names) - current == {"pareto_rank", "cell"}
    assert not set(RENAMED) & set(read.column_names)
    assert all(read[name].null_count == read.num_rows for name in set(read.column_names) - current)


@pytest.mark.parametrize("fixture", [FIXTURE, FIXTURE_V2], ids=["schema1", "schema2"])
def test_an_old_runs_surface_named_columns_read_under_the_current_names(fixture):
    store = RunStore.open(fixture)
    assert store.schema_version < SCHEMA_VERSION == 3
    assert set(RENAMED) <= set(store.schema.names) and store.renamed == RENAMED
    assert store.sizes == ("vertices", "edges", "regions")
    stored = store.dataset().stored.to_table(columns=list(RENAMED)).sort_by("surface_digest")
    read = store.individuals(["phenotype_digest", "size_vertices", "size_edges", "size_regions"])
    assert read.sort_by("phenotype_digest").rename_columns(list(RENAMED)).to_pylist() == stored.to_pylist()
    assert store.dataset().to_table(columns=["size_regions"]).num_rows == store.dataset().count_rows()
    one = store.load_generation(0, 0)[0]
    assert set(one.sizes) == {"vertices", "edges", "regions"} and one.phenotype_digest is not None
    # SQL sees both names of each renamed column, with equal values
    both = history.query(fixture, "select count(*) as n from individuals where surface_digest = "
                                  "phenotype_digest and n_regions = size_regions "
                                  "and n_vertices = size_vertices")
    valid = history.query(fixture, "select count(*) as n from individuals where phenotype_digest is not null")
    assert both["n"].to_pylist() == valid["n"].to_pylist() and valid["n"][0].as_py() > 0
    best = history.top(fixture, 2)
    assert {"phenotype_digest", "size_vertices", "size_regions"} <= set(best.column_names)
