"""Surfaces out of genr8_dist: triangle meshes and scaffolds through trimesh, and PNG previews.

All three work on any value with the ``Surface`` contract (docs/ARCHITECTURE.md): ``vertices``
(V, 3) float64, ``edges`` (E, 2) int64, ``labels`` (E,), ``regions`` (vertex cycles) and
``triangles()`` (T, 3). Files are written atomically: to a temporary file beside the target, then
renamed, so a crash or a bad argument never leaves half a file.

- ``export_mesh``: the regions, triangulated, as OBJ, PLY, STL or GLB (chosen by the suffix). Every
  vertex is written, in the surface's order, so vertex i of the file is vertex i of the map.
- ``export_scaffold``: the map's edges as polylines (Genr8's "scaffold"): OBJ ``l`` lines (grouped
  by edge label), PLY with an ``edge`` element, or DXF LINE entities (one layer per edge label).
- ``render_png``: a shaded picture of the surface with its edges, axes and a title, drawn headless
  with matplotlib (the ``viz`` extra); with ``env`` it also shows the environment's boundaries,
  attractors, repellers and gravity.
"""

from __future__ import annotations

import contextlib
import tempfile
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np

from genr8_dist.errors import ConfigError, Genr8Error
from genr8_dist.files import is_stream, replacing

if TYPE_CHECKING:
    from genr8_dist.environment import Environment

__all__ = [
    "MESH_FORMATS",
    "SCAFFOLD_FORMATS",
    "SURFACE_FORMATS",
    "SurfaceFormat",
    "SurfaceLike",
    "draw_surface",
    "export_3dm",
    "export_mesh",
    "export_scaffold",
    "export_surface",
    "mesh_of",
    "pyplot",
    "render_png",
    "save_png",
    "surface_bytes",
    "write_mesh",
]



class SurfaceLike(Protocol):
    """What export needs of a surface (genr8_dist.hemls.Surface has it)."""

    vertices: np.ndarray
    edges: np.ndarray
    labels: np.ndarray

    def triangles(self) -> np.ndarray: ...


def _suffix(path: Path, allowed: tuple[str, ...], what: str) -> str:
    suffix = path.suffix.lower().lstrip(".")
    if suffix not in allowed:
        names = ", ".join(f".{s}" for s in allowed)
        given = path.suffix or "(no suffix)"
        raise ConfigError(f"{path}: unknown {what} format '{given}'; use one of {names}")
    return suffix


@contextlib.contextmanager
def _atomic(path: Path) -> Iterator[Path]:
    """Yield a temporary path beside ``path``; rename it over ``path`` only when the block succeeds."""
    path = Path(path)
    folder = path.parent if str(path.parent) else Path(".")
    if not folder.is_dir():
        raise ConfigError(f"{path}: folder '{folder}' does not exist")
    with replacing(path) as tmp:
        yield tmp


def _write_bytes(path: Path, data: bytes | str) -> None:
    with _atomic(path) as tmp:
        tmp.write_bytes(data.encode() if isinstance(data, str) else data)


def _arrays(surface: SurfaceLike, smooth: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(points, edges, faces): the surface's mesh by its meshing (``Surface.mesh``: its vertices first,
    then the points meshing added), after ``smooth`` Loop subdivision steps (each cuts every triangle
    into four and moves the points towards the smooth limit surface)."""
    vertices = np.asarray(surface.vertices, dtype=np.float64).reshape(-1, 3)
    edges = np.asarray(surface.edges, dtype=np.int64).reshape(-1, 2)
    meshed = getattr(surface, "mesh", None)
    if callable(meshed):
        mesh = meshed()
        points, faces = np.asarray(mesh.points, dtype=np.float64), np.asarray(mesh.triangles, dtype=np.int64)
    else:
        points, faces = vertices, np.asarray(surface.triangles(), dtype=np.int64).reshape(-1, 3)
    if smooth and len(faces):
        from trimesh.remesh import subdivide_loop

        points, faces = subdivide_loop(points, faces, iterations=int(smooth))
    return points, edges, faces


def check_smooth(smooth: Any) -> int:
    """``--smooth N`` checked: subdivision steps, 0 to 4 (each multiplies the triangles by four)."""
    if isinstance(smooth, bool) or not isinstance(smooth, int) or not 0 <= smooth <= 4:
        raise ConfigError(f"--smooth {smooth!r}: use 0 to 4 subdivision steps (each x4 the triangles)")
    return smooth


def mesh_of(surface: SurfaceLike, smooth: int = 0) -> Any:
    """The surface's regions as one ``trimesh.Trimesh``: the surface's vertices first, in order (not
    merged), then the points its meshing added; ``smooth`` Loop subdivision steps after."""
    import trimesh

    points, _, faces = _arrays(surface, check_smooth(smooth))
    return trimesh.Trimesh(vertices=points, faces=faces, process=False, validate=False)


def export_mesh(surface: SurfaceLike, path: str | Path, *, smooth: int = 0) -> Path:
    """Write the triangulated regions to ``path`` (OBJ, PLY, STL or GLB by suffix), after ``smooth``
    subdivision steps; returns the path."""
    return write_mesh(mesh_of(surface, smooth), path)


def write_mesh(mesh: Any, path: str | Path) -> Path:
    """Write a ``trimesh.Trimesh`` to ``path`` atomically (OBJ, PLY, STL or GLB by suffix, the same
    bytes for the same mesh); returns the path. Phenotype plugins export through this too."""
    path = Path(path)
    kind = _suffix(path, MESH_FORMATS, "mesh")
    if kind == "obj":
        data = mesh.export(file_type="obj", include_normals=False, include_texture=False, digits=17,
                           header="genr8_dist")
    else:
        data = mesh.export(file_type=kind)
    _write_bytes(path, data)
    return path


def _scaffold_obj(vertices: np.ndarray, edges: np.ndarray, labels: np.ndarray) -> str:
    lines = ["# genr8 scaffold: the map's edges as polylines, grouped by edge label"]
    lines.extend(f"v {x:.17g} {y:.17g} {z:.17g}" for x, y, z in vertices)
    for label in np.unique(labels) if len(labels) else []:
        lines.append(f"g label{label}")
        lines.extend(f"l {a + 1} {b + 1}" for a, b in edges[labels == label])
    return "\n".join(lines) + "\n"


def _scaffold_ply(vertices: np.ndarray, edges: np.ndarray, labels: np.ndarray) -> str:
    head = [
        "ply", "format ascii 1.0", "comment genr8 scaffold",
        f"element vertex {len(vertices)}", "property double x", "property double y", "property double z",
        f"element edge {len(edges)}", "property int vertex1", "property int vertex2", "property int label",
        "end_header",
    ]
    body = [f"{x:.17g} {y:.17g} {z:.17g}" for x, y, z in vertices]
    body.extend(f"{a} {b} {int(label)}" for (a, b), label in zip(edges, labels, strict=True))
    return "\n".join(head + body) + "\n"


def _scaffold_dxf(vertices: np.ndarray, edges: np.ndarray, labels: np.ndarray) -> str:
    """A minimal DXF (R12, ENTITIES only): one LINE per edge, on layer ``label<N>``; CAD tools read it."""
    out = ["0", "SECTION", "2", "ENTITIES"]
    for (a, b), label in zip(edges, labels, strict=True):
        (x1, y1, z1), (x2, y2, z2) = vertices[a], vertices[b]
        out += ["0", "LINE", "8", f"label{int(label)}",
                "10", f"{x1:.17g}", "20", f"{y1:.17g}", "30", f"{z1:.17g}",
                "11", f"{x2:.17g}", "21", f"{y2:.17g}", "31", f"{z2:.17g}"]
    out += ["0", "ENDSEC", "0", "EOF"]
    return "\n".join(out) + "\n"


#: The scaffold formats by suffix: each one's text from (vertices, edges, labels).
_SCAFFOLD_WRITERS: dict[str, Callable[[np.ndarray, np.ndarray, np.ndarray], str]] = {
    "obj": _scaffold_obj, "ply": _scaffold_ply, "dxf": _scaffold_dxf,
}
SCAFFOLD_FORMATS: tuple[str, ...] = tuple(_SCAFFOLD_WRITERS)


def export_scaffold(surface: SurfaceLike, path: str | Path) -> Path:
    """Write the map's edges as polylines to ``path`` (OBJ lines, PLY edges, or DXF); returns the path."""
    path = Path(path)
    kind = _suffix(path, SCAFFOLD_FORMATS, "scaffold")
    vertices = np.asarray(surface.vertices, dtype=np.float64).reshape(-1, 3)
    edges = np.asarray(surface.edges, dtype=np.int64).reshape(-1, 2)
    labels = np.asarray(surface.labels).reshape(-1)
    if len(labels) != len(edges):
        labels = np.zeros(len(edges), dtype=np.int64)
    _write_bytes(path, _SCAFFOLD_WRITERS[kind](vertices, edges, labels.astype(np.int64)))
    return path


# -- pictures ------------------------------------------------------------------------------------------

def pyplot(needs: str = "PNG previews", error: type[Genr8Error] = ConfigError) -> Any:
    """``matplotlib.pyplot`` on the headless Agg backend; without matplotlib (the ``viz`` extra), an
    ``error`` saying that ``needs`` it and how to install it. Every picture of genr8_dist draws
    through this."""
    try:
        import matplotlib
    except ImportError:
        raise error(f"{needs} need matplotlib: pip install 'genr8-dist[viz]'") from None
    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    return plt


def save_png(fig: Any, path: str | Path, *, dpi: int = 120) -> Path:
    """Save a matplotlib figure as the PNG ``path`` atomically and close it; returns the path."""
    path = Path(path)
    plt = pyplot()
    try:
        if path.suffix.lower() != ".png" and not is_stream(path):
            raise ConfigError(f"{path}: a preview is a .png file")
        with _atomic(path) as tmp:
            fig.savefig(tmp, format="png", dpi=dpi, bbox_inches="tight", pad_inches=0.15,
                        facecolor="white")
    finally:
        plt.close(fig)
    return path


_LIGHT = np.array([-0.4, -0.5, 0.77]) / np.linalg.norm([-0.4, -0.5, 0.77])
_DRAWN_TRIANGLES = 40_000   # a mesh of more triangles is drawn as its meshing-1 triangles (speed)


def smooth_normals(points: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """(P, 3) unit normals at the points: the area-weighted mean of the normals of the triangles
    around each (the faces are oriented like their regions, so neighbours agree)."""
    tri = points[faces]
    face = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])      # length: twice the area
    normal = np.zeros_like(points)
    for k in range(3):
        np.add.at(normal, faces[:, k], face)
    length = np.linalg.norm(normal, axis=1, keepdims=True)
    result: np.ndarray = np.divide(normal, length, out=np.zeros_like(normal), where=length > 0)
    return result


_SHADED_SPLIT = 12_000   # meshes of up to this many triangles are drawn split in four (smoother shading)


def _face_colours(vertices: np.ndarray, faces: np.ndarray, cmap: Any, low: float = 0.15,
                  span_: float = 0.7, dark: float = 0.45) -> tuple[np.ndarray, np.ndarray]:
    """The polygons drawn and their colours: colour by height, shaded by a fixed light through smooth
    (point-averaged) normals, both taken at the points and blended across each triangle as Gouraud
    shading does. A polygon takes one colour, so each triangle of a mesh up to ``_SHADED_SPLIT`` is
    drawn as its four midpoint triangles, each the mean of its corners' colours: no facet or seam
    shows. Returns (T, 3, 3) polygons and (T, 4) colours."""
    lambert = np.abs(smooth_normals(vertices, faces) @ _LIGHT)
    z = vertices[:, 2]
    used = np.unique(faces)
    zlo = float(z[used].min()) if len(used) else 0.0
    span = float(np.ptp(z[used])) if len(used) else 0.0
    level = (z - zlo) / span if span > 1e-12 else np.full(len(z), 0.55)
    point_colours = cmap(low + span_ * np.clip(level, 0.0, 1.0))
    point_colours[:, :3] *= (dark + (1.0 - dark) * lambert)[:, None]
    point_colours[:, 3] = 1.0
    tri, col = vertices[faces], point_colours[faces]          # (F, 3, 3), (F, 3, 4)
    if len(faces) <= _SHADED_SPLIT:
        mid = (tri + np.roll(tri, -1, axis=1)) / 2            # midpoints of ab, bc, ca
        mcol = (col + np.roll(col, -1, axis=1)) / 2
        a, b, c = tri[:, 0], tri[:, 1], tri[:, 2]
        ab, bc, ca = mid[:, 0], mid[:, 1], mid[:, 2]
        ka, kb, kc = col[:, 0], col[:, 1], col[:, 2]
        mab, mbc, mca = mcol[:, 0], mcol[:, 1], mcol[:, 2]
        tri = np.concatenate([np.stack(t, 1) for t in ((a, ab, ca), (ab, b, bc), (ca, bc, c), (ab, bc, ca))])
        col = np.concatenate([np.stack(t, 1) for t in ((ka, mab, mca), (mab, kb, mbc), (mca, mbc, kc),
                                                       (mab, mbc, mca))])
    colours = col.mean(axis=1)
    colours[:, 3] = 1.0
    return tri, colours


def _drawn(surface: SurfaceLike) -> tuple[np.ndarray, np.ndarray]:
    """The points and triangles a picture draws: the surface's mesh, or its meshing-1 triangles when
    the mesh is too large to draw quickly."""
    points, _, faces = _arrays(surface)
    if len(faces) > _DRAWN_TRIANGLES and hasattr(surface, "triangles"):
        points = np.asarray(surface.vertices, dtype=np.float64).reshape(-1, 3)
        faces = np.asarray(surface.triangles(), dtype=np.int64).reshape(-1, 3)
    return points, faces


def _add_surface(ax: Any, surface: SurfaceLike, plt: Any, *, low: float, span: float, dark: float,
                 curve_width: float, zorder: float | None = None) -> None:
    """The shaded mesh (triangle edges hidden: drawn in the face colour, hairline, to close seams)
    and the scaffold as B-spline curves (``genr8_dist.scaffold``)."""
    from mpl_toolkits.mplot3d.art3d import Line3DCollection, Poly3DCollection

    from genr8_dist.scaffold import scaffold_curves

    points, faces = _drawn(surface)
    extra = {} if zorder is None else {"zorder": zorder}
    if len(faces):
        polygons, colours = _face_colours(points, faces, plt.get_cmap("viridis"), low, span, dark)
        ax.add_collection3d(Poly3DCollection(polygons, facecolors=colours, edgecolors=colours,
                                             linewidths=0.1, antialiased=False, **extra))
    edges = np.asarray(surface.edges).reshape(-1, 2)
    if len(edges):
        curves = scaffold_curves(surface)
        extra_l = {} if zorder is None else {"zorder": zorder + 1}
        ax.add_collection3d(Line3DCollection(curves, colors="0.12", linewidths=curve_width, alpha=0.8,
                                             **extra_l))


def _draw_environment(ax: Any, env: Environment, lo: np.ndarray, hi: np.ndarray,
                      vertices: np.ndarray | None = None) -> None:
    """Boundaries as light wireframes (each its own ``outline``), attractors (green dots) and
    repellers (red crosses)."""
    from mpl_toolkits.mplot3d.art3d import Line3DCollection

    middle, size = (lo + hi) / 2, 0.6 * float(np.max(hi - lo))
    for b in env.boundaries:
        style = ({"colors": "0.55", "linewidths": 0.3, "alpha": 0.5} if b.faint
                 else {"colors": "0.45", "linewidths": 0.5, "alpha": 0.6})
        ax.add_collection3d(Line3DCollection(b.outline(middle, size), zorder=0, **style))
    for force, colour, marker in ([(a, "tab:green", "o") for a in env.attractors]
                                  + [(r, "tab:red", "X") for r in env.repellers]):
        where = np.asarray(force.position)
        # a charge under the surface is drawn before it (hidden where the surface covers it)
        below = vertices is not None and len(vertices) and where[2] < _height_at(vertices, where)
        ax.scatter(*where[:, None], color=colour, marker=marker, s=70, depthshade=False,
                   edgecolors="black", linewidths=0.6, zorder=0.5 if below else 5)


def _height_at(vertices: np.ndarray, point: np.ndarray) -> float:
    """z of the surface vertex nearest ``point`` in plan (x, y)."""
    nearest = int(np.argmin(np.sum((vertices[:, :2] - point[:2]) ** 2, axis=1)))
    return float(vertices[nearest, 2])


def _legend(env: Environment) -> str:
    """One line naming what the environment holds (drawn under the picture)."""
    parts = []
    g = np.asarray(env.gravity)
    if np.any(g):
        parts.append("gravity (" + ", ".join(f"{v:g}" for v in g) + ")/step")
    if env.attractors:
        parts.append(f"● {len(env.attractors)} attractor{'s' if len(env.attractors) > 1 else ''}")
    if env.repellers:
        parts.append(f"✖ {len(env.repellers)} repeller{'s' if len(env.repellers) > 1 else ''}")
    for b in env.boundaries:
        side = "inside" if b.allowed_inside else "outside"
        parts.append(f"{b.kind} boundary ({b.behaviour}, {side} allowed)")
    flags = [name.replace("_", " ") for name in ("fixed_perimeter", "fixed_centre", "uniform_cells")
             if getattr(env, name)]
    if env.repelling_points:
        flags.append("repelling points")
    if env.position_noise:
        flags.append(f"position noise {env.position_noise:g}")
    parts.extend(flags)
    return "   ".join(parts)


def _perimeter(surface: SurfaceLike) -> np.ndarray:
    """The outer boundary's vertex cycle when the surface offers one (``Surface.perimeter()``)."""
    perimeter = getattr(surface, "perimeter", None)
    if not callable(perimeter):
        return np.zeros(0, dtype=np.int64)
    return np.asarray(perimeter(), dtype=np.int64).reshape(-1)


def _scene_bounds(env: Environment, lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The surface's bounding box grown to show nearby attractors, repellers and boundaries (their
    ``reach``).

    Things further than twice the surface's size away are cut off at that distance (a huge enclosing
    box would otherwise shrink the surface to a dot).
    """
    size = max(float(np.max(hi - lo)), 1e-9)
    middle = (lo + hi) / 2
    limit_lo, limit_hi = middle - 2.0 * size, middle + 2.0 * size
    points = [np.asarray(f.position) for f in (*env.attractors, *env.repellers)]
    for b in env.boundaries:
        points += list(b.reach())
    new_lo, new_hi = lo.copy(), hi.copy()
    for point in points:
        clipped = np.clip(point, limit_lo, limit_hi)
        new_lo = np.minimum(new_lo, clipped)
        new_hi = np.maximum(new_hi, clipped)
    return new_lo, new_hi


def render_png(surface: SurfaceLike, path: str | Path, *, title: str, env: Environment | None = None,
               size: tuple[float, float] = (8.0, 7.0), dpi: int = 120) -> Path:
    """Draw the surface (shaded regions, edges, axes, ``title``) into a PNG at ``path``; returns the path.

    The outer boundary is drawn heavier; the subtitle gives the vertex, edge and region counts. With
    ``env`` the environment's boundaries (grey wireframes), attractors (green dots) and repellers (red
    crosses) are drawn too, and a line under the picture lists gravity, boundaries and the internal
    forces in use.
    """
    path = Path(path)
    if path.suffix.lower() != ".png":
        raise ConfigError(f"{path}: a preview is a .png file")
    plt = pyplot()
    vertices = np.asarray(surface.vertices, dtype=np.float64).reshape(-1, 3)
    edges = np.asarray(surface.edges, dtype=np.int64).reshape(-1, 2)
    faces = np.asarray(surface.triangles(), dtype=np.int64).reshape(-1, 3)
    regions = getattr(surface, "regions", None)
    fig = plt.figure(figsize=size, dpi=dpi)
    try:
        ax = fig.add_subplot(projection="3d")
        ax.set_proj_type("persp", focal_length=0.4)
        # draw order: environment wireframes, then the surface (depth-sorted), its edges, then markers
        ax.computed_zorder = False
        if len(vertices):
            lo, hi = vertices.min(axis=0), vertices.max(axis=0)
        else:
            lo, hi = np.zeros(3), np.ones(3)
        if len(faces) or len(edges):
            width = 0.8 if len(edges) < 3000 else (0.4 if len(edges) < 20000 else 0.2)
            _add_surface(ax, surface, plt, low=0.15, span=0.7, dark=0.45, curve_width=width, zorder=1)
        rim = _perimeter(surface)
        if len(rim) > 1:
            loop = vertices[np.append(rim, rim[0])]
            ax.plot(loop[:, 0], loop[:, 1], loop[:, 2], color="0.05", linewidth=1.3, zorder=3)
        if env is not None:
            lo, hi = _scene_bounds(env, lo, hi)
            _draw_environment(ax, env, lo, hi, vertices)
            legend = _legend(env)
            if legend:
                fig.text(0.5, -0.01, legend, ha="center", va="top", fontsize=8, color="0.25")
        extent = _fit_box(ax, lo, hi)
        ax.set_xlabel("x")
        ax.set_ylabel("y")
        ax.set_zlabel("z")
        ax.view_init(elev=32, azim=-58)
        ax.tick_params(labelsize=7)
        from matplotlib.ticker import MaxNLocator

        for axis, span in zip((ax.xaxis, ax.yaxis, ax.zaxis), extent / np.max(extent), strict=True):
            axis.set_major_locator(MaxNLocator(nbins=max(2, round(7 * span)), min_n_ticks=2))
        n_regions = len(regions) if regions is not None else len(faces)
        counts = ", ".join(f"{n} {one if n == 1 else many}" for n, one, many in
                           ((len(vertices), "vertex", "vertices"), (len(edges), "edge", "edges"),
                            (n_regions, "region", "regions")))
        fig.text(0.5, 0.965, title, ha="center", va="top", fontsize=13, fontweight="bold")
        fig.text(0.5, 0.925, counts, ha="center", va="top", fontsize=9, color="0.35")
        fig.subplots_adjust(left=0.0, right=0.97, bottom=0.02, top=0.97)
        with _atomic(path) as tmp:
            fig.savefig(tmp, format="png", bbox_inches="tight", pad_inches=0.15, facecolor="white")
    finally:
        plt.close(fig)
    return path


def _fit_box(ax: Any, lo: np.ndarray, hi: np.ndarray, zoom: float = 1.0) -> np.ndarray:
    """Set the 3D axes ``ax`` to the box ``lo``..``hi`` at equal scale on every axis, each side at
    least 8% of the longest (a flat surface gets a flat box, not a cube of empty height; a point,
    a unit cube); returns the sides."""
    centre = (lo + hi) / 2
    extent: np.ndarray = np.maximum(hi - lo, 0.08 * float(np.max(hi - lo)) if np.any(hi > lo) else 1.0)
    ax.set_xlim(centre[0] - extent[0] / 2, centre[0] + extent[0] / 2)
    ax.set_ylim(centre[1] - extent[1] / 2, centre[1] + extent[1] / 2)
    ax.set_zlim(centre[2] - extent[2] / 2, centre[2] + extent[2] / 2)
    ax.set_box_aspect(tuple(extent / np.max(extent)), zoom=zoom)
    return extent


def draw_surface(ax: Any, surface: SurfaceLike, *, elev: float = 32.0, azim: float = -58.0) -> None:
    """Draw ``surface`` on the 3D axes ``ax``: its mesh shaded by height and lit from above through
    smooth normals (no triangle edge drawn), its scaffold as B-spline curves, equal scale on every
    axis, no axis clutter. The box fits the surface on each axis (a flat surface gets a flat box,
    not a cube of empty height), so the form fills its tile."""
    plt = pyplot()
    v = np.asarray(surface.vertices, dtype=np.float64).reshape(-1, 3)
    _add_surface(ax, surface, plt, low=0.18, span=0.64, dark=0.55, curve_width=0.45)
    _fit_box(ax, v.min(axis=0), v.max(axis=0), zoom=1.05)
    ax.view_init(elev=elev, azim=azim)
    ax.set_axis_off()


def export_3dm(surface: SurfaceLike, path: str | Path, *, name: str, smooth: int = 0) -> Path:
    """A Rhino file holding the surface as one mesh named ``name`` (its vertices first, in order, then
    the points its meshing added; ``smooth`` subdivision steps after), its edges as a line layer
    ("genr8 scaffold"), and the scaffold's lines as degree-3 NURBS curves ("genr8 scaffold curves":
    ``genr8_dist.scaffold``, the smooth lines a designer builds on; the ``rhino`` extra)."""
    path = Path(path)
    try:
        import importlib

        rhino3dm: Any = importlib.import_module("rhino3dm")  # its stubs miss writable attributes
    except ImportError:
        raise ConfigError(".3dm export needs rhino3dm: pip install 'genr8-dist[rhino]'") from None
    points, edges, faces = _arrays(surface, check_smooth(smooth))
    vertices = np.asarray(surface.vertices, dtype=np.float64).reshape(-1, 3)
    mesh = rhino3dm.Mesh()
    for x, y, z in points.tolist():
        mesh.Vertices.Add(x, y, z)
    for a, b, c in faces.tolist():
        mesh.Faces.AddFace(a, b, c)
    mesh.Normals.ComputeNormals()
    model = rhino3dm.File3dm()
    surface_layer = rhino3dm.Layer()
    surface_layer.Name = "genr8 surface"
    scaffold_layer = rhino3dm.Layer()
    scaffold_layer.Name = "genr8 scaffold"
    surface_index = model.Layers.Add(surface_layer)
    scaffold_index = model.Layers.Add(scaffold_layer)
    attributes = rhino3dm.ObjectAttributes()
    attributes.Name = name
    attributes.LayerIndex = surface_index
    model.Objects.AddMesh(mesh, attributes)
    line_attributes = rhino3dm.ObjectAttributes()
    line_attributes.LayerIndex = scaffold_index
    for a, b in edges.tolist():
        p, q = vertices[a], vertices[b]
        model.Objects.AddLine(rhino3dm.Point3d(*p), rhino3dm.Point3d(*q), line_attributes)
    from genr8_dist.scaffold import scaffold_lines

    curve_layer = rhino3dm.Layer()
    curve_layer.Name = "genr8 scaffold curves"
    curve_attributes = rhino3dm.ObjectAttributes()
    curve_attributes.LayerIndex = model.Layers.Add(curve_layer)
    for ids, closed in scaffold_lines(vertices, edges):
        control = [rhino3dm.Point3d(*p) for p in vertices[ids].tolist()]
        degree = min(3, len(control) - 1)
        curve = rhino3dm.NurbsCurve.Create(closed, degree, control)
        if curve is not None:
            model.Objects.AddCurve(curve, curve_attributes)
    with _atomic(path) as tmp:
        if not model.Write(str(tmp), 7):
            raise OSError(5, "rhino3dm could not write the file", str(path))
    return path


# -- the surface formats ---------------------------------------------------------------------------

@dataclass(frozen=True)
class SurfaceFormat:
    """One file format a surface is exported in: its ``suffix``; ``write(surface, path, name,
    smooth)`` writing it; whether it is a triangle ``mesh`` through trimesh (``write_mesh`` writes
    those for a plugin's meshes too); the studio's ``label`` and ``media`` type for a download, and
    whether the studio offers it (``download``)."""

    suffix: str
    write: Callable[[SurfaceLike, Path, str, int], Path]
    label: str
    media: str = "application/octet-stream"
    mesh: bool = False
    download: bool = True


def _trimesh_format(surface: SurfaceLike, path: Path, name: str, smooth: int) -> Path:
    return export_mesh(surface, path, smooth=smooth)


def _rhino_format(surface: SurfaceLike, path: Path, name: str, smooth: int) -> Path:
    return export_3dm(surface, path, name=name or "genr8 surface", smooth=smooth)


#: Every format a surface is exported in, by suffix: ``genr8 grow -o``, ``genr8 show -o``, the
#: surface phenotype's ``export_formats`` and the studio's downloads all read this one table.
SURFACE_FORMATS: dict[str, SurfaceFormat] = {f.suffix: f for f in (
    SurfaceFormat("obj", _trimesh_format, "OBJ", "text/plain", mesh=True),
    SurfaceFormat("ply", _trimesh_format, "PLY", mesh=True, download=False),
    SurfaceFormat("stl", _trimesh_format, "STL", mesh=True, download=False),
    SurfaceFormat("glb", _trimesh_format, "GLB", "model/gltf-binary", mesh=True),
    SurfaceFormat("3dm", _rhino_format, "3DM"),
)}
MESH_FORMATS: tuple[str, ...] = tuple(s for s, f in SURFACE_FORMATS.items() if f.mesh)


def export_surface(surface: SurfaceLike, path: str | Path, *, name: str = "", smooth: int = 0) -> Path:
    """Write ``surface`` to ``path`` in the format its suffix names (one of ``SURFACE_FORMATS``),
    named ``name`` where the format keeps names, after ``smooth`` subdivision steps; returns the path."""
    path = Path(path)
    found = SURFACE_FORMATS[_suffix(path, tuple(SURFACE_FORMATS), "surface")]
    return found.write(surface, path, name, smooth)


def surface_bytes(surface: SurfaceLike, suffix: str, *, name: str) -> bytes:
    """The bytes ``export_surface`` writes for ``surface`` in the format ``suffix`` (a download)."""
    with tempfile.TemporaryDirectory(prefix="genr8-export-") as tmp:
        return export_surface(surface, Path(tmp) / f"{name}.{suffix}", name=name).read_bytes()
