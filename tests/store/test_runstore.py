"""The run store: creation, commits all-or-nothing, reads, configurations, events, faults, compaction."""

from __future__ import annotations

import math
import os
import re
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import duckdb
import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.fs as pafs
import pytest

from genr8_dist.errors import ConfigError, StoreError
from genr8_dist.evolution.individual import Individual
from genr8_dist.rng import stream
from genr8_dist.store import Event, RunStore
from genr8_dist.store._fs import RunFS
from genr8_dist.store.runstore import KEEP_MANIFESTS

CONFIG = '[run]\nseed = 3\nislands = 2\n'


def generation(island: int, gen: int, pop: int = 5) -> list[Individual]:
    """A generation whose rows vary in every field, including the awkward values."""
    out = []
    for k in range(pop):
        valid = (k + gen) % 3 != 0
        out.append(Individual(
            island=island, generation=gen, index=k, genome=tuple(range(k, k + 4 + gen % 3)),
            origin="random" if gen == 0 else "crossover",
            parents=() if gen == 0 else (f"{island}-{gen - 1}-{k}", f"{island}-{gen - 1}-0"),
            text=f"Axiom a b c\na -> a [+ b] {k}" if valid or k % 2 else None,
            valid=valid, stage=None if valid else "grow", error=None if valid else "no regions",
            fitness=float(gen * 10 + k) if valid else math.inf,
            criteria={"size": 1.5 * k, "symmetry": 0.25} if valid else {},
            config_version=1, codons_used=7 + k, wraps=k % 2,
            sizes={"vertices": 10 * k, "edges": 20 * k, "regions": k},
            steps_done=3, capped="vertices" if k == 4 else None,
            phenotype_digest=f"{gen:08x}{k:024x}" if valid else None,
            eval_seconds=0.5, map_seconds=0.1, grow_seconds=0.3, score_seconds=0.1,
        ))
    return out


def epoch(gens: range, islands: int = 2, pop: int = 5) -> list[Individual]:
    return [ind for i in range(islands) for g in gens for ind in generation(i, g, pop)]


def named(folder: Path, stem: str) -> Path:
    """The one file of ``folder`` whose name is ``stem`` followed by its writer token."""
    (found,) = [p for p in folder.iterdir() if re.fullmatch(re.escape(stem) + r"-[0-9a-f]{16}\.\w+", p.name)]
    return found


def tree(path: Path) -> dict[str, bytes]:
    return {str(p.relative_to(path)): p.read_bytes() for p in sorted(path.rglob("*")) if p.is_file()}


@pytest.fixture
def store(tmp_path: Path) -> RunStore:
    return RunStore.create(tmp_path / "run", CONFIG)


# --- creating and opening ----------------------------------------------------------------------

def test_create_then_open_reads_the_same_run(tmp_path: Path) -> None:
    created = RunStore.create(tmp_path / "my-run", CONFIG)
    assert created.run_id == "my-run"
    assert created.path == str(tmp_path / "my-run")
    created.commit(epoch(range(3)))
    opened = RunStore.open(str(tmp_path / "my-run"))
    assert opened.run_id == "my-run"
    assert opened.committed_generations() == {0: 2, 1: 2}
    assert opened.individuals().num_rows == 2 * 3 * 5
    assert opened.configs()[0].toml == CONFIG


def test_create_refuses_an_existing_run_and_leaves_it_untouched(store: RunStore, tmp_path: Path) -> None:
    store.commit(epoch(range(2)))
    before = tree(tmp_path / "run")
    with pytest.raises(StoreError, match=r"run.*already holds run 'run'"):
        RunStore.create(tmp_path / "run", CONFIG)
    assert tree(tmp_path / "run") == before


def test_create_refuses_a_directory_holding_other_things(tmp_path: Path) -> None:
    (tmp_path / "home").mkdir()
    (tmp_path / "home" / "thesis.pdf").write_bytes(b"%PDF")
    with pytest.raises(StoreError, match=r"home: exists and is not empty \(holds 'thesis.pdf'\)"):
        RunStore.create(tmp_path / "home", CONFIG)
    assert os.listdir(tmp_path / "home") == ["thesis.pdf"]


def test_create_finishes_a_creation_that_crashed_but_never_overwrites_data(tmp_path: Path) -> None:
    half = tmp_path / "half"
    (half / "configs").mkdir(parents=True)
    (half / "configs" / "v0001.toml").write_text("[run]\nseed = 1\n")  # crashed before its manifest
    RunStore.create(half, CONFIG)
    assert RunStore.open(half).configs()[0].toml == CONFIG
    damaged = tmp_path / "damaged"
    store = RunStore.create(damaged, CONFIG)
    store.commit(epoch(range(1)))
    for manifest in (damaged / "_manifest").iterdir():
        manifest.write_text("{}")
    before = tree(damaged)
    with pytest.raises(StoreError, match="damaged: holds a damaged run"):
        RunStore.create(damaged, CONFIG)
    assert tree(damaged) == before


def test_create_accepts_an_empty_directory_and_refuses_bad_toml(tmp_path: Path) -> None:
    (tmp_path / "empty").mkdir()
    RunStore.create(tmp_path / "empty", CONFIG, run_id="exp-7")
    assert RunStore.open(tmp_path / "empty").run_id == "exp-7"
    with pytest.raises(ConfigError, match=r"configuration version 1: not valid TOML.*line 1"):
        RunStore.create(tmp_path / "bad", "[run\nseed = 1")
    with pytest.raises(StoreError, match="run_id"):
        RunStore.create(tmp_path / "bad2", CONFIG, run_id="a b")


def test_open_names_the_path_when_missing_or_not_a_run(tmp_path: Path) -> None:
    with pytest.raises(StoreError, match=r"nowhere: no such run directory"):
        RunStore.open(tmp_path / "nowhere")
    (tmp_path / "plain").mkdir()
    (tmp_path / "plain" / "x.txt").write_text("hi")
    with pytest.raises(StoreError, match=r"plain: not a run directory"):
        RunStore.open(tmp_path / "plain")
    with pytest.raises(StoreError, match=r"x.txt: is a file"):
        RunStore.open(tmp_path / "plain" / "x.txt")


def test_open_refuses_a_run_written_by_a_newer_schema(store: RunStore, tmp_path: Path) -> None:
    import json

    from genr8_dist.store.manifest import encode_manifest

    path = tmp_path / "run" / "_manifest" / "0000000001.json"
    manifest = json.loads(path.read_text())
    manifest["schema_version"] = 99
    path.write_bytes(encode_manifest(manifest))
    with pytest.raises(StoreError, match="schema version 99 is newer"):
        RunStore.open(tmp_path / "run")


# --- commits and reads -------------------------------------------------------------------------

def test_load_generation_round_trips_every_field(store: RunStore) -> None:
    store.commit(epoch(range(4)))
    reopened = RunStore.open(store.path)
    for island in (0, 1):
        for gen in range(4):
            assert reopened.load_generation(island, gen) == generation(island, gen)
    back = reopened.load_generation(1, 3)
    assert math.isinf(back[0].fitness) and back[0].text is None
    assert back[1].parents == ("1-2-1", "1-2-0")


def test_a_reader_finds_generations_committed_after_it_opened(store: RunStore) -> None:
    store.commit(epoch(range(2)))
    reader = RunStore.open(store.path)
    store.commit(epoch(range(2, 4)))
    assert reader.load_generation(1, 3) == generation(1, 3)
    assert reader.committed_generations() == {0: 3, 1: 3}
    store.commit(epoch(range(4, 5)))
    assert RunStore.open(store.path).verify() == []
    assert reader.verify() == []  # a newer intact manifest is not a problem


def test_an_old_snapshot_still_reads_after_its_files_were_compacted_away(tmp_path: Path) -> None:
    store = RunStore.create(tmp_path / "run", CONFIG, compact_every=None)
    for g in range(4):
        store.commit(epoch(range(g, g + 1)))
    reader = RunStore.open(store.path)
    store.compact(target_rows=1000)
    for g in range(4, 4 + KEEP_MANIFESTS):
        store.commit(epoch(range(g, g + 1)))
    store.collect_garbage()
    names = [p.name for p in (Path(store.path) / "_files" / "individuals").iterdir()]
    assert not [n for n in names if n.startswith("part-0000000002")]
    assert reader.load_generation(0, 1) == generation(0, 1)
    assert reader.individuals().num_rows == (4 + KEEP_MANIFESTS) * 10


def test_commits_must_follow_each_islands_last_generation(store: RunStore) -> None:
    store.commit(epoch(range(2)))
    with pytest.raises(StoreError, match=r"island 0: .*generations \[1\].*next one to commit is 2"):
        store.commit(generation(0, 1))
    with pytest.raises(StoreError, match=r"island 1: .*next one to commit is 2"):
        store.commit(generation(1, 3))
    with pytest.raises(StoreError, match="1-2-0 appears twice"):
        store.commit(generation(1, 2) + generation(1, 2)[:1])
    assert store.committed_generations() == {0: 1, 1: 1}
    store.commit(generation(0, 2))  # islands may move separately
    assert store.committed_generations() == {0: 2, 1: 1}
    with pytest.raises(StoreError, match=r"not committed.*last committed generation is 1"):
        store.load_generation(1, 2)


def test_individuals_projects_columns_and_filters_rows(store: RunStore) -> None:
    store.commit(epoch(range(3)))
    store.commit(epoch(range(3, 5)))
    table = store.individuals(columns=["id", "fitness"], filter=pc.field("generation") == 4)
    assert table.column_names == ["id", "fitness"]
    assert sorted(table.column("id").to_pylist()) == sorted(f"{i}-4-{k}" for i in (0, 1) for k in range(5))
    everything = store.individuals()
    assert everything.num_rows == 2 * 5 * 5
    assert everything.column("run_id").unique().to_pylist() == ["run"]
    with pytest.raises(StoreError, match="no column 'beauty'"):
        store.individuals(columns=["beauty"])


def test_dataset_is_queryable_by_duckdb(store: RunStore) -> None:
    store.commit(epoch(range(3)))
    individuals = store.dataset()  # noqa: F841  (DuckDB finds it by name)
    rows = duckdb.sql(
        "select generation, count(*), min(fitness) from individuals group by generation order by generation"
    ).fetchall()
    assert rows == [(0, 10, 1.0), (1, 10, 10.0), (2, 10, 20.0)]


def test_rows_written_by_commit_table_are_checked(store: RunStore) -> None:
    from genr8_dist.store.schema import individuals_table

    good = individuals_table(generation(0, 0), "run", store.criteria)
    with pytest.raises(StoreError, match="another run"):
        store.commit_table(individuals_table(generation(0, 0), "other", store.criteria))
    bad_id = good.set_column(1, "id", pa.array(["x"] * good.num_rows))
    with pytest.raises(StoreError, match="'id' must be"):
        store.commit_table(bad_id)
    with pytest.raises(StoreError, match="lacks column 'fitness'"):
        store.commit_table(good.drop_columns(["fitness"]))
    assert store.commit_table(good) == 2


# --- configurations and events -----------------------------------------------------------------

def test_config_versions_and_the_one_in_force(store: RunStore) -> None:
    store.commit(epoch(range(5)))
    with pytest.raises(StoreError, match=r"already committed.*generation 5 or later"):
        store.add_config(CONFIG, 4)
    assert store.add_config(CONFIG + "mutation = 0.2\n", 5) == 2
    assert store.add_config(CONFIG + "mutation = 0.3\n", 9, events=[Event("intervention", 9)]) == 3
    versions = RunStore.open(store.path).configs()
    assert [(v.version, v.effective_generation) for v in versions] == [(1, 0), (2, 5), (3, 9)]
    assert versions[2].toml.endswith("mutation = 0.3\n")
    assert store.config_for(0).version == 1
    assert store.config_for(4).version == 1
    assert store.config_for(5).version == 2
    assert store.config_for(8).version == 2
    assert store.config_for(100).version == 3
    assert store.events().column("kind").to_pylist() == ["intervention"]
    with pytest.raises(StoreError, match="before configuration version 3"):
        store.add_config(CONFIG, 7)
    with pytest.raises(ConfigError, match="configuration version 4: not valid TOML"):
        store.add_config("= 1", 12)
    assert named(Path(store.path) / "configs", "v0003").read_text().endswith("mutation = 0.3\n")


def test_events_are_numbered_in_order_with_their_details(store: RunStore) -> None:
    store.record_event("start", generation=0, detail={"islands": 2})
    store.commit(epoch(range(2)), [Event("migration", 1, detail={"moved": 4})])
    store.record_event("interrupt", generation=1, island=None, detail={"signal": "SIGTERM"})
    store.record_event("recovery", generation=1, island=1, detail={"actor": "lost"})
    events = RunStore.open(store.path).events()
    assert events.column_names == ["run_id", "seq", "kind", "generation", "island", "detail", "time"]
    assert events.column("seq").to_pylist() == [0, 1, 2, 3]
    assert events.column("kind").to_pylist() == ["start", "migration", "interrupt", "recovery"]
    assert events.column("island").to_pylist() == [None, None, None, 1]
    assert events.column("detail").to_pylist()[1] == '{"moved":4}'
    with pytest.raises(StoreError, match="'bogus'"):
        store.record_event("bogus", generation=0)


# --- atomicity ---------------------------------------------------------------------------------

def test_a_crash_between_data_and_manifest_leaves_nothing(
    store: RunStore, monkeypatch: pytest.MonkeyPatch
) -> None:
    store.commit(epoch(range(2)))

    def crash(self: RunFS, rel: str, data: bytes) -> None:
        raise OSError("power cut")

    monkeypatch.setattr(RunFS, "write_exclusive", crash)
    with pytest.raises(OSError, match="power cut"):
        store.commit(epoch(range(2, 4)), [Event("migration", 3)])
    monkeypatch.undo()
    data_files = os.listdir(Path(store.path) / "_files" / "individuals")
    assert len(data_files) == 1  # the failed commit removed the files it wrote, and only those
    assert os.listdir(Path(store.path) / "_files" / "events") == []
    # a crash (no chance to clean) leaves its files: not part of the run, removed by the next writer
    events = Path(store.path) / "_files" / "events"
    (events / "events-0000000003-0123456789abcdef.parquet").write_bytes(b"half")
    (events / ".tmp-events-0000000003-999999999-01234567").write_bytes(b"half")
    reopened = RunStore.open(store.path)
    assert reopened.committed_generations() == {0: 1, 1: 1}
    assert reopened.individuals().num_rows == 20
    assert reopened.events().num_rows == 0
    assert reopened.verify() == []
    reopened.commit(epoch(range(2, 4)))
    assert reopened.individuals().num_rows == 40
    assert reopened.collect_garbage() == 2  # the orphaned events file and the dead writer's temporary
    assert len(os.listdir(Path(store.path) / "_files" / "events")) == 0


CHILD = textwrap.dedent("""
    import sys
    from genr8_dist.evolution.individual import Individual
    from genr8_dist.store import Event, RunStore
    store = RunStore.open(sys.argv[1], compact_every=4)
    g = max(store.committed_generations().values(), default=-1) + 1
    while True:
        rows = [Individual(island=i, generation=g, index=k, genome=tuple(range(200)), origin="random",
                           fitness=float(g * 100 + k), text="x" * 500)
                for i in range(3) for k in range(60)]
        store.commit(rows, [Event("migration", g, detail={"g": g})])
        print(g, flush=True)
        g += 1
""")


@pytest.mark.slow
def test_sigkill_at_any_moment_leaves_whole_commits(tmp_path: Path) -> None:
    store = RunStore.create(tmp_path / "run", CONFIG)
    rng = stream(11, "test", "sigkill")
    for attempt in range(4):
        child = subprocess.Popen([sys.executable, "-c", CHILD, store.path], stdout=subprocess.PIPE,
                                 stderr=subprocess.PIPE, text=True)
        target = int(rng.integers(2, 9))
        for _ in range(target):
            assert child.stdout is not None
            if not child.stdout.readline():
                pytest.fail(f"writer died: {child.stderr.read() if child.stderr else ''}")
        time.sleep(float(rng.uniform(0.0, 0.03)))
        child.kill()
        child.wait()
        assert child.stdout is not None and child.stderr is not None
        child.stdout.close()
        child.stderr.close()
        reopened = RunStore.open(store.path)
        # a kill between a commit and its glob view leaves whole commits and a view one commit behind:
        # verify names only that, and repair publishes it
        problems = reopened.verify()
        assert all("a crash between a commit and its view" in p for p in problems), f"attempt {attempt}"
        if problems:
            reopened.repair()
            assert reopened.verify() == [], f"attempt {attempt}"
        done = reopened.committed_generations()
        assert set(done) == {0, 1, 2} and len(set(done.values())) == 1
        last = done[0]
        table = reopened.individuals(columns=["island", "generation", "fitness"])
        assert table.num_rows == 3 * 60 * (last + 1)
        counts = table.group_by(["island", "generation"]).aggregate([("fitness", "count")])
        assert set(counts.column("fitness_count").to_pylist()) == {60}
        events = reopened.events()
        assert events.column("generation").to_pylist() == list(range(last + 1))
        assert reopened.load_generation(2, last)[59].fitness == last * 100 + 59


# --- faults: detection and repair --------------------------------------------------------------

def test_a_truncated_file_is_named_and_repair_keeps_every_later_commit(store: RunStore) -> None:
    store.commit(epoch(range(3)), [Event("migration", 2)])
    store.commit(epoch(range(3, 6)), [Event("migration", 5)])
    store.commit(epoch(range(6, 9)), [Event("migration", 8)])
    victim = named(Path(store.path) / "_files" / "individuals", "part-0000000003")
    victim.write_bytes(victim.read_bytes()[:-100])
    reopened = RunStore.open(store.path)
    problems = reopened.verify()
    assert len(problems) == 1 and f"{victim.name}: truncated" in problems[0]
    for read in (reopened.individuals, reopened.dataset, lambda: reopened.load_generation(0, 4)):
        with pytest.raises(StoreError, match=re.escape(victim.name)):
            read()
    assert reopened.repair() == problems
    assert reopened.last_repair == (
        f"dropped _files/individuals/{victim.name} (30 individuals: islands 0-1, generations 3..5)")
    assert reopened.verify() == []
    assert reopened.committed_generations() == {0: 8, 1: 8}  # commit 4 (generations 6..8) is kept
    gens = sorted(set(reopened.individuals(columns=["generation"]).column(0).to_pylist()))
    assert gens == [0, 1, 2, 6, 7, 8]
    events = reopened.events()
    assert events.column("kind").to_pylist() == ["migration", "migration", "migration", "recovery"]
    assert victim.name in events.column("detail")[3].as_py()
    assert "dropped _files/individuals/" in events.column("detail")[3].as_py()
    # the run goes on after its last generation
    reopened.commit(epoch(range(9, 10)))
    assert RunStore.open(store.path).committed_generations() == {0: 9, 1: 9}
    assert reopened.load_generation(0, 9) == generation(0, 9)


def test_repair_of_the_newest_commit_drops_it_with_its_events(store: RunStore) -> None:
    store.commit(epoch(range(3)), [Event("migration", 2)])
    store.commit(epoch(range(3, 6)), [Event("migration", 5)])
    store.add_config(CONFIG + "x = 1\n", 6, events=[Event("intervention", 6)])
    named(Path(store.path) / "_files" / "individuals", "part-0000000003").unlink()
    assert store.repair()
    assert store.committed_generations() == {0: 2, 1: 2}
    assert [c.version for c in store.configs()] == [1, 2]  # the later edit is kept
    assert store.events().column("kind").to_pylist() == ["migration", "intervention", "recovery"]
    assert "events-0000000003" in store.last_repair


def test_a_damaged_configuration_is_restored_from_the_manifest(store: RunStore) -> None:
    store.commit(epoch(range(3)))
    store.add_config(CONFIG + "mutation = 0.2\n", 3)
    store.commit(epoch(range(3, 5)))
    for version in ("v0001", "v0002"):
        named(Path(store.path) / "configs", version).write_text("[run]\nseed = 999\n")
    reopened = RunStore.open(store.path)
    with pytest.raises(StoreError, match=r"v0002-[0-9a-f]+\.toml: truncated or altered"):
        reopened.config_for(4)
    assert len(reopened.repair()) == 2
    assert reopened.last_repair.startswith("dropped nothing; restored configuration version 1")
    assert reopened.committed_generations() == {0: 4, 1: 4}
    assert reopened.config_for(4).toml == CONFIG + "mutation = 0.2\n"
    assert RunStore.open(store.path).verify() == []


def test_a_flipped_byte_is_detected_by_its_checksum(store: RunStore) -> None:
    store.commit(epoch(range(2)))
    store.commit(epoch(range(2, 4)))
    victim = named(Path(store.path) / "_files" / "individuals", "part-0000000003")
    data = bytearray(victim.read_bytes())
    data[len(data) // 2] ^= 0xFF
    victim.write_bytes(bytes(data))
    problems = RunStore.open(store.path).verify()
    assert problems == [f"{victim}: corrupt: its sha256 differs from the one the manifest recorded"]


def test_a_dataset_of_some_generations_checks_only_the_files_it_reads(store: RunStore) -> None:
    store.commit(epoch(range(3)))
    store.commit(epoch(range(3, 6)))
    store.commit(epoch(range(6, 9)))
    victim = Path(store.path) / store.manifest["individuals"][0]["path"]   # generations 0..2
    data = bytearray(victim.read_bytes())
    data[len(data) // 2] ^= 0xFF
    victim.write_bytes(bytes(data))
    reader = RunStore.open(store.path)
    late = reader.dataset((4, 7)).to_table(columns=["generation"])
    assert sorted(set(late["generation"].to_pylist())) == [3, 4, 5, 6, 7, 8] and late.num_rows == 60
    for span in ((2, 4), None):   # any read that touches the damaged file is refused, naming it
        with pytest.raises(StoreError, match=re.escape(str(victim)) + ": corrupt"):
            reader.dataset() if span is None else reader.dataset(span)


def test_a_missing_individuals_file_is_named_by_every_reader(store: RunStore) -> None:
    store.commit(epoch(range(2)))
    store.commit(epoch(range(2, 4)))
    victim = named(Path(store.path) / "_files" / "individuals", "part-0000000003")
    victim.unlink()
    for read in (store.dataset, store.individuals, lambda: store.load_generation(1, 3)):
        with pytest.raises(StoreError, match=r"part-0000000003-[0-9a-f]+\.parquet: missing \(the manifest"):
            read()
    assert store.load_generation(1, 1) == generation(1, 1)  # the intact commit still reads


def test_a_missing_events_file_is_dropped_alone(store: RunStore) -> None:
    store.record_event("start", generation=0)
    store.commit(epoch(range(2)), [Event("migration", 1)])
    store.commit(epoch(range(2, 4)), [Event("migration", 3)])
    named(Path(store.path) / "_files" / "events", "events-0000000002").unlink()
    with pytest.raises(StoreError, match=r"events-0000000002-[0-9a-f]+.parquet: missing"):
        store.events()
    store.repair()
    assert store.committed_generations() == {0: 3, 1: 3}
    assert store.events().column("kind").to_pylist() == ["migration", "migration", "recovery"]
    assert "1 event(s), seq 0..0" in store.last_repair


def test_repair_of_a_corrupt_compacted_file_uses_the_files_before_compaction(store: RunStore) -> None:
    for g in range(6):
        store.commit(epoch(range(g, g + 1)))
    assert store.compact(target_rows=1000) == 5
    (merged,) = store.individual_files()
    Path(merged).write_bytes(b"garbage")
    assert store.repair()
    assert store.committed_generations() == {0: 5, 1: 5}  # nothing lost: the small files were kept
    assert store.individuals().num_rows == 60
    assert store.verify() == []


def test_a_torn_newest_manifest_is_named_by_readers_and_repaired(store: RunStore) -> None:
    store.commit(epoch(range(2)))
    torn = Path(store.path) / "_manifest" / "0000000003.json"
    torn.write_text('{"format": "genr8-run", "vers')
    reopened = RunStore.open(store.path)
    assert reopened.version == 2
    expected = f"{torn}: the newest manifest is torn or altered; the run would read as commit 2"
    assert reopened.verify() == [expected]
    with pytest.raises(StoreError, match="newest manifest is torn"):
        reopened.individuals()
    with pytest.raises(StoreError, match="repair the run before writing"):
        reopened.commit(epoch(range(2, 3)))
    reopened.repair()
    assert not torn.exists()
    assert reopened.verify() == []
    reopened.commit(epoch(range(2, 3)))
    assert reopened.committed_generations() == {0: 2, 1: 2}


def test_the_loss_of_the_newest_manifest_is_seen(store: RunStore) -> None:
    store.commit(epoch(range(2)))
    store.commit(epoch(range(2, 4)))
    (Path(store.path) / "_manifest" / "0000000003.json").unlink()
    reopened = RunStore.open(store.path)
    (problem,) = reopened.verify()
    assert "0000000003.json: the newest manifest (commit 3, recorded in _manifest/HEAD) is missing" in problem
    with pytest.raises(StoreError, match=r"newest manifest .* is missing"):
        reopened.events()
    reopened.repair()
    assert "commit 3's manifest" in reopened.last_repair
    assert reopened.committed_generations() == {0: 1, 1: 1}
    assert RunStore.open(store.path).verify() == []


def test_damage_to_an_older_manifest_is_reported(store: RunStore) -> None:
    store.commit(epoch(range(2)))
    store.commit(epoch(range(2, 4)))
    older = Path(store.path) / "_manifest" / "0000000002.json"
    older.write_text("{}")
    (problem,) = RunStore.open(store.path).verify()
    assert problem.startswith(f"{older}: an older manifest is torn or altered")
    assert RunStore.open(store.path).individuals().num_rows == 40  # the run itself is intact


def test_a_manifest_naming_a_file_outside_the_run_is_not_followed(store: RunStore, tmp_path: Path) -> None:
    import json

    from genr8_dist.store.manifest import encode_manifest

    store.commit(epoch(range(2)))
    outside = tmp_path / "secret.parquet"
    outside.write_bytes(b"x")
    path = Path(store.path) / "_manifest" / "0000000002.json"
    for evil in ("../secret.parquet", str(outside), "individuals/../../secret.parquet"):
        manifest = json.loads(path.read_text())
        manifest["individuals"][0]["path"] = evil
        newest = Path(store.path) / "_manifest" / "0000000003.json"
        newest.write_bytes(encode_manifest(dict(manifest, version=3)))
        with pytest.raises(StoreError, match=r"0000000003\.json: the newest manifest is torn or altered"):
            RunStore.open(store.path).individuals()


def test_two_writers_cannot_both_commit(store: RunStore) -> None:
    other = RunStore.open(store.path)
    store.commit(epoch(range(1)))
    with pytest.raises(StoreError, match="another process committed"):
        other.commit(epoch(range(1)))
    assert RunStore.open(store.path).individuals().num_rows == 10


# --- compaction --------------------------------------------------------------------------------

def test_compaction_keeps_rows_identical_and_reduces_files(tmp_path: Path) -> None:
    store = RunStore.create(tmp_path / "run", CONFIG, compact_every=None)
    for g in range(12):
        store.commit(epoch(range(g, g + 1)), [Event("migration", g)])
    before = store.individuals()
    events_before = store.events().drop_columns(["time"])
    reader = RunStore.open(store.path)  # holds the old snapshot
    assert store.compact(target_rows=40) == 12 * 2 - 3 - 1
    assert len(store.individual_files()) == 3
    assert store.individuals().equals(before)
    assert store.events().drop_columns(["time"]).equals(events_before)
    assert reader.individuals().equals(before)  # old files are kept for readers of older snapshots
    assert store.load_generation(1, 7) == generation(1, 7)
    assert store.compact(target_rows=40) == 0  # nothing left to merge
    assert RunStore.open(store.path).verify() == []


def test_commits_compact_by_themselves_and_old_files_go(tmp_path: Path) -> None:
    store = RunStore.create(tmp_path / "run", CONFIG, compact_every=4)
    for g in range(3 * KEEP_MANIFESTS):
        store.commit(epoch(range(g, g + 1)))
    assert len(store.individual_files()) < 4
    assert len(os.listdir(Path(store.path) / "_manifest")) <= KEEP_MANIFESTS + 1  # and HEAD
    on_disk = len(os.listdir(Path(store.path) / "_files" / "individuals"))
    assert on_disk <= len(store.individual_files()) + 4 * 4
    assert store.individuals().num_rows == 3 * KEEP_MANIFESTS * 10


# --- filesystems -------------------------------------------------------------------------------

def test_a_file_uri_works(tmp_path: Path) -> None:
    uri = (tmp_path / "run").as_uri()
    store = RunStore.create(uri, CONFIG)
    store.commit(epoch(range(2)))
    reopened = RunStore.open(uri)
    assert reopened.path == str(tmp_path / "run")
    assert reopened.load_generation(1, 1) == generation(1, 1)


@pytest.mark.parametrize("kind", ["subtree", "mock"])
def test_other_pyarrow_filesystems_work(tmp_path: Path, kind: str) -> None:
    if kind == "subtree":
        (tmp_path / "base").mkdir()
        fs = pafs.SubTreeFileSystem(str(tmp_path / "base"), pafs.LocalFileSystem())
    else:
        fs = pafs._MockFileSystem()
    store = RunStore.create("runs/exp", CONFIG, filesystem=fs)
    store.commit(epoch(range(2)), [Event("migration", 1)])
    store.commit(epoch(range(2, 4)))
    store.add_config(CONFIG + "x = 1\n", 4)
    assert store.compact(target_rows=1000) == 1
    reopened = RunStore.open("runs/exp", filesystem=fs)
    assert reopened.committed_generations() == {0: 3, 1: 3}
    assert reopened.load_generation(0, 3) == generation(0, 3)
    assert reopened.config_for(4).version == 2
    assert reopened.events().num_rows == 1
    assert reopened.verify() == []
    with pytest.raises(StoreError, match="already holds run"):
        RunStore.create("runs/exp", CONFIG, filesystem=fs)


def test_manifests_are_published_where_hard_links_are_not_supported(
    store: RunStore, monkeypatch: pytest.MonkeyPatch
) -> None:
    def no_links(src: str, dst: str) -> None:
        raise PermissionError(1, "Operation not permitted")

    monkeypatch.setattr(os, "link", no_links)
    store.commit(epoch(range(2)))
    other = RunStore.open(store.path)
    store.commit(epoch(range(2, 3)))
    with pytest.raises(StoreError, match="another process committed"):
        other.commit(epoch(range(2, 3)))
    monkeypatch.undo()
    assert RunStore.open(store.path).committed_generations() == {0: 2, 1: 2}
    assert not [n for n in os.listdir(Path(store.path) / "_manifest") if n.startswith(".tmp")]


# --- creation that stopped half-way, a full disk -------------------------------------------------

def test_a_half_created_run_is_named_and_a_new_run_finishes_it(tmp_path: Path) -> None:
    from genr8_dist.distributed.session import _check_new_run_dir

    half = tmp_path / "half"
    for folder in ("_manifest", "configs", "individuals", "events"):
        (half / folder).mkdir(parents=True)
    (half / "configs" / ".tmp-v0001.toml-4242-0badf00d").write_bytes(b"[run")  # killed while writing
    with pytest.raises(StoreError, match=r"half: a run whose creation did not finish .*genr8 run CONFIG"):
        RunStore.open(half)
    _check_new_run_dir(str(half))  # `genr8 run` accepts it ...
    store = RunStore.create(half, CONFIG)  # ... and finishes it
    assert store.verify() == [] and RunStore.open(half).configs()[0].toml == CONFIG
    with pytest.raises(StoreError, match="already holds a run"):
        _check_new_run_dir(str(half))


def test_a_full_disk_names_the_file_and_leaves_the_run_whole(
    store: RunStore, monkeypatch: pytest.MonkeyPatch
) -> None:
    import errno

    store.commit(epoch(range(2)))
    real_write = os.write

    def full(fd: int, data: object) -> int:
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(os, "write", full)
    with pytest.raises(OSError) as caught:
        store.commit(epoch(range(2, 4)))
    monkeypatch.setattr(os, "write", real_write)
    assert caught.value.errno == errno.ENOSPC
    part = Path(store.path) / "_files" / "individuals" / "part-0000000003-"
    assert caught.value.filename.startswith(str(part))
    assert RunStore.open(store.path).verify() == []
    assert RunStore.open(store.path).committed_generations() == {0: 1, 1: 1}
    assert not [p for p in Path(store.path).rglob("*") if p.name.startswith((".tmp-", "part-0000000003"))]


def test_garbage_collection_sets_users_files_aside_and_deletes_only_its_own(store: RunStore) -> None:
    store.commit(epoch(range(2)))
    root = Path(store.path)
    (root / "configs" / "notes.txt").write_text("my notes")
    (root / "individuals" / "mine.parquet").write_bytes(b"a user's table")
    orphan = root / "individuals" / "part-0000000009-0123456789abcdef.parquet"
    orphan.write_bytes(b"a crashed writer's part")
    reopened = RunStore.open(store.path)
    assert reopened.collect_garbage() == 1          # the orphan, the store's own name
    assert not orphan.exists()
    assert sorted(reopened.set_aside) == [("configs/notes.txt", "_foreign/configs/notes.txt"),
                                          ("individuals/mine.parquet", "_foreign/individuals/mine.parquet")]
    assert (root / "_foreign" / "configs" / "notes.txt").read_text() == "my notes"
    assert (root / "_foreign" / "individuals" / "mine.parquet").read_bytes() == b"a user's table"
    assert not (root / "configs" / "notes.txt").exists()
    (root / "configs" / "notes.txt").write_text("again")        # a second one keeps the first
    again = RunStore.open(store.path)
    again.collect_garbage()
    assert again.set_aside == [("configs/notes.txt", "_foreign/configs/notes.txt.1")]
    assert again.verify() == [] and again.individuals().num_rows == 20
    from genr8_dist.store.foreign import describe

    assert describe(again.set_aside, "runs/r") == ("runs/r: set aside 1 file(s) the run did not write "
                                                   "(configs/notes.txt) in runs/r/_foreign/")


def test_verify_reports_a_deleted_older_manifest_and_repair_mends_it(store: RunStore) -> None:
    for g in range(4):
        store.commit(epoch(range(g, g + 1)))
    root = Path(store.path) / "_manifest"
    newest = RunStore.open(store.path).version
    (root / f"{newest - 2:010d}.json").unlink()
    reopened = RunStore.open(store.path)
    assert reopened.version == newest
    assert reopened.verify() == [f"{reopened._fs.show(f'_manifest/{newest - 2:010d}.json')}: an older "
                                 "manifest is missing (deleted by hand?); repair drops the snapshots older "
                                 "than it"]
    rows = reopened.individuals().num_rows
    reopened.repair()
    assert reopened.verify() == [] and reopened.individuals().num_rows == rows


@pytest.mark.parametrize("head", [b"", b"1", b"12", b"x\n"])
def test_verify_reports_a_truncated_head_even_when_it_still_reads_as_a_number(store: RunStore, head) -> None:
    for g in range(3):
        store.commit(epoch(range(g, g + 1)))
    path = Path(store.path) / "_manifest" / "HEAD"
    assert path.read_bytes() == f"{store.version}\n".encode()
    path.write_bytes(head)
    reopened = RunStore.open(store.path)
    problems = reopened.verify()
    assert any(p.endswith("_manifest/HEAD: damaged (it should hold the newest commit's number)")
               for p in problems), problems
    reopened.repair()
    assert reopened.verify() == []


def test_a_new_run_records_its_screen_and_a_configuration_naming_one_keeps_it(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A new run records the screen before growth it uses (``ea.screen``); its configurations use it
    unless they name one, and a run created under an older screen keeps it once a newer one is the
    default (a run created before it was recorded reads 1: tests/store/test_old_schema_store)."""
    from genr8_dist import config as config_module
    from genr8_dist.config import SCREEN

    text = "seed = 3\n[ea]\npopulation = 4\n"
    store = RunStore.create(tmp_path / "new", text)
    assert store.screen == SCREEN == 3 and store.config(1).ea.screen == SCREEN
    with monkeypatch.context() as patch:   # a run created when screen 2 was the newest
        patch.setattr(config_module, "SCREEN", 2)
        RunStore.create(tmp_path / "older", text)
    older = RunStore.open(tmp_path / "older")
    assert older.screen == 2 and older.config(1).ea.screen == 2
    named = RunStore.create(tmp_path / "named", text + "screen = 1\n")
    assert named.screen == 1 and named.config(1).ea.screen == 1
