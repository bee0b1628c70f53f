"""What the studio shows, read from the run directory: progress, curves, a generation, one design, its
surface as GLB, the environment's forces and boundaries.

Everything comes from the run store (``RunStore``, ``genr8_dist.history``). A surface is grown again
from the rewrite system the run recorded, in the environment of the configuration version that scored
it: no universe is loaded, so no plugin code runs to show a design. Curves are computed once and then
only for the generations committed since (``per_generation(since=...)``), so a live run of a million
individuals updates in a fraction of a second.

A running run's generations are shown as each island completes them, before their commit: the live
view the driver writes (``store/live.py``) fills in what the store does not hold yet, and every row
and generation taken from it says ``durable: false`` (the page marks it "not yet committed").
"""

from __future__ import annotations

import json
import math
import threading
import time
from collections import OrderedDict
from typing import TYPE_CHECKING, Any, cast

from genr8_dist.errors import ConfigError, Genr8Error, StoreError
from genr8_dist.store.schema import criterion_column, size_column, size_of

if TYPE_CHECKING:
    import pyarrow as pa

    from genr8_dist.config import RunConfig
    from genr8_dist.hemls.surface import Surface
    from genr8_dist.store import RunStore

__all__ = ["MAX_FACES", "RunView"]

MAX_FACES = 20_000          # a surface with more triangles is decimated before it is sent
MAX_EDGES = 30_000          # scaffold edges sent with a surface (every k-th one past this)
GLB_CACHE = 256             # surfaces kept in memory
GENERATION_CACHE = 32       # generations' rows (and their kinds of form) kept in memory
KINDS = 12                  # kinds of form shown (Biomorpher shows 12)
MAX_KINDS = 36
LINEAGE_DEPTH = 12          # generations of the main line shown for a design


def _finite(value: float | None) -> float | None:
    if value is None:
        return None
    value = float(value)
    return value if math.isfinite(value) else None


class RunView:
    """A run directory as the studio reads it; thread-safe (the server answers requests in threads)."""

    def __init__(self, run_dir: str) -> None:
        self.run_dir = run_dir
        self._store: RunStore | None = None
        self._lock = threading.RLock()
        self._curves_lock = threading.Lock()
        self._curves_store: RunStore | None = None
        self._curves: dict[str, Any] | None = None
        self._curves_version = -1
        self._surfaces: OrderedDict[str, bytes] = OrderedDict()
        self._generations: OrderedDict[int, list[dict[str, Any]]] = OrderedDict()
        self._kinds: OrderedDict[tuple[int, int, int | None], dict[str, Any]] = OrderedDict()
        self._configs: dict[int, RunConfig] = {}
        self._seen: tuple[float, int] | None = None   # (time, individuals) when the newest commit was seen

    # -- the store ----------------------------------------------------------------------------------
    def store(self) -> RunStore:
        """The run's store at its newest commit (``StoreError`` until the run directory is a run)."""
        from genr8_dist.store import RunStore

        with self._lock:
            if self._store is None:
                self._store = RunStore.open(self.run_dir)
            else:
                self._store.refresh()
            return self._store

    def config(self, version: int | None = None) -> RunConfig:
        """Configuration ``version`` (default: the newest) as a ``RunConfig``."""
        from genr8_dist.history._run import config_of

        with self._lock:
            if version is not None and version in self._configs:
                return self._configs[version]
        store = self.store() if version is None or self._store is None else self._store
        if version is None:
            version = int(store.configs()[-1].version)
        with self._lock:
            found = self._configs.get(version)
            if found is None:
                found = self._configs[version] = config_of(store, version)
            return found

    def warm(self) -> None:
        """Read what the page asks for first (the state, the newest generation, then the curves) while
        the designer opens it; a run not created yet is left to the page's polls."""
        from genr8_dist.errors import Genr8Error

        try:
            self.state()
            self.generation()
            self.curves()
        except (Genr8Error, OSError):
            pass

    # -- progress -----------------------------------------------------------------------------------
    def state(self) -> dict[str, Any]:
        """Progress and status: generation, individuals/s, time left, islands, queue, interventions."""
        store = self.store()
        config = self.config()
        committed = store.committed_generations()
        n = int(config.islands.count)
        low = min((committed.get(i, -1) for i in range(n)), default=-1)
        last = int(config.ea.generations)
        events = self._events(store)
        holder = store.running()
        kinds = [e["kind"] for e in events]
        paused = False
        for e in events:
            if e["kind"] == "pause":
                paused = True
            elif e["kind"] in ("continue", "resume", "start"):
                paused = False
        if holder is not None and holder.get("role") == "run":
            status = "paused" if paused else "running"
        elif low >= last and "complete" in kinds:
            status = "complete"
        else:
            status = "stopped"
        population = int(config.ea.population)
        live = store.live().read() if status in ("running", "paused") else {}
        done = {i: max([committed.get(i, -1), *(g for g, by in live.items() if i in by)]) for i in range(n)}
        shown = min(done.values(), default=-1)
        rate, left = self._rate(events, shown, n * population, last, status)
        with self._lock:
            curves = self._curves or {"islands": {}}   # as far as computed (``curves`` runs apart)
        islands = []
        for i in range(n):
            best = curves["islands"].get(str(i), {}).get("best", [])
            live_best = [r["fitness"] for r in live.get(done[i], {}).get(i, ()) if r["fitness"] is not None]
            islands.append({"island": i, "generation": committed.get(i, -1), "completed": done[i],
                            "best": min(live_best) if done[i] > committed.get(i, -1) and live_best
                            else best[-1] if best else None})
        return {
            "run_id": store.run_id, "path": str(store.path), "version": store.version, "status": status,
            "generation": low, "last_generation": last, "islands": islands, "population": population,
            "completed": shown, "live": {"generations": sorted(live), "durable": shown <= low},
            "individuals_per_second": rate, "seconds_left": left,
            "criteria": self._criteria(config),
            "queued": [{"number": q.number, "kind": q.request.get("kind"),
                        "label": _request_label(q.request)} for q in store.queued()],
            "interventions": self._interventions(events),
            "environment": self._environment_values(config),
            "injectable": _builtin_universe(str(config.universe)),
            "search": getattr(getattr(config, "search", None), "mode", "weighted"),
            "objectives": self._objectives(config),
        }

    def _objectives(self, config: RunConfig) -> list[str]:
        """The criteria a Pareto search would treat as objectives (``pareto_objectives``), stored ones."""
        from genr8_dist.evolution.island import pareto_objectives

        return [n for n in pareto_objectives(config) if n in self.store().criteria]

    def _events(self, store: RunStore) -> list[dict[str, Any]]:
        table = store.events()
        out = []
        for row in table.select(["kind", "generation", "island", "detail", "time"]).to_pylist():
            row["detail"] = json.loads(row["detail"] or "{}")
            row["time"] = row["time"].timestamp() if row["time"] is not None else None
            out.append(row)
        return out

    def _rate(self, events: list[dict[str, Any]], low: int, per_generation: int, last: int,
              status: str) -> tuple[float | None, float | None]:
        """Individuals per second since the run last started or resumed, and seconds left."""
        starts = [e for e in events if e["kind"] in ("start", "resume") and e["time"] is not None]
        if not starts or low < 0:
            return None, None
        since = starts[-1]
        first = since["generation"] if since["kind"] == "resume" else 0
        done = max(0, low - first + 1) * per_generation
        now = time.time()
        if status != "running":
            ends = [e["time"] for e in events if e["kind"] in ("complete", "interrupt", "pause")
                    and e["time"] is not None and e["time"] >= since["time"]]
            if not ends:   # stopped without a trace (killed): no rate can be told, and nothing is left
                return None, None
            now = ends[-1]
        elapsed = now - since["time"]
        if done <= 0 or elapsed <= 0:
            return None, None
        rate = done / elapsed
        return rate, max(0, last - low) * per_generation / rate

    def _criteria(self, config: RunConfig) -> list[dict[str, Any]]:
        spec = config.fitness
        out: list[dict[str, Any]] = []
        for name in self.store().criteria:
            try:
                term = spec[name]
            except KeyError:
                out.append({"name": name, "target": None, "weight": None})
                continue
            out.append({"name": name, "target": _finite(term.target), "weight": _finite(term.weight),
                        "unit": _finite(term.unit)})
        return out

    @staticmethod
    def _environment_values(config: RunConfig) -> dict[str, Any]:
        env = config.environment
        return {"steps": int(env.steps), "scale": [float(v) for v in env.scale],
                "gravity": [float(v) for v in env.gravity],
                "attractors": len(env.attractors), "repellers": len(env.repellers),
                "boundaries": len(env.boundaries)}

    @staticmethod
    def _interventions(events: list[dict[str, Any]]) -> list[dict[str, Any]]:
        out = []
        for e in events:
            if e["kind"] not in ("intervention", "pause", "continue", "refused"):
                continue
            d = e["detail"]
            parts: list[str] = []
            if e["kind"] == "intervention":
                parts += [f"{k} = {v}" for k, v in (d.get("changes") or {}).items()]
                for item in d.get("injected") or ():
                    parts.append(str(item.get("source")))
                for item in d.get("hand_fitness") or ():
                    parts.append(f"hand fitness {item['id']} = {item['fitness']:.4g}")
                label = f"v{d.get('config_version')}"
            elif e["kind"] == "refused":
                parts.append(str(d.get("reason")))
                label = "refused"
            else:
                label = e["kind"]
            out.append({"kind": e["kind"], "generation": e["generation"], "label": label,
                        "what": parts, "source": d.get("source", "edit")})
        return out

    # -- curves -------------------------------------------------------------------------------------
    def curves(self) -> dict[str, Any]:
        """Per generation: the best and mean fitness over all islands, each island's best, and the
        raw criteria of the generation's best design; plus the configuration versions' first
        generations. Only the generations committed since the last call are read. A running run's
        generations every island has completed but not committed follow (``live`` counts them)."""
        import copy

        durable = self._durable_curves()
        store = self.store()
        live = store.live().read() if store.running() is not None else {}
        n = int(self.config().islands.count)
        ahead = sorted(g for g, by in live.items() if g > durable["last"] and len(by) == n)
        if not ahead:
            return dict(durable, live=0)
        curves = copy.deepcopy(durable)
        for g in ahead:
            rows = [r for by in live[g].values() for r in by]
            valid = [r for r in rows if r["fitness"] is not None]
            best = min(valid, key=lambda r: (r["fitness"], r["island"], r["index"]), default=None)
            curves["generation"].append(g)
            curves["best"].append(best["fitness"] if best else None)
            curves["mean"].append(sum(r["fitness"] for r in valid) / len(valid) if valid else None)
            curves["best_id"].append(best["id"] if best else None)
            for name in store.criteria:
                value = best.get(criterion_column(name)) if best else None
                curves["criteria"].setdefault(name, []).append(value)
            for island, by in live[g].items():
                isl = curves["islands"].setdefault(str(island), {"generation": [], "best": []})
                fits = [r["fitness"] for r in by if r["fitness"] is not None]
                isl["generation"].append(g)
                isl["best"].append(min(fits) if fits else None)
        curves["last"] = ahead[-1]
        curves["live"] = len(ahead)
        return curves

    def _durable_curves(self) -> dict[str, Any]:
        """``curves`` of the committed generations (cached, extended by each commit)."""
        import copy

        from genr8_dist.store import RunStore

        version = self.store().version
        with self._lock:
            if self._curves is not None and self._curves_version == version:
                return self._curves
        # Computed apart (its own store, its own lock): the state, a generation and a surface are
        # answered meanwhile, so the page shows them before the first read of the whole run ends.
        with self._curves_lock:
            if self._curves_store is None:
                self._curves_store = RunStore.open(self.run_dir)
            store = self._curves_store.refresh()
            with self._lock:
                if self._curves is not None and self._curves_version == store.version:
                    return self._curves
                curves = copy.deepcopy(self._curves) if self._curves is not None else {
                    "generation": [], "best": [], "mean": [], "best_id": [], "islands": {}, "criteria": {},
                    "last": -1}
            _add_generations(curves, store)
            curves["versions"] = [{"version": int(c.version), "generation": int(c.effective_generation)}
                                  for c in store.configs()]
            with self._lock:
                self._curves, self._curves_version = curves, store.version
            return curves

    # -- generations and designs --------------------------------------------------------------------
    def generation(self, generation: int | None = None) -> dict[str, Any]:
        """The individuals of ``generation`` (default: the newest every island committed), best first."""

        store = self.store()
        committed = store.committed_generations()
        live = store.live().read() if store.running() is not None else {}
        n = int(self.config().islands.count)
        newest = min((committed.get(i, -1) for i in range(n)), default=-1)
        completed = min((max([committed.get(i, -1), *(g for g, by in live.items() if i in by)])
                         for i in range(n)), default=-1)
        if generation is None or generation < 0:   # the newest every island completed; else the founders
            generation = completed if completed >= 0 or 0 not in live else 0
        if generation > newest and generation in live:
            return self._live_generation(store, int(generation), committed, live[generation], newest)
        if not committed:
            return {"generation": -1, "individuals": []}
        g = min(int(generation), max(committed.values()))
        with self._lock:
            rows = self._generations.get(g)
            if rows is not None:
                self._generations.move_to_end(g)
                return {"generation": g, "newest": newest, "individuals": rows}
        crits = [criterion_column(c) for c in store.criteria]
        columns = ["id", "island", "index", "fitness", "valid", "origin",
                   *[size_column(s) for s in store.sizes], "config_version", *crits]
        import pyarrow.compute as pc

        # one read of the files holding generation g (only they are checked against their sha256)
        table = store.dataset((g, g)).to_table(columns=columns, filter=pc.field("generation") == g)
        front = self._pareto(table, store.criteria)
        rows = table.to_pylist()
        for r, on in zip(rows, front, strict=True):
            r["pareto"] = bool(on)
            r["criteria"] = {c: _finite(r.pop(criterion_column(c))) for c in store.criteria}
        rows.sort(key=lambda r: (not r["valid"], r["fitness"] if math.isfinite(r["fitness"]) else math.inf,
                                 r["island"], r["index"]))
        for r in rows:
            r["fitness"] = _finite(r["fitness"])
        if g <= newest:   # every island committed it: its rows and its front never change
            with self._lock:
                self._generations[g] = rows
                while len(self._generations) > GENERATION_CACHE:
                    self._generations.popitem(last=False)
        return {"generation": g, "newest": newest, "individuals": rows}

    def _live_generation(self, store: RunStore, g: int, committed: dict[int, int],
                         live: dict[int, list[dict[str, Any]]], newest: int) -> dict[str, Any]:
        """Generation ``g`` as far as the islands have completed it: committed islands' rows from the
        store, the others' from the live view (``durable: false``)."""
        import pyarrow as pa
        import pyarrow.compute as pc

        crits = [criterion_column(c) for c in store.criteria]
        columns = ["id", "island", "index", "fitness", "valid", "origin",
                   *[size_column(s) for s in store.sizes], "config_version", *crits]
        rows: list[dict[str, Any]] = []
        if any(c >= g for c in committed.values()):
            table = store.dataset((g, g)).to_table(columns=columns, filter=pc.field("generation") == g)
            rows = [dict(r, durable=True) for r in table.to_pylist()]
        held = {r["island"] for r in rows}
        for island, found in sorted(live.items()):
            if island not in held:
                rows += [dict({c: r.get(c) for c in columns}, durable=False) for r in found]
        for r in rows:
            r["fitness"] = _finite(r["fitness"]) if r["fitness"] is not None else None
        table = pa.Table.from_pylist([{c: (math.inf if c == "fitness" and r[c] is None else r[c])
                                       for c in columns} for r in rows])
        front = self._pareto(table, store.criteria) if rows else []
        for r, on in zip(rows, front, strict=True):
            r["pareto"] = bool(on)
            r["criteria"] = {c: r.pop(criterion_column(c), None) for c in store.criteria}
        rows.sort(key=lambda r: (not r["valid"], r["fitness"] if r["fitness"] is not None else math.inf,
                                 r["island"], r["index"]))
        return {"generation": g, "newest": newest, "individuals": rows, "durable": False,
                "islands": sorted({r["island"] for r in rows})}

    def live_row(self, id: str) -> dict[str, Any] | None:
        """``id``'s row in the running run's live view (completed, not committed), if it is there."""
        from genr8_dist.evolution.individual import parse_id

        parsed = parse_id(id)
        if parsed is None:
            return None
        island, generation, _ = parsed
        store = self.store()
        for r in store.live().read().get(generation, {}).get(island, ()):
            if r["id"] == id:
                return dict(r)
        return None

    def _pareto(self, table: pa.Table, criteria: tuple[str, ...]) -> list[bool]:
        """Which rows are on the Pareto front of their generation (all islands together): the
        non-dominated valid ones over the weighted deviations of the Pareto objectives (the search's
        own ``pareto_objectives``, ``objectives_of`` and ``non_dominated``), under the newest
        configuration version among them."""
        from genr8_dist.evolution.island import pareto_objectives
        from genr8_dist.evolution.pareto import non_dominated, objectives_of

        if table.num_rows == 0:
            return []
        config = self.config(max(table["config_version"].to_pylist()))
        names = [n for n in pareto_objectives(config) if n in criteria]
        if not names:
            return [False] * table.num_rows
        raws = [{n: (math.nan if r[criterion_column(n)] is None else r[criterion_column(n)]) for n in names}
                for r in table.select([criterion_column(n) for n in names]).to_pylist()]
        valid = table["valid"].to_pylist()
        front = non_dominated(objectives_of(raws, valid, config.fitness, names))
        return [bool(ok) and bool(on) for ok, on in zip(valid, front, strict=True)]

    def clusters(self, generation: int | None = None, k: int = KINDS, island: int | None = None
                 ) -> dict[str, Any]:
        """The kinds of form of ``generation`` (default: the newest), as Biomorpher shows them: its
        distinct valid surfaces (of ``island``, or all) as ``k`` kinds told apart by outline, height
        field and curvature (``history.clusters``), one representative per kind with the kind's size
        and criterion ranges, largest first."""
        from genr8_dist.errors import HistoryError
        from genr8_dist.history import clusters
        from genr8_dist.history._search import cluster_ranges, weighted_criteria

        store = self.store()
        committed = store.committed_generations()
        if not committed:
            return {"generation": -1, "k": k, "representatives": []}
        newest = min(committed.values())
        g = newest if generation is None or generation < 0 else min(int(generation), max(committed.values()))
        if not 1 <= k <= MAX_KINDS:
            raise ConfigError(f"k {k}: the studio shows 1 to {MAX_KINDS} kinds of form")
        key = (g, k, island)
        with self._lock:
            found = self._kinds.get(key)
        if found is not None:
            return found
        try:
            table = clusters(store, k, generation=g, island=island)
            sizes = [c for c in table.column_names if size_of(c) is not None]
            ranges = {s["id"]: s["ranges"] for s in cluster_ranges(table, weighted_criteria(store))}
            rows = [{"id": r["id"], "cluster": r["cluster"], "members": r["members"], "island": r["island"],
                     "fitness": _finite(r["fitness"]), **{c: r[c] for c in sizes},
                     "ranges": {n: list(v) for n, v in ranges[r["id"]].items()}}
                    for r in table.select(["id", "cluster", "members", "island", "fitness", *sizes])
                    .to_pylist()]
            answer: dict[str, Any] = {"generation": g, "k": k, "representatives": rows,
                                      "surfaces": sum(r["members"] for r in rows)}
        except HistoryError as exc:   # no valid design in it: nothing to cluster
            answer = {"generation": g, "k": k, "representatives": [], "message": str(exc)}
        if g <= newest:
            with self._lock:
                self._kinds[key] = answer
                while len(self._kinds) > GENERATION_CACHE:
                    self._kinds.popitem(last=False)
        return answer

    def archive(self, generation: int | None = None) -> dict[str, Any] | None:
        """The MAP-Elites archive of ``generation`` (default: the newest) when the run searches in
        ``map-elites`` mode: per occupied cell its bins and elite (the lowest fitness over all islands,
        ``Grid.archive``); ``None`` for a run of another mode."""
        from genr8_dist.evolution.archive import Grid

        store = self.store()
        committed = store.committed_generations()
        config = self.config()
        search = getattr(config, "search", None)
        if not committed or search is None or search.mode != "map-elites":
            return None
        g = min(committed.values()) if generation is None or generation < 0 else int(generation)
        grid = Grid.from_settings(search)
        individuals = [ind for i in sorted(committed) if committed[i] >= g
                       for ind in store.load_generation(i, g)]
        cells = grid.archive(individuals)
        return {"generation": g, "descriptors": list(grid.descriptors),
                "ranges": [list(r) for r in grid.ranges], "bins": list(grid.bins),
                "cells": [{"cell": c, "bins": list(grid.coordinates(c)), "id": ind.id,
                           "fitness": _finite(ind.fitness)} for c, ind in sorted(cells.items())]}

    def individual(self, id: str) -> dict[str, Any]:
        """One design: its row (criteria, rewrite system, provenance), its main line of ancestors, the
        hand fitness a designer gave it, and the targets and weights it was scored under."""
        from genr8_dist.history import individual, lineage

        store = self.store()
        try:
            row = individual(store, id).to_pylist()[0]
            durable = True
        except Genr8Error:
            found = self.live_row(id)
            if found is None:
                raise
            row, durable = found, False
        config = self.config(int(row["config_version"]))
        crits = []
        for c in self._criteria(config):
            c["value"] = _finite(row.get(criterion_column(c["name"])))
            crits.append(c)
        line = lineage(store, id, depth=LINEAGE_DEPTH).to_pylist() if durable else []
        main = [{"id": r["id"], "generation": r["generation"], "origin": r["origin"],
                 "fitness": _finite(r["fitness"])} for r in line if r.get("main_line")]
        hand = [h for e in self._events(store) if e["kind"] == "intervention"
                for h in e["detail"].get("hand_fitness") or () if h["id"] == id]
        return {
            "id": row["id"], "island": row["island"], "generation": row["generation"], "index": row["index"],
            "fitness": _finite(row["fitness"]), "valid": row["valid"], "stage": row["stage"],
            "error": row["error"], "origin": row["origin"], "parents": row["parents"],
            "config_version": row["config_version"], "text": row["text"],
            "genome_length": len(row["genome"]) if "genome" in row else None,
            "counts": {**{s: row[c] for c in row if (s := size_of(c)) is not None},
                       "steps": row["steps_done"]},
            "criteria": crits, "lineage": main, "hand_fitness": hand, "durable": durable,
            "downloads": downloads(),
        }

    # -- surfaces -----------------------------------------------------------------------------------
    def _grow(self, id: str) -> tuple[Surface, RunConfig]:
        """The recorded rewrite system of ``id`` grown again in its configuration's environment."""
        from genr8_dist.hemls import grow, parse
        from genr8_dist.history import individual

        try:
            row = individual(self.store(), id, ["text", "config_version", "phenotype_digest"]).to_pylist()[0]
        except Genr8Error:
            row = self.live_row(id)
            if row is None:
                raise
        if not row["text"] or row.get("phenotype_digest") is None:
            raise StoreError(f"{id} has no surface: it failed before growing one")
        config = self.config(int(row["config_version"]))
        surface = grow(parse(row["text"]), config.environment).surface
        return surface.with_meshing(config.meshing), config

    def surface_glb(self, id: str) -> bytes:
        """``id``'s surface as GLB: its regions (decimated past ``MAX_FACES`` triangles) and its map's
        edges as lines; cached."""
        with self._lock:
            found = self._surfaces.get(id)
            if found is not None:
                self._surfaces.move_to_end(id)
                return found
        surface, _ = self._grow(id)
        data = _glb(surface)
        with self._lock:
            self._surfaces[id] = data
            while len(self._surfaces) > GLB_CACHE:
                self._surfaces.popitem(last=False)
        return data

    def download(self, id: str, kind: str) -> tuple[bytes, str]:
        """``id``'s full surface as a file of one of the ``downloads()`` formats (bytes, media type)."""
        from genr8_dist.export import SURFACE_FORMATS, surface_bytes

        surface, _ = self._grow(id)
        found = SURFACE_FORMATS.get(kind)
        if found is None or not found.download:
            raise StoreError(f"unknown download format {kind!r}: "
                             f"{', '.join(d['format'] for d in downloads())}")
        return surface_bytes(surface, kind, name=id), found.media

    def environment(self, version: int | None = None) -> dict[str, Any]:
        """The environment of configuration ``version`` to draw: attractors, repellers, boundaries."""
        env = self.config(version).environment
        boundaries = [b.sketch() for b in env.boundaries]   # each kind draws itself (boundaries.py)
        return {
            "attractors": [{"position": list(map(float, a.position)), "constant": float(a.constant)}
                           for a in env.attractors],
            "repellers": [{"position": list(map(float, r.position)), "constant": float(r.constant)}
                          for r in env.repellers],
            "boundaries": boundaries, "gravity": [float(v) for v in env.gravity],
        }


def _add_generations(curves: dict[str, Any], store: RunStore) -> None:
    """Extend ``curves`` with the generations every island committed after ``curves["last"]``: one
    read of five columns and Arrow's hash aggregation (a million rows in well under a second)."""
    import numpy as np
    import pyarrow as pa
    import pyarrow.compute as pc

    committed = store.committed_generations()
    if not committed:
        return
    done = min(committed.values())
    since = int(curves["last"])
    if done <= since:
        return
    crits = [criterion_column(c) for c in store.criteria]
    span = (pc.field("generation") > since) & (pc.field("generation") <= done)
    table = store.dataset().to_table(columns=["generation", "island", "index", "fitness", *crits],
                                     filter=span if since >= 0 or done < max(committed.values()) else None)
    if table.num_rows == 0:
        return
    fitness = pc.if_else(pc.is_finite(table["fitness"]), table["fitness"], pa.scalar(None, pa.float64()))
    table = table.set_column(table.schema.get_field_index("fitness"), "fitness", fitness)
    per_island = table.group_by(["generation", "island"]).aggregate([("fitness", "min")])
    per_gen = table.group_by("generation").aggregate([("fitness", "min"), ("fitness", "mean")])
    per_gen = per_gen.sort_by("generation")
    best_rows = table.join(per_gen.select(["generation", "fitness_min"]), keys=["generation", "fitness"],
                           right_keys=["generation", "fitness_min"], join_type="inner")
    best_rows = best_rows.sort_by([("generation", "ascending"), ("island", "ascending"),
                                   ("index", "ascending")])
    first: dict[int, dict[str, Any]] = {}
    for row in best_rows.to_pylist():
        first.setdefault(int(row["generation"]), row)
    gens = np.asarray(per_gen["generation"].to_numpy(zero_copy_only=False), dtype=np.int64)
    bests = per_gen["fitness_min"].to_pylist()
    means = per_gen["fitness_mean"].to_pylist()
    for g, best, mean in zip(gens.tolist(), bests, means, strict=True):
        row = first.get(g)
        curves["generation"].append(g)
        curves["best"].append(_finite(best))
        curves["mean"].append(_finite(mean))
        curves["best_id"].append(f"{row['island']}-{g}-{row['index']}" if row else None)
        for name in store.criteria:
            value = _finite(row[criterion_column(name)]) if row else None
            curves["criteria"].setdefault(name, []).append(value)
    island_rows = per_island.sort_by([("island", "ascending"), ("generation", "ascending")]).to_pylist()
    for row in island_rows:
        isl = curves["islands"].setdefault(str(row["island"]), {"generation": [], "best": []})
        isl["generation"].append(int(row["generation"]))
        isl["best"].append(_finite(row["fitness_min"]))
    curves["last"] = done


def _glb(surface: Surface) -> bytes:
    import numpy as np
    import trimesh

    from genr8_dist.scaffold import scaffold_curves

    mesh_ = surface.mesh()          # the run's meshing; its meshing-1 triangles when it is too large
    vertices, faces = np.asarray(mesh_.points, dtype=np.float64), np.asarray(mesh_.triangles, dtype=np.int64)
    if len(faces) > MAX_FACES:
        vertices = np.asarray(surface.vertices, dtype=np.float64).reshape(-1, 3)
        faces = np.asarray(surface.triangles(), dtype=np.int64).reshape(-1, 3)
    edges = np.asarray(surface.edges, dtype=np.int64).reshape(-1, 2)
    scene = trimesh.Scene()
    if len(faces):
        mesh = trimesh.Trimesh(vertices=vertices, faces=faces, process=False, validate=False)
        if len(faces) > MAX_FACES:
            mesh = _decimate(mesh, MAX_FACES)
        scene.add_geometry(mesh, geom_name="surface")
    if len(edges):      # the scaffold's lines as B-spline curves (genr8_dist.scaffold), sampled
        per_span = max(1, min(8, MAX_EDGES // len(edges)))
        curves = scaffold_curves(surface, per_span)
        segments = np.concatenate([np.stack([c[:-1], c[1:]], 1) for c in curves if len(c) > 1])
        if len(segments) > MAX_EDGES:
            segments = segments[:: math.ceil(len(segments) / MAX_EDGES)]
        path = trimesh.load_path(segments)
        scene.add_geometry(path, geom_name="edges")
    return cast(bytes, scene.export(file_type="glb"))


def _decimate(mesh: Any, faces: int) -> Any:
    """Vertex clustering: snap vertices to a grid coarse enough to leave about ``faces`` triangles."""
    import numpy as np
    import trimesh

    extent = float(np.max(mesh.extents)) or 1.0
    cells = max(8, int(math.sqrt(faces / 2)))
    out = mesh
    for _ in range(6):
        size = extent / cells
        snapped = np.round(mesh.vertices / size) * size
        keys, inverse = np.unique(snapped, axis=0, return_inverse=True)
        f = inverse.reshape(-1)[mesh.faces]
        f = f[(f[:, 0] != f[:, 1]) & (f[:, 1] != f[:, 2]) & (f[:, 0] != f[:, 2])]
        f = np.unique(np.sort(f, axis=1), axis=0) if len(f) else f
        out = trimesh.Trimesh(vertices=keys, faces=f, process=False, validate=False)
        if len(f) <= faces:
            return out
        cells = int(cells * 0.7)
    return out


def downloads() -> list[dict[str, str]]:
    """The formats a design downloads in (``genr8_dist.export.SURFACE_FORMATS``'s ``download`` ones):
    each one's ``format`` (the suffix) and ``label`` (the link's text)."""
    from genr8_dist.export import SURFACE_FORMATS

    return [{"format": f.suffix, "label": f.label} for f in SURFACE_FORMATS.values() if f.download]


def _request_label(request: dict[str, Any]) -> str:
    kind = request.get("kind")
    if kind != "edit":
        return str(kind)
    edit = request.get("edit") or {}
    parts = [str(a) for a in edit.get("assignments") or ()]
    parts += [f"favour {i}" for i in edit.get("favour") or ()]
    parts += [f"hand fitness {i} = {f:.4g}" for i, f in edit.get("hand_fitness") or ()]
    parts += [f"inject {label}" for label, _ in edit.get("inject_systems") or ()]
    if edit.get("generations"):
        parts.append(f"{edit['generations']} more generations")
    return ", ".join(parts) or "edit"


def _builtin_universe(name: str) -> bool:
    """Whether ``name`` is a universe shipped with genr8_dist (loading it runs no plugin code)."""
    from genr8_dist.resources import grammars_dir

    return name.isidentifier() and (grammars_dir() / f"{name}.lark").is_file()
