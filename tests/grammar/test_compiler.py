"""A malformed universe is refused with one line naming the file, line and column."""

from __future__ import annotations

from pathlib import Path

import pytest

from genr8_dist.errors import UniverseError
from genr8_dist.grammar import load_universe
from genr8_dist.grammar.compiler import compile_grammar


@pytest.mark.parametrize("text, where, words", [
    ('start: "x" (\n', ":1:13:", "Unclosed parenthesis"),
    ('start: a\n', ":1:8:", "Rule 'a' used but not defined"),
    ('start: "x"\n  | A\n', ":2:5:", "'A' used but not defined"),
    ('start: EDGE\nEDGE: "Edge"\n', ":2:1:", "must be defined by a regular expression"),
    ('start: EDGE\nEDGE: /Ed.ge[0-9]+/\n', ":2:1:", "literal text around one label hole"),
    ('start: NUM\nNUM: /[0-9]+/\n', ":2:1:", "terminal NUM cannot be generated"),
    ('start: "a" /x+/\n', ":1:1:", "regular expression /x+/ directly"),
    ('//@ frobnicate\nstart: "x"\n', ":1:1:", "unknown directive '//@ frobnicate'"),
    ('//@ bias start\nstart: "x"\n', ":1:1:", "X an integer >= 2"),
    ('//@ bias start 1\nstart: "x"*\n', ":1:1:", "X an integer >= 2"),
    ('\n//@ bias nothere 3\nstart: "x"\n', ":2:1:", "names no rule"),
    ('//@ repair nothere\nstart: "x"\n', ":1:1:", "names no rule"),
    ('//@ bias start#2 3\nstart: "x"*\n', ":1:1:", "has only 1 repetition"),
    ('start: a\na: "x" a\n', ":2:1:", "rule a can never finish"),
    ('foo: "x"\n', ":1:1:", "needs a rule named 'start'"),
    ('start: "x"~3\n', ":1:1:", "repetition range"),
    ('_t{x}: x\nstart: _t{"a"}\n', ":1:1:", "template"),
    ('//@ number N 1\nstart: N\nN: /[0-9]+/\n', ":1:1:", "write '//@ number TERMINAL LO HI'"),
    ('//@ number N 5 1\nstart: N\nN: /[0-9]+/\n', ":1:1:", "HI (1) is below LO (5)"),
    ('//@ number N 0 1 0\nstart: N\nN: /[0-9]+/\n', ":1:1:", "STEP must be > 0"),
    ('//@ number N 0 x\nstart: N\nN: /[0-9]+/\n', ":1:1:", "must be numbers"),
    ('//@ number N 0 1e9\nstart: N\nN: /[0-9]+/\n', ":1:1:", "at most 10000"),
    ('//@ number N -1 1\nstart: N\nN: /[0-9]+/\n', ":3:1:", "does not match the value -1"),
    ('//@ number N 0 1\nstart: N\nN: "1"\n', ":3:1:", "numeric terminal N must be defined by a regular"),
    ('//@ number M 0 1\nstart: "x"\n', ":1:1:", "names no terminal used"),
])
def test_malformed_universe_errors_name_file_line_column(text, where, words):
    with pytest.raises(UniverseError) as info:
        compile_grammar(text, "bad.lark")
    message = str(info.value)
    assert message.startswith("bad.lark" + where), message
    assert words in message
    assert "\n" not in message


def test_loading_a_malformed_file_names_its_path(tmp_path: Path):
    path = tmp_path / "broken.lark"
    path.write_text('start: axiom\naxiom: EDGE "+" (EDGE\nEDGE: /Edge[0-9]+/\n')
    with pytest.raises(UniverseError, match=rf"^{path}:2:\d+: "):
        load_universe(str(path))


def test_bias_directive_applies_per_rule_and_per_repetition():
    cg = compile_grammar('//@ bias start 5\n//@ bias start#2 3\nstart: "a"* "b"* "c"*\n', "x.lark")
    reps = [node for node in cg.rules["start"][0][1] if node[0] == "rep"]
    assert [rep[2] for rep in reps] == [5, 3, 5]


@pytest.mark.parametrize("lo, hi, step, values", [
    ("-1", "3", "1", ("-1", "0", "1", "2", "3")),
    ("0.5", "2", "0.5", ("0.5", "1.0", "1.5", "2.0")),
    ("0", "1", "0.3", ("0.0", "0.3", "0.6", "0.9")),      # HI need not be reached
    ("-2.5", "-2.5", "1", ("-2.5",)),
    ("1", "1.2", "0.1", ("1.0", "1.1", "1.2")),           # exact: no 1.2000000000000002
])
def test_number_directive_values_are_exact_and_printed_with_the_steps_decimals(lo, hi, step, values):
    cg = compile_grammar(f"//@ number N {lo} {hi} {step}\nstart: N\nN: /-?[0-9.]+/\n", "x")
    assert cg.rules["start"] == (("num", values, "N"),)
    assert cg.min_depth == {"start": 1}


def test_minimum_depths_and_edge_templates():
    cg = compile_grammar('start: a "x"\na: "(" a ")" | b\nb: EDGE_I\nEDGE_I: /Edge[0-9]+_i\\+1/\n', "x")
    assert cg.min_depth == {"start": 3, "a": 2, "b": 1}
    (template,) = cg.templates
    assert (template.prefix, template.suffix) == ("Edge", "_i+1")
    assert template.text(7) == "Edge7_i+1"
    assert template.regex().fullmatch("Edge12_i+1").group(1) == "12"


# --- nesting: groups deeper than MAX_NESTING refused, naming where, before Lark's loader recurses -----

def _grouped(levels: int, opener: str = "(", closer: str = ")") -> str:
    default = (Path(__file__).parents[2] / "grammars" / "default.lark").read_text()
    return default.replace("successor: modifier* EDGE",
                           f"successor: {opener * levels} modifier* EDGE {closer * levels}")


@pytest.mark.parametrize("levels", [500, 5000])
@pytest.mark.parametrize("brackets", ["()", "[]"])
def test_groups_nested_too_deep_are_one_error_at_the_group(levels, brackets):
    from genr8_dist.grammar.compiler import MAX_NESTING

    text = _grouped(levels, *brackets)
    line = text[:text.index("successor: ")].count("\n") + 1
    with pytest.raises(UniverseError) as info:
        compile_grammar(text, "deep.lark")
    column = len("successor: ") + MAX_NESTING + 1
    assert str(info.value).startswith(f"deep.lark:{line}:{column}: groups nest deeper than {MAX_NESTING}")
    assert "\n" not in str(info.value)


def test_the_deepest_grouping_allowed_compiles_and_maps():
    from genr8_dist.grammar.compiler import MAX_NESTING

    compiled = compile_grammar(_grouped(MAX_NESTING), "deep.lark")
    assert "successor" in compiled.rules


def test_brackets_in_strings_regular_expressions_and_comments_do_not_count():
    text = _grouped(3).replace('EDGE: /Edge[0-9]+/', 'EDGE: /Edge[0-9]+/  // ' + "(" * 300) + \
        "\n// " + "[" * 300 + "\n"
    assert "successor" in compile_grammar(text, "ok.lark").rules
