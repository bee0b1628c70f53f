"""``genr8 history / top / lineage / query`` in-process: printed output against pyarrow, files, errors."""

from __future__ import annotations

import importlib.util
import re
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc
import pytest

from genr8_dist import cli

_SPEC = importlib.util.spec_from_file_location(
    "history_runs_for_cli", Path(__file__).resolve().parents[1] / "history" / "history_runs.py")
history_runs = importlib.util.module_from_spec(_SPEC)
_SPEC.loader.exec_module(history_runs)


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory):
    path = tmp_path_factory.mktemp("cli-history") / "run"
    history_runs.build_history_run(path)
    return path


@pytest.fixture(scope="module")
def rows(run_dir):
    import pyarrow.parquet as pq

    from genr8_dist.store import RunStore

    return pa.concat_tables([pq.read_table(f) for f in RunStore.open(run_dir).individual_files()])


def _run(capsys, *argv) -> tuple[int, str, str]:
    code = cli.main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


def _is_png_with_content(path: Path) -> bool:
    import matplotlib.image as mpimg

    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    image = mpimg.imread(path)
    return image.shape[0] > 200 and image.shape[1] > 200 and float(image[..., :3].std()) > 0.05


def test_history_prints_every_generation_and_island(capsys, run_dir, rows):
    code, out, err = _run(capsys, "history", run_dir)
    assert code == 0 and err == ""
    lines = out.strip().splitlines()
    assert lines[0].split()[:7] == ["gen", "isl", "n", "valid", "best", "median", "worst"]
    assert len(lines) == 1 + history_runs.ISLANDS * history_runs.GENERATIONS
    valid = rows.filter(rows["valid"])
    for line in lines[1:]:
        fields = line.split()
        g, i = int(fields[0]), int(fields[1])
        mine = valid.filter(pc.and_(pc.equal(valid["generation"], g), pc.equal(valid["island"], i)))
        fitness = np.array(mine["fitness"].to_pylist())
        assert int(fields[3]) == len(fitness)
        assert fields[4] == f"{fitness.min():.5g}"
        assert fields[5] == f"{np.median(fitness):.5g}"
        assert fields[6] == f"{fitness.max():.5g}"
        assert fields[7] == mine["id"][int(np.argmin(fitness))].as_py()


def test_history_csv_and_png(capsys, run_dir, rows, tmp_path):
    import pyarrow.csv as pcsv

    code, out, _ = _run(capsys, "history", run_dir, "--island", 1, "--csv", tmp_path / "h.csv",
                        "--png", tmp_path / "h.png")
    assert code == 0 and "wrote" in out
    table = pcsv.read_csv(tmp_path / "h.csv")
    assert table["generation"].to_pylist() == list(range(history_runs.GENERATIONS))
    assert set(table["island"].to_pylist()) == {1}
    valid = rows.filter(pc.and_(rows["valid"], pc.equal(rows["island"], 1)))
    expected = valid.group_by("generation").aggregate([("fitness", "min")]).sort_by("generation")
    assert table["best"].to_pylist() == pytest.approx(expected["fitness_min"].to_pylist(), rel=1e-15)
    assert _is_png_with_content(tmp_path / "h.png")


def test_top_prints_the_k_best_in_order(capsys, run_dir, rows):
    code, out, _ = _run(capsys, "top", run_dir, "-k", 10, "--all")
    assert code == 0
    lines = out.strip().splitlines()
    assert len(lines) == 11
    valid = rows.filter(rows["valid"])
    order = pc.sort_indices(valid, sort_keys=[("fitness", "ascending"), ("generation", "ascending")])
    expected = valid.take(order).slice(0, 10)
    assert [line.split()[1] for line in lines[1:]] == expected["id"].to_pylist()
    assert [line.split()[4] for line in lines[1:]] == [f"{f:.5g}" for f in expected["fitness"].to_pylist()]


def test_top_lists_distinct_forms_by_default(capsys, run_dir):
    from genr8_dist import history

    code, out, _ = _run(capsys, "top", run_dir, "-k", 10)
    assert code == 0
    lines = out.strip().splitlines()
    assert lines[0].split()[-1] == "copies"
    distinct = history.top(str(run_dir), 10, distinct=True)
    assert [line.split()[1] for line in lines[1:]] == distinct["id"].to_pylist()
    assert len(set(distinct["id"].to_pylist())) == len(distinct)
    assert sum(int(line.split()[-1]) for line in lines[1:]) >= len(lines) - 1


def test_top_with_systems_of_the_last_generation(capsys, run_dir, rows):
    code, out, _ = _run(capsys, "top", run_dir, "-k", 3, "--generation", -1, "--island", 0, "--systems",
                        "--all")
    assert code == 0
    last = rows.filter(pc.and_(rows["valid"], pc.and_(
        pc.equal(rows["generation"], history_runs.GENERATIONS - 1), pc.equal(rows["island"], 0))))
    best = last.take(pc.sort_indices(last, sort_keys=[("fitness", "ascending")])).slice(0, 3)
    for ident, text in zip(best["id"].to_pylist(), best["text"].to_pylist(), strict=True):
        assert f" {ident} " in out
        for statement in text.splitlines():
            assert f"      {statement}\n" in out


def test_top_by_criterion(capsys, run_dir):
    code, out, _ = _run(capsys, "top", run_dir, "-k", 4, "--criterion", "symmetry")
    assert code == 0
    header = out.splitlines()[0].split()
    assert "deviation" in header
    deviations = [float(line.split()[header.index("deviation")]) for line in out.strip().splitlines()[1:]]
    assert deviations == sorted(deviations)


def test_lineage_text_and_png(capsys, run_dir, rows, tmp_path):
    code, out, _ = _run(capsys, "lineage", run_dir, "3-49-10", "--all", "--png", tmp_path / "l.png")
    assert code == 0
    parents = dict(zip(rows["id"].to_pylist(), rows["parents"].to_pylist(), strict=True))
    seen, todo = set(), ["3-49-10"]
    while todo:
        current = todo.pop()
        if current not in seen:
            seen.add(current)
            todo.extend(parents[current])
    assert out.splitlines()[0].startswith("ancestry of 3-49-10 (generation 49, island 3, fitness ")
    assert f": {len(seen) - 1} ancestors over 50 generations" in out.splitlines()[0]
    listed = {m.group(1) for m in re.finditer(r"^ [ *] (\S+) +fitness ", out, re.MULTILINE)}
    assert listed == seen
    assert "migrant from island" in out
    assert _is_png_with_content(tmp_path / "l.png")
    code, short, _ = _run(capsys, "lineage", run_dir, "3-49-10")
    assert code == 0 and short.splitlines()[:3] == out.splitlines()[:3]
    assert "more in generation 0" in short and short.count("\n") < out.count("\n")


def test_query_prints_and_writes(capsys, run_dir, rows, tmp_path):
    import pyarrow.parquet as pq

    sql = "select island, count(*) as n, max(generation) as last from individuals group by 1 order by 1"
    code, out, _ = _run(capsys, "query", run_dir, sql)
    assert code == 0
    lines = out.strip().splitlines()
    assert lines[0].split() == ["island", "n", "last"]
    assert lines[-1] == "(4 rows)"
    per = history_runs.GENERATIONS * history_runs.POP
    assert [line.split() for line in lines[1:-1]] == [[str(i), str(per), "49"] for i in range(4)]
    code, out, _ = _run(capsys, "query", run_dir, sql, "--parquet", tmp_path / "q.parquet")
    assert code == 0 and out.startswith("wrote 4 rows")
    assert pq.read_table(tmp_path / "q.parquet")["n"].to_pylist() == [per] * 4
    code, _, _ = _run(capsys, "query", run_dir, "select id, parents from individuals where generation = 3 "
                      "order by id limit 5", "--csv", tmp_path / "q.csv")
    assert code == 0 and (tmp_path / "q.csv").read_text().splitlines()[0] == '"id","parents"'


@pytest.mark.parametrize("argv", [
    ("lineage", "{run}", "7-7-7"),
    ("show", "{run}", "0-99-0"),
    ("query", "{run}", "select * form individuals"),
    ("query", "{run}", "select missing_column from individuals"),
    ("top", "{run}", "--criterion", "beauty"),
    ("history", "{missing}"),
    ("top", "{missing}"),
    ("history", "{empty}"),
    ("top", "{empty}"),
    ("report", "{empty}", "-o", "{tmp}/r.html"),
    ("gallery", "{missing}", "-o", "{tmp}/g.png"),
    ("gallery", "{run}", "-k", "0", "-o", "{tmp}/g.png"),
    ("lineage", "{run}", "0-5-5", "--depth", "-2"),
    ("top", "{run}", "--generation", "-51"),
    ("history", "{run}", "--csv", "{tmp}/no/such/folder/h.csv"),
    ("query", "{run}", "   "),
    ("query", "{run}", ";"),
    ("query", "{run}", "-- nothing"),
    ("query", "{run}", "/* a comment */ ;;"),
])
def test_bad_input_is_one_line_and_exit_2(capsys, run_dir, tmp_path, argv):
    from genr8_dist.store import RunStore

    empty = tmp_path / "empty"
    RunStore.create(empty, history_runs.TOML_V1)
    values = {"run": run_dir, "missing": tmp_path / "nowhere", "empty": empty, "tmp": tmp_path}
    code, out, err = _run(capsys, *(a.format(**values) for a in argv))
    assert code == 2
    assert out == ""
    assert err.startswith("genr8: error: ") and err.count("\n") == 1, err
    assert "Traceback" not in err
    assert not (tmp_path / "r.html").exists() and not (tmp_path / "g.png").exists()


@pytest.fixture(scope="module")
def real_run(tmp_path_factory):
    path = tmp_path_factory.mktemp("cli-history-real") / "run"
    history_runs.build_real_run(path)
    return path


@pytest.mark.slow
def test_export_writes_every_chosen_design_in_every_chosen_format(capsys, real_run, tmp_path):
    from genr8_dist import history

    run_dir = real_run
    best = history.top(str(run_dir), 1)["id"][0].as_py()
    code, out, _ = _run(capsys, "export", run_dir, "--ids", "best", "0-0-1", "-o", tmp_path / "ids",
                        "--format", "obj", "--format", "glb")
    assert code == 0, _
    assert out.startswith("wrote 2 designs x obj, glb")
    assert sorted(p.name for p in (tmp_path / "ids").iterdir()) == sorted(
        f"{i}.{f}" for i in (best, "0-0-1") for f in ("obj", "glb"))
    code, _, _ = _run(capsys, "show", run_dir, best, "-o", tmp_path / "one.obj")
    assert (tmp_path / "one.obj").read_bytes() == (tmp_path / "ids" / f"{best}.obj").read_bytes()

    front = history.pareto_front(str(run_dir))["id"].to_pylist()
    assert _run(capsys, "export", run_dir, "--front", "-o", tmp_path / "front")[0] == 0
    assert sorted(p.stem for p in (tmp_path / "front").iterdir()) == sorted(front)

    kinds = history.clusters(str(run_dir), 4)
    assert _run(capsys, "export", run_dir, "--cluster", 1, "--clusters", 4, "-o", tmp_path / "kind")[0] == 0
    written = sorted(p.stem for p in (tmp_path / "kind").iterdir())
    assert len(written) == kinds["members"][0].as_py() and kinds["id"][0].as_py() in written

    code, _, err = _run(capsys, "export", run_dir, "--cluster", 9, "--clusters", 4, "-o", tmp_path / "none")
    assert code == 2 and "1..4" in err and not (tmp_path / "none").exists()
    code, _, err = _run(capsys, "export", run_dir, "--front", "-o", tmp_path / "bad", "--format", "docx")
    assert code == 2 and "docx" in err and not (tmp_path / "bad").exists()


def test_show_marks_the_rules_that_never_fired(capsys, tmp_path):
    """``genr8 show`` marks each rule that rewrote no edge in the individual's growth: here the
    rule for Edge0, a label the axiom and the other rule never draw; the rule that fired is not."""
    from genr8_dist.config import RunConfig
    from genr8_dist.evolution.evaluate import evaluate_text
    from genr8_dist.evolution.individual import Individual
    from genr8_dist.store import RunStore

    text = ("Edge1 + Edge1 + Edge1 + Edge1\nEdge0 Edge1 -> Edge0\n"
            "Edge1 -> Edge1 [ [ + Edge1 ] - Edge1 ] Edge1 Edge1\nAngle 90\n")
    config = RunConfig.from_dict({"environment": {"steps": 2}})
    store = RunStore.create(tmp_path / "run", config.to_toml())
    store.commit([Individual(0, 0, 0, (1, 2, 3), "injected", **evaluate_text(text, config).as_fields())])
    code, out, err = _run(capsys, "show", tmp_path / "run", "0-0-0")
    assert code == 0, err
    lines = out.splitlines()
    start = next(i for i, line in enumerate(lines) if line.startswith("rewrite system"))
    assert "# never fired" in lines[start]
    marked = [line.strip() for line in lines[start + 1:start + 5] if line.endswith("# never fired")]
    assert marked == ["Edge0 Edge1 -> Edge0    # never fired"]
