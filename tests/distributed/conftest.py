"""Fixtures of the distributed-run tests (helpers live in distributed_runs.py)."""

from __future__ import annotations

from pathlib import Path

import pytest
from distributed_runs import tiny_toml


@pytest.fixture
def tiny_config(tmp_path) -> Path:
    """A tiny 3-island configuration file."""
    path = tmp_path / "tiny.toml"
    path.write_text(tiny_toml())
    return path
