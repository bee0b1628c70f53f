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
from typing import Any

from genr8_dist.history._run import (
    HistoryError,
    RunLike,
    atomic_write,
    config_of,
    open_run,
    phenotype_for,
    run_directory_holding,
)

__all__ = ["EXPORT_FORMATS", "Regrown", "check_export_path", "config_of", "export", "export_formats",
           "phenotype_of_run", "picture", "regrow", "save_text"]

EXPORT_FORMATS = ("obj", "ply", "stl", "glb", "3dm")


@dataclass(frozen=True)
class Regrown:
    """One individual regrown: its stored ``row``, the ``config`` it was evaluated under, its universe's
    ``phenotype``, the ``developed`` phenotype (``None`` when the individual never developed one), the
    derivation ``steps`` done, the ``digest``, and whether the genome still maps to the recorded text."""

    row: dict[str, Any]
    config: Any
    phenotype: Any
    developed: Any
    steps: int
    digest: str | None
    text_matches: bool | None    # None: not checked (the universe's hooks are code history never runs)

    @property
    def surface(self) -> Any:
        """The developed phenotype itself (a ``Surface`` for HEMLS universes), ``None`` if none."""
        return self.developed.value if self.developed is not None else None


def regrow(run: RunLike, id: str) -> Regrown:
    """Regrow individual ``id`` of ``run`` and check it against what the run recorded.

    The text grown is the recorded rewrite system (what the run grew); the genome is mapped again to
    check it still gives that text. The grown surface must have the recorded digest and counts, else a
    ``HistoryError`` says what differs. An individual that failed before growth has no surface.
    """
    from genr8_dist.evolution.evaluate import universe_for
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
        mapped = universe.map(list(row["genome"]), max_depth=config.genome.max_depth,
                              max_wraps=config.genome.max_wraps)
        text_matches = bool(mapped.valid) and mapped.text == text
    if text is None or row["surface_digest"] is None:
        return Regrown(row, config, phenotype, None, 0, None, text_matches)
    developed = phenotype.develop(text, config)
    digest = developed.digest
    counts = (*(int(developed.counts.get(k, 0)) for k in ("n_vertices", "n_edges", "n_regions")),
              developed.steps)
    recorded = (row["n_vertices"], row["n_edges"], row["n_regions"], row["steps_done"])
    if digest != row["surface_digest"] or counts != recorded:
        raise HistoryError(
            f"regrowing {id} did not reproduce the recorded {phenotype.name}: digest {digest} vs "
            f"{row['surface_digest']}, "
            f"(vertices, edges, regions, steps) {counts} vs {recorded}; was the run made by another version "
            f"of genr8_dist?")
    return Regrown(row, config, phenotype, developed, developed.steps, digest, text_matches)


def phenotype_of_run(run: RunLike, id: str) -> Any:
    """The phenotype individual ``id`` of ``run`` develops into (its configuration's universe's)."""
    from genr8_dist.history._tables import individual

    store = open_run(run)
    row = individual(store, id).select(["config_version"]).to_pylist()[0]
    return phenotype_for(store, config_of(store, row["config_version"]))


def _need_surface(result: Regrown, what: str) -> Any:
    if result.developed is None:
        row = result.row
        raise HistoryError(f"{row['id']} has no {result.phenotype.name} to {what}: it failed at "
                           f"{row['stage']} ({row['error']})")
    return result.surface


def export_formats(phenotype: Any) -> tuple[str, ...]:
    """The file suffixes ``export`` writes for ``phenotype`` (a surface: meshes and .3dm)."""
    from genr8_dist.phenotype import SURFACES

    return EXPORT_FORMATS if phenotype is SURFACES else tuple(phenotype.export_formats)


def check_export_path(path: str | os.PathLike, phenotype: Any) -> Path:
    """``path`` when ``export`` can write it for ``phenotype``; a ``HistoryError`` naming the formats
    otherwise."""
    path = Path(path)
    allowed = export_formats(phenotype)
    if path.suffix.lower().lstrip(".") not in allowed:
        raise HistoryError(f"{path}: unknown format '{path.suffix or '(no suffix)'}'; use one of "
                           + ", ".join(f".{s}" for s in allowed))
    inside = run_directory_holding(path)
    if inside is not None:
        raise HistoryError(f"{path}: is inside the run directory {inside}; the history commands never "
                           "write into a run: choose a path outside it")
    return path


def export(result: Regrown, path: str | os.PathLike) -> Path:
    """Write the regrown phenotype to ``path``: a surface as .obj .ply .stl .glb through trimesh or
    .3dm through rhino3dm (the ``rhino`` extra); a plugin's phenotype through its own ``export``. The
    file is written atomically."""
    from genr8_dist.phenotype import SURFACES

    path = check_export_path(path, result.phenotype)
    suffix = path.suffix.lower().lstrip(".")
    surface = _need_surface(result, "export")
    if result.phenotype is not SURFACES:
        return result.phenotype.export(result.developed, path, result.config)
    if suffix == "3dm":
        _export_3dm(surface, path, name=result.row["id"])
    else:
        from genr8_dist.export import export_mesh

        export_mesh(surface, path)
    return path


def _export_3dm(surface: Any, path: Path, *, name: str) -> None:
    """A Rhino file holding the surface as one mesh (every vertex, in order; the regions' triangles)
    and its edges as a line layer, the scaffold a designer builds on."""
    import numpy as np

    try:
        import importlib

        rhino3dm: Any = importlib.import_module("rhino3dm")  # its stubs miss writable attributes
    except ImportError:
        raise HistoryError(".3dm export needs rhino3dm: pip install 'genr8-dist[rhino]'") from None
    vertices = np.asarray(surface.vertices, dtype=np.float64)
    faces = np.asarray(surface.triangles(), dtype=np.int64).reshape(-1, 3)
    mesh = rhino3dm.Mesh()
    for x, y, z in vertices.tolist():
        mesh.Vertices.Add(x, y, z)
    for a, b, c in faces.tolist():
        mesh.Faces.AddFace(a, b, c)
    mesh.Normals.ComputeNormals()
    model = rhino3dm.File3dm()
    surface_layer = rhino3dm.Layer()
    surface_layer.Name = "genr8 surface"
    scaffold_layer = rhino3dm.Layer()
    scaffold_layer.Name = "genr8 scaffold"
    surface_index = model.Layers.Add(surface_layer)
    scaffold_index = model.Layers.Add(scaffold_layer)
    attributes = rhino3dm.ObjectAttributes()
    attributes.Name = name
    attributes.LayerIndex = surface_index
    model.Objects.AddMesh(mesh, attributes)
    line_attributes = rhino3dm.ObjectAttributes()
    line_attributes.LayerIndex = scaffold_index
    for a, b in np.asarray(surface.edges, dtype=np.int64).reshape(-1, 2).tolist():
        p, q = vertices[a], vertices[b]
        model.Objects.AddLine(rhino3dm.Point3d(*p), rhino3dm.Point3d(*q), line_attributes)

    def write(tmp: str) -> None:
        if not model.Write(tmp, 7):
            raise OSError(5, "rhino3dm could not write the file", str(path))

    atomic_write(path, write)


def picture(result: Regrown, path: str | os.PathLike) -> Path:
    """A shaded PNG of the regrown phenotype (a surface in its environment), titled with its id and
    fitness."""
    from genr8_dist.export import render_png
    from genr8_dist.phenotype import SURFACES

    surface = _need_surface(result, "draw")
    row = result.row
    title = (f"{row['id']}  fitness {row['fitness']:.4g}  (generation {row['generation']}, "
             f"island {row['island']})")
    if result.phenotype is not SURFACES:
        return result.phenotype.preview(result.developed, Path(path), title=title, config=result.config)
    return render_png(surface, Path(path), title=title, env=result.config.environment)


def save_text(text: str, path: str | os.PathLike, *, what: str, id: str) -> Path:
    """Write ``text`` (a rewrite system or a genome) to ``path`` atomically."""
    if not text:
        raise HistoryError(f"{id} has no {what} to save")
    body = text if text.endswith("\n") else text + "\n"
    atomic_write(path, lambda tmp: Path(tmp).write_text(body, encoding="utf-8"))
    return Path(path)
