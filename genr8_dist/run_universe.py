"""The universe a run configuration names: found, checked, its code consented to, its phenotype chosen.

A layer above ``grammar`` (universes) and ``phenotype`` (what their texts develop into), and below
``config``, which calls it when a ``RunConfig`` is built:

- ``resolve_universe(name, base_dir)``: a name or a path to its ``UniverseSource``, the grammar
  compiled, the hook names checked and, for a universe without code, a sample of derivations parsed
  by its phenotype (no plugin code runs);
- ``check_source(source)``: the grammar and hook names of a stored universe (cached per digest);
- ``run_phenotype(source)``: the phenotype the universe develops into, running its code only where
  the trust rule lets it (:mod:`genr8_dist.grammar.trust`); ``phenotype_kind``: its name.
"""

from __future__ import annotations

from pathlib import Path

from genr8_dist.errors import ConfigError, Genr8Error
from genr8_dist.fields import fail
from genr8_dist.grammar.compiler import compile_grammar
from genr8_dist.grammar.discovery import find_source, installed_code_digest
from genr8_dist.grammar.source import UniverseSource
from genr8_dist.grammar.trust import consent, may_run, remembered
from genr8_dist.grammar.universe import build_universe
from genr8_dist.phenotype import SURFACES, Phenotype, phenotype_of

__all__ = ["check_source", "phenotype_kind", "resolve_universe", "run_phenotype"]

_CHECKED: set[str] = set()


def _fail(path: str, message: str) -> ConfigError:
    return fail("", path, message)


def resolve_universe(name: object, base_dir: Path | None) -> tuple[str, UniverseSource]:
    """The universe ``name`` (a name, or a path resolved against ``base_dir``) read into a source and
    checked (no plugin code runs): ``(its name, its UniverseSource)``; a ``ConfigError`` on the
    configuration's ``universe`` field otherwise."""
    if not isinstance(name, str) or not name:
        raise _fail("universe", f"must be a universe name or path, got {name!r}")
    try:
        source, _origin = find_source(name, base_dir)
        check_source(source)
        if not source.code_digest:  # code-free: parse a sample of derivations now (no code runs)
            build_universe(source, check=True)
    except Genr8Error as exc:
        raise _fail("universe", str(exc)) from None
    return source.name, source


def check_source(source: UniverseSource) -> None:
    """Compile the grammar and check the hook names of ``source`` (cached per digest; runs no code)."""
    if source.digest in _CHECKED:
        return
    source.check_hook_names()
    compile_grammar(source.grammar_text, source.where(source.grammar_file))
    _CHECKED.add(source.digest)


def run_phenotype(source: UniverseSource | None) -> Phenotype:
    """The phenotype the universe ``source`` (``None``: the default universe) develops into: the
    built-in surfaces for HEMLS.

    Only a universe's code can say, and code runs only where the trust rule lets it
    (:mod:`genr8_dist.grammar.trust`): an installed plugin's or a remembered digest is consented to
    here; other code is not run and the phenotype read as the built-in surfaces (``genr8 run`` reads
    its file again once the user's universe is consented to)."""
    digest = source.code_digest if source is not None else ""
    if source is None or not digest:
        return SURFACES
    if not may_run(digest):
        if installed_code_digest(source.name) != digest and digest not in remembered():
            return SURFACES
        consent(digest)
    return phenotype_of(build_universe(source, check=False))


def phenotype_kind(source: UniverseSource | None) -> str:
    """The name of the phenotype ``source`` develops into (``run_phenotype``), under which its
    criteria are registered: ``surface`` for HEMLS."""
    return str(run_phenotype(source).name)
