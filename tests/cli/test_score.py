"""``genr8 score``, run in-process."""

from __future__ import annotations

import io
import json

import pytest

from genr8_dist.cli import main
from genr8_dist.fitness import CRITERIA

TILES = "Edge0 + ~ Edge1 + ~ Edge0 + Edge1\nEdge0 -> Edge0 [ [ + Edge1 ] - Edge1 ] Edge0\n" \
        "Edge1 -> Edge1 [ [ + Edge0 ] - Edge0 ] Edge1\nAngle 90\n"


def score_json(capsys, *argv):
    assert main(["score", *argv, "--json"]) == 0
    return json.loads(capsys.readouterr().out)


def test_table_lists_every_criterion_and_the_total(capsys, tmp_path):
    env = tmp_path / "env.toml"
    env.write_text("steps = 2\n")
    assert main(["score", "four-sided-tiles", "--env", str(env)]) == 0
    out = capsys.readouterr().out
    for name in (*CRITERIA, "total"):
        assert any(line.startswith(name) for line in out.splitlines()), name
    assert "25 vertices, 40 edges, 16 regions after 2 derivation steps" in out


def test_json_report_of_the_four_sided_tiles(capsys, tmp_path):
    env = tmp_path / "env.toml"
    env.write_text("steps = 3\n")
    report = score_json(capsys, "four-sided-tiles", "--env", str(env))
    m = 2**3
    assert report["vertices"] == (m + 1) ** 2 and report["edges"] == 2 * m * (m + 1)
    crit = report["criteria"]
    assert list(crit) == list(CRITERIA)
    assert crit["subdivisions"]["raw"] == pytest.approx((m + 1) ** 2 / (2 * m * (m + 1)))
    assert crit["undulation"]["raw"] == 0.0 and crit["smoothness"]["raw"] == 0.0
    assert crit["symmetry"]["raw"] == 1.0
    assert crit["size"]["raw"] == pytest.approx(2 * 1.5**3)   # start length 1, scale 1.5, 3 steps
    assert report["total"] == pytest.approx(sum(c["deviation"] for c in crit.values()))
    assert report["valid"] is True


def test_fitness_from_a_run_configuration(capsys, tmp_path):
    config = tmp_path / "run.toml"
    config.write_text("[fitness.size]\ntarget = 2.0\nweight = 10\n[environment]\nsteps = 1\n")
    report = score_json(capsys, "four-sided-tiles", "--fitness", str(config))
    size = report["criteria"]["size"]
    assert size["target"] == 2.0 and size["weight"] == 10.0
    assert size["deviation"] == pytest.approx(10 * abs(size["raw"] - 2.0) / 2.0)
    assert report["steps"] == 1  # the configuration's environment is used when --env is not given


def test_the_table_leaves_out_criteria_the_configuration_does_not_mention_and_that_count_for_nothing(
        capsys, tmp_path):
    """quick.toml-like: `smoothness` named with weight 0 is shown; `cells` (default weight 0) is not
    named and not shown; `size` not named but weighted by default is shown, marked (default)."""
    from genr8_dist.fitness import FitnessSpec

    defaults = FitnessSpec()
    assert defaults["cells"].weight == 0 and defaults["size"].weight > 0
    config = tmp_path / "run.toml"
    config.write_text("[fitness]\nsmoothness = { target = 0.0, weight = 0.0 }\n"
                      "undulation = { target = 1.0, weight = 1.0 }\n[environment]\nsteps = 1\n")
    assert main(["score", "four-sided-tiles", "--fitness", str(config)]) == 0
    rows = {line.split()[0]: line for line in capsys.readouterr().out.splitlines()[3:-2]}
    assert "cells" not in rows and "smoothness" in rows and "undulation" in rows
    assert rows["size"].endswith("(default)") and not rows["undulation"].endswith("(default)")
    shown = [n for n in CRITERIA if n in rows]
    assert shown == [n for n in CRITERIA if n in ("smoothness", "undulation") or defaults[n].weight > 0]
    report = score_json(capsys, "four-sided-tiles", "--fitness", str(config))
    assert list(report["criteria"]) == list(CRITERIA)   # the JSON report keeps every criterion


def test_system_from_stdin(capsys, monkeypatch, tmp_path):
    monkeypatch.setattr("sys.stdin", io.StringIO(TILES))
    env = tmp_path / "env.toml"
    env.write_text("steps = 1\n")
    report = score_json(capsys, "-", "--env", str(env))
    assert report["vertices"] == 9 and report["edges"] == 12


def test_errors_are_one_line_and_exit_2(capsys, tmp_path):
    assert main(["score", "no-such-system"]) == 2
    assert capsys.readouterr().err.startswith("genr8: error:")
    bad = tmp_path / "bad.hemls"
    bad.write_text("Edge0 + Edge1 +\n")
    assert main(["score", str(bad)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("genr8: error:") and "bad.hemls:1:" in err and "Traceback" not in err
    config = tmp_path / "run.toml"
    config.write_text("[fitness.size]\nweight = -1\n")
    assert main(["score", "square", "--fitness", str(config)]) == 2
    assert "'fitness.size.weight'" in capsys.readouterr().err


def test_a_plugin_phenotypes_text_is_scored_by_its_phenotype(capsys, tmp_path):
    from pathlib import Path

    examples = Path(__file__).resolve().parents[2] / "examples" / "tables.toml"
    tree = tmp_path / "tree.txt"
    tree.write_text("P0 ( 4 ) iterations 4\n"
                    "P0 ( n0 ) : n0 > 1.0 -> [ P1 ( n0 * 1.5 ) ] ^ ( 1 ) f ( 3 ) v ( 1 ) P0 ( n0 - 1 )\n"
                    "P1 ( n0 ) : n0 > 1.0 -> { [ f ( n0 ) ] < ( 1 ) } ( 4 )\n")
    report = score_json(capsys, str(tree), "--fitness", str(examples))
    assert report["valid"] and report["universe"] == "tables"
    assert report["criteria"] == {"height": 9.0, "surface": 1.0, "stability": 183.0, "excess": 61.0,
                                  "voxels": 62.0}
    assert report["fitness"] == pytest.approx(-27.0)     # the paper's 9 * 1 * 183 / 61, negated
