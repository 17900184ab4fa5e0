"""3D picture of the wing and its wake at a few instants (``wake_3d.png``), by replaying the aero unit.

The wake lives inside the aero unit (FMU), which publishes only Q and scalar loads. After the run we
therefore replay the aero solver in-process: ``aero_fmu.solver.AeroSolver`` of the scene with the unit's default
tunable parameters (those ``run_scene`` runs with), advanced with the e, de the aero unit was given at each
of its steps (``RunResult.aero_inputs``, recorded by the master) and the same step end times
(t + h, as ``AeroSlave.do_step`` computes them). With explicit coupling the aero unit's state depends
on nothing else, so the replay reproduces the unit's wake bit for bit (tests/cli/test_wake_view.py). With
implicit coupling the master records only the accepted (final) iterate of each communication step (the
rejected iterates were undone by restoring the unit's saved state), and the replay takes one ``advance``
per step with those inputs, as for explicit coupling. It then agrees with the unit to about 1e-10
(relative), not bit for bit: the aero unit reuses its influence-matrix factorization while the lattice
moves rigidly within ``aero_fmu.factorization.RIGID_TOLERANCE``, and that cache, not part of the unit's
FMU state, may have been built at a rejected iterate's geometry (tests/units/test_coupling.py).

The figure: ``INSTANTS`` panels at 1/4, 1/2, 3/4 and the end of the run, each a mplot3d view with equal
scales on x, y, z (m) and the time in the title; the wing's panels (leading to trailing edge) in grey, the
shed wake's vortex rings coloured by their circulation (m^2/s), the flat wake's horseshoe legs as lines
(semi-infinite legs drawn 2 wing extents long), strip theory the wing only. A very slender picture (one
extent more than ``SLENDER`` times the next, e.g. the AR-1000 heaving wing) shows a window of ``WINDOW``
times that next extent around the centre, to scale, named in the title.

Cost: the replay costs about what the aero unit cost in the run. It stops after ``budget_s`` seconds
(default ``REPLAY_BUDGET_S``, or the environment variable ``WINGSIM_WAKE_BUDGET_S``; 0 skips the picture)
and then shows the last replayed time instead of the end, saying so.
"""

from __future__ import annotations

import math
import os
import sys
import time as _time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from orchestrator.files import write_file

WAKE_FILE = "wake_3d.png"
INSTANTS = 4
REPLAY_BUDGET_S = 60.0
BUDGET_ENV = "WINGSIM_WAKE_BUDGET_S"
SLENDER = 8.0              # a picture whose longest extent exceeds SLENDER x the next one is windowed
WINDOW = 1.5               # the window's width along the longest extent, x the next extent
DPI = 100
MAX_WAKE_EDGES = 300       # above this many drawn wake rings, they are drawn without edges
FONT_SIZE = 10             # axis labels and panel titles; ticks 2 points smaller (legible at DPI in a 10-inch figure)


@dataclass
class Snapshot:
    """The aero state of one replayed instant: time (s), wing panel grid (B, M + 1, N + 1, 3) m (leading to
    trailing edge), ``AeroSolver.vortex_geometry()`` and ``AeroSolver.outputs()`` (CL, lift, ...)."""

    time: float
    wing: np.ndarray
    vortex: dict
    outputs: dict


def aero_parameters(scene: dict) -> dict:
    """The tunable parameters the aero unit starts with (``AeroSlave``: their defaults)."""
    from aero_fmu.solver import AeroSolver
    from fmu_common.specs import AeroUnitSpec

    return {name: float(default[0]) for name, default in
            AeroSolver.tunable_parameters(AeroUnitSpec.from_scene(scene)).items()}


def replay(scene: dict, inputs, at_steps, budget_s: float | None = None):
    """Replay the aero unit over the recorded ``inputs`` (``coupling.AeroInputs``) up to the largest step
    index in ``at_steps`` (0-based), keeping a ``Snapshot`` after each of those steps.

    Returns (snapshots, solver, stopped): the solver as it is after the last replayed step, and
    ``stopped`` True if the budget (s; None: no limit) ran out first, in which case the last snapshot is
    the last replayed step. Raises whatever the solver raises (the run had succeeded with the same calls).
    """
    from aero_fmu.solver import AeroSolver
    from fmu_common.specs import AeroUnitSpec

    solver = AeroSolver(AeroUnitSpec.from_scene(scene), parameters=aero_parameters(scene))
    wanted = sorted({int(k) for k in at_steps if 0 <= int(k) < len(inputs)})
    keep = set(wanted)
    snapshots: list[Snapshot] = []
    if not wanted:
        return snapshots, solver, False
    deadline = None if budget_s is None else _time.perf_counter() + budget_s
    stopped = False
    for k in range(wanted[-1] + 1):
        e = inputs.e[k]
        solver.advance(inputs.t[k] + inputs.h[k] - 0.0, e, inputs.de[k])  # as AeroSlave.do_step (t0 = 0)
        last = k == wanted[-1]
        stopped = not last and deadline is not None and _time.perf_counter() > deadline
        if k in keep or stopped:
            snapshots.append(_snapshot(solver, e))
        if stopped:
            break
    return snapshots, solver, stopped


def _snapshot(solver, e) -> Snapshot:
    lat = solver.lattice
    wing = lat.grid_points(e).reshape(len(lat.body_names), lat.M + 1, lat.N + 1, 3)
    return Snapshot(solver.time, wing, solver.vortex_geometry(), solver.outputs())


def instant_steps(n_steps: int, count: int = INSTANTS) -> list[int]:
    """Step indices at 1/count, 2/count, ..., 1 of the run (0-based, distinct)."""
    if n_steps <= 0:
        return []
    return sorted({max(0, math.ceil(n_steps * (i + 1) / count) - 1) for i in range(count)})


# ---- drawing -------------------------------------------------------------------------------------------
def quads(grid: np.ndarray) -> np.ndarray:
    """The quadrilaterals (Q, 4, 3) of a structured grid (B, rows, cols, 3), row-major per body."""
    g = np.asarray(grid, dtype=float)
    quads = np.stack([g[:, :-1, :-1], g[:, 1:, :-1], g[:, 1:, 1:], g[:, :-1, 1:]], axis=3)
    return quads.reshape(-1, 4, 3)


def _legs(snapshot: Snapshot) -> np.ndarray | None:
    """The flat wake's legs (L, 2, 3): trailing corners to the far ends (semi-infinite: 2 wing extents)."""
    v = snapshot.vortex
    if v["legs"] is None or v["rings"] is None:
        return None
    direction, length = v["legs"]
    start = v["rings"][:, -1]                                             # (B, N + 1, 3)
    extent = float(np.ptp(snapshot.wing.reshape(-1, 3), axis=0).max())
    length = np.where(np.isfinite(length), length, 2.0 * max(extent, 1e-9))
    end = start + length[:, None, None] * direction
    return np.stack([start.reshape(-1, 3), end.reshape(-1, 3)], axis=1)


def _clip(polygons, axis: int, low: float, high: float):
    """Polygons (lists of (k, 3) arrays) clipped to low <= p[axis] <= high (Sutherland-Hodgman, 2 planes)."""
    out = []
    for poly in polygons:
        for sign, bound in ((1.0, low), (-1.0, high)):
            if len(poly) == 0:
                break
            d = sign * (poly[:, axis] - bound)                             # >= 0 inside
            kept = []
            for i in range(len(poly)):
                p, q, dp, dq = poly[i], poly[(i + 1) % len(poly)], d[i], d[(i + 1) % len(poly)]
                if dp >= 0:
                    kept.append(p)
                if (dp >= 0) != (dq >= 0):
                    kept.append(p + (q - p) * (dp / (dp - dq)))
            poly = np.array(kept).reshape(-1, 3)
        if len(poly) >= 3:
            out.append(poly)
    return out


def _window(points: np.ndarray):
    """(axis, low, high) of the display window of a slender picture, or None (module docstring)."""
    extent = np.ptp(points, axis=0)
    order = np.argsort(extent)[::-1]
    longest, next_ = extent[order[0]], extent[order[1]]
    if not (longest > SLENDER * next_ and next_ > 0):
        return None
    centre = 0.5 * (points[:, order[0]].min() + points[:, order[0]].max())
    half = 0.5 * WINDOW * next_
    return int(order[0]), centre - half, centre + half


def _select(polygons: np.ndarray, window, values=None):
    """Polygons (Q, k, 3) within the window (clipped), with their values; all of them without a window."""
    if window is None:
        return list(polygons), values
    axis, low, high = window
    coord = polygons[:, :, axis]
    inside = (coord.min(axis=1) >= low) & (coord.max(axis=1) <= high)
    straddle = ~inside & (coord.max(axis=1) >= low) & (coord.min(axis=1) <= high)
    kept = list(polygons[inside])
    vals = None if values is None else list(values[inside])
    for index in np.flatnonzero(straddle):                               # a clipped polygon keeps its value
        clipped = _clip([polygons[index]], axis, low, high)
        if clipped:
            kept += clipped
            if vals is not None:
                vals.append(values[index])
    return kept, None if vals is None else np.array(vals)


def wake_figure(scene: dict, snapshots: list[Snapshot], note: str = ""):
    """The figure (matplotlib Figure) of the snapshots, one 3D panel each (module docstring)."""
    from matplotlib import colormaps
    from matplotlib.colors import Normalize
    from matplotlib.figure import Figure
    from matplotlib.ticker import MaxNLocator
    from mpl_toolkits.mplot3d.art3d import Line3DCollection, Poly3DCollection

    wings = [quads(s.wing) for s in snapshots]
    wakes = [None if s.vortex["wake"] is None else quads(s.vortex["wake"]) for s in snapshots]
    gammas = [None if s.vortex["wake_gamma"] is None else s.vortex["wake_gamma"].ravel() for s in snapshots]
    legs = [_legs(s) for s in snapshots]
    points = np.concatenate([w.reshape(-1, 3) for w in wings]
                            + [w.reshape(-1, 3) for w in wakes if w is not None]
                            + [l.reshape(-1, 3) for l in legs if l is not None])
    window = _window(points)
    live = [g for g in gammas if g is not None and g.size]
    scale = max((float(np.abs(g).max()) for g in live), default=0.0) or 1.0
    norm, cmap = Normalize(-scale, scale), colormaps["RdBu_r"]

    drawn = []
    for wing, wake, gamma, leg in zip(wings, wakes, gammas, legs):
        w, _ = _select(wing, window)
        k, g = _select(wake, window, gamma) if wake is not None else ([], None)
        if leg is not None and window is not None:
            axis, low, high = window
            leg = leg[(leg[:, 0, axis] >= low) & (leg[:, 0, axis] <= high)]
        drawn.append((w, k, g, leg))
    visible = [np.asarray(p).reshape(-1, 3) for w, k, _, l in drawn for p in (*w, *k, *([] if l is None else l))]
    allpts = np.concatenate(visible) if visible else points
    low, high = allpts.min(axis=0), allpts.max(axis=0)
    span = np.maximum(high - low, 1e-3 * max(float((high - low).max()), 1e-9))
    centre = 0.5 * (low + high)

    n = len(snapshots)
    cols = 2 if n > 1 else 1
    rows = math.ceil(n / cols)
    fig = Figure(figsize=(5.2 * cols, 4.2 * rows))
    from fmu_common.choices import aero_model

    aero = scene["aero"]
    model = aero["model"]
    mesh = (f"M x N = {aero['chordwise_panels']} x {aero['spanwise_panels']} per body"
            if aero_model(model).chordwise else f"{aero['spanwise_panels']} strips per body")
    title = f"{scene['name']}: wing and wake ({model}, {mesh})"
    if window is not None:
        axis, lo, hi = window
        title += f"\nspanwise window {'xyz'[axis]} in [{lo:.4g}, {hi:.4g}] m of [{points[:, axis].min():.4g}, " \
                 f"{points[:, axis].max():.4g}] m"
    if note:
        title += f"\n{note}"
    fig.suptitle(title, fontsize=FONT_SIZE + 1)
    for i, (snap, (w, k, g, leg)) in enumerate(zip(snapshots, drawn)):
        ax = fig.add_subplot(rows, cols, i + 1, projection="3d")
        if k:
            many = len(k) > MAX_WAKE_EDGES
            ax.add_collection3d(Poly3DCollection(k, facecolors=cmap(norm(g)), edgecolors="none" if many else "0.4",
                                                 linewidths=0.2, alpha=0.85))
        if leg is not None and len(leg):
            ax.add_collection3d(Line3DCollection(leg, colors="tab:blue", linewidths=0.6))
        ax.add_collection3d(Poly3DCollection(w, facecolors="0.7", edgecolors="0.3", linewidths=0.25))
        ax.set_xlim(centre[0] - span[0] / 2, centre[0] + span[0] / 2)
        ax.set_ylim(centre[1] - span[1] / 2, centre[1] + span[1] / 2)
        ax.set_zlim(centre[2] - span[2] / 2, centre[2] + span[2] / 2)
        ax.set_box_aspect(tuple(span))                                     # equal scales on x, y, z
        ax.set_xlabel("x (m)", fontsize=FONT_SIZE)
        ax.set_ylabel("y (m)", fontsize=FONT_SIZE)
        ax.set_zlabel("z (m)", fontsize=FONT_SIZE)
        ax.tick_params(labelsize=FONT_SIZE - 2)
        for axis in (ax.xaxis, ax.yaxis, ax.zaxis):
            axis.set_major_locator(MaxNLocator(4))
        for name, c, s in zip("xyz", centre, span):   # a flat axis gets one tick, not a smudge of labels
            if s < 0.1 * span.max():
                tick = 0.0 if abs(c) < 1e-6 * span.max() else float(f"{c:.2g}")
                getattr(ax, f"set_{name}ticks")([tick], [f"{tick:g}"])
        ax.set_title(f"t = {snap.time:.4g} s", fontsize=FONT_SIZE)
    if live:
        from matplotlib.cm import ScalarMappable

        bar = fig.colorbar(ScalarMappable(norm=norm, cmap=cmap), ax=fig.axes, shrink=0.6, pad=0.08)
        bar.set_label("wake ring circulation (m^2/s)", fontsize=FONT_SIZE)
        bar.ax.tick_params(labelsize=FONT_SIZE - 2)
    return fig


def write_wake_view(result, out_dir, budget_s: float | None = None) -> Path | None:
    """Write ``wake_3d.png`` into ``out_dir`` for a run with an aero unit and recorded aero steps; returns
    its path, or None (and removes a stale file) when there is nothing to draw or the picture is switched
    off (budget 0). Prints a note when the replay was capped. Raises on a failure (the caller warns)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    path = Path(out_dir) / WAKE_FILE
    inputs = getattr(result, "aero_inputs", None)
    if budget_s is None:
        budget_s = float(os.environ.get(BUDGET_ENV, REPLAY_BUDGET_S))
    if inputs is None or len(inputs) == 0 or budget_s <= 0:
        path.unlink(missing_ok=True)
        return None
    steps = instant_steps(len(inputs))
    snapshots, _, stopped = replay(result.scene, inputs, steps, budget_s)
    note = ""
    if stopped:
        note = (f"replay capped at {budget_s:g} s of wall time: the last panel is t = {snapshots[-1].time:.4g} s, "
                f"not the end of the run ({BUDGET_ENV} sets the cap)")
    elif not inputs.complete:
        note = "only the recorded part of the run (the master stopped recording the aero inputs)"
    if note:
        print(f"note: {WAKE_FILE}: {note}", file=sys.stderr)
    fig = wake_figure(result.scene, snapshots, note)
    FigureCanvasAgg(fig)
    write_file(path, lambda tmp: fig.savefig(tmp, dpi=DPI))   # whole or not at all
    return path
