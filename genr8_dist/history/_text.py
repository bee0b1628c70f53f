"""Plain-text renderings of history tables: aligned columns a person can read in a terminal or a log."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import pyarrow as pa

__all__ = ["format_table", "format_value", "heading", "lineage_text", "short_criterion", "shown_columns"]

def short_criterion(name: str) -> str:
    """A column heading for criterion ``name`` (``smoothness`` -> ``smooth``): its registered heading."""
    from genr8_dist.fitness import criterion_heading

    return criterion_heading(name)


def heading(column: str) -> str:
    """The heading of a stored column in a text table: a criterion's short heading, a declared
    column's ``heading``, else the name."""
    from genr8_dist.store.schema import column_heading

    return column_heading(column)


def shown_columns(available: Sequence[str]) -> list[str]:
    """The columns ``genr8 top`` prints of a ``history.top`` table with these columns, in order."""
    from genr8_dist.store.schema import criterion_of, listed_columns, sizes_of

    crits = [c for name in available if (c := criterion_of(name)) is not None]
    return listed_columns(crits, sizes=sizes_of(available), shown=True, available=available)


def format_value(value: Any, width: int | None = None) -> str:
    """``value`` as a short string: floats to 5 significant digits, lists joined by commas, nulls as
    ``-``; cut to ``width`` characters with an ellipsis."""
    if value is None:
        text = "-"
    elif isinstance(value, bool):
        text = "yes" if value else "no"
    elif isinstance(value, float):
        if math.isnan(value):
            text = "nan"
        elif math.isinf(value):
            text = "inf" if value > 0 else "-inf"
        else:
            text = f"{value:.5g}"
    elif isinstance(value, (list, tuple)):
        text = ",".join(format_value(v) for v in value) or "-"
    else:
        text = str(value).replace("\n", " | ")
    if width is not None and len(text) > width:
        text = text[: max(1, width - 1)] + "…"
    return text


def format_table(table: pa.Table, columns: Sequence[str] | None = None, *,
                 headings: dict[str, str] | None = None, max_width: int = 48,
                 max_rows: int | None = None) -> str:
    """``table`` as aligned text columns, numbers right-aligned; ``max_rows`` rows at most, with a
    closing line saying how many were left out."""
    columns = list(columns or table.column_names)
    headings = headings or {}
    shown = table if max_rows is None else table.slice(0, max_rows)
    cells = {name: [format_value(v, max_width) for v in shown[name].to_pylist()] for name in columns}
    numeric = {name: pa.types.is_integer(table.schema.field(name).type)
               or pa.types.is_floating(table.schema.field(name).type) for name in columns}
    widths = {name: max([len(headings.get(name, name))] + [len(c) for c in cells[name]])
              for name in columns}

    def cell(name: str, text: str) -> str:
        return text.rjust(widths[name]) if numeric[name] else text.ljust(widths[name])

    lines = ["  ".join(cell(n, headings.get(n, n)) for n in columns).rstrip()]
    for row in range(shown.num_rows):
        lines.append("  ".join(cell(n, cells[n][row]) for n in columns).rstrip())
    if max_rows is not None and table.num_rows > max_rows:
        lines.append(f"... {table.num_rows - max_rows} more rows (of {table.num_rows})")
    return "\n".join(lines)


def _how(origin: str, parents: list[str], island: int) -> str:
    """How an individual was made, in words."""
    from genr8_dist.history._run import parse_id

    parents = list(parents or [])
    if origin == "random":
        return "random (founder)" if not parents else "random"
    if origin == "migrant" and parents:
        where = parse_id(parents[0])
        source = f"island {where[0]}" if where else "another island"
        return f"migrant from {source} ({parents[0]})"
    if origin == "injected":
        return f"injected (copy of {', '.join(parents)})" if parents else "injected by the user"
    if origin == "elite" and parents:
        return f"elite copy of {parents[0]}"
    if parents:
        return f"{origin} of {' x '.join(parents)}"
    return origin


def lineage_text(table: pa.Table, id: str, *, per_generation: int | None = 12) -> str:
    """The ancestry table from ``history.lineage`` as text: a summary, the main line, then the
    ancestors by generation (``*`` marks the main line), at most ``per_generation`` of each generation
    besides the main line (``None``: all of them)."""
    import numpy as np
    import pyarrow.compute as pc

    if table.num_rows == 0:
        return f"no ancestry for {id}"
    me = table.filter(pc.equal(table["id"], id)).to_pylist()[0]
    origins = dict(zip(*[c.to_pylist() for c in pc.value_counts(table["origin"]).flatten()],
                       strict=True))
    gens = table["generation"].to_numpy()
    n_gens = len(np.unique(gens))
    founders = int((gens == 0).sum())
    missing = sorted({p for ps in table.filter(pc.greater(pc.list_value_length(table["missing"]), 0))[
        "missing"].to_pylist() for p in ps})
    summary = (f"ancestry of {id} (generation {me['generation']}, island {me['island']}, fitness "
               f"{format_value(me['fitness']) if me['valid'] else 'invalid'}): "
               f"{table.num_rows - 1} ancestors over {n_gens} "
               f"generation{'s' if n_gens != 1 else ''}; {origins.get('migrant', 0)} migrants, "
               f"{origins.get('injected', 0)} injected, {founders} in generation 0")
    lines = [summary]
    if missing:
        lines.append(f"parents not in this run: {', '.join(missing)}")
    chain = table.filter(table["main_line"]).to_pylist()
    import textwrap

    lines.extend(textwrap.wrap(" <- ".join(
        f"{r['id']} ({r['origin']}, {format_value(r['fitness']) if r['valid'] else 'invalid'})"
        for r in chain),
        width=110, initial_indent="main line (first parents): ", subsequent_indent="    ",
        break_long_words=False, break_on_hyphens=False))
    change = np.r_[True, gens[1:] != gens[:-1]]
    group_start = np.maximum.accumulate(np.where(change, np.arange(len(gens)), 0))
    position = np.arange(len(gens)) - group_start
    size = np.bincount(gens - gens.min())[gens - gens.min()]
    line = table["main_line"].to_numpy(zero_copy_only=False)
    keep = line | (position < per_generation) if per_generation is not None else np.ones(len(gens), bool)
    shown = table.filter(pa.array(keep)).to_pylist()
    hidden = {int(g): int(size[i] - keep[i:i + size[i]].sum())
              for i, g in enumerate(gens) if change[i]}
    width = max(len(r["id"]) for r in shown)
    current = None
    for r in shown:
        if r["generation"] != current:
            if current is not None and hidden[current]:
                lines.append(f"   ... and {hidden[current]} more in generation {current}")
            current = r["generation"]
            lines.append(f"generation {current}")
        mark = "*" if r["main_line"] else " "
        fitness = format_value(r["fitness"]) if r["valid"] else "invalid"
        lines.append(f" {mark} {r['id'].ljust(width)}  fitness {fitness:>9}  "
                     f"{_how(r['origin'], r['parents'], r['island'])}")
    if current is not None and hidden[current]:
        lines.append(f"   ... and {hidden[current]} more in generation {current}")
    if per_generation is not None and any(hidden.values()):
        lines.append(f"({sum(hidden.values())} ancestors not listed; --all lists every one)")
    return "\n".join(lines)
