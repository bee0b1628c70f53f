"""The search modes' views of a run: Pareto front, clusters, MAP-Elites archive, and their commands."""

from __future__ import annotations

import math

import numpy as np
import pytest

from genr8_dist.config import RunConfig
from genr8_dist.evolution import Island
from genr8_dist.store import RunStore

pytestmark = pytest.mark.slow   # three small real runs, grown: about 20 s

BASE = {"universe": "tiles", "seed": 7, "genome": {"length": 50},
        "ea": {"population": 12, "generations": 3},
        "fitness": {"undulation": {"target": 1.0}, "slivers": {"target": 0.0, "weight": 1.0}},
        "environment": {"steps": 2}}


def _run(path, **search):
    config = RunConfig.from_dict({**BASE, "search": search} if search else BASE)
    store = RunStore.create(path, config.to_toml())
    for generation in Island(config, 0).run():
        store.commit(generation)
    return store, config


@pytest.fixture(scope="module")
def pareto_run(tmp_path_factory):
    return _run(tmp_path_factory.mktemp("search") / "pareto", mode="pareto",
                objectives=["undulation", "subdivisions", "slivers"])


@pytest.fixture(scope="module")
def archive_run(tmp_path_factory):
    return _run(tmp_path_factory.mktemp("search") / "archive", mode="map-elites",
                descriptors=["undulation", "cells"], ranges=[[0, 2], [1, 33]], bins=[3, 4])


def _distinct_devs(store, names, config):
    rows = [r for r in store.individuals().to_pylist() if r["valid"]]
    best = {}
    for r in sorted(rows, key=lambda r: (r["fitness"], r["generation"], r["island"], r["index"])):
        # one per form: equal sizes and raw criteria (to 9 digits) are one design, mirror images too
        best.setdefault(tuple(f"{r[c]:.9g}" for c in sorted(r) if c.startswith(("crit_", "size_"))), r)
    return {r["id"]: [config.fitness[n].deviation(r[f"crit_{n}"]) for n in names] for r in best.values()}


def test_the_pareto_front_is_every_non_dominated_surface_and_nothing_else(pareto_run):
    from genr8_dist import history

    store, config = pareto_run
    names = ["undulation", "subdivisions", "slivers"]
    front = history.pareto_front(store)
    devs = _distinct_devs(store, names, config)

    def dominated(a):
        return any(all(x <= y for x, y in zip(b, a, strict=True)) and b != a for b in devs.values())

    expected = {i for i, d in devs.items() if not dominated(d)}
    assert set(front["id"].to_pylist()) == expected and front.num_rows == len(expected)
    assert front.column_names[-3:] == [f"dev_{n}" for n in names]
    # stored: each individual's front among its generation, 0 for the non-dominated
    ranks = [r["pareto_rank"] for r in store.individuals(["pareto_rank", "generation"]).to_pylist()]
    assert min(ranks) == 0 and all(r is not None for r in ranks)


def test_kinds_cover_the_best_distinct_surfaces_once_look_apart_and_are_repeatable(pareto_run):
    from genr8_dist import history
    from genr8_dist.history._search import POOL_PER_KIND
    from genr8_dist.phenotype import SURFACES

    store, config = pareto_run
    a = history.clusters(store, 4)
    b = history.clusters(store, 4)
    assert a.equals(b)
    n = len(_distinct_devs(store, ["size"], config))
    pool = min(n, POOL_PER_KIND * 4)
    assert a.num_rows == 4 and sum(a["members"].to_pylist()) == pool
    members = [i for ids in a["member_ids"].to_pylist() for i in ids]
    assert len(set(members)) == pool
    assert all(r in ids for r, ids in zip(a["id"].to_pylist(), a["member_ids"].to_pylist(), strict=True))
    assert a["members"].to_pylist() == sorted(a["members"].to_pylist(), reverse=True)
    # the best distinct surface is a kind, and no two kinds look alike
    assert history.top(store, 1)["id"][0].as_py() in a["id"].to_pylist()
    seen = [np.concatenate(SURFACES.looks(history.regrow(store, i).developed)) for i in a["id"].to_pylist()]
    gaps = [np.linalg.norm(seen[i] - seen[j]) for i in range(4) for j in range(i)]
    assert min(gaps) > 0.05


def test_each_cluster_carries_the_ranges_of_its_members_criteria(pareto_run):
    from genr8_dist.history._search import cluster_ranges, clusters, format_range, weighted_criteria

    store, config = pareto_run
    kinds = clusters(store, 4)
    rows = {r["id"]: r for r in store.individuals().to_pylist()}
    for stats, members in zip(cluster_ranges(kinds), kinds["member_ids"].to_pylist(), strict=True):
        assert stats["members"] == len(members)
        for name in ["fitness", "undulation", "slivers"]:
            column = name if name == "fitness" else f"crit_{name}"
            values = [rows[m][column] for m in members if math.isfinite(rows[m][column])]
            assert stats["ranges"][name] == (min(values), max(values))
    assert set(cluster_ranges(kinds, ["slivers"])[0]["ranges"]) == {"fitness", "slivers"}
    assert weighted_criteria(store) == [n for n in config.fitness.names if config.fitness[n].weight > 0]
    assert format_range(0.5, 1.25) == "0.5–1.25" and format_range(2.0, 2.0) == "2"
    assert format_range(None, None) == "-"


def test_gallery_clusters_prints_each_clusters_size_and_ranges(pareto_run, tmp_path, capsys):
    from genr8_dist.cli import main
    from genr8_dist.history._search import cluster_ranges, clusters, format_range

    store, _ = pareto_run
    assert main(["gallery", str(store.path), "--clusters", "3", "-o", str(tmp_path / "k.png")]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0].startswith(f"wrote {tmp_path / 'k.png'}: 3 clusters")
    assert out[1] == "ranges over each cluster's members:"
    assert out[2].split()[:4] == ["cluster", "members", "representative", "fitness"]
    for line, stats in zip(out[3:], cluster_ranges(clusters(store, 3)), strict=True):
        cells = line.split()
        assert cells[:3] == [str(stats["cluster"]), str(stats["members"]), stats["id"]]
        assert cells[3] == format_range(*stats["ranges"]["fitness"])


def test_the_archive_holds_the_best_surface_of_each_cell(archive_run):
    from genr8_dist import history
    from genr8_dist.evolution.archive import Grid

    store, config = archive_run
    grid = Grid.from_settings(config.search)
    table = history.archive(store)
    last = store.load_generation(0, config.ea.generations)
    cells = grid.archive(last)
    assert sorted(table["cell"].to_pylist()) == sorted(cells)
    for row in table.to_pylist():
        assert row["fitness"] == cells[row["cell"]].fitness
        assert math.isfinite(row["fitness"])
    # the stored cell column is the archive cell of every valid individual
    stored = [(i.extra.get("cell"), grid.cell(i)) for i in last]
    assert all(a == b for a, b in stored)
    assert np.all(np.diff(table["fitness"].to_numpy()) >= 0)


def test_the_commands_list_the_front_and_draw_clusters_and_the_archive(pareto_run, archive_run, tmp_path,
                                                                        capsys):
    from genr8_dist.cli import main
    from genr8_dist.history._search import told_apart_by

    assert main(["top", str(pareto_run[0].path), "--pareto"]) == 0
    out = capsys.readouterr().out
    assert "non-dominated designs" in out and "dev_undulation" in out
    png = tmp_path / "kinds.png"
    assert main(["gallery", str(pareto_run[0].path), "--clusters", "3", "-o", str(png)]) == 0
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert told_apart_by(pareto_run[0]) == "outline, height field and curvature"   # the sheet's title
    grid = tmp_path / "map.png"
    assert main(["gallery", str(archive_run[0].path), "--archive", "-o", str(grid)]) == 0
    assert grid.stat().st_size > 1000
    assert main(["top", str(pareto_run[0].path), "--pareto", "--criterion", "size"]) == 2
    assert "--pareto and --criterion" in capsys.readouterr().err
