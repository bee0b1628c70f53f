"""A universe's source: the files it consists of, as text, so that a run can carry it.

A universe is one ``.lark`` grammar plus, for a plugin, the Python modules beside it (``hooks.py``
and any other top-level ``*.py`` a plugin brings, e.g. a phenotype module). :class:`UniverseSource`
holds them as ``(file name, text)`` pairs with their digests; it is what a run stores in its
configuration, what travels to every Ray host, and what a universe is built from. Nothing here runs
a plugin's code: modules are executed only by :func:`load_modules`, and only for a code digest the
process has consented to (:mod:`genr8_dist.grammar.trust`).
"""

from __future__ import annotations

import ast
import difflib
import functools
import hashlib
import importlib.abc
import importlib.machinery
import linecache
import re
import sys
import threading
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from types import ModuleType
from typing import Any

from genr8_dist.errors import UniverseError, located

__all__ = ["KNOWN_HOOKS", "MAX_FILE_BYTES", "UniverseSource", "load_modules"]

KNOWN_HOOKS: tuple[str, ...] = ("repair",)   # the functions hooks.py may define
MAX_FILE_BYTES = 1_000_000                             # one file of a universe, at most
_FILE_NAME = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*\.(lark|py)$")


@functools.lru_cache(maxsize=64)
def _digest(files: tuple[tuple[str, str], ...]) -> str:
    """The sha256 of ``files``, once per process and files: a host asks for its universe's digest at
    every evaluation (``build_universe`` keys its cache by it), and hashing the files each time cost
    more than half of a simulated host's CPU (bench/scale.py)."""
    h = hashlib.sha256()
    for name, text in files:
        data = text.encode("utf-8")
        h.update(f"{name}\0{len(data)}\0".encode())
        h.update(data)
    return h.hexdigest()


@dataclass(frozen=True)
class UniverseSource:
    """The files of one universe: exactly one ``.lark`` and any number of top-level ``.py`` modules.

    ``name`` is the universe's name; ``origin`` says where the files were read (a folder, ``built-in``,
    ``stored in <run>``) and takes no part in equality. ``digest`` covers every file;
    ``code_digest`` only the Python modules (``""`` when there are none): consent is given per
    ``code_digest``.
    """

    name: str
    files: tuple[tuple[str, str], ...]
    origin: str = field(default="", compare=False)

    def __post_init__(self) -> None:
        files = tuple(sorted((str(n), str(t)) for n, t in self.files))
        object.__setattr__(self, "files", files)
        where = self.origin or f"universe '{self.name}'"
        if not isinstance(self.name, str) or not re.fullmatch(r"[A-Za-z0-9_][A-Za-z0-9_.-]*", self.name):
            raise UniverseError(f"{where}: a universe name is letters, digits, '_', '.' or '-', "
                                f"got {self.name!r}")
        for name, text in files:
            if not _FILE_NAME.match(name):
                raise UniverseError(f"{where}: file name {name!r} is not a universe file "
                                    "(one .lark grammar and Python modules named like identifiers)")
            if len(text.encode("utf-8")) > MAX_FILE_BYTES:
                raise UniverseError(f"{where}: {name} is larger than {MAX_FILE_BYTES} bytes")
        larks = [n for n, _ in files if n.endswith(".lark")]
        if len(larks) != 1:
            raise UniverseError(f"{where}: a universe has exactly one .lark file, found "
                                f"{', '.join(larks) or 'none'}")

    # -- reading ------------------------------------------------------------------------------

    @classmethod
    def from_grammar_file(cls, lark: Path, name: str, origin: str, *, with_code: bool) -> UniverseSource:
        """The universe of ``lark`` (and, ``with_code``, every ``*.py`` beside it), read now."""
        files = [(lark.name, _read(lark))]
        if with_code:
            for py in sorted(lark.parent.glob("*.py")):
                if py.is_file():
                    files.append((py.name, _read(py)))
        return cls(name, tuple(files), origin=origin)

    @classmethod
    def from_dict(cls, data: Any, where: str) -> UniverseSource:
        """A source stored in a configuration (``{name, digest, files}``); the digest must match."""
        if not isinstance(data, Mapping):
            raise UniverseError(f"{where}: [stored_universe] must be a table, got {data!r}")
        unknown = sorted(set(data) - {"name", "digest", "files"})
        if unknown:
            raise UniverseError(f"{where}: [stored_universe] has unknown key '{unknown[0]}' "
                                "(allowed: name, digest, files)")
        files = data.get("files")
        if not isinstance(files, Mapping) or not all(isinstance(v, str) for v in files.values()):
            raise UniverseError(f"{where}: [stored_universe.files] must map file names to their text")
        source = cls(str(data.get("name", "")), tuple(files.items()), origin=where)
        if data.get("digest") != source.digest:
            raise UniverseError(f"{where}: the stored universe's digest {str(data.get('digest'))[:16]}... "
                                f"does not match its files ({source.digest[:16]}...): it was altered")
        return source

    def to_dict(self) -> dict[str, Any]:
        """The table stored in a configuration as ``[stored_universe]``."""
        return {"name": self.name, "digest": self.digest, "files": dict(self.files)}

    # -- what it holds ------------------------------------------------------------------------

    @property
    def grammar_file(self) -> str:
        """The ``.lark`` file's name."""
        return next(n for n, _ in self.files if n.endswith(".lark"))

    @property
    def grammar_text(self) -> str:
        return next(t for n, t in self.files if n.endswith(".lark"))

    def text(self, file_name: str) -> str | None:
        """The text of ``file_name``, ``None`` when the universe has no such file."""
        return next((t for n, t in self.files if n == file_name), None)

    @property
    def modules(self) -> tuple[str, ...]:
        """The Python modules' names (``hooks``, ``phenotype``, ...)."""
        return tuple(n[:-3] for n, _ in self.files if n.endswith(".py"))

    @property
    def digest(self) -> str:
        return _digest(self.files)

    @property
    def code_digest(self) -> str:
        code = tuple(f for f in self.files if f[0].endswith(".py"))
        return _digest(code) if code else ""

    @property
    def folder(self) -> str:
        """Where the files were read (a folder), or the run that stores them."""
        return str(Path(self.origin).parent) if self.origin.endswith(".lark") else self.origin or self.name

    def where(self, file_name: str) -> str:
        """How errors name ``file_name`` of this universe: its path when the files were read from a
        folder (``origin`` is then the ``.lark`` file's path), else ``<origin>/<file name>``."""
        if self.origin.endswith(".lark"):
            return str(Path(self.origin).parent / file_name)
        return f"{self.origin or self.name}/{file_name}"

    def hook_functions(self) -> list[tuple[str, int]]:
        """The public top-level functions ``hooks.py`` defines, with their lines (no code is run)."""
        text = self.text("hooks.py")
        if text is None:
            return []
        try:
            tree = ast.parse(text, filename="hooks.py")
        except SyntaxError as exc:
            raise UniverseError(located(f"hooks.py is not valid Python: {exc.msg}", self.where("hooks.py"),
                                        exc.lineno or 0, exc.offset or 0)) from None
        functions = (ast.FunctionDef, ast.AsyncFunctionDef)
        return [(node.name, node.lineno) for node in tree.body
                if isinstance(node, functions) and not node.name.startswith("_")]

    def check_hook_names(self) -> None:
        """Refuse a public function of ``hooks.py`` that is no known hook (a misspelt one is named)."""
        for name, line in self.hook_functions():
            if name in KNOWN_HOOKS:
                continue
            near = difflib.get_close_matches(name, KNOWN_HOOKS, n=1, cutoff=0.6)
            hint = f"did you mean '{near[0]}'? " if near else ""
            raise UniverseError(located(
                f"unknown hook '{name}': {hint}hooks.py may define {', '.join(KNOWN_HOOKS)}; "
                "start helper functions' names with '_'", self.where("hooks.py"), line, 1))

    def __reduce__(self) -> tuple[Callable[[str, tuple[tuple[str, str], ...], str, bool], UniverseSource],
                                  tuple[str, tuple[tuple[str, str], ...], str, bool]]:
        """Pickled with whether this process consented to its code, so that a Ray host may run the
        code the driver consented to (a source read from a file never carries consent)."""
        from genr8_dist.grammar.trust import may_run

        return (_unpickle, (self.name, self.files, self.origin, may_run(self.code_digest)))


def _unpickle(name: str, files: tuple[tuple[str, str], ...], origin: str, consented: bool) -> UniverseSource:
    from genr8_dist.grammar.trust import consent

    source = UniverseSource(name, files, origin=origin)
    if consented and source.code_digest:
        consent(source.code_digest)
    return source


def _read(path: Path) -> str:
    try:
        size = path.stat().st_size
        if size > MAX_FILE_BYTES:
            raise UniverseError(f"{path}: larger than {MAX_FILE_BYTES} bytes; a universe file is text")
        return path.read_text(encoding="utf-8")
    except OSError as exc:
        raise UniverseError(f"{path}: cannot read universe file: {exc.strerror or exc}") from None
    except UnicodeDecodeError as exc:
        raise UniverseError(f"{path}: universe file is not UTF-8: {exc.reason}") from None


# ----------------------------------------------------------------------------- running modules


class _SourceFinder(importlib.abc.MetaPathFinder, importlib.abc.Loader):
    """Imports a universe's modules from their text: package ``genr8_universe_<digest>``, one
    sub-module per ``.py`` file, so that ``from . import other`` works between a plugin's modules."""

    def __init__(self) -> None:
        self.packages: dict[str, UniverseSource] = {}

    def find_spec(self, fullname: str, path: Any = None, target: Any = None
                  ) -> importlib.machinery.ModuleSpec | None:
        package, _, module = fullname.partition(".")
        source = self.packages.get(package)
        if source is None:
            return None
        if not module:
            return importlib.machinery.ModuleSpec(fullname, self, is_package=True)
        if "." in module or module not in source.modules:
            return None
        spec = importlib.machinery.ModuleSpec(fullname, self, origin=source.where(f"{module}.py"))
        spec.has_location = True
        return spec

    def create_module(self, spec: importlib.machinery.ModuleSpec) -> None:
        return None

    def exec_module(self, module: ModuleType) -> None:
        package, _, name = module.__name__.partition(".")
        if not name:
            module.__path__ = []
            return
        source = self.packages[package]
        where = source.where(f"{name}.py")
        text = source.text(f"{name}.py") or ""
        module.__file__ = where
        linecache.cache[where] = (len(text), None, text.splitlines(keepends=True), where)
        exec(compile(text, where, "exec"), module.__dict__)


_FINDER = _SourceFinder()
_MODULES: dict[str, dict[str, ModuleType]] = {}
_LOCK = threading.RLock()


def load_modules(source: UniverseSource) -> dict[str, ModuleType]:
    """Run the universe's Python modules (once per process) and return them by name.

    Refuses (``UniverseError``) a code digest this process has not consented to; a module that
    raises on import is a one-line error naming its file.
    """
    from genr8_dist.grammar.trust import may_run

    digest = source.code_digest
    if not digest:
        return {}
    if not may_run(digest):
        files = ", ".join(f"{m}.py" for m in source.modules)
        raise UniverseError(
            f"universe '{source.name}': refusing to run its Python code ({files}, sha256 {digest[:16]}...) "
            "without consent; see the trust rule in docs/run-store.md")
    with _LOCK:
        done = _MODULES.get(digest)
        if done is not None:
            return done
        package = f"genr8_universe_{digest[:24]}"
        if _FINDER not in sys.meta_path:
            sys.meta_path.insert(0, _FINDER)
        _FINDER.packages[package] = source
        loaded: dict[str, ModuleType] = {}
        for name in source.modules:
            try:
                loaded[name] = importlib.import_module(f"{package}.{name}")
            except (Exception, SystemExit) as exc:  # a plugin's own bug: one line, its file
                for key in [k for k in sys.modules if k == package or k.startswith(package + ".")]:
                    sys.modules.pop(key, None)
                line = getattr(exc, "lineno", None) or _line_in(exc, source.where(f"{name}.py"))
                where = located("", source.where(f"{name}.py"), line or 0).rstrip(": ")
                raise UniverseError(f"{where}: importing the plugin's {name}.py failed: "
                                    f"{type(exc).__name__}: {_first_line(exc)}") from None
        _MODULES[digest] = loaded
        return loaded


def _first_line(exc: BaseException) -> str:
    text = str(exc).strip()
    return text.splitlines()[0] if text else "(no message)"


def _line_in(exc: BaseException, filename: str) -> int:
    tb = exc.__traceback__
    line = 0
    while tb is not None:
        if tb.tb_frame.f_code.co_filename == filename:
            line = tb.tb_lineno
        tb = tb.tb_next
    return line
