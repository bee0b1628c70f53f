"""The manifest's format (store/manifest.py): its declared keys are the ones a run writes, and a
manifest whose body was altered after its checksum reads as damaged."""

from __future__ import annotations

import json
import typing
from pathlib import Path

from test_runstore import CONFIG, epoch

from genr8_dist.store import Event, RunStore
from genr8_dist.store.manifest import (
    Entry,
    Manifest,
    add_entries,
    decode_manifest,
    encode_manifest,
    file_entries,
)


def _keys(kind: type) -> tuple[set[str], set[str]]:
    """The required and the optional keys ``kind`` (a TypedDict) declares."""
    hints = typing.get_type_hints(kind, include_extras=True)
    optional = {k for k, v in hints.items() if typing.get_origin(v) is typing.NotRequired}
    return set(hints) - optional, optional


def test_every_key_a_run_writes_is_declared_and_every_required_key_is_written(tmp_path: Path) -> None:
    store = RunStore.create(tmp_path / "run", CONFIG)
    store.commit(epoch(range(2)), [Event("start", 0, None, {})])
    store.add_config(CONFIG + "\n# edited\n", 2)
    store.commit(epoch(range(2, 3)))
    store.compact(target_rows=10)
    manifest = RunStore.open(tmp_path / "run").manifest
    required, optional = _keys(Manifest)
    assert required <= set(manifest) <= required | optional | {"checksum"}
    required, optional = _keys(Entry)
    kinds = {kind for kind, _ in file_entries(manifest)}
    assert kinds == {"configs", "individuals", "events"}
    for _, entry in file_entries(manifest):
        assert required <= set(entry) <= required | optional


def test_a_feature_lists_its_own_files_and_the_store_names_them(tmp_path: Path) -> None:
    store = RunStore.create(tmp_path / "run", CONFIG)

    def add(manifest: Manifest, version: int) -> None:
        add_entries(manifest, "notes", [store.write_file(f"notes/n-{version:010d}", ".txt", b"hello")])

    store.commit([], [Event("start", 0, None, {})], add=add)
    reopened = RunStore.open(tmp_path / "run")
    (entry,) = [e for kind, e in file_entries(reopened.manifest) if kind == "notes"]
    assert reopened.read_file(entry) == b"hello" and reopened.verify() == []
    assert reopened.collect_garbage() == 0 and (tmp_path / "run" / entry["path"]).is_file()


def test_an_altered_body_is_not_read_as_a_manifest(tmp_path: Path) -> None:
    store = RunStore.create(tmp_path / "run", CONFIG)
    data = encode_manifest(store.manifest)
    assert decode_manifest(data) == json.loads(data)
    body = json.loads(data)
    body["run_id"] = "another"
    assert decode_manifest(json.dumps(body).encode()) is None
