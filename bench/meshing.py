"""Meshings 1, 2 and 3 (issue 25): thin exported triangles, slivers, and meshing's CPU cost.

    python bench/meshing.py --genomes 300                      # random genomes of each built-in universe
    python bench/meshing.py --genomes 0 --run /tmp/mesh/quick  # a run's best 12 distinct surfaces

Printed per universe (N random genomes, each grown in the empty environment, those with at least one
region) and meshing: surfaces, triangles, the share of triangles whose smallest angle is below 15
degrees (all; inside regions whose own corners are all at least 20 degrees in their plane; inside
those of them that do not fold over themselves, i.e. no meshing-1 triangle faces against the
region's normal), the regions cut as meshing 1 cuts them, and the CPU seconds per surface
(``time.process_time``). With ``--run``: the same for the run's best 12 distinct surfaces, and each
one's ``slivers`` under each meshing. ``--json FILE`` also writes the figures as JSON.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path
from typing import Any

import numpy as np

from genr8_dist.environment import Environment
from genr8_dist.fitness import slivers, triangle_min_angles
from genr8_dist.hemls import Surface, grow, parse
from genr8_dist.hemls.meshing import MESHINGS, _frame, _region_geometry

UNIVERSES = ("default", "gecco", "probabilistic", "reversible", "symmetric", "symmetric_thesis", "tiles")


def fresh(s: Any, meshing: int) -> Surface:
    """``s`` with nothing cached, cut by ``meshing``."""
    return Surface(s.vertices, s.edges, s.labels, s.ages, s.region_offsets, s.region_vertices, s.perimeter(),
                   s.masses, s.stopped, meshing=meshing)


def corner_ok(s: Any) -> np.ndarray:
    """(F,) whether every corner of each region is at least 20 degrees in the region's plane."""
    centroid, newell, _, _, _ = _region_geometry(s.vertices, s.region_offsets, s.region_vertices)
    ok = np.zeros(s.n_regions, dtype=bool)
    for r, cyc in enumerate(s.regions):
        frame = _frame(newell[r])
        if frame is None:
            continue
        xy = (s.vertices[cyc] - centroid[r]) @ frame.T
        a, b = xy - np.roll(xy, 1, 0), np.roll(xy, -1, 0) - xy
        turn = np.degrees(np.arctan2(a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0], np.einsum("ij,ij->i", a, b)))
        ok[r] = np.all(180.0 - turn >= 20.0)
    return ok


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


def measure(surfaces: list[Any]) -> dict[str, float]:
    out: dict[str, float] = {"surfaces": len(surfaces), "regions": sum(s.n_regions for s in surfaces)}
    classes = [(corner_ok(s), corner_ok(s) & ~folded(s)) for s in surfaces]
    out["good_regions"] = sum(int(g.sum()) for g, _ in classes)
    out["flat_good_regions"] = sum(int(f.sum()) for _, f in classes)
    for meshing in MESHINGS:
        tri = thin = good = good_thin = flat = flat_thin = fallback = 0
        cpu = 0.0
        for s, (ok, flat_ok) in zip(surfaces, classes, strict=True):
            f = fresh(s, meshing)
            t0 = time.process_time()
            mesh = f.mesh()
            cpu += time.process_time() - t0
            angles = triangle_min_angles(mesh.points, mesh.triangles)
            thin_ = angles < 15.0
            tri += len(angles)
            thin += int(np.sum(thin_))
            good += int(np.sum(ok[mesh.regions]))
            good_thin += int(np.sum(ok[mesh.regions] & thin_))
            flat += int(np.sum(flat_ok[mesh.regions]))
            flat_thin += int(np.sum(flat_ok[mesh.regions] & thin_))
            fallback += len(mesh.fallback) if meshing > 1 else 0
        out[f"tri{meshing}"] = tri
        out[f"thin{meshing}"] = thin / max(tri, 1)
        out[f"goodthin{meshing}"] = good_thin / max(good, 1)
        out[f"flatthin{meshing}"] = flat_thin / max(flat, 1)
        out[f"cpu{meshing}"] = cpu / max(len(surfaces), 1)
        out[f"fallback{meshing}"] = fallback / max(out["regions"], 1)
    return out


def show(name: str, m: dict[str, float]) -> None:
    for v in MESHINGS:
        ratio = "" if v == 1 else f" ({m['thin1'] / max(m[f'thin{v}'], 1e-12):.1f}x)"
        print(f"| {name} | {v} | {m['surfaces']:.0f} | {m[f'tri{v}']:.0f} | {m[f'thin{v}']:.2%}{ratio} | "
              f"{m[f'goodthin{v}']:.2%} | {m[f'flatthin{v}']:.2%} | {m[f'fallback{v}']:.1%} | "
              f"{m[f'cpu{v}'] * 1e3:.1f} ms |")


HEADER = ("| set | meshing | surfaces | triangles | under 15 deg | same, regions with corners >= 20 deg | "
          "same, of those not folded | regions cut as m1 | CPU per surface |\n"
          "|---|---|---|---|---|---|---|---|---|")


def random_surfaces(name: str, n: int) -> list[Any]:
    from genr8_dist.grammar import load_universe
    from genr8_dist.rng import stream

    universe, rng = load_universe(name), stream(0, "bench", "meshing", name)
    out = []
    for _ in range(n):
        result = universe.map(rng.integers(0, 2**16, size=int(rng.integers(50, 150))))
        if not result.valid:
            continue
        g = grow(parse(result.text), Environment())
        if not g.capped and g.surface.n_regions:
            out.append(g.surface)
    return out


def run_best(run: str) -> dict[str, Any]:
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
    surfaces = [_regrow.regrow(run, i).developed.value for i in best]
    print(f"\nrun {run} (meshing {store.meshing}): best 12 distinct\n" + HEADER)
    figures = measure(surfaces)
    show("best 12", figures)
    print("\n| id | " + " | ".join(f"slivers meshing {v}" for v in MESHINGS) + " |\n|---|"
          + "---|" * len(MESHINGS))
    figures["slivers"] = {}
    for i, s in zip(best, surfaces, strict=True):
        values = [slivers(fresh(s, v)) for v in MESHINGS]
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
    args = parser.parse_args()
    figures: dict[str, Any] = {"genomes": args.genomes, "universes": {}}
    if args.genomes:
        print(f"{args.genomes} random genomes per universe, empty environment\n" + HEADER)
        for name in args.universes.split(","):
            figures["universes"][name] = measure(random_surfaces(name, args.genomes))
            show(name, figures["universes"][name])
            if args.json:
                Path(args.json).write_text(json.dumps(figures, indent=1))
    if args.run:
        figures["run"] = {"path": args.run, **run_best(args.run)}
    if args.json:
        Path(args.json).write_text(json.dumps(figures, indent=1))


if __name__ == "__main__":
    main()
