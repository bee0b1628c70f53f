"""The HEMLS parser: every construct of the language, printing back, and located errors."""

from __future__ import annotations

import pytest

from genr8_dist.errors import ParseError
from genr8_dist.hemls import PREDEFINED, Branch, Condition, Segment, load_system, parse

AA_WEIGHTED = """Edge0 + ~ Edge1 + ~ Edge0 + Edge1
Edge0 -> Edge0 [ [ + + Edge1 ] - - Edge1 ] Edge0    Weight 2
     -> Edge0 - Edge0 + + Edge0 - Edge0
Edge1 -> Edge1 [ [ + + Edge0 ] - - Edge0 ] Edge1    Weight 4
     -> Edge1 \\ Edge1 / / Edge1 \\ Edge1
Angle 90
"""

AA_TIMED = """Edge0 + ~ Edge1 + ~ Edge0 + Edge1
Edge0_i -> Edge0_i+1 [ [ + Edge1_i ] - Edge1_i ] Edge0_i+1 If i < 3
Edge0_i -> Edge0_i+1
Edge1_i -> Edge1_i+1 [ [ + Edge0_i ] - Edge0_i ] Edge1_i+1 If i < 1
Edge1_i -> Edge1_i+1
Angle 90
"""


@pytest.mark.parametrize("name", PREDEFINED)
def test_predefined_systems_parse_and_print_back(name):
    system = load_system(name)
    assert system.name == name
    assert parse(system.to_text()) == system
    assert len(system.axiom) >= 3 and system.rules


def test_canonical_text_prints_back_unchanged():
    text = ("Edge0 + ~ Edge1 + Edge2\n"
            "Edge2 < Edge0 > Edge1 -> Edge0 [ [ + Edge1 ] - Edge1 ] ~ Edge0 Weight 3 -> Edge0 Weight 1\n"
            "Edge1_i -> Edge1_i+1 & Edge2_i-1 ^ Edge1_i If i < 2\n"
            "Edge2 -> Edge2\n"
            "Angle 45\nSync\nBranchAngle 15.5\n")
    assert parse(text).to_text() == text


def test_manual_example_with_comments_and_single_brackets():
    text = """Edge0 + Edge1 + Edge2 + Edge3
// This is a comment, the parser ignores this text
Edge0 -> Edge3 [ + Edge0 ] Edge1
Edge1 -> Edge1
Edge2 -> Edge1 [ + Edge0 ] Edge1
Edge3 -> Edge2
# Another comment
Angle 90
Sync
BranchAngle 30
"""
    s = parse(text)
    assert len(s.rules) == 4 and s.sync and s.angle == 90 and s.branch_angle == 30
    assert s.rules[0].successors[0].symbols == (
        Segment("Edge3"), Branch(("+", Segment("Edge0"))), Segment("Edge1"))


def test_continuation_lines_and_weights():
    s = parse(AA_WEIGHTED)
    r0 = s.rules[0]
    assert len(s.rules) == 2 and len(r0.successors) == 2
    assert r0.weights == (2.0, 1.0)
    assert s.rules[1].weights == (4.0, 1.0)
    assert "\\" in s.rules[1].successors[1].symbols
    # the one-line form is the same system
    one_line = AA_WEIGHTED.replace("    Weight 2\n     ->", " Weight 2 ->").replace(
        "    Weight 4\n     ->", " Weight 4 ->")
    assert parse(one_line) == s


def test_timed_rules_and_conditions():
    s = parse(AA_TIMED)
    r0 = s.rules[0]
    assert r0.predecessor == Segment("Edge0", 0)
    assert r0.condition == Condition("<", 3)
    assert r0.successors[0].symbols[0] == Segment("Edge0", 1)
    assert s.rules[1].condition is None
    assert str(Segment("Edge2", -1)) == "Edge2_i-1"


def test_semicolons_separate_statements_like_newlines():
    text = "Edge0 + Edge1 + Edge2; Edge0 -> Edge0 Edge0; Angle 60; Sync"
    s = parse(text)
    assert s.angle == 60 and s.sync and len(s.rules) == 1
    assert parse(s.to_text()) == s


def test_context_forms():
    s = parse("Edge0 + Edge1 + Edge2\nEdge1 < Edge0 -> Edge0\nEdge0 > Edge2 -> Edge0\n"
              "Edge1 < Edge0 > Edge2 -> Edge0\n")
    assert [(r.left, r.right) for r in s.rules] == [
        (Segment("Edge1"), None), (None, Segment("Edge2")), (Segment("Edge1"), Segment("Edge2"))]


def test_predecessor_of_several_segments():
    s = parse("Edge0 + Edge1 + Edge2\nEdge0 Edge1 Edge2 -> Edge0\n")
    assert s.rules[0].predecessor == Segment("Edge0")
    assert s.rules[0].chain == (Segment("Edge1"), Segment("Edge2"))
    assert s.to_text().splitlines()[1] == "Edge0 Edge1 Edge2 -> Edge0"


def test_journal_letter_labels():
    s = parse("A + B + A + B\nA -> A [ [ + B ] - B ] A\nB -> B [ [ + A ] - A ] B\nAngle 90\n"
              "BranchAngle 90\n")
    assert s.label_ids() == {"A": 0, "B": 1}
    assert s.to_text().startswith("A + B + A + B\n")


def test_axiom_reverse_either_side_of_plus():
    a = parse("Edge0 + ~ Edge1 + Edge2")
    b = parse("Edge0 ~ + Edge1 + Edge2")
    assert a == b
    assert [e.reversed for e in a.axiom] == [False, True, False]
    assert parse("~ Edge0 + Edge1 + Edge2").axiom[0].reversed


def test_defaults():
    s = parse("Edge0 + Edge0 + Edge0")
    assert s.angle is None and s.turn_angle == 90 and s.cone_angle == 30 and not s.sync
    assert s.to_text() == "Edge0 + Edge0 + Edge0\n"


@pytest.mark.parametrize(("text", "line", "column", "words"), [
    ("Edge0 + Edge1", 1, 1, "at least 3 edges"),
    ("Edge0 + Edge1 + Edge2\nEdge0 => Edge1", 2, 7, "unexpected '='"),
    ("Edge0 + Edge1 + Edge2\nEdge0 -> Edge1 Weight\n", 2, 22, "expected a number"),
    ("Edge0 + Edge1 + Edge2\nEdge0 -> [ + Edge1 ]", 2, 10, "main line"),
    ("Edge0 + Edge1 + Edge2\nAngle 400", 2, 7, "between 0 and 360"),
    ("Edge0 + Edge1 + Edge2\nBranchAngle 95", 2, 13, "between 0 and 90"),
    ("Edge0 + Edge1 + Edge2\n-> Edge1", 2, 1, "must follow a rewrite rule"),
    ("Edge0 + Edge1 + Edge2\nEdge0 -> Edge1 $", 2, 16, "unexpected character '$'"),
    ("Edge0 - Edge1 + Edge2", 1, 7, "with '+' only"),
    ("Edge0 + Edge1 + Edge2\nAngle 30\nAngle 40", 3, 1, "given twice"),
    ("Edge0 + Edge1 + Edge2\nEdge0 -> Edge1 [ + Edge2", 2, 25, "expected"),
    ("Edge0 + Edge1 + Edge2\nEdge0_i+1 -> Edge1", 2, 1, "only be timed as Edge0_i"),
    ("Edge0 + Edge1 + Edge2\nEdge0 -> Edge1 Weight 0 -> Edge0 Weight 0", 2, 1, "add up to 0"),
])
def test_errors_name_line_column_and_what_was_expected(text, line, column, words):
    with pytest.raises(ParseError) as info:
        parse(text, source="sys.hemls")
    err = info.value
    assert (err.line, err.column) == (line, column), str(err)
    assert words in str(err)
    assert str(err).startswith(f"sys.hemls:{line}:{column}: ")
    assert "\n" not in str(err)


def test_empty_text_is_an_error():
    with pytest.raises(ParseError, match="empty"):
        parse("   \n")
    with pytest.raises(ParseError, match="empty"):
        parse("// only a comment\n")


def test_load_system_errors_and_files(tmp_path):
    with pytest.raises(ParseError, match="not a file"):
        load_system(tmp_path / "missing.hemls")
    path = tmp_path / "mine.hemls"
    path.write_text("Edge0 + Edge0 + Edge0\nEdge0 -> Edge0 - Edge0 + + Edge0 - Edge0\nAngle 60\n")
    assert load_system(path) == load_system("koch")
    assert load_system(path).name == "mine"
    assert load_system("four-sided-tiles") == load_system("four_sided_tiles")


def test_keywords_are_case_insensitive_and_windows_line_ends_are_fine():
    s = parse("Edge0 + Edge1 + Edge2\r\nEdge0_i -> Edge0_i+1 weight 2 -> Edge0 WEIGHT 1 if i < 2\r\n"
              "angle 22.5\r\nsync\r\nbranchangle 45\r\n")
    assert s.angle == 22.5 and s.sync and s.branch_angle == 45
    assert s.rules[0].weights == (2.0, 1.0) and s.rules[0].condition == Condition("<", 2)
    assert parse(s.to_text()) == s


TABLE_2_3 = """D + D + D + D
D -> + D - - D p = 0.5
D -> - D + + D p=0.5
Angle 45
"""


def test_table_2_3_probabilities_on_separate_rules_become_one_weighted_rule():
    system = parse(TABLE_2_3)
    assert len(system.rules) == 1
    rule = system.rules[0]
    assert rule.weights == (0.5, 0.5)
    assert [str(s) for s in rule.successors] == ["+ D - - D Weight 0.5", "- D + + D Weight 0.5"]
    assert system.warnings() == []
    assert parse(system.to_text()) == system


def test_probabilities_merge_only_rules_of_the_same_context_and_condition():
    system = parse("A + A + A\nA -> A A p = 0.3 If i < 2\nB < A -> A p = 1\nA -> A A A p = 0.7 If i < 2\n"
                   "A -> A\n")
    assert [len(r.successors) for r in system.rules] == [2, 1, 1]
    assert system.rules[0].weights == (0.3, 0.7)


def test_a_probability_above_one_is_refused_with_its_position():
    with pytest.raises(ParseError, match=r"2:14: a probability p must be between 0 and 1, got 1.5"):
        parse("A + A + A\nA -> A A p = 1.5\n")


def test_rules_that_can_never_fire_are_named_with_the_rule_that_shadows_them():
    system = parse("A + B + A + B\nA -> A B\nA -> B A\nB < A -> A\nB -> B If i < 2\nB -> B B If i < 2\n"
                   "B -> A\nB > A -> B\n")
    shadowed = [(r.line, e.line) for r, e in system.never_firing()]
    assert shadowed == [(3, 2), (4, 2), (6, 5), (8, 7)]
    assert system.warnings()[0].startswith("line 3: the rule for A can never fire: the rule on line 2")
    # a fallback after a condition or a context does fire
    assert parse(AA_TIMED).warnings() == []


# -- the direct reader agrees with Lark ------------------------------------------------------------------

def _universe_texts(per_universe: int) -> list[str]:
    from genr8_dist.evolution.operators import random_genome
    from genr8_dist.grammar import list_universes, load_universe
    from genr8_dist.phenotype import SURFACES, phenotype_of
    from genr8_dist.rng import stream

    texts = []
    for info in list_universes():
        universe = load_universe(info.name)
        if phenotype_of(universe) is not SURFACES:
            continue  # its texts are not HEMLS
        rng = stream(0, "test", "direct reader", info.name)
        for _ in range(per_universe):
            mapped = universe.map(random_genome(rng, 100, 255))
            if mapped.valid:
                texts.append(mapped.text)
    return texts


def _lark_outcome(text: str):
    from genr8_dist.hemls.language import _parse_lark

    try:
        system = _parse_lark(text, "<t>", "")
    except ParseError as exc:
        return "error", str(exc)
    return "system", (system, system.to_text(), tuple(r.line for r in system.rules))


def _outcome(text: str):
    try:
        system = parse(text, "<t>")
    except ParseError as exc:
        return "error", str(exc)
    return "system", (system, system.to_text(), tuple(r.line for r in system.rules))


def test_direct_reader_reads_every_universe_text_as_lark_does():
    from genr8_dist.hemls.language import _direct

    texts = _universe_texts(40)
    assert len(texts) > 100
    for text in texts:
        direct = _direct(text)
        assert direct is not None, text   # the universes' texts never need Lark
        assert _outcome(text) == _lark_outcome(text)


EDITS = ["", " ", "\n", "~", "+", "-", "->", "[", "]", "<", ">", "Weight", "Weight 2", "Weight -1",
         "If i < 2", "If i", "Angle 30", "Angle 400", "Sync", "BranchAngle 95", "Edge1", "Edge1_i",
         "Edge1_i+2", "A", "2", "0.5", "i", "==", "!=", ";", "// c", "#", "\t", "Edge", "1e999", "Weight 0",
         "_i", "p = 0.5", "p=1", "p = 2"]


def test_direct_reader_and_lark_agree_on_edited_texts():
    """Words inserted, deleted and swapped in universe texts: the same system or the same error."""
    from genr8_dist.rng import stream

    rng = stream(0, "test", "edited texts")
    texts = _universe_texts(8)
    checked = 0
    for text in texts:
        for _ in range(12):
            words = text.split(" ")
            k = int(rng.integers(0, len(words)))
            action = int(rng.integers(0, 3))
            if action == 0:
                words.insert(k, EDITS[int(rng.integers(0, len(EDITS)))])
            elif action == 1:
                del words[k]
            else:
                j = int(rng.integers(0, len(words)))
                words[k], words[j] = words[j], words[k]
            edited = " ".join(words)
            assert _outcome(edited) == _lark_outcome(edited), edited
            checked += 1
    assert checked > 300


APPENDIX_B = """Edge2 + Edge0 + Edge0
Edge2 > Edge0 -> ^ Edge0 & Edge1
Edge0 > Edge1 -> [ [ + + Edge0 ] - Edge2 ] Edge0
Edge1 -> Edge0
Angle 30
BranchAngle 75
"""


def test_thesis_appendix_b_rewrite_system_parses_and_grows_as_the_thesis_expects():
    """Thesis Appendix B maps a genome to this system and expects "a very boring structure that
    [is] unable to subdivide in an interesting way"."""
    from genr8_dist.environment import Environment
    from genr8_dist.hemls import grow

    system = parse(APPENDIX_B)
    assert [str(r) for r in system.rules][1] == "Edge0 > Edge1 -> [ [ + + Edge0 ] - Edge2 ] Edge0"
    assert system.turn_angle == 30 and system.cone_angle == 75 and not system.sync
    result = grow(system, Environment(steps=4))
    assert result.surface.validate() == [] and result.surface.n_regions == 1


# --- nesting: refused beyond MAX_NESTING, naming where, before any reader recurses -------------------

def _nested(levels: int, comment: bool = False) -> str:
    tail = " // read by Lark" if comment else ""
    return (f"Edge1 + Edge1 + Edge1 + Edge1{tail}\n"
            f"Edge1 -> Edge1 {'[ ' * levels}+ Edge1 {'] ' * levels}\n")


@pytest.mark.parametrize("levels", [500, 5000])
@pytest.mark.parametrize("comment", [False, True])   # the direct reader's text, and Lark's
def test_brackets_nested_too_deep_are_one_parse_error_at_the_bracket(levels, comment):
    from genr8_dist.hemls.language import MAX_NESTING

    with pytest.raises(ParseError) as info:
        parse(_nested(levels, comment), source="deep.hemls")
    column = len("Edge1 -> Edge1 ") + 2 * MAX_NESTING + 1    # the (MAX_NESTING + 1)-th '['
    assert (info.value.line, info.value.column) == (2, column)
    assert str(info.value).startswith(f"deep.hemls:2:{column}: brackets nest deeper than {MAX_NESTING} "
                                      "levels")
    assert "\n" not in str(info.value)


def test_the_deepest_nesting_allowed_reads_alike_and_grows_from_a_deep_stack():
    from genr8_dist.hemls.language import MAX_NESTING

    def deep(frames: int):   # a caller that has used a good part of the stack already (a Ray worker)
        if frames:
            return deep(frames - 1)
        direct, lark = parse(_nested(MAX_NESTING)), parse(_nested(MAX_NESTING, comment=True))
        return direct, lark, str(direct), direct.segment_names()

    direct, lark, text, names = deep(300)
    assert direct.rules == lark.rules
    assert text.count("[") == MAX_NESTING and names == ("Edge1",)


def test_brackets_inside_comments_do_not_count():
    text = "Edge1 + Edge1 + Edge1 // " + "[" * 500 + "\nEdge1 -> Edge1 [ + Edge1 ]\n"
    assert parse(text).rules[0].successors[0].symbols[1].symbols == ("+", parse(text).rules[0].predecessor)
