"""Fixtures for the history tests: one synthetic run per session, an empty run, and its rows."""

from __future__ import annotations

import pytest
from history_runs import TOML_V1, build_history_run


@pytest.fixture(scope="session")
def history_run(tmp_path_factory):
    """The path of the 4 x 50 x 50 synthetic run with an intervention at generation 30."""
    path = tmp_path_factory.mktemp("history") / "run"
    build_history_run(path)
    return path


@pytest.fixture(scope="session")
def all_rows(history_run):
    """Every committed row, read straight from the Parquet files with pyarrow (the independent side)."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    from genr8_dist.store import RunStore

    files = RunStore.open(history_run).individual_files()
    return pa.concat_tables([pq.read_table(f) for f in files])


@pytest.fixture
def empty_run(tmp_path):
    """A run that has a configuration but no committed generation."""
    from genr8_dist.store import RunStore

    path = tmp_path / "empty"
    RunStore.create(path, TOML_V1)
    return path
