"""The tables plugins' own genomes and operators (Hornby & Pollack, GECCO 2001, sections 2.4 to 2.6):
random systems and strings of the paper's sizes, structural mutation and recombination, the paper's
ranges reachable, every text one ``voxels.parse`` reads and ``variation.write`` writes back."""

from __future__ import annotations

import numpy as np
import pytest

from genr8_dist.grammar import load_universe

HOOKS = load_universe("tables").hooks
V, VAR = HOOKS.voxels, HOOKS.variation


def _commands(items) -> int:
    """Build commands and calls in ``items`` (brackets' and blocks' bodies included, once each)."""
    n = 0
    for item in items:
        if item[0] == "[":
            n += _commands(item[1])
        elif item[0] == "{":
            n += _commands(item[2])
        else:
            n += 1
    return n


def _kinds(items) -> set[str]:
    out = set()
    for item in items:
        out.add(item[0])
        if item[0] == "[":
            out |= _kinds(item[1])
        elif item[0] == "{":
            out |= _kinds(item[2])
    return out


def test_generative_founders_are_the_papers_random_systems():
    rng = np.random.default_rng(1)
    for _ in range(30):
        text = VAR.GENERATIVE.founder(rng)
        system = V.parse(text)
        assert VAR.write(system) == text
        assert list(system.productions) == [f"P{k}" for k in range(20)]
        assert 1 <= system.iterations <= 2 and system.axiom[0][1] == "P0"
        assert all(1 <= v <= 10 for v in system.axiom[0][2])
        for production in system.productions.values():
            assert production.params == ("n0", "n1") and 1 <= len(production.pairs) <= 3
            for _, limit, items in production.pairs:
                assert 3 <= _commands(items) <= 8     # 3 to 8 build commands per successor
                assert -5 <= limit <= 10


def test_direct_founders_are_4_to_104_commands_without_replication_or_calls():
    rng = np.random.default_rng(2)
    sizes = []
    for _ in range(200):
        text = VAR.DIRECT.founder(rng)
        system = V.parse(text)
        assert not system.productions and VAR.write(system) == text
        assert _kinds(system.axiom) <= {"c", "["}
        sizes.append(_commands(system.axiom))
    assert min(sizes) >= 4 and max(sizes) <= 104 and max(sizes) - min(sizes) > 60


def test_operators_draw_only_from_their_generator():
    def texts(seed: int) -> list[str]:
        rng = np.random.default_rng(seed)
        out = []
        for variation in (VAR.GENERATIVE, VAR.DIRECT):
            a, b = variation.founder(rng), variation.founder(rng)
            out += [a, b, variation.mutate(rng, a), variation.recombine(rng, a, b)]
        return out

    assert texts(5) == texts(5) and texts(5) != texts(6)


def test_a_mutation_changes_one_production_or_the_axiom_and_children_read_back():
    rng = np.random.default_rng(3)
    parent = VAR.GENERATIVE.founder(rng)
    before = V.parse(parent)
    changed = 0
    for _ in range(60):
        child = VAR.GENERATIVE.mutate(rng, parent)
        after = V.parse(child)
        assert VAR.write(after) == child
        V.develop(child)
        differ = [n for n in sorted(set(before.productions) | set(after.productions))
                  if before.productions.get(n) != after.productions.get(n)]
        axiom = (before.axiom, before.iterations) != (after.axiom, after.iterations)
        # one production edited, or one encapsulated into a production not used before (two)
        assert len(differ) + axiom <= 2
        changed += bool(differ) or axiom
    assert changed >= 50


def test_encapsulation_moves_a_block_into_an_unused_production_with_the_same_conditions():
    rng = np.random.default_rng(4)
    text = "P0(4,10) iterations 3\nP0(n0,n1): n0>5 -> f(1) b(2) ^(1) | n1>2 -> [f(3)]\n"
    rules = VAR._Rules(V.parse(text))
    pairs = rules.productions["P0"]
    assert VAR.GENERATIVE._encapsulate(rng, rules, "P0", pairs)
    new = [n for n in rules.used() if n != "P0"]
    assert len(new) == 1
    assert [(i, limit) for i, limit, _ in rules.productions[new[0]]] == [(0, 5.0), (1, 2.0)]
    assert f"{new[0]}(n0,n1)" in rules.text()
    # the same commands run: the call expands to the block it took
    assert V.develop(rules.text()).commands >= 1


def test_recombination_copies_the_first_parent_with_a_part_of_the_second():
    rng = np.random.default_rng(5)
    a = "P0(4,10) iterations 2\nP0(n0,n1): n0>1 -> f(1) f(1) f(1) f(1)\n"
    b = "P0(4,10) iterations 2\nP0(n0,n1): n1>3 -> b(5) ^(5) b(5)\n"
    children = {VAR.GENERATIVE.recombine(rng, a, b) for _ in range(40)}
    assert len(children) > 3
    for child in children:
        ((_, _, items),) = V.parse(child).productions["P0"].pairs
        symbols = [it[1] for it in items if it[0] == "c"]
        assert set(symbols) <= {"f", "b", "^"} and {"b", "^"} & set(symbols)
    assert "P0(4,10) iterations 2\nP0(n0,n1): n1>3 -> b(5) ^(5) b(5)\n" in children  # a whole pair


def test_the_papers_ranges_are_reachable_and_kept():
    """Table 4.d: 17 derivation steps, limits 22 and -10, axiom P0(4, 10): a text of those reads, and
    mutation reaches such steps and limits from a founder (within MAX_LIMIT and MAX_ITERATIONS)."""
    paper = ("P0(4,10) iterations 17\nP0(n0,n1): n1>3 -> P11(n0-4,n0-2) v(1) {P16(n1-3,n1-2)}(4)\n"
             "P11(n0,n1): n1>-10 -> >(1)\nP16(n0,n1): n1>22 -> | n1>5 -> | n1>0 -> [b(1) f(3)] /(2)\n")
    assert VAR.write(V.parse(paper)) == paper
    rng = np.random.default_rng(6)
    rules = VAR._Rules(V.parse(VAR.GENERATIVE.founder(rng)))
    steps, limits = set(), set()
    for _ in range(2000):   # the axiom's mutation and the condition's, as mutate() draws them
        VAR.Generative._mutate_axiom(rng, rules)
        VAR.GENERATIVE._condition(rng, rules, "P0", rules.productions["P0"])
        steps.add(rules.iterations)
        limits |= {limit for _, limit, _ in rules.productions["P0"]}
    assert max(steps) >= 17 and max(limits) >= 22 and min(limits) <= -10
    assert max(steps) <= V.MAX_ITERATIONS and max(map(abs, limits)) <= VAR.MAX_LIMIT
    assert VAR.write(V.parse(rules.text())) == rules.text()


def test_a_direct_string_never_passes_20000_commands():
    rng = np.random.default_rng(7)
    long = VAR.write_items(tuple(("c", "f", 1.0) for _ in range(19_999))) + "\n"
    for _ in range(5):
        child = VAR.DIRECT.recombine(rng, long, long)
        assert _commands(V.parse(child).axiom) <= 20_000
        long = child
    assert _commands(V.parse(long).axiom) >= 19_990


def test_the_top_layers_filled_share():
    solid = np.zeros((V.GRID,) * 3, dtype=bool)
    solid[10:15, 0:3, 10:15] = True
    assert V.top_filled_share(solid) == 1.0
    lattice = np.zeros_like(solid)
    lattice[10, 0:3, 10] = True
    lattice[0:40:4, 3, 0:40] = True        # ten bars across a 37 x 40 hull
    assert V.top_filled_share(lattice) == pytest.approx(400 / (37 * 40))
    assert V.top_filled_share(np.zeros_like(solid)) == 0.0


def test_the_operators_read_section_2_2s_one_parameter_example_as_the_same_table():
    example = ("P0(4) iterations 4\nP0(n0): n0>1.0 -> [P1(n0*1.5)] ^(1) f(3) v(1) P0(n0-1)\n"
               "P1(n0): n0>1.0 -> {[f(n0)] <(1)}(4)\n")
    two = VAR._Rules(V.parse(example)).text()
    assert two.startswith("P0(4,0) iterations 4\nP0(n0,n1): n0>1 -> [P1(n0*1.5,0)]")
    assert V.develop(two).digest() == V.develop(example).digest()
    rng = np.random.default_rng(8)
    for _ in range(40):   # every child reads and develops
        V.develop(VAR.GENERATIVE.recombine(rng, VAR.GENERATIVE.mutate(rng, example), example))
