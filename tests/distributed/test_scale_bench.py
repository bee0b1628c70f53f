"""bench/scale.py's ``--timeline`` figures (where the simulated CPUs' time went, from the waits' log),
its ``--real`` configuration and its ``--sweep`` table."""

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


def test_real_evolves_the_given_configuration_with_only_the_options_changed(bench_module):
    import argparse

    from genr8_dist.config import RunConfig, load_config

    quick = Path(__file__).resolve().parents[2] / "examples" / "quick.toml"
    args = argparse.Namespace(real=str(quick), islands=16, population=None, generations=6, interval=None,
                              seed=None, genome_length=20)
    config = RunConfig.from_toml(bench_module("scale").config_toml(args))
    given = load_config(quick)
    assert (config.islands.count, config.ea.generations) == (16, 6)
    assert config.replace(islands={"count": given.islands.count},
                          ea={"generations": given.ea.generations}) == given


def test_the_sweep_table_gives_speedup_and_scaling_efficiency_over_the_first_count(bench_module):
    def figures(cpus: int, wall: float) -> dict:
        return {"cpus": cpus, "hosts": cpus, "rows": 100, "wall_s": wall, "efficiency": 0.5,
                "coordinator_share": 0.01, "commit_p99_s": 0.1, "driver_bytes_per_row": 40.0}

    sweep = [figures(1, 40.0), figures(4, 12.5), figures(16, 5.0)]
    table = bench_module("scale").sweep_table(sweep)
    assert [f["speedup"] for f in sweep] == pytest.approx([1.0, 3.2, 8.0])
    assert [f["scaling_efficiency"] for f in sweep] == pytest.approx([1.0, 0.8, 0.5])
    assert table.splitlines()[3].startswith("| 4 | 4 | 100 | 12.50 | 3.20 | 0.800 |")
