"""Picture of the mechanism at several instants (``mechanism.png``): the bodies' reference lines, drawn from
the structure unit's exchanged coordinates E the master recorded (``RunResult.structure_coordinates``).

Each element's reference line is the cubic Hermite curve between its nodes A and B,
r(x) = N_1 r^A + N_2 r_x^A + N_3 r^B + N_4 r_x^B (Otsuka et al. 2019, Eq. 2 at y = 0;
``fmu_common.shape_functions.hermite``), sampled at ``POINTS_PER_ELEMENT`` intervals; nodes and elements come
from ``fmu_common.topology.Topology.from_spec``.

The figure: the instants t = 0 and ``INSTANTS`` - 1 more evenly spread up to the last recorded time (the end
of the run, or where it stopped), each the nearest recorded sample, overlaid and coloured by time (a
sequential colormap, legend with the times). Nodes of two or more bodies that coincide (within
``JOINT_TOLERANCE`` of the picture's extent) at every instant drawn, i.e. where bodies meet at a joint, are
circled. A planar mechanism (every drawn point within ``PLANAR_TOLERANCE`` of the extent of one plane) is
drawn in 2D in that plane: a coordinate plane on its global axes ("x (m)", "z (m)"), another plane on two
orthogonal in-plane directions named by their global components; any other mechanism in a 3D view. Both
with equal scales.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from fmu_common.shape_functions import hermite
from orchestrator.files import write_file

MECHANISM_FILE = "mechanism.png"
INSTANTS = 5
POINTS_PER_ELEMENT = 16
JOINT_TOLERANCE = 1e-6      # x the extent: nodes closer than this meet (shared points coincide to round-off)
PLANAR_TOLERANCE = 1e-6     # x the extent: points closer than this to a plane lie in it
COLORMAP = "viridis"
FLAT = 0.1                  # x the largest extent: the least depth of a 3D view (limits widened, scales equal)
VIEWS = ((20, -15), (20, -75), (60, -60))   # (elevation, azimuth) deg of a 3D view thin along x, y, z
DPI = 120


@dataclass(frozen=True)
class Plane:
    """The plane of a planar picture: ``basis`` (2, 3), its two orthonormal in-plane directions (global
    components), their axis ``labels`` and the plane's ``name`` for the title."""

    basis: np.ndarray
    labels: tuple[str, str]
    name: str


def instant_indices(times, count: int = INSTANTS) -> list[int]:
    """Indices of the recorded ``times`` (s, increasing) nearest to ``count`` times evenly spread from the first
    to the last (both included), distinct and increasing."""
    times = np.asarray(times, dtype=float)
    if times.size == 0:
        return []
    targets = np.linspace(times[0], times[-1], count)
    return sorted({int(np.argmin(np.abs(times - target))) for target in targets})


def reference_lines(topology, e, points_per_element: int = POINTS_PER_ELEMENT) -> dict[str, np.ndarray]:
    """{body: (elements x points_per_element + 1, 3) m}: the reference line of each body for the exchanged
    coordinates ``e`` (9 per node), root to tip; node k of the body is row k x points_per_element."""
    nodes = np.asarray(e, dtype=float).reshape(-1, 3, 3)            # per node: r, r_x, r_y
    xi = np.linspace(0.0, 1.0, points_per_element + 1)
    lengths = topology.element_lengths()
    lines = {}
    for name, body in topology.bodies.items():
        pieces = []
        for k, element in enumerate(body.elements):
            a, b = topology.element_nodes[element]
            N = hermite(xi, lengths[element])[0]                      # (points, 4) for r^A, r_x^A, r^B, r_x^B
            piece = N @ np.stack([nodes[a, 0], nodes[a, 1], nodes[b, 0], nodes[b, 1]])
            pieces.append(piece if k == 0 else piece[1:])             # the shared node once
        lines[name] = np.concatenate(pieces)
    return lines


def joint_nodes(topology, coordinates, tolerance: float) -> list[int]:
    """Indices of the nodes that coincide within ``tolerance`` (m) with a node of another body for every E
    in ``coordinates``."""
    from scipy.spatial import cKDTree

    body_of = np.empty(topology.n_nodes, dtype=object)
    for name, body in topology.bodies.items():
        body_of[body.nodes] = name
    pairs = None
    for e in coordinates:
        positions = np.asarray(e, dtype=float).reshape(-1, 9)[:, :3]
        found = {(i, j) for i, j in cKDTree(positions).query_pairs(tolerance) if body_of[i] != body_of[j]}
        pairs = found if pairs is None else pairs & found
    return sorted({node for pair in pairs or () for node in pair})


def drawing_plane(points, tolerance: float = PLANAR_TOLERANCE) -> Plane | None:
    """The plane of ``points`` (k, 3) m when all lie within ``tolerance`` x their extent of one (module
    docstring), else None. A coordinate plane is preferred (x-y, then x-z, then y-z), so that collinear or
    coincident points get one too. In another plane the second (vertical) direction is z projected on it (y
    for a plane normal to z), the first is perpendicular to it with its first nonzero global component
    positive."""
    points = np.asarray(points, dtype=float).reshape(-1, 3)
    span = np.ptp(points, axis=0)
    limit = tolerance * float(span.max())
    for normal in (2, 1, 0):
        if span[normal] <= limit:
            first, second = (k for k in range(3) if k != normal)
            return Plane(np.eye(3)[[first, second]], (f"{'xyz'[first]} (m)", f"{'xyz'[second]} (m)"),
                         f"the {'xyz'[first]}-{'xyz'[second]} plane")
    centre = points.mean(axis=0)
    normal = np.linalg.svd(points - centre, full_matrices=False)[2][2]
    if np.abs((points - centre) @ normal).max() > limit:
        return None
    along = np.eye(3) - np.outer(normal, normal)                       # the global axes projected on the plane
    up = along[2] if np.linalg.norm(along[2]) > 1e-6 else along[1]
    v = up / np.linalg.norm(up)
    u = np.cross(v, normal)
    u *= np.sign(next(c for c in u if abs(c) > 1e-12))
    return Plane(np.stack([u, v]), (_in_plane_label(1, u), _in_plane_label(2, v)), "the plane of the mechanism")


def _in_plane_label(index: int, direction: np.ndarray) -> str:
    """The axis label of an in-plane direction, with its global components."""
    return f"in-plane {index} (m), along ({', '.join(f'{c:.3g}' for c in direction + 0.0)})"


def mechanism_figure(result, topology=None):
    """The figure (matplotlib Figure) of the recorded run ``result`` (module docstring)."""
    from matplotlib import colormaps
    from matplotlib.figure import Figure

    from fmu_common.wing_spec import StructureSpec
    from fmu_common.topology import Topology

    topology = topology or Topology.from_spec(StructureSpec.from_scene(result.scene))
    record = result.structure_coordinates
    chosen = instant_indices(record.t)
    times = [record.t[i] for i in chosen]
    coordinates = [record.e[i] for i in chosen]
    lines = [reference_lines(topology, e) for e in coordinates]
    points = np.concatenate([p for drawn in lines for p in drawn.values()])
    extent = float(np.ptp(points, axis=0).max())
    joints = joint_nodes(topology, coordinates, JOINT_TOLERANCE * extent)
    plane = drawing_plane(points)
    colors = colormaps[COLORMAP](np.linspace(0.0, 0.85, len(times)) if len(times) > 1 else [0.0])

    fig = Figure(figsize=(7, 6), layout="constrained")
    ax = fig.add_subplot() if plane is not None else fig.add_subplot(projection="3d")
    project = (lambda p: p @ plane.basis.T) if plane is not None else (lambda p: p)
    for t, drawn, e, color in zip(times, lines, coordinates, colors):
        for k, line in enumerate(drawn.values()):
            ax.plot(*project(line).T, color=color, linewidth=1.5, label=f"t = {t:.4g} s" if k == 0 else None)
        if joints:
            at = project(np.asarray(e, dtype=float).reshape(-1, 9)[joints, :3])
            ax.plot(*at.T, "o", color=color, markerfacecolor="none", markersize=6)
    if joints:
        ax.plot([], [], "o", color="0.3", markerfacecolor="none", label="joint nodes")
    if plane is not None:
        ax.set_aspect("equal", adjustable="datalim")
        ax.set_xlabel(plane.labels[0])
        ax.set_ylabel(plane.labels[1])
        ax.grid(True, alpha=0.3)
    else:
        equal_3d(ax, points)
    fig.legend(loc="outside right upper", fontsize=8)   # outside the axes: over neither the title nor the lines
    instants = f"{len(times)} instants" if len(times) > 1 else "t = 0"
    where = f"in {plane.name}" if plane is not None else "in 3D"
    status = "" if result.status == "ok" else f"; the run {result.status} at t = {result.simulated_time_s:.4g} s"
    fig.suptitle(f"{result.scene['name']}: reference lines of the bodies at {instants}\n{where}{status}",
                 fontsize=10)
    return fig


def equal_3d(ax, points: np.ndarray) -> None:
    """Limits and box aspect of a 3D axis with equal scales on x, y, z (m), labelled; a view thin along an axis
    looks nearly along it (``VIEWS``)."""
    from matplotlib.ticker import MaxNLocator

    low, high = points.min(axis=0), points.max(axis=0)
    largest = max(float((high - low).max()), 1e-9)
    span = np.maximum(high - low, FLAT * largest)          # a nearly flat picture keeps a visible depth
    centre = 0.5 * (low + high)
    for name, c, s in zip("xyz", centre, span):
        getattr(ax, f"set_{name}lim")(c - s / 2, c + s / 2)
        getattr(ax, f"set_{name}label")(f"{name} (m)")
        getattr(ax, f"{name}axis").set_major_locator(MaxNLocator(4))
        if s <= FLAT * largest:                               # one tick, not a smudge of labels
            tick = float(f"{c:.2g}") if abs(c) > 1e-6 * largest else 0.0
            getattr(ax, f"set_{name}ticks")([tick], [f"{tick:g}"])
    ax.set_box_aspect(tuple(span))
    thin = int(np.argmin(high - low))
    if high[thin] - low[thin] <= FLAT * largest:             # a nearly planar mechanism: seen nearly face-on
        ax.view_init(*VIEWS[thin])


def write_mechanism_view(result, out_dir) -> Path | None:
    """Write ``mechanism.png`` into ``out_dir`` for a run with recorded structure coordinates; returns its path,
    or None (and removes a stale file) when nothing was recorded. Raises on a failure (the caller warns)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    path = Path(out_dir) / MECHANISM_FILE
    record = getattr(result, "structure_coordinates", None)
    if record is None or len(record) == 0:
        path.unlink(missing_ok=True)
        return None
    fig = mechanism_figure(result)
    FigureCanvasAgg(fig)
    write_file(path, lambda tmp: fig.savefig(tmp, dpi=DPI))   # whole or not at all
    return path
