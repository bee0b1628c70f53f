"""Criteria and stored columns are declared once: one registry entry, made here in the test alone, is
scored, stored, shown by ``genr8 top`` and documented; the built-in criteria's docs table is the
registry's."""

from __future__ import annotations

from pathlib import Path

import pytest

from genr8_dist.cli import main
from genr8_dist.config import RunConfig
from genr8_dist.evolution import Individual, evaluate_text
from genr8_dist.evolution.individual import Column, registered_column
from genr8_dist.fitness import CriterionInfo, criteria_table, registered
from genr8_dist.hemls import load_system
from genr8_dist.store import RunStore

ROOT = Path(__file__).resolve().parents[2]


def _vertex_count(surface, env) -> float:
    return float(len(surface.vertices))


VERTICES = CriterionInfo("vertex_count", _vertex_count, target=300.0, weight=0.5, heading="verts",
                         description="the number of vertices `V`")


def _top_lines(run_dir, capsys, *args: str) -> list[str]:
    capsys.readouterr()
    assert main(["top", str(run_dir), *args]) == 0
    return capsys.readouterr().out.splitlines()


def test_a_registered_criterion_is_scored_stored_shown_and_documented(tmp_path, capsys):
    text = load_system("four-sided-tiles").to_text()
    with registered(VERTICES):
        config = RunConfig()
        assert config.fitness.names[-1] == "vertex_count"
        assert config.fitness["vertex_count"].weight == 0.5
        evaluation = evaluate_text(text, config)
        assert evaluation.valid
        # scored: the raw value is the measure's, and it counts in the total with its weight
        assert evaluation.criteria["vertex_count"] == evaluation.sizes["vertices"]
        without = {k: v for k, v in evaluation.criteria.items()}
        assert evaluation.fitness == pytest.approx(config.fitness.evaluate(without))
        assert config.fitness.deviations(without)["vertex_count"] == pytest.approx(
            0.5 * abs(evaluation.sizes["vertices"] - 300.0) / 300.0)
        # stored: the run keeps a crit_vertex_count column and the value round-trips
        run_dir = tmp_path / "run"
        store = RunStore.create(run_dir, config.to_toml())
        assert store.criteria[-1] == "vertex_count"
        store.commit([Individual(0, 0, 0, (1, 2, 3), "injected", **evaluation.as_fields())])
        stored = store.individuals(["crit_vertex_count"]).column(0).to_pylist()
        assert stored == [evaluation.sizes["vertices"]]
        assert store.load_generation(0, 0)[0].criteria == evaluation.criteria
        # shown by top, under its heading, and rankable by it
        lines = _top_lines(run_dir, capsys)
        assert lines[0].split()[-4:] == ["verts", "origin", "front", "copies"]   # distinct forms
        assert lines[1].split()[-4:-1] == [str(evaluation.sizes["vertices"]), "injected", "-"]
        assert "verts" in _top_lines(run_dir, capsys, "--criterion", "vertex_count")[0].split()
        # documented: the generated docs table has its row
        assert ("| `vertex_count` | the number of vertices `V` | `300.0` | `0.5` |"
                in criteria_table().splitlines())
    # unregistered again: new configurations no longer have it, the run keeps it and still opens
    assert "vertex_count" not in RunConfig().fitness.names
    again = RunStore.open(run_dir)
    assert again.criteria[-1] == "vertex_count"
    assert again.config(1).fitness.names[-1] == "vertex_count"
    assert "vertex_count" in _top_lines(run_dir, capsys)[0].split()


def test_a_run_keeps_its_criteria_when_one_is_registered_later(tmp_path):
    store = RunStore.create(tmp_path / "run", RunConfig().to_toml())
    with registered(VERTICES):
        config = store.config(1)  # the run's own criteria, not the registry's
        assert "vertex_count" not in config.fitness.names
        evaluation = evaluate_text(load_system("four-sided-tiles").to_text(), config)
        assert set(evaluation.criteria) == set(store.criteria)
        store.commit([Individual(0, 0, 0, (1,), "injected", **evaluation.as_fields())])
    assert "crit_vertex_count" not in store.schema.names


PARETO = Column("novelty", "int32", top=18, shown=8, heading="novel")


def test_a_registered_column_is_stored_read_back_and_shown_by_top(tmp_path, capsys):
    with registered_column(PARETO):
        run_dir = tmp_path / "run"
        store = RunStore.create(run_dir, RunConfig().to_toml())
        assert store.schema.names[-1] == "novelty"
        rows = [Individual(0, 0, n, (n + 1,), "random", valid=True, fitness=float(n),
                           criteria={"size": 1.0}, extra={"novelty": 3 - n}) for n in range(3)]
        store.commit(rows)
        assert [i.extra for i in store.load_generation(0, 0)] == [{"novelty": 3 - n} for n in range(3)]
        from genr8_dist import history

        top = history.top(store, 3)
        assert top.column_names[-1] == "novelty" and top["novelty"].to_pylist() == [3, 2, 1]
        lines = _top_lines(run_dir, capsys, "--all")   # the three rows share one form
        assert lines[0].split()[-3:] == ["origin", "front", "novel"]
        assert [line.split()[-1] for line in lines[1:]] == ["3", "2", "1"]
        # the synthetic writer fills a column it knows nothing about with the declared default (null)
        from genr8_dist.store.synthetic import write_synthetic_run

        synthetic = write_synthetic_run(tmp_path / "synthetic", 1, 2, 5, 0)
        assert synthetic.individuals(["novelty"]).column(0).null_count == 10
        # a run created before the column existed reads it as nulls
        old = RunStore.open(ROOT / "tests" / "data" / "run-schema-v1")
        assert "novelty" not in old.schema.names
        assert old.individuals(["novelty"]).column(0).null_count == old.individuals().num_rows
    # unregistered: the run keeps the column it was created with
    assert RunStore.open(run_dir).individuals(["novelty"]).column(0).to_pylist() == [3, 2, 1]


def test_the_docs_criteria_table_is_the_registrys():
    """docs/run-config.md holds ``criteria_table()`` verbatim (regenerate it with
    ``python -c "from genr8_dist.fitness import criteria_table; print(criteria_table())"``)."""
    docs = (ROOT / "docs" / "run-config.md").read_text(encoding="utf-8")
    assert criteria_table() in docs


def test_a_criterion_name_is_declared_once():
    from genr8_dist.errors import ConfigError
    from genr8_dist.fitness import register_criterion

    with registered(VERTICES), pytest.raises(ConfigError, match="already registered"):
        register_criterion(VERTICES)
    with pytest.raises(ConfigError, match="identifier"):
        CriterionInfo("not a name", _vertex_count, 0.0)
