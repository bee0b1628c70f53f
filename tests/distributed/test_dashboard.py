"""``--dashboard``: Ray's dashboard for a run, its URL printed (off for a local Ray by default, a
cluster's printed when its head runs one)."""

from __future__ import annotations

import io
import subprocess
import sys
import urllib.request

import pytest

from genr8_dist.cli import build_parser
from genr8_dist.distributed.session import RunOptions, _dashboard_options


@pytest.mark.parametrize("argv, expected", [([], None), (["--dashboard"], True), (["--no-dashboard"], False)])
def test_the_flag_reaches_the_run_options(argv, expected, tmp_path):
    from genr8_dist.cli.run import _options

    for command in (["run", "x.toml", "--run-dir", str(tmp_path / "r")], ["resume", str(tmp_path / "r")]):
        args = build_parser().parse_args([*command, *argv])
        assert _options(args).dashboard is expected


def test_the_url_is_printed_when_there_is_one_and_asked_for_when_not():
    out = io.StringIO()
    default = _dashboard_options(RunOptions(), out)
    assert default["dashboard"] is False                 # a local Ray starts none by default
    default["on_dashboard"]("http://10.0.0.5:8265")       # a cluster's head runs one: printed
    default["on_dashboard"](None)                        # none there, none asked for: nothing said
    assert out.getvalue() == "dashboard: http://10.0.0.5:8265\n"
    out = io.StringIO()
    asked = _dashboard_options(RunOptions(dashboard=True), out)
    assert asked["dashboard"] is True
    asked["on_dashboard"](None)
    assert out.getvalue().startswith("dashboard: none on this cluster")
    assert _dashboard_options(RunOptions(dashboard=False), out)["on_dashboard"] is None


TOML = """\
universe = "default"
seed = 3
[genome]
length = 30
[ea]
population = 4
generations = 1
[environment]
steps = 1
"""


@pytest.mark.slow
def test_a_run_with_dashboard_prints_a_url_that_answers(tmp_path):
    config = tmp_path / "run.toml"
    config.write_text(TOML)
    proc = subprocess.Popen([sys.executable, "-m", "genr8_dist.cli", "run", str(config), "--run-dir",
                             str(tmp_path / "run"), "--cpus", "1", "--dashboard"],
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    url, seen = None, []
    try:
        for line in proc.stdout:
            seen.append(line)
            if line.startswith("dashboard: "):
                url = line.split()[1]
                with urllib.request.urlopen(url, timeout=30) as answer:   # while the run holds Ray
                    assert answer.status == 200
                break
    finally:
        rest, _ = proc.communicate(timeout=600)
    assert url is not None and url.startswith("http://127.0.0.1:"), "".join(seen) + rest
    assert proc.returncode == 0, "".join(seen) + rest
