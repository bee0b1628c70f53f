"""The trust rule: whose Python code a universe may run, and when.

A universe's ``.lark`` grammar is data; its Python modules (``hooks.py``, a phenotype module) are
code. Code runs only where the user said so:

* a universe the user names by name (``--universe NAME``, a plugin in ``GENR8_PLUGINS``, the
  plugins shipped with genr8_dist, an installed package's entry point) is the user's choice, and so
  is ``load_universe`` in the user's own Python;
* a plugin folder named by a path (in a run TOML, or ``--universe PATH`` on the command line) runs
  only with consent: ``--trust-hooks`` or a yes on a terminal, after which its digest is remembered
  (``discovery.consent_for_new_run``); a notice is not consent;
* code stored in a run directory runs only for the commands that continue the run (``run``,
  ``resume``, ``edit``), and only when its code digest is remembered, matches an installed plugin's,
  or the user passes ``--trust-hooks`` (which remembers it). History commands, ``show`` and the report
  never run stored code; they run an installed plugin's (or a remembered) code of the same digest,
  which is the user's own, to regrow a phenotype plugin's individuals
  (``genr8_dist.history._regrow.phenotype_for``).

Consent is per process (:func:`consent`, :func:`may_run`) and travels to Ray hosts with the
configuration the driver sends (see :class:`~genr8_dist.grammar.source.UniverseSource`); remembered
digests live in ``$GENR8_TRUST_FILE``, default ``~/.config/genr8/trusted-hooks`` (one
``sha256  what`` line each), never inside a run directory.
"""

from __future__ import annotations

import os
import threading
from collections.abc import Callable
from pathlib import Path
from typing import Protocol

from genr8_dist.errors import UniverseError

__all__ = ["StoredCode", "consent", "may_run", "remember", "remembered", "require_trust", "trust_file"]



class StoredCode(Protocol):
    """What the trust rule reads of a universe's files (``grammar.source.UniverseSource``, which asks
    this module whether its code may run)."""

    @property
    def name(self) -> str: ...

    @property
    def origin(self) -> str: ...

    @property
    def code_digest(self) -> str: ...

    @property
    def folder(self) -> str: ...

    @property
    def modules(self) -> tuple[str, ...]: ...


_CONSENTED: set[str] = set()
_LOCK = threading.Lock()


def consent(code_digest: str) -> None:
    """Let this process run the code whose digest is ``code_digest``."""
    if code_digest:
        with _LOCK:
            _CONSENTED.add(code_digest)


def may_run(code_digest: str) -> bool:
    """Whether this process may run the code ``code_digest`` (no code: always)."""
    return not code_digest or code_digest in _CONSENTED


def trust_file() -> Path:
    """Where remembered code digests are kept."""
    env = os.environ.get("GENR8_TRUST_FILE")
    if env:
        return Path(env).expanduser()
    base = os.environ.get("XDG_CONFIG_HOME") or os.path.join(os.path.expanduser("~"), ".config")
    return Path(base) / "genr8" / "trusted-hooks"


def remembered() -> set[str]:
    """The code digests the user has trusted before (an unreadable file trusts nothing)."""
    try:
        lines = trust_file().read_text(encoding="utf-8").splitlines()
    except (OSError, UnicodeDecodeError):
        return set()
    return {line.split()[0] for line in lines if line.strip() and not line.startswith("#")}


def remember(code_digest: str, what: str) -> None:
    """Remember ``code_digest`` as trusted (best effort: a read-only home only loses the memory)."""
    if not code_digest or code_digest in remembered():
        return
    path = trust_file()
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        with path.open("a", encoding="utf-8") as fh:
            fh.write(f"{code_digest}  {' '.join(what.split())}\n")
    except OSError:
        pass


def require_trust(source: StoredCode, *, trust_flag: bool, command: str,
                  installed: Callable[[str], str | None] | None = None) -> None:
    """Consent to ``source``'s stored code for ``command`` (``resume``, ``edit``), or refuse in one line.

    Consent comes from a remembered digest, an installed plugin of the same name with the same code
    (``installed(name)`` gives that plugin's code digest), or ``trust_flag`` (then remembered).
    """
    digest = source.code_digest
    if may_run(digest):
        return
    if digest in remembered() or (installed is not None and installed(source.name) == digest):
        consent(digest)
        return
    if trust_flag:
        remember(digest, f"universe {source.name} ({source.folder})")
        consent(digest)
        return
    modules = ", ".join(f"{m}.py" for m in source.modules)
    raise UniverseError(
        f"{source.origin or 'the run'}: universe '{source.name}' carries Python code ({modules}, sha256 "
        f"{digest[:16]}...) that this machine has not trusted; read it (the [stored_universe] table of the "
        f"run's configs/*.toml), then run `genr8 {command} --trust-hooks`")
