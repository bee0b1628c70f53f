"""One self-contained HTML page about a run: Genr8's output window as a file a designer can open anywhere.

The page holds the fitness curves, a gallery of the best designs of the last generation (drawn by the
run's phenotype: surfaces, tables...), the kinds of form the run found (clusters; and the Pareto front
or the MAP-Elites archive in those modes) with each cluster's size and criterion ranges, the
parallel coordinates of the run's distinct designs across their criteria (brushing an axis selects
designs), the top individuals with their criteria and rewrite systems, the interventions with what
each changed, and the configuration versions. Images are embedded as base64 PNG; the one script (the
parallel coordinates, the studio's ``parallel.js``) is inline and its data too; there are no fonts or
links to fetch, so it opens offline and can be mailed as one file.
"""

from __future__ import annotations

import base64
import html
import json
import math
import os
import tomllib
from pathlib import Path
from typing import TYPE_CHECKING, Any

from genr8_dist.errors import Genr8Error
from genr8_dist.history._regrow import export_formats
from genr8_dist.history._run import RunLike, atomic_write, criteria_of, open_run, run_label
from genr8_dist.history._search import POOL_PER_KIND
from genr8_dist.store.schema import criterion_column

if TYPE_CHECKING:
    from genr8_dist.phenotype import Phenotype
    from genr8_dist.store import ConfigVersion, RunStore

__all__ = ["report_html", "write_report"]

_LINEAGE_DEPTH = 30  # generations of the best individual's ancestry drawn in the report
PARALLEL_DESIGNS = 300   # the best distinct designs drawn in the parallel coordinates
_PARALLEL_JS = Path(__file__).resolve().parents[1] / "studio" / "static" / "parallel.js"
_PARALLEL_GLUE = Path(__file__).resolve().parent / "report_parallel.js"

_CSS = """
body { font-family: -apple-system, "Segoe UI", Helvetica, Arial, sans-serif; margin: 0;
       background: #f6f6f3; color: #222; }
header { background: #1f2a36; color: #fff; padding: 22px 36px; }
header h1 { margin: 0 0 6px 0; font-size: 26px; font-weight: 600; }
header p { margin: 0; color: #c8d0d8; font-size: 14px; }
main { padding: 10px 36px 40px 36px; max-width: 1500px; }
section { background: #fff; border-radius: 8px; padding: 16px 22px; margin: 18px 0;
          box-shadow: 0 1px 3px rgba(0,0,0,0.08); }
h2 { font-size: 19px; margin: 4px 0 12px 0; color: #1f2a36; }
.facts { display: flex; flex-wrap: wrap; gap: 12px; }
.fact { background: #eef2f5; border-radius: 6px; padding: 10px 16px; min-width: 120px; }
.fact b { display: block; font-size: 22px; color: #1f2a36; }
.fact span { font-size: 12px; color: #5a6570; text-transform: uppercase; letter-spacing: .04em; }
img { max-width: 100%; height: auto; display: block; }
table { border-collapse: collapse; font-size: 13px; width: 100%; }
th { text-align: left; background: #eef2f5; padding: 6px 8px; font-weight: 600; }
td { padding: 6px 8px; border-top: 1px solid #eceff1; vertical-align: top; }
td.num { text-align: right; font-variant-numeric: tabular-nums; white-space: nowrap; }
pre { margin: 0; font-size: 12px; background: #f7f7f2; padding: 6px 8px; border-radius: 4px;
      white-space: pre-wrap; }
.note { color: #6b747c; font-size: 13px; }
code { background: #eef2f5; padding: 1px 5px; border-radius: 3px; white-space: nowrap; }
svg.pc { width: 100%; height: 300px; display: block; background: #fbfbf9; border-radius: 6px;
         user-select: none; }
svg.pc .axis line { stroke: #7a8794; stroke-width: 1; }
svg.pc .axis text { fill: #2b3640; font-size: 12px; }
svg.pc .axis .tick { fill: #6b747c; font-size: 10px; }
svg.pc .axis .hit { fill: transparent; cursor: ns-resize; }
svg.pc .brush { fill: rgba(224, 120, 40, 0.16); stroke: #d9772b; stroke-width: 1; }
svg.pc path.design { fill: none; stroke-width: 1.2; opacity: 0.7; cursor: pointer; }
svg.pc path.design.out { opacity: 0.06; }
svg.pc path.design.selected { stroke-width: 3; opacity: 1; }
svg.pc .target { stroke: #d9772b; stroke-width: 2; }
tr.picked td { background: #fdf0e1; }
.pc-bar { display: flex; gap: 12px; align-items: baseline; margin: 8px 0; }
.pc-bar button { font: inherit; font-size: 13px; padding: 3px 10px; border: 1px solid #c8d0d8;
                 border-radius: 4px; background: #fff; cursor: pointer; }
"""


def _fmt(value: Any) -> str:
    if value is None:
        return "–"
    if isinstance(value, float):
        if math.isinf(value):
            return "∞"
        return f"{value:.4g}"
    return str(value)


def _img(png: bytes, alt: str) -> str:
    data = base64.b64encode(png).decode("ascii")
    return f'<img alt="{html.escape(alt)}" src="data:image/png;base64,{data}">'


def _flatten(data: Any, prefix: str = "") -> dict[str, Any]:
    if isinstance(data, dict):
        out: dict[str, Any] = {}
        for key, value in data.items():
            out.update(_flatten(value, f"{prefix}.{key}" if prefix else str(key)))
        return out
    return {prefix: data}


def _changes(old_toml: str, new_toml: str) -> list[str]:
    """What a configuration version changed from the one before, as ``key: old -> new`` lines."""
    try:
        old, new = _flatten(tomllib.loads(old_toml)), _flatten(tomllib.loads(new_toml))
    except tomllib.TOMLDecodeError:
        return []
    lines = []
    for key in sorted(set(old) | set(new)):
        if key.startswith("stored_universe.") and key != "stored_universe.digest":
            continue   # the universe's files: their digest says whether they changed
        if old.get(key) != new.get(key):
            lines.append(f"{key}: {_short(old.get(key, '(default)'))} → {_short(new.get(key, '(default)'))}")
    return lines


def _short(value: Any, limit: int = 80) -> str:
    text = str(value)
    return text if len(text) <= limit else text[:limit - 1] + "…"


def _section(title: str, body: str) -> str:
    return f"<section><h2>{html.escape(title)}</h2>{body}</section>"


def _phenotype(store: RunStore, configs: list[ConfigVersion]) -> Phenotype:
    """The phenotype of the run's newest configuration (surfaces when it cannot be read)."""
    from genr8_dist.history._run import phenotype_for
    from genr8_dist.phenotype import SURFACES

    try:
        return phenotype_for(store, store.config(configs[-1].version))
    except Genr8Error:
        return SURFACES


def report_html(run: RunLike, *, k: int = 10, gallery_k: int = 12) -> str:
    """The report page of ``run`` as one HTML string (see the module docstring)."""
    import pyarrow.compute as pc

    from genr8_dist.history import _tables, pictures

    store = open_run(run)
    per_gen = _tables.per_generation(store)
    name = getattr(store, "run_id", run_label(store))
    gens = per_gen["generation"]
    last = int(pc.max(gens).as_py())
    islands = sorted(set(per_gen["island"].to_pylist()))
    n_total = int(pc.sum(per_gen["n"]).as_py())
    n_valid = int(pc.sum(per_gen["n_valid"]).as_py())
    newest = int(store.configs()[-1].version)
    best = _tables.top(store, k, systems=True, under=newest, distinct=True)
    events = _tables.events(store)
    configs = list(store.configs())
    kinds = events["kind"].to_pylist()

    facts = [("generations", last + 1), ("islands", len(islands)), ("individuals", f"{n_total:,}"),
             ("valid", f"{100.0 * n_valid / max(n_total, 1):.1f}%"),
             ("best fitness", _fmt(best["fitness"][0].as_py()) if best.num_rows else "–"),
             ("best individual", best["id"][0].as_py() if best.num_rows else "–"),
             ("interventions", kinds.count("intervention")),
             ("configuration versions", len(configs))]
    parts = ['<div class="facts">' + "".join(
        f'<div class="fact"><b>{html.escape(str(v))}</b><span>{html.escape(t)}</span></div>'
        for t, v in facts) + "</div>"]
    parts.append(_section("Fitness over the generations", _img(
        pictures.png_bytes(pictures.curves_figure(store, per_gen), dpi=90),
        "fitness curves per island") + '<p class="note">Solid: the best individual of each island; '
        "dashed: the median. Triangles along the axis mark migrations; vertical lines mark "
        "interventions and resumptions. Lower fitness is better.</p>"))

    try:
        fig, info = pictures.gallery_figure_of(store, generation=last, k=gallery_k)
        gallery = _img(pictures.png_bytes(fig, dpi=80), f"gallery: {info}")
        gallery += f'<p class="note">{html.escape(info)}, regrown from the run\'s rows.</p>'
    except Genr8Error as exc:
        gallery = f'<p class="note">No gallery: {html.escape(str(exc))}</p>'
    phenotype = _phenotype(store, configs)
    parts.append(_section(f"The best {phenotype.noun}s of generation {last}", gallery))
    parts.extend(_search_sections(store, run_label(store), phenotype.noun))
    parts.append(_cluster_statistics_section(store, phenotype.noun))
    parts.append(_parallel_section(store, phenotype.noun))

    crits = criteria_of(best.schema)
    head = "".join(f"<th>{h}</th>" for h in ["#", "id", "gen", "island", f"fitness under v{newest}",
                                              "as scored",
                                              *[c.replace("_", " ") for c in crits],
                                              "copies", "made by", "rewrite system"])
    formats = export_formats(phenotype)
    rows = []
    for r in best.to_pylist():
        cells = [f'<td class="num">{r["rank"]}</td>', f"<td><code>{html.escape(r['id'])}</code></td>",
                 f'<td class="num">{r["generation"]}</td>', f'<td class="num">{r["island"]}</td>',
                 f'<td class="num"><b>{_fmt(r[f"fitness_v{newest}"])}</b></td>',
                 f'<td class="num">{_fmt(r["fitness"])} (v{r["config_version"]})</td>']
        cells += [f'<td class="num">{_fmt(r[criterion_column(c)])}</td>' for c in crits]
        cells.append(f'<td class="num">{r["copies"]}</td>')
        made = r["origin"] + (" of " + ", ".join(r["parents"]) if r["parents"] else "")
        cells.append(f"<td>{html.escape(made)}</td>")
        cells.append(f"<td><pre>{html.escape(r.get('text') or '')}</pre></td>")
        rows.append("<tr>" + "".join(cells) + "</tr>")
    top_note = (f'<p class="note">Regrow and export any of them: <code>genr8 show '
                f"{html.escape(str(run_label(store)))} ID -o {phenotype.noun}.{formats[0]}</code> (also "
                f"{' '.join('.' + f for f in formats[1:])}).</p>")
    ranked = (f'<p class="note">Ranked under configuration version {newest}, the one in force at the '
              "run's end: each individual rescored from its stored raw criteria with that version's "
              "targets and weights. <i>As scored</i> is the fitness the run gave it under the version "
              "in brackets.</p>" if len(configs) > 1 else "")
    forms = ('<p class="note">One row per form: an individual\'s elites and copies, and its mirror '
             "images (equal sizes and criteria), are one form, shown by its best; <i>copies</i> counts "
             "the run's valid individuals of that form.</p>")
    parts.append(_section(f"The {best.num_rows} best forms of the run",
                          f"{forms}{ranked}<table><tr>{head}</tr>{''.join(rows)}</table>{top_note}"))

    if best.num_rows:
        champion = best["id"][0].as_py()
        tree = _tables.lineage(store, champion, depth=_LINEAGE_DEPTH)
        parts.append(_section(f"Where {champion} came from", _img(
            pictures.png_bytes(pictures.lineage_figure(tree, champion), dpi=80),
            f"ancestry of {champion}") + f'<p class="note">Its ancestors over the last '
            f"{_LINEAGE_DEPTH} generations at most, coloured by how each was made; the black line "
            f"follows first parents. <code>genr8 lineage {html.escape(str(run_label(store)))} "
            f"{champion}</code> lists them.</p>"))

    rows = []
    previous = None
    for cv in configs:
        change = _changes(previous.toml, cv.toml) if previous is not None else ["the run's start"]
        rows.append(f'<tr><td class="num">{cv.version}</td><td class="num">{cv.effective_generation}</td>'
                    f"<td>{html.escape(str(cv.created))}</td>"
                    f"<td><pre>{html.escape(chr(10).join(change) or '(no change)')}</pre></td></tr>")
        previous = cv
    table = ("<table><tr><th>version</th><th>from generation</th><th>created</th><th>what changed</th>"
             f"</tr>{''.join(rows)}</table>")
    other = [e for e in events.to_pylist() if e["kind"] in ("intervention", "interrupt", "resume",
                                                              "recovery")]
    if other:
        table += "<h2 style='margin-top:18px'>Interruptions, interventions, resumptions</h2><table>"
        table += "<tr><th>generation</th><th>what</th><th>detail</th></tr>"
        for e in other:
            try:
                detail = json.dumps(json.loads(e["detail"]), indent=1, sort_keys=True)
            except ValueError:
                detail = e["detail"]
            table += (f'<tr><td class="num">{e["generation"]}</td><td>{html.escape(e["kind"])}</td>'
                      f"<td><pre>{html.escape(detail)}</pre></td></tr>")
        table += "</table>"
    migrations = kinds.count("migration")
    table += f'<p class="note">{migrations} migrations between islands.</p>'
    parts.append(_section("Configuration versions and interventions", table))

    title = f"genr8 run {name}"
    subtitle = (f"{html.escape(str(run_label(store)))} · generations 0–{last} · "
                f"{len(islands)} islands")
    return ("<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">"
            f"<title>{html.escape(title)}</title><style>{_CSS}</style></head><body>"
            f"<header><h1>{html.escape(title)}</h1><p>{subtitle}</p></header>"
            f"<main>{''.join(parts)}</main></body></html>\n")


def _figure_section(title: str, draw: Any, dpi: int, note: Any, failed: str = "") -> str:
    """A section holding the figure ``draw()`` returns with ``note(info)`` under it, or the one-line
    reason it could not be drawn (prefixed by ``failed``)."""
    from genr8_dist.history import pictures

    try:
        fig, info = draw()
    except Genr8Error as exc:
        return _section(title, f'<p class="note">{failed}{html.escape(str(exc))}</p>')
    return _section(title, _img(pictures.png_bytes(fig, dpi=dpi), info) + note(info))


def _search_sections(store: RunStore, label: str, noun: str) -> list[str]:
    """The search modes' sections: the Pareto front (``pareto`` mode), the MAP-Elites archive
    (``map-elites`` mode), and in every mode the kinds of form the run found (12 clusters)."""
    from genr8_dist.history import pictures

    sections = []
    mode = store.config(store.configs()[-1]).search.mode
    shown = html.escape(str(label))
    if mode == "pareto":
        sections.append(_figure_section(
            "The Pareto front", lambda: pictures.pareto_figure_of(store), 80,
            lambda info: f'<p class="note">{html.escape(info)} over the run; the first two '
                         "objectives drawn, the thumbnails numbered as on the plot. "
                         f"<code>genr8 top {shown} --pareto</code> lists them all.</p>"))
    if mode == "map-elites":
        sections.append(_figure_section(
            "The MAP-Elites archive", lambda: pictures.archive_figure_of(store), 70,
            lambda info: f'<p class="note">{html.escape(info)} held after the last '
                         f"generation: each tile the best {noun} of its cell. "
                         f"<code>genr8 gallery {shown} --archive -o map.png</code>.</p>"))
    sections.append(_figure_section(
        "Kinds of form the run found", lambda: pictures.clusters_figure_of(store, 12), 80,
        lambda info: f'<p class="note">Among the run\'s best {POOL_PER_KIND * 12} distinct {noun}s, '
                     "12 that look least alike (outline, height field, curvature), chosen from the "
                     "best one on; in brackets, how many of those look most like each, largest first. "
                     f"<code>genr8 gallery {shown} --clusters 12 -o kinds.png</code>.</p>",
        failed="No clusters: "))
    return sections


def _cluster_statistics_section(store: RunStore, noun: str) -> str:
    """Per kind of form (the 12 clusters drawn above): its size, its representative and
    the range of the fitness and of each weighted criterion over its members."""
    from genr8_dist.history._search import cluster_ranges, clusters, format_range, weighted_criteria

    title = "Statistics of the kinds of form"
    try:
        stats = cluster_ranges(clusters(store, 12), weighted_criteria(store))
    except Genr8Error as exc:
        return _section(title, f'<p class="note">No clusters: {html.escape(str(exc))}</p>')
    names = list(stats[0]["ranges"]) if stats else []
    head = "".join(f"<th>{html.escape(h)}</th>" for h in
                   ["kind", f"{noun}s", "representative", *[n.replace("_", " ") for n in names]])
    rows = "".join(
        f'<tr><td class="num">{s["cluster"]}</td><td class="num">{s["members"]}</td>'
        f"<td><code>{html.escape(s['id'])}</code></td>"
        + "".join(f'<td class="num">{html.escape(format_range(*s["ranges"][n]))}</td>' for n in names)
        + "</tr>" for s in stats)
    note = (f'<p class="note">Each cluster\'s distinct {noun}s: how many, and the lowest and highest '
            "value of the fitness and of each weighted criterion among them (raw values).</p>")
    return _section(title, f"{note}<table><tr>{head}</tr>{rows}</table>")


def _parallel_section(store: RunStore, noun: str) -> str:
    """The parallel coordinates of the run's best distinct designs (``PARALLEL_DESIGNS``) across the
    fitness and the weighted criteria, drawn in the page by the studio's ``parallel.js``: dragging
    along an axis brushes a range, and the designs inside every brush are listed under the plot."""
    from genr8_dist.history._search import _distinct, _newest_config

    title = "Parallel coordinates of the criteria"
    try:
        table = _distinct(store, None, None, [])
    except Genr8Error as exc:
        return _section(title, f'<p class="note">No designs: {html.escape(str(exc))}</p>')
    fitness = _newest_config(store).fitness
    names = [n for n in fitness.names if fitness[n].weight > 0 and criterion_column(n) in table.column_names]
    shown = table.slice(0, PARALLEL_DESIGNS)

    def finite(v: Any) -> float | None:
        return float(v) if v is not None and math.isfinite(v) else None

    rows = [{"id": r["id"], "generation": r["generation"], "island": r["island"],
             "fitness": finite(r["fitness"]), "criteria": {n: finite(r[criterion_column(n)]) for n in names}}
            for r in shown.select(["id", "generation", "island", "fitness", *map(criterion_column, names)])
            .to_pylist()]
    axes = [{"key": n, "label": n.replace("_", " "), "target": finite(fitness[n].target)} for n in names]
    data = json.dumps({"rows": rows, "axes": axes}, separators=(",", ":")).replace("</", "<\\/")
    script = (_PARALLEL_JS.read_text(encoding="utf-8").replace("export function", "function") + "\n"
              + _PARALLEL_GLUE.read_text(encoding="utf-8"))
    of = (f"the best {len(rows)} of the run's {table.num_rows} distinct {noun}s" if table.num_rows > len(rows)
          else f"the run's {len(rows)} distinct {noun}s")
    note = (f'<p class="note">One line per design ({of}, best amber to worst blue) across its fitness '
            "and weighted criteria, raw values, each target marked on its axis. Drag along an axis to "
            "brush a range (a click on the axis clears it); the designs inside every brush are listed "
            "below, best first. Click a line to mark its design in the list.</p>")
    body = (f'{note}<svg class="pc" id="pc"></svg><div class="pc-bar"><b id="pc-count"></b>'
            '<button id="pc-clear" type="button">clear brushes</button></div>'
            '<table id="pc-list"></table>'
            f'<script type="application/json" id="pc-data">{data}</script>'
            f"<script>\n{script}</script>")
    return _section(title, body)


def write_report(run: RunLike, path: str | os.PathLike[str], *, k: int = 10, gallery_k: int = 12) -> Path:
    """Write ``report_html(run)`` to ``path`` atomically; returns the path."""
    text = report_html(run, k=k, gallery_k=gallery_k)
    atomic_write(path, lambda tmp: Path(tmp).write_text(text, encoding="utf-8"))
    return Path(path)
