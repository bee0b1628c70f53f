"""Damage to every kind of file a run holds: readers name it or answer exactly as before, repair keeps
every intact later commit and every edit.

The run has every file kind: configuration versions 1 and 2 (an edit), individuals files of single
commits and a compacted one, events files of single commits and a compacted one, the newest manifest,
older manifests and ``_manifest/HEAD``. Each file is truncated, zeroed, bit-flipped (three places) or
deleted; then ``genr8 history``, ``top`` and ``query`` (in-process, as a user runs them) must print
exactly what they printed before, or exit 2 with one line naming a damaged file or manifest; then
``repair`` must leave a run that verifies, keeps every configuration version, and keeps every commit
after the damaged one whose files were intact.
"""

from __future__ import annotations

import contextlib
import io
import shutil
from pathlib import Path
from typing import Any

import pytest
from test_runstore import CONFIG, epoch

from genr8_dist.cli import main
from genr8_dist.store import Event, RunStore
from genr8_dist.store.manifest import file_entries

READERS = (["history"], ["top", "-k", "50"], ["query", "select island, generation, count(*), sum(fitness) "
                                               "from individuals group by all order by all"],
           ["query", "select seq, kind, generation from events order by seq"],
           ["query", "select version, effective_generation, toml from configs order by version"])
HOW = ("truncate", "zero", "flip-start", "flip-middle", "flip-end", "delete")


def build(path: Path) -> RunStore:
    store = RunStore.create(path, CONFIG, compact_every=None)
    store.record_event("start", generation=0)
    store.commit(epoch(range(0, 3)), [Event("migration", 2)])
    store.commit(epoch(range(3, 6)), [Event("migration", 5)])
    store.compact(target_rows=1000)
    store.add_config(CONFIG + "mutation_rate = 0.02\n", 6, events=[Event("intervention", 6)])
    store.commit(epoch(range(6, 9)), [Event("migration", 8)])
    store.commit(epoch(range(9, 12)), [Event("migration", 11)])
    return store


def damage(path: Path, how: str) -> None:
    data = path.read_bytes()
    if how == "truncate":
        path.write_bytes(data[: len(data) // 2])
    elif how == "zero":
        path.write_bytes(bytes(len(data)))
    elif how == "delete":
        path.unlink()
    else:
        at = {"flip-start": 0, "flip-middle": len(data) // 2, "flip-end": len(data) - 1}[how]
        out = bytearray(data)
        out[at] ^= 0x04
        path.write_bytes(bytes(out))


def run_cli(argv: list[str]) -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            rc = main(argv)
        except SystemExit as exc:
            rc = int(exc.code or 0)
    return rc, out.getvalue(), err.getvalue()


def commit_of(store: RunStore, rel: str) -> int | None:
    """The commit a data file belongs to (its first), or None for a manifest or HEAD."""
    for _, e in file_entries(store.manifest):
        if e["path"] == rel:
            return int(e["commits"][0]) if "commits" in e else int(e["commit"])
    return None


def check(baseline_dir: Path, tmp: Path, rel: str, how: str, answers: dict[str, str]) -> dict[str, Any]:
    """Damage ``rel`` of a copy of the baseline run; what readers and repair did."""
    run = tmp / f"{rel.replace('/', '_')}-{how}"
    shutil.copytree(baseline_dir, run)
    before = RunStore.open(run)
    damaged_commit = commit_of(before, rel)
    n_configs = len(before.manifest["configs"])
    damage(run / rel, how)
    found: dict[str, Any] = {"tracebacks": [], "wrong": [], "unnamed": [], "lost": [], "repair": ""}
    for argv in READERS:
        try:
            rc, out, err = run_cli([argv[0], str(run), *argv[1:]])
        except Exception as exc:
            found["tracebacks"].append(f"{argv[0]}: {type(exc).__name__}: {exc}")
            continue
        if rc == 0:
            if out != answers[" ".join(argv)]:
                found["wrong"].append(" ".join(argv))
        elif not (rc == 2 and err.startswith("genr8: error: ") and err.count("\n") == 1
                  and (Path(rel).name in err or "_manifest" in err)):
            found["unnamed"].append(f"{argv[0]}: rc {rc}: {err.strip()[:200]}")
    try:
        store = RunStore.open(run)
        store.repair()
        found["repair"] = store.last_repair
        after = RunStore.open(run)
        if after.verify():
            found["lost"].append(f"still damaged: {after.verify()[0]}")
        kept = {e["path"] for _, e in file_entries(after.manifest)}
        for kind, e in file_entries(before.manifest):
            first = int(e["commits"][0]) if "commits" in e else int(e["commit"])
            later = damaged_commit is not None and first > damaged_commit
            if kind == "configs":
                continue
            if later and e["path"] not in kept:
                found["lost"].append(f"later commit {first}: {e['path']}")
        if len(after.configs()) != n_configs:
            found["lost"].append("a configuration version")
        for argv in READERS:
            rc, _, err = run_cli([argv[0], str(run), *argv[1:]])
            if rc != 0:
                found["lost"].append(f"after repair {argv[0]}: {err.strip()[:200]}")
    except Exception as exc:
        found["tracebacks"].append(f"repair: {type(exc).__name__}: {exc}")
    return found


def cases(path: Path) -> list[str]:
    return sorted(str(p.relative_to(path)) for p in path.rglob("*")   # (views: links to these files)
                  if p.is_file() and p.relative_to(path).parts[0] != "_views")


@pytest.fixture(scope="module")
def baseline(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict[str, str]]:
    path = tmp_path_factory.mktemp("corruption") / "run"
    build(path)
    answers = {}
    for argv in READERS:
        rc, out, err = run_cli([argv[0], str(path), *argv[1:]])
        assert rc == 0, err
        answers[" ".join(argv)] = out
    return path, answers


def test_the_run_has_every_file_kind(baseline: tuple[Path, dict[str, str]]) -> None:
    names = cases(baseline[0])
    for stem in ("configs/v0001-", "configs/v0002-", "_files/individuals/part-",
                 "_files/individuals/compact-", "_files/events/events-", "_files/events/compact-",
                 "_manifest/HEAD"):
        assert any(n.startswith(stem) for n in names), stem
    assert sum(n.startswith("_manifest/0") for n in names) >= 5


@pytest.mark.parametrize("how", ["flip-middle", "delete"])
def test_damage_to_each_file_kind_is_named_or_harmless(baseline, tmp_path, how) -> None:
    path, answers = baseline
    picked: dict[str, str] = {}
    for rel in cases(path):
        picked.setdefault(rel.rsplit("/", 1)[0] + rel.split("/")[-1][:4], rel)
    for rel in picked.values():
        found = check(path, tmp_path, rel, how, answers)
        assert found["tracebacks"] == [] and found["wrong"] == [] and found["unnamed"] == [], (rel, found)
        assert found["lost"] == [], (rel, found)


@pytest.mark.slow
def test_every_file_every_damage(baseline, tmp_path) -> None:
    path, answers = baseline
    totals = {"cases": 0, "tracebacks": 0, "wrong": 0, "unnamed": 0, "lost": 0}
    failures = []
    for rel in cases(path):
        for how in HOW:
            found = check(path, tmp_path, rel, how, answers)
            totals["cases"] += 1
            for key in ("tracebacks", "wrong", "unnamed", "lost"):
                totals[key] += len(found[key])
                if found[key]:
                    failures.append((rel, how, key, found[key]))
    print(f"corruption: {totals}")
    assert totals["cases"] >= 100
    assert failures == []
