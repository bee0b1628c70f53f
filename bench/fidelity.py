"""Fidelity figures (issue 14): what the thesis's figures show, measured on the code as it is.

    python bench/fidelity.py              # all four figures
    python bench/fidelity.py --only drape # penetrations and regions kept
    python bench/fidelity.py --genomes 100
    python bench/fidelity.py --pictures docs   # docs/boundary_behaviours.png

1. penetrations: four_sided_tiles draped over the sphere of examples/environments/drape_sphere.toml
   (gravity, slide): vertices on the wrong side of the sphere after each derivation step (deeper
   than 1e-9, the hair boundaries leave on the allowed side) and the deepest one;
2. regions kept: the same drape at 5 steps for BranchAngle 15, 30 (the default) and 45; a square
   split into four every step has 4**5 = 1,024 regions when every join is made;
3. symmetric share: random genomes (seed 0, 50-150 codons) of the symmetric universes grown 4 steps
   in the empty environment; the share of grown (uncapped) surfaces with a mirror line
   (``Surface.mirror_line``: a vertical plane through the centre mapping every vertex onto one), with
   ties between joins settled whatever the drawing order (``branch_ties = "crossing"``, the default)
   and, for ``symmetric``, with the rule before (``"first"``: the tie to the branch drawn first) and
   with ``"none"``; ``regions`` is the mean number of regions of the grown surfaces.

4. ties across universes (``--only ties``): 100 random genomes of every built-in surface universe
   grown 4 steps in the empty environment with the default ``branch_ties = "crossing"`` and with
   ``"first"`` (the rule before): how many grown surfaces differ, and their mean regions.

``--pictures DIR`` draws four_sided_tiles in examples/environments/box_corner*.toml (slide, cut-off,
reflect: thesis Figs 2-13 and 2-14) side by side into DIR/boundary_behaviours.png.
"""

from __future__ import annotations

import argparse
import dataclasses
import time
from pathlib import Path

import numpy as np

from genr8_dist.environment import Environment, load_environment
from genr8_dist.grammar import list_universes, load_universe
from genr8_dist.hemls import grow, load_system, parse
from genr8_dist.rng import stream

ROOT = Path(__file__).resolve().parent.parent
DRAPE = ROOT / "examples" / "environments" / "drape_sphere.toml"


def penetrations() -> None:
    env = load_environment(DRAPE)
    system = load_system("four_sided_tiles")
    result = grow(system, env, keep_steps=True)
    print(f"penetrations: four_sided_tiles in {DRAPE.relative_to(ROOT)} ({env.steps} steps)")
    print(f"{'step':>4} {'V':>7} {'inside':>7} {'deepest':>9}")
    for step, surface in enumerate(result.history):
        depth = np.zeros(surface.n_vertices)
        for b in env.boundaries:
            if b.behaviour != "soft":
                depth = np.maximum(depth, b.violation(surface.vertices))
        bad = depth > 1e-9
        print(f"{step:>4} {surface.n_vertices:>7} {int(bad.sum()):>7} {float(depth.max(initial=0)):>9.4f}")


def regions_kept() -> None:
    env = dataclasses.replace(load_environment(DRAPE), steps=5)
    text = load_system("four_sided_tiles").to_text()
    print("\nregions kept: four_sided_tiles in the drape at 5 steps (1,024 when every join is made)")
    for angle in (15, 30, 45):
        system = parse(text + f"BranchAngle {angle}\n")
        surface = grow(system, env).surface
        print(f"  BranchAngle {angle:>2}: {surface.n_regions:>5} regions")


def symmetric_share(n_genomes: int) -> None:
    names = [u.name for u in list_universes() if u.name.startswith("symmetric")]
    print(f"\nsymmetric share: {n_genomes} random genomes per universe, grown 4 steps, empty environment")
    print(f"{'universe':>20} {'ties':>5} {'mapped':>6} {'grown':>6} {'capped':>6} {'mirror':>6} {'share':>7} "
          f"{'regions':>7} {'s':>6}")
    for name, ties in [(n, "crossing") for n in names] + [("symmetric", t) for t in ("first", "none")]:
        env = Environment(max_edges=20_000, max_work=15_000, max_seconds=10.0, branch_ties=ties)
        universe = load_universe(name)
        rng = stream(0, "bench", "fidelity", name)
        mapped = grown = capped = mirror = regions = 0
        t0 = time.perf_counter()
        for _ in range(n_genomes):
            result = universe.map(rng.integers(0, 2**16, size=int(rng.integers(50, 150))))
            if not result.valid:
                continue
            mapped += 1
            growth = grow(parse(result.text), env)
            if growth.capped:
                capped += 1
                continue
            grown += 1
            mirror += growth.surface.mirror_line() is not None
            regions += growth.surface.n_regions
        share = mirror / grown if grown else float("nan")
        print(f"{name:>20} {ties:>5} {mapped:>6} {grown:>6} {capped:>6} {mirror:>6} {share:>7.1%} "
              f"{regions / max(grown, 1):>7.1f} {time.perf_counter() - t0:>6.1f}")


def ties_effect(n_genomes: int = 100) -> None:
    from genr8_dist.phenotype import SURFACES, phenotype_of

    print(f"\nties across universes: {n_genomes} random genomes each, grown 4 steps, empty environment")
    print(f"{'universe':>18} {'grown':>6} {'differ':>6} {'regions first':>14} {'regions crossing':>17}")
    for info in list_universes():
        universe = load_universe(info.name)
        if phenotype_of(universe) is not SURFACES:
            continue
        rng = stream(0, "bench", "ties", info.name)
        grown = differ = first_regions = crossing_regions = 0
        for _ in range(n_genomes):
            result = universe.map(rng.integers(0, 2**16, size=int(rng.integers(50, 150))))
            if not result.valid:
                continue
            system = parse(result.text)
            first, crossing = (grow(system, Environment(max_edges=20_000, max_seconds=10.0, branch_ties=ties))
                               for ties in ("first", "crossing"))
            if first.capped or crossing.capped:
                continue
            grown += 1
            differ += (first.surface.vertices.tobytes() != crossing.surface.vertices.tobytes()
                       or first.surface.edges.tobytes() != crossing.surface.edges.tobytes())
            first_regions += first.surface.n_regions
            crossing_regions += crossing.surface.n_regions
        print(f"{info.name:>18} {grown:>6} {differ:>6} {first_regions / max(grown, 1):>14.1f} "
              f"{crossing_regions / max(grown, 1):>17.1f}")


BOXES = (("slide", "box_corner.toml"), ("cut-off", "box_corner_cutoff.toml"),
         ("reflect", "box_corner_reflect.toml"))


def pictures(folder: Path) -> Path:
    import tempfile

    import matplotlib.image as mpimg

    from genr8_dist.export import _pyplot, render_png, save_png

    plt = _pyplot()
    system = load_system("four_sided_tiles")
    fig, axes = plt.subplots(1, len(BOXES), figsize=(15, 4.8))
    with tempfile.TemporaryDirectory() as tmp:
        for ax, (behaviour, name) in zip(axes, BOXES, strict=True):
            env = load_environment(ROOT / "examples" / "environments" / name)
            surface = grow(system, env).surface
            one = render_png(surface, Path(tmp) / f"{behaviour}.png", env=env, size=(5.5, 5.0), dpi=90,
                             title=f"{behaviour} ({name})")
            ax.imshow(mpimg.imread(one))
            ax.axis("off")
            print(f"{behaviour:>8}: {surface!r}, {int(surface.stopped.sum())} stopped, "
                  f"highest z {surface.vertices[:, 2].max():.2f}")
    fig.tight_layout()
    return save_png(fig, folder / "boundary_behaviours.png", dpi=90)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--only", choices=("drape", "symmetric", "ties"), help="one part only")
    parser.add_argument("--genomes", type=int, default=500, help="random genomes per symmetric universe")
    parser.add_argument("--pictures", type=Path, metavar="DIR", help="only draw the boundary behaviours")
    args = parser.parse_args()
    if args.pictures:
        print(f"wrote {pictures(args.pictures)}")
        return
    if args.only in (None, "drape"):
        penetrations()
        regions_kept()
    if args.only in (None, "symmetric"):
        symmetric_share(args.genomes)
    if args.only in (None, "ties"):
        ties_effect()


if __name__ == "__main__":
    main()
