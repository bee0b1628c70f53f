"""Every meshing (issue 25): thin exported triangles, slivers, and meshing's CPU cost.

    python bench/meshing.py --genomes 300                      # random genomes of each built-in universe
    python bench/meshing.py --genomes 0 --run /tmp/mesh/quick  # a run's best 12 distinct surfaces
    python bench/meshing.py --meshings 1,4                     # only meshings 1 and 4

Printed per universe (N random genomes, each grown in the empty environment, those with at least one
region) and meshing: surfaces, triangles, the share of triangles whose smallest angle is below 15
degrees (all; inside regions whose own corners are all at least 20 degrees in their plane; inside
those of them that do not fold over themselves, i.e. no meshing-1 triangle faces against the
region's normal; inside those of them whose outline does not cross itself in their plane, as
meshing's ``_simple`` tells: a figure-eight outline has a crossing, a corner its vertices do not
show; inside those of them whose corners are all at least 20 degrees in space too, with the count),
the regions cut as meshing 1 cuts them, and the CPU seconds per surface
(``time.process_time``). With ``--run``: the same for the run's best 12 distinct surfaces, and each
one's ``slivers`` under each meshing. ``--json FILE`` also writes the figures as JSON.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path
from typing import Any, cast

import numpy as np

from genr8_dist.environment import Environment
from genr8_dist.fitness import slivers, triangle_min_angles
from genr8_dist.hemls import Surface, grow, parse
from genr8_dist.hemls.meshing import MESHINGS, _frame, _region_geometry, _simple

#: The meshings measured (``--meshings``; meshing 1 always, the others' ratios are to it).
CHOSEN: tuple[int, ...] = MESHINGS

UNIVERSES = ("default", "gecco", "probabilistic", "reversible", "symmetric", "symmetric_thesis", "tiles")


def fresh(s: Any, meshing: int) -> Surface:
    """``s`` with nothing cached, cut by ``meshing``."""
    return Surface(s.vertices, s.edges, s.labels, s.ages, s.region_offsets, s.region_vertices, s.perimeter(),
                   s.masses, s.stopped, meshing=meshing)


def region_shapes(s: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(F,) masks from one projection of each region into its plane: whether every corner is at
    least 20 degrees there; whether, among those, the outline does not cross itself; and whether,
    among those, every corner is at least 20 degrees in space too (the angle between its two sides,
    taken beyond 180 where the corner is reflex in the plane: a bent region's corner can be wider in
    its plane than in space, and a triangle's angles are measured in space)."""
    centroid, newell, _, _, _ = _region_geometry(s.vertices, s.region_offsets, s.region_vertices)
    ok = np.zeros(s.n_regions, dtype=bool)
    simple = np.zeros(s.n_regions, dtype=bool)
    sound = np.zeros(s.n_regions, dtype=bool)
    for r, cyc in enumerate(s.regions):
        frame = _frame(newell[r])
        if frame is None:
            continue
        xy = (s.vertices[cyc] - centroid[r]) @ frame.T
        a, b = xy - np.roll(xy, 1, 0), np.roll(xy, -1, 0) - xy
        turn = np.degrees(np.arctan2(a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0], np.einsum("ij,ij->i", a, b)))
        ok[r] = np.all(180.0 - turn >= 20.0)
        simple[r] = ok[r] and _simple(xy / max(float(np.abs(xy).max()), 1e-300))
        p = s.vertices[cyc]
        u, w = np.roll(p, 1, 0) - p, np.roll(p, -1, 0) - p
        norms = np.linalg.norm(u, axis=1) * np.linalg.norm(w, axis=1)
        space = np.degrees(np.arccos(np.clip(np.einsum("ij,ij->i", u, w) / np.where(norms > 0, norms, 1.0),
                                             -1.0, 1.0)))
        space = np.where(turn < 0, 360.0 - space, space)
        sound[r] = simple[r] and bool(np.all(space >= 20.0))
    return ok, simple, sound


def folded(s: Any) -> np.ndarray:
    """(F,) whether some meshing-1 triangle of each region faces against the region's normal (the
    region folds over itself in space)."""
    _, newell, _, _, _ = _region_geometry(s.vertices, s.region_offsets, s.region_vertices)
    tri = s.triangles()
    owners = np.repeat(np.arange(s.n_regions), np.maximum(s.region_sizes - 2, 0))
    p = s.vertices[tri]
    normal = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    out = np.zeros(s.n_regions, dtype=bool)
    np.logical_or.at(out, owners, np.einsum("ij,ij->i", normal, newell[owners]) < 0)
    return out


def one_surface(s: Any) -> dict[str, float]:
    """One surface's counts under every meshing (summed by ``measure``)."""
    ok, simple_ok, sound_ok = region_shapes(s)
    flat_ok = ok & ~folded(s)
    out: dict[str, float] = {"good_regions": int(ok.sum()), "flat_good_regions": int(flat_ok.sum()),
                             "simple_good_regions": int(simple_ok.sum()),
                             "sound_good_regions": int(sound_ok.sum())}
    for meshing in CHOSEN:
        f = fresh(s, meshing)
        t0 = time.process_time()
        mesh = f.mesh()
        out[f"cpu{meshing}"] = time.process_time() - t0
        thin_ = triangle_min_angles(mesh.points, mesh.triangles) < 15.0
        out[f"tri{meshing}"] = len(thin_)
        out[f"thin{meshing}"] = int(np.sum(thin_))
        out[f"good{meshing}"] = int(np.sum(ok[mesh.regions]))
        out[f"goodthin{meshing}"] = int(np.sum(ok[mesh.regions] & thin_))
        out[f"flat{meshing}"] = int(np.sum(flat_ok[mesh.regions]))
        out[f"flatthin{meshing}"] = int(np.sum(flat_ok[mesh.regions] & thin_))
        out[f"simple{meshing}"] = int(np.sum(simple_ok[mesh.regions]))
        out[f"simplethin{meshing}"] = int(np.sum(simple_ok[mesh.regions] & thin_))
        out[f"sound{meshing}"] = int(np.sum(sound_ok[mesh.regions]))
        out[f"soundthin{meshing}"] = int(np.sum(sound_ok[mesh.regions] & thin_))
        out[f"fallback{meshing}"] = len(mesh.fallback) if meshing > 1 else 0
    return out


def isolated(s: Any, memory: float) -> dict[str, float] | None:
    """``one_surface(s)`` in a forked child limited to ``memory`` GB of address space (0: no limit),
    None if it failed there: Triangle can take all the machine's memory on one region (a random
    ``probabilistic`` genome reached 24 GB), and does not free what it took when it fails."""
    import os
    import pickle
    import resource

    read, write = os.pipe()
    pid = os.fork()
    if pid == 0:
        os.close(read)
        try:
            if memory > 0:
                limit = int(memory * 2**30)
                resource.setrlimit(resource.RLIMIT_AS, (limit, limit))
            got: dict[str, float] | None = one_surface(s)
        except (MemoryError, RuntimeError):
            got = None
        with os.fdopen(write, "wb") as pipe:
            pickle.dump(got, pipe)
        os._exit(0)
    os.close(write)
    with os.fdopen(read, "rb") as pipe:
        data = pipe.read()
    os.waitpid(pid, 0)
    return cast("dict[str, float] | None", pickle.loads(data)) if data else None


def measure(surfaces: list[Any], memory: float = 0.0) -> dict[str, float]:
    """The figures over ``surfaces`` (each measured in a child limited to ``memory`` GB); surfaces
    whose meshing failed there are counted in ``failed`` and left out of the rest."""
    parts = [isolated(s, memory) for s in surfaces]
    kept = [(s, p) for s, p in zip(surfaces, parts, strict=True) if p is not None]
    total = {k: sum(p[k] for _, p in kept) for k in (kept[0][1] if kept else {})}
    out: dict[str, float] = {"surfaces": len(kept), "failed": len(surfaces) - len(kept),
                             "regions": sum(s.n_regions for s, _ in kept),
                             "good_regions": total.get("good_regions", 0),
                             "flat_good_regions": total.get("flat_good_regions", 0),
                             "simple_good_regions": total.get("simple_good_regions", 0),
                             "sound_good_regions": total.get("sound_good_regions", 0)}
    for m in CHOSEN:
        tri = total.get(f"tri{m}", 0)
        out[f"tri{m}"] = tri
        out[f"thin{m}"] = total.get(f"thin{m}", 0) / max(tri, 1)
        out[f"goodthin{m}"] = total.get(f"goodthin{m}", 0) / max(total.get(f"good{m}", 0), 1)
        out[f"flatthin{m}"] = total.get(f"flatthin{m}", 0) / max(total.get(f"flat{m}", 0), 1)
        out[f"simplethin{m}"] = total.get(f"simplethin{m}", 0) / max(total.get(f"simple{m}", 0), 1)
        out[f"soundthin{m}"] = total.get(f"soundthin{m}", 0) / max(total.get(f"sound{m}", 0), 1)
        out[f"soundthin_count{m}"] = total.get(f"soundthin{m}", 0)
        out[f"cpu{m}"] = total.get(f"cpu{m}", 0.0) / max(len(kept), 1)
        out[f"fallback{m}"] = total.get(f"fallback{m}", 0) / max(out["regions"], 1)
    return out


def show(name: str, m: dict[str, float]) -> None:
    for v in CHOSEN:
        ratio = "" if v == 1 else " (none left)" if not m[f"thin{v}"] else \
            f" ({m['thin1'] / m[f'thin{v}']:.1f}x)"
        print(f"| {name} | {v} | {m['surfaces']:.0f} | {m[f'tri{v}']:.0f} | {m[f'thin{v}']:.2%}{ratio} | "
              f"{m[f'goodthin{v}']:.2%} | {m[f'flatthin{v}']:.2%} | {m[f'simplethin{v}']:.3%} | "
              f"{m[f'soundthin{v}']:.4%} ({m[f'soundthin_count{v}']:.0f}) | "
              f"{m[f'fallback{v}']:.1%} | "
              f"{m[f'cpu{v}'] * 1e3:.1f} ms | {m.get('failed', 0):.0f} |")


HEADER = ("| set | meshing | surfaces | triangles | under 15 deg | same, regions with corners >= 20 deg | "
          "same, of those not folded | same, of those simple in their plane | "
          "same, of those with corners >= 20 deg in space too (count) | regions cut as m1 | "
          "CPU per surface | failed (memory) |\n"
          "|---|---|---|---|---|---|---|---|---|---|---|---|")


def random_surfaces(name: str, n: int) -> list[Any]:
    from genr8_dist.grammar import load_universe
    from genr8_dist.rng import stream

    universe, rng = load_universe(name), stream(0, "bench", "meshing", name)
    out = []
    for _ in range(n):
        result = universe.map(rng.integers(0, 2**16, size=int(rng.integers(50, 150))))
        if not result.valid or result.text is None:
            continue
        g = grow(parse(result.text), Environment())
        if not g.capped and g.surface.n_regions:
            out.append(g.surface)
    return out


def run_best(run: str, memory: float = 0.0) -> dict[str, Any]:
    from genr8_dist.history import _regrow
    from genr8_dist.store import RunStore

    store = RunStore.open(run)
    rows = store.dataset().to_table(columns=["id", "fitness", "phenotype_digest", "valid"]).to_pylist()
    rows = sorted((r for r in rows if r["valid"] and r["fitness"] is not None), key=lambda r: r["fitness"])
    best, seen = [], set()
    for r in rows:
        if r["phenotype_digest"] in seen:
            continue
        seen.add(r["phenotype_digest"])
        best.append(r["id"])
        if len(best) == 12:
            break
    regrown = [_regrow.regrow(run, i).developed for i in best]
    surfaces = [d.value for d in regrown if d is not None]
    print(f"\nrun {run} (meshing {store.meshing}): best 12 distinct\n" + HEADER)
    figures: dict[str, Any] = dict(measure(surfaces, memory))
    show("best 12", figures)
    print("\n| id | " + " | ".join(f"slivers meshing {v}" for v in CHOSEN) + " |\n|---|"
          + "---|" * len(CHOSEN))
    figures["slivers"] = {}
    for i, s in zip(best, surfaces, strict=True):
        values = [slivers(fresh(s, v)) for v in CHOSEN]
        figures["slivers"][i] = values
        print(f"| {i} | " + " | ".join(f"{x:.3f}" for x in values) + " |")
    return figures


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--genomes", type=int, default=300, metavar="N",
                        help="random genomes per universe (0: none)")
    parser.add_argument("--universes", default=",".join(UNIVERSES))
    parser.add_argument("--run", help="a run directory: measure its best 12 distinct surfaces")
    parser.add_argument("--json", metavar="FILE", help="also write the figures to FILE as JSON")
    parser.add_argument("--memory", type=float, default=4.0, metavar="GB",
                        help="address space each surface's meshing may use (0: no limit)")
    parser.add_argument("--meshings", default=",".join(map(str, MESHINGS)),
                        help="the meshings to measure, comma-separated (1 is always measured)")
    args = parser.parse_args()
    global CHOSEN
    CHOSEN = tuple(sorted({1, *(int(m) for m in args.meshings.split(","))}))
    figures: dict[str, Any] = {"genomes": args.genomes, "universes": {}}
    if args.genomes:
        print(f"{args.genomes} random genomes per universe, empty environment\n" + HEADER)
        for name in args.universes.split(","):
            figures["universes"][name] = measure(random_surfaces(name, args.genomes), args.memory)
            show(name, figures["universes"][name])
            if args.json:
                Path(args.json).write_text(json.dumps(figures, indent=1))
    if args.run:
        figures["run"] = {"path": args.run, **run_best(args.run, args.memory)}
    if args.json:
        Path(args.json).write_text(json.dumps(figures, indent=1))


if __name__ == "__main__":
    main()
