"""What users import: every name in each ``__all__`` exists, and the top level stays light."""

from __future__ import annotations

import importlib
import subprocess
import sys

import pytest

import genr8_dist

PACKAGES = [
    "genr8_dist", "genr8_dist.errors", "genr8_dist.rng", "genr8_dist.grammar", "genr8_dist.hemls",
    "genr8_dist.environment", "genr8_dist.fitness", "genr8_dist.config", "genr8_dist.evolution",
    "genr8_dist.store", "genr8_dist.history", "genr8_dist.distributed", "genr8_dist.export",
]


@pytest.mark.parametrize("name", PACKAGES)
def test_every_exported_name_exists(name: str) -> None:
    module = importlib.import_module(name)
    exported = module.__all__
    assert len(exported) == len(set(exported)), f"{name}.__all__ repeats a name"
    missing = [attr for attr in exported if not hasattr(module, attr)]
    assert missing == []


def test_top_level_names_are_the_stage_objects() -> None:
    from genr8_dist.grammar import load_universe
    from genr8_dist.hemls import grow
    from genr8_dist.store import RunStore

    assert genr8_dist.load_universe is load_universe
    assert genr8_dist.grow is grow
    assert genr8_dist.RunStore is RunStore
    with pytest.raises(AttributeError):
        genr8_dist.no_such_name  # noqa: B018


def test_importing_the_package_loads_no_heavy_dependency() -> None:
    code = ("import sys, genr8_dist; "
            "print(sorted(m for m in ('ray', 'pyarrow', 'trimesh', 'lark', 'numpy') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"
