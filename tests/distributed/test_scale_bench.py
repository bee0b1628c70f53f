"""bench/scale.py's ``--timeline`` figures: where the simulated CPUs' time went, from the waits' log."""

from __future__ import annotations

from pathlib import Path

import pytest


def _log(folder: Path, name: str, waits: list[tuple[float, float, float]]) -> None:
    folder.mkdir(exist_ok=True)
    lines = "".join(f"{a!r} {b!r} {s!r}\n" for a, b, s in waits)
    (folder / f"{name}.txt").write_text(lines, encoding="ascii")


def test_two_cpus_busy_but_for_a_gap_and_one_overshoot(tmp_path, bench_module):
    # 0-10 s one wait that asked 9.9 s; 0-5 and 6-10 s two more on the other CPU (two processes)
    _log(tmp_path, "1", [(100.0, 110.0, 9.9)])
    _log(tmp_path, "2", [(100.0, 105.0, 5.0), (106.0, 110.0, 4.0)])
    figures = bench_module("scale").timeline_figures(tmp_path, cpus=2)
    assert figures["waited_s"] == pytest.approx(9.5)
    assert figures["waits_span_s"] == pytest.approx(10.0)
    assert figures["idle_share"] == pytest.approx(0.05)     # one CPU idle for 1 s of 20
    assert figures["overshoot_ms_mean"] == pytest.approx(100.0 / 3)
    assert figures["overshoot_ms_p99"] == pytest.approx(100.0)
    assert figures["tail_s"] == pytest.approx(0.0)


def test_a_lone_long_wait_at_the_end_is_the_tail(tmp_path, bench_module):
    _log(tmp_path, "1", [(0.0, 4.0, 4.0), (4.0, 10.0, 6.0)])
    _log(tmp_path, "2", [(0.0, 4.0, 4.0)])
    figures = bench_module("scale").timeline_figures(tmp_path, cpus=2)
    assert figures["tail_s"] == pytest.approx(6.0)
    assert figures["idle_share"] == pytest.approx(0.3)
    assert figures["overshoot_ms_mean"] == pytest.approx(0.0)


def test_no_log_no_figures(tmp_path, bench_module):
    assert bench_module("scale").timeline_figures(tmp_path, cpus=4) == {}
