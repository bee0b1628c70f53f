"""The seeded streams: the same key path gives the same draws anywhere, different paths differ."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

from genr8_dist.rng import stream


def test_same_path_same_draws() -> None:
    a = stream(7, "island", 3, "generation", 12, "mutation").integers(0, 2**31, 100)
    b = stream(7, "island", 3, "generation", 12, "mutation").integers(0, 2**31, 100)
    assert np.array_equal(a, b)


@pytest.mark.parametrize(
    "other",
    [(8, "island", 3, "generation", 12, "mutation"),
     (7, "island", 4, "generation", 12, "mutation"),
     (7, "island", 3, "generation", 13, "mutation"),
     (7, "island", 3, "generation", 12, "crossover")],
)
def test_any_key_changes_the_stream(other: tuple) -> None:
    a = stream(7, "island", 3, "generation", 12, "mutation").integers(0, 2**31, 20)
    b = stream(*other).integers(0, 2**31, 20)
    assert not np.array_equal(a, b)


def test_string_and_int_keys_do_not_collide() -> None:
    a = stream(1, "3").integers(0, 2**31, 20)
    b = stream(1, 3).integers(0, 2**31, 20)
    assert not np.array_equal(a, b)


def test_streams_are_stable_across_processes() -> None:
    code = ("from genr8_dist.rng import stream; "
            "print(stream(42, 'growth').integers(0, 1000, 5).tolist())")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == str(stream(42, "growth").integers(0, 1000, 5).tolist())


@pytest.mark.parametrize("bad", [(-1,), (1, -2), (1, 1.5), (1, True)])
def test_bad_keys_are_refused(bad: tuple) -> None:
    with pytest.raises((ValueError, TypeError)):
        stream(*bad)
