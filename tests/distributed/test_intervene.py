"""`genr8 edit` without Ray: what an edit records, and edits refused with the run directory unchanged."""

from __future__ import annotations

import hashlib
import json

import pytest
from distributed_runs import new_run, tiny_toml

from genr8_dist.distributed.coordinator import parse_config
from genr8_dist.distributed.intervene import Edit, apply_edit, parse_assignment
from genr8_dist.errors import ConfigError, Genr8Error, StoreError
from genr8_dist.evolution.island import Island
from genr8_dist.store import RunStore


def _snapshot(root):
    return {str(p.relative_to(root)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(root.rglob("*")) if p.is_file() and p.name != "_running.lock"}


@pytest.fixture
def run_dir(tmp_path):
    """A 2-island run with generation 0 committed (made by the islands themselves, without Ray)."""
    path = tmp_path / "run"
    store = new_run(path, tiny_toml(islands=2))
    config = parse_config(tiny_toml(islands=2), "tiny")
    store.commit([ind for i in range(2) for ind in Island(config, i).initial()])
    return path


def test_parse_assignment():
    assert parse_assignment("fitness.size.weight=2") == (("fitness", "size", "weight"), 2)
    assert parse_assignment("fitness.weights.size=2.5") == (("fitness", "size", "weight"), 2.5)
    assert parse_assignment("fitness.targets.symmetry=1") == (("fitness", "symmetry", "target"), 1)
    assert parse_assignment("islands.topology=random") == (("islands", "topology"), "random")
    assert parse_assignment("environment.scale=[1, 1, 2]") == (("environment", "scale"), [1, 1, 2])
    with pytest.raises(ConfigError, match="KEY=VALUE"):
        parse_assignment("ea.mutation_rate")


def test_an_edit_is_a_new_version_from_the_next_generation(run_dir):
    result = apply_edit(str(run_dir), Edit(assignments=["ea.mutation_rate=0.1"], generations=3,
                                           inject_copy=["1-0-2"]))
    assert (result.version, result.effective_generation, result.last_generation) == (2, 1, 3)
    store = RunStore.open(run_dir)
    version = store.config_for(1)
    assert version.version == 2 and store.config_for(0).version == 1
    config = parse_config(version.toml, "v2")
    assert config.ea.mutation_rate == 0.1 and config.ea.generations == 3
    (event,) = [e for e in store.events().to_pylist() if e["kind"] == "intervention"]
    detail = json.loads(event["detail"])
    assert event["generation"] == 1 and detail["config_version"] == 2
    (item,) = detail["injected"]
    source = store.load_generation(1, 0)[2]
    assert item == {"island": 1, "genome": list(source.genome), "copy_of": "1-0-2",
                    "source": "copy of 1-0-2"}


def test_injected_text_goes_through_the_inverse_mapping(run_dir, tmp_path):
    from genr8_dist.grammar import load_universe

    store = RunStore.open(run_dir)
    text = next(ind.text for ind in store.load_generation(0, 0) if ind.valid)
    path = tmp_path / "mine.hemls"
    path.write_text(text)
    result = apply_edit(str(run_dir), Edit(inject_text=[str(path)], island=1))
    (item,) = result.injected
    assert item["island"] == 1
    assert load_universe("default").map(item["genome"], max_depth=4).text == text   # the run's max_depth


def test_injected_from_another_run(run_dir, tmp_path):
    other = tmp_path / "other"
    store = new_run(other, tiny_toml(islands=1))
    store.commit(Island(parse_config(tiny_toml(islands=1), "t"), 0).initial())
    result = apply_edit(str(run_dir), Edit(inject_from=[f"{other}:0-0-4"]))
    (item,) = result.injected
    assert item["genome"] == list(RunStore.open(other).load_generation(0, 0)[4].genome)
    assert item["source"] == f"{other}:0-0-4" and item["copy_of"] is None


@pytest.mark.parametrize(("edit", "error", "words"), [
    (Edit(assignments=["ea.mutaton_rate=0.1"]), ConfigError, "ea.mutaton_rate"),
    (Edit(assignments=["fitness.beauty.weight=1"]), ConfigError, "fitness.beauty"),
    (Edit(assignments=["ea.mutation_rate=7"]), ConfigError, "ea.mutation_rate"),
    (Edit(assignments=["islands.count=5"]), ConfigError, "islands.count"),
    (Edit(inject_copy=["0-9-0"]), StoreError, "0-9-0"),
    (Edit(inject_copy=["zero"]), ConfigError, "ISLAND-GENERATION-INDEX"),
    (Edit(inject_from=["nowhere:0-0-0"]), StoreError, "nowhere"),
    (Edit(island=7, inject_copy=["0-0-0"]), ConfigError, "--island 7"),
    (Edit(generations=0), ConfigError, "--generations"),
])
def test_refused_edits_leave_the_run_unchanged(run_dir, edit, error, words):
    before = _snapshot(run_dir)
    with pytest.raises(error) as info:
        apply_edit(str(run_dir), edit)
    assert words in str(info.value) and "\n" not in str(info.value)
    assert _snapshot(run_dir) == before


def test_text_the_universe_cannot_invert(run_dir, tmp_path):
    path = tmp_path / "bad.hemls"
    path.write_text("Edge0 -> -> Edge1\n")
    before = _snapshot(run_dir)
    with pytest.raises(Genr8Error):
        apply_edit(str(run_dir), Edit(inject_text=[str(path)]))
    assert _snapshot(run_dir) == before


def test_a_run_with_nothing_committed_is_edited_from_generation_0(tmp_path):
    new_run(tmp_path / "fresh", tiny_toml())
    result = apply_edit(str(tmp_path / "fresh"), Edit(assignments=["ea.mutation_rate=0.1"], generations=4))
    assert (result.version, result.effective_generation, result.last_generation) == (2, 0, 3)
    store = RunStore.open(tmp_path / "fresh")
    assert store.config_for(0).version == 2
    assert parse_config(store.config_for(0).toml, "v2").ea.mutation_rate == 0.1


def test_an_edit_of_a_running_run_queues_before_its_first_commit_and_is_taken_inside_an_epoch(tmp_path):
    """From the run's first second: queued with nothing committed; the coordinator takes the queue's
    leading edits inside an epoch from the first generation no island started, and leaves a pause and
    an edit that changes the epochs (here the run's length) for the epoch's end, in queue order."""
    from genr8_dist.distributed.intervene import take_queued

    new_run(tmp_path / "live", tiny_toml())
    driver = RunStore.open(tmp_path / "live")
    lock = driver.lock("run")
    assert lock.acquire()
    try:
        first = apply_edit(str(tmp_path / "live"), Edit(assignments=["fitness.size.weight=3"]))
        assert first.queued and first.effective_generation == 0
        longer = apply_edit(str(tmp_path / "live"), Edit(generations=10))
        driver.enqueue({"kind": "pause"})
        third = apply_edit(str(tmp_path / "live"), Edit(assignments=["fitness.size.weight=4"]))
        assert [q.name for q in driver.queued()] == [first.queued, longer.queued, "0000000003.json",
                                                     third.queued]
        ((kind, result),) = take_queued(driver, during=2)
        assert kind == "edit" and (result.version, result.effective_generation) == (2, 2)
        assert len(driver.queued()) == 3 and take_queued(driver, during=3) == []
        taken = take_queued(driver)                      # the epoch's end: the rest, in order
        assert [k for k, _ in taken] == ["edit", "pause", "edit"]
    finally:
        lock.release()
    store = RunStore.open(tmp_path / "live")
    assert [(v.version, v.effective_generation) for v in store.configs()] == [(1, 0), (2, 2), (3, 2), (4, 2)]


def test_an_edit_of_a_running_run_is_queued_then_recorded_as_an_edit_records_it(run_dir, tmp_path):
    from genr8_dist.distributed.intervene import take_queued

    driver = RunStore.open(run_dir)
    lock = driver.lock("run")
    assert lock.acquire()
    try:
        before = _snapshot(run_dir)
        result = apply_edit(str(run_dir), Edit(assignments=["ea.mutation_rate=0.1"], favour=["1-0-2"],
                                               hand_fitness=[("0-0-4", 0.25)]), source="studio")
        assert result.queued == "0000000001.json" and result.effective_generation == 1
        assert RunStore.open(run_dir).configs()[-1].version == 1          # nothing recorded yet
        assert set(_snapshot(run_dir)) - set(before) == {"queue/0000000001.json"}
        with pytest.raises(ConfigError, match="hand fitness"):              # still checked at once
            apply_edit(str(run_dir), Edit(hand_fitness=[("0-0-4", float("nan"))]))
        taken = take_queued(driver)                                          # the coordinator's part
    finally:
        lock.release()
    ((kind, outcome),) = taken
    assert kind == "edit" and (outcome.version, outcome.effective_generation) == (2, 1)
    store = RunStore.open(run_dir)
    assert store.queued() == [] and store.config_for(1).version == 2
    (event,) = [e for e in store.events().to_pylist() if e["kind"] == "intervention"]
    detail = json.loads(event["detail"])
    assert event["generation"] == 1 and detail["source"] == "studio" and detail["queued"]
    assert detail["injected"] == [{"island": 1, "genome": list(store.load_generation(1, 0)[2].genome),
                                   "copy_of": "1-0-2", "source": "favoured 1-0-2", "favoured": True}]
    computed = store.load_generation(0, 0)[4].fitness
    assert detail["hand_fitness"] == [{"id": "0-0-4", "island": 0, "fitness": 0.25, "computed": computed}]
    # a request already recorded (a crash before its file was deleted) is dropped, not recorded twice
    store.enqueue({"kind": "edit", "edit": {}, "id": detail["queued"]})
    assert take_queued(store) == [] and store.queued() == []
    # one that no longer fits when its epoch comes is refused with a recorded reason
    store.enqueue({"kind": "edit", "edit": {"assignments": ["ea.generations=0"]}})
    ((kind, reason),) = take_queued(store)
    assert kind == "refused" and "ea.generations" in reason
    assert store.events().column("kind").to_pylist()[-1] == "refused"


def test_hand_fitness_is_for_valid_designs_only(tmp_path):
    """A design that failed has no surface to judge: scoring it by hand is refused."""
    import dataclasses
    import math

    path = tmp_path / "run"
    store = new_run(path, tiny_toml(islands=1))
    config = parse_config(tiny_toml(islands=1), "tiny")
    first = Island(config, 0).initial()
    failed = dataclasses.replace(first[3], valid=False, stage="grow", error="too many edges",
                                 fitness=math.inf)
    store.commit([*first[:3], failed, *first[4:]])
    with pytest.raises(ConfigError, match="hand fitness for 0-0-3: it failed at grow"):
        apply_edit(str(path), Edit(hand_fitness=[("0-0-3", 0.0)]))


def test_hand_fitness_makes_a_marked_individual_an_elite_of_the_next_generation():
    config = parse_config(tiny_toml(islands=1), "tiny")
    island = Island(config, 0)
    first = island.initial()
    worst = max((ind for ind in first if ind.valid), key=lambda ind: ind.fitness)
    second = island.step(first, 1, hand=[(worst, 0.0)])
    (elite,) = [ind for ind in second if ind.origin == "elite"]
    assert elite.parents == (worst.id,) and elite.genome == worst.genome
    assert elite.fitness == worst.fitness                       # the row keeps the computed fitness
    # an individual of an older generation joins the pool of the generation it is marked for
    third = island.step(second, 2, hand=[(worst, 0.0)])
    assert [ind.parents for ind in third if ind.origin == "elite"] == [(worst.id,)]
    assert island.step(first, 1) != second


def test_genr8_edit_and_resume_of_a_running_run(run_dir, capsys):
    """With the run's lock held (what `genr8 run` holds), `genr8 edit` queues and says so, and a second
    `genr8 resume` is refused in one line before Ray starts."""
    from genr8_dist.cli import main

    lock = RunStore.open(run_dir).lock("run")
    assert lock.acquire()
    try:
        assert main(["edit", str(run_dir), "--favour", "0-0-1", "--hand-fitness", "1-0-2=0.5"]) == 0
        out = capsys.readouterr().out
        assert "the run is running; the edit is queued (0000000001.json)" in out
        assert "inject favoured 0-0-1 into island 0" in out
        (queued,) = RunStore.open(run_dir).queued()
        assert queued.request["edit"]["hand_fitness"] == [["1-0-2", 0.5]]
        assert main(["resume", str(run_dir)]) == 2
        err = capsys.readouterr().err.strip()
        assert err.startswith("genr8: error:") and "is running already" in err and len(err.splitlines()) == 1
        assert main(["edit", str(run_dir), "--hand-fitness", "1-0-2"]) == 2
        assert "expected ID=FITNESS" in capsys.readouterr().err
    finally:
        lock.release()
