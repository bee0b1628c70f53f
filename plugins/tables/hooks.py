"""Hooks of the ``tables`` universe: its phenotype, Hornby & Pollack's voxel tables.

``PHENOTYPE`` is what genr8_dist's evaluator, run store, history and report use (the interface:
``genr8_dist.phenotype``; a walk-through: docs/phenotypes.md). The domain logic, free of genr8_dist,
is in ``voxels.py`` beside this file: the P0L-system, the turtle, the criteria, the mesh.
"""

from __future__ import annotations

from collections.abc import Mapping
from functools import lru_cache
from pathlib import Path
from typing import Any

from genr8_dist.fitness import CriterionInfo, criterion_names, register_criterion
from genr8_dist.phenotype import Developed, Phenotype

# A plugin's modules are one package (genr8_dist.grammar.source): its siblings are relative imports,
# and they travel with the run that stores the universe, so this works after the plugin folder is gone.
from . import variation, voxels


def _declare(name: str, heading: str, description: str) -> None:
    """Register one criterion of the ``voxels`` phenotype (once per process: hooks may be reloaded).
    Their targets and weights are unused: the fitness is the paper's product, not deviations."""
    if name not in criterion_names("voxels"):
        register_criterion(CriterionInfo(name, lambda table, env: voxels.criteria(table.voxels)[name],
                                         0.0, 0.0, heading=heading, description=description,
                                         phenotype="voxels"))


for _name, _heading, _description in (
    ("height", "height", "`Y_max`, the highest filled layer (the ground is layer 0)"),
    ("surface", "surf", "the voxels in layer `Y_max` (the table top)"),
    ("stability", "stab", "the sum, over the layers below `Y_max`, of the area of each layer's convex hull"),
    ("excess", "excess", "the voxels not in layer `Y_max`"),
    ("voxels", "voxels", "all filled voxels (recorded, not part of the fitness)"),
):
    _declare(_name, _heading, _description)


class TablesPhenotype(Phenotype):
    """Voxel tables (GECCO 2001): develop = rewrite the P0L-system, run the turtle on a 40^3 grid;
    criteria = height, surface, stability, excess (and the voxel count, for the record); fitness =
    height * surface * stability / excess, maximised, so the engine's (lower-is-better) fitness is its
    negation."""

    name = "voxels"
    noun = "table"
    direction = "maximise"
    capped_is_invalid = False
    export_formats = ("obj", "ply", "stl", "glb")
    stage = "develop"
    sizes = ("commands", "modules")  # turtle commands run; modules in the final word

    def develop(self, text: str, config: Any) -> Developed:
        table = voxels.develop(text)
        return Developed(table, table.digest(), table.steps, table.capped,
                         {"commands": table.commands, "modules": table.modules})

    def copies(self, text: str, other: str, reads: str | None, config: Any) -> bool:
        """Whether ``text`` builds the table ``other`` builds, told from their final words without
        running the turtle (``voxels.same_cells_form``; a word the command cap cuts, only by the word
        itself). It costs about a third of a development; most of the paper's mutations change a
        production the derivation never reaches with the parameters it passes, a condition that
        never decides, or a turn that no move follows."""
        mine = _built(text)
        return mine is not None and mine == _built(other)

    def trivial(self, evaluation: Any) -> bool:
        """A structure the paper's fitness scores 0 (flat, or nothing below its top layer)."""
        return voxels.fitness(evaluation.criteria) == 0.0 if evaluation.criteria else True

    def describe(self, developed: Developed) -> str:
        table = developed.value
        return (f"{table.n_voxels} voxels from {table.commands} commands" +
                (f" (capped: {table.capped})" if table.capped else ""))

    def measure(self, developed: Developed, config: Any) -> dict[str, float]:
        raw = voxels.criteria(developed.value.voxels)
        names = config.fitness.names if config is not None else self.criteria
        return {name: raw[name] for name in names}

    def fitness(self, raw: Mapping[str, float], config: Any) -> float:
        return -voxels.fitness(dict(raw))

    def export(self, developed: Developed, path: str | Path, config: Any, *, name: str = "") -> Path:
        import trimesh

        from genr8_dist.export import write_mesh

        vertices, faces = voxels.mesh_arrays(developed.value.voxels)
        return write_mesh(trimesh.Trimesh(vertices, faces, process=False), path)

    def preview(self, developed: Developed, path: str | Path, *, title: str, config: Any) -> Path:
        import matplotlib

        from genr8_dist.export import save_png

        matplotlib.use("Agg", force=False)
        import matplotlib.pyplot as plt

        fig = plt.figure(figsize=(8.4, 5.0))
        ax = fig.add_axes((0.0, 0.08, 0.62, 0.84), projection="3d")
        self.draw(ax, developed)
        voxels.draw_plan(fig.add_axes((0.64, 0.52, 0.34, 0.36)), developed.value.voxels)
        voxels.draw_side(fig.add_axes((0.64, 0.10, 0.34, 0.32)), developed.value.voxels)
        raw = voxels.criteria(developed.value.voxels)
        fig.suptitle(title, fontsize=10)
        fig.text(0.5, 0.03, voxels.voxel_count_text(developed.value, raw), ha="center", fontsize=7.5)
        fig.text(0.81, 0.48, f"top layer filled: {voxels.top_filled_share(developed.value.voxels):.0%} "
                 "of its hull", ha="center", fontsize=7.5)
        return save_png(fig, path)

    def draw(self, ax: Any, developed: Developed) -> None:
        voxels.draw(ax, developed.value.voxels)


@lru_cache(maxsize=4096)
def _built(text: str) -> tuple[Any, ...] | None:
    """What ``text``'s turtle builds, as far as its final word says (``None``: it does not parse)."""
    try:
        word = voxels.derive(voxels.parse(text))[0]
    except Exception:   # development reports it, as data
        return None
    form = voxels.same_cells_form(word)
    return ("word", word) if form is None else ("form", form)


PHENOTYPE = TablesPhenotype()

# The paper's variation (sections 2.4 to 2.6: random systems, structural mutation and recombination
# of the P0L-system), used instead of GE's under ``ea.variation = "auto"`` (genr8_dist.evolution.variation).
VARIATION = variation.GENERATIVE
