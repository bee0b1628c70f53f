"""Rows <-> Individual: every field survives the trip through Arrow and Parquet exactly."""

from __future__ import annotations

import math

import pyarrow as pa
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from genr8_dist.errors import StoreError
from genr8_dist.evolution.individual import ORIGINS, Individual
from genr8_dist.fitness import CRITERIA
from genr8_dist.store import (
    EVENT_KINDS,
    SCHEMA_VERSION,
    TIMING_COLUMNS,
    Event,
    events_schema,
    individuals_schema,
)
from genr8_dist.store.schema import individuals_from_table, individuals_table

finite = st.floats(allow_nan=False, allow_infinity=False, width=64)
maybe_text = st.none() | st.text(max_size=40)
counts = st.integers(0, 2**31 - 1)


@st.composite
def individuals(draw: st.DrawFn) -> Individual:
    return Individual(
        island=draw(st.integers(0, 1000)),
        generation=draw(st.integers(0, 100_000)),
        index=draw(st.integers(0, 10_000)),
        genome=tuple(draw(st.lists(st.integers(0, 2**31 - 1), max_size=30))),
        origin=draw(st.sampled_from(ORIGINS)),
        parents=tuple(draw(st.lists(st.text(min_size=1, max_size=12), max_size=3))),
        text=draw(maybe_text),
        valid=draw(st.booleans()),
        stage=draw(st.none() | st.sampled_from(["map", "parse", "grow", "score"])),
        error=draw(maybe_text),
        fitness=draw(finite | st.just(math.inf)),
        criteria=draw(st.dictionaries(st.sampled_from(CRITERIA), finite | st.just(math.inf))),
        config_version=draw(st.integers(1, 50)),
        codons_used=draw(counts),
        wraps=draw(counts),
        sizes={"vertices": draw(counts), "edges": draw(counts), "regions": draw(counts)},
        steps_done=draw(counts),
        capped=draw(st.none() | st.sampled_from(["vertices", "steps", "time"])),
        phenotype_digest=draw(st.none() | st.text("0123456789abcdef", min_size=32, max_size=32)),
        eval_seconds=draw(finite),
        map_seconds=draw(finite),
        grow_seconds=draw(finite),
        score_seconds=draw(finite),
    )


@given(st.lists(individuals(), max_size=8))
def test_individuals_round_trip_through_arrow_and_parquet(inds: list[Individual]) -> None:
    table = individuals_table(inds, "r1", CRITERIA)
    sink = pa.BufferOutputStream()
    import pyarrow.parquet as pq

    pq.write_table(table, sink)
    back = individuals_from_table(pq.read_table(pa.BufferReader(sink.getvalue())))
    assert back == inds


def test_schema_has_every_column_with_its_type_and_version() -> None:
    schema = individuals_schema()
    assert schema.metadata[b"genr8.schema_version"] == str(SCHEMA_VERSION).encode()
    for name in CRITERIA:
        assert schema.field(f"crit_{name}").type == pa.float64()
        assert schema.field(f"crit_{name}").nullable
    assert schema.field("genome").type == pa.list_(pa.int32())
    assert schema.field("parents").type == pa.list_(pa.string())
    assert schema.field("fitness").type == pa.float64()
    for name in TIMING_COLUMNS:
        assert schema.field(name).type == pa.float64()
    assert schema.names[:5] == ["run_id", "id", "island", "generation", "index"]
    assert events_schema().names == ["run_id", "seq", "kind", "generation", "island", "detail", "time"]


def test_unknown_criterion_is_refused_naming_it() -> None:
    ind = Individual(0, 0, 0, (1,), "random", criteria={"beauty": 1.0})
    with pytest.raises(StoreError, match=r"0-0-0.*'beauty'"):
        individuals_table([ind], "r", CRITERIA)


def test_codon_too_large_for_int32_is_refused_naming_the_column() -> None:
    ind = Individual(0, 0, 0, (2**40,), "random")
    with pytest.raises(StoreError, match="'genome'"):
        individuals_table([ind], "r", CRITERIA)


def test_event_validation() -> None:
    assert "recovery" in EVENT_KINDS
    with pytest.raises(StoreError, match="'explosion'"):
        Event("explosion", 0)
    with pytest.raises(StoreError, match="generation"):
        Event("start", -1)
    with pytest.raises(StoreError, match="island"):
        Event("migration", 3, island=-2)
    with pytest.raises(StoreError, match="JSON"):
        Event("migration", 3, detail={"x": object()}).detail_json()
    assert Event("migration", 3, detail={"b": 1, "a": [1, 2]}).detail_json() == '{"a":[1,2],"b":1}'


def test_criterion_names_must_be_identifiers() -> None:
    with pytest.raises(StoreError, match="identifier"):
        individuals_schema(["soft boundary"])


def test_the_public_names_are_exported() -> None:
    import genr8_dist.store as store

    for name in store.__all__:
        assert getattr(store, name) is not None
    assert {"RunStore", "SCHEMA_VERSION", "individuals_schema", "events_schema", "EVENT_KINDS", "Event",
            "ConfigVersion", "write_synthetic_run"} <= set(store.__all__)


@settings(max_examples=20)  # each example creates a run on disk
@given(st.lists(individuals(), min_size=1, max_size=6))
def test_individuals_round_trip_through_a_run(tmp_path_factory: pytest.TempPathFactory,
                                              inds: list[Individual]) -> None:
    from dataclasses import replace

    from genr8_dist.store import RunStore

    # one generation of one island, indexed in order, as a commit requires
    rows = [replace(ind, island=3, generation=0, index=k) for k, ind in enumerate(inds)]
    store = RunStore.create(tmp_path_factory.mktemp("run") / "r", "[run]\n")
    store.commit(rows)
    assert RunStore.open(store.path).load_generation(3, 0) == rows
