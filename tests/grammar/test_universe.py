"""Properties of every built-in universe over random genomes (hypothesis).

The compiled mapper is checked against a plain recursive interpreter of the same tables written
straight from DESIGN.md's rules, which also measures the derivation's depth.
"""

from __future__ import annotations

import re

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from genr8_dist.grammar import load_universe
from genr8_dist.grammar.hooks import RepairContext, hemls_repair, rule_predecessors
from genr8_dist.grammar.mapper import eligible

BUILT_INS = ["default", "reversible", "symmetric", "symmetric_thesis", "probabilistic", "gecco"]
genomes = st.lists(st.integers(0, 65535), min_size=1, max_size=300)


class Exhausted(Exception):
    pass


class Reference:
    """A slow, obvious GE mapper over a compiled grammar (no code generation, no inlining)."""

    def __init__(self, universe, genome, max_depth=5, max_wraps=2):
        self.u = universe
        self.cg = universe.grammar
        self.g = list(genome)
        self.limit = len(self.g) * (max_wraps + 1)
        self.i = 0
        self.maxd = max_depth
        self.count = 2
        self.deepest = 0
        self.has: set[int] = set()
        self.birth = True

    def codon(self):
        if self.i >= self.limit:
            raise Exhausted
        value = self.g[self.i % len(self.g)]
        self.i += 1
        return value

    def label(self, template, value):
        return self.cg.templates[template].text(value)

    def fits(self, node, d):
        need = self.cg.alt_need(node)  # a body that opens no rule fits even past max_depth
        return need == 0 or d + need <= self.maxd

    def rule(self, name, d, out):
        self.deepest = max(self.deepest, d)
        alts = self.cg.rules[name]
        e = eligible(self.cg, alts, d, self.maxd)
        self.node(alts[e[self.codon() % len(e)]], d, out, {})

    def node(self, node, d, out, scope):
        kind = node[0]
        if kind == "lit":
            out.append(node[1])
        elif kind == "edge":
            _, mode, template, letter = node
            if mode == "B" and letter in scope:
                out.append(self.label(template, scope[letter]))
                return
            if mode in ("P", "C") or not self.birth:
                lab = self.codon() % self.count
                if mode == "P" and self.birth:
                    self.has.add(lab)
            else:
                lab = self.codon() % (self.count + 1)
                if lab == self.count:
                    self.count += 1
            if mode == "B":
                scope[letter] = lab
            out.append(self.label(template, lab))
        elif kind == "rule":
            self.rule(node[1], d + 1, out)
        elif kind == "seq":
            for child in node[1]:
                self.node(child, d, out, scope)
        elif kind == "choice":
            e = eligible(self.cg, node[1], d, self.maxd)
            self.node(node[1][e[self.codon() % len(e)]], d, out, scope)
        elif kind == "opt":
            if self.codon() % 2 == 1 and self.fits(node[1], d):
                self.node(node[1], d, out, scope)
        elif kind == "rep":
            body, x, plus = node[1], node[2], node[3]
            if plus:
                self.node(body, d, out, scope)
            c = 0
            while self.codon() % (c + x) > c and self.fits(body, d):
                self.node(body, d, out, scope)
                c += 1

    def run(self):
        out: list[str] = []
        try:
            self.rule("start", 1, out)
            text = " ".join(out).replace(" \n ", "\n").replace(" \n", "\n")
            if self.cg.repair_rule:
                text = self.repair(text, out)
        except Exhausted:
            return None, self.limit
        return text, self.i

    def repair(self, text, out):
        self.birth = False
        occurring = {lab for tok in out if (lab := self.u.label_of(tok)) is not None}

        def expand():
            tokens: list[str] = []
            self.rule(self.cg.repair_rule, self.cg.repair_depth, tokens)
            return tokens

        ctx = RepairContext(text=text, expand=expand, occurring=occurring, has_rule=set(self.has),
                            label_of=self.u.label_of, edge=lambda k: f"Edge{k}", count=self.count,
                            labels_in=lambda toks: {x for t in toks if (x := self.u.label_of(t)) is not None})
        hemls_repair(ctx)
        return ctx.text


@pytest.mark.parametrize("name", BUILT_INS)
@given(genome=genomes, max_depth=st.integers(3, 7))
def test_mapper_matches_reference_and_respects_max_depth(name, genome, max_depth):
    u = load_universe(name)
    result = u.map(genome, max_depth=max_depth)
    assert u.map(genome, max_depth=max_depth) == result  # deterministic
    ref = Reference(u, genome, max_depth)
    text, used = ref.run()
    assert result.text == text
    assert result.valid == (text is not None)
    assert result.codons_used == used
    # No genome is invalid because of depth: max_depth bounds the tree whenever the universe's
    # shallowest derivation fits (reversible and symmetric need 4 levels).
    assert ref.deepest <= max(max_depth, u.grammar.min_depth["start"])
    if not result.valid:
        assert "genome exhausted" in result.reason


@pytest.mark.parametrize("name", BUILT_INS)
@settings(max_examples=25)
@given(genome=genomes)
def test_every_label_has_a_rule_and_the_text_parses(name, genome):
    u = load_universe(name)
    result = u.map(genome)
    if not result.valid:
        return
    text = result.text
    lines = text.splitlines()
    assert text.endswith("\n") and all(line == " ".join(line.split()) for line in lines)
    labels = {u.label_of(w) for w in text.split()} - {None}
    assert labels <= rule_predecessors(text, u.label_of)
    # Labels appear in birth order: the first new label in reading order is 2, then 3, ...
    born = [lab for w in text.split() if (lab := u.label_of(w)) is not None and lab >= 2]
    firsts = list(dict.fromkeys(born))
    assert firsts == list(range(2, 2 + len(firsts)))
    u.parser().parse(text)  # the universe's own grammar reads what it wrote
    assert lines[-1].startswith("BranchAngle ")


@given(genome=genomes)
def test_symmetric_axioms_have_a_mirror_symmetry(genome):
    u = load_universe("symmetric")
    result = u.map(genome)
    if not result.valid:
        return
    axiom = [u.label_of(w) for w in result.text.splitlines()[0].split() if w != "+"]
    n = len(axiom)
    assert n in (4, 6, 8)
    assert any(all(axiom[i] == axiom[(k - i) % n] for i in range(n)) for k in range(n))


def test_genomes_of_every_kind_terminate():
    u = load_universe("default")
    # All zeros, all ones, huge codons, a single codon: each maps or is invalid with a reason.
    for genome in ([0] * 10, [1] * 10, [2**62] * 50, [7], list(range(1000))):
        result = u.map(genome)
        assert result.valid or result.reason


GECCO_AS_RULES = """successor: item* segment

item: segment
    | "+" | "-" | "&" | "^" | "\\\\" | "/" | "~"
    | "[" successor "]"

segment: EDGE | EDGE_I | EDGE_INEXT | EDGE_IPREV
"""


def test_gecco_derives_turned_branches_at_the_default_max_depth(tmp_path):
    """gecco's successor items and segments are inline groups: a branch holding a turn fits
    max_depth 5. Written as rules (successor -> item -> [ successor ] -> segment) it needed 6, so no
    branch, and no subdivided surface, could be derived at the default depth. Where the depth limit
    does not bind, the groups read the genome exactly as the rules did."""
    import numpy as np

    from genr8_dist.resources import grammars_dir

    text = (grammars_dir() / "gecco.lark").read_text()
    start = text.index("successor: ((EDGE")
    end = text.index("\n\n", start)
    (tmp_path / "gecco_rules.lark").write_text(text[:start] + GECCO_AS_RULES + text[end + 2:])
    groups, rules = load_universe("gecco"), load_universe(str(tmp_path / "gecco_rules.lark"))
    rng = np.random.default_rng(5)
    branched = {"groups": 0, "rules": 0}   # texts with a branch at max_depth 5
    turned = {"groups": 0, "rules": 0}     # ... with a branch that starts with a turn
    for _ in range(200):
        genome = [int(c) for c in rng.integers(0, 256, size=80)]
        a, b = groups.map(genome, max_depth=14), rules.map(genome, max_depth=14)
        assert (a.text, a.codons_used) == (b.text, b.codons_used)
        for name, u in (("groups", groups), ("rules", rules)):
            mapped = u.map(genome, max_depth=5).text or ""
            branched[name] += "[" in mapped
            turned[name] += bool(re.search(r"\[ [+-] Edge", mapped))
    assert branched["rules"] == turned["rules"] == 0
    assert branched["groups"] >= 40 and turned["groups"] >= 4


def test_max_depth_out_of_range_is_a_value_error():
    u = load_universe("default")
    with pytest.raises(ValueError, match="max_depth"):
        u.map([1, 2, 3], max_depth=0)
    with pytest.raises(ValueError, match="max_wraps"):
        u.map([1, 2, 3], max_wraps=-1)


@pytest.mark.parametrize("name", [*BUILT_INS, "timed"])
def test_universes_pickle_and_their_texts_are_read_by_the_hemls_parser(name):
    import pickle

    from genr8_dist.hemls.language import parse
    from genr8_dist.rng import stream

    u = load_universe(name)
    copy = pickle.loads(pickle.dumps(u))
    assert (copy.name, copy.origin, copy.path) == (u.name, u.origin, u.path)
    parsed = 0
    for genome in stream(5, "test", name).integers(0, 65536, size=(40, 200)).tolist():
        result = u.map(genome)
        assert copy.map(genome) == result
        if result.valid:
            parse(result.text)
            parsed += 1
    assert parsed >= 35


SYNTHETIC = [
    # groups and options inside a recursive rule (depth known only at run time), bound edges in
    # repetitions, x+ with a rule body, a rule whose options do not fit near max_depth.
    '''start: tree (";" tree)*
tree: EDGE_X ( "(" tree ")" | "<" EDGE_X ">" | PRED ) [ "!" tree ] ("," EDGE_X)*
EDGE_X: /E[0-9]+/
PRED: /E[0-9]+/
''',
    '''//@ bias start 4
start: item+ ["end" deep]
item: EDGE | "(" item item ")" | ( "-" | "+" item )
deep: "d" deep | "z"
EDGE: /E[0-9]+/
''',
    # a bound edge first drawn inside a repetition, then reused by later rounds and after it
    '''start: ("a" EDGE_X ["!" EDGE_Z])* "b" EDGE_X [EDGE_Z] ("c" EDGE_X | "d" EDGE_Z)
EDGE_X: /X[0-9]+/
EDGE_Z: /Z[0-9]+/
''',
    '''start: a
a: b b | "x" a "y"
b: c | "q"
c: ("k" a)? EDGE_Y "m" EDGE_Y
EDGE_Y: /Y[0-9]+/
''',
]


@pytest.mark.parametrize("text", SYNTHETIC)
@given(genome=genomes, max_depth=st.integers(1, 8))
def test_compiled_mapper_matches_the_reference_on_synthetic_grammars(text, genome, max_depth):
    from pathlib import Path

    from genr8_dist.grammar.universe import Universe

    u = Universe("synthetic", "path", Path("synthetic.lark"), text + '%ignore " "\n')
    result = u.map(genome, max_depth=max_depth)
    ref = Reference(u, genome, max_depth)
    expected, used = ref.run()
    assert (result.text, result.codons_used) == (expected, used)
    assert ref.deepest <= max(max_depth, u.grammar.min_depth["start"])


@given(genome=genomes)
def test_symmetric_successors_are_mirror_palindromes(genome):
    from genr8_dist.hemls import Branch, parse

    result = load_universe("symmetric").map(genome)
    if not result.valid:
        return
    system = parse(result.text)
    assert all(r.left is None and r.right is None and not r.chain for r in system.rules)
    for rule in system.rules:
        for successor in rule.successors:
            units: list[str] = []  # '~ Edge3' is one unit: a reversed edge
            for symbol in map(str, successor.symbols):
                units.append(units.pop() + " " + symbol if units and units[-1] == "~" else symbol)
            assert units == units[::-1], str(successor)
            # a branch pair only at the middle vertex, perpendicular both ways
            branches = [str(s) for s in successor.symbols if isinstance(s, Branch)]
            assert len(branches) <= 1
            assert all(re.fullmatch(r"\[ \[ \+ \+ (Edge\d+) \] - - \1 \]", b) for b in branches)


def _mirror_share(name: str, genomes_: int, ties: str = "crossing") -> tuple[int, int]:
    from genr8_dist.environment import Environment
    from genr8_dist.hemls import grow, parse
    from genr8_dist.rng import stream

    universe = load_universe(name)
    rng = stream(0, "test", "mirror", name)
    # the work cap these figures were measured under (the default is 8000 since round 4: 386 grow)
    env = Environment(max_edges=20_000, max_work=15_000, max_seconds=10.0, branch_ties=ties)
    grown = mirrored = 0
    for _ in range(genomes_):
        result = universe.map(rng.integers(0, 2**16, size=int(rng.integers(50, 150))))
        growth = grow(parse(result.text), env) if result.valid else None
        if growth is None or growth.capped:
            continue
        grown += 1
        mirrored += growth.surface.mirror_line() is not None
    return grown, mirrored


def test_symmetric_surfaces_have_a_mirror_line_far_more_often_than_the_thesis_bnf():
    grown, mirrored = _mirror_share("symmetric", 40)
    thesis_grown, thesis_mirrored = _mirror_share("symmetric_thesis", 40)
    assert grown >= 30 and thesis_grown >= 30
    assert mirrored / grown >= 0.85    # 31 of 32
    assert mirrored / grown >= thesis_mirrored / thesis_grown + 0.5   # the thesis BNF: 10 of 35


@pytest.mark.slow
def test_95_percent_of_500_symmetric_surfaces_have_a_mirror_line_under_default_growth():
    """The issue's figure (bench/fidelity.py prints it for its own 500 genomes: 397 of 409, 97.1%):
    here 401 of the 409 surfaces that 500 random genomes grow in the empty environment have a mirror
    line (98.0%), with the default branch_ties = "crossing" (mirror-image joins settled whatever the
    drawing order; 85.4% with "first", the tie to the branch drawn first)."""
    grown, mirrored = _mirror_share("symmetric", 500)
    assert grown >= 400 and mirrored / grown >= 0.95


@pytest.mark.slow
def test_95_percent_of_500_symmetric_surfaces_have_a_mirror_line_when_tied_joins_join_neither():
    """With branch_ties = "none" (every tied join left out) 379 of the 387 surfaces grown have a
    mirror line (97.9%); they are less subdivided than with the default (bench/fidelity.py)."""
    grown, mirrored = _mirror_share("symmetric", 500, ties="none")
    assert grown >= 350 and mirrored / grown >= 0.95
