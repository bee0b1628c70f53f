"""Finding universes: built-ins, plugin folders, paths, and installed packages' entry points.

Discovery order (the first universe found under a name wins):

1. built-ins: ``*.lark`` in :func:`genr8_dist.resources.grammars_dir` (``hemls.lark``, the parser's
   full language, is not a universe);
2. plugins shipped with genr8_dist: one folder each in :func:`genr8_dist.resources.plugins_dir`;
3. ``./plugins`` in the current directory, then every folder in ``GENR8_PLUGINS``
   (``os.pathsep``-separated; a folder holding a ``.lark`` is itself a plugin, otherwise each of its
   sub-folders is);
4. installed packages: entry points in the group ``genr8_dist.universes`` whose value is a path to a
   ``.lark`` file or plugin folder, or ``module:attr`` naming such a path or a function returning one.

A path to a ``.lark`` file or plugin folder is accepted wherever a name is.
"""

from __future__ import annotations

import os
import re
import threading
from dataclasses import dataclass
from pathlib import Path

from genr8_dist.errors import UniverseError
from genr8_dist.grammar.compiler import read_grammar_file
from genr8_dist.grammar.hooks import load_hooks
from genr8_dist.grammar.universe import Universe
from genr8_dist.resources import grammars_dir, plugins_dir

__all__ = ["ENTRY_POINT_GROUP", "UniverseInfo", "list_universes", "load_universe"]

ENTRY_POINT_GROUP = "genr8_dist.universes"
_NOT_UNIVERSES = {"hemls"}
_CACHE: dict[tuple, Universe] = {}
_LOCK = threading.Lock()


@dataclass(frozen=True, slots=True)
class UniverseInfo:
    """A universe found by discovery: its name, where it came from, its ``.lark`` file."""

    name: str
    origin: str
    path: Path
    description: str = ""


def _plugin_lark(folder: Path) -> Path | None:
    """A plugin folder's ``.lark``: ``<folder name>.lark``, else ``universe.lark``, else the only one."""
    for candidate in (folder / f"{folder.name}.lark", folder / "universe.lark"):
        if candidate.is_file():
            return candidate
    found = sorted(folder.glob("*.lark"))
    if len(found) == 1:
        return found[0]
    if len(found) > 1:
        raise UniverseError(f"{folder}: a plugin folder holds one .lark file (or <name>.lark or "
                            f"universe.lark); found {', '.join(p.name for p in found)}")
    return None


def _description(path: Path) -> str:
    try:
        for line in path.read_text(encoding="utf-8").splitlines():
            m = re.match(r"^\s*//@\s*description\s+(.*?)\s*$", line)
            if m:
                return m.group(1)
    except (OSError, UnicodeDecodeError):
        return ""
    return ""


def _plugin_folders(root: Path) -> list[Path]:
    if not root.is_dir():
        return []
    if any(root.glob("*.lark")):
        return [root]
    return sorted(p for p in root.iterdir() if p.is_dir() and not p.name.startswith((".", "_")))


def _entry_point_infos() -> list[UniverseInfo]:
    from importlib.metadata import entry_points

    infos = []
    for ep in entry_points(group=ENTRY_POINT_GROUP):
        dist = ep.dist.name if ep.dist is not None else "?"
        origin = f"entry point:{dist}"
        value = ep.value.strip()
        try:
            if re.fullmatch(r"[\w.]+:[\w.]+", value):
                target = ep.load()
                target = target() if callable(target) else target
            else:
                target = value
            path = Path(os.fspath(target))
        except Exception as exc:  # a broken third-party package must not break discovery
            raise UniverseError(f"entry point '{ep.name}' of {dist} ({value}) cannot be loaded: "
                                f"{type(exc).__name__}: {exc}") from None
        lark = _plugin_lark(path) if path.is_dir() else path
        if lark is None or not lark.is_file():
            raise UniverseError(f"entry point '{ep.name}' of {dist} names {path}, which is neither a "
                                ".lark file nor a plugin folder")
        infos.append(UniverseInfo(ep.name, origin, lark, _description(lark)))
    return infos


def list_universes() -> list[UniverseInfo]:
    """Every universe discovery finds, in discovery order; a later one with a taken name is skipped."""
    infos: list[UniverseInfo] = []
    seen: set[str] = set()

    def add(info: UniverseInfo) -> None:
        if info.name not in seen:
            seen.add(info.name)
            infos.append(info)

    builtin = grammars_dir()
    if builtin.is_dir():
        for path in sorted(builtin.glob("*.lark")):
            if path.stem not in _NOT_UNIVERSES:
                add(UniverseInfo(path.stem, "built-in", path, _description(path)))
    roots = [plugins_dir(), Path.cwd() / "plugins"]
    roots += [Path(p) for p in os.environ.get("GENR8_PLUGINS", "").split(os.pathsep) if p.strip()]
    done: set[Path] = set()
    for root in roots:
        for folder in _plugin_folders(root):
            key = folder.resolve()
            if key in done:
                continue
            done.add(key)
            lark = _plugin_lark(folder)
            if lark is not None:
                add(UniverseInfo(folder.name, f"plugin:{folder}", lark, _description(lark)))
    for info in _entry_point_infos():
        add(info)
    return infos


def _build(name: str, origin: str, lark: Path) -> Universe:
    lark = lark.resolve()
    try:
        stat = lark.stat()
    except OSError as exc:
        raise UniverseError(f"{lark}: cannot read universe file: {exc.strerror or exc}") from None
    hooks_file = lark.parent / "hooks.py"
    plugin = origin.startswith(("plugin:", "entry point:")) or (origin == "path" and hooks_file.is_file()
                                                                and lark.parent.name == name)
    hooks_stat = hooks_file.stat().st_mtime_ns if plugin and hooks_file.is_file() else None
    key = (name, origin, str(lark), stat.st_mtime_ns, stat.st_size, hooks_stat)
    with _LOCK:
        cached = _CACHE.get(key)
    if cached is not None:
        return cached
    text = read_grammar_file(lark)
    hooks = load_hooks(lark.parent) if plugin else None
    universe = Universe(name, origin, lark, text, hooks)
    with _LOCK:
        _CACHE[key] = universe
    return universe


def load_universe(name: str | os.PathLike[str]) -> Universe:
    """The universe called ``name`` (built-in, plugin or entry point), or at the path ``name``.

    Compiled universes are cached (keyed by file, size and modification time), so loading one again
    is free. Raises :class:`UniverseError` for an unknown name or a malformed ``.lark`` file.
    """
    text = os.fspath(name)
    if not isinstance(text, str) or not text.strip():
        raise UniverseError(f"a universe is named by a non-empty string, got {name!r}")
    looks_like_path = text.endswith(".lark") or os.sep in text or "/" in text
    if not looks_like_path:
        for info in list_universes():
            if info.name == text:
                return _build(info.name, info.origin, info.path)
    path = Path(text).expanduser()
    if path.is_file():
        return _build(path.stem, "path", path)
    if path.is_dir():
        lark = _plugin_lark(path)
        if lark is not None:
            return _build(path.name, "path", lark)
        raise UniverseError(f"{path}: folder holds no .lark file, so it is not a universe")
    if looks_like_path:
        raise UniverseError(f"{text}: no such universe file or plugin folder")
    known = ", ".join(info.name for info in list_universes())
    raise UniverseError(f"unknown universe '{text}' (known: {known}); give one of these names or a "
                        "path to a .lark file or plugin folder")
