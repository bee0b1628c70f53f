"""Two writers racing for one commit: the loser never touches the winner's bytes, at any step.

The loser's filesystem calls are counted; for every step k of its commit, the winner makes its whole
commit just before the loser's k-th call. Whoever links the manifest first has committed; the other
gets a ``StoreError`` and removes only the files it wrote.
"""

from __future__ import annotations

import hashlib
from collections.abc import Callable
from pathlib import Path

import pytest
from test_runstore import CONFIG, epoch

from genr8_dist.errors import StoreError
from genr8_dist.store import Event, RunStore
from genr8_dist.store._fs import resolve
from genr8_dist.store.manifest import file_entries, list_manifests, read_manifest

STEPS = ("write_new", "write_exclusive", "write_atomic", "delete")

Writer = Callable[[RunStore], object]
WRITERS: dict[str, Writer] = {
    "commit": lambda s: s.commit(epoch(range(3, 5)), [Event("migration", 4)]),
    "edit": lambda s: s.add_config(CONFIG + "mutation_rate = 0.02\n", 3, events=[Event("intervention", 3)]),
    "compact": lambda s: s.compact(target_rows=1000),
    "event": lambda s: s.record_event("interrupt", generation=3),
}
WINNERS: dict[str, Writer] = {
    "commit": lambda s: s.commit(epoch(range(3, 4)), [Event("migration", 3)]),
    "edit": lambda s: s.add_config(CONFIG + "mutation_rate = 0.5\n", 3, events=[Event("intervention", 3)]),
}


def _committed_bytes(path: Path) -> dict[str, str]:
    """sha256 of every file the newest manifest names."""
    store = RunStore.open(path)
    return {e["path"]: hashlib.sha256((path / e["path"]).read_bytes()).hexdigest()
            for _, e in file_entries(store.manifest)}


def _on_disk(path: Path) -> set[str]:
    """The run's own files (not the glob views' links: derived from manifests, store/views.py)."""
    return {str(p.relative_to(path)) for p in path.rglob("*")
            if p.is_file() and p.parent.name != "_manifest" and p.relative_to(path).parts[0] != "_views"}


def _steps(path: Path, loser_op: Writer) -> int:
    """How many filesystem calls the loser's commit makes when nobody races it."""
    probe = path.parent / f"{path.name}-probe"
    _make_run(probe)
    store = RunStore.open(probe, compact_every=None)
    calls = _count(store)
    loser_op(store)
    return len(calls)


def _count(store: RunStore, before: Callable[[int], None] | None = None) -> list[str]:
    calls: list[str] = []
    fs = store._fs
    for name in STEPS:
        original = getattr(fs, name)

        def wrapped(*args: object, _original: Callable = original, _name: str = name) -> object:
            if before is not None:
                before(len(calls))
            calls.append(_name)
            return _original(*args)

        setattr(fs, name, wrapped)
    return calls


def _make_run(path: Path) -> None:
    store = RunStore.create(path, CONFIG, compact_every=None)
    store.commit(epoch(range(2)), [Event("migration", 1)])
    store.commit(epoch(range(2, 3)))


@pytest.mark.parametrize("winner_name", sorted(WINNERS))
@pytest.mark.parametrize("loser_name", sorted(WRITERS))
def test_the_loser_never_touches_the_winners_bytes_at_any_step(
    tmp_path: Path, loser_name: str, winner_name: str
) -> None:
    loser_op, winner_op = WRITERS[loser_name], WINNERS[winner_name]
    n_steps = _steps(tmp_path / "count", loser_op)
    assert n_steps >= 2
    for step in range(n_steps):
        run = tmp_path / f"run-{step}"
        _make_run(run)
        loser = RunStore.open(run, compact_every=None)
        winner = RunStore.open(run, compact_every=None)
        after_winner: dict[str, str] = {}

        def race(k: int, _step: int = step, _winner: RunStore = winner, _run: Path = run,
                 _after: dict[str, str] = after_winner) -> None:
            if k == _step and not _after:
                try:
                    winner_op(_winner)
                except StoreError:
                    return  # the loser had already linked its manifest: the winner lost instead
                _after.update(_committed_bytes(_run))

        _count(loser, race)
        try:
            loser_op(loser)
            loser_won = True
        except StoreError as exc:
            assert "another process committed" in str(exc)
            loser_won = False
        final = RunStore.open(run)
        assert final.verify() == [], f"step {step}"
        if after_winner and not loser_won:
            # every byte the winner committed is still there, unchanged
            assert _committed_bytes(run) == after_winner, f"step {step}"
        rfs = resolve(str(run))
        referenced = {e["path"] for version in list_manifests(rfs)
                      if (m := read_manifest(rfs, version)) is not None for _, e in file_entries(m)}
        leftovers = _on_disk(run) - referenced
        if not loser_won:
            assert leftovers == set(), f"step {step}: the loser left {leftovers}"


def test_a_losing_edit_leaves_the_winners_configuration_readable(tmp_path: Path) -> None:
    """The issue's case: two edits, the first one's manifest link delayed until the second committed."""
    _make_run(tmp_path / "run")
    slow = RunStore.open(tmp_path / "run")
    fast = RunStore.open(tmp_path / "run")
    original = slow._fs.write_exclusive

    def delayed(rel: str, data: bytes) -> None:
        fast.add_config(CONFIG + "mutation_rate = 0.5\n", 3)
        original(rel, data)

    slow._fs.write_exclusive = delayed  # type: ignore[method-assign]
    with pytest.raises(StoreError, match="another process committed manifest 4"):
        slow.add_config(CONFIG + "mutation_rate = 0.02\n", 3)
    reopened = RunStore.open(tmp_path / "run")
    assert reopened.verify() == []
    assert reopened.config_for(3).toml.endswith("mutation_rate = 0.5\n")
    assert len(list((tmp_path / "run" / "configs").iterdir())) == 2
