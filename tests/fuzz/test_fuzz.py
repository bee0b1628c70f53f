"""1,000 fuzzed ``genr8`` inputs: each ends with an answer or a one-line error, on time, changing nothing it
should only read (tests/fuzz/harness.py says how inputs are drawn and judged)."""

from __future__ import annotations

import io

import pytest
from harness import fuzz, mutate


@pytest.mark.slow
def test_a_thousand_fuzzed_inputs_end_in_an_answer_or_one_line() -> None:
    log = io.StringIO()
    report = fuzz(1000, seed=1, out=log)
    assert sum(report["counts"].values()) == 1000
    assert report["failures"] == [], log.getvalue()
    assert report["counts"].get("ok", 0) >= 100  # the inputs are not all rejected at the door


def test_mutations_are_seeded() -> None:
    from genr8_dist.rng import stream

    data = b"[ea]\npopulation = 20\ngenerations = 15\n"
    first = [mutate(data, stream(3, "m", k)) for k in range(20)]
    again = [mutate(data, stream(3, "m", k)) for k in range(20)]
    assert first == again
    assert len(set(first)) > 10
