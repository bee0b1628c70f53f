"""A run written by store schema version 1 (tests/data/run-schema-v1, interrupted) resumes to the rows
an uninterrupted run of the same configuration writes today, and stays a version-1 run."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest
from distributed_runs import drive_to_end, event_kinds, new_run, rows, tiny_toml

pytestmark = pytest.mark.usefixtures("ray_local")

FIXTURE = Path(__file__).resolve().parents[1] / "data" / "run-schema-v1"


def test_an_old_schema_run_resumes_to_the_rows_of_an_uninterrupted_run(tmp_path):
    from genr8_dist.store import RunStore

    old = Path(shutil.copytree(FIXTURE, tmp_path / "old"))
    summary, _ = drive_to_end(old)
    assert summary.status == "complete"
    assert event_kinds(old)[-1] == "complete"
    fresh = tmp_path / "fresh"
    new_run(fresh, tiny_toml(islands=2, generations=4))
    drive_to_end(fresh)
    assert rows(old) == rows(fresh)
    store = RunStore.open(old)
    assert store.schema_version == 1 and store.committed_generations() == {0: 4, 1: 4}
