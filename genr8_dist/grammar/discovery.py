"""Finding universes: built-ins, plugin folders, paths, and installed packages' entry points.

Discovery order (the first universe found under a name wins):

1. built-ins: ``*.lark`` in :func:`genr8_dist.resources.grammars_dir` (``hemls.lark``, the parser's
   full language, is not a universe);
2. plugins shipped with genr8_dist: one folder each in :func:`genr8_dist.resources.plugins_dir`;
3. every folder in ``GENR8_PLUGINS`` (``os.pathsep``-separated; a folder holding a ``.lark`` is
   itself a plugin, otherwise each of its sub-folders is). The current directory is never searched:
   code runs only from where the user said (a copied run or download holding ``plugins/`` runs nothing);
4. installed packages: entry points in the group ``genr8_dist.universes`` whose value is a path to a
   ``.lark`` file or plugin folder, or ``module:attr`` naming such a path or a function returning one.

A path to a ``.lark`` file or plugin folder is accepted wherever a name is. A plugin that is broken
(two ``.lark`` files, an entry point that cannot be loaded) is listed with its one-line error and
fails only when it is itself loaded; every other universe keeps working.

Discovery reads a universe's files into a :class:`~genr8_dist.grammar.source.UniverseSource` and runs
none of its code; :func:`load_universe` builds it (running a plugin's modules, which naming it is
consent to).
"""

from __future__ import annotations

import os
import re
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from pathlib import Path

from genr8_dist.errors import UniverseError
from genr8_dist.grammar.source import UniverseSource
from genr8_dist.grammar.trust import consent, may_run, remember, remembered, require_trust
from genr8_dist.grammar.universe import Universe, build_universe
from genr8_dist.resources import grammars_dir, plugins_dir

__all__ = ["ENTRY_POINT_GROUP", "UniverseInfo", "consent_for_history", "consent_for_new_run",
           "consent_for_stored", "find_source",
           "installed_code_digest", "list_universes", "load_named_universe", "load_universe"]

ENTRY_POINT_GROUP = "genr8_dist.universes"
_NOT_UNIVERSES = {"hemls"}


@dataclass(frozen=True, slots=True)
class UniverseInfo:
    """A universe found by discovery: its name, where it came from, its ``.lark`` file, and the
    one-line ``error`` of a broken plugin (``None`` when it is sound as far as discovery can tell)."""

    name: str
    origin: str
    path: Path
    description: str = ""
    error: str | None = None


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
    try:
        if not root.is_dir():
            return []
        if any(root.glob("*.lark")):
            return [root]
        return sorted(p for p in root.iterdir() if p.is_dir() and not p.name.startswith((".", "_")))
    except OSError:
        return []


def _entry_point_infos() -> list[UniverseInfo]:
    import importlib.metadata

    try:
        eps = list(importlib.metadata.entry_points(group=ENTRY_POINT_GROUP))
    except Exception:  # a broken installed distribution's metadata: no entry points from there
        return []
    infos = []
    for ep in eps:
        found = getattr(ep, "dist", None)
        dist = found.name if found is not None else "?"
        origin = f"entry point:{dist}"
        value = ep.value.strip()
        try:
            if re.fullmatch(r"[\w.]+:[\w.]+", value):
                target = ep.load()
                target = target() if callable(target) else target
            else:
                target = value
            path = Path(os.fspath(target))
            lark = _plugin_lark(path) if path.is_dir() else path
            if lark is None or not lark.is_file():
                raise UniverseError(f"names {path}, which is neither a .lark file nor a plugin folder")
        except Exception as exc:  # a broken third-party package must not break discovery
            detail = str(exc) if isinstance(exc, UniverseError) else f"{type(exc).__name__}: {exc}"
            error = f"entry point '{ep.name}' of {dist} ({value}) cannot be loaded: {detail}"
            infos.append(UniverseInfo(ep.name, origin, Path(value), "", error.splitlines()[0]))
            continue
        infos.append(UniverseInfo(ep.name, origin, lark, _description(lark)))
    return infos


def _plugin_roots() -> list[Path]:
    listed = os.environ.get("GENR8_PLUGINS", "").split(os.pathsep)
    return [plugins_dir()] + [Path(p).expanduser() for p in listed if p.strip()]


def list_universes() -> list[UniverseInfo]:
    """Every universe discovery finds, in discovery order; a later one with a taken name is skipped.
    A broken plugin is listed with its ``error``."""
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
    done: set[Path] = set()
    for root in _plugin_roots():
        for folder in _plugin_folders(root):
            key = folder.resolve()
            if key in done:
                continue
            done.add(key)
            try:
                lark = _plugin_lark(folder)
            except UniverseError as exc:
                add(UniverseInfo(folder.name, f"plugin:{folder}", folder, "", str(exc)))
                continue
            if lark is not None:
                add(UniverseInfo(folder.name, f"plugin:{folder}", lark, _description(lark)))
    for info in _entry_point_infos():
        add(info)
    return infos


def _source_of(info: UniverseInfo) -> UniverseSource:
    if info.error is not None:
        raise UniverseError(info.error)
    lark = info.path.resolve()
    with_code = info.origin.startswith(("plugin:", "entry point:")) and lark.name != "hemls.lark"
    if info.origin == "built-in":
        with_code = False
    return UniverseSource.from_grammar_file(lark, info.name, str(lark), with_code=with_code)


def _path_source(path: Path) -> UniverseSource:
    """The universe at a path: a ``.lark`` file (with the ``.py`` beside it when its folder is named
    like it, i.e. it is a plugin's) or a plugin folder."""
    path = path.resolve()
    if path.is_file():
        hooks = path.parent / "hooks.py"
        with_code = hooks.is_file() and path.parent.name == path.stem
        return UniverseSource.from_grammar_file(path, path.stem, str(path), with_code=with_code)
    lark = _plugin_lark(path)
    if lark is None:
        raise UniverseError(f"{path}: folder holds no .lark file, so it is not a universe")
    return UniverseSource.from_grammar_file(lark, path.name, str(lark), with_code=True)


def _looks_like_path(text: str) -> bool:
    return text.endswith(".lark") or os.sep in text or "/" in text or text.startswith((".", "~"))


def find_source(name: str | os.PathLike[str], base_dir: str | os.PathLike[str] | None = None
                ) -> tuple[UniverseSource, str]:
    """The files of the universe called ``name``, or at the path ``name`` (relative paths resolved
    against ``base_dir``, default the current directory), and its origin (``built-in``,
    ``plugin:<folder>``, ``entry point:<dist>`` or ``path``). Reads files; runs no code."""
    text = os.fspath(name)
    if not isinstance(text, str) or not text.strip():
        raise UniverseError(f"a universe is named by a non-empty string, got {name!r}")
    if not _looks_like_path(text):
        for info in list_universes():
            if info.name == text:
                return _source_of(info), info.origin
    path = Path(text).expanduser()
    if not path.is_absolute() and base_dir is not None:
        path = Path(base_dir) / path
    if path.exists():
        return _path_source(path), "path"
    if _looks_like_path(text):
        raise UniverseError(f"{path}: no such universe file or plugin folder")
    usable = [info.name for info in list_universes() if info.error is None]
    raise UniverseError(f"unknown universe '{text}' (known: {', '.join(usable)}); give one of these names or "
                        "a path to a .lark file or plugin folder")


def installed_code_digest(name: str) -> str | None:
    """The code digest of the installed universe called ``name`` (``None`` when there is none)."""
    for info in list_universes():
        if info.name == name and info.error is None and info.origin != "built-in":
            try:
                return _source_of(info).code_digest
            except UniverseError:
                return None
    return None


def load_universe(name: str | os.PathLike[str]) -> Universe:
    """The universe called ``name`` (built-in, plugin or entry point), or at the path ``name``.

    Naming a universe is consent to run its plugin code. Compiled universes are cached (keyed by the
    digest of their files), so loading one again is cheap. Raises :class:`UniverseError` for an
    unknown name, a broken plugin or a malformed universe, in one line naming file, line and fault.
    """
    source, origin = find_source(name)
    consent(source.code_digest)
    return build_universe(source, origin=origin)


def consent_for_history(source: UniverseSource) -> bool:
    """Whether a history command (``show``, ``gallery``, the report) may run ``source``'s code, giving
    consent if so: only when the code is byte for byte the installed plugin's of the same name, or a
    digest this machine already trusted (the user's own code either way). Never anything else."""
    digest = source.code_digest
    if may_run(digest):
        return True
    if digest in remembered() or installed_code_digest(source.name) == digest:
        consent(digest)
        return True
    return False


def consent_for_new_run(source: UniverseSource, *, trust_flag: bool, command: str = "run",
                        ask: Callable[[str], bool] | None = None) -> None:
    """Consent to the code of a universe named by a path (in a run TOML, on the command line) or
    carried in a TOML's ``[stored_universe]``, or refuse in one line (``UniverseError``).

    An installed plugin's code (same name, same digest) and a digest this machine trusted before run
    at once. Other code runs only with ``trust_flag`` (``--trust-hooks``) or a yes to ``ask`` (a
    prompt, on a terminal only); its digest is then remembered. A notice is not consent."""
    digest = source.code_digest
    if may_run(digest):
        return
    if installed_code_digest(source.name) == digest or digest in remembered():
        consent(digest)
        return
    modules = ", ".join(f"{m}.py" for m in source.modules)
    what = (f"universe '{source.name}' carries Python code ({modules} from {source.folder}, sha256 "
            f"{digest[:16]}...)")
    asker = ask if ask is not None else _terminal_prompt
    if trust_flag or asker(f"genr8: {what}; run it, and trust it from now on? [y/N] "):
        remember(digest, f"universe {source.name} ({source.folder})")
        consent(digest)
        return
    raise UniverseError(f"{what} that this machine has not trusted; read it, then run `genr8 {command} "
                        "--trust-hooks` (the trust rule: docs/run-store.md)")


def _terminal_prompt(question: str) -> bool:
    """Ask ``question`` on the terminal; False at once when standard input or error is not one."""
    import sys

    if not (sys.stdin is not None and sys.stdin.isatty() and sys.stderr.isatty()):
        return False
    print(question, end="", file=sys.stderr, flush=True)
    try:
        answer = sys.stdin.readline()
    except (OSError, KeyboardInterrupt):
        return False
    return answer.strip().lower() in ("y", "yes")


def load_named_universe(name: str | os.PathLike[str], *, trust_flag: bool, command: str) -> Universe:
    """``load_universe`` for a command line's ``--universe``: a plugin folder given by a path runs its
    code only with consent (:func:`consent_for_new_run`); a name (built-in, shipped or installed
    plugin, entry point) is the user's own choice."""
    source, origin = find_source(name)
    if origin == "path":
        source.check_hook_names()   # read, not run: a misspelt hook is named before consent is asked
        consent_for_new_run(source, trust_flag=trust_flag, command=command)
    else:
        consent(source.code_digest)
    return build_universe(source, origin=origin)


def consent_for_stored(sources: Iterable[UniverseSource], *, trust_flag: bool, command: str) -> None:
    """:func:`require_trust` for every universe a run stores (one per configuration version)."""
    for source in sources:
        require_trust(source, trust_flag=trust_flag, command=command, installed=installed_code_digest)
