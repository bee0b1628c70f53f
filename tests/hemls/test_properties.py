"""Property tests over random rewrite systems: they print back, grow into valid maps within the caps,
and regrow bit for bit."""

from __future__ import annotations

from hypothesis import given, settings
from hypothesis import strategies as st

from genr8_dist.environment import Environment
from genr8_dist.hemls import grow, parse

OPS = ["+", "-", "&", "^", "/", "\\", "~"]


@st.composite
def segments(draw, n_labels: int, timed: bool = False) -> str:
    name = f"Edge{draw(st.integers(0, n_labels - 1))}"
    if timed and draw(st.booleans()):
        return name + draw(st.sampled_from(["_i", "_i+1", "_i-1"]))
    return name


@st.composite
def successors(draw, n_labels: int, depth: int = 0, timed: bool = False) -> str:
    parts: list[str] = []
    for _ in range(draw(st.integers(0, 4))):
        kind = draw(st.sampled_from(["op", "seg", "branch", "pair"] if depth < 2 else ["op", "seg"]))
        if kind == "op":
            parts.append(draw(st.sampled_from(OPS)))
        elif kind == "seg":
            parts.append(draw(segments(n_labels, timed)))
        elif kind == "branch":
            ops = draw(st.lists(st.sampled_from(OPS), max_size=3))
            parts.append("[ " + " ".join([*ops, draw(segments(n_labels, timed))]) + " ]")
        else:  # the universes' double bracket: [ [ + X ] - Y ]
            a, b = draw(segments(n_labels, timed)), draw(segments(n_labels, timed))
            turn = draw(st.sampled_from(["+", "+ +", "&"]))
            back = {"+": "-", "+ +": "- -", "&": "^"}[turn]
            parts.append(f"[ [ {turn} {a} ] {back} {b} ]")
    parts.append(draw(segments(n_labels, timed)))
    return " ".join(parts)


@st.composite
def rewrite_systems(draw) -> str:
    n_labels = draw(st.integers(1, 4))
    timed = draw(st.booleans())
    n_axiom = draw(st.integers(3, 6))
    axiom = []
    for _ in range(n_axiom):
        seg = draw(segments(n_labels))
        axiom.append(("~ " if draw(st.booleans()) else "") + seg)
    lines = [" + ".join(axiom)]
    for _ in range(draw(st.integers(1, 4))):
        pred = draw(segments(n_labels))
        if timed:
            pred += "_i"
        ctx = draw(st.sampled_from(["", "left", "right"]))
        if ctx == "left":
            pred = f"{draw(segments(n_labels))} < {pred}"
        elif ctx == "right":
            pred = f"{pred} > {draw(segments(n_labels))}"
        alts = [draw(successors(n_labels, timed=timed)) for _ in range(draw(st.integers(1, 2)))]
        if len(alts) > 1:
            rule = pred + "".join(f" -> {a} Weight {draw(st.integers(1, 4))}" for a in alts)
        else:
            rule = f"{pred} -> {alts[0]}"
            if timed and draw(st.booleans()):
                rule += f" If i {draw(st.sampled_from(['<', '>', '=']))} {draw(st.integers(0, 3))}"
        lines.append(rule)
    lines.append(f"Angle {draw(st.sampled_from([30, 45, 60, 90, 120]))}")
    if draw(st.booleans()):
        lines.append("Sync")
    lines.append(f"BranchAngle {draw(st.sampled_from([15, 30, 60, 90]))}")
    return "\n".join(lines) + "\n"


@st.composite
def tile_like_systems(draw) -> str:
    """Subdividing systems whose branches often meet: every rule splits its edge and sends a branch
    pair to both sides, as the tiles do, with random labels, angles and extra operators."""
    n_labels = draw(st.integers(1, 3))
    n_axiom = draw(st.integers(3, 6))
    axiom = " + ".join(("~ " if draw(st.booleans()) else "") + f"Edge{draw(st.integers(0, n_labels - 1))}"
                       for _ in range(n_axiom))
    lines = [axiom]
    for label in range(n_labels):
        seg = f"Edge{label}"
        a, b = (f"Edge{draw(st.integers(0, n_labels - 1))}" for _ in range(2))
        turn = draw(st.sampled_from(["+", "+ +", "+ &"]))
        back = {"+": "-", "+ +": "- -", "+ &": "- &"}[turn]
        middle = f"[ [ {turn} {a} ] {back} {b} ]"
        tail = draw(st.sampled_from(["", f" {seg}", f" - {seg} + {seg}", f" [ + {a} ] {seg}"]))
        lines.append(f"{seg} -> {seg} {middle} {seg}{tail}")
    lines.append(f"Angle {draw(st.sampled_from([45, 60, 72, 90]))}")
    if draw(st.booleans()):
        lines.append("Sync")
    lines.append(f"BranchAngle {draw(st.sampled_from([30, 60, 90]))}")
    return "\n".join(lines) + "\n"


# The caps this property is about: edges and time. The work cap (default 8,000 edge-steps) is off: a
# system that subdivides every step reaches it at 5 steps with 128 edges (tests/hemls/test_budget.py
# tests that cap).
CAPPED = Environment(max_edges=3000, max_seconds=5.0, max_work=0)


@given(rewrite_systems())
def test_random_systems_print_back(text):
    system = parse(text)
    assert parse(system.to_text()) == system
    assert system.to_text() == text


@settings(max_examples=40)
@given(rewrite_systems(), st.integers(1, 5), st.integers(0, 2**31))
def test_random_systems_grow_valid_maps_within_caps(text, steps, seed):
    system = parse(text)
    result = grow(system, CAPPED, steps=steps, seed=seed, keep_steps=True)
    assert result.capped in (None, "edges", "time")
    if result.capped is None:
        assert len(result.steps) == steps
    assert result.surface.n_edges <= CAPPED.max_edges
    for surface in result.history:
        assert surface.validate() == [], text
    again = grow(system, CAPPED, steps=steps, seed=seed)
    if result.capped != "time" and again.capped != "time":
        assert again.surface.digest() == result.surface.digest()


@settings(max_examples=40)
@given(tile_like_systems(), st.integers(1, 5), st.integers(0, 2**31))
def test_subdividing_systems_join_branches_into_valid_maps(text, steps, seed):
    system = parse(text)
    result = grow(system, CAPPED, steps=steps, seed=seed, keep_steps=True)
    for surface in result.history:
        assert surface.validate() == [], text
        assert surface.n_vertices - surface.n_edges + surface.n_regions == 1
