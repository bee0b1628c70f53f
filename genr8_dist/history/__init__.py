"""Query a run's history, look at it, and take designs out of it (Genr8's output window, from the files).

Every function takes a run directory (or an open ``RunStore``) and returns Arrow tables, so a notebook
gets the same data the ``genr8 history / top / lineage / query`` commands print.
"""

from __future__ import annotations

from genr8_dist.history import pictures, report
from genr8_dist.history._regrow import Regrown, export, export_formats, picture, regrow, save_text
from genr8_dist.history._run import HistoryError, open_run, run_directory_holding, write_table
from genr8_dist.history._search import archive, clusters, pareto_front
from genr8_dist.history._tables import (
    QUERY_TIMEOUT,
    configs,
    events,
    individual,
    interventions,
    lineage,
    per_generation,
    query,
    top,
)

__all__ = [
    "QUERY_TIMEOUT",
    "HistoryError",
    "Regrown",
    "archive",
    "clusters",
    "configs",
    "events",
    "export",
    "export_formats",
    "individual",
    "interventions",
    "lineage",
    "open_run",
    "pareto_front",
    "per_generation",
    "picture",
    "pictures",
    "query",
    "regrow",
    "report",
    "run_directory_holding",
    "save_text",
    "top",
    "write_table",
]
