"""PNG plots of a run (matplotlib, Agg backend; no display needed).

- ``fold_angles.png``: fold angle of each hinge (degrees) vs time (s), with its stop angle and the time it
  latched there (the structure unit's latch time, the deployment time of a single hinge);
- ``probe_displacements.png``: displacement of each probe from its initial position (m), per
  global component, vs time (s);
- ``probe_velocities.png`` and ``probe_accelerations.png``: each probe's global velocity (m/s) and acceleration
  (m/s^2), per global component, vs time (s), as the structure unit outputs them;
- ``strain_gauges.png`` (scenes with strain gauges): surface strain of each gauge (microstrain) vs time (s);
- ``energy_residual.png``: the energy balance, the change of the energy since t = 0 (E - E_0), the external work
  (the point loads' and Q's since t = 0) and their difference E - E_0 - W (J; zero but for damping, driven motions
  and the integrator's drift, the numerator of summary.json's ``energy_drift``), or the energy alone where no
  external work is recorded, and the constraint residual (log scale) vs time (s), with the joints' monitors
  (``<joint>_point_mismatch`` m, ``_axis_product`` / ``_axis_error``) in the residual panel;
- ``lift_coefficient.png`` (aero scenes): lift coefficient CL (-) and lift (N) vs time (s);
- ``wake_3d.png`` (aero scenes): a 3D view of the wing and its wake at 4 instants, drawn by replaying the
  aero unit in-process with the recorded inputs (``orchestrator.output.wake_view``; capped in wall time);
- ``mechanism.png``: the bodies' reference lines at 5 instants from t = 0 to the end, from the structure
  coordinates the master recorded (``orchestrator.output.mechanism_view``), in the mechanism's plane when it is
  planar, else in 3D;
- ``planform.png`` (aero scenes): the planform and vortex lattice of each body as designed, unfolded
  (``orchestrator.output.planform_view``).

A failure of one of the three pictures prints a warning and never affects the other plots or the run's status.

Layout: matplotlib's constrained layout, so titles (wrapped at ``TITLE_CHARS`` characters) and axis labels are
never clipped; a legend of more than ``LEGEND_INSIDE`` entries goes outside the axes, right of them, so it covers
neither the title nor the curves. A panel whose every curve is zero (or has no finite value) over the run says so
in a note at its centre (``note_flat_panels``), so that an empty-looking panel is not taken for a missing one.

A plot that does not apply (no hinge, no probe, no sample) is not written, and a stale file of
that name from an earlier run in the same folder is removed. Each PNG is written to a temporary name in the
folder and renamed (``orchestrator.files.write_file``): a PNG under its own name is complete. `wingsim run` draws
the files in forked processes at once on Linux, one per CPU it may use (`plot_workers`; the same bytes as in turn).
"""

from __future__ import annotations

import importlib
import multiprocessing
import os
import sys
import textwrap
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from orchestrator.files import write_file
from orchestrator.run.master import RunResult
from orchestrator.scene.load import hinge_joints

PLOT_FILES = ("fold_angles.png", "probe_displacements.png", "probe_velocities.png", "probe_accelerations.png",
              "strain_gauges.png", "energy_residual.png", "lift_coefficient.png")
DPI = 120
TITLE_CHARS = 64
"""Titles are wrapped at this many characters, which fit the 7-inch-wide figures at the default font size."""
LEGEND_INSIDE = 4
"""A legend of more entries than this is placed outside the axes."""
LEGEND_FONT = 8
FLAT_NOTE = "zero throughout the run"
NO_VALUE_NOTE = "no finite value in the run"


def _title(result: RunResult, what: str) -> str:
    status = "" if result.status == "ok" else f" ({result.status} at t = {result.simulated_time_s:.4g} s)"
    return textwrap.fill(f"{result.scene['name']}: {what}{status}", TITLE_CHARS)


def _figure(width: float, height: float) -> Figure:
    """A figure with constrained layout (titles, labels and outside legends kept within it)."""
    return Figure(figsize=(width, height), layout="constrained")


def legend(fig: Figure, ax) -> None:
    """The legend of ``ax``'s labelled artists: inside it (best place) up to LEGEND_INSIDE entries, else outside
    the figure's axes on the right, in columns of at most 20 entries."""
    handles, labels = ax.get_legend_handles_labels()
    if not handles:
        return
    if len(handles) <= LEGEND_INSIDE:
        ax.legend(fontsize=LEGEND_FONT)
    else:
        fig.legend(handles, labels, loc="outside right upper", fontsize=LEGEND_FONT, ncols=-(-len(handles) // 20))


def note_flat_panels(fig: Figure, no_value: str = NO_VALUE_NOTE) -> None:
    """Write FLAT_NOTE (``no_value``) at the centre of each 2D axis of ``fig`` whose every line is zero (has no
    finite value) at every sample."""
    for ax in fig.axes:
        if ax.name != "rectilinear" or not ax.lines:
            continue
        values = np.concatenate([np.asarray(line.get_ydata(), dtype=float).ravel() for line in ax.lines])
        finite = values[np.isfinite(values)]
        note = no_value if finite.size == 0 else FLAT_NOTE if not finite.any() else None
        if note is not None:
            ax.text(0.5, 0.5, note, transform=ax.transAxes, ha="center", va="center", fontsize=10, color="0.3",
                    bbox={"boxstyle": "round", "facecolor": "white", "edgecolor": "0.6", "alpha": 0.9})


def fold_angles_figure(result: RunResult) -> Figure | None:
    series = result.series
    if not series.hinge_names:
        return None
    stops = {j["name"]: j["stop_angle_deg"] for j in hinge_joints(result.scene)}
    fig = _figure(7, 4)
    ax = fig.add_subplot()
    for i, hinge in enumerate(series.hinge_names):
        line, = ax.plot(series.time, series.fold_angles_deg[:, i], label=hinge)
        if stops.get(hinge) is not None:
            ax.axhline(stops[hinge], color=line.get_color(), linestyle=":", label=f"{hinge} stop")
            if hinge in result.latch_times:
                latched = result.latch_times[hinge]
                ax.plot([latched], [stops[hinge]], "o", color=line.get_color(),
                        label=f"{hinge} latched, {latched:.4g} s")
    ax.set(title=_title(result, "fold angles"), xlabel="time (s)", ylabel="fold angle (deg)")
    ax.grid(True, alpha=0.3)
    legend(fig, ax)
    return fig


def probe_displacements_figure(result: RunResult) -> Figure | None:
    series = result.series
    if not series.probe_names:
        return None
    positions = series.positions                               # (samples, probes, 3), m
    return _probe_figure(result, positions - positions[:1], "probe displacement from initial position", "d{} (m)")


def probe_velocities_figure(result: RunResult) -> Figure | None:
    return _probe_figure(result, result.series.velocities, "probe velocity", "v{} (m/s)")


def probe_accelerations_figure(result: RunResult) -> Figure | None:
    return _probe_figure(result, result.series.accelerations, "probe acceleration", "a{} (m/s^2)")


def _probe_figure(result: RunResult, values: np.ndarray, what: str, label: str) -> Figure | None:
    """One panel per global component of ``values`` (samples, probes, 3), a line per probe; None without a probe
    or a finite value (a series built without the probe's rates)."""
    series = result.series
    if not series.probe_names or not np.isfinite(values).any():
        return None
    fig = _figure(7, 7)
    axes = fig.subplots(3, 1, sharex=True)
    for c, (ax, axis) in enumerate(zip(axes, "xyz")):
        for i, probe in enumerate(series.probe_names):
            ax.plot(series.time, values[:, i, c], label=probe)
        ax.set_ylabel(label.format(axis))
        ax.grid(True, alpha=0.3)
    axes[0].set_title(_title(result, f"{what} (global frame)"))
    legend(fig, axes[0])
    axes[-1].set_xlabel("time (s)")
    return fig


def strain_figure(result: RunResult) -> Figure | None:
    series = result.series
    if not series.strain_names:
        return None
    gauges = {g["name"]: g for g in result.scene["strain_gauges"]}
    fig = _figure(7, 4)
    ax = fig.add_subplot()
    for i, name in enumerate(series.strain_names):
        g = gauges.get(name, {})
        where = f" ({g['body']}, {1e3 * g['span']:g} mm)" if g else ""
        ax.plot(series.time, 1e6 * series.strains[:, i], label=name + where)
    ax.set(title=_title(result, "surface strain (bending curvature x distance to the surface)"),
           xlabel="time (s)", ylabel="strain (microstrain)")
    ax.grid(True, alpha=0.3)
    legend(fig, ax)
    return fig


def monitors_figure(result: RunResult) -> Figure:
    series = result.series
    fig = _figure(7, 6)
    energy_ax, residual_ax = fig.subplots(2, 1, sharex=True)
    energy, work = series.energy, series.external_work
    if np.isfinite(work).any():   # the balance: what the energy gained against the work done on the structure
        start = energy[np.isfinite(energy)][0] if np.isfinite(energy).any() else np.nan
        energy_ax.plot(series.time, energy - start, label=f"energy - E_0 (E_0 = {start:.4g} J)")
        energy_ax.plot(series.time, work, label="external work")
        energy_ax.plot(series.time, energy - start - work, linestyle="--", label="energy - E_0 - external work")
        energy_ax.set(ylabel="change since t = 0 (J)")
    else:
        energy_ax.plot(series.time, energy, label="energy")
        energy_ax.set(ylabel="energy (J)")
    energy_ax.set_title(_title(result, "energy balance and constraint residual"))
    legend(fig, energy_ax)
    residual = series.constraint_residual
    residual_ax.plot(series.time, residual, label="constraint residual")
    curves = [residual]
    for name in series.joint_names:      # the joints' own conditions, on the same (log) scale
        curves.append(np.abs(series.column(name)))
        residual_ax.plot(series.time, curves[-1], label=name)
    if any(np.any(np.isfinite(c) & (c > 0)) for c in curves):
        residual_ax.set_yscale("log")
    if series.joint_names:
        legend(fig, residual_ax)
    residual_ax.set(xlabel="time (s)", ylabel="residual, joint monitors (-, m)")
    for ax in (energy_ax, residual_ax):
        ax.grid(True, alpha=0.3)
    return fig


def lift_figure(result: RunResult) -> Figure | None:
    series = result.series
    if not series.has_aero:
        return None
    fig = _figure(7, 6)
    cl_ax, lift_ax = fig.subplots(2, 1, sharex=True)
    cl_ax.plot(series.time, series.CL)
    model = result.scene["aero"]["model"]
    cl_ax.set(title=_title(result, f"lift coefficient ({model})"), ylabel="CL (-)")
    lift_ax.plot(series.time, series.lift)
    lift_ax.set(xlabel="time (s)", ylabel="lift (N)")
    for ax in (cl_ax, lift_ax):
        ax.grid(True, alpha=0.3)
    return fig


PICTURES = (("wake_view", "wake_3d.png", "wake"), ("mechanism_view", "mechanism.png", "mechanism"),
            ("planform_view", "planform.png", "planform"))
"""The pictures of `write_plots` beside the figures of PLOT_FILES: (module of orchestrator.output, file, what)."""
FORKS = sys.platform.startswith("linux")
"""Whether `write_plots` may draw in forked workers here (`plot_workers`)."""
FIGURES = (fold_angles_figure, probe_displacements_figure, probe_velocities_figure, probe_accelerations_figure,
           strain_figure, monitors_figure, lift_figure)
"""The figure of each of PLOT_FILES, in its order."""


def plot_workers() -> int:
    """Processes `write_plots` may draw in at once here: the CPUs this process may run on, on Linux (where a worker
    is a fork, which starts in milliseconds with everything imported); 1 elsewhere (a spawned worker would import
    matplotlib again, about as long as it draws, and a forked one is unsafe where system libraries hold threads)."""
    return len(os.sched_getaffinity(0)) if FORKS else 1


def write_plots(result: RunResult, out_dir: Path, workers: int = 1) -> list[Path]:
    """Write the plots that apply into ``out_dir``; returns the paths written.

    Each file is drawn whole by one process: with ``workers`` > 1 (on Linux: see `plot_workers`) in that many
    forked processes at once, the same files, byte for byte, in about 1/workers of the time (the figures and
    pictures take 0.2-0.6 s each). A figure's failure raises (in the workers too: the first in PLOT_FILES' order);
    a picture's prints a warning, in the order of PICTURES.

    Args:
        result: the run's RunResult.
        out_dir: the folder; made if missing.
        workers: processes drawing at once: 1, here in turn; more, forked workers (Linux only).
    """
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    tasks = [(_write_figure, index) for index in range(len(PLOT_FILES))]
    tasks += [(_write_picture, index) for index in range(len(PICTURES))]
    if workers > 1:
        if not FORKS:
            raise ValueError(f"write_plots: workers={workers} needs Linux's fork; 1 draws here in turn")
        # the workers are forks: they hold the result and the imports already; only an index crosses to them
        pool = ProcessPoolExecutor(min(workers, len(tasks)), mp_context=multiprocessing.get_context("fork"),
                                   initializer=_hold, initargs=(result, out_dir))
        try:
            # the pictures (the last tasks) first, the slowest (0.3-0.6 s): no worker is left alone with one at the end
            order = [*range(len(PLOT_FILES), len(tasks)), *range(len(PLOT_FILES))]
            futures = {k: pool.submit(_task, *tasks[k]) for k in order}
            outcomes = [futures[k].result() for k in range(len(tasks))]
        finally:        # a failed figure or an interrupt: the files not begun are not drawn
            pool.shutdown(cancel_futures=True)
    else:
        outcomes = [task(result, out_dir, index) for task, index in tasks]
    written = []
    for path, warning in outcomes:
        if warning:
            print(warning, file=sys.stderr)
        if path is not None:
            written.append(path)
    return written


_HELD = None
"""(RunResult, out_dir) of a forked plot worker (`_hold`)."""


def _hold(result: RunResult, out_dir: Path) -> None:
    """A plot worker's initializer: keep the run's result and folder (inherited through the fork, not pickled)."""
    global _HELD
    _HELD = (result, out_dir)


def _task(task, index: int):
    """A plot worker's task: `task` (_write_figure or _write_picture) on the held result."""
    return task(*_HELD, index)


def _write_figure(result: RunResult, out_dir: Path, index: int) -> tuple[Path | None, str]:
    """Draw PLOT_FILES[index] into out_dir, or remove a stale one where it does not apply; (its path or None, "")."""
    path = out_dir / PLOT_FILES[index]
    fig = None if len(result.series) == 0 else FIGURES[index](result)
    if fig is None:
        path.unlink(missing_ok=True)
        return None, ""
    FigureCanvasAgg(fig)
    note_flat_panels(fig)
    write_file(path, lambda tmp: fig.savefig(tmp, dpi=DPI))   # whole or not at all
    return path, ""


def _write_picture(result: RunResult, out_dir: Path, index: int) -> tuple[Path | None, str]:
    """Draw PICTURES[index] into out_dir: (its path, or None where it does not apply, ""), or (None, the warning)
    where it fails (the pictures are a courtesy: a failure never fails the run or the other plots)."""
    module, filename, what = PICTURES[index]
    try:
        return getattr(importlib.import_module(f"orchestrator.output.{module}"), f"write_{module}")(result, out_dir), ""
    except Exception as err:
        (out_dir / filename).unlink(missing_ok=True)  # no stale picture of an earlier run
        return None, f"warning: {what} picture not written: {type(err).__name__}: {err}"
