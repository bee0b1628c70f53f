"""The live view (store/live.py): what a reader sees of generations completed and not committed, and
that writing it costs no fsync, loses no earlier file and leaves no temporary file behind."""

from __future__ import annotations

import os

import pytest

import genr8_dist.files
from genr8_dist.evolution.individual import Individual
from genr8_dist.store import live
from genr8_dist.store._fs import resolve


def _population(island: int, generation: int, n: int = 3) -> list[Individual]:
    return [Individual(island, generation, k, (k + 1, 7), "random", valid=True, fitness=float(k),
                       text=f"axiom {k}") for k in range(n)]


def test_a_reader_sees_each_written_generation_until_it_is_committed(tmp_path):
    rfs = resolve(tmp_path)
    for island in (0, 1):
        for g in (0, 1, 2):
            live.write_generation(rfs, island, g, _population(island, g))
    seen = live.read(rfs)
    assert sorted(seen) == [0, 1, 2] and all(sorted(seen[g]) == [0, 1] for g in seen)
    assert [row["fitness"] for row in seen[2][1]] == [0.0, 1.0, 2.0]
    assert {row["text"] for row in seen[0][0]} == {"axiom 0", "axiom 1", "axiom 2"}
    live.drop_committed(rfs, {0: 1, 1: 0})
    seen = live.read(rfs)
    assert {g: sorted(i) for g, i in seen.items()} == {1: [1], 2: [0, 1]}
    live.clear(rfs)
    assert live.read(rfs) == {} and not (tmp_path / live.LIVE_DIR).exists()


def test_a_torn_or_foreign_file_is_skipped_not_raised(tmp_path):
    rfs = resolve(tmp_path)
    live.write_generation(rfs, 0, 4, _population(0, 4))
    folder = tmp_path / live.LIVE_DIR
    (folder / "5-0.json").write_bytes(b'[{"id": "0-5-0", "fitn')   # a torn write
    (folder / "6-0.json").write_bytes(b"\xff\xfe")                  # not text
    (folder / "notes.txt").write_text("not a generation")
    assert {g: sorted(i) for g, i in live.read(rfs).items()} == {4: [0]}


def test_the_live_view_is_not_fsynced_while_the_run_store_is(tmp_path, monkeypatch):
    rfs = resolve(tmp_path)
    rfs.makedirs(live.LIVE_DIR)
    synced: list[int] = []
    real = os.fsync
    monkeypatch.setattr(os, "fsync", lambda fd: synced.append(fd) or real(fd))
    live.write_generation(rfs, 0, 0, _population(0, 0))
    assert synced == []
    rfs.write_atomic("HEAD", b"1\n")   # the run store's writes stay durable: file and folder
    assert len(synced) == 2


def test_a_failed_write_keeps_the_previous_file_and_leaves_no_temporary(tmp_path, monkeypatch):
    rfs = resolve(tmp_path)
    live.write_generation(rfs, 0, 3, _population(0, 3, n=2))
    before = (tmp_path / live.LIVE_DIR / "3-0.json").read_bytes()

    def full_disk(src, dst):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(genr8_dist.files.os, "replace", full_disk)
    with pytest.raises(OSError):
        live.write_generation(rfs, 0, 3, _population(0, 3, n=5))
    monkeypatch.undo()
    assert (tmp_path / live.LIVE_DIR / "3-0.json").read_bytes() == before
    assert os.listdir(tmp_path / live.LIVE_DIR) == ["3-0.json"]
    assert len(live.read(rfs)[3][0]) == 2
