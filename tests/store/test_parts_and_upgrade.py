"""Parts written by another process and committed by the run's writer (store/parts.py), and the
in-place upgrade of a layout 1 run, the checked-in schema 1 and 2 runs included (store/upgrade.py):
atomic, a crash at either side of its commit point leaving a run that reads the same rows."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.parquet as pq
import pytest

from genr8_dist import history
from genr8_dist.cli import main
from genr8_dist.errors import StoreError
from genr8_dist.store import Event, RunStore, write_synthetic_run
from genr8_dist.store._fs import RunFS
from genr8_dist.store.parts import Part, write_part
from genr8_dist.store.synthetic import _text_pool, synthetic_epoch

ROOT = Path(__file__).resolve().parents[2]
DATA = ROOT / "tests" / "data"


def _glob_ids(run: Path) -> list[str]:
    files = sorted((run / "individuals").glob("*.parquet"))
    tables = [pq.read_table(f, columns=["id"]) for f in files]
    return sorted(pa.concat_tables(tables).column("id").to_pylist())


def _query_ids(run: Path) -> list[str]:
    return sorted(history.query(run, "select id from individuals").column("id").to_pylist())


HOST = """
import json, sys
import pyarrow.compute as pc
from genr8_dist.store import RunStore
from genr8_dist.store.parts import write_part
from genr8_dist.store.synthetic import _text_pool, synthetic_epoch
store = RunStore.open(sys.argv[1])
island = int(sys.argv[2])
table = synthetic_epoch(store, 3, 1, 2, 3, 2, 6, (16, 64), _text_pool(3))
part = write_part(store, table.filter(pc.equal(table["island"], island)), stem=f"part-island{island}")
print(json.dumps({"name": part.name, "sha256": part.sha256, "rows": part.rows, "bytes": part.bytes,
                  "islands": part.islands}))
"""


def test_parts_written_by_other_processes_commit_as_one_epoch(tmp_path: Path) -> None:
    store = write_synthetic_run(tmp_path / "run", 2, 2, 6, 3, generations_per_commit=2)
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    parts = []
    for island in (0, 1):   # two island hosts, each its own process
        out = subprocess.run([sys.executable, "-c", HOST, str(tmp_path / "run"), str(island)], env=env,
                             check=True, capture_output=True, text=True).stdout
        parts.append(Part(**json.loads(out)))
    assert _glob_ids(tmp_path / "run") == _query_ids(tmp_path / "run")   # staged parts are not seen
    assert history.query(tmp_path / "run", "select count(*) n from individuals").to_pylist() == [{"n": 24}]
    version = store.commit_parts(parts, [Event("migration", 3)])
    assert store.committed_generations() == {0: 3, 1: 3}
    assert os.listdir(tmp_path / "run" / "_staging") == []
    reopened = RunStore.open(tmp_path / "run")
    assert reopened.version == version and reopened.verify() == []
    assert reopened.individuals().num_rows == 48
    assert _glob_ids(tmp_path / "run") == _query_ids(tmp_path / "run")
    expected = synthetic_epoch(store, 3, 1, 2, 3, 2, 6, (16, 64), _text_pool(3))
    got = reopened.individuals(filter=pc.field("generation") >= 2).sort_by("id")
    assert got.column("id").to_pylist() == expected.sort_by("id").column("id").to_pylist()
    assert reopened.events().column("kind").to_pylist()[-1] == "migration"


def test_a_part_that_does_not_follow_is_refused_and_left_staged(tmp_path: Path) -> None:
    store = write_synthetic_run(tmp_path / "run", 2, 2, 6, 3, generations_per_commit=2)
    table = synthetic_epoch(store, 3, 2, 4, 5, 2, 6, (16, 64), _text_pool(3))   # generations 4..5: a gap
    part = write_part(store, table)
    with pytest.raises(StoreError, match=r"island 0: the parts hold generations from 4 to 5.*next one to "
                                         r"commit is 2"):
        store.commit_parts([part])
    assert os.listdir(tmp_path / "run" / "_staging") == [part.name]
    assert RunStore.open(tmp_path / "run").version == store.version
    with pytest.raises(StoreError, match="appears twice"):
        write_part(store, pa.concat_tables([table, table]))
    bad = Part(part.name, part.sha256, part.rows + 1, part.bytes, part.islands)
    with pytest.raises(StoreError, match="descriptor says"):
        store.commit_parts([bad])


def _layout1(tmp_path: Path, name: str) -> Path:
    """A copy of a checked-in run of layout 1 (schema 1 or 2)."""
    return Path(shutil.copytree(DATA / name, tmp_path / name))


@pytest.mark.parametrize("name", ["run-schema-v1", "run-schema-v2"])
def test_repair_upgrade_converts_an_old_run_in_place(tmp_path: Path, name: str,
                                                     capsys: pytest.CaptureFixture[str]) -> None:
    run = _layout1(tmp_path, name)
    before = history.query(run, "select * from individuals order by id")
    events = history.query(run, "select kind, generation, seq from events order by seq")
    assert RunStore.open(run).manifest_layout == 1
    assert main(["repair", "--upgrade", str(run)]) == 0
    assert "upgraded to layout 2" in capsys.readouterr().out
    store = RunStore.open(run)
    assert store.manifest_layout == 2 and store.verify() == []
    assert os.path.islink(run / "individuals") and os.path.islink(run / "events")
    assert history.query(run, "select * from individuals order by id").equals(before)
    assert history.query(run, "select kind, generation, seq from events order by seq").equals(events)
    assert _glob_ids(run) == _query_ids(run)
    assert main(["repair", "--upgrade", str(run)]) == 0     # once is enough
    assert RunStore.open(run).version == store.version


def test_a_crash_before_the_upgrades_commit_leaves_the_old_layout(tmp_path: Path,
                                                                  monkeypatch: pytest.MonkeyPatch) -> None:
    run = _layout1(tmp_path, "run-schema-v2")
    want = _query_ids(run)

    def cut(self: RunFS, rel: str, data: bytes) -> None:
        raise OSError("power cut")

    monkeypatch.setattr(RunFS, "write_exclusive", cut)
    with pytest.raises(OSError, match="power cut"):
        RunStore.open(run).upgrade()
    monkeypatch.undo()
    store = RunStore.open(run)
    assert store.manifest_layout == 1 and store.verify() == []
    assert not os.path.islink(run / "individuals") and _glob_ids(run) == want == _query_ids(run)
    assert store.upgrade() and _glob_ids(run) == want == _query_ids(run)


def test_a_crash_after_the_upgrades_commit_reads_the_same_rows_either_way(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    from genr8_dist.store import views

    run = _layout1(tmp_path, "run-schema-v1")
    want = _query_ids(run)

    def killed(rfs: RunFS, manifest: dict[str, object]) -> bool:
        raise OSError("killed before the view")

    monkeypatch.setattr(views, "publish_view", killed)
    RunStore.open(run).upgrade()   # the commit point passed; its view did not
    monkeypatch.undo()
    store = RunStore.open(run)
    assert store.manifest_layout == 2
    assert [p for p in store.verify() if "glob view shows no commit" in p] == store.verify()
    assert not os.path.islink(run / "individuals")        # the old folder, still exactly the run
    assert _glob_ids(run) == want == _query_ids(run)
    assert not store.upgrade()                             # the next writer finishes the view
    assert os.path.islink(run / "individuals") and _glob_ids(run) == want == _query_ids(run)
    assert RunStore.open(run).verify() == []


def test_an_upgraded_old_run_takes_new_commits(tmp_path: Path) -> None:
    run = _layout1(tmp_path, "run-schema-v2")
    store = RunStore.open(run)
    store.upgrade()
    store.record_event("resume", generation=1)
    assert RunStore.open(run).verify() == [] and _glob_ids(run) == _query_ids(run)
    assert sorted(p.name for p in (run / "events").glob("*.parquet")) == sorted(
        Path(e["path"]).name for e in RunStore.open(run).manifest["events"])


def test_an_altered_or_lagging_view_is_named_and_repair_rebuilds_it(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    from genr8_dist.store import views

    run = tmp_path / "run"
    write_synthetic_run(run, 2, 6, 6, 3, generations_per_commit=1)
    victim = sorted((run / "individuals").glob("*.parquet"))[0]
    victim.unlink()                                  # the glob would now miss rows
    store = RunStore.open(run)
    assert [p for p in store.verify() if victim.name in p and "glob view is altered" in p]
    assert store.repair() and "rebuilt the glob view" in store.last_repair
    assert RunStore.open(run).verify() == [] and _glob_ids(run) == _query_ids(run)
    monkeypatch.setattr(views, "publish_view", lambda rfs, m: (_ for _ in ()).throw(OSError("killed")))
    store.record_event("resume", generation=6)      # committed; killed before its view
    monkeypatch.undo()
    problems = RunStore.open(run).verify()
    assert len(problems) == 1 and "the glob view shows commit" in problems[0]
    assert RunStore.open(run).repair() == problems
    assert RunStore.open(run).verify() == [] and _glob_ids(run) == _query_ids(run)
    assert views.current_view(RunStore.open(run)._fs) == RunStore.open(run).version
