"""``genr8 universes``, ``genr8 map`` and ``genr8 invert`` run in-process: output and exit codes."""

from __future__ import annotations

import io
import json

import pytest

from genr8_dist.cli import main
from genr8_dist.grammar import load_universe

WORKED = 'start: axiom\naxiom: EDGE "+" EDGE "+" EDGE ("+" EDGE)*\nEDGE: /Edge[0-9]+/\n%ignore " "\n'


def run(capsys, *argv):
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


def test_universes_lists_names_and_origins(capsys):
    code, out, _ = run(capsys, "universes")
    assert code == 0
    names = [line.split()[0] for line in out.splitlines()]
    assert names[:6] == ["default", "gecco", "probabilistic", "reversible", "symmetric", "symmetric_thesis"]
    assert "timed" in names and "plugin:" in out
    code, out, _ = run(capsys, "universes", "--json")
    listed = {u["name"]: u for u in json.loads(out)}
    assert listed["default"]["origin"] == "built-in" and listed["default"]["path"].endswith("default.lark")


def test_map_prints_the_journal_worked_example(tmp_path, capsys):
    path = tmp_path / "worked.lark"
    path.write_text(WORKED)
    code, out, _ = run(capsys, "map", "--universe", str(path), "--genome", "212,187,632,832,800,517,338,39")
    assert (code, out) == (0, "Edge2 + Edge0 + Edge0 + Edge2")
    code, out, _ = run(capsys, "map", "--universe", str(path), "--genome",
                       "212, 187, 632, 832, 800, 517, 338, 39", "--json")
    assert json.loads(out) == {"universe": "worked", "genome": [212, 187, 632, 832, 800, 517, 338, 39],
                               "text": "Edge2 + Edge0 + Edge0 + Edge2", "valid": True, "reason": None,
                               "codons_used": 8, "wraps": 0, "warnings": []}


def test_map_random_is_seeded_and_matches_the_api(capsys):
    code, first, _ = run(capsys, "map", "--random", "--seed", "3", "--json")
    _, second, _ = run(capsys, "map", "--universe", "default", "--random", "--seed", "3", "--json")
    assert code == 0 and first == second
    record = json.loads(first)
    assert len(record["genome"]) == 200 and max(record["genome"]) <= 65535
    assert load_universe("default").map(record["genome"]).text == record["text"]
    _, other, _ = run(capsys, "map", "--random", "--seed", "4", "--length", "50", "--json")
    assert len(json.loads(other)["genome"]) == 50 and json.loads(other)["text"] != record["text"]


def test_map_of_an_invalid_genome_exits_1_with_the_reason(capsys):
    code, out, err = run(capsys, "map", "--genome", "3", "--max-wraps", "0")
    assert code == 1 and out == "" and "genome exhausted" in err


@pytest.mark.parametrize("argv, message", [
    (["map", "--genome", "1,-2,3"], "codon 1 is -2"),
    (["map", "--genome", "1,2.5"], "codon 1 is '2.5'"),
    (["map", "--genome", ""], "the genome is empty"),
    (["map", "--genome", "1,x"], "codon 1 is 'x'"),
    (["map", "--universe", "nope", "--genome", "1"], "unknown universe 'nope'"),
    (["map", "--genome", "1", "--max-depth", "0"], "--max-depth must be >= 1"),
    (["invert", "--universe", "default", "/no/such/file.hemls"], "/no/such/file.hemls"),
])
def test_bad_input_is_one_line_and_exit_2(capsys, argv, message):
    code, out, err = run(capsys, *argv)
    assert code == 2 and out == ""
    assert err.startswith("genr8: error: ") and message in err and err.count("\n") == 1


def test_invert_of_a_binary_file_is_a_one_line_error(tmp_path, capsys):
    path = tmp_path / "system.bin"
    path.write_bytes(b"\xff\xfe\x00Edge0")
    code, _, err = run(capsys, "invert", str(path))
    assert code == 2 and f"{path}: not UTF-8 text" in err


def test_malformed_universe_file_names_line_and_column(tmp_path, capsys):
    path = tmp_path / "bad.lark"
    path.write_text('start: "a" (\n')
    code, _, err = run(capsys, "map", "--universe", str(path), "--genome", "1")
    assert code == 2 and f"{path}:1:13: Unclosed parenthesis" in err


def test_invert_prints_a_genome_that_maps_back(tmp_path, capsys):
    system = ("Edge2 + Edge0 + Edge0\nEdge2 > Edge0 -> ^ Edge0 & Edge1\nEdge0 -> Edge2\nEdge1 -> Edge0\n"
              "Angle 30\nBranchAngle 75\n")
    path = tmp_path / "b.hemls"
    path.write_text(system)
    code, out, _ = run(capsys, "invert", "--universe", "reversible", str(path))
    assert code == 0
    genome = [int(c) for c in out.strip().split(",")]
    assert load_universe("reversible").map(genome).text == system
    code, out, _ = run(capsys, "invert", "--universe", "reversible", str(path), "--json")
    record = json.loads(out)
    assert record["genome"] == genome and record["text"] == system


def test_invert_reads_standard_input_and_reports_texts_outside_the_universe(capsys, monkeypatch):
    monkeypatch.setattr("sys.stdin", io.StringIO("Edge0 + Edge1\nAngle 30\n"))
    code, out, err = run(capsys, "invert", "--universe", "default", "-")
    assert code == 2 and out == ""
    assert "genr8: error: <stdin>: line 1, column 14:" in err and "universe 'default'" in err


def test_map_then_invert_round_trip_through_the_cli(capsys, monkeypatch):
    _, text, _ = run(capsys, "map", "--universe", "symmetric", "--random", "--seed", "11")
    monkeypatch.setattr("sys.stdin", io.StringIO(text))
    code, out, _ = run(capsys, "invert", "--universe", "symmetric", "-")
    assert code == 0
    _, again, _ = run(capsys, "map", "--universe", "symmetric", "--genome", out.strip())
    assert again == text


def test_invert_skips_comment_lines_and_names_the_file_and_original_line(tmp_path, capsys):
    text = load_universe("default").map([5, 9, 14, 3, 7, 1, 8, 2, 6, 4] * 20).text
    commented = tmp_path / "commented.hemls"
    commented.write_text("// written by hand\n\n# keep this\n" + text)
    assert main(["invert", "--universe", "default", str(commented)]) == 0
    genome = [int(v) for v in capsys.readouterr().out.strip().split(",")]
    assert load_universe("default").map(genome).text == text

    outside = tmp_path / "tiles.hemls"
    outside.write_text("// four-sided tiles\nEdge0 + ~ Edge1 + ~ Edge0 + Edge1\n"
                       "Edge0 -> Edge0 [ [ + Edge1 ] - Edge1 ] Edge0\nAngle 90\n")
    assert main(["invert", "--universe", "default", str(outside)]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"genr8: error: {outside}: line 3, column ")
    assert err.count("\n") == 1


def test_map_warns_about_a_rule_that_can_never_fire(capsys):
    code, out, err = run(capsys, "map", "--random", "--seed", "14")
    assert code == 0 and "Edge0 < Edge0 > Edge1 -> Edge4" in out
    assert err.strip() == ("genr8: warning: line 4: the rule for Edge0 can never fire: the rule on line 2 "
                           "rewrites every such edge first (for a random choice write the successors in "
                           "one rule, or 'p =' on each)")
    code, out, _ = run(capsys, "map", "--random", "--seed", "14", "--json")
    assert json.loads(out)["warnings"] == [err.strip()[len("genr8: warning: "):]]


def test_map_of_a_plugin_phenotypes_universe_prints_its_text_without_hemls_warnings(capsys):
    code, out, err = run(capsys, "map", "--universe", "tables", "--random", "--seed", "2")
    assert code == 0 and out.startswith("P0 ( ") and " iterations " in out.splitlines()[0]
    assert err == ""


@pytest.mark.parametrize("levels", [500, 5000])
def test_map_and_invert_refuse_nesting_too_deep_in_one_line(tmp_path, capsys, levels):
    from pathlib import Path

    default = (Path(__file__).parents[2] / "grammars" / "default.lark").read_text()
    universe = tmp_path / "deep.lark"
    universe.write_text(default.replace("successor: modifier* EDGE",
                                        f"successor: {'(' * levels} modifier* EDGE {')' * levels}"))
    status, out, err = run(capsys, "map", "--universe", str(universe), "--random")
    assert status == 2 and out == "" and len(err.splitlines()) == 1
    assert err.startswith(f"genr8: error: {universe}:") and "groups nest deeper than 100 levels" in err

    text = tmp_path / "deep.hemls"
    text.write_text("Edge0 + Edge1 + Edge2\nEdge0 -> " + "Edge0 [ " * levels + "Edge0 " + "] Edge0 " * levels
                    + "Edge0\nAngle 30\nBranchAngle 15\n")
    status, out, err = run(capsys, "invert", str(text))
    assert status == 2 and out == ""
    assert err == f"genr8: error: {text}: line 2, column 816: brackets nest deeper than 100 levels (the " \
                  "limit of a rewrite system, docs/hemls.md)\n"


def test_a_genome_with_a_newline_is_echoed_on_one_line(capsys):
    status, out, err = run(capsys, "map", "--genome", "1,x\ny")
    assert status == 2 and out == ""
    assert err == "genr8: error: codon 1 is 'x\\ny': codons are non-negative integers\n"
