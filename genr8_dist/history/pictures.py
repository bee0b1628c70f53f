"""Pictures of a run for a person to look at: fitness curves, an ancestry, a gallery of its designs.

Drawn with matplotlib (the ``viz`` extra) on the non-interactive Agg backend, written atomically.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np
import pyarrow as pa

from genr8_dist.errors import Genr8Error
from genr8_dist.history._run import HistoryError, RunLike, atomic_write, open_run, run_label

if TYPE_CHECKING:
    from genr8_dist.config import RunConfig
    from genr8_dist.store import RunStore

__all__ = [
    "curves_figure",
    "curves_png",
    "gallery_figure",
    "gallery_figure_of",
    "gallery_png",
    "lineage_figure",
    "lineage_png",
    "png_bytes",
]

# Colours for how an individual was made (lineage) and the palette for islands.
ORIGIN_COLOURS = {
    "random": "#9e9e9e",
    "elite": "#1f77b4",
    "crossover": "#2ca02c",
    "mutation": "#ff7f0e",
    "crossover+mutation": "#9467bd",
    "migrant": "#d62728",
    "injected": "#e377c2",
}
_MAX_LINKS = 50_000  # an ancestry picture draws parent links up to this many (a haze beyond)
_EVENT_STYLE = {
    "intervention": ("#c0392b", "--", "intervention"),
    "resume": ("#7f8c8d", ":", "resumed"),
    "recovery": ("#e67e22", ":", "recovery"),
}


def _pyplot() -> Any:
    from genr8_dist.export import pyplot

    return pyplot("pictures", HistoryError)


def save_figure(fig: Any, path: str | os.PathLike[str]) -> None:
    """Write ``fig`` to ``path`` (a PNG, atomically) and close it."""
    _save(fig, path, dpi=100)


def _save(fig: Any, path: str | os.PathLike[str], dpi: int = 110) -> None:
    plt = _pyplot()
    suffix = os.path.splitext(os.fspath(path))[1] or ".png"

    def write(tmp: str) -> None:
        fig.savefig(tmp, dpi=dpi, format=suffix.lstrip(".") or "png", facecolor=fig.get_facecolor())

    try:
        atomic_write(path, write)
    finally:
        plt.close(fig)


def _island_colours(n: int) -> list[Any]:
    plt = _pyplot()
    cmap = plt.get_cmap("tab10" if n <= 10 else "tab20")
    return [cmap(i % cmap.N) for i in range(n)]


def _label_interventions(ax: Any, labels: dict[int, list[str]], *, span: int) -> None:
    """One label per generation where interventions take effect (several at one generation are joined),
    each beside its line; labels of generations close together step right so that none overlap."""
    colour = _EVENT_STYLE["intervention"][0]
    near = max(1.0, span / 45)   # generations closer than this would share the labels' column
    previous: float | None = None
    shift = 0
    for g in sorted(labels):
        shift = shift + 1 if previous is not None and g - previous < near * (shift + 1) else 0
        texts = labels[g]
        text = texts[0] if len(texts) == 1 else f"{len(texts)} edits: " + "; ".join(texts)
        if len(text) > 60:
            text = text[:59] + "…"
        ax.annotate(text, xy=(g, 1.0), xycoords=("data", "axes fraction"), xytext=(4 + 11 * shift, -4),
                    textcoords="offset points", rotation=90, va="top", fontsize=8, color=colour)
        if shift == 0:
            previous = g


def _short_detail(detail: str, limit: int = 38) -> str:
    """An intervention's detail as a short label (``fitness.size.weight=2``)."""
    try:
        data = json.loads(detail) if detail else {}
    except ValueError:
        data = {}
    parts: list[str] = []

    def walk(prefix: str, value: Any) -> None:
        if isinstance(value, dict):
            for k, v in value.items():
                walk(f"{prefix}.{k}" if prefix else str(k), v)
        else:
            parts.append(f"{prefix}={value}")

    if isinstance(data, dict):
        for key in ("changes", "edit", "set"):
            if key in data:
                walk("", data[key])
                break
        else:
            walk("", {k: v for k, v in data.items() if k not in ("version", "config_version")})
        parts += [str(item.get("source")) for item in data.get("injected") or () if isinstance(item, dict)]
        parts += [f"hand fitness {item.get('id')}={item.get('fitness')}"
                  for item in data.get("hand_fitness") or () if isinstance(item, dict)]
    text = ", ".join(parts)
    return text if len(text) <= limit else text[: limit - 1] + "…"


def curves_figure(store: RunLike, table: pa.Table | None = None) -> Any:
    """The fitness-curve figure: best (solid) and median (dashed) total fitness per island over the
    generations, migrations as ticks along the bottom, interventions and resumptions as vertical lines;
    below, each criterion's value closest to its target per island, the target dashed."""
    from genr8_dist.history._run import targets_by_version
    from genr8_dist.history._tables import events as run_events
    from genr8_dist.history._tables import per_generation

    plt = _pyplot()
    from matplotlib.ticker import MaxNLocator

    store = open_run(store)
    if table is None:
        table = per_generation(store)
    crits = [c[5:] for c in table.column_names if c.startswith("best_") and c != "best_id"]
    ev = run_events(store)
    islands = sorted(set(table["island"].to_pylist()))
    colours = dict(zip(islands, _island_colours(max(islands) + 1 if islands else 1), strict=False))
    ncols = 3
    nrows = math.ceil(len(crits) / ncols) if crits else 0
    fig = plt.figure(figsize=(13, 5.2 + 2.6 * nrows), facecolor="white")
    grid = fig.add_gridspec(1 + nrows, ncols, height_ratios=[2.4] + [1] * nrows, hspace=0.45,
                            wspace=0.25, left=0.07, right=0.98, top=0.95, bottom=0.07)
    ax = fig.add_subplot(grid[0, :])
    gen = np.asarray(table["generation"].to_pylist())
    isl = np.asarray(table["island"].to_pylist())

    def column(name: str) -> np.ndarray:
        return np.asarray([math.nan if v is None else v for v in table[name].to_pylist()], float)

    best, median = column("best"), column("median")
    for i in islands:
        rows = isl == i
        ax.plot(gen[rows], best[rows], color=colours[i], lw=2.0, label=f"island {i} best")
        ax.plot(gen[rows], median[rows], color=colours[i], lw=1.0, ls="--", alpha=0.6)
    if len(islands) > 2:  # the run's best over all islands, so the trend reads at a glance
        overall = [np.nanmin(best[gen == g]) if np.isfinite(best[gen == g]).any() else np.nan
                   for g in sorted(set(gen.tolist()))]
        # a wide grey band under the islands' lines, so the island holding the best stays visible
        ax.plot(sorted(set(gen.tolist())), overall, color="black", lw=6.0, alpha=0.18,
                solid_capstyle="round", label="best of all islands", zorder=1)
    finite = best[np.isfinite(best)]
    if finite.size and finite.min() > 0 and finite.max() / finite.min() > 50:
        ax.set_yscale("log")
    last = int(gen.max()) if gen.size else 0
    ax.set_xlim(-0.5, last + 0.5)
    ax.xaxis.set_major_locator(MaxNLocator(integer=True))
    ax.set_xlabel("generation")
    ax.set_ylabel("total fitness (lower is better)")
    ax.grid(True, color="#e5e5e5", lw=0.8)
    ax.set_axisbelow(True)
    for side in ("top", "right"):
        ax.spines[side].set_visible(False)
    title = f"{getattr(store, 'run_id', run_label(store))}: fitness per generation"
    ax.set_title(title + "  (solid: best, dashed: median)", loc="left", fontsize=13,
                 fontweight="bold")

    kinds = ev["kind"].to_pylist() if ev.num_rows else []
    gens_ev = ev["generation"].to_pylist() if ev.num_rows else []
    details = ev["detail"].to_pylist() if ev.num_rows else []
    migrations = sorted({g for k, g in zip(kinds, gens_ev, strict=True) if k == "migration"})
    if migrations:
        ax.plot(migrations, [0.0] * len(migrations), transform=ax.get_xaxis_transform(),
                marker="^", ls="none", ms=7, color="#555555", alpha=0.8, label="migration",
                clip_on=False)
    drawn: set[str] = set()
    labels: dict[int, list[str]] = {}   # generation -> the interventions taking effect there
    for kind, g, detail in zip(kinds, gens_ev, details, strict=True):
        if kind not in _EVENT_STYLE:
            continue
        colour, style, label = _EVENT_STYLE[kind]
        if kind != "intervention" or g not in labels:
            ax.axvline(g, color=colour, ls=style, lw=1.4, label=None if label in drawn else label)
        drawn.add(label)
        if kind == "intervention":
            labels.setdefault(g, []).append(_short_detail(detail))
    _label_interventions(ax, labels, span=max(1, last))
    ax.legend(loc="upper right", fontsize=8, ncols=2 if len(islands) > 4 else 1, frameon=False)

    targets = targets_by_version(store, list(crits)) if crits else {}
    configs = {int(c.version): int(c.effective_generation) for c in store.configs()}
    for n, name in enumerate(crits):
        cax = fig.add_subplot(grid[1 + n // ncols, n % ncols])
        values = column(f"closest_{name}")
        for i in islands:
            rows = isl == i
            cax.plot(gen[rows], values[rows], color=colours[i], lw=1.2)
        steps = sorted((g, targets[v][name][0]) for v, g in configs.items()
                       if v in targets and name in targets[v])
        if steps:
            xs = [g for g, _ in steps] + [last]
            ys = [t for _, t in steps] + [steps[-1][1]]
            cax.step(xs, ys, where="post", color="black", ls="--", lw=1.0, label="target")
        cax.set_title(name.replace("_", " "), loc="left", fontsize=10)
        cax.xaxis.set_major_locator(MaxNLocator(integer=True))
        cax.grid(True, color="#eeeeee", lw=0.6)
        cax.tick_params(labelsize=8)
        for side in ("top", "right"):
            cax.spines[side].set_visible(False)
        if n == 0 and steps:
            cax.legend(fontsize=7, frameon=False, loc="best")
    if crits:
        fig.text(0.01, 0.005, "criteria: per island, the value closest to its target in each "
                 "generation", fontsize=8, color="#555555")
    return fig


def curves_png(store: RunLike, path: str | os.PathLike[str], *, table: pa.Table | None = None) -> None:
    """Write the fitness curves of ``store`` (see ``curves_figure``) to the PNG ``path``."""
    _save(curves_figure(store, table), path)


def lineage_png(table: pa.Table, id: str, path: str | os.PathLike[str]) -> None:
    """Write ``lineage_figure(table, id)`` to the PNG ``path``."""
    _save(lineage_figure(table, id), path)


def lineage_figure(table: pa.Table, id: str) -> Any:
    """Draw an ancestry (``history.lineage``'s table): generations left to right, each island a band,
    individuals coloured by how they were made, parent-to-child links, the main line in black."""
    from matplotlib.collections import LineCollection
    from matplotlib.lines import Line2D

    plt = _pyplot()
    rows = table.to_pylist()
    if not rows:
        raise HistoryError(f"no ancestry to draw for {id}")
    islands = sorted({r["island"] for r in rows})
    band = {i: n for n, i in enumerate(islands)}
    width = max(r["index"] for r in rows) + 1
    pos = {r["id"]: (r["generation"], band[r["island"]] + (r["index"] + 0.5) / width * 0.8 + 0.1)
           for r in rows}
    links: list[Any] = []
    main: list[Any] = []
    line = {r["id"] for r in rows if r["main_line"]}
    for r in rows:
        for parent in r["parents"] or ():
            if parent in pos:
                segment = [pos[parent], pos[r["id"]]]
                (main if parent in line and r["id"] in line else links).append(segment)
    gens = [r["generation"] for r in rows]
    span = max(gens) - min(gens) + 1
    fig, ax = plt.subplots(figsize=(min(22, 6 + 0.32 * span), 2.0 + 1.6 * len(islands)),
                           facecolor="white")
    if len(links) <= _MAX_LINKS:
        ax.add_collection(LineCollection(links, colors="#b0b0b0", linewidths=0.5, alpha=0.6, zorder=1))
    ax.add_collection(LineCollection(main, colors="black", linewidths=2.2, zorder=3))
    xs = np.array([pos[r["id"]][0] for r in rows], float)
    ys = np.array([pos[r["id"]][1] for r in rows], float)
    colours = [ORIGIN_COLOURS.get(r["origin"], "#333333") for r in rows]
    sizes = np.where([r["main_line"] for r in rows], 46, 18)
    ax.scatter(xs, ys, c=colours, s=sizes, edgecolors="white", linewidths=0.4, zorder=2)
    me = pos[id]
    ax.scatter([me[0]], [me[1]], s=180, facecolors="none", edgecolors="black", linewidths=1.8,
               zorder=4)
    ax.annotate(id, me, xytext=(8, 6), textcoords="offset points", fontsize=10, fontweight="bold")
    for n in range(1, len(islands)):
        ax.axhline(n, color="#dddddd", lw=0.8, zorder=0)
    ax.set_yticks([n + 0.5 for n in range(len(islands))], [f"island {i}" for i in islands])
    ax.set_ylim(0, len(islands))
    ax.set_xlim(min(gens) - 0.8, max(gens) + 0.8 + 0.08 * span)
    from matplotlib.ticker import MaxNLocator

    ax.xaxis.set_major_locator(MaxNLocator(integer=True))
    ax.set_xlabel("generation")
    ax.invert_yaxis()
    for side in ("top", "right"):
        ax.spines[side].set_visible(False)
    present = [o for o in ORIGIN_COLOURS if any(r["origin"] == o for r in rows)]
    handles = [Line2D([], [], marker="o", ls="none", color=ORIGIN_COLOURS[o], label=o) for o in present]
    handles.append(Line2D([], [], color="black", lw=2.2, label="main line (first parents)"))
    ax.legend(handles=handles, loc="upper left", bbox_to_anchor=(1.0, 1.0), fontsize=8, frameon=False)
    note = "" if len(links) <= _MAX_LINKS else f" (too many to link: {len(links):,} links left out)"
    ax.set_title(f"ancestry of {id}: {len(rows) - 1:,} ancestors{note}", loc="left", fontsize=12,
                 fontweight="bold")
    fig.tight_layout()
    return fig


def _tile_grid(n: int, columns: int | None = None) -> tuple[int, int]:
    cols = columns or min(max(n, 1), 4 if n <= 8 else 5 if n <= 15 else 6)
    return math.ceil(n / cols), cols


def _draw_tile(ax: Any, item: Any) -> bool:
    """Draw a regrown individual (``history._regrow.Regrown``) through its phenotype; False when there
    is nothing to draw."""
    if item is None or item.developed is None:
        return False
    item.phenotype.draw(ax, item.developed)
    return True


def gallery_figure(tiles: Sequence[tuple[str, Any]], *, title: str, columns: int | None = None,
                   row_labels: Sequence[str] | None = None) -> Any:
    """A contact sheet: one 3D tile per ``(label, regrown individual)``, drawn by its phenotype;
    ``None`` shows the label only."""
    plt = _pyplot()
    rows, cols = _tile_grid(len(tiles), columns)
    fig = plt.figure(figsize=(3.1 * cols, 3.2 * rows + 0.7), facecolor="white")
    for n, (label, regrown) in enumerate(tiles):
        ax = fig.add_subplot(rows, cols, n + 1, projection="3d")
        ax.set_facecolor("white")
        if not _draw_tile(ax, regrown):
            ax.set_axis_off()
            ax.text2D(0.5, 0.5, "nothing grown", ha="center", va="center", transform=ax.transAxes,
                      color="#999999")
        ax.set_title(label, fontsize=9, pad=-2)
        if row_labels and n % cols == 0:
            ax.text2D(-0.02, 0.5, row_labels[n // cols], rotation=90, ha="right", va="center",
                      transform=ax.transAxes, fontsize=10, fontweight="bold")
    fig.suptitle(title, x=0.01, ha="left", fontsize=13, fontweight="bold")
    fig.subplots_adjust(left=0.03, right=0.99, top=1 - 0.7 / (3.2 * rows + 0.7), bottom=0.01,
                        wspace=0.02, hspace=0.12)
    return fig


def _best_ids(store: RunStore, k: int, generation: int | None, island: int | None,
              distinct: bool) -> list[str]:
    """The ids of the ``k`` best valid individuals; with ``distinct``, only the best individual of
    each form (``_tables.form_ids``: an elite and its copies, or mirror images, are one design)."""
    from genr8_dist.history._tables import top

    return list(top(store, k, generation=generation, island=island, distinct=distinct)["id"].to_pylist())


GALLERY_MAX = 144  # designs on one contact sheet (a row per island with per_island)


def gallery_figure_of(run: RunLike, *, generation: int | None = -1, k: int = 12,
                      island: int | None = None, per_island: bool = False,
                      distinct: bool = True) -> tuple[Any, str]:
    """The contact sheet of the ``k`` best valid individuals of ``generation`` (negative counts back
    from the last; ``None``: the whole run), of one ``island``, or the best ``k`` of each island with
    ``per_island``; each regrown from its row and drawn by its phenotype. With ``distinct`` (default) an
    individual whose phenotype equals a better one's (an elite, a migrant's copy) is left out, so the
    sheet shows k different designs. Returns the figure and a one-line description."""
    from genr8_dist.history._regrow import regrow
    from genr8_dist.history._run import dataset
    from genr8_dist.history._tables import _resolve_generation

    if k < 1:
        raise HistoryError(f"k: must be at least 1, got {k}")
    if k > GALLERY_MAX:
        raise HistoryError(f"k: a contact sheet holds at most {GALLERY_MAX} designs (per island with "
                           f"per-island), got {k}")
    store = open_run(run)
    generation = _resolve_generation(dataset(store), generation)
    if per_island:
        islands = [island] if island is not None else sorted(
            int(i) for i in store.committed_generations())
        row_labels = []
        ids: list[str | None] = []
        for i in islands:
            try:
                chosen = _best_ids(store, k, generation, i, distinct)
            except HistoryError:  # an island without a valid individual in this generation
                continue
            row_labels.append(f"island {i}")
            ids.extend(chosen + [None] * (k - len(chosen)))
        if not ids:
            raise HistoryError(f"{run_label(store)}: no valid individual of generation {generation}")
        columns: int | None = k
    else:
        ids = list(_best_ids(store, k, generation, island, distinct))
        row_labels, columns = None, None
    tiles: list[tuple[str, Any]] = []
    count = 0
    noun = "design"
    for ident in ids:
        if ident is None:
            tiles.append(("", None))
            continue
        try:
            result = regrow(store, ident)
        except Genr8Error as exc:
            raise HistoryError(f"gallery: cannot regrow {ident}: {exc}") from None
        count += 1
        # + 0.0: a maximising phenotype's negated score of 0 (-0.0) shows as 0
        tiles.append((f"{ident}   fitness {result.row['fitness'] + 0.0:.4g}", result))
        noun = result.phenotype.noun
    where = "the whole run" if generation is None else f"generation {generation}"
    if island is not None:
        where += f", island {island}"
    title = (f"{getattr(store, 'run_id', run_label(store))}: the best {count if not per_island else k}"
             + (f" distinct {noun}s" if distinct else "") + f" of {where}"
             + (" per island" if per_island else "") + "  (lower fitness is better)")
    fig = gallery_figure(tiles, title=title, columns=columns, row_labels=row_labels)
    return fig, f"{count} {noun}s of {where}"


def gallery_png(run: RunLike, path: str | os.PathLike[str], *, generation: int | None = -1, k: int = 12,
                island: int | None = None, per_island: bool = False, distinct: bool = True) -> str:
    """Write the contact sheet of ``gallery_figure_of`` to the PNG ``path``; returns its description."""
    fig, info = gallery_figure_of(run, generation=generation, k=k, island=island, per_island=per_island,
                                  distinct=distinct)
    _save(fig, path, dpi=100)
    return info


def png_bytes(fig: Any, dpi: int = 100) -> bytes:
    """The figure as PNG bytes (closed afterwards), for embedding in a page."""
    import io

    plt = _pyplot()
    buffer = io.BytesIO()
    try:
        fig.savefig(buffer, format="png", dpi=dpi, facecolor=fig.get_facecolor())
    finally:
        plt.close(fig)
    return buffer.getvalue()


# --------------------------------------------------------------------------------------------------
# The search modes' pictures: Pareto front, MAP-Elites archive, clusters.


def _noun(store: RunStore, config: RunConfig) -> str:
    """What one design of the run is called (its phenotype's ``noun``; "design" when unknown)."""
    from genr8_dist.history._run import phenotype_for

    try:
        return str(phenotype_for(store, config).noun)
    except Genr8Error:
        return "design"


def _regrown_tiles(store: RunStore, table: pa.Table, label: Any) -> list[tuple[str, Any]]:
    from genr8_dist.history._regrow import regrow

    tiles = []
    for row in table.to_pylist():
        try:
            regrown = regrow(store, row["id"])
        except Genr8Error as exc:
            raise HistoryError(f"cannot regrow {row['id']}: {exc}") from None
        tiles.append((label(row), regrown))
    return tiles


def clusters_figure_of(run: RunLike, k: int = 12, *, generation: int | None = None,
                       island: int | None = None) -> tuple[Any, str]:
    """A contact sheet of one representative per kind of form (``history._search.clusters``)."""
    from genr8_dist.history._search import clusters, told_apart_by

    store = open_run(run)
    table = clusters(store, k, generation=generation, island=island)
    tiles = _regrown_tiles(store, table, lambda r: f"kind {r['cluster']} ({r['members']})   "
                                                   f"{r['id']}  {r['fitness'] + 0.0:.3g}")
    where = "the whole run" if generation is None else f"generation {generation}"
    title = (f"{getattr(store, 'run_id', run_label(store))}: {len(tiles)} kinds of form in {where} "
             f"(told apart by {told_apart_by(store)}; designs alike in brackets)")
    return gallery_figure(tiles, title=title), f"{len(tiles)} clusters of {where}"


def pareto_figure_of(run: RunLike, *, objectives: Sequence[str] | None = None) -> tuple[Any, str]:
    """The run's distinct designs over two Pareto objectives (weighted deviations, lower is better),
    the non-dominated front highlighted, with thumbnails of up to 8 front members."""
    from genr8_dist.evolution.island import pareto_objectives
    from genr8_dist.history._search import _distinct, _newest_config, pareto_front

    store = open_run(run)
    config = _newest_config(store)
    names = list(objectives or pareto_objectives(config))[:2]
    front = pareto_front(store)
    everyone = _distinct(store, None, None, [])
    noun = _noun(store, config)
    plt = _pyplot()
    fig = plt.figure(figsize=(13, 6.2), facecolor="white")
    ax = fig.add_axes((0.06, 0.1, 0.42, 0.8))

    def devs(table: Any, name: str) -> Any:
        from genr8_dist.store.schema import criterion_column

        return np.array([config.fitness[name].deviation(v) if v is not None else np.inf
                         for v in table[criterion_column(name)].to_pylist()])

    x, y = devs(everyone, names[0]), devs(everyone, names[1])
    ok = np.isfinite(x) & np.isfinite(y)
    ax.scatter(x[ok], y[ok], s=10, color="#b9c2ca", label=f"{int(ok.sum())} distinct {noun}s")
    fx, fy = devs(front, names[0]), devs(front, names[1])
    count = len(pareto_objectives(config))
    ax.scatter(fx, fy, s=36, color="#d1495b", zorder=3,
               label=f"front ({front.num_rows}, non-dominated over {count} objectives)")
    ax.set_xlabel(f"{names[0]}: weighted deviation from its target")
    ax.set_ylabel(f"{names[1]}: weighted deviation from its target")
    ax.legend(loc="upper right", fontsize=9, frameon=False)
    ax.set_title("Pareto front, seen on its first two objectives (lower is better)", fontsize=11,
                 loc="left")
    shown = front.take(list(range(min(8, front.num_rows))))
    tiles = _regrown_tiles(store, shown, lambda r: f"{r['id']}")
    for n, (label, regrown) in enumerate(tiles):
        row, col = divmod(n, 4)
        sub = fig.add_axes((0.52 + col * 0.12, 0.5 - row * 0.42, 0.12, 0.4), projection="3d")
        _draw_tile(sub, regrown)
        sub.set_title(label, fontsize=8, pad=-2)
        ax.annotate(str(n + 1), (fx[n], fy[n]), fontsize=8, xytext=(3, 3), textcoords="offset points")
        sub.text2D(0.02, 0.92, str(n + 1), transform=sub.transAxes, fontsize=9, fontweight="bold")
    fig.suptitle(f"{getattr(store, 'run_id', run_label(store))}: the non-dominated {noun}s",
                 x=0.01, ha="left", fontsize=13, fontweight="bold")
    return fig, f"front of {front.num_rows} {noun}s"


def archive_figure_of(run: RunLike, *, generation: int | None = -1) -> tuple[Any, str]:
    """The MAP-Elites archive as a map of thumbnails: one tile per cell of the first two descriptors
    (the best over a third), empty cells blank."""
    from genr8_dist.evolution.archive import Grid
    from genr8_dist.history._run import dataset
    from genr8_dist.history._search import _newest_config, archive
    from genr8_dist.history._tables import _resolve_generation

    store = open_run(run)
    grid = Grid.from_settings(_newest_config(store).search)
    generation = _resolve_generation(dataset(store), generation)
    table = archive(store, generation=generation)
    names = grid.descriptors
    cols = grid.bins[0]
    rows = grid.bins[1] if len(names) > 1 else 1
    best: dict[tuple[int, int], dict[str, Any]] = {}
    for r in table.to_pylist():   # best first
        key = (r[f"bin_{names[0]}"], r[f"bin_{names[1]}"] if len(names) > 1 else 0)
        best.setdefault(key, r)
    plt = _pyplot()
    fig = plt.figure(figsize=(2.3 * cols + 1.0, 2.3 * rows + 0.9), facecolor="white")
    from genr8_dist.history._regrow import regrow

    for (i, j), r in best.items():
        ax = fig.add_subplot(rows, cols, (rows - 1 - j) * cols + i + 1, projection="3d")
        _draw_tile(ax, regrow(store, r["id"]))
        ax.set_title(f"{r['id']}  {r['fitness'] + 0.0:.3g}", fontsize=7, pad=-4)
    (lo0, hi0), n0 = grid.ranges[0], grid.bins[0]
    xlabel = f"{names[0]} →  ({lo0:g} to {hi0:g}, {n0} bins)"
    ylabel = (f"{names[1]} →  ({grid.ranges[1][0]:g} to {grid.ranges[1][1]:g}, {grid.bins[1]} bins)"
              if len(names) > 1 else "")
    fig.text(0.5, 0.01, xlabel, ha="center", fontsize=11)
    fig.text(0.005, 0.5, ylabel, va="center", rotation=90, fontsize=11)
    where = "the whole run" if generation is None else f"after generation {generation}"
    fig.suptitle(f"{getattr(store, 'run_id', run_label(store))}: MAP-Elites archive {where}, "
                 f"{len(table)} of {grid.size} cells held (best fitness per cell)", x=0.01, ha="left",
                 fontsize=12, fontweight="bold")
    fig.subplots_adjust(left=0.03, right=0.99, bottom=0.05, top=1 - 1.0 / (2.3 * rows + 0.9),
                        wspace=0.02, hspace=0.1)
    return fig, f"{len(table)} of {grid.size} cells"
