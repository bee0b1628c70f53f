"""``genr8 history / top / lineage / show / query / gallery / report``: look into a run from its files.

Genr8's output window, for runs of any size: the fitness curves, the population ranked with each
individual's criteria and rewrite system, where an individual came from, re-growing one to export it,
SQL over everything, a contact sheet of the best designs, and one HTML page that holds it all.
"""

from __future__ import annotations

import argparse
import sys
from typing import Any

from genr8_dist.cli._args import int32

__all__ = ["register"]


def _run_arg(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("run", metavar="RUN", help="the run directory (or a URI pyarrow understands)")


def _generation(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a generation number: {text!r}") from None
    if not -(2**31) <= value < 2**31:
        raise argparse.ArgumentTypeError(f"{text}: out of range (at most {2**31 - 1} either way)")
    return value


def _count(text: str) -> int:
    value = int32(text)
    if value < 0:
        raise argparse.ArgumentTypeError(f"{value}: must be 0 or more")
    return value


def _seconds(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number of seconds: {text!r}") from None
    if not 0 < value < 1e9:
        raise argparse.ArgumentTypeError(f"{text}: must be a positive number of seconds")
    return value


def register(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add the history commands to ``genr8``."""
    p = subparsers.add_parser(
        "history", help="fitness per generation and island (best, median, worst, criteria)",
        description="Per generation and island: best, median and worst total fitness of the valid "
                    "individuals and each criterion's value closest to its target.")
    _run_arg(p)
    p.add_argument("--island", type=int32, help="only this island")
    p.add_argument("--png", metavar="OUT.png", help="also draw the fitness curves to this PNG")
    p.add_argument("--csv", metavar="OUT.csv", help="write the table as CSV instead of printing it")
    p.set_defaults(handler=_history)

    p = subparsers.add_parser(
        "top", help="the best individuals, with their criteria (and rewrite systems)",
        description="The k best valid individuals of the run, a generation or an island.")
    _run_arg(p)
    p.add_argument("-k", type=int32, default=10, help="how many (default 10)")
    p.add_argument("--generation", type=_generation, help="only this generation (-1: the last)")
    p.add_argument("--island", type=int32, help="only this island")
    p.add_argument("--criterion", help="rank by this criterion's distance to its target, not the total")
    p.add_argument("--systems", action="store_true", help="print each individual's rewrite system")
    rows = p.add_mutually_exclusive_group()
    rows.add_argument("--distinct", action="store_true",
                      help="one row per form, the default: copies, elites and mirror images of one design "
                           "are one form, listed by its best with how many individuals share it")
    rows.add_argument("--all", action="store_true",
                      help="every individual, a form's copies included (elites rank twice)")
    p.add_argument("--pareto", action="store_true",
                   help="list the non-dominated designs over the Pareto objectives instead")
    p.set_defaults(handler=_top)

    p = subparsers.add_parser(
        "lineage", help="the ancestry of an individual back to the first generation",
        description="Every ancestor of an individual, how each was made (crossover, mutation, elite, "
                    "migrant, injected) and from whom; '*' marks the line of first parents.")
    _run_arg(p)
    p.add_argument("id", metavar="ID", help="the individual, as island-generation-index (e.g. 2-49-3), or "
                                            "'best': the run's best valid individual")
    p.add_argument("--depth", type=int32, help="only this many generations back")
    p.add_argument("--all", action="store_true",
                   help="list every ancestor (default: the main line and 12 per generation)")
    p.add_argument("--png", metavar="OUT.png", help="also draw the ancestry to this PNG")
    p.set_defaults(handler=_lineage)

    p = subparsers.add_parser(
        "show", help="regrow one individual, check it is bit-identical, export it",
        description="Regrow an individual from its row and the configuration version it was evaluated "
                    "under, check its phenotype (a surface, a table...) against the recorded digest and "
                    "sizes, and export it.")
    _run_arg(p)
    p.add_argument("id", metavar="ID", help="the individual, as island-generation-index, or 'best': the "
                                            "run's best valid individual")
    p.add_argument("-o", "--output", action="append", default=[], metavar="OUT",
                   help="export it in a format of its phenotype (a surface: .obj .ply .stl .glb through "
                        "trimesh or .3dm for Rhino; a table: .obj .ply .stl .glb); repeatable")
    p.add_argument("--png", metavar="OUT.png", help="a picture of it (its phenotype's preview)")
    p.add_argument("--smooth", type=int, default=0, metavar="N",
                   help="Loop subdivision steps applied to a surface's -o mesh (0-4; each x4 the triangles)")
    p.add_argument("--grammar", metavar="OUT.txt", help="save its rewrite system")
    p.add_argument("--genome", metavar="OUT.txt", help="save its genome (codons, one line)")
    p.set_defaults(handler=_show)

    p = subparsers.add_parser(
        "query", help="SQL over the run (tables individuals, events, configs)",
        description="Run an SQL statement (DuckDB) over the views individuals, events and configs. "
                    "docs/history.md lists their columns.")
    _run_arg(p)
    p.add_argument("sql", metavar="SQL", help='e.g. "select generation, min(fitness) from individuals '
                                              'group by 1 order by 1"')
    out = p.add_mutually_exclusive_group()
    out.add_argument("--csv", metavar="OUT.csv", help="write the result as CSV")
    out.add_argument("--parquet", metavar="OUT.parquet", help="write the result as Parquet")
    p.add_argument("--max-rows", type=_count, default=100, help="rows printed at most (default 100)")
    p.add_argument("--timeout", type=_seconds, default=None, metavar="SECONDS",
                   help="interrupt a statement running longer (default 60)")
    p.add_argument("--as-of", type=_count, default=None, metavar="G",
                   help="read the run as of generation G: its individuals up to G, the events at them, "
                        "the configurations in force by G (time travel)")
    p.set_defaults(handler=_query)

    p = subparsers.add_parser(
        "gallery", help="a contact sheet of the best designs of a generation",
        description="Regrow the k best individuals of a generation (or of each island) and draw them "
                    "side by side, each tile labelled with its id and fitness.")
    _run_arg(p)
    p.add_argument("--generation", type=_generation, default=-1, help="the generation (default -1: the last)")
    p.add_argument("-k", type=int32, default=12,
                   help="how many designs (default 12; per island with --per-island)")
    p.add_argument("--island", type=int32, help="only this island")
    p.add_argument("--per-island", action="store_true", help="one row of the best k per island")
    p.add_argument("--duplicates", action="store_true",
                   help="also show individuals whose phenotype equals a better one's (elites, copies)")
    view = p.add_mutually_exclusive_group()
    view.add_argument("--clusters", type=int32, metavar="K",
                      help="instead: K kinds of form among the whole run's distinct designs "
                           "(the least alike in outline, height field and curvature)")
    view.add_argument("--archive", action="store_true",
                      help="instead: the MAP-Elites archive after the generation, as a map")
    p.add_argument("-o", "--output", required=True, metavar="OUT.png", help="the PNG to write")
    p.set_defaults(handler=_gallery)

    p = subparsers.add_parser(
        "export", help="regrow many designs and export each: the Pareto front, a cluster, or ids",
        description="Regrow every chosen design (checked bit-identical, as `genr8 show`) and write it in "
                    "each chosen format into DIR, as DIR/ID.FORMAT.")
    _run_arg(p)
    which = p.add_mutually_exclusive_group(required=True)
    which.add_argument("--front", action="store_true",
                       help="the run's Pareto front (its non-dominated distinct designs, as top --pareto)")
    which.add_argument("--cluster", type=int32, metavar="K",
                       help="every distinct design of kind of form K (1: the largest cluster) of the run's "
                            "--clusters N (as gallery --clusters)")
    which.add_argument("--ids", nargs="+", metavar="ID", help="these individuals ('best' for the best)")
    p.add_argument("--clusters", type=int32, default=12, metavar="N", help="kinds of form (default 12)")
    p.add_argument("--format", action="append", metavar="EXT",
                   help="obj, ply, stl, glb or 3dm (a surface), repeatable (default: obj)")
    p.add_argument("-o", "--output", required=True, metavar="DIR", help="the folder to write into")
    p.set_defaults(handler=_export)

    p = subparsers.add_parser(
        "report", help="one self-contained HTML page: curves, gallery, top individuals, interventions",
        description="Write one HTML file with the fitness curves, a gallery of the best designs, the "
                    "top individuals with their rewrite systems and criteria, and the interventions. "
                    "Images are embedded; it needs no network to view.")
    _run_arg(p)
    p.add_argument("-o", "--output", required=True, metavar="OUT.html", help="the HTML file to write")
    p.add_argument("-k", type=int32, default=10, help="individuals in the table (default 10)")
    p.add_argument("--gallery", type=int32, default=12, metavar="K",
                   help="designs in the gallery (default 12)")
    p.set_defaults(handler=_report)


def _print(text: str) -> None:
    sys.stdout.write(text + "\n")


def _sayer(*paths: Any) -> Any:
    """``_print``, or its standard-error twin when one of ``paths`` is standard output (``-``,
    ``/dev/stdout``): the data alone goes there, as a Unix tool's does."""
    from genr8_dist.files import is_stdout

    if any(p is not None and is_stdout(p) for p in paths):
        return lambda text: print(text, file=sys.stderr)
    return _print


def _individual_id(run: str, ident: str) -> str:
    """``ident``, with ``best`` standing for the run's best valid individual (so a command written
    before the run is known, as in the README, names an individual every run has)."""
    if ident.strip().lower() != "best":
        return ident
    from genr8_dist import history

    table = history.top(run, 1)
    if table.num_rows == 0:
        raise history.HistoryError(f"{run}: has no valid individual yet; name one as ISLAND-GENERATION-INDEX")
    return str(table["id"][0].as_py())


def _history(args: argparse.Namespace) -> int:
    from genr8_dist import history
    from genr8_dist.history import _text
    from genr8_dist.store.schema import criterion_column

    store = history.open_run(args.run)
    table = history.per_generation(store, island=args.island)
    if args.csv:
        history.write_table(table, args.csv)
        _sayer(args.csv)(f"wrote {table.num_rows} rows to {args.csv}")
    else:
        crits = [c[len("closest_"):] for c in table.column_names if c.startswith("closest_")]
        headings = {"generation": "gen", "island": "isl", "n_valid": "valid", "best_id": "best id"}
        headings.update({f"closest_{c}": "closest_" + _text.heading(criterion_column(c)) for c in crits})
        columns = ["generation", "island", "n", "n_valid", "best", "median", "worst", "best_id"]
        _print(_text.format_table(table, columns + [f"closest_{c}" for c in crits], headings=headings))
    if args.png:
        from genr8_dist.history import pictures

        pictures.curves_png(store, args.png, table=table)
        _print(f"wrote {args.png}")
    return 0


def _top(args: argparse.Namespace) -> int:
    from genr8_dist import history
    from genr8_dist.history import _text

    if args.pareto:
        if args.criterion:
            raise history.HistoryError("--pareto and --criterion: give one of them")
        table = history.pareto_front(args.run, generation=args.generation, island=args.island)
        devs = [c for c in table.column_names if c.startswith("dev_")]
        columns = [*_text.shown_columns(table.column_names), *devs]
        headings = {name: _text.heading(name) for name in columns} | {d: d for d in devs}
        _print(f"{table.num_rows} non-dominated designs (dev_: weighted deviation from the target)")
        _print(_text.format_table(table, columns, headings=headings))
        return 0
    table = history.top(args.run, args.k, generation=args.generation, island=args.island,
                        criterion=args.criterion, systems=args.systems, distinct=not args.all)
    columns = ["rank", *_text.shown_columns(table.column_names)]
    if not args.all:
        columns.append("copies")
    if args.criterion:
        columns.insert(columns.index("fitness") + 1, "deviation")
    headings = {name: _text.heading(name) for name in columns}
    if not args.systems:
        _print(_text.format_table(table, columns, headings=headings))
        return 0
    lines = _text.format_table(table, columns, headings=headings).splitlines()
    _print(lines[0])
    for row, line in enumerate(lines[1:]):
        _print(line)
        text = table["text"][row].as_py() or ""
        for statement in text.splitlines():
            _print(f"      {statement}")
    return 0


def _lineage(args: argparse.Namespace) -> int:
    from genr8_dist import history
    from genr8_dist.history import _text

    store = history.open_run(args.run)
    args.id = _individual_id(args.run, args.id)
    table = history.lineage(store, args.id, depth=args.depth)
    _print(_text.lineage_text(table, args.id, per_generation=None if args.all else 12))
    if args.png:
        from genr8_dist.history import pictures

        pictures.lineage_png(table, args.id, args.png)
        _print(f"wrote {args.png}")
    return 0


def _show(args: argparse.Namespace) -> int:
    from genr8_dist.history import HistoryError, _text
    from genr8_dist.history import _regrow as regrow
    from genr8_dist.store.schema import criterion_of

    say = _sayer(*args.output, args.png, args.grammar, args.genome)

    if args.png and args.png != "-" and not str(args.png).lower().endswith(".png"):
        raise HistoryError(f"{args.png}: --png writes a .png file")
    args.id = _individual_id(args.run, args.id)
    if args.smooth:
        from genr8_dist.export import check_smooth

        check_smooth(args.smooth)
    if args.output:  # refuse a bad name before anything is grown or written
        phenotype = regrow.phenotype_of_run(args.run, args.id)
        for path in args.output:
            regrow.check_export_path(path, phenotype)
    result = regrow.regrow(args.run, args.id)
    row = result.row
    crits = {c: v for k, v in row.items() if (c := criterion_of(k)) is not None}
    say(f"{row['id']}: generation {row['generation']}, island {row['island']}, "
           f"{row['origin']}, configuration version {row['config_version']}")
    if row["valid"]:
        say(f"fitness {_text.format_value(row['fitness'])}  " + "  ".join(
            f"{k} {_text.format_value(v)}" for k, v in crits.items()))
    else:
        say(f"invalid at {row['stage']}: {row['error']}")
    reads = result.developed.reads if result.developed is not None else None
    unread = set(result.phenotype.unread(row["text"], reads)) if row["text"] and reads else set()
    say("rewrite system" + (" (# never fired: a rule that rewrote no edge in this growth):" if unread
                            else ":"))
    for number, statement in enumerate((row["text"] or "(none: the genome did not map)").splitlines(), 1):
        say(f"    {statement}" + ("    # never fired" if number in unread else ""))
    if row["text"] and result.text_matches is False:
        say("note: the genome no longer maps to this rewrite system with this universe; the "
               "recorded system was grown")
    if result.developed is not None:
        say(f"regrown: {result.phenotype.describe(result.developed)} after {result.steps} "
               f"derivation steps; digest {result.digest} matches the recorded one")
    for path in args.output:
        regrow.export(result, path, smooth=args.smooth)
        say(f"wrote {path}")
    if args.png:
        regrow.picture(result, args.png)
        say(f"wrote {args.png}")
    if args.grammar:
        regrow.save_text(row["text"] or "", args.grammar, what="rewrite system", id=row["id"])
        say(f"wrote {args.grammar}")
    if args.genome:
        regrow.save_text(" ".join(str(c) for c in row["genome"]) + "\n", args.genome, what="genome",
                         id=row["id"])
        say(f"wrote {args.genome}")
    return 0


def _query(args: argparse.Namespace) -> int:
    from genr8_dist import history
    from genr8_dist.history import _text

    timeout = args.timeout if args.timeout is not None else history.QUERY_TIMEOUT
    target = args.csv or args.parquet
    if target:
        inside = history.run_directory_holding(target)
        if inside is not None:
            raise history.HistoryError(f"{target}: is inside the run directory {inside}; query never "
                                       "writes into a run: choose a path outside it")
    table = history.query(args.run, args.sql, timeout=timeout, as_of=args.as_of)
    if target:
        history.write_table(table, target, format="csv" if args.csv else "parquet")
        _sayer(target)(f"wrote {table.num_rows} rows to {target}")
        return 0
    if table.num_columns == 0:
        _print("(no result)")
        return 0
    _print(_text.format_table(table, max_rows=args.max_rows))
    _print(f"({table.num_rows} row{'s' if table.num_rows != 1 else ''})")
    return 0


def _gallery(args: argparse.Namespace) -> int:
    from genr8_dist.history import pictures

    if args.clusters is not None:
        fig, info = pictures.clusters_figure_of(args.run, args.clusters, generation=None,
                                                island=args.island)
        pictures.save_figure(fig, args.output)
        _sayer(args.output)(f"wrote {args.output}: {info}")
        _sayer(args.output)(_cluster_statistics(args.run, args.clusters, args.island))
        return 0
    elif args.archive:
        fig, info = pictures.archive_figure_of(args.run, generation=args.generation)
        pictures.save_figure(fig, args.output)
    else:
        info = pictures.gallery_png(args.run, args.output, generation=args.generation, k=args.k,
                                    island=args.island, per_island=args.per_island,
                                    distinct=not args.duplicates)
    _sayer(args.output)(f"wrote {args.output}: {info}")
    return 0


def _cluster_statistics(run: str, k: int, island: int | None) -> str:
    """Per kind of form (the clusters ``gallery --clusters`` draws): its size and the range of the
    fitness and of each weighted criterion over its members, as an aligned table."""
    import pyarrow as pa

    from genr8_dist.history import _search, _text

    stats = _search.cluster_ranges(_search.clusters(run, k, island=island), _search.weighted_criteria(run))
    names = list(stats[0]["ranges"]) if stats else []
    table = pa.table({"cluster": [s["cluster"] for s in stats], "members": [s["members"] for s in stats],
                      "representative": [s["id"] for s in stats],
                      **{_text.short_criterion(n) if n != "fitness" else n:
                         [_search.format_range(*s["ranges"][n]) for s in stats] for n in names}})
    return "ranges over each cluster's members:\n" + _text.format_table(table)


def _export(args: argparse.Namespace) -> int:
    from pathlib import Path

    from genr8_dist import history
    from genr8_dist.history import _regrow as regrow

    if args.front:
        ids = history.pareto_front(args.run)["id"].to_pylist()
    elif args.cluster is not None:
        kinds = history.clusters(args.run, args.clusters)
        if not 1 <= args.cluster <= kinds.num_rows:
            raise history.HistoryError(f"--cluster {args.cluster}: the run's {kinds.num_rows} kinds of form "
                                       f"are 1..{kinds.num_rows}")
        ids = kinds["member_ids"][args.cluster - 1].as_py()
    else:
        ids = list(dict.fromkeys(_individual_id(args.run, i) for i in args.ids))
    out = Path(args.output)
    inside = history.run_directory_holding(out)
    if inside is not None:
        raise history.HistoryError(f"{out}: is inside the run directory {inside}; choose a folder outside it")
    formats = [f.lower().lstrip(".") for f in (args.format or ["obj"])]
    if not ids:
        raise history.HistoryError(f"{args.run}: no design to export")
    phenotype = regrow.phenotype_of_run(args.run, ids[0])
    paths = {i: [out / f"{i}.{f}" for f in formats] for i in ids}
    for path in paths[ids[0]]:   # a bad format is refused before anything is grown or written
        regrow.check_export_path(path, phenotype)
    out.mkdir(parents=True, exist_ok=True)
    for ident in ids:
        result = regrow.regrow(args.run, ident)
        for path in paths[ident]:
            regrow.export(result, path)
    more = f" and {len(ids) - 12} more" if len(ids) > 12 else ""
    _print(f"wrote {len(ids)} design{'s' if len(ids) != 1 else ''} x {', '.join(formats)} to {out}: "
           + " ".join(ids[:12]) + more)
    return 0


def _report(args: argparse.Namespace) -> int:
    from genr8_dist.history import report

    report.write_report(args.run, args.output, k=args.k, gallery_k=args.gallery)
    _sayer(args.output)(f"wrote {args.output}")
    return 0
