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


class _Terminal(io.StringIO):
    """A fake terminal: ``isatty`` says yes."""

    def isatty(self):
        return True


def _screen(text: str) -> list[str]:
    """What a terminal shows after ``text``: lines, with ESC[nF (n lines up) and ESC[J (clear below)."""
    import re

    lines: list[str] = [""]
    for token in re.split(r"(\x1b\[\d*F|\x1b\[J|\n)", text):
        if token == "\n":
            lines.append("")
        elif token.startswith("\x1b[") and token.endswith("F"):
            up = int(token[2:-1] or 1)
            del lines[len(lines) - 1 - up:]   # the cursor sits on the last (empty) line
            lines.append("")
        elif token == "\x1b[J":
            pass   # the lines below the cursor were dropped with the move
        else:
            lines[-1] += token
    return lines[:-1] if lines[-1] == "" else lines


def test_a_terminal_gets_a_table_redrawn_in_place_with_messages_above():
    out, clock = _Terminal(), _Clock()
    display = ProgressDisplay(total_generations=20, out=out, clock=clock)
    assert display.table
    display.message("run r1: 2 islands")
    display.island(0, 0, _pop(0, [3.0, 1.0, math.inf]))
    display.island(1, 0, _pop(1, [0.5, 4.0, 1.5]))
    clock.now += 2.0
    display.generation(0, {0: _pop(0, [3.0, 1.0, math.inf]), 1: _pop(1, [0.5, 4.0, 1.5])}, remaining=20)
    display.island(0, 1, _pop(0, [0.75, 2.0, 2.0]))
    display.message("migration after generation 1")
    screen = _screen(out.getvalue())
    assert "\x1b[" in out.getvalue()
    assert screen[0] == "run r1: 2 islands"
    assert screen[1] == "migration after generation 1"       # messages above the table
    assert screen[2].startswith("generation 0/20 completed by every island · best 0.5 · 3.0 ind/s")
    assert screen[3].split() == ["island", "generation", "best", "mean", "evaluations"]
    assert screen[4].split() == ["0", "1/20", "0.75", "1.583", "6"]   # the mean of the valid
    assert screen[5].split() == ["1", "0/20", "0.5", "2", "3"]
    assert len(screen) == 6                                      # redrawn in place, not appended


def test_a_pipe_gets_lines_and_no_table():
    out, clock = io.StringIO(), _Clock()
    display = ProgressDisplay(total_generations=5, out=out, clock=clock)
    assert not display.table
    display.island(0, 0, _pop(0, [1.0]))
    line = display.generation(0, {0: _pop(0, [1.0])}, remaining=5)
    assert out.getvalue() == line + "\n" and "\x1b" not in out.getvalue()
    quiet = ProgressDisplay(total_generations=5, out=_Terminal(), quiet=True)
    assert not quiet.table


def test_the_display_draws_from_the_coordinators_hooks_in_the_order_they_subscribed():
    from types import SimpleNamespace

    from genr8_dist.distributed.coordinator import Hooks

    out, seen = io.StringIO(), []
    hooks = Hooks()
    display = ProgressDisplay(total_generations=0, out=out, table=False)
    display.attach(hooks)
    hooks.subscribe(on_generation=lambda run, g: seen.append(("after the display", g, out.getvalue())),
                    on_message=lambda run, text: seen.append(("message", text)))
    run = SimpleNamespace(last=20, populations=lambda g: {0: _pop(0, [3.0, 1.0])})
    hooks.say(run, "migration after generation 5")
    hooks.generation_done(run, 4)
    lines = out.getvalue().splitlines()
    assert lines[0] == "migration after generation 5" and lines[1].startswith("gen  4/20")
    assert display.total_generations == 20   # read from the run: an edit may move its last generation
    assert seen[0] == ("message", "migration after generation 5")
    assert seen[1][:2] == ("after the display", 4) and "gen  4/20" in seen[1][2]
