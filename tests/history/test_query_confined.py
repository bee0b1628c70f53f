"""``query`` reads the run's three tables and nothing else, writes nothing, and stops on time."""

from __future__ import annotations

import hashlib
import time
from pathlib import Path

import pytest

from genr8_dist import history
from genr8_dist.cli import main
from genr8_dist.errors import HistoryError


def _tree(path: Path) -> dict[str, str]:
    return {str(p.relative_to(path)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(path.rglob("*")) if p.is_file()}


ESCAPES = [
    "select * from read_csv('/etc/passwd')",
    "select * from read_text('/etc/passwd')",
    "select * from glob('/etc/*')",
    "select * from '/etc/passwd'",
    "copy (select 1 as x) to '{out}/copied.csv'",
    "copy (select 1 as x) to '{run}/individuals/part-0000000003.parquet'",
    "attach '{out}/attached.db' as other",
    "export database '{out}/exported'",
    "install httpfs",
    "load httpfs",
    "set enable_external_access = true",
    "set temp_directory = '{out}'",
    "select * from read_parquet('{run}/individuals/*.parquet')",
]


@pytest.mark.parametrize("sql", ESCAPES)
def test_query_reaches_nothing_outside_its_tables(history_run, tmp_path, sql):
    before = _tree(history_run)
    with pytest.raises(HistoryError, match=r"^query: "):
        history.query(history_run, sql.format(out=tmp_path, run=history_run))
    assert list(tmp_path.iterdir()) == []
    assert _tree(history_run) == before


def test_python_variables_are_not_tables(history_run):
    secret = history.top(history_run, 1)  # noqa: F841  (DuckDB would find it by name by default)
    with pytest.raises(HistoryError, match="secret"):
        history.query(history_run, "select * from secret")


def test_a_runaway_statement_is_interrupted(history_run):
    start = time.monotonic()
    with pytest.raises(HistoryError, match=r"stopped after 1 s, the statement timeout"):
        history.query(history_run, "with recursive r(n) as (select 1 union all select n + 1 from r) "
                                   "select count(*) from r", timeout=1)
    assert time.monotonic() - start < 10


def test_results_are_not_written_into_a_run(history_run, tmp_path, capsys):
    before = _tree(history_run)
    for target in (history_run / "_manifest" / "0000000008.json", history_run / "out.csv",
                   history_run / "individuals" / "x.parquet"):
        flag = "--parquet" if target.suffix == ".parquet" else "--csv"
        assert main(["query", str(history_run), "select 1 as x", flag, str(target)]) == 2
        err = capsys.readouterr().err
        assert err.startswith(f"genr8: error: {target}: is inside the run directory") and err.count("\n") == 1
    assert main(["history", str(history_run), "--csv", str(history_run / "h.csv")]) == 2
    assert "never write into a run" in capsys.readouterr().err
    assert _tree(history_run) == before
    assert main(["query", str(history_run), "select 1 as x", "--csv", str(tmp_path / "ok.csv")]) == 0
    assert (tmp_path / "ok.csv").read_text() == '"x"\n1\n'


def test_max_rows_must_not_be_negative(history_run, capsys):
    with pytest.raises(SystemExit) as exit_:
        main(["query", str(history_run), "select 1", "--max-rows", "-1"])
    assert exit_.value.code == 2
    assert "--max-rows: -1: must be 0 or more" in capsys.readouterr().err


def test_a_damaged_file_is_named_not_answered(tmp_path):
    from history_runs import build_history_run

    from genr8_dist.errors import StoreError
    from genr8_dist.store import RunStore

    run = tmp_path / "run"
    build_history_run(run)
    victim = Path(RunStore.open(run).individual_files()[1])
    data = bytearray(victim.read_bytes())
    data[len(data) // 2] ^= 0x01
    victim.write_bytes(bytes(data))
    with pytest.raises(StoreError, match=rf"{victim.name}: corrupt"):
        history.query(run, "select count(*) from individuals")
