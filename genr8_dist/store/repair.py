"""Verifying a run (every committed byte, and the manifests) and repairing it, keeping every intact
commit and naming what is dropped.
"""

from __future__ import annotations

import copy
import hashlib
from typing import TYPE_CHECKING, Any, cast

from genr8_dist.errors import StoreError
from genr8_dist.store import views
from genr8_dist.store.audit import describe_missing, head_damaged, missing_manifests
from genr8_dist.store.manifest import (
    HEAD,
    Entry,
    Manifest,
    as_json,
    file_entries,
    first_commit,
    last_generations,
    list_manifests,
    manifest_rel,
    read_manifest,
)
from genr8_dist.store.schema import Event
from genr8_dist.store.transactions import Transactions

__all__ = ["Repair"]


class Repair(Transactions):
    """A store's ``verify`` and ``repair``."""

    if TYPE_CHECKING:
        def collect_garbage(self) -> int: ...   # store/garbage.py
    def verify(self) -> list[str]:
        """Problems with the committed files (missing, truncated, altered, unreadable) and with the
        manifests (the newest lost or damaged, an older one damaged), each naming its file; empty when
        the run is intact. Reads every committed byte."""
        return ([p for _, _, p in self._bad_entries(self._m, {})] + self._manifest_problems()
                + ([] if self._stale else views.view_problems(self._fs, self._m)))

    def _manifest_problems(self) -> list[str]:
        out = [self._stale] if self._stale else []
        if head_damaged(self._fs, HEAD):   # unreadable, or truncated to what still reads as a number
            out.append(f"{self._fs.show(HEAD)}: damaged (it should hold the newest commit's number)")
        listed = list_manifests(self._fs)
        out += describe_missing(missing_manifests(listed, self.version),
                                lambda v: self._fs.show(manifest_rel(v)))
        for version in listed:
            if version >= self.version:
                continue  # a newer one torn or altered is the stale newest manifest, above
            rel = manifest_rel(version)
            if read_manifest(self._fs, version) is None and self._fs.size(rel) is not None:
                out.append(f"{self._fs.show(manifest_rel(version))}: an older manifest is torn or altered "
                           "(a snapshot no longer in use; repair removes it)")
        return out

    def repair(self) -> list[str]:
        """Mend what ``verify`` finds, keeping every intact commit: a damaged configuration file is
        rewritten from the manifest's copy; a damaged individuals or events file is replaced by intact
        files an older manifest names holding the same commits, or else dropped alone (later commits
        stay); a lost or damaged newest manifest gives way to the newest intact one. What was dropped
        is said in one line (``last_repair``) and recorded with the problems in a "recovery" event.
        Returns the problems repaired (empty: nothing to do)."""
        cache: dict[tuple[str, str], str | None] = {}
        bad = self._bad_entries(self._m, cache)
        problems = [p for _, _, p in bad] + self._manifest_problems()
        view = [] if self._stale else views.view_problems(self._fs, self._m)
        if view and not problems:   # only the glob view: published again, no commit needed
            views.rebuild_view(self._fs, self._m)
            self.last_repair = f"rebuilt the glob view of commit {self.version}"
            return view
        if not problems:
            self.last_repair = ""
            return []
        with self._transaction():
            manifest, dropped, restored = self._mended(bad, cache)
            manifest["next_seq"] = self._m["next_seq"]
            manifest["generations"] = last_generations(manifest["individuals"])
            version = self._next_version(repairing=True)
            if self._stale:
                dropped.append(f"commit {version - 1}'s manifest (lost or damaged; its files are no "
                               "longer named)")
            line = "dropped " + "; ".join(dropped) if dropped else "dropped nothing"
            if restored:
                line += "; restored " + "; ".join(restored)
            last = max((int(g) for g in manifest["generations"].values()), default=0)
            detail = {
                "problems": problems,
                "dropped": line,
                "kept_commits_through": self.version,
                "generations": manifest["generations"],
            }
            self._add_events(manifest, [Event("recovery", last, None, detail)], version)
            self._publish(manifest, version)
        self.last_repair = line
        self.collect_garbage()
        return problems

    def _mended(self, bad: list[tuple[str, Entry, str]], cache: dict[tuple[str, str], str | None]
                ) -> tuple[Manifest, list[str], list[str]]:
        """The manifest with every damaged file restored, replaced or dropped; what was dropped and
        what was restored, each as short phrases."""
        m = copy.deepcopy(self._m)
        dropped: list[str] = []
        restored: list[str] = []
        damaged = {(e["path"], e["sha256"]) for _, e, _ in bad}
        older: list[Manifest] = []
        for version in sorted(list_manifests(self._fs), reverse=True):
            if version < self.version and (om := read_manifest(self._fs, version)) is not None:
                older.append(om)
        # configurations: rewritten from the manifest's copy; a run written before copies were kept
        # falls back to the state before the damaged version (the old rule)
        for e in list(m["configs"]):
            if (e["path"], e["sha256"]) not in damaged:
                continue
            text = e.get("toml")
            if isinstance(text, str) and hashlib.sha256(text.encode()).hexdigest() == e["sha256"]:
                new = self.write_file(f"configs/v{e['version']:04d}", ".toml", text.encode())
                e["path"] = new["path"]
                restored.append(f"configuration version {e['version']} (from the manifest's copy)")
                continue
            if e["commit"] <= m["configs"][0]["commit"]:
                problem = next(p for _, b, p in bad if b["path"] == e["path"])
                raise StoreError(f"{problem}; it belongs to the run's creation and the manifest "
                                 "holds no copy, so it cannot be repaired")
            cut = int(e["commit"])
            for kind, entry in file_entries(m):
                if first_commit(entry) >= cut:
                    dropped.append(_describe(kind, entry))
            m = _prefix(m, cut)
            break
        lists = as_json(m)   # every list of files, a feature's own included
        tails: list[Entry] = []
        for kind in [k for k, v in m.items() if isinstance(v, list) and k != "configs"]:
            kept: list[Any] = []
            for e in lists[kind]:
                if not isinstance(e, dict) or (e.get("path"), e.get("sha256")) not in damaged:
                    kept.append(e)
                    continue
                pieces = self._replacement(kind, e, older, cache)
                if pieces:
                    kept.extend(pieces)
                    restored.append(f"{e['path']} (from the {len(pieces)} file(s) it was compacted from)")
                else:
                    dropped.append(_describe(kind, e))
                    if kind == "individuals":
                        tails.append(e)
            lists[kind] = kept
        # events of a commit whose individuals were the newest of their islands describe generations
        # the run will make again: dropped with them, or a resumed run would record them twice
        for e in tails:
            newer = any(k["islands"][i][1] > span[1] for k in m["individuals"]
                        for i, span in e["islands"].items() if i in k["islands"])
            if newer:
                continue
            lo, hi = e["commits"]
            gone = [x for x in m["events"] if lo <= x["commits"][0] and x["commits"][1] <= hi]
            m["events"] = [x for x in m["events"] if x not in gone]
            dropped.extend(_describe("events", x) for x in gone)
        return m, dropped, restored

    def _replacement(self, kind: str, entry: Entry, older: list[Manifest],
                     cache: dict[tuple[str, str], str | None]) -> list[Entry]:
        """Intact files older manifests name that hold exactly ``entry``'s commits, or []."""
        if "commits" not in entry or "rows" not in entry:
            return []
        lo, hi = entry["commits"]
        candidates: dict[str, Entry] = {}
        for om in older:
            for e in as_json(om).get(kind, []):
                if (isinstance(e, dict) and e.get("path") != entry["path"] and "commits" in e
                        and lo <= e["commits"][0] and e["commits"][1] <= hi
                        and _within(e.get("islands", {}), entry.get("islands", {}))):
                    candidates.setdefault(e["path"], cast(Entry, e))
        chosen: list[Entry] = []
        end = lo - 1
        for e in sorted(candidates.values(), key=lambda x: (x["commits"][0], -x["commits"][1])):
            if e["commits"][0] <= end:
                continue
            k = (e["path"], e["sha256"])
            if k not in cache:
                cache[k] = self._check_entry(e, deep=True)
            if cache[k] is None:
                chosen.append(e)
                end = e["commits"][1]
        if not chosen or sum(e["rows"] for e in chosen) != entry["rows"]:
            return []
        return chosen


def _describe(kind: str, entry: Entry) -> str:
    """A dropped file in a few words: which commits, islands, generations, rows or events it held."""
    path = entry["path"]
    if kind == "individuals":
        spans = entry["islands"].values()
        lo = min(s[0] for s in spans) if spans else 0
        hi = max(s[1] for s in spans) if spans else 0
        isl = sorted(int(i) for i in entry["islands"])
        islands = f"island {isl[0]}" if len(isl) == 1 else f"islands {isl[0]}-{isl[-1]}"
        return f"{path} ({entry['rows']} individuals: {islands}, generations {lo}..{hi})"
    if kind == "events":
        return f"{path} ({entry['rows']} event(s), seq {entry['seq'][0]}..{entry['seq'][1]})"
    if kind == "configs":
        return f"{path} (configuration version {entry['version']})"
    return f"{path} ({kind})"


def _within(islands: dict[str, list[int]], outer: dict[str, list[int]]) -> bool:
    """Whether every island's generations in ``islands`` lie in ``outer``'s (a commit holds one part
    per island when the hosts write them: a replacement must be of the same islands)."""
    return all(i in outer and outer[i][0] <= lo and hi <= outer[i][1] for i, (lo, hi) in islands.items())


def _prefix(manifest: Manifest, first_bad: int) -> Manifest:
    """The state of ``manifest`` before commit ``first_bad`` (commits only append, so it is a prefix)."""
    out = copy.deepcopy(manifest)
    lists = as_json(out)
    for key, value in manifest.items():
        if isinstance(value, list) and value and all(isinstance(e, dict) and "path" in e for e in value):
            lists[key] = [e for e in lists[key] if first_commit(e) < first_bad]
    return out
