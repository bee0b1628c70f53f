"""Runs written by store schema versions 1 and 2 (tests/data/run-schema-v1, -v2, interrupted) resume:
each keeps its committed rows and its schema (its surface-named columns too), completes every
generation, and two resumptions write the same rows. (Its rows are not compared with a fresh run's:
growth may change between versions.)"""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest
from distributed_runs import drive_to_end, event_kinds, rows

pytestmark = pytest.mark.usefixtures("ray_local")

DATA = Path(__file__).resolve().parents[1] / "data"


@pytest.mark.parametrize("version", [1, 2])
def test_an_old_schema_run_resumes_in_its_own_schema(tmp_path, version):
    import pyarrow.parquet as pq

    from genr8_dist.store import RunStore

    fixture = DATA / f"run-schema-v{version}"
    before = rows(fixture)
    resumed = []
    for name in ("a", "b"):
        copy = Path(shutil.copytree(fixture, tmp_path / name))
        summary, _ = drive_to_end(copy)
        assert summary.status == "complete"
        assert event_kinds(copy)[-1] == "complete"
        store = RunStore.open(copy)
        assert store.schema_version == version and store.committed_generations() == {0: 4, 1: 4}
        assert "crit_size" in store.schema.names and store.verify() == []
        for path in store.individual_files():   # written in the run's own column names
            names = pq.read_schema(path).names
            assert "surface_digest" in names and "n_regions" in names and "phenotype_digest" not in names
        resumed.append(rows(copy))
    assert len(resumed[0]) == 2 * 6 * 5
    assert resumed[0] == resumed[1]
    kept = {r["id"]: r for r in resumed[0]}
    assert [kept[r["id"]] for r in before] == before
    for r in resumed[0]:
        for parent in r["parents"]:
            assert parent in kept and kept[parent]["generation"] == r["generation"] - 1
