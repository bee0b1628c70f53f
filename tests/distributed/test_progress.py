"""The progress display: plain lines with the generation, fitness per island, rate and time left."""

from __future__ import annotations

import io
import math

from genr8_dist.distributed.progress import ProgressDisplay, format_duration, format_fitness
from genr8_dist.evolution.individual import Individual


def _pop(island, fitnesses):
    return [Individual(island=island, generation=3, index=i, genome=(1,), origin="random", fitness=f)
            for i, f in enumerate(fitnesses)]


class _Clock:
    def __init__(self):
        self.now = 100.0

    def __call__(self):
        return self.now


def test_line_shows_generation_fitness_rate_and_time_left():
    out, clock = io.StringIO(), _Clock()
    display = ProgressDisplay(total_generations=20, out=out, clock=clock)
    clock.now += 2.0
    line = display.generation(4, {0: _pop(0, [3.0, 1.0, 2.0]), 1: _pop(1, [0.5, math.inf, 4.0])},
                              remaining=16)
    assert out.getvalue() == line + "\n"
    assert "\r" not in line and "\x1b" not in line
    assert line.startswith("gen  4/20")
    assert "best 0.5 " in line and "median 2 " in line
    assert "i0 1/2" in line and "i1 0.5/4" in line
    assert "3.0 ind/s" in line
    assert "32s left" in line     # 2 s per generation, 16 to go


def test_quiet_prints_nothing():
    out = io.StringIO()
    display = ProgressDisplay(total_generations=5, out=out, quiet=True)
    display.generation(1, {0: _pop(0, [1.0])}, remaining=4)
    display.message("hello")
    assert out.getvalue() == ""


def test_formats():
    assert format_duration(5) == "5s"
    assert format_duration(65) == "1m05s"
    assert format_duration(3 * 3600 + 120) == "3h02m"
    assert format_duration(math.inf) == "?"
    assert format_fitness(math.inf) == "inf"
    assert format_fitness(0.123456) == "0.1235"
