"""docs/run-store.md's recipes, taken out of the doc and run: every engine the test extra installs
(DuckDB, Polars, pyarrow, pandas) reads a run directory without genr8 and gets exactly the rows
`genr8 query` gives (ids, fitness, every criterion), on a finished run, a compacted run, a run being
written (a commit cut off between its parts and its manifest, a host's part not yet committed) and a
run resumed after a SIGKILL; and as of a generation (time travel)."""

from __future__ import annotations

import contextlib
import json
import math
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from genr8_dist import history
from genr8_dist.store import Event, RunStore, write_synthetic_run
from genr8_dist.store._fs import RunFS
from genr8_dist.store.synthetic import _text_pool, synthetic_epoch

ROOT = Path(__file__).resolve().parents[2]
DOC = ROOT / "docs" / "run-store.md"
ISLANDS, GENERATIONS, POP, SEED = 3, 12, 8, 5
AS_OF = 5


def recipes() -> dict[str, str]:
    """The ``python`` blocks of the doc's "Reading a run with any engine" section, by recipe name."""
    text = DOC.read_text()
    start = text.index("## Reading a run with any engine")
    section = text[start:text.index("\n## ", start + 1)]
    found = {}
    for block in re.findall(r"```python\n(.*?)```", section, flags=re.S):
        first = block.splitlines()[0]
        match = re.match(r"# recipe: ([\w-]+)", first)
        assert match, f"a recipe block of {DOC.name} must start with '# recipe: NAME': {first!r}"
        found[match.group(1)] = block
    return found


RECIPES = recipes()
PLAIN = [n for n in RECIPES if not n.endswith("-as-of") and n != "spark"]
AS_OF_RECIPES = [n for n in RECIPES if n.endswith("-as-of")]
MODULE = {"duckdb": "duckdb", "polars": "polars", "pandas": "pandas", "pyarrow": "pyarrow"}


def test_the_doc_has_a_recipe_for_every_engine() -> None:
    assert {"duckdb", "polars", "pyarrow", "pandas", "spark", "duckdb-manifest"} <= set(RECIPES)
    assert AS_OF_RECIPES, "time travel has recipes"
    assert "not run" in RECIPES["spark"].splitlines()[0]


def run_recipe(name: str, run: Path, generation: int | None = None) -> pa.Table:
    """Execute recipe ``name`` on ``run``; its ``rows`` as an Arrow table."""
    pytest.importorskip(MODULE[name.split("-")[0]])
    scope: dict[str, Any] = {"run": str(run), "G": generation}
    exec(compile(RECIPES[name], f"{DOC.name}:{name}", "exec"), scope)
    rows = scope["rows"]
    if isinstance(rows, pa.Table):
        return rows
    if type(rows).__module__.startswith("polars"):
        return rows.to_arrow()
    return pa.Table.from_pandas(rows, preserve_index=False)


def _key(table: pa.Table, columns: list[str]) -> list[tuple[Any, ...]]:
    def norm(v: Any) -> Any:
        return None if isinstance(v, float) and math.isnan(v) else v
    data = table.select(columns).to_pylist()
    return sorted((tuple(norm(r[c]) for c in columns) for r in data), key=lambda t: t[0])


def same_as_query(run: Path, got: pa.Table, as_of: int | None = None) -> None:
    store = RunStore.open(run)
    columns = ["id", "fitness", *[f"crit_{c}" for c in store.criteria]]
    want = history.query(run, f"select {', '.join(columns)} from individuals", as_of=as_of)
    assert want.num_rows > 0
    got_rows, want_rows = _key(got, columns), _key(want, columns)
    assert len(got_rows) == len(want_rows)          # no row missing, none doubled
    assert got_rows == want_rows                     # ids, fitness, every criterion


# --- runs of every kind ------------------------------------------------------------------------

def _finished(path: Path) -> Path:
    write_synthetic_run(path, ISLANDS, GENERATIONS, POP, SEED, generations_per_commit=1)
    return path


def _compacted(path: Path) -> Path:
    store = write_synthetic_run(path, ISLANDS, GENERATIONS, POP, SEED, generations_per_commit=1)
    superseded = list(store.individual_files())
    store.compact(target_rows=4 * ISLANDS * POP)
    assert len(store.individual_files()) < len(superseded)
    on_disk = os.listdir(path / "_files" / "individuals")
    assert len(on_disk) > len(store.individual_files())   # the superseded files are still kept ...
    assert sorted(os.listdir(path / "individuals")) == sorted(   # ... and out of the glob's sight
        Path(f).name for f in store.individual_files())
    return path


def _being_written(path: Path) -> Path:
    from genr8_dist.store.parts import write_part

    store = write_synthetic_run(path, ISLANDS, 6, POP, SEED, generations_per_commit=2)
    texts = _text_pool(SEED)
    table = synthetic_epoch(store, SEED, 9, 6, 7, ISLANDS, POP, (16, 64), texts)
    write_part(store, table.filter(pa.compute.equal(table["island"], 0)))  # a host's part, not committed
    with pytest.MonkeyPatch.context() as mp:   # killed between writing the parts and the manifest
        mp.setattr(RunStore, "_publish", lambda self, m, v: (_ for _ in ()).throw(KeyboardInterrupt()))
        mp.setattr(RunFS, "delete", lambda self, rel: None)     # (a kill leaves its files behind)
        with pytest.raises(KeyboardInterrupt):
            store.commit_table(table, [Event("migration", 7)])
    assert len(os.listdir(path / "_files" / "individuals")) > len(store.individual_files())
    assert os.listdir(path / "_staging")
    return path


WRITER = """
import sys
from genr8_dist.store import Event, RunStore
from genr8_dist.store.synthetic import _text_pool, synthetic_epoch
path, first_epoch, epochs, islands, pop, seed = sys.argv[1], *map(int, sys.argv[2:])
store = RunStore.open(path, compact_every=3)
texts = _text_pool(seed)
for epoch in range(first_epoch, epochs):
    table = synthetic_epoch(store, seed, epoch, epoch, epoch, islands, pop, (16, 64), texts)
    store.commit_table(table, [Event("migration", epoch)])
"""


def _resumed_after_sigkill(path: Path) -> Path:
    store = RunStore.create(path, 'universe = "default"\nseed = 5\n')
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    args = [sys.executable, "-c", WRITER, str(path), "0", "400", str(ISLANDS), str(POP), str(SEED)]
    proc = subprocess.Popen(args, env=env)
    try:
        deadline = time.monotonic() + 60
        while len(os.listdir(path / "_manifest")) < 8 and time.monotonic() < deadline:
            time.sleep(0.02)
        time.sleep(0.05 + (os.getpid() % 7) / 20)  # some moment inside a commit, or a compaction
    finally:
        proc.send_signal(signal.SIGKILL)
        proc.wait()
    # before the resume: the glob sees one whole commit, the one _current names
    from genr8_dist.store.views import current_view

    shown = current_view(RunStore.open(path)._fs)
    manifest = json.loads((path / "_manifest" / f"{shown:010d}.json").read_text())
    globbed = [pq.read_table(f, columns=["id"]) for f in (path / "individuals").glob("*.parquet")]
    ids = pa.concat_tables(globbed).column("id").to_pylist() if globbed else []
    assert len(ids) == len(set(ids)) == sum(e["rows"] for e in manifest["individuals"])
    # the resume: what `genr8 resume` does to the store (finish the view, collect garbage), then go on
    store = RunStore.open(path, compact_every=3)
    store.upgrade()
    store.collect_garbage()
    done = max(store.committed_generations().values(), default=-1)
    subprocess.run([*args[:4], str(done + 1), str(done + 3), *args[6:]], env=env, check=True)
    assert max(RunStore.open(path).committed_generations().values()) == done + 2
    return path


KINDS = {"finished": _finished, "compacted": _compacted, "being-written": _being_written,
         "resumed-after-sigkill": _resumed_after_sigkill}


@pytest.fixture(scope="module", params=list(KINDS))
def run(request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory) -> Path:
    return KINDS[request.param](tmp_path_factory.mktemp(request.param) / "run")


@pytest.mark.parametrize("recipe", PLAIN)
def test_every_engine_reads_exactly_what_query_answers(run: Path, recipe: str) -> None:
    same_as_query(run, run_recipe(recipe, run))


@pytest.mark.parametrize("recipe", AS_OF_RECIPES)
def test_every_engine_reads_the_run_as_of_a_generation(run: Path, recipe: str) -> None:
    got = run_recipe(recipe, run, AS_OF)
    assert max(got.column("generation").to_pylist()) == AS_OF
    same_as_query(run, got, as_of=AS_OF)


def test_a_kept_view_is_exactly_its_commit(tmp_path: Path) -> None:
    run = _finished(tmp_path / "run")
    store = RunStore.open(run)
    older = store.version - 3
    manifest = json.loads((run / "_manifest" / f"{older:010d}.json").read_text())
    files = sorted((run / "_views" / f"{older:010d}" / "individuals").glob("*.parquet"))
    table = pa.concat_tables([pq.read_table(f) for f in files])
    assert table.num_rows == sum(e["rows"] for e in manifest["individuals"])
    last = max(manifest["generations"].values())
    assert max(table.column("generation").to_pylist()) == last
    same_as_query(run, table, as_of=last)


def test_query_as_of_reads_events_and_configurations_by_then(tmp_path: Path) -> None:
    run = _finished(tmp_path / "run")
    store = RunStore.open(run)
    store.add_config('universe = "default"\nseed = 5\n# v2\n', GENERATIONS,
                     events=[Event("intervention", GENERATIONS)])
    events = history.query(run, "select max(generation) g, count(*) n from events", as_of=AS_OF).to_pylist()
    assert events == [{"g": AS_OF, "n": AS_OF + 2}]   # start, and a migration after each generation
    configs = history.query(run, "select count(*) n from configs", as_of=AS_OF).to_pylist()
    assert configs == [{"n": 1}]
    assert history.query(run, "select count(*) n from configs").to_pylist() == [{"n": 2}]


TINY = """\
universe = "default"
seed = 7

[genome]
length = 30
max_depth = 4

[ea]
population = 6
generations = 10
tournament = 2
elites = 1

[environment]
steps = 2

[islands]
count = 3
migration_interval = 2
migrants = 1
"""


@pytest.fixture(scope="module")
def real_run_killed_and_resumed(tmp_path_factory: pytest.TempPathFactory, ray_local: Any) -> Path:
    """A real `genr8 run` (Ray islands, grown surfaces), SIGKILLed after generation 3, then resumed."""
    import io

    from genr8_dist.distributed.session import RunOptions, resume_run

    tmp = tmp_path_factory.mktemp("real")
    (tmp / "tiny.toml").write_text(TINY)
    run_dir = tmp / "run"
    env = dict(os.environ, RAY_USAGE_STATS_ENABLED="0", PYTHONPATH=str(ROOT))
    env.pop("RAY_ADDRESS", None)
    proc = subprocess.Popen([sys.executable, "-m", "genr8_dist.cli", "run", str(tmp / "tiny.toml"),
                             "--run-dir", str(run_dir), "--cpus", "2"], stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL, env=env, start_new_session=True)
    try:
        deadline = time.monotonic() + 240
        while time.monotonic() < deadline:
            try:
                done = RunStore.open(run_dir).committed_generations()
            except Exception:  # not created yet
                done = {}
            if len(done) == 3 and min(done.values()) >= 3:
                break
            assert proc.poll() is None, "the run ended early"
            time.sleep(0.05)
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait(timeout=30)
    finally:
        with contextlib.suppress(ProcessLookupError, PermissionError):
            os.killpg(proc.pid, signal.SIGKILL)   # its local Ray, by the group's id
        proc.wait(timeout=30)
    summary = resume_run(str(run_dir), RunOptions(quiet=True), out=io.StringIO())
    assert summary.status == "complete"
    return run_dir


@pytest.mark.slow
@pytest.mark.parametrize("recipe", PLAIN + AS_OF_RECIPES)
def test_every_engine_reads_a_real_run_resumed_after_a_sigkill(real_run_killed_and_resumed: Path,
                                                               recipe: str) -> None:
    run = real_run_killed_and_resumed
    as_of = AS_OF if recipe.endswith("-as-of") else None
    same_as_query(run, run_recipe(recipe, run, as_of), as_of=as_of)
    assert RunStore.open(run).verify() == []
