"""The run's lock and its queue of pending interventions: two writers never lose or overwrite a request,
a killed holder never leaves a run looking busy."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from genr8_dist.errors import StoreError
from genr8_dist.store import RunStore

CONFIG = 'universe = "default"\nseed = 1\n'


@pytest.fixture
def store(tmp_path):
    return RunStore.create(tmp_path / "run", CONFIG)


def test_requests_are_taken_in_the_order_they_were_queued(store):
    first = store.enqueue({"kind": "pause"})
    second = store.enqueue({"kind": "continue", "id": "mine"})
    assert (first.number, second.number) == (1, 2)
    assert [q.request["kind"] for q in store.queued()] == ["pause", "continue"]
    assert store.queued()[1].request["id"] == "mine" and len(first.request["id"]) == 16
    store.dequeue(first)
    assert [q.number for q in store.queued()] == [2]
    assert store.enqueue({"kind": "pause"}).number == 3


def test_two_writers_at_once_lose_no_request(store):
    writers, each = 6, 15
    stores = [RunStore.open(store.path) for _ in range(writers)]
    barrier = threading.Barrier(writers)

    def write(k):
        barrier.wait()
        for j in range(each):
            stores[k].enqueue({"kind": "edit", "edit": {"assignments": [f"ea.mutation_rate=0.{k}{j}"]}})

    threads = [threading.Thread(target=write, args=(k,)) for k in range(writers)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    items = store.queued()
    assert [q.number for q in items] == list(range(1, writers * each + 1))
    got = sorted(q.request["edit"]["assignments"][0] for q in items)
    assert got == sorted(f"ea.mutation_rate=0.{k}{j}" for k in range(writers) for j in range(each))
    assert not [n for n in os.listdir(os.path.join(store.path, "queue")) if not n.endswith(".json")]


def test_a_torn_or_foreign_file_in_the_queue_is_skipped(store):
    store.enqueue({"kind": "pause"})
    queue = os.path.join(store.path, "queue")
    with open(os.path.join(queue, "0000000002.json"), "w") as fh:
        fh.write('{"kind": "pau')
    with open(os.path.join(queue, "notes.txt"), "w") as fh:
        fh.write("hello")
    assert [q.number for q in store.queued()] == [1]


def test_the_lock_says_who_runs_the_run(store):
    assert store.running() is None
    run = store.lock("run")
    assert run.acquire()
    holder = RunStore.open(store.path).running()
    assert holder["role"] == "run" and holder["pid"] == os.getpid()
    assert RunStore.open(store.path).lock("edit").acquire() is False   # a running run: edits queue
    run.release()
    assert store.running() is None
    with store.lock("edit") as edit:
        assert edit.acquire() and edit.held


def test_an_edit_lock_is_waited_for_then_named(store):
    with store.lock("edit") as first:
        assert first.acquire()
        with pytest.raises(StoreError, match="another command holds the run's lock"):
            RunStore.open(store.path).lock("edit", wait=0.2).acquire()


def test_a_killed_driver_leaves_the_run_free(store):
    script = ("import sys, time\nfrom genr8_dist.store import RunStore\n"
              "lock = RunStore.open(sys.argv[1]).lock('run')\nassert lock.acquire()\n"
              "print('held', flush=True)\ntime.sleep(60)\n")
    proc = subprocess.Popen([sys.executable, "-c", script, store.path], stdout=subprocess.PIPE, text=True)
    try:
        assert proc.stdout.readline().strip() == "held"
        assert store.running()["pid"] == proc.pid
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait(10)
        deadline = time.monotonic() + 5
        while store.running() is not None and time.monotonic() < deadline:
            time.sleep(0.05)
        assert store.running() is None
        assert store.lock("run").acquire()
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()


def test_a_request_too_large_is_refused(store):
    with pytest.raises(StoreError, match="too large"):
        store.enqueue({"kind": "edit", "edit": {"inject_systems": [["big", "x" * (1 << 21)]]}})
    assert store.queued() == []
    assert json.loads(json.dumps(store.enqueue({"kind": "pause"}).request))["kind"] == "pause"


@pytest.mark.parametrize("ending", ["finished", "failed"])
def test_the_lock_file_goes_when_the_run_ends(store, ending):
    """`hold_run_lock` wraps a run: finished or failed (an interrupt ends it the same way), the run
    directory keeps no `_running.lock`."""
    from genr8_dist.distributed.session import hold_run_lock

    lock_file = Path(store.path) / "_running.lock"
    try:
        with hold_run_lock(store):
            assert lock_file.exists() and store.running()["role"] == "run"
            if ending == "failed":
                raise RuntimeError("the run failed")
    except RuntimeError:
        pass
    assert not lock_file.exists() and store.running() is None


def test_a_lock_whose_file_its_holder_removed_is_taken_on_the_new_file(store):
    """A command waiting while the holder lets go (and removes the file) holds the lock on the file
    now at the path, so a third command is kept out, not let in on another file."""
    first = store.lock("edit")
    assert first.acquire()
    waiter = RunStore.open(store.path).lock("edit", wait=5.0)
    got: list[bool] = []
    thread = threading.Thread(target=lambda: got.append(waiter.acquire()))
    thread.start()
    time.sleep(0.3)    # the waiter has opened the file and is retrying its flock
    first.release()
    thread.join()
    lock_file = Path(store.path) / "_running.lock"
    assert got == [True] and os.fstat(waiter._fd).st_ino == os.stat(lock_file).st_ino
    with pytest.raises(StoreError, match="another command holds the run's lock"):
        RunStore.open(store.path).lock("edit", wait=0.2).acquire()
    waiter.release()
    assert not lock_file.exists()
