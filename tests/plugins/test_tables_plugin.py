"""The tables plugin (Hornby & Pollack, GECCO 2001): P0L-systems, the voxel turtle, the criteria."""

from __future__ import annotations

import re

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from genr8_dist.grammar import load_universe

TABLES = load_universe("tables")
DIRECT = load_universe("tables_direct")
V = TABLES.hooks.voxels

# Section 2.2: two productions, one condition-successor pair each, started with P0(4).
PAPER_22 = """P0 ( 4 ) iterations 4
P0 ( n0 ) : n0 > 1.0 -> [ P1 ( n0 * 1.5 ) ] ^ ( 1 ) f ( 3 ) v ( 1 ) P0 ( n0 - 1 )
P1 ( n0 ) : n0 > 1.0 -> { [ f ( n0 ) ] < ( 1 ) } ( 4 )
"""
# The sequence of strings the paper prints (its words for our symbols).
PAPER_22_STRINGS = [
    "P0(4)",
    "[P1(6)] up(1) forward(3) down(1) P0(3)",
    "[{ [forward(6)] left(1) } (4)] up(1) forward(3) down(1) [P1(4.5)] up(1) forward(3) down(1) P0(2)",
    "[{ [forward(6)] left(1) } (4)] up(1) forward(3) down(1) [{ [forward(4.5)] left(1) } (4)] up(1) "
    "forward(3) down(1) [P1(3)] up(1) forward(3) down(1) P0(1)",
    "[{ [forward(6)] left(1) } (4)] up(1) forward(3) down(1) [{ [forward(4.5)] left(1) } (4)] up(1) "
    "forward(3) down(1) [{ [forward(3)] left(1) } (4)] up(1) forward(3) down(1)",
]


def _squash(text: str) -> str:
    return re.sub(r"\s+", "", text)


def test_the_papers_two_production_example_derives_the_papers_strings():
    system = V.parse(PAPER_22)
    for steps, want in enumerate(PAPER_22_STRINGS):
        word = V.derive(V.System(system.axiom, steps, system.productions))[0]
        assert _squash(V.command_string(word)) == _squash(want)


def test_the_papers_tree_has_the_voxels_and_criteria_counted_by_hand():
    table = V.develop(PAPER_22)
    # ground cross 1 + 4 x 6, trunk 9 (y 1..9), crosses of 4 x 4 (y 3) and 4 x 3 (y 6) around it
    assert table.n_voxels == 25 + 9 + 16 + 12 == 62
    assert (table.steps, table.capped) == (4, None)
    raw = V.criteria(table.voxels)
    # hull areas: 13 x 13 square less four 6 x 6 / 2 corners = 97; 9 x 9 less 4 x 8 = 49;
    # 7 x 7 less 4 x 4.5 = 31; six trunk-only layers of 1
    assert raw == {"height": 9.0, "surface": 1.0, "stability": 97 + 49 + 31 + 6, "excess": 61.0,
                   "voxels": 62.0}
    assert V.fitness(raw) == pytest.approx(9 * 1 * 183 / 61)


# A hand-built table: four legs 3 high at the corners of a 5 x 5 square, and a full 5 x 5 top.
LEG = "^ ( 1 ) f ( 3 ) v ( 1 )"
HAND_TABLE = (f"f ( 4 ) [ {LEG} ] < ( 1 ) f ( 4 ) [ {LEG} ] < ( 1 ) f ( 4 ) [ {LEG} ] < ( 1 ) f ( 4 ) "
              f"{LEG} < ( 1 ) f ( 4 ) < ( 1 ) f ( 4 ) < ( 1 ) f ( 4 ) < ( 1 ) "
              "f ( 1 ) < ( 1 ) f ( 3 ) > ( 1 ) f ( 1 ) > ( 1 ) f ( 3 ) < ( 1 ) f ( 1 ) < ( 1 ) f ( 3 )")


def test_a_hand_built_table_scores_as_counted():
    table = V.develop(HAND_TABLE + "\n")
    voxels = table.voxels
    ys = np.argwhere(voxels)[:, 1]
    assert V.is_connected(voxels)
    # layer 0: the 5 x 5 square's rim (16 cells); legs y 1..2 at 4 corners; top y 3: 5 x 5 = 25
    assert [int((ys == y).sum()) for y in range(4)] == [16, 4, 4, 25]
    raw = V.criteria(voxels)
    assert raw == {"height": 3.0, "surface": 25.0, "stability": 25.0 + 25.0 + 25.0, "excess": 24.0,
                   "voxels": 49.0}
    assert V.fitness(raw) == pytest.approx(3 * 25 * 75 / 24)


@pytest.mark.parametrize("cells, area", [
    ([], 0.0),
    ([(3, 3)], 1.0),
    ([(0, 0), (1, 0), (2, 0)], 3.0),
    ([(0, 0), (1, 0), (0, 1)], 3.5),          # an L: the 2 x 2 square less half a cell
    ([(0, 0), (4, 4)], 25 - 2 * 8),             # opposite corners of a 5 x 5 square
])
def test_convex_hull_area_of_unit_cells(cells, area):
    assert V.hull_area(np.asarray(cells, dtype=np.int64).reshape(-1, 2)) == pytest.approx(area)


def test_flat_structures_and_a_single_voxel_score_zero():
    assert V.fitness(V.criteria(V.develop("f ( 5 ) < ( 1 ) f ( 5 )\n").voxels)) == 0.0
    single = V.develop("< ( 2 )\n")
    assert single.n_voxels == 1
    assert V.criteria(single.voxels)["excess"] == 0.0


def test_moves_stop_at_the_grid_and_commands_are_capped():
    wall = V.develop("f ( 5 ) f ( 5 ) f ( 5 ) f ( 5 ) f ( 5 )\n")   # from x = 20 the grid ends at 39
    assert wall.n_voxels == 20
    system = "P0 ( 1 , 1 ) iterations 1\nP0 ( n0 , n1 ) : n0 > 0 -> { f ( 1 ) < ( 1 ) } ( 100000 )\n"
    capped = V.develop(system)
    assert (capped.commands, capped.capped) == (V.MAX_COMMANDS, "commands")
    growing = "P0 ( 1 , 1 ) iterations 30\nP0 ( n0 , n1 ) : n0 > 0 -> P0 ( n0 , n1 ) P0 ( n0 , n1 ) f ( 1 )\n"
    table = V.develop(growing)
    assert table.capped == "modules" and table.steps < 30 and table.modules <= V.MAX_MODULES


def test_replicating_blocks_without_commands_costs_nothing():
    text = ("P0 ( 1 , 1 ) iterations 2\n"
            "P0 ( n0 , n1 ) : n0 > 0 -> f ( 1 ) { { P1 ( n0 , n1 ) } ( 1000000 ) [ ] } ( 1000000 )\n")
    table = V.develop(text)
    assert (table.commands, table.n_voxels, table.capped) == (1, 2, None)


def test_arithmetic_never_fails_a_derivation():
    text = ("P0 ( 1 , 0 ) iterations 12\n"
            "P0 ( n0 , n1 ) : n0 > -10 -> f ( 1 ) P0 ( n0 * 9 , n0 / n1 ) { f ( n1 ) } ( n0 / 0 )\n")
    table = V.develop(text)
    assert table.steps == 12 and V.is_connected(table.voxels)


@pytest.mark.parametrize("text, words", [
    ("", "the text is empty"),
    ("f ( 1 ) { f ( 1 ) } ( 2 )\n", "line 1, column 9: expected a build command"),
    ("P0 ( 1 ) iterations 3\nP0 ( n0 ) : n2 > 1 -> f ( 1 )\n", "line 2, column 13: expected a condition"),
    ("P0 ( 1 ) iterations 3\nP0 ( n0 ) : n0 > 1 -> f ( 1\n", "line 2: expected ')' at the end"),
    ("P0 ( 1 ) iterations 3\nP0 ( n0 ) : n0 > 1 -> f ( 1 )\nP0 ( n0 ) : n0 > 2 -> f ( 1 )\n",
     "line 3: production P0 is defined twice"),
    ("P0 ( 1 ) iterations 99\n", "iterations must be an integer from 0 to 30"),
    ("f ( 1 ) ? f ( 1 )\n", "line 1, column 9: unexpected character '?'"),
])
def test_bad_texts_are_one_line_errors_with_where(text, words):
    with pytest.raises(V.TablesError) as info:
        V.parse(text)
    assert words in str(info.value) and "\n" not in str(info.value)


@settings(max_examples=25, deadline=None)
@given(st.lists(st.integers(0, 255), min_size=20, max_size=300), st.sampled_from(["tables", "tables_direct"]))
def test_evolved_texts_round_trip_and_the_turtle_never_places_a_disconnected_voxel(genome, name):
    universe = TABLES if name == "tables" else DIRECT
    mapped = universe.map(genome, max_depth=5)
    if not mapped.valid:
        return
    assert universe.map(universe.invert(mapped.text, max_depth=5), max_depth=5).text == mapped.text
    table = V.develop(mapped.text)
    assert V.is_connected(table.voxels)
    assert table.voxels[V.START]


@settings(max_examples=40, deadline=None)
@given(st.lists(st.tuples(st.sampled_from([*V.COMMANDS, "[", "]"]), st.integers(-7, 45)),
                min_size=1, max_size=60))
def test_any_command_string_builds_one_connected_structure(commands):
    depth, parts = 0, ["f ( 1 )"]
    for symbol, n in commands:
        if symbol == "[":
            depth += 1
            parts.append("[")
        elif symbol == "]":
            if depth:
                depth -= 1
                parts.append("]")
        else:
            parts.append(f"{symbol} ( {n} )")
    table = V.develop(" ".join(parts + ["]"] * depth) + "\n")
    assert V.is_connected(table.voxels)


def _reference_turtle(word) -> tuple[np.ndarray, int]:
    """Table 1 read plainly: a frame of three world vectors turned a quarter at a time, a move
    one cell at a time that stops at the grid's edge, push/pop of position and frame; at most
    ``MAX_COMMANDS`` commands run. The filled cells and the commands run."""
    grid = np.zeros((V.GRID,) * 3, dtype=bool)
    grid[V.START] = True
    left = [V.MAX_COMMANDS]
    about = {"^": (0, 1), "v": (0, 1), "<": (0, 2), ">": (0, 2), "/": (1, 2), "\\": (1, 2)}

    def run(items, pos, frame):
        for item in items:
            if left[0] <= 0:
                break
            if item[0] == "[":
                run(item[1], list(pos), [list(v) for v in frame])
            elif item[0] == "{":
                for _ in range(max(0, int(item[1]))):
                    pos, frame = run(item[2], pos, frame)
            elif item[1] in "fb":
                left[0] -= 1
                n, sign = int(item[2]), 1 if item[1] == "f" else -1
                sign, n = (-sign, -n) if n < 0 else (sign, n)
                for _ in range(n):
                    nxt = [p + sign * d for p, d in zip(pos, frame[0], strict=True)]
                    if not all(0 <= c < V.GRID for c in nxt):
                        break
                    pos = nxt
                    grid[tuple(pos)] = True
            else:
                left[0] -= 1
                a, b = about[item[1]]
                turns = int(item[2]) % 4 if item[1] in "^</" else (-int(item[2])) % 4
                for _ in range(turns):
                    frame[a], frame[b] = frame[b], [-c for c in frame[a]]
        return pos, frame

    run(word, list(V.START), [[1, 0, 0], [0, 1, 0], [0, 0, 1]])
    return grid, V.MAX_COMMANDS - left[0]


def _hull_of_each_layer(voxels: np.ndarray) -> float:
    layers = np.flatnonzero(voxels.sum(axis=(0, 2)))
    total = 0.0
    for y in layers[:-1]:
        xs, zs = np.nonzero(voxels[:, y, :])
        total += V.hull_area(np.column_stack([xs, zs]))
    return total


def _nested(commands, repeats, last: int) -> str:
    """A successor of ``commands``: ``[`` and ``{`` open, ``]`` closes what is open (a bracket with
    ``]``, a block with ``} ( repeats(n) )``), what is left open closed at the end (blocks repeated
    ``last`` times); a ``("raw", text)`` pair is put in as it is."""
    opened, parts = [], []
    for symbol, n in commands:
        if symbol == "raw":
            parts.append(n)
        elif symbol in "[{":
            opened.append(symbol)
            parts.append(symbol)
        elif symbol == "]":
            if opened:
                parts.append("]" if opened.pop() == "[" else f"}} ( {repeats(n)} )")
        else:
            parts.append(f"{symbol} ( {n} )")
    parts += ["]" if symbol == "[" else f"}} ( {last} )" for symbol in reversed(opened)]
    return " ".join(parts)


@settings(max_examples=40, deadline=None)
@given(st.lists(st.tuples(st.sampled_from([*V.COMMANDS, "[", "]", "{"]), st.integers(-7, 45)),
                min_size=1, max_size=50))
def test_the_turtle_fills_the_cells_a_plain_reading_of_table_1_fills(commands):
    body = _nested(commands, lambda n: n % 4, 3)
    text = f"P0 ( 1 , 1 ) iterations 1\nP0 ( n0 , n1 ) : n0 > 0 -> f ( 1 ) {body}\n"
    table = V.develop(text)
    word = V.derive(V.parse(text))[0]
    assert np.array_equal(table.voxels, _reference_turtle(word)[0])
    assert V.criteria(table.voxels)["stability"] == _hull_of_each_layer(table.voxels)


@settings(max_examples=30, deadline=None)
@given(st.lists(st.tuples(st.sampled_from([*V.COMMANDS, "[", "]", "{"]), st.integers(-7, 45)),
                min_size=1, max_size=40))
def test_repeated_blocks_fill_and_count_as_run_one_by_one(commands):
    """The turtle runs a block again from a start it ran it from before at once (its memo); long
    and nested repetitions, up to the command cap, still fill and count what running every
    command one by one does."""
    body = _nested(commands, lambda n: abs(n) + 2, 40)
    text = f"P0 ( 1 , 1 ) iterations 1\nP0 ( n0 , n1 ) : n0 > 0 -> f ( 1 ) {{ {body} }} ( 30 )\n"
    table = V.develop(text)
    voxels, run = _reference_turtle(V.derive(V.parse(text))[0])
    assert np.array_equal(table.voxels, voxels)
    assert table.commands == run


def test_the_mesh_is_watertight_with_the_voxels_volume_and_the_same_bytes_each_time(tmp_path):
    import trimesh

    phenotype = TABLES.hooks.PHENOTYPE
    developed = phenotype.develop(PAPER_22, None)
    first = phenotype.export(developed, tmp_path / "a.stl", None)
    second = phenotype.export(phenotype.develop(PAPER_22, None), tmp_path / "b.stl", None)
    assert first.read_bytes() == second.read_bytes()
    mesh = trimesh.load(first)
    assert mesh.is_watertight and mesh.volume == pytest.approx(62)
    assert mesh.bounds[0][2] == 0 and mesh.bounds[1][2] == 10     # z up: ground to the top of layer 9


def test_tables_direct_shares_the_tables_phenotype():
    assert DIRECT.hooks.PHENOTYPE is TABLES.hooks.PHENOTYPE
    raw = TABLES.hooks.PHENOTYPE.measure(TABLES.hooks.PHENOTYPE.develop(PAPER_22, None), None)
    assert TABLES.hooks.PHENOTYPE.fitness(raw, None) == pytest.approx(-27.0)


TABLES_RUN = """\
universe = "tables"
seed = 3

[genome]
length = 120

[ea]
population = 4
generations = 2
"""


def test_a_tables_run_stores_its_phenotypes_criteria_and_sizes_under_generic_names(tmp_path):
    """A run of the tables universe is created with its phenotype's criteria and sizes (nobody passes
    them), stores them as crit_/size_ columns beside phenotype_digest, and the history commands read,
    regrow, export and draw it through the phenotype interface."""
    import trimesh

    from genr8_dist import history
    from genr8_dist.config import RunConfig
    from genr8_dist.evolution.evaluate import evaluate_text
    from genr8_dist.evolution.individual import Individual
    from genr8_dist.store import SCHEMA_VERSION, RunStore

    config = RunConfig.from_toml(TABLES_RUN)
    store = RunStore.create(tmp_path / "run", config.to_toml())
    assert store.schema_version == SCHEMA_VERSION == 3
    assert store.criteria == ("height", "surface", "stability", "excess", "voxels")
    assert store.sizes == ("commands", "modules")
    names = store.schema.names
    assert {"phenotype_digest", "size_commands", "size_modules", "crit_height"} <= set(names)
    assert not {n for n in names if n.startswith("n_") or n.startswith("surface")}
    evaluation = evaluate_text(PAPER_22, config)
    table = V.develop(PAPER_22)
    assert evaluation.valid and evaluation.fitness == pytest.approx(-27.0)
    assert evaluation.sizes == {"commands": table.commands, "modules": table.modules}
    assert evaluation.phenotype_digest == table.digest()
    store.commit([Individual(0, 0, 0, (1, 2, 3), "injected", **evaluation.as_fields())])
    assert store.load_generation(0, 0)[0].evaluation() == evaluation
    best = history.top(store, 1)
    assert best["size_commands"].to_pylist() == [table.commands]
    assert best["phenotype_digest"].to_pylist() == [table.digest()]
    assert history.query(store, "select size_modules from individuals")["size_modules"].to_pylist() == [
        table.modules]
    regrown = history.regrow(store, "0-0-0")
    assert regrown.digest == table.digest() and regrown.phenotype is TABLES.hooks.PHENOTYPE
    assert history.export_formats(regrown.phenotype) == ("obj", "ply", "stl", "glb")
    mesh = trimesh.load(history.export(regrown, tmp_path / "t.stl"))
    assert mesh.is_watertight and mesh.volume == pytest.approx(62)
    assert history.picture(regrown, tmp_path / "t.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    import matplotlib.pyplot as plt

    fig, info = history.pictures.gallery_figure_of(store, k=1)
    assert info == "1 tables of generation 0" and len(fig.axes[0].collections) > 0   # drawn voxels
    plt.close(fig)
    fig, info = history.pictures.clusters_figure_of(store, k=1)   # no looks: told apart by the numbers
    assert info == "1 clusters of the whole run"
    assert "(told apart by criteria and sizes;" in fig.texts[0].get_text()
    plt.close(fig)
    with pytest.raises(history.HistoryError, match=r"use one of \.obj, \.ply, \.stl, \.glb"):
        history.export(regrown, tmp_path / "t.3dm")


def test_an_offspring_that_rewrites_to_its_parents_word_is_not_developed(monkeypatch):
    """The tables phenotype knows a copy before building it: a text that rewrites to the word a
    parent's rewrites to builds the parent's table. An island varies such offspring again without
    developing them, so its rows are the ones it builds when it develops them, with fewer
    evaluations (the paper's mutations often change a production the derivation never reaches)."""
    from collections import OrderedDict

    from genr8_dist.config import RunConfig
    from genr8_dist.evolution import Island, evaluate

    phenotype = TABLES.hooks.PHENOTYPE
    unread = PAPER_22 + "P2 ( n0 ) : n0 > 1.0 -> f ( 5 )\n"          # a production nothing calls
    read = PAPER_22.replace("f ( n0 )", "f ( n0 + 1 )")                # the legs one longer
    assert phenotype.copies(unread, PAPER_22, None, None)
    assert V.develop(unread).digest() == V.develop(PAPER_22).digest()
    assert not phenotype.copies(read, PAPER_22, None, None)
    config = RunConfig.from_toml(TABLES_RUN).replace(ea={"population": 12, "generations": 6})

    def rows(island: Island) -> list[tuple]:
        return [(i.genome, i.text, repr(i.fitness), i.phenotype_digest, i.origin, i.parents)
                for gen in island.run() for i in gen]

    monkeypatch.setattr(evaluate, "_DEVELOPED", OrderedDict())
    knowing = Island(config, 0)
    known = rows(knowing)
    monkeypatch.setattr(Island, "_copy", lambda self, kin, genome: None)
    monkeypatch.setattr(evaluate, "_DEVELOPED", OrderedDict())
    building = Island(config, 0)
    assert rows(building) == known
    assert knowing.evaluator.evaluations < building.evaluator.evaluations


# Changes that fill no other cell: a turn by whole turns, a move split in two one way, a block
# run once, a bracket that only turns, a block that only turns by whole turns, one never run, and
# a turn before the word ends.
_NEUTRAL = (
    lambda part: f"{part} ^ ( 4 )",
    lambda part: f"< ( 0 ) {part}",
    lambda part: f"{{ {part} }} ( 1 )",
    lambda part: f"[ v ( 1 ) / ( 3 ) ] {part}",
    lambda part: f"{part} {{ > ( 3 ) }} ( 4 )",
    lambda part: f"{{ f ( 9 ) }} ( 0 ) {part}",
)


@settings(max_examples=60, deadline=None)
@given(st.lists(st.tuples(st.sampled_from([*V.COMMANDS, "[", "]", "{"]), st.integers(-7, 45)),
                min_size=1, max_size=40),
       st.lists(st.integers(0, len(_NEUTRAL) + 1), min_size=40, max_size=40))
def test_a_text_changed_where_no_cell_changes_is_known_to_copy_and_builds_the_same_table(commands, changes):
    """``copies`` sees through what fills no cell (``voxels.same_cells_form``): each text below,
    changed by ``_NEUTRAL`` or by splitting its moves, is known to copy the text it was changed
    from, and both build the same table (and a plain reading of table 1 agrees)."""
    phenotype = TABLES.hooks.PHENOTYPE
    changed = []
    for (symbol, n), change in zip(commands, changes, strict=False):
        if symbol not in "[]{" and change < len(_NEUTRAL):
            changed.append(("raw", _NEUTRAL[change](f"{symbol} ( {n} )")))
        elif symbol == "f" and n >= 2 and change == len(_NEUTRAL):
            changed += [("f", 1), ("f", n - 1)]
        else:
            changed.append((symbol, n))

    def text(items) -> str:
        body = _nested(items, lambda n: n % 4, 3)
        return f"P0 ( 1 , 1 ) iterations 1\nP0 ( n0 , n1 ) : n0 > 0 -> f ( 1 ) {body} / ( 1 )\n"

    original, neutral = text(commands), text(changed)
    assert phenotype.copies(neutral, original, None, None)
    table = V.develop(neutral)
    assert np.array_equal(table.voxels, V.develop(original).voxels)
    assert np.array_equal(table.voxels, _reference_turtle(V.derive(V.parse(neutral))[0])[0])


def test_texts_known_to_copy_build_the_same_table_along_the_papers_mutations():
    """Never two tables called alike: along chains of the paper's mutations from random systems,
    every pair of texts ``copies`` calls alike builds the same table, and it calls many alike."""
    from collections import defaultdict

    phenotype, variation = TABLES.hooks.PHENOTYPE, TABLES.hooks.VARIATION
    rng = np.random.default_rng(11)
    texts = []
    for _ in range(40):
        chain = [variation.founder(rng)]
        for _ in range(15):
            chain.append(variation.mutate(rng, chain[int(rng.integers(len(chain)))]))
        texts += chain
    by_form = defaultdict(list)
    for t in texts:
        by_form[V.same_cells_form(V.derive(V.parse(t))[0])].append(t)
    alike = [group for form, group in by_form.items() if form is not None and len(group) > 1]
    assert sum(len(group) for group in alike) > len(texts) // 2
    for group in alike:
        assert all(phenotype.copies(t, group[0], None, None) for t in group)
        assert len({V.develop(t).digest() for t in group}) == 1


def test_short_command_strings_share_a_form_only_when_they_fill_the_same_cells():
    """Short strings over few commands collide often: 4,000 of them, grouped by form, each group
    one table (a form that merged a move and its way back, or dropped a turn some move follows,
    would put two tables in one group)."""
    from collections import defaultdict

    rng = np.random.default_rng(3)
    tokens = ["f", "b", "^", "<", "/", "[", "]", "{"]
    groups = defaultdict(set)
    for _ in range(4000):
        picked = [(tokens[i], int(n)) for i, n in zip(rng.integers(0, len(tokens), rng.integers(1, 7)),
                                                       rng.integers(-2, 4, 7), strict=False)]
        text = f"P0 ( 1 , 1 ) iterations 1\nP0 ( n0 , n1 ) : n0 > 0 -> f ( 1 ) {_nested(picked, abs, 2)}\n"
        form = V.same_cells_form(V.derive(V.parse(text))[0])
        groups[form].add(V.develop(text).digest())
    assert len(groups) < 2000 and all(len(tables) == 1 for tables in groups.values())
