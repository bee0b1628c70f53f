"""The run store on an S3-compatible server (moto's, on 127.0.0.1): the same commit, verify and repair as on
a local disk, manifests created only if their number is free, and the run's lease (one writer across
machines: taken with a conditional create, renewed and taken over with conditional replaces)."""

from __future__ import annotations

import json
import socket
import subprocess
import sys
import time

import pytest

from genr8_dist.errors import StoreError
from genr8_dist.store import RunStore
from genr8_dist.store._fs import resolve
from genr8_dist.store.lease import Lease, _boot_id, lease_holder
from genr8_dist.store.synthetic import _text_pool, synthetic_epoch, write_synthetic_run

pytest.importorskip("boto3")


def _rows(store: RunStore) -> list[dict]:
    table = store.individuals().drop_columns(["run_id"])
    table = table.sort_by([("island", "ascending"), ("generation", "ascending"), ("index", "ascending")])
    return table.to_pylist()


def _next_epoch(store: RunStore, seed: int, islands: int, pop: int):
    """The rows of the run's next generation (each island's), as its driver would commit them."""
    first = max(store.committed_generations().values()) + 1
    return synthetic_epoch(store, seed, first, first, first, islands, pop, (16, 128), _text_pool(seed))


def _events(store: RunStore) -> list[tuple]:
    table = store.events()
    return list(zip(table.column("seq").to_pylist(), table.column("kind").to_pylist(), strict=True))


def test_a_synthetic_run_on_s3_equals_the_same_run_on_disk(s3_server, tmp_path):
    bucket = s3_server.bucket()
    uri = s3_server.uri(bucket, "runs/synthetic")
    on_s3 = write_synthetic_run(uri, 3, 12, 8, seed=5, generations_per_commit=4)
    on_disk = write_synthetic_run(tmp_path / "synthetic", 3, 12, 8, seed=5, generations_per_commit=4)
    reopened = RunStore.open(uri)
    assert reopened.verify() == []
    assert reopened.version == on_disk.version == on_s3.version
    assert len(_rows(reopened)) == 3 * 12 * 8
    assert _rows(reopened) == _rows(RunStore.open(tmp_path / "synthetic"))
    assert _events(reopened) == _events(on_disk)
    keys = s3_server.keys(bucket)
    assert "runs/synthetic/_manifest/HEAD" in keys
    assert not [k for k in keys if "/.tmp-" in k]


def test_damage_on_s3_is_named_by_verify_and_mended_by_repair(s3_server):
    bucket = s3_server.bucket()
    uri = s3_server.uri(bucket, "runs/damaged")
    store = write_synthetic_run(uri, 2, 9, 6, seed=3, generations_per_commit=3)
    before = _rows(store)
    part = store.manifest["individuals"][1]["path"]
    s3_server.client.put_object(Bucket=bucket, Key=f"runs/damaged/{part}", Body=b"not parquet")
    problems = RunStore.open(uri).verify()
    assert len(problems) == 1 and part in problems[0]
    repaired = RunStore.open(uri)
    repaired.repair()
    assert repaired.verify() == []
    after = _rows(RunStore.open(uri))
    lost = {(r["generation"]) for r in before} - {(r["generation"]) for r in after}
    assert lost == {3, 4, 5}          # the damaged commit alone is dropped, the later one stays
    assert [r for r in before if r["generation"] not in lost] == after
    assert "recovery" in [kind for _, kind in _events(RunStore.open(uri))]


def test_a_manifest_number_is_created_once_and_the_loser_changes_nothing(s3_server):
    bucket = s3_server.bucket()
    uri = s3_server.uri(bucket, "runs/race")
    write_synthetic_run(uri, 2, 4, 6, seed=1, generations_per_commit=2)
    keys_before = s3_server.keys(bucket)
    rfs = resolve(uri)
    taken = "_manifest/0000000002.json"
    with pytest.raises(FileExistsError):
        rfs.write_exclusive(taken, b"{}")
    assert s3_server.keys(bucket) == keys_before   # the conditional PUT left the winner's bytes

    first, second = RunStore.open(uri), RunStore.open(uri)   # two writers, the same snapshot
    first.commit_table(_next_epoch(first, 1, 2, 6))
    with pytest.raises(StoreError, match="only one writer may commit"):
        second.commit_table(_next_epoch(second, 1, 2, 6))
    after = RunStore.open(uri)
    assert after.verify() == []
    assert after.version == first.version
    stray = set(s3_server.keys(bucket)) - set(keys_before)
    assert all(k.endswith(".json") or k.endswith("HEAD") or k in
               {f"runs/race/{e['path']}" for e in after.manifest["individuals"]} for k in stray)


def test_a_manifest_put_is_conditional_even_when_the_check_before_it_missed(s3_server, monkeypatch):
    """The window check-then-PUT left open: both writers pick the same number; the server refuses one."""
    import genr8_dist.store.transactions as transactions

    bucket = s3_server.bucket()
    uri = s3_server.uri(bucket, "runs/window")
    write_synthetic_run(uri, 2, 4, 6, seed=1, generations_per_commit=2)
    first, second = RunStore.open(uri), RunStore.open(uri)
    rows = _next_epoch(second, 1, 2, 6)
    number = first.version + 1
    first.commit_table(_next_epoch(first, 1, 2, 6))
    monkeypatch.setattr(transactions, "list_manifests", lambda rfs: [v for v in range(1, number)])
    monkeypatch.setattr(transactions, "read_head", lambda rfs: number - 1)
    with pytest.raises(StoreError, match=f"committed manifest {number} at the same time"):
        second.commit_table(rows)
    monkeypatch.undo()
    store = RunStore.open(uri)
    assert store.verify() == [] and store.version == number
    assert store.collect_garbage() == 0   # the loser removed its own part; nothing else was touched


def test_the_lease_keeps_one_writer_and_is_given_back(s3_server):
    uri = s3_server.uri(s3_server.bucket(), "runs/lease")
    store = write_synthetic_run(uri, 1, 2, 6, seed=2, generations_per_commit=2)
    lock = store.lock("run")
    assert lock.acquire() and lock.held
    holder = RunStore.open(uri).running()
    assert holder is not None and holder["role"] == "run" and holder["host"] == socket.gethostname()
    other = RunStore.open(uri)
    assert other.lock("run").acquire() is False                    # a second driver is refused
    assert RunStore.open(uri).lock("edit").acquire() is False      # an edit queues its request instead
    lock.release()
    assert RunStore.open(uri).running() is None
    assert other.lock("run").acquire()                              # given back: taken at once
    other.writer_lock.release()


def test_an_edit_holding_the_lease_is_waited_for_then_refused(s3_server):
    uri = s3_server.uri(s3_server.bucket(), "runs/edit")
    store = write_synthetic_run(uri, 1, 2, 6, seed=2, generations_per_commit=2)
    editing = store.lock("edit")
    assert editing.acquire()
    start = time.monotonic()
    with pytest.raises(StoreError, match="another command holds the run's lease"):
        RunStore.open(uri).lock("edit", wait=0.5).acquire()
    assert time.monotonic() - start >= 0.5
    editing.release()
    assert RunStore.open(uri).lock("edit", wait=0.5).acquire()


def _plant(s3_server, bucket: str, key: str, body: dict) -> None:
    s3_server.client.put_object(Bucket=bucket, Key=key, Body=json.dumps(body).encode())


def test_a_crashed_drivers_lease_is_taken_over_once_it_expires(s3_server):
    bucket = s3_server.bucket()
    uri = s3_server.uri(bucket, "runs/expired")
    write_synthetic_run(uri, 1, 2, 6, seed=2, generations_per_commit=2)
    _plant(s3_server, bucket, "runs/expired/_running.lock",
           {"role": "run", "pid": 4242, "host": "another-machine", "boot": "x", "seconds": 2.0})
    assert RunStore.open(uri).lock("run").acquire() is False        # held, by a machine we cannot see
    time.sleep(3.2)                                                  # not renewed for longer than its length
    store = RunStore.open(uri)
    assert store.lock("run").acquire()
    assert store.running()["pid"] != 4242
    store.writer_lock.release()


def test_a_killed_driver_on_this_machine_frees_its_lease_at_once(s3_server):
    bucket = s3_server.bucket()
    uri = s3_server.uri(bucket, "runs/killed")
    write_synthetic_run(uri, 1, 2, 6, seed=2, generations_per_commit=2)
    gone = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True,
                          text=True, check=True)
    _plant(s3_server, bucket, "runs/killed/_running.lock",
           {"role": "run", "pid": int(gone.stdout), "host": socket.gethostname(), "boot": _boot_id(),
            "seconds": 600.0})
    store = RunStore.open(uri)
    assert store.running() is None
    assert store.lock("run").acquire()
    store.writer_lock.release()


def test_a_stalled_driver_whose_lease_was_taken_over_commits_nothing(s3_server):
    bucket = s3_server.bucket()
    uri = s3_server.uri(bucket, "runs/stalled")
    write_synthetic_run(uri, 2, 4, 6, seed=4, generations_per_commit=2)
    stalled = RunStore.open(uri)
    rows = _next_epoch(stalled, 4, 2, 6)
    lease = Lease(stalled._fs.objects(), "_running.lock", "run", seconds=2.0)
    assert lease.acquire() is None
    lease._stop.set()                     # it stops renewing (a paused process, a lost network)
    lease._thread.join()
    lock = stalled.lock("run")
    lock._lease = lease
    time.sleep(3.2)
    winner = RunStore.open(uri)
    assert winner.lock("run").acquire()   # the lease expired: another driver takes it over
    keys = s3_server.keys(bucket)
    with pytest.raises(StoreError, match="taken over by another driver"):
        stalled.commit_table(rows)         # before the new holder commits: its lease check refuses it
    assert {k: v for k, v in s3_server.keys(bucket).items() if not k.endswith("_running.lock")} == {
        k: v for k, v in keys.items() if not k.endswith("_running.lock")}
    winner.commit_table(_next_epoch(winner, 4, 2, 6))
    with pytest.raises(StoreError, match="only one writer may commit"):
        stalled.commit_table(rows)         # after: the newer manifest refuses it as well
    store = RunStore.open(uri)
    assert store.verify() == [] and store.version == winner.version
    holder = lease_holder(stalled._fs.objects(), "_running.lock")
    assert holder is not None and holder["token"] == winner.writer_lock._lease._body["token"]
    winner.writer_lock.release()


def test_the_endpoint_may_come_from_the_environment(s3_server, monkeypatch):
    monkeypatch.setenv("AWS_ENDPOINT_URL", s3_server.url)
    bucket = s3_server.bucket()
    uri = f"s3://{bucket}/runs/env"
    store = write_synthetic_run(uri, 1, 4, 6, seed=6, generations_per_commit=2)
    assert RunStore.open(uri).verify() == []
    assert f"runs/env/{store.manifest['individuals'][0]['path']}" in s3_server.keys(bucket)
    lock = store.lock("run")
    assert lock.acquire() and RunStore.open(uri).lock("run").acquire() is False
    lock.release()


def test_without_boto3_a_write_on_s3_says_which_extra_to_install(s3_server, monkeypatch):
    uri = s3_server.uri(s3_server.bucket(), "runs/noboto")
    monkeypatch.setitem(sys.modules, "boto3", None)
    with pytest.raises(StoreError, match=r"needs boto3 .*pip install 'genr8-dist\[s3\]'") as info:
        RunStore.create(uri, 'universe = "default"\n')
    assert "\n" not in str(info.value)
