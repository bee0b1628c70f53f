"""The GE mapper's semantics on small universes, and the journal's worked example."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from genr8_dist.errors import GenomeError
from genr8_dist.grammar import MapResult, Universe, load_universe

# Journal section 5.2: a three-edge axiom followed by a repetition { + Edge } (no ~ options).
WORKED = """
start: axiom
axiom: EDGE "+" EDGE "+" EDGE ("+" EDGE)*
EDGE: /Edge[0-9]+/
%ignore " "
"""
WORKED_GENOME = [212, 187, 632, 832, 800, 517, 338, 39]


def small(text: str, name: str = "small") -> Universe:
    return Universe(name, "path", Path(f"{name}.lark"), text)


def test_journal_worked_example():
    result = small(WORKED).map(WORKED_GENOME)
    assert result == MapResult("Edge2 + Edge0 + Edge0 + Edge2", True, None, 8, 0)


def test_thesis_appendix_b_axiom_stops_at_codon_122():
    # Thesis Appendix B: same start, but 122 mod 2 = 0 stops the repetition after three edges.
    result = small(WORKED).map([212, 187, 632, 832, 800, 122])
    assert result.text == "Edge2 + Edge0 + Edge0"
    assert result.codons_used == 6


def test_a_codon_is_read_for_single_alternative_rules():
    u = small(WORKED)
    # The first two codons (start, axiom) choose nothing: any values give the same text ...
    assert u.map([0, 1, *WORKED_GENOME[2:]]).text == "Edge2 + Edge0 + Edge0 + Edge2"
    # ... but they are read: dropping one shifts every later choice.
    # 832 mod 3 = 1, 800 mod 3 = 2 (born), 517 mod 4 = 1, 338 mod 2 = 0 stops.
    assert u.map(WORKED_GENOME[1:]).text == "Edge1 + Edge2 + Edge1"


def test_repetition_stop_test_and_bias():
    u = small('//@ bias start 5\nstart: "a" ("b")* ["c"]\n%ignore " "\n')
    # c=0: 4 mod 5 = 4 > 0 go on; c=1: 8 mod 6 = 2 > 1 go on; c=2: 2 mod 7 = 2 <= 2 stop; 1 odd: "c".
    assert u.map([0, 4, 8, 2, 1]) == MapResult("a b b c", True, None, 5, 0)
    # Default bias 2: c=0: 4 mod 2 = 0 <= 0 stop at once.
    v = small('start: "a" ("b")* ["c"]\n%ignore " "\n')
    assert v.map([0, 4, 8]).text == "a"


def test_plus_emits_once_then_repeats_like_star():
    u = small('start: "a" "b"+\n%ignore " "\n')
    assert u.map([0, 0]).text == "a b"
    assert u.map([0, 1, 0]).text == "a b b"


def test_labelled_and_predecessor_edges():
    u = small('start: EDGE EDGE PRED\nEDGE: /Edge[0-9]+/\nPRED: /Edge[0-9]+/\n%ignore " "\n')
    # 2 mod 3 = 2 is born; 3 mod 4 = 3 is born; the predecessor edge never creates: 4 mod 4 = 0.
    assert u.map([0, 2, 3, 4]).text == "Edge2 Edge3 Edge0"
    assert u.map([0, 2, 3, 7]).text == "Edge2 Edge3 Edge3"


def test_bound_edges_share_a_label_within_one_expansion():
    u = small('start: pair pair\npair: EDGE_X "[" EDGE_X "]"\nEDGE_X: /Edge[0-9]+/\n%ignore " "\n')
    # start, pair, X drawn once (2 -> born), pair, X drawn again in the new expansion (1).
    result = u.map([0, 0, 2, 0, 1])
    assert result.text == "Edge2 [ Edge2 ] Edge1 [ Edge1 ]"
    assert result.codons_used == 5


def test_wrapping_is_bounded_and_reported():
    u = small('start: "a" ("b")*\n%ignore " "\n')
    # Codon 1 always continues at c=0 and stops at c=1: wraps once.
    assert u.map([0, 1]).wraps == 1
    r = u.map([1], max_wraps=0)
    assert not r.valid and r.text is None and "max_wraps=0" in r.reason
    # 2519 = lcm(2..10) - 1 goes on for c = 0..8 and stops at c = 9: 1 + 10 codons in all.
    r = u.map([2519], max_wraps=20)
    assert r.text == "a" + " b" * 9 and r.codons_used == 11 and r.wraps == 10
    # With too few wraps the genome is invalid, never an exception.
    r = u.map([2519], max_wraps=5)
    assert not r.valid and r.codons_used == 6 and r.wraps == 5


def test_max_depth_filters_alternatives():
    u = small('start: x\nx: "(" x ")" | "o"\n%ignore " "\n')
    # Every codon 0 picks the recursive alternative while it still fits.
    for depth in (2, 3, 5):
        text = u.map([0] * 50, max_depth=depth).text
        assert text.count("(") == depth - 2
    # A universe deeper than max_depth allows still maps: the shallowest alternatives are taken.
    deep = small('start: a\na: b\nb: "x"\n%ignore " "\n')
    assert deep.map([0, 0, 0], max_depth=1).text == "x"


@pytest.mark.parametrize("genome, match", [
    ([], "empty"),
    ([1, -2, 3], "codon 1 is -2"),
    ([1, 2.5], "codon 1 is 2.5"),
    (["1"], "codon 0 is '1'"),
    ("123", "got str"),
    (np.array([1.0, 2.0]), "dtype float64"),
])
def test_bad_genomes_raise_genome_error(genome, match):
    with pytest.raises(GenomeError, match=match):
        small(WORKED).map(genome)


def test_numpy_and_tuple_genomes_map_like_lists():
    u = load_universe("default")
    genome = [212, 187, 632, 832, 800, 122, 517, 338, 197, 39, 878, 185] * 10
    want = u.map(genome)
    assert u.map(tuple(genome)) == want
    assert u.map(np.array(genome, dtype=np.uint16)) == want
    assert u.map(np.array(genome, dtype=np.int64)) == want


def test_default_universe_maps_appendix_b_genome():
    genome = [212, 187, 632, 832, 800, 122, 517, 338, 197, 39, 878, 185, 954, 863, 660, 276, 909,
              321, 545, 240, 670, 231, 292, 158, 494, 999, 658, 844, 316, 710, 362, 27, 194, 144,
              171, 243, 260, 414, 337, 790, 309, 344, 456, 30, 134, 13, 774, 162, 911, 222]
    result = load_universe("default").map(genome)
    assert result.valid
    lines = result.text.splitlines()
    # The thesis' own walk-through reads no codons for the axiom's ~ options; with them, the axiom's
    # first edge is still 632 mod 3 = 2.
    assert lines[0].startswith("Edge2 + ")
    assert lines[-1].startswith("BranchAngle ")
    assert result.text.endswith("\n")
