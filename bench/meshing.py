"""Meshing 1 against meshing 2 (issue 25): thin exported triangles, slivers, and meshing's CPU cost.

    python bench/meshing.py --genomes 300                      # random genomes of each built-in universe
    python bench/meshing.py --genomes 0 --run /tmp/mesh/quick  # a run's best 12 distinct surfaces

Printed per universe (random genomes, each grown in the empty environment, those with at least one
region): surfaces, triangles under each meshing, the share of triangles whose smallest angle is below
15 degrees (all, and inside regions whose own corners are all at least 20 degrees in their plane),
the regions meshing 2 cut as meshing 1 does (not simple in their plane), and the CPU seconds per
surface (``time.process_time``) of each meshing. With ``--run``: the same for the run's best 12
distinct surfaces (regrown with meshing 1 and 2), and each one's ``slivers`` under both.
"""

from __future__ import annotations

import argparse
import time
from typing import Any

import numpy as np

from genr8_dist.environment import Environment
from genr8_dist.fitness import slivers, triangle_min_angles
from genr8_dist.hemls import Surface, grow, parse
from genr8_dist.hemls.meshing import _frame, _region_geometry

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


def measure(surfaces: list[Any]) -> dict[str, float]:
    out: dict[str, float] = {"surfaces": len(surfaces)}
    for meshing in (1, 2):
        tri = thin = good = good_thin = fallback = 0
        cpu = 0.0
        for s in surfaces:
            f = fresh(s, meshing)
            t0 = time.process_time()
            mesh = f.mesh()
            cpu += time.process_time() - t0
            angles = triangle_min_angles(mesh.points, mesh.triangles)
            inside = corner_ok(s)[mesh.regions]
            tri += len(angles)
            thin += int(np.sum(angles < 15.0))
            good += int(np.sum(inside))
            good_thin += int(np.sum(inside & (angles < 15.0)))
            fallback += len(mesh.fallback) if meshing == 2 else 0
        out[f"tri{meshing}"] = tri
        out[f"thin{meshing}"] = thin / max(tri, 1)
        out[f"goodthin{meshing}"] = good_thin / max(good, 1)
        out[f"cpu{meshing}"] = cpu / max(len(surfaces), 1)
        if meshing == 2:
            out["fallback"] = fallback / max(sum(s.n_regions for s in surfaces), 1)
    return out


def show(name: str, m: dict[str, float]) -> None:
    print(f"| {name} | {m['surfaces']:.0f} | {m['tri1']:.0f} / {m['tri2']:.0f} | {m['thin1']:.1%} -> "
          f"{m['thin2']:.2%} ({m['thin1'] / max(m['thin2'], 1e-12):.1f}x) | {m['goodthin1']:.1%} -> "
          f"{m['goodthin2']:.2%} | {m['fallback']:.1%} | {m['cpu1'] * 1e3:.1f} / {m['cpu2'] * 1e3:.1f} ms |")


HEADER = ("| set | surfaces | triangles m1 / m2 | under 15 deg m1 -> m2 | same, regions with corners "
          ">= 20 deg | regions cut as m1 | CPU per surface m1 / m2 |\n|---|---|---|---|---|---|---|")


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


def run_best(run: str) -> None:
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
    show("best 12", measure(surfaces))
    print("\n| id | slivers meshing 1 (triangles) | slivers meshing 2 (thin regions) |\n|---|---|---|")
    for i, s in zip(best, surfaces, strict=True):
        print(f"| {i} | {slivers(fresh(s, 1)):.3f} | {slivers(fresh(s, 2)):.3f} |")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--genomes", type=int, default=300)
    parser.add_argument("--universes", default=",".join(UNIVERSES))
    parser.add_argument("--run")
    args = parser.parse_args()
    if args.genomes:
        print(f"{args.genomes} random genomes per universe, empty environment\n" + HEADER)
        for name in args.universes.split(","):
            show(name, measure(random_surfaces(name, args.genomes)))
    if args.run:
        run_best(args.run)


if __name__ == "__main__":
    main()
