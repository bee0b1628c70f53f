"""A universe is checked when it is loaded: each fault a user met later (a traceback, a run whose every
individual failed, a hook silently ignored) is refused at once in one line naming file, line and fault;
one broken plugin breaks no other universe; compiling chained rules stays fast."""

from __future__ import annotations

import importlib.metadata
import time
from pathlib import Path

import pytest

from genr8_dist.cli import main
from genr8_dist.grammar import ENTRY_POINT_GROUP, list_universes
from genr8_dist.resources import grammars_dir

DEFAULT = (grammars_dir() / "default.lark").read_text()
SYSTEM = "Edge0 + Edge0 + Edge0 + Edge0\nEdge0 -> Edge0\nAngle 30\nBranchAngle 15\n"



@pytest.fixture(autouse=True)
def _own_trust_file(tmp_path, monkeypatch):
    """--trust-hooks remembers digests: in this test's file, never the user's."""
    monkeypatch.setenv("GENR8_TRUST_FILE", str(tmp_path / "trusted-hooks"))

def variant(tmp_path: Path, old: str, new: str, name: str = "broken") -> Path:
    assert old in DEFAULT
    path = tmp_path / f"{name}.lark"
    path.write_text(DEFAULT.replace(old, new))
    return path


def one_error_line(capsys, *argv: str) -> str:
    status = main([str(a) for a in argv])
    captured = capsys.readouterr()
    assert status == 2, captured
    assert "Traceback" not in captured.err
    (line,) = captured.err.splitlines()
    assert line.startswith("genr8: error: ")
    return line[len("genr8: error: "):]


def test_a_literal_holding_a_space(tmp_path, capsys):
    path = variant(tmp_path, 'angle_value: "30" | "45"', 'angle_value: "30" | "4 5"')
    message = one_error_line(capsys, "map", "--universe", path, "--random")
    assert message == (f"{path}:36:21: the literal '4 5' in rule angle_value holds whitespace: a literal "
                       "is one token of the text (tokens are separated by spaces); split it into several "
                       "literals")


def test_a_literal_the_phenotype_cannot_parse(tmp_path, capsys):
    """Before: every individual failed at `parse`, `best inf` every generation, exit 0."""
    path = variant(tmp_path, 'angle_value: "30" | "45"', 'angle_value: "30" | "forty"')
    message = one_error_line(capsys, "map", "--universe", path, "--random")
    assert message == (f"{path}:36:21: the literal \"forty\" (rule angle_value) derives text the phenotype's "
                       "parser cannot read: unexpected character 'f'; expected a number")
    toml = tmp_path / "run.toml"
    toml.write_text(f'universe = "{path.name}"\n')
    message = one_error_line(capsys, "run", toml, "--run-dir", tmp_path / "run")
    assert message.startswith(f"{toml}: field 'universe': {path}:36:21: the literal \"forty\"")
    assert not (tmp_path / "run").exists()


def test_three_optionals_side_by_side(tmp_path, capsys):
    """Before: `genr8 invert` died with lark's GrammarError traceback."""
    path = variant(tmp_path, "successor: modifier* EDGE",
                   'successor: modifier* EDGE ["+" EDGE] ["+" EDGE] ["+" EDGE]')
    system = tmp_path / "s.hemls"
    system.write_text(SYSTEM)
    message = one_error_line(capsys, "invert", "--universe", path, system)
    assert message.startswith(f"{path}:21:1: rule successor: its optional parts ([...] or ?) side by side "
                              "can expand to the same sequence in two ways")


def test_recursion_is_reported_at_the_rule_that_recurses(tmp_path, capsys):
    path = variant(tmp_path, "successor: modifier* EDGE", "successor: modifier* EDGE successor")
    message = one_error_line(capsys, "map", "--universe", path, "--random")
    assert message.startswith(f"{path}:21:1: rule successor can never finish: every alternative expands "
                              "successor again")


@pytest.mark.parametrize("old, new, where, words", [
    ("PRED: /Edge[0-9]+/", "PRED /Edge[0-9]+/", ":40:6:",
     "syntax error: unexpected regular expression '/Edge[0-9]+/'; expected '.' or ':'"),
    ("predecessor: PRED CTX*", "predecessor PRED CTX*", ":16:13:",
     "syntax error: unexpected terminal name 'PRED'; expected '.' or ':' or '{'"),
])
def test_syntax_errors_in_our_words_with_the_location_once(tmp_path, capsys, old, new, where, words):
    path = variant(tmp_path, old, new)
    message = one_error_line(capsys, "map", "--universe", path, "--random")
    assert message == f"{path}{where} {words}"


def plugin(root: Path, name: str, hooks: str) -> Path:
    folder = root / name
    folder.mkdir(parents=True)
    (folder / f"{name}.lark").write_text(DEFAULT)
    (folder / "hooks.py").write_text(hooks)
    return folder


def test_a_misspelt_hook_is_named(tmp_path, capsys):
    folder = plugin(tmp_path, "typo", "def _helper():\n    pass\n\n\ndef repare(ctx):\n    pass\n")
    message = one_error_line(capsys, "map", "--universe", folder, "--random")
    assert message == (f"{folder}/hooks.py:5:1: unknown hook 'repare': did you mean 'repair'? hooks.py may "
                       "define repair; start helper functions' names with '_'")


def test_a_hook_that_raises_is_a_map_failure_naming_it(tmp_path, capsys):
    folder = plugin(tmp_path, "raising", "def repair(ctx):\n    raise ValueError('no luck')\n")
    status = main(["map", "--universe", str(folder), "--random", "--seed", "1", "--trust-hooks"])
    captured = capsys.readouterr()
    assert status == 1 and "Traceback" not in captured.err
    assert captured.err == ("genr8: invalid genome: hook repair of universe 'raising' raised ValueError: "
                            "no luck\n")
    from genr8_dist.config import RunConfig
    from genr8_dist.evolution.evaluate import evaluate_genome

    config = RunConfig(universe=str(folder))
    result = evaluate_genome(list(range(1, 80)), config)
    assert (result.valid, result.stage) == (False, "map")
    assert result.error == "hook repair of universe 'raising' raised ValueError: no luck"


def test_a_hook_that_calls_sys_exit_is_a_map_failure_not_a_silent_end(tmp_path, capsys):
    folder = plugin(tmp_path, "exiting", "import sys\n\n\ndef repair(ctx):\n    sys.exit(0)\n")
    status = main(["map", "--universe", str(folder), "--random", "--seed", "1", "--trust-hooks"])
    captured = capsys.readouterr()
    assert status == 1 and "Traceback" not in captured.err
    assert captured.err == "genr8: invalid genome: hook repair of universe 'exiting' raised SystemExit: 0\n"


def test_one_broken_plugin_breaks_no_other_universe(tmp_path, monkeypatch, capsys):
    two = tmp_path / "plugins" / "twofold"
    two.mkdir(parents=True)
    (two / "a.lark").write_text(DEFAULT)
    (two / "b.lark").write_text(DEFAULT)
    eps = [importlib.metadata.EntryPoint("ghost", "no_such_module_xyz:universe", ENTRY_POINT_GROUP)]
    real = importlib.metadata.entry_points
    monkeypatch.setattr(importlib.metadata, "entry_points",
                        lambda **kw: eps if kw.get("group") == ENTRY_POINT_GROUP else real(**kw))
    monkeypatch.setenv("GENR8_PLUGINS", str(tmp_path / "plugins"))

    assert main(["map", "--universe", "default", "--random", "--seed", "3"]) == 0
    capsys.readouterr()
    assert main(["universes"]) == 0
    listing = capsys.readouterr().out
    assert "default" in listing and "timed" in listing
    broken = {i.name: i.error for i in list_universes() if i.error}
    assert broken == {
        "twofold": f"{two}: a plugin folder holds one .lark file (or <name>.lark or universe.lark); "
                   "found a.lark, b.lark",
        "ghost": "entry point 'ghost' of ? (no_such_module_xyz:universe) cannot be loaded: "
                 "ModuleNotFoundError: No module named 'no_such_module_xyz'",
    }
    for name, error in broken.items():
        assert f"BROKEN: {error}" in listing
        assert one_error_line(capsys, "map", "--universe", name, "--random") == error


def chained(n: int) -> str:
    """``n`` rules, each using the next twice (``rI: rJ "x" | "y" rJ``): 2^n inlined expansions."""
    lines = ['start: EDGE "+" EDGE "+" EDGE "\\n" EDGE "->" r0 "\\n"', "EDGE: /Edge[0-9]+/"]
    for i in range(n):
        nxt = f"r{i + 1}" if i + 1 < n else "EDGE"
        lines.append(f'r{i}: {nxt} "+" | "-" {nxt}')
    return "\n".join(lines) + "\n"


def test_thirty_chained_rules_compile_fast(tmp_path, capsys):
    """Before: 16 rules 10 s and 1.2 GB, 18 a MemoryError, 30 over 600 s."""
    path = tmp_path / "chain.lark"
    path.write_text(chained(30))
    t0 = time.perf_counter()
    assert main(["map", "--universe", str(path), "--random", "--max-depth", "40"]) == 0
    assert time.perf_counter() - t0 < 5.0
    text = capsys.readouterr().out
    assert text.count("+") + text.count("-") >= 30 + 2


def test_a_universe_past_the_size_limit_is_one_line(tmp_path, capsys, monkeypatch):
    from genr8_dist.grammar import compiler

    monkeypatch.setattr(compiler, "MAX_NODES", 50)
    path = tmp_path / "chain.lark"
    path.write_text(chained(20))
    message = one_error_line(capsys, "map", "--universe", path, "--random")
    assert message == f"{path}: the universe is too large: 131 grammar nodes in 21 rules (at most 50)"
