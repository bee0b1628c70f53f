"""The coordinator on a real local Ray: complete runs, interruption and resumption, lost actors, edits,
damaged files. Every comparison is row for row over every column except timings."""

from __future__ import annotations

import collections
import json
import math
import time

import pytest
from distributed_runs import drive_to_end, event_kinds, new_run, rows, stop_at, tiny_toml

pytestmark = pytest.mark.usefixtures("ray_local")


@pytest.fixture(scope="module")
def pool(tmp_path_factory, ray_local):
    """Island hosts shared by this module's runs (rebound to each run; the CLI tests start their own)."""
    from genr8_dist.distributed.hosts import HostPool

    hosts = HostPool(str(tmp_path_factory.mktemp("unbound")), 3)
    yield hosts
    hosts.shutdown()


@pytest.fixture(scope="module")
def reference(tmp_path_factory, pool):
    """The uninterrupted 3-island run every other run is compared with."""
    run_dir = tmp_path_factory.mktemp("ref") / "run"
    new_run(run_dir, tiny_toml())
    summary, log = drive_to_end(run_dir, pool)
    return run_dir, summary, log


def test_an_idle_host_helps_the_busy_one_and_no_row_changes(pool, tmp_path, request):
    # 3 islands on 2 hosts: the host of one island is idle while the other advances two. This test
    # runs first in the module: after another run of the same texts the hosts' evaluation caches would
    # answer every genome at once and leave nothing to help with.
    run_dir = tmp_path / "run"
    new_run(run_dir, tiny_toml())
    before = pool.helped()
    summary, _ = drive_to_end(run_dir, pool)
    assert summary.status == "complete"
    assert pool.helped() > before
    assert rows(run_dir) == rows(request.getfixturevalue("reference")[0])


def test_three_islands_with_migration_complete_with_every_row(reference):
    run_dir, summary, log = reference
    got = rows(run_dir)
    assert summary.status == "complete"
    assert len(got) == 3 * 6 * 7                       # islands x population x generations 0..6
    assert {(r["island"], r["generation"]) for r in got} == {(i, g) for i in range(3) for g in range(7)}
    assert all(r["id"] == f"{r['island']}-{r['generation']}-{r['index']}" for r in got)
    # migration after generations 2 and 4: one migrant arrives at 3 and 5 from the previous island
    migrants = [r for r in got if r["origin"] == "migrant"]
    assert sorted({r["generation"] for r in migrants}) == [3, 5]
    for r in migrants:
        (parent,) = r["parents"]
        source_island, source_gen, _ = (int(x) for x in parent.split("-"))
        assert (source_island + 1) % 3 == r["island"] and source_gen == r["generation"] - 1
    kinds = event_kinds(run_dir)
    assert kinds.count("migration") == 2 and kinds[-1] == "complete"
    assert "gen 6/6" in log and "ind/s" in log


# A call asks for an island's generations to its epoch's end (0..2, 3..4, 5..6): a stop when every
# island has completed 5 finds 6, the run's last, complete too, so the last stop point is 4.
@pytest.mark.parametrize("at", [0, 1, 3, 4])
def test_interrupted_and_resumed_equals_uninterrupted(reference, pool, tmp_path, at):
    run_dir = tmp_path / "run"
    new_run(run_dir, tiny_toml())
    first, _ = drive_to_end(run_dir, pool, on_generation=stop_at(at))
    assert first.status == "interrupted"
    assert min(first.committed.values()) >= at
    assert "interrupt" in event_kinds(run_dir)
    second, _ = drive_to_end(run_dir, pool)
    assert second.status == "complete"
    assert rows(run_dir) == rows(reference[0])


def test_killed_island_actor_is_rebuilt_and_the_rows_are_the_same(reference, pool, tmp_path):
    import ray

    run_dir = tmp_path / "run"
    new_run(run_dir, tiny_toml())
    killed = []

    def kill_island_1(coordinator, g):
        if g == 3 and not killed:
            killed.append(g)
            ray.kill(coordinator.hosts.host_of(1), no_restart=True)

    summary, log = drive_to_end(run_dir, pool, on_generation=kill_island_1)
    assert killed and summary.status == "complete"
    assert summary.recoveries >= 1
    assert "recovery" in event_kinds(run_dir)
    assert "rebuilt from generation" in log
    assert rows(run_dir) == rows(reference[0])


def test_edit_takes_effect_from_its_generation_only(reference, pool, tmp_path):
    from genr8_dist.distributed.intervene import Edit, apply_edit
    from genr8_dist.fitness import FitnessSpec
    from genr8_dist.store import RunStore

    run_dir = tmp_path / "run"
    new_run(run_dir, tiny_toml())
    drive_to_end(run_dir, pool, on_generation=stop_at(2))
    done = max(RunStore.open(run_dir).committed_generations().values())
    edit = Edit(assignments=["fitness.size.weight=5", "fitness.weights.symmetry=0"], inject_copy=["1-1-0"])
    result = apply_edit(str(run_dir), edit)
    assert result.effective_generation == done + 1 and result.version == 2
    drive_to_end(run_dir, pool)

    got, ref = rows(run_dir), rows(reference[0])
    assert [r for r in got if r["generation"] <= done] == [r for r in ref if r["generation"] <= done]
    after = [r for r in got if r["generation"] > done]
    assert after and all(r["config_version"] == 2 for r in after)
    spec = FitnessSpec.from_dict({"size": {"weight": 5}, "symmetry": {"weight": 0}})
    valid = [r for r in after if r["valid"]]
    assert valid
    for r in valid:
        raw = {k[len("crit_"):]: v for k, v in r.items() if k.startswith("crit_") and v is not None}
        assert math.isclose(r["fitness"], spec.evaluate(raw), rel_tol=1e-12, abs_tol=1e-12)
    injected = [r for r in got if r["origin"] == "injected"]
    assert len(injected) == 1
    (inj,) = injected
    source = next(r for r in got if r["id"] == "1-1-0")
    assert (inj["island"], inj["generation"], inj["genome"], inj["parents"]) == (
        1, done + 1, source["genome"], ["1-1-0"])
    events = RunStore.open(run_dir).events().to_pylist()
    (intervention,) = [e for e in events if e["kind"] == "intervention"]
    assert intervention["generation"] == done + 1
    assert json.loads(intervention["detail"])["changes"]["fitness.size.weight"] == 5


def test_truncated_parquet_is_named_and_the_run_resumes_from_the_last_intact_generation(
        reference, pool, tmp_path):
    from genr8_dist.store import RunStore

    run_dir = tmp_path / "run"
    new_run(run_dir, tiny_toml())
    drive_to_end(run_dir, pool, on_generation=stop_at(4))
    store = RunStore.open(run_dir)
    newest = store.individual_files()[-1]
    with open(newest, "r+b") as f:
        f.truncate(f.seek(0, 2) // 2)
    problems = RunStore.open(run_dir).verify()
    assert problems and any(newest.rsplit("/", 1)[-1] in p for p in problems)
    summary, log = drive_to_end_after_repair(run_dir, pool)
    assert "damaged:" in log and newest.rsplit("/", 1)[-1] in log
    assert summary.status == "complete"
    assert rows(run_dir) == rows(reference[0])


def test_a_damaged_configuration_version_is_restored_not_dropped(reference, pool, tmp_path):
    """A corrupt configs/v0002-*.toml (an edit's) is reported and rewritten from the manifest's copy on
    resume: the edit is kept, and the run completes under it."""
    from genr8_dist.distributed.intervene import Edit, apply_edit
    from genr8_dist.store import RunStore

    run_dir = tmp_path / "run"
    new_run(run_dir, tiny_toml())
    drive_to_end(run_dir, pool, on_generation=stop_at(2))
    apply_edit(str(run_dir), Edit(assignments=["fitness.size.weight=5"]))
    edited = RunStore.open(run_dir).configs()[1].toml
    (version2,) = [p for p in (run_dir / "configs").iterdir() if p.name.startswith("v0002")]
    version2.write_text("[ea\npopulation = ")
    summary, log = drive_to_end_after_repair(run_dir, pool)
    assert "damaged:" in log and version2.name in log
    assert "restored configuration version 2" in log
    assert summary.status == "complete"
    store = RunStore.open(run_dir)
    assert [c.version for c in store.configs()] == [1, 2]
    assert store.configs()[1].toml == edited
    assert store.verify() == []


def drive_to_end_after_repair(run_dir, pool):
    """What ``genr8 resume`` does: report damage, repair, go on."""
    import io

    from genr8_dist.distributed.session import RunOptions, resume_run

    out = io.StringIO()
    summary = resume_run(str(run_dir), RunOptions(quiet=True), out=out, hosts=pool)
    return summary, out.getvalue()


def test_a_run_that_cannot_be_scheduled_is_refused(pool, tmp_path):
    """With every CPU of the session's Ray held by hosts, another run is refused, not left waiting."""
    import ray

    from genr8_dist.distributed.hosts import HostPool
    from genr8_dist.errors import RunError

    free = int(ray.available_resources().get("CPU", 0))
    blocker = HostPool(str(tmp_path / "blocker"), free) if free >= 1 else None
    try:
        with pytest.raises(RunError, match="no free CPU"):
            HostPool(str(tmp_path / "run"), 2, settle=0.5)
    finally:
        if blocker is not None:
            blocker.shutdown()
    assert not (tmp_path / "run").exists()


def test_edits_queued_while_the_run_runs_equal_the_same_edit_of_a_stopped_run(reference, pool, tmp_path):
    """A live run takes a queued edit (favour, hand fitness, a weight) without stopping, from the first
    generation no island has started (islands run up to an epoch ahead of the oldest uncommitted one,
    so which one that is depends on timing: the event says); the rows equal a run edited from that
    generation while stopped. A queued pause holds the run at the end of the epoch under way until a
    continue, and changes no row."""
    import re
    import threading

    from genr8_dist.distributed.intervene import Edit, apply_edit, record_edit
    from genr8_dist.store import RunStore

    edit = Edit(assignments=["fitness.size.weight=5"], favour=["0-2-1"], hand_fitness=[("1-2-3", 0.0)])
    toml = tiny_toml(generations=10)   # room after the edit: an island's call runs on until it is cut
    live = tmp_path / "live"
    new_run(live, toml)
    lock = RunStore.open(live).lock("run")      # what `genr8 run` holds while it runs
    assert lock.acquire()
    queued = []

    def steer(coordinator, generation):
        if generation == 3 and not queued:
            queued.append(apply_edit(str(live), edit, source="studio"))
            apply_edit_pause = RunStore.open(live)
            apply_edit_pause.enqueue({"kind": "pause"})
            threading.Timer(1.0, lambda: RunStore.open(live).enqueue({"kind": "continue"})).start()

    try:
        summary, log = drive_to_end(live, pool, on_generation=steer)
    finally:
        lock.release()
    assert summary.status == "complete" and queued[0].queued
    events = RunStore.open(live).events().to_pylist()
    kinds = [e["kind"] for e in events]
    assert kinds.index("intervention") < kinds.index("pause") < kinds.index("continue")
    (intervention,) = [e for e in events if e["kind"] == "intervention"]
    start = intervention["generation"]
    assert 5 <= start <= 9                      # islands had started 4 (and maybe more) when it was taken
    (paused,) = re.findall(r"paused before generation (\d+)", log)
    assert int(paused) % 2 == 1 and int(paused) in (start, start + 1)   # the end of the epoch under way
    assert f"continuing before generation {paused}" in log
    detail = json.loads(intervention["detail"])
    assert detail["source"] == "studio"
    assert [h["id"] for h in detail["hand_fitness"]] == ["1-2-3"]
    got = rows(live)
    assert [r["parents"] for r in got if r["origin"] == "injected"] == [["0-2-1"]]
    assert ["1-2-3"] in [r["parents"] for r in got if r["origin"] == "elite" and r["island"] == 1
                         and r["generation"] == start]

    stopped = tmp_path / "stopped"
    new_run(stopped, toml)
    drive_to_end(stopped, pool, on_generation=stop_at(2))
    assert max(RunStore.open(stopped).committed_generations().values()) < start
    record_edit(RunStore.open(stopped), edit, effective=start)
    drive_to_end(stopped, pool)
    assert rows(stopped) == got
    ref = rows(reference[0])
    assert [r for r in got if r["generation"] < min(start, 7)] == [r for r in ref if r["generation"] < start]


@pytest.mark.parametrize("search", [
    '[search]\nmode = "map-elites"\ndescriptors = ["undulation", "size_regions"]\n'
    'ranges = [[0.0, 1.5], [1.0, 9.0]]\nbins = [3, 4]\n',
    '[search]\nmode = "pareto"\n',
])
def test_a_search_mode_run_resumed_equals_the_uninterrupted_one_archive_included(pool, tmp_path, search):
    """The MAP-Elites archive travels in the rows (each generation starts with every held cell's
    elite, more of them than the population holds), so a killed and resumed run has the same archive,
    row for row; likewise Pareto ranks."""
    toml = tiny_toml(islands=2, generations=5) + search
    whole = tmp_path / "whole"
    new_run(whole, toml)
    assert drive_to_end(whole, pool)[0].status == "complete"
    cut = tmp_path / "cut"
    new_run(cut, toml)
    assert drive_to_end(cut, pool, on_generation=stop_at(2))[0].status == "interrupted"
    assert drive_to_end(cut, pool)[0].status == "complete"
    assert rows(cut) == rows(whole)
    if "map-elites" in search:
        assert any(r["cell"] is not None for r in rows(whole))
        assert any(r["origin"] == "elite" for r in rows(whole) if r["generation"] > 0)
        sizes = collections.Counter((r["island"], r["generation"]) for r in rows(whole))
        assert max(sizes.values()) > 6   # the archive outgrew the population of 6
    assert all(r["pareto_rank"] is not None for r in rows(whole))


@pytest.mark.parametrize("calls", ["a generation each", "the epoch each"])
def test_an_edit_queued_before_the_first_commit_takes_effect_at_once(pool, tmp_path, monkeypatch, calls):
    """Edits made before anything is committed are queued, not refused: one queued before the first
    epoch starts is in force from generation 0; one queued while the islands run (nothing committed
    yet) is taken inside the epoch under way, from the first generation no island had started, not at
    the epoch's end. The rows equal those of a run whose edits were recorded at those generations
    before it started. So whether the hosts answer each generation or are asked for the whole epoch
    in one call (then the driver finds the request while the calls run, asks them to answer after the
    generation under way, and takes it once they have)."""
    import threading

    from genr8_dist.distributed import coordinator as coordinator_module
    from genr8_dist.distributed.intervene import Edit, apply_edit, record_edit
    from genr8_dist.store import RunStore

    each = calls == "a generation each"
    last = 12 if each else 40
    monkeypatch.setattr(coordinator_module, "ANSWERS_PER_SECOND", 1e9 if each else 1e-9)
    toml = tiny_toml(generations=last).replace("migration_interval = 2", f"migration_interval = {last}")
    at_once = Edit(assignments=["fitness.size.weight=3"])
    later = Edit(assignments=["fitness.size.weight=5"])
    live = tmp_path / "live"
    new_run(live, toml)
    lock = RunStore.open(live).lock("run")
    assert lock.acquire()
    queued = [apply_edit(str(live), at_once)]

    def steer(coordinator, generation):
        if generation == 0 and len(queued) == 1:
            assert RunStore.open(live).committed_generations() == {}
            queued.append(apply_edit(str(live), later, source="studio"))

    def watch():   # the islands' calls run to the epoch's end: queue once the live view shows generation 2
        view = RunStore.open(live).live()
        while len(queued) == 1:
            if 2 in view.read():
                queued.append(apply_edit(str(live), later, source="studio"))
            time.sleep(0.005)

    watcher = threading.Thread(target=watch, daemon=True)
    try:
        if each:
            summary, log = drive_to_end(live, pool, on_generation=steer)
        else:
            watcher.start()
            summary, log = drive_to_end(live, pool)
    finally:
        lock.release()
    assert summary.status == "complete" and len(queued) == 2 and all(q.queued for q in queued)
    store = RunStore.open(live)
    starts = [e["generation"] for e in store.events().to_pylist() if e["kind"] == "intervention"]
    assert starts[0] == 0 and 1 <= starts[1] < last
    assert f"configuration version 3 in force from generation {starts[1]}" in log
    got = rows(live)
    assert {r["config_version"] for r in got if r["generation"] < starts[1]} == {2}
    assert {r["config_version"] for r in got if r["generation"] >= starts[1]} == {3}

    recorded = tmp_path / "recorded"
    new_run(recorded, toml)
    record_edit(RunStore.open(recorded), at_once, effective=0)
    record_edit(RunStore.open(recorded), later, source="studio", effective=starts[1])
    drive_to_end(recorded, pool)
    assert rows(recorded) == got


class _Crash(BaseException):
    """A driver dying (not a stop: nothing more is committed)."""


def test_a_crash_while_an_epoch_commits_and_the_next_runs_leaves_whole_epochs(reference, pool, tmp_path,
                                                                              monkeypatch):
    """The commit of epoch 0..2 is slow; islands go on with generations 3 and 4 meanwhile (what the
    hook sees), and the driver dies there. The store holds whole epochs only, and the resumed run
    equals the uninterrupted one row for row."""
    import time

    from genr8_dist.store import RunStore

    commit_parts = RunStore.commit_parts
    threads = []

    def slow_commit(self, parts, events=(), **kw):
        import threading

        threads.append(threading.current_thread().name)
        time.sleep(2.0)
        return commit_parts(self, parts, events, **kw)

    monkeypatch.setattr(RunStore, "commit_parts", slow_commit)
    seen = []

    def crash(coordinator, island, generation, done):
        pipeline = coordinator._now
        if pipeline is not None and pipeline.inflight is not None and generation > 2:
            seen.append((island, generation))
            raise _Crash

    run_dir = tmp_path / "run"
    new_run(run_dir, tiny_toml())
    with pytest.raises(_Crash):
        drive_to_end(run_dir, pool, on_island=crash)
    monkeypatch.setattr(RunStore, "commit_parts", commit_parts)
    assert seen and threads and threads[0].startswith("genr8-commit")
    committed = RunStore.open(run_dir).committed_generations()
    assert committed == {0: 2, 1: 2, 2: 2}      # epoch 0..2, whole; nothing of 3 or 4
    summary, _ = drive_to_end(run_dir, pool)
    assert summary.status == "complete"
    assert rows(run_dir) == rows(reference[0])



def test_the_driver_keeps_no_history_that_grows_with_the_run(pool, tmp_path):
    """What the coordinator holds between commits (uncommitted generations, migrants, events,
    emigrant candidates, offers of help, migrations recorded) is the same size at the sixth commit as
    at the second: nothing accumulates with the run's length."""
    toml = tiny_toml(generations=12)
    run_dir = tmp_path / "run"
    new_run(run_dir, toml)
    sizes = []

    def measure(coordinator, after):
        pipeline = coordinator._now
        sizes.append((sum(len(r) for r in pipeline.results.values()), len(pipeline.migrants_after),
                      sum(len(e) for e in pipeline.events.values()), len(coordinator._candidates),
                      len(pipeline.offers) // 65, len(coordinator._migrated)))

    summary, _ = drive_to_end(run_dir, pool, on_commit=measure)
    assert summary.status == "complete" and len(sizes) >= 6
    peak = [max(column) for column in zip(*sizes[1:], strict=True)]
    # at most two epochs of 3 islands x 2 generations, two migrations' worth of the rest
    assert all(x <= y for x, y in zip(peak, (3 * 2 * 2, 2, 2, 2, 0, 2), strict=True)), sizes
