"""Phenotypes: what a universe's texts develop into, how that is measured, scored, exported and shown.

A universe's texts are genotypes written out; its *phenotype* says what they become. The built-in
one is the HEMLS surface (:data:`SURFACES`: parse the rewrite system, grow it in the run's
environment, score the six surface criteria against targets and weights). A plugin brings its own by
defining ``PHENOTYPE`` in its ``hooks.py`` (see docs/phenotypes.md, with ``plugins/tables`` as the
worked example); the evaluator, the islands, the run store, the history commands, ``genr8 show`` and
the report only ever talk to a phenotype through this interface:

``develop(text, config) -> Developed``     the phenotype of one text (raise to fail the individual)
``sizes``                                  the names of its sizes (``Developed.counts``), stored as
                                           ``size_<name>`` columns beside the criteria
``measure(developed, config) -> {name: raw value}``   one value per name in ``criteria``
``trivial(evaluation) -> bool``            not worth a founder's place (sensible initialisation)
``screen(text, config) -> (bool, str)``    (optional) what the text shows before development:
                                           wasted for sure (trivial, or failed), and a key equal
                                           for texts that develop alike (default: never wasted,
                                           the text)
``unread(text, reads)``                    (optional) the lines of ``text`` development did not
                                           read (``genr8 show`` marks them; default none)
``copies(text, other, reads, config)``     (optional) whether ``text`` develops into ``other``'s
                                           phenotype, known without developing it (``reads``: what
                                           ``other``'s development read, ``Developed.reads``);
                                           default ``False``: cannot say
``problem(counts, raw) -> str | None``     why it cannot be scored (degenerate), else ``None``
``fitness(raw, config) -> float``          the run's fitness, **lower is better** (the engine
                                           minimises; a phenotype whose paper maximises a score
                                           returns its negation and says so in ``direction``)
``export_formats``                         the file suffixes ``export`` writes
``export(developed, path, config)``        a file a CAD tool or a 3D printer reads (suffix decides)
``preview(developed, path, title, config)`` a PNG picture
``draw(ax, developed)``                    the same picture on a matplotlib 3D axes (gallery tiles)
``parse(text)`` (optional)                 read a text; when given, a universe is checked at load by
                                           parsing a sample of its derivations

Development is a pure function of (text, configuration); ``Developed.digest`` identifies the result,
so regrowing an individual checks it is bit-identical to what the run scored.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol

from genr8_dist.errors import UniverseError
from genr8_dist.export import SURFACE_FORMATS, export_surface

if TYPE_CHECKING:
    from genr8_dist.environment import Environment
    from genr8_dist.fitness import FitnessSpec

__all__ = ["SCHEMA_2_NAMES", "SURFACES", "Developed", "Phenotype", "RunSettings", "SurfacePhenotype",
           "descriptor_sizes", "phenotype_of"]


class RunSettings(Protocol):
    """What a phenotype is given of a run's configuration (``genr8_dist.config.RunConfig``, a layer
    above this one): its environment, its fitness (criteria, targets, weights) and its meshing."""

    @property
    def environment(self) -> Environment: ...

    @property
    def fitness(self) -> FitnessSpec: ...

    @property
    def meshing(self) -> int: ...


@dataclass(frozen=True)
class Developed:
    """One text developed: the phenotype ``value`` and the facts the run store keeps about it.

    ``digest``: equal digests, equal phenotypes; ``steps``: derivation steps done; ``capped``: what
    cut development short (``None`` when nothing did); ``counts``: its sizes, one per name in the
    phenotype's ``sizes`` (a surface: ``vertices``, ``edges``, ``regions``), stored with the row as
    ``size_<name>`` (a size left out is stored as 0); ``reads``: which parts of the text development
    read, in the phenotype's own notation (``Phenotype.copies``; ``None``: not said)."""

    value: Any
    digest: str
    steps: int = 0
    capped: str | None = None
    counts: Mapping[str, int] = field(default_factory=dict)
    reads: str | None = None


class Phenotype(ABC):
    """The interface a universe's phenotype implements (subclass it, or write the same attributes).

    ``name``: the phenotype kind; its criteria are those registered under it
    (``genr8_dist.fitness.register_criterion(CriterionInfo(..., phenotype=name))``: name, heading,
    description, default target and weight), and ``measure`` returns a raw value for each criterion
    of the run (``config.fitness.names``, the run's ``crit_<name>`` columns). ``direction``:
    ``"minimise"`` when ``fitness`` is the paper's own measure, ``"maximise"`` when it is the negated
    score of a paper that maximises; ``noun``: what one is called in titles; ``capped_is_invalid``:
    whether a development that hit a cap fails the individual; ``export_formats``: suffixes
    ``export`` writes; ``stage``: the name of the failing stage when ``develop`` raises; ``sizes``:
    the names of the sizes ``develop`` counts (``Developed.counts``), which a run stores as
    ``size_<name>`` integer columns (fixed when the run is created, like its criteria) and a
    MAP-Elites grid may use as descriptors (``size_<name>``); ``trivial_from_sizes``: whether
    ``trivial`` reads only the sizes, not the criteria (then an island redraws a trivial founder
    without measuring it); ``says_reads``: whether ``develop`` says what it read of the text
    (``Developed.reads``, which ``copies`` is given).
    """

    name: str = "phenotype"
    noun: str = "phenotype"  # what one is called in titles: "surface", "table"
    direction: str = "minimise"
    capped_is_invalid: bool = True
    export_formats: tuple[str, ...] = ()
    stage: str = "grow"
    sizes: tuple[str, ...] = ()
    trivial_from_sizes: bool = False
    says_reads: bool = False

    @property
    def criteria(self) -> tuple[str, ...]:
        """The criteria registered for this phenotype, in registration order."""
        from genr8_dist.fitness import criterion_names

        return criterion_names(self.name)

    @abstractmethod
    def develop(self, text: str, config: RunSettings) -> Developed:
        """The phenotype of ``text`` (raise to fail the individual at ``stage``)."""

    @abstractmethod
    def measure(self, developed: Developed, config: RunSettings) -> dict[str, float]:
        """A raw value for each of the run's criteria."""

    @abstractmethod
    def fitness(self, raw: Mapping[str, float], config: RunSettings) -> float:
        """The run's fitness from the raw values, lower is better."""

    def trivial(self, evaluation: Any) -> bool:
        """Whether a valid evaluation (its stored counts and ``criteria``) is not worth a founder's
        place in generation 0 (sensible initialisation redraws it); by default never."""
        return False

    def screen(self, text: str, config: RunSettings) -> tuple[bool, str]:
        """What ``text`` shows before it is developed: whether its development is sure to be
        wasted, ``trivial`` or failed (an island then draws or varies it again without developing
        it), and a key equal for two texts only when they develop into one phenotype (a copy, known
        without developing it); by default never wasted, and the text itself."""
        return False, text

    def unread(self, text: str, reads: str | None) -> tuple[int, ...]:
        """The lines of ``text`` its development did not read (``reads``: its ``Developed.reads``),
        which ``genr8 show`` marks; by default none."""
        return ()

    def copies(self, text: str, other: str, reads: str | None, config: RunSettings) -> bool:
        """Whether ``text`` develops into the phenotype ``other`` develops into, known without
        developing it (``reads``: what ``other``'s development read, its ``Developed.reads``): an
        island then knows a child is a copy of its parent before developing it. Never ``True``
        for two texts that develop differently; by default ``False`` (cannot say)."""
        return False

    def looks(self, developed: Developed) -> list[Any] | None:
        """What a person sees of ``developed``, as blocks of numbers (arrays of a fixed length each,
        each block counting alike), by which the kinds of form of a run are told apart
        (``history.clusters``); by default ``None``: the criteria and sizes tell them apart."""
        return None

    def describe(self, developed: Developed) -> str:
        """One line saying what was developed (``genr8 show``): its counts, else its kind."""
        parts = [f"{n} {k}" for k, n in developed.counts.items()]
        return ", ".join(parts) if parts else f"a {self.name} phenotype"

    def problem(self, counts: Mapping[str, Any], raw: Mapping[str, float]) -> str | None:
        """Why a measured phenotype cannot be scored (``None``: it can), from its stored ``counts``
        (its sizes by name, and ``steps_done``) and raw values; by default, raw values that are not
        finite."""
        bad = [name for name, value in raw.items() if not math.isfinite(value)]
        return f"degenerate {self.name}: {', '.join(bad)} not finite" if bad else None

    def export(self, developed: Developed, path: str | Path, config: RunSettings, *, name: str = "") -> Path:
        """Write ``developed`` to ``path``, in the format its suffix names (one of ``export_formats``);
        ``name`` is what to call it inside the file, where the format keeps names."""
        raise UniverseError(f"phenotype {self.name} exports nothing")

    def preview(self, developed: Developed, path: str | Path, *, title: str, config: RunSettings) -> Path:
        """A PNG picture of ``developed`` at ``path``, titled ``title``."""
        raise UniverseError(f"phenotype {self.name} draws no preview")

    def draw(self, ax: Any, developed: Developed) -> None:
        """Draw ``developed`` on the matplotlib 3D axes ``ax`` (a gallery tile)."""
        raise UniverseError(f"phenotype {self.name} draws no preview")


class SurfacePhenotype(Phenotype):
    """The built-in phenotype: HEMLS rewrite systems grown into surfaces (thesis ch. 2, 4.3)."""

    name = "surface"
    noun = "surface"
    direction = "minimise"
    capped_is_invalid = True
    stage = "grow"
    sizes = ("vertices", "edges", "regions")
    trivial_from_sizes = True
    says_reads = True       # Developed.reads: which rules fired
    export_formats = tuple(SURFACE_FORMATS)   # genr8_dist.export's table of surface formats
    smooths = True      # export takes smooth=N (Loop subdivision steps: genr8 show --smooth)

    def parse(self, text: str) -> Any:
        """Read a derived text (a rewrite system); raises for a text no individual could grow from.
        Optional for a phenotype: when present, a universe is checked at load by parsing a sample of
        its derivations (genr8_dist.grammar.universe.Universe.check_sample)."""
        from genr8_dist.hemls import parse

        return parse(text)

    def develop(self, text: str, config: RunSettings) -> Developed:
        from genr8_dist.hemls import grow, parse

        try:
            system = parse(text)
        except Exception as exc:
            exc.genr8_stage = "parse"  # type: ignore[attr-defined]
            raise
        result = grow(system, config.environment)
        surface = result.surface
        if hasattr(surface, "with_meshing"):     # the run's meshing (a stored run keeps its own)
            surface = surface.with_meshing(getattr(config, "meshing", surface.meshing))
        steps = result.steps
        capped = result.capped
        n_regions = getattr(surface, "n_regions", None)
        counts = {"vertices": len(surface.vertices), "edges": len(surface.edges),
                  "regions": int(n_regions) if n_regions is not None else len(surface.regions)}
        return Developed(surface, surface.digest(),
                         len(steps) if isinstance(steps, (list, tuple)) else int(steps),
                         (capped if isinstance(capped, str) else "cap") if capped else None, counts,
                         None if capped or not result.fired
                         else "".join("1" if f else "0" for f in result.fired))

    def measure(self, developed: Developed, config: RunSettings) -> dict[str, float]:
        from genr8_dist.fitness import score_surface

        return score_surface(developed.value, config.environment, config.fitness.names)

    def trivial(self, evaluation: Any) -> bool:
        """At most one region: the axiom polygon as it was, or grown without a subdivision."""
        return bool(evaluation.sizes.get("regions", 0) <= 1)

    def screen(self, text: str, config: RunSettings) -> tuple[bool, str]:
        """Wasted when no rule that can fire draws a branch (no region can ever split: one region
        whatever the environment); under ``ea.screen = 2`` also when no step of the environment's
        can hold two branches that could join (``hemls.splitting.can_join``); under
        ``ea.screen = 3`` also when every growth of it spends more than the environment's
        ``max_work`` (``hemls.budget.least_work``: it is capped, invalid). The key is the text
        without the rules that can never fire (``genr8_dist.hemls.splitting.screen``)."""
        from genr8_dist.hemls.splitting import screen

        env = getattr(config, "environment", None)
        version = getattr(getattr(config, "ea", None), "screen", 1)
        steps = int(env.steps) if env is not None and version >= 2 else None
        max_work = int(getattr(env, "max_work", 0) or 0) if version >= 3 else 0
        return screen(text, bool(getattr(env, "label_noise", 0.0) > 0), steps, max_work)

    def unread(self, text: str, reads: str | None) -> tuple[int, ...]:
        """The lines of the rules that rewrote no edge in the growth (``reads``: one ``1`` or ``0``
        per rule)."""
        from genr8_dist.hemls import parse

        try:
            rules = parse(text).rules
        except Exception:   # a text that does not parse developed nothing to read
            return ()
        if reads is None or len(reads) != len(rules):
            return ()
        return tuple(rule.line for rule, mark in zip(rules, reads, strict=True) if mark == "0")

    def copies(self, text: str, other: str, reads: str | None, config: RunSettings) -> bool:
        """``reads``: one ``1`` or ``0`` per rule of ``other``, whether it rewrote an edge in its
        growth (``GrowthResult.fired``); ``hemls.splitting.same_growth`` (never under label noise,
        which draws from every label a text uses)."""
        from genr8_dist.hemls.splitting import same_growth

        env = getattr(config, "environment", None)
        if env is not None and getattr(env, "label_noise", 0.0) > 0:
            return False
        return same_growth(text, other, reads)

    def problem(self, counts: Mapping[str, Any], raw: Mapping[str, float]) -> str | None:
        if not counts.get("vertices") or not counts.get("edges"):
            return "degenerate surface: no vertices or no edges"
        return super().problem(counts, raw)

    def fitness(self, raw: Mapping[str, float], config: RunSettings) -> float:
        return config.fitness.evaluate(raw)

    def export(self, developed: Developed, path: str | Path, config: RunSettings, *, name: str = "",
               smooth: int = 0) -> Path:
        """The surface in a format of ``genr8_dist.export.SURFACE_FORMATS`` by its run's meshing: a
        triangle mesh (.obj .ply .stl .glb: every vertex in order, then the points meshing added) or
        a Rhino .3dm file (the mesh, named ``name``, the scaffold's edges as lines and its lines as
        NURBS curves); ``smooth`` subdivision steps."""
        return export_surface(developed.value, path, name=name, smooth=smooth)

    def preview(self, developed: Developed, path: str | Path, *, title: str, config: RunSettings) -> Path:
        """The shaded surface in the run's environment (boundaries, attractors, repellers, gravity)."""
        from genr8_dist.export import render_png

        return render_png(developed.value, Path(path), title=title,
                          env=getattr(config, "environment", None))

    def looks(self, developed: Developed) -> list[Any] | None:
        """The surface's outline, height field and curvature (``genr8_dist.forms``)."""
        from genr8_dist.forms import form_descriptors

        return form_descriptors(developed.value)

    def draw(self, ax: Any, developed: Developed) -> None:
        """The shaded surface and its edges (nothing for a surface without vertices)."""
        from genr8_dist.export import draw_surface

        if len(developed.value.vertices):
            draw_surface(ax, developed.value)


SURFACES = SurfacePhenotype()


def phenotype_of(universe: object) -> Phenotype:
    """The phenotype of ``universe``: its hooks' ``PHENOTYPE``, else the built-in surfaces."""
    hooks = getattr(universe, "hooks", None)
    found = getattr(hooks, "PHENOTYPE", None) if hooks is not None else None
    return found if found is not None else SURFACES


# Store schemas 1 and 2 named the phenotype's digest and sizes after the built-in surface phenotype;
# schema 3 renamed them. A run keeps the names it was created with: the store reads an older run's
# columns under the names on the right, and writes them under the names on the left.
SCHEMA_2_NAMES: dict[str, str] = {
    "surface_digest": "phenotype_digest",
    "n_vertices": "size_vertices",
    "n_edges": "size_edges",
    "n_regions": "size_regions",
}


def descriptor_sizes(sizes: Iterable[str]) -> tuple[str, ...]:
    """The MAP-Elites descriptor names a phenotype's ``sizes`` give besides its criteria:
    ``size_<name>`` each, and the names schemas 1 and 2 gave them (``n_regions``...), which older
    configurations use."""
    names = tuple(f"size_{s}" for s in sizes)
    return names + tuple(old for old, new in SCHEMA_2_NAMES.items() if new in names)
