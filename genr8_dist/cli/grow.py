"""``genr8 grow``: grow one rewrite system in an environment; print each step; export meshes and pictures.

::

    genr8 grow four-sided-tiles --steps 5 -o tiles.obj --png tiles.png
    genr8 grow my-system.hemls --env examples/environments/drape_sphere.toml -o drape.glb
    genr8 map --universe default --genome 212,187,632,832,800,517,338,39 | genr8 grow - --png mapped.png
    genr8 grow square --each-step -o square.ply        # square-step1.ply ... square-step4.ply
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any

from genr8_dist.errors import ConfigError

if TYPE_CHECKING:
    from genr8_dist.environment import Environment
    from genr8_dist.hemls import Surface

__all__ = ["register", "step_path"]


def register(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add ``genr8 grow``."""
    parser = subparsers.add_parser(
        "grow",
        help="grow a rewrite system into a surface; export it as a mesh, scaffold or picture",
        description="Grow a rewrite system (a file, a predefined name, or - for standard input) in an "
        "environment, print the vertices, edges and regions after every derivation step, and write "
        "the surface as a triangle mesh (OBJ, PLY, STL, GLB), a scaffold of edges, or a PNG preview.",
    )
    parser.add_argument("system", metavar="SYSTEM",
                        help="a rewrite-system file, a predefined system (three-sided-tiles, "
                        "four-sided-tiles, koch, quadratic-koch, square), or - to read standard input")
    parser.add_argument("--env", metavar="ENV.toml", help="the environment (docs/environment.md); "
                        "default: the empty environment with Genr8's defaults")
    parser.add_argument("--steps", type=int, metavar="N",
                        help="derivation steps (overrides the environment's steps)")
    parser.add_argument("--seed", type=int, metavar="S", help="random seed (overrides the environment)")
    parser.add_argument("-o", "--output", metavar="OUT.{obj,ply,stl,glb}",
                        help="write the triangulated surface to this mesh file")
    parser.add_argument("--scaffold", metavar="OUT.{obj,ply,dxf}", help="write the edges as polylines")
    parser.add_argument("--png", metavar="OUT.png", help="write a shaded picture of the surface")
    parser.add_argument("--each-step", action="store_true",
                        help="write one file per derivation step (OUT-step1.obj, OUT-step2.obj, ...)")
    parser.add_argument("--title", help="title of the PNG (default: the system's name and step count)")
    parser.add_argument("--smooth", type=int, default=0, metavar="N",
                        help="Loop subdivision steps applied to the -o mesh (0-4; each x4 the triangles)")
    parser.add_argument("--meshing", type=int, default=None, metavar="V",
                        help="meshing version (docs/run-config.md; default the current, 3; 1: the old "
                        "cut of each region into m - 2 triangles)")
    parser.set_defaults(handler=_handle)


def step_path(path: Path, step: int) -> Path:
    """``out.obj`` -> ``out-step3.obj``: the file for one derivation step under ``--each-step``."""
    return path.with_name(f"{path.stem}-step{step}{path.suffix}")


def _check_outputs(args: argparse.Namespace) -> None:
    """Refuse bad file names before any growth: unknown suffixes, missing folders, no matplotlib."""
    from genr8_dist.export import MESH_FORMATS, SCAFFOLD_FORMATS

    for value, allowed, what in ((args.output, MESH_FORMATS, "mesh"),
                                 (args.scaffold, SCAFFOLD_FORMATS, "scaffold"),
                                 (args.png, ("png",), "picture")):
        if value is None:
            continue
        path = Path(value)
        if path.suffix.lower().lstrip(".") not in allowed:
            names = ", ".join(f".{s}" for s in allowed)
            given = path.suffix or "(no suffix)"
            raise ConfigError(f"{value}: unknown {what} format '{given}'; use {names}")
        folder = path.parent if str(path.parent) else Path(".")
        if not folder.is_dir():
            raise ConfigError(f"{value}: folder '{folder}' does not exist")
    if args.png:
        try:
            import matplotlib  # noqa: F401
        except ImportError:
            raise ConfigError("--png needs matplotlib: pip install 'genr8-dist[viz]'") from None


def _environment(args: argparse.Namespace) -> Environment:
    from genr8_dist.environment import Environment, load_environment

    env = load_environment(args.env) if args.env else Environment(source="<default environment>")
    changes: dict[str, Any] = {}
    if args.steps is not None:
        changes["steps"] = args.steps
    if args.seed is not None:
        changes["seed"] = args.seed
    if changes:
        source = f"{env.source} (with --steps/--seed)" if args.env else "command line"
        try:
            env = dataclasses.replace(env, **changes, source=source)
        except ConfigError as exc:
            message = str(exc).replace("field 'steps'", "--steps").replace("field 'seed'", "--seed")
            raise ConfigError(message) from None
    return env


def _write(surface: Surface, args: argparse.Namespace, env: Environment, title: str, step: int | None
           ) -> list[str]:
    from genr8_dist.export import export_mesh, export_scaffold, render_png

    written = []
    for value, writer in ((args.output, "mesh"), (args.scaffold, "scaffold"), (args.png, "png")):
        if value is None:
            continue
        path = Path(value) if step is None else step_path(Path(value), step)
        if writer == "mesh":
            export_mesh(surface, path, smooth=args.smooth)
        elif writer == "scaffold":
            export_scaffold(surface, path)
        else:
            render_png(surface, path, title=title, env=env)
        written.append(str(path))
    return written


def _cap_message(capped: str, env: Environment) -> str:
    if capped == "edges":
        return f"the edge cap (max_edges = {env.max_edges}) would be exceeded"
    if capped == "work":
        return (f"the work cap (max_work = {env.max_work} edge-steps) was reached; raise max_work in the "
                "environment (0: no cap) to grow further")
    if capped == "time":
        return f"the time cap (max_seconds = {env.max_seconds:g}) was reached"
    return f"the {capped} cap was reached"


def _handle(args: argparse.Namespace) -> int:
    from genr8_dist.export import check_smooth
    from genr8_dist.hemls import grow, load_system
    from genr8_dist.hemls.meshing import check_meshing

    check_smooth(args.smooth)
    if args.meshing is not None:
        check_meshing(args.meshing, "--meshing")
    _check_outputs(args)
    env = _environment(args)
    system = load_system(args.system)
    for warning in system.warnings():
        print(f"genr8: warning: {system.name or args.system}: {warning}", file=sys.stderr)
    name = "rewrite system from stdin" if args.system == "-" else (
        getattr(system, "name", "") or Path(args.system).stem).replace("_", " ")
    writes = args.each_step and any((args.output, args.scaffold, args.png))

    result = grow(system, env, keep_steps=writes)
    if args.meshing is not None:
        result = dataclasses.replace(result, surface=result.surface.with_meshing(args.meshing),
                                     history=[s.with_meshing(args.meshing) for s in result.history])
    out = sys.stdout
    print(f"{name}: {env.steps} derivation step{'s' if env.steps != 1 else ''}, seed {env.seed}", file=out)
    print(f"{'step':>4}  {'vertices':>9}  {'edges':>9}  {'regions':>9}  {'seconds':>8}", file=out)
    for stats in result.steps:
        print(f"{stats.step:>4}  {stats.n_vertices:>9}  {stats.n_edges:>9}  {stats.n_regions:>9}  "
              f"{stats.seconds:>8.3f}", file=out)
    done = len(result.steps)
    if result.capped:
        print(f"growth stopped at step {done} of {env.steps}: {_cap_message(result.capped, env)}", file=out)
    if writes:
        for step, surface in enumerate(result.history[1:], start=1):
            for path in _write(surface, args, env, f"{args.title or name}, step {step}", step):
                print(f"wrote {path}", file=out)
    else:
        title = args.title or f"{name}, {done} step{'s' if done != 1 else ''}"
        for path in _write(result.surface, args, env, title, None):
            print(f"wrote {path}", file=out)
    return 0
