"""The run directory's format: its folders and its numbered manifests (docs/run-store.md).

A manifest (``_manifest/0000000001.json``) is a complete snapshot of a run: what the run is (run id,
criteria, sizes, columns, meshing, schema version, layout), every committed file with its rows, size
and sha256 (``configs``, ``individuals``, ``events``, and any list a later feature adds the same way),
each island's last committed generation and the next event ``seq``. It is JSON with a checksum over
its body: one that is torn, altered or not a run manifest reads as None. ``_manifest/HEAD`` holds the
newest commit's number. How commits publish manifests: ``store/transactions.py``.
"""

from __future__ import annotations

import hashlib
import json
import re
from datetime import UTC, datetime
from typing import Any, NotRequired, TypedDict, cast

from genr8_dist.errors import StoreError
from genr8_dist.store._fs import RunFS
from genr8_dist.store.schema import SCHEMA_VERSION

__all__ = [
    "FORMAT",
    "HEAD",
    "KEEP_MANIFESTS",
    "LAYOUT_FOLDERS",
    "MANIFEST_DIR",
    "REL_PATH",
    "Entry",
    "Manifest",
    "add_entries",
    "as_json",
    "decode_manifest",
    "encode_manifest",
    "file_entries",
    "first_commit",
    "is_int",
    "last_generations",
    "list_manifests",
    "load_state",
    "manifest_rel",
    "read_head",
    "read_manifest",
    "utc_now",
]
FORMAT = "genr8-run"
MANIFEST_DIR = "_manifest"
KEEP_MANIFESTS = 16          # manifests kept for concurrent readers and for repair()
HEAD = f"{MANIFEST_DIR}/HEAD"   # the newest commit's number, written after its manifest is linked
_MANIFEST_NAME = re.compile(r"^(\d{10})\.json$")
REL_PATH = re.compile(r"^[A-Za-z0-9_][A-Za-z0-9._-]{0,200}(/[A-Za-z0-9_][A-Za-z0-9._-]{0,200}){1,3}$")
_SHA256 = re.compile(r"^[0-9a-f]{64}$")
LAYOUT_FOLDERS = {MANIFEST_DIR, "configs", "individuals", "events"}


class Entry(TypedDict):
    """One file a manifest names: ``path`` (inside the run), ``bytes`` and ``sha256``, whatever list
    names it; the other keys belong to the lists said."""

    path: str
    bytes: int
    sha256: str
    rows: NotRequired[int]                      # individuals, events: the Parquet file's rows
    commits: NotRequired[list[int]]             # individuals, events: the first and last commit held
    islands: NotRequired[dict[str, list[int]]]  # individuals: each island's first and last generation
    seq: NotRequired[list[int]]                 # events: the first and last event seq held
    version: NotRequired[int]                   # configs: the configuration version
    effective_generation: NotRequired[int]      # configs: the generation it is in force from
    created: NotRequired[str]                   # configs: when it was recorded (ISO 8601)
    commit: NotRequired[int]                    # configs: the commit that recorded it
    toml: NotRequired[str]                      # configs: its text, which repair() restores it from


class Manifest(TypedDict):
    """A run's committed state, as ``_manifest/NNNNNNNNNN.json`` holds it. A key marked "absent" is
    missing from runs written before it was kept. A feature's own list of files is one more key
    (``add_entries``), read through ``as_json``."""

    format: str                                 # FORMAT
    schema_version: int                         # the store schema the run was created with
    layout: NotRequired[int]                    # 2: data files in _files/ (absent: layout 1)
    run_id: str
    criteria: list[str]
    sizes: NotRequired[list[str]]               # absent: a run of schema 1 or 2
    columns: NotRequired[list[list[str | bool]]]  # [name, type, nullable]; absent: schema 1
    meshing: NotRequired[int]                   # absent: meshing 1
    screen: NotRequired[int]                    # the ea.screen its configurations default to; absent: 1
    created: NotRequired[str]
    version: int                                # the commit number
    written: NotRequired[str]                   # when this commit was published
    upgraded: NotRequired[dict[str, int]]       # repair --upgrade: from_layout, at_commit
    checksum: NotRequired[str]                  # sha256 of the rest (on disk only)
    configs: list[Entry]
    individuals: list[Entry]
    events: list[Entry]
    generations: dict[str, int]                 # each island's last committed generation
    next_seq: int                               # the next event's seq


def as_json(manifest: Manifest) -> dict[str, Any]:
    """``manifest`` as the JSON object it is (the same object), for code that walks every key: the
    lists of files a feature adds are keys the type does not declare."""
    return cast(dict[str, Any], manifest)


def add_entries(manifest: Manifest, key: str, entries: list[Entry]) -> None:
    """List ``entries`` (from ``RunStore.write_file``) under the feature's own ``key`` of ``manifest``
    (in ``add(manifest, version)`` of a commit): verify, repair and garbage collection know them."""
    as_json(manifest).setdefault(key, []).extend(entries)


def utc_now() -> datetime:
    return datetime.now(UTC)


def _body_digest(body: dict[str, object]) -> str:
    text = json.dumps(body, sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()


def encode_manifest(m: Manifest) -> bytes:
    body = {k: v for k, v in m.items() if k != "checksum"}
    out = dict(body, checksum=_body_digest(body))
    return (json.dumps(out, sort_keys=True, indent=1) + "\n").encode()


def decode_manifest(data: bytes) -> Manifest | None:
    """The manifest in ``data``, or None when it is torn, altered or not a run manifest."""
    try:
        m = json.loads(data)
    except (ValueError, UnicodeDecodeError):
        return None
    if not isinstance(m, dict) or m.get("format") != FORMAT:
        return None
    body = {k: v for k, v in m.items() if k != "checksum"}
    if m.get("checksum") != _body_digest(body):
        return None
    try:
        _check_manifest(m)
    except (ValueError, TypeError, KeyError, AttributeError):
        return None
    return cast(Manifest, m)


def is_int(value: object) -> bool:
    return isinstance(value, int) and not isinstance(value, bool)


def _check_range(value: object) -> None:
    if not (isinstance(value, list) and len(value) == 2 and all(is_int(v) for v in value)
            and value[0] <= value[1]):
        raise ValueError(f"not a range: {value!r}")


def file_entries(manifest: Manifest) -> list[tuple[str, Entry]]:
    """Every file a manifest names, as ``(kind, entry)``: the kind is the manifest key listing it
    (``configs``, ``individuals``, ``events``, or any list a later feature adds the same way)."""
    out: list[tuple[str, Entry]] = []
    for key, value in manifest.items():
        if isinstance(value, list) and value and all(isinstance(e, dict) and "path" in e for e in value):
            out.extend((key, e) for e in value)
    return out


def _check_manifest(m: dict[str, Any]) -> None:
    """Raise ``ValueError`` unless ``m`` is well formed and names only files inside the run."""
    if not is_int(m["version"]) or not is_int(m["next_seq"]) or not isinstance(m["run_id"], str):
        raise ValueError("header")
    if not (isinstance(m["criteria"], list) and all(isinstance(c, str) for c in m["criteria"])):
        raise ValueError("criteria")
    for key in ("configs", "individuals", "events"):
        if not isinstance(m[key], list):
            raise ValueError(key)
    for kind, e in file_entries(cast(Manifest, m)):
        path = e["path"]
        if (not isinstance(path, str) or not REL_PATH.match(path) or path.startswith(MANIFEST_DIR + "/")
                or not is_int(e["bytes"]) or e["bytes"] < 0 or not isinstance(e["sha256"], str)
                or not _SHA256.match(e["sha256"])):
            raise ValueError(f"{kind} entry {path!r}")
        if kind == "configs":
            if not (is_int(e["version"]) and is_int(e["effective_generation"]) and is_int(e["commit"])
                    and isinstance(e["created"], str)):
                raise ValueError("config entry")
        elif kind in ("individuals", "events"):
            if not is_int(e["rows"]):
                raise ValueError("rows")
            _check_range(e["commits"])
            if kind == "events":
                _check_range(e["seq"])
            else:
                if not isinstance(e["islands"], dict):
                    raise ValueError("islands")
                for island, span in e["islands"].items():
                    int(island)
                    _check_range(span)
    if not isinstance(m["generations"], dict):
        raise ValueError("generations")
    for island, g in m["generations"].items():
        int(island)
        if not is_int(g):
            raise ValueError("generations")


def manifest_rel(version: int) -> str:
    return f"{MANIFEST_DIR}/{version:010d}.json"


def last_generations(entries: list[Entry]) -> dict[str, int]:
    last: dict[str, int] = {}
    for e in entries:
        for island, (_, gmax) in e["islands"].items():
            last[island] = max(last.get(island, -1), gmax)
    return dict(sorted(last.items(), key=lambda kv: int(kv[0])))


def first_commit(entry: Entry) -> int:
    return int(entry["commits"][0]) if "commits" in entry else int(entry["commit"])


def list_manifests(rfs: RunFS) -> list[int]:
    return sorted(int(m.group(1)) for n in rfs.listdir(MANIFEST_DIR) if (m := _MANIFEST_NAME.match(n)))


def read_manifest(rfs: RunFS, version: int) -> Manifest | None:
    try:
        data = rfs.read_bytes(manifest_rel(version))
    except OSError:
        return None
    manifest = decode_manifest(data)
    if manifest is not None and manifest.get("version") != version:
        return None
    return manifest


def read_head(rfs: RunFS) -> int | None:
    """The commit number ``_manifest/HEAD`` records, or None (absent: a run written before it was
    kept; unreadable: damaged, which ``verify`` reports)."""
    try:
        text = rfs.read_bytes(HEAD).decode().strip()
    except (OSError, UnicodeDecodeError):
        return None
    return int(text) if text.isdigit() and len(text) <= 10 else None


def load_state(rfs: RunFS) -> tuple[Manifest | None, str | None]:
    """The highest-numbered intact manifest (None when there is none) and, when the newest manifest
    is lost or damaged, a line saying so. Refuses runs written by a newer schema."""
    head = read_head(rfs)  # read before listing: a writer links its manifest before writing HEAD
    skipped: list[int] = []
    for version in sorted(list_manifests(rfs), reverse=True):
        manifest = read_manifest(rfs, version)
        if manifest is None:
            if rfs.size(manifest_rel(version)) is not None:  # not merely pruned by a writer
                skipped.append(version)
            continue
        found = manifest.get("schema_version")
        if not isinstance(found, int) or not is_int(found) or found > SCHEMA_VERSION:
            raise StoreError(
                f"{rfs.show(manifest_rel(version))}: schema version {found!r} is newer than this "
                f"genr8_dist reads ({SCHEMA_VERSION}); upgrade genr8_dist"
            )
        if skipped:
            return manifest, (f"{rfs.show(manifest_rel(max(skipped)))}: the newest manifest is torn or "
                              f"altered; the run would read as commit {version}")
        if head is not None and head > version:
            return manifest, (f"{rfs.show(manifest_rel(head))}: the newest manifest (commit {head}, "
                              f"recorded in {HEAD}) is missing; the run would read as commit {version}")
        return manifest, None
    return None, None
