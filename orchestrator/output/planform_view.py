"""Picture of the wing's planform and vortex lattice as designed (``planform.png``), for scenes with an aero unit.

Each body is drawn in its own material plane (docs/aero.md, Planform): span x from its root to the right, chord
offset y from the reference line downward (the leading edge up): a planform as drawn on a drawing board, the
flow from top to bottom, a leading edge swept back running down the page toward the tip. Bodies are
laid side by side along the span in the order a wing is built (every parent before its children,
``Topology.bodies``), each child starting where its parent ends, unfolded (fold angles and dihedral do not
change a planform). Drawn per body: the outline (leading and trailing edges from ``Planform.chord_offset``), the
panel edges of the aero lattice (``aero.chordwise_panels`` x ``aero.spanwise_panels``, at chord fractions i / M),
the vortex rings' bound segments (at the panels' quarter chords) dashed, the collocation points (three-quarter
chords), the reference line (the beam) and each hinge (its point, and a revolute's axis across the root
chord); a label with the body's chords, sweep, twist and camber. Twist and camber turn the sections out of this
plane and are given in the labels only. Strip theory draws one panel per strip.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from orchestrator.files import write_file

PLANFORM_FILE = "planform.png"
DPI = 120
COLORMAP = "tab10"


def _outline(planform, x):
    """(leading edge, trailing edge) y (m) of `planform` at spans x (m)."""
    return planform.chord_offset(x, 0.0), planform.chord_offset(x, 1.0)


def _draw_hinge(ax, line, start, child):
    """A hinge at span `start` of the picture: its point on the reference line and, for a revolute joint, its axis
    across the child's root chord (its span and chord components in the parent's tip frame)."""
    ax.plot([start], [0.0], "o", color="0.2", markerfacecolor="none", markersize=6)
    span, chord = line.axis[:2]
    if line.kind != "revolute" or np.hypot(span, chord) < 1e-9:
        return
    lead, trail = _outline(child, 0.0)
    t = np.array([lead, trail]) / chord if abs(chord) > 1e-9 else np.array([lead, trail])
    ax.plot(start + span * t, -chord * t, ":", color="0.2", linewidth=1.2)


def planform_figure(scene, topology=None):
    """The figure (matplotlib Figure) of the resolved `scene`'s planform and lattice (module docstring)."""
    from matplotlib import colormaps
    from matplotlib.figure import Figure

    from fmu_common.choices import aero_model
    from fmu_common.topology import Topology
    from fmu_common.wing_spec import StructureSpec

    topology = topology or Topology.from_spec(StructureSpec.from_scene(scene))
    aero = scene["aero"]
    M = aero["chordwise_panels"] if aero_model(aero["model"]).chordwise else 1
    N = aero["spanwise_panels"]
    colors = colormaps[COLORMAP](np.arange(len(topology.bodies)) % 10)
    hinges = {line.child: line for line in topology.joint_lines if line.parent is not None}
    fig = Figure(figsize=(9, 4.5))
    ax = fig.add_subplot()
    start = 0.0
    for (name, body), color in zip(topology.bodies.items(), colors):
        p = body.planform
        if name in hinges:
            _draw_hinge(ax, hinges[name], start, p)
        x = np.linspace(0.0, p.length, N + 1)
        lead, trail = _outline(p, x)
        ax.plot(start + np.r_[x, x[::-1], x[:1]], -np.r_[lead, trail[::-1], lead[:1]], color=color, linewidth=1.6,
                label=f"{name}: chord {p.chord_root:.3g} -> {p.chord_tip:.3g} m, leading-edge sweep "
                      f"{np.degrees(np.arctan((p.leading_edge_tip - p.leading_edge(0.0)) / p.length)):.3g} deg, "
                      f"twist {np.degrees(p.twist_root):.3g} -> {np.degrees(p.twist_tip):.3g} deg"
                      + (f", camber {p.camber.m:.0%} at {p.camber.p:.0%}" if p.camber.m else ""))
        for i in range(1, M):                               # chordwise panel edges
            ax.plot(start + x, -p.chord_offset(x, i / M), color=color, linewidth=0.6)
        for xj in x[1:-1]:                                  # spanwise panel edges
            ax.plot([start + xj] * 2, -np.array(_outline(p, xj)), color=color, linewidth=0.6)
        for i in range(M):                                  # bound segments at the panels' quarter chords
            ax.plot(start + x, -p.chord_offset(x, (i + 0.25) / M), color=color, linewidth=0.8, linestyle="--")
        xc = (np.arange(N) + 0.5) * p.length / N
        fc = (np.arange(M) + 0.75) / M
        ax.plot(start + np.repeat(xc, M), -p.chord_offset(np.repeat(xc, M), np.tile(fc, N)), ".", color=color,
                markersize=3)
        ax.plot([start, start + p.length], [0.0, 0.0], color="k", linewidth=0.8, linestyle="-.")
        start += p.length
    ax.plot([], [], "k-.", linewidth=0.8, label="reference lines (beams)")
    ax.plot([], [], "--", color="0.3", linewidth=0.8, label="bound vortex segments; dots: collocation points")
    if hinges:
        ax.plot([], [], ":", color="0.2", linewidth=1.2, marker="o", markerfacecolor="none",
                label="hinges: point and axis in the wing plane")
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("span from the first root, unfolded (m)")
    ax.set_ylabel("chord offset, leading edge up (m)")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.18), ncol=1)
    fig.suptitle(f"{scene['name']}: planform and vortex lattice ({aero['model']}, {M} x {N} panels per body), "
                 "unfolded, flow from top to bottom", fontsize=10)
    return fig


def write_planform_view(result, out_dir) -> Path | None:
    """Write ``planform.png`` into ``out_dir`` for a run of a scene with an aero unit; returns its path, or None
    (and removes a stale file) without one. Raises on a failure (the caller warns)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    from orchestrator.run.master import has_aero

    path = Path(out_dir) / PLANFORM_FILE
    if not has_aero(result.scene):
        path.unlink(missing_ok=True)
        return None
    fig = planform_figure(result.scene)
    FigureCanvasAgg(fig)
    fig.tight_layout()
    write_file(path, lambda tmp: fig.savefig(tmp, dpi=DPI))   # whole or not at all
    return path
