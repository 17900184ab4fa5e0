"""Write a run's ``summary.json`` and ``timeseries.csv``, also for a failed run.

Write order, so that a full disk or a killed process loses at most the big files and always leaves a
summary (at worst the one written before the run):
``check_out_dir`` refuses an output folder that cannot be written before anything runs;
``write_started`` writes a summary with status "running" and the resolved scene before the run; at the end
``write_results`` replaces it with the final summary, then writes ``timeseries.csv`` (the plots come after).
Each file is written to a temporary name in the folder and renamed (``orchestrator.files.write_file``), so a
file that exists is complete (a failed write leaves the previous summary in place). A failed write raises
``WriteError`` naming the file and the cause.

Summary fields (SI units, angles in degrees):

- ``status`` ("ok" | "diverged" | "error" | "interrupted" (Ctrl-C or SIGTERM); "running" only in the summary
  written before the run, which a run that was killed leaves behind), ``message``, ``wall_time_s`` (s, the
  whole run: loading the units included), ``stepping_wall_time_s`` (s, the communication steps alone, null
  if none ran; over ``simulated_time_s`` it is the real-time factor), ``simulated_time_s``, ``scene`` (the
  resolved scene, after ``--set``);
- ``deployment_time_s``: the time, s, at which every hinge that has a ``stop_angle_deg`` has latched
  (for a single hinge: the first time its fold angle reaches the stop, from either side), as the
  structure unit reports it (output ``latch_time_<hinge>``: interpolated within its internal step, not
  between communication points, where the latch has already arrested the fold); null if a hinge never
  latches or no hinge has a stop;
- ``max_constraint_residual``: the largest constraint residual over the run;
- ``structure_counts``: the size of the structural equations (``orchestrator.output.structure_counts``):
  ``fidelity``, ``coordinates`` (n_q, the generalized coordinates the integrator advances, after pins and
  prescribed motions have eliminated theirs), ``exchanged_coordinates`` (n, the unit's E: 9 per node) and
  ``constraint_rows`` (m, the constraint rows it solves, redundant rows of planar rigid loops left out; 0: an
  ODE); derived from the resolved scene by the structure unit's own construction, not by running it; null
  only for a failed run whose structure could not be built (its message says why);
- ``energy_drift``: (E_final - E_0 - W_external) / max(|E_0|, max over the run of the kinetic energy,
  1e-12 J), with E_0 and E_final the first and last samples with a finite energy and external work,
  W_external the work the structure unit integrated over the same span (``external_work``: the point loads
  and the aerodynamic Q, trapezoidal over the internal steps), and the kinetic energy taken over those
  samples (NaN samples ignored); null when no sample has both. It is the energy that no load accounts for:
  the numerical drift of the integrator, plus the work of damping (always negative) and of driven motions
  (prescribed clamps and laws, which the unit does not count), so a driven conservative structure reports
  its numerical drift, not the work of its loads. The peak kinetic energy is the scale of the energy the
  structure exchanges, so the drift stays meaningful when E_0 = 0 (e.g. a pendulum released at rest at
  its potential datum); the 1e-12 J floor only avoids a division by zero for a structure at rest;
- ``probes``: per probe ``initial`` and ``final`` global position [x, y, z] (m) and per-component
  ``min_displacement`` / ``max_displacement`` [dx, dy, dz] (m) relative to the initial position;
- ``strain_gauges`` (only for a scene with strain gauges): per gauge ``min``, ``max`` (-), ``peak`` (the
  largest |strain|, -) and ``peak_time_s`` (s) over the samples;
- ``joint_monitors`` (only for a scene with joints between bodies): per joint monitor column the largest
  |value| over the samples (m for ``_point_mismatch``, - for ``_axis_product`` and ``_axis_error``);
- ``aero`` (only for a scene with an aero unit): ``model``, ``CL_final``, ``CL_min``, ``CL_max`` (-) and
  ``lift_final`` (N) over the samples after t = 0 (at t = 0 no circulation has been shed yet), and for a scene
  with hinges ``hinge_moments``: per hinge ``final``, ``min``, ``max`` (N m) of the aerodynamic moment about its
  axis (the aero unit's ``hinge_moment_<hinge>``) over the same samples;
- ``coupling`` (only for an implicitly coupled aero scene): ``algorithm``, ``acceleration``,
  ``total_iterations`` (over the accepted communication steps), ``max_iterations_used`` (in one step) and
  ``max_residual`` (the largest accepted relative interface residual, -).

Values that do not apply, or are NaN/inf, are written as null (the JSON stays strict).
"""

from __future__ import annotations

import json
import math
import os
import tempfile
import warnings
from pathlib import Path
from typing import Any

import numpy as np

from fmu_common.errors import SceneError
from orchestrator.files import WriteError, write_file
from orchestrator.output.column_units import column_units, header_cell, split_header_cell
from orchestrator.output.structure_counts import structure_counts
from orchestrator.run.master import RunResult, new_series
from orchestrator.scene.load import hinge_joints
from orchestrator.run.timeseries import TimeSeries

SUMMARY_FIELDS = ("status", "message", "wall_time_s", "stepping_wall_time_s", "simulated_time_s", "scene",
                  "deployment_time_s", "max_constraint_residual", "structure_counts", "energy_drift", "probes")
"""The fields of every summary; a scene with strain gauges adds STRAIN_FIELD, an aero scene AERO_FIELD, an
implicitly coupled one COUPLING_FIELD."""
STRAIN_FIELD = "strain_gauges"
AERO_FIELD = "aero"
COUPLING_FIELD = "coupling"
SUMMARY_FILE = "summary.json"
TIMESERIES_FILE = "timeseries.csv"
RUNNING = "running"
"""Status of the summary written before the run; the end of the run replaces it with "ok", "diverged" or
"error"."""
ENERGY_FLOOR_J = 1e-12
"""Smallest energy scale (J) the energy drift is relative to, so that a structure at rest with E_0 = 0
does not divide by zero."""


def latching_hinges(scene: dict) -> list[str]:
    """Names of the scene's hinges that have a stop angle (they latch there), in scene order."""
    return [j["name"] for j in hinge_joints(scene) if j.get("stop_angle_deg") is not None]   # resolved: None


def deployment_time(latch_times: dict[str, float], scene: dict) -> float | None:
    """Time (s) at which every hinge with a stop angle has latched, from the structure unit's latch times
    {hinge: s} (``RunResult.latch_times``); None if one has not or no hinge has a stop."""
    stops = latching_hinges(scene)
    if not stops or any(h not in latch_times for h in stops):
        return None
    return float(max(latch_times[h] for h in stops))


def energy_drift(energy: np.ndarray, kinetic_energy: np.ndarray | None, external_work: np.ndarray | None
                 ) -> float | None:
    """(E_final - E_0 - W_external) / max(|E_0|, max kinetic energy, ENERGY_FLOOR_J), or None without a sample
    whose energy and external work are finite.

    E_0 and E_final are the first and last samples of ``energy`` (J) at which the external work (J, since the
    start, one value per energy sample) is finite too, W_external its change between them; None for the work:
    no load acts (W_external = 0). The kinetic energy (J, one value per energy sample, or None) counts over
    those samples, NaN values ignored.
    """
    energy = np.asarray(energy, dtype=float)
    work = np.zeros_like(energy) if external_work is None else np.asarray(external_work, dtype=float)
    finite = np.isfinite(energy) & np.isfinite(work)
    if not finite.any():
        return None
    e, w = energy[finite], work[finite]
    scale = max(abs(e[0]), ENERGY_FLOOR_J)
    if kinetic_energy is not None:
        kinetic = np.asarray(kinetic_energy, dtype=float)[finite]
        kinetic = kinetic[np.isfinite(kinetic)]
        if kinetic.size:
            scale = max(scale, float(kinetic.max()))
    return float((e[-1] - e[0] - (w[-1] - w[0])) / scale)


def largest_magnitude(values: np.ndarray) -> float | None:
    """The largest finite |value|, or None without one."""
    finite = np.abs(values[np.isfinite(values)])
    return float(finite.max()) if finite.size else None


def max_constraint_residual(residual: np.ndarray) -> float | None:
    """Largest residual over the run (NaN samples ignored), or None."""
    values = np.asarray(residual, dtype=float)
    values = values[~np.isnan(values)]
    return float(values.max()) if values.size else None


def probe_summary(series: TimeSeries) -> dict[str, dict[str, Any]]:
    """Per probe: initial, final position and min/max displacement per component (m)."""
    if len(series) == 0:
        keys = ("initial", "final", "min_displacement", "max_displacement")
        return {p: dict.fromkeys(keys) for p in series.probe_names}
    positions = series.positions                      # (samples, probes, 3)
    displacement = positions - positions[:1]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # an all-NaN component gives NaN, written null
        low, high = np.nanmin(displacement, axis=0), np.nanmax(displacement, axis=0)
    return {
        p: {"initial": positions[0, i].tolist(), "final": positions[-1, i].tolist(),
            "min_displacement": low[i].tolist(), "max_displacement": high[i].tolist()}
        for i, p in enumerate(series.probe_names)
    }


def strain_summary(series: TimeSeries) -> dict[str, dict[str, Any]]:
    """Per strain gauge: min, max, peak (largest |strain|) (-) and the time of the peak (s)."""
    out = {}
    strains, time = series.strains, series.time          # each builds the whole table: once
    for name, strain in zip(series.strain_names, strains.T):
        finite = np.isfinite(strain)
        if not finite.any():
            out[name] = dict.fromkeys(("min", "max", "peak", "peak_time_s"))
            continue
        k = int(np.argmax(np.where(finite, np.abs(strain), -np.inf)))
        out[name] = {"min": float(strain[finite].min()), "max": float(strain[finite].max()),
                     "peak": float(abs(strain[k])), "peak_time_s": float(time[k])}
    return out


def aero_summary(series: TimeSeries, scene: dict) -> dict[str, Any]:
    """model, CL_final, CL_min, CL_max (-) and lift_final (N) over the samples after the first; with hinges,
    hinge_moments {hinge: {final, min, max} N m}."""
    keys = ("CL_final", "CL_min", "CL_max", "lift_final")
    out: dict[str, Any] = {"model": scene["aero"]["model"], **dict.fromkeys(keys)}
    if series.hinge_moment_names:
        out["hinge_moments"] = {h: _extremes(series.hinge_moments[1:, i]) for i, h in enumerate(series.hinge_names)}
    if len(series) < 2:
        return out
    cl, lift = series.CL[1:], series.lift[1:]
    finite = cl[np.isfinite(cl)]
    out.update(CL_final=cl[-1], lift_final=lift[-1])
    if finite.size:
        out.update(CL_min=finite.min(), CL_max=finite.max())
    return out


def _extremes(values: np.ndarray) -> dict[str, Any]:
    """final, min and max of samples (min and max of the finite ones; None where there are none)."""
    finite = values[np.isfinite(values)]
    return {"final": values[-1] if values.size else None, "min": finite.min() if finite.size else None,
            "max": finite.max() if finite.size else None}


def coupling_summary(series: TimeSeries, scene: dict) -> dict[str, Any]:
    """algorithm, acceleration, total_iterations, max_iterations_used, max_residual over the steps after t = 0."""
    coupling = scene["coupling"]
    out: dict[str, Any] = {"algorithm": coupling["algorithm"], "acceleration": coupling["acceleration"],
                           "total_iterations": 0, "max_iterations_used": None, "max_residual": None}
    if len(series) < 2:
        return out
    iterations = series.column("coupling_iterations")[1:]
    residual = series.column("coupling_residual")[1:]
    out.update(total_iterations=int(np.nansum(iterations)), max_iterations_used=int(np.nanmax(iterations)),
               max_residual=float(np.nanmax(residual)) if np.isfinite(residual).any() else None)
    return out


def run_structure_counts(result: RunResult) -> dict[str, Any] | None:
    """`structure_counts` of the run's scene; None for a run that failed and whose structure cannot be built
    (the run's message says why). A run that ran built the same structure, so its counts cannot fail."""
    try:
        return structure_counts(result.scene)
    except Exception:
        if result.status in ("ok", "diverged"):
            raise
        return None


def summarize(result: RunResult) -> dict[str, Any]:
    """The summary.json content (SUMMARY_FIELDS, STRAIN_FIELD for a scene with strain gauges, AERO_FIELD
    for an aero scene, COUPLING_FIELD for an implicitly coupled one), JSON-safe."""
    series = result.series
    summary = {
        "status": result.status,
        "message": result.message,
        "wall_time_s": result.wall_time_s,
        "stepping_wall_time_s": result.stepping_wall_time_s,
        "simulated_time_s": result.simulated_time_s,
        "scene": result.scene,
        "deployment_time_s": deployment_time(result.latch_times, result.scene),
        "max_constraint_residual": max_constraint_residual(series.constraint_residual),
        "structure_counts": run_structure_counts(result),
        "energy_drift": energy_drift(series.energy, series.kinetic_energy, series.external_work),
        "probes": probe_summary(series),
    }
    if series.strain_names:
        summary[STRAIN_FIELD] = strain_summary(series)
    if series.joint_names:
        summary["joint_monitors"] = {name: largest_magnitude(series.column(name)) for name in series.joint_names}
    if series.has_aero:
        summary[AERO_FIELD] = aero_summary(series, result.scene)
    if series.has_coupling:
        summary[COUPLING_FIELD] = coupling_summary(series, result.scene)
    return json_safe(summary)


def json_safe(value: Any) -> Any:
    """Plain Python types for JSON: numpy scalars/arrays converted, NaN and inf as None."""
    if isinstance(value, dict):
        return {str(k): json_safe(v) for k, v in value.items()}
    if isinstance(value, (list, tuple, np.ndarray)):
        return [json_safe(v) for v in value]
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        return float(value) if math.isfinite(value) else None
    return value


class OutFolderError(SceneError):
    """An output folder (``--out``) that cannot be written: a file, below a file, or not writable. Raised
    before anything runs (exit 2); the message names the option, the path and why."""

    def __init__(self, option: str, path: Path, why: str):
        ValueError.__init__(self, f"{option} {str(path)!r}: {why}")
        self.key, self.value, self.allowed = option, str(path), why


def check_out_dir(path: Path, option: str = "--out") -> Path:
    """Create the folder ``path`` (and its parents) if missing and check that a file can be created in it
    (by creating and removing one: permission bits alone do not tell, e.g. for root or a read-only mount);
    returns ``path``. OutFolderError naming ``option``, the path and why, before anything runs."""
    path = Path(path)
    for existing in (path, *path.parents):
        if existing.exists():
            if not existing.is_dir():
                why = ("is a file; give a folder (it is created if missing)" if existing == path else
                       f"is below {str(existing)!r}, which is a file, not a folder")
                raise OutFolderError(option, path, why)
            break
    try:
        path.mkdir(parents=True, exist_ok=True)
        handle, probe = tempfile.mkstemp(prefix=".wingsim-probe-", dir=path)
        os.close(handle)
        os.unlink(probe)
    except OSError as err:
        raise OutFolderError(option, path, f"cannot write there: {err.strerror or err}") from err
    return path


def write_timeseries(series: TimeSeries, path: Path) -> None:
    """CSV with a header row (``time [s]`` first: each column's name and unit, ``column_units``) and one row per
    sample; NaN written as ``nan``."""
    header = ",".join(header_cell(name, unit) for name, unit in column_units(series).items())
    np.savetxt(path, series.table(), delimiter=",", header=header, comments="", fmt="%.12g")


def read_timeseries(path: Path) -> tuple[np.ndarray, dict[str, str]]:
    """A ``timeseries.csv`` read back: (samples, {column: unit}), the samples a numpy structured array with one
    float field per column named as the column (``time``, ``tip_z``, ...), shape (samples,). A header cell
    without a unit (a file written before the header carried units) gets the unit ``""``."""
    with Path(path).open() as handle:
        cells = handle.readline().rstrip("\n").split(",")
        lines = handle.read().splitlines()
    names, units = zip(*(split_header_cell(cell) for cell in cells))
    rows = np.loadtxt(lines, delimiter=",", ndmin=2).reshape(-1, len(names)) if lines else np.empty((0, len(names)))
    samples = np.empty(len(rows), dtype=[(name, float) for name in names])
    for k, name in enumerate(names):
        samples[name] = rows[:, k]
    return samples, {name: unit or "" for name, unit in zip(names, units)}


def write_summary(result: RunResult, path: Path, summary: dict | None = None) -> None:
    """``summary`` (default ``summarize(result)``) as strict JSON; WriteError naming the file."""
    text = json.dumps(summary if summary is not None else summarize(result), indent=2, allow_nan=False) + "\n"
    write_file(Path(path), lambda tmp: tmp.write_text(text))


def write_started(scene: dict, out_dir: Path, message: str = "the run has started") -> Path:
    """The summary written before a run: status "running", the resolved scene, no figures yet."""
    path = Path(out_dir) / SUMMARY_FILE
    write_summary(RunResult(RUNNING, message, 0.0, 0.0, scene, new_series(scene)), path)
    return path


def write_results(result: RunResult, out_dir: Path) -> list[Path]:
    """Write ``summary.json``, then ``timeseries.csv``, into ``out_dir`` (created); returns the paths.

    WriteError names the file that could not be written. When ``timeseries.csv`` fails, the summary's
    message says so (if the summary can still be rewritten)."""
    out_dir = Path(out_dir)
    summary_path, csv_path = out_dir / SUMMARY_FILE, out_dir / TIMESERIES_FILE
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise WriteError(summary_path, err) from err
    summary = summarize(result)
    write_summary(result, summary_path, summary)
    try:
        write_file(csv_path, lambda tmp: write_timeseries(result.series, tmp))
    except WriteError as err:
        summary["message"] = f"{summary['message']} ({TIMESERIES_FILE} not written: {err.cause.strerror or err.cause})"
        try:
            write_summary(result, summary_path, summary)
        except WriteError:
            pass   # the summary written above stands; the error below names the missing file
        raise
    return [csv_path, summary_path]
