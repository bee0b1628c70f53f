"""Synthetic histories: written with the store's writer, deterministic, shaped like a real run."""

from __future__ import annotations

import math
import time
from pathlib import Path

import pyarrow.compute as pc
import pytest

from genr8_dist.errors import StoreError
from genr8_dist.store import RunStore, write_synthetic_run


def test_same_arguments_give_the_same_rows(tmp_path: Path) -> None:
    a = write_synthetic_run(tmp_path / "a", 3, 12, 20, seed=4, generations_per_commit=5)
    b = write_synthetic_run(tmp_path / "b", 3, 12, 20, seed=4, generations_per_commit=5)
    c = write_synthetic_run(tmp_path / "c", 3, 12, 20, seed=5, generations_per_commit=5)
    rows_a = a.individuals().drop_columns(["run_id"])
    assert rows_a.equals(b.individuals().drop_columns(["run_id"]))
    assert not rows_a.equals(c.individuals().drop_columns(["run_id"]))


def test_rows_look_like_a_run(tmp_path: Path) -> None:
    store = write_synthetic_run(tmp_path / "s", 4, 10, 25, seed=1, generations_per_commit=3)
    assert store.committed_generations() == {i: 9 for i in range(4)}
    table = store.individuals()
    assert table.num_rows == 4 * 10 * 25
    ids = set(table.column("id").to_pylist())
    for row in table.filter(pc.field("generation") > 0).slice(0, 300).to_pylist():
        assert all(parent in ids for parent in row["parents"])
        assert all(int(p.split("-")[1]) == row["generation"] - 1 for p in row["parents"])
        if row["origin"] == "migrant":
            assert int(row["parents"][0].split("-")[0]) == (row["island"] - 1) % 4
    invalid = table.filter(pc.invert(table.column("valid")))
    assert 0 < invalid.num_rows < table.num_rows / 4
    assert all(math.isinf(f) for f in invalid.column("fitness").to_pylist())
    assert invalid.column("crit_size").null_count == invalid.num_rows
    best = table.group_by("generation").aggregate([("fitness", "min")]).sort_by("generation")
    mins = best.column("fitness_min").to_pylist()
    assert mins[-1] < mins[0]
    kinds = store.events().column("kind").to_pylist()
    assert kinds == ["start", "migration", "migration", "migration", "complete"]
    assert RunStore.open(store.path).verify() == []


def test_bad_sizes_are_refused_naming_them(tmp_path: Path) -> None:
    with pytest.raises(StoreError, match="pop must be an integer >= 5"):
        write_synthetic_run(tmp_path / "x", 2, 3, 2, seed=0)
    assert not (tmp_path / "x").exists()


@pytest.mark.slow
def test_a_hundred_thousand_individuals_are_written_quickly(tmp_path: Path) -> None:
    started = time.perf_counter()
    store = write_synthetic_run(tmp_path / "big", 16, 63, 100, seed=2)
    seconds = time.perf_counter() - started
    assert store.individuals(columns=["fitness"]).num_rows == 100_800
    assert len(store.individual_files()) <= 8
    assert seconds < 30, f"100k synthetic individuals took {seconds:.1f} s"
