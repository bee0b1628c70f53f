"""Regrow one individual of a run from its row, bit for bit, and take it out of the run as files.

Genr8 let a designer "re-grow that member and thus study it in closer detail" and save its genome, its
grammar and its surface (thesis 4.1.2). Here the row gives the genome and the configuration version it
was evaluated under; the genome is mapped again with that version's universe, the text is developed
by that universe's phenotype (a HEMLS surface grown in that version's environment, or a plugin's
phenotype, ``genr8_dist.phenotype``), and the phenotype's digest (for a surface, blake2b of the vertex
array) must equal the one recorded when the run evaluated it: what is exported is what the run scored.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol, cast

from genr8_dist.history._run import (
    HistoryError,
    RunLike,
    atomic_write,
    config_of,
    open_run,
    phenotype_for,
    run_directory_holding,
)
from genr8_dist.store.schema import size_column, sizes_of

if TYPE_CHECKING:
    from genr8_dist.config import RunConfig
    from genr8_dist.phenotype import Developed, Phenotype, RunSettings

__all__ = ["Regrown", "check_export_path", "config_of", "export", "export_formats",
           "phenotype_of_run", "picture", "regrow", "save_text"]


class _Smoothing(Protocol):
    """A phenotype whose ``smooths`` is true: its export takes ``smooth`` steps."""

    def export(self, developed: Developed, path: str | Path, config: RunSettings, *, name: str = "",
               smooth: int = 0) -> Path: ...


@dataclass(frozen=True)
class Regrown:
    """One individual regrown: its stored ``row``, the ``config`` it was evaluated under, its universe's
    ``phenotype``, the ``developed`` phenotype (``None`` when the individual never developed one), the
    derivation ``steps`` done, the ``digest``, and whether the genome still maps to the recorded text."""

    row: dict[str, Any]
    config: RunConfig
    phenotype: Phenotype
    developed: Developed | None
    steps: int
    digest: str | None
    text_matches: bool | None    # None: not checked (the universe's hooks are code history never runs)

    @property
    def value(self) -> Any:
        """The developed phenotype itself (``Developed.value``: a ``Surface`` for the built-in surface
        phenotype), ``None`` if none."""
        return self.developed.value if self.developed is not None else None


def regrow(run: RunLike, id: str) -> Regrown:
    """Regrow individual ``id`` of ``run`` and check it against what the run recorded.

    The text developed is the recorded one (what the run developed); the genome is mapped again to
    check it still gives that text. The phenotype must have the recorded digest, sizes and derivation
    steps, else a ``HistoryError`` says what differs. An individual that failed before development
    has none.
    """
    from genr8_dist.evolution.evaluate import universe_for
    from genr8_dist.evolution.variation import map_genome
    from genr8_dist.grammar.trust import may_run
    from genr8_dist.history._tables import individual

    store = open_run(run)
    row = individual(store, id).to_pylist()[0]
    config = config_of(store, row["config_version"])
    text = row["text"]
    text_matches: bool | None = None
    phenotype = phenotype_for(store, config)
    if may_run(config.universe_source.code_digest):  # consented by phenotype_for: installed or trusted
        universe = universe_for(config)
        mapped = map_genome(config, universe, row["genome"])
        text_matches = bool(mapped.valid) and mapped.text == text
    if text is None or row["phenotype_digest"] is None:
        return Regrown(row, config, phenotype, None, 0, None, text_matches)
    developed = phenotype.develop(text, config)
    digest = developed.digest
    sizes = sizes_of(list(row))   # the run's (a schema 1 or 2 run: a surface's, 0 for other phenotypes)
    counts = (*(int(developed.counts.get(s, 0)) for s in sizes), developed.steps)
    recorded = (*(row[size_column(s)] for s in sizes), row["steps_done"])
    if digest != row["phenotype_digest"] or counts != recorded:
        raise HistoryError(
            f"regrowing {id} did not reproduce the recorded {phenotype.name}: digest {digest} vs "
            f"{row['phenotype_digest']}, ({', '.join([*sizes, 'steps'])}) {counts} vs {recorded}; "
            "was the run made by another version of genr8_dist?")
    return Regrown(row, config, phenotype, developed, developed.steps, digest, text_matches)


def phenotype_of_run(run: RunLike, id: str) -> Phenotype:
    """The phenotype individual ``id`` of ``run`` develops into (its configuration's universe's)."""
    from genr8_dist.history._tables import individual

    store = open_run(run)
    row = individual(store, id).select(["config_version"]).to_pylist()[0]
    return phenotype_for(store, config_of(store, row["config_version"]))


def _need_developed(result: Regrown, what: str) -> Developed:
    if result.developed is None:
        row = result.row
        raise HistoryError(f"{row['id']} has no {result.phenotype.name} to {what}: it failed at "
                           f"{row['stage']} ({row['error']})")
    return result.developed


def export_formats(phenotype: Phenotype) -> tuple[str, ...]:
    """The file suffixes ``export`` writes for ``phenotype`` (its ``export_formats``)."""
    return tuple(phenotype.export_formats)


def check_export_path(path: str | os.PathLike[str], phenotype: Any) -> Path:
    """``path`` when ``export`` can write it for ``phenotype``; a ``HistoryError`` naming the formats
    otherwise."""
    path = Path(path)
    allowed = export_formats(phenotype)
    if path.suffix.lower().lstrip(".") not in allowed:
        raise HistoryError(f"{path}: unknown format '{path.suffix or '(no suffix)'}'; use one of "
                           + ", ".join(f".{s}" for s in allowed))
    return _outside_runs(path)


def _outside_runs(path: Path) -> Path:
    """``path``, unless it is inside a run directory (the history commands never write into a run)."""
    inside = run_directory_holding(path)
    if inside is not None:
        raise HistoryError(f"{path}: is inside the run directory {inside}; the history commands never "
                           "write into a run: choose a path outside it")
    return path


def export(result: Regrown, path: str | os.PathLike[str], *, smooth: int = 0) -> Path:
    """Write the regrown phenotype to ``path`` through its phenotype's ``export`` (the suffix picks the
    format; a surface: .obj .ply .stl .glb through trimesh, .3dm through rhino3dm), named after the
    individual where the format keeps names; ``smooth`` subdivision steps (a surface's meshes). The
    file is written atomically."""
    path = check_export_path(path, result.phenotype)
    developed = _need_developed(result, "export")
    if not smooth:
        return result.phenotype.export(developed, path, result.config, name=result.row["id"])
    if not getattr(result.phenotype, "smooths", False):
        raise HistoryError(f"--smooth: phenotype {result.phenotype.name} has no smoothed export")
    smoothing = cast(_Smoothing, result.phenotype)
    return smoothing.export(developed, path, result.config, name=result.row["id"], smooth=smooth)


def picture(result: Regrown, path: str | os.PathLike[str]) -> Path:
    """A PNG of the regrown phenotype (its phenotype's ``preview``: a surface in its environment),
    titled with its id and fitness."""
    developed = _need_developed(result, "draw")
    row = result.row
    title = (f"{row['id']}  fitness {row['fitness']:.4g}  (generation {row['generation']}, "
             f"island {row['island']})")
    return result.phenotype.preview(developed, _outside_runs(Path(path)), title=title, config=result.config)


def save_text(text: str, path: str | os.PathLike[str], *, what: str, id: str) -> Path:
    """Write ``text`` (a rewrite system or a genome) to ``path`` atomically."""
    if not text:
        raise HistoryError(f"{id} has no {what} to save")
    body = text if text.endswith("\n") else text + "\n"
    atomic_write(path, lambda tmp: Path(tmp).write_text(body, encoding="utf-8"))
    return Path(path)
