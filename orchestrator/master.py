"""The run loop for structure-only scenes (``aero.model = "none"``).

Steps the structure unit from t = 0 to ``time.stop`` with the communication step ``coupling.step``
(the last step shortened to land on ``time.stop``), holding the generalized force Q = 0, and records
at every communication point: probe global positions (m), fold angles (degrees), energy (J), kinetic
energy (J) and constraint residual. A failure never loses the samples recorded before it.

The unit interface (``orchestrator.units``): ``make_unit(kind, scene, backend, fmu_dir)`` returns a
unit with ``n``, ``get_outputs() -> (e, de)``, ``set_inputs(Q)``, ``do_step(t, h)`` (raises
``UnitError`` on an FMI error or discard, with the unit's logged reason), ``monitors()`` (``energy``,
``kinetic_energy``, ``constraint_residual``, ``fold_angles_deg``) and ``terminate()``.
"""

from __future__ import annotations

import importlib
import logging
import math
import time as _time
from dataclasses import dataclass
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np

from orchestrator.progress import Progress
from orchestrator.scene import hinge_joints
from orchestrator.timeseries import TimeSeries
from structure_fmu.errors import SolverDiverged

log = logging.getLogger(__name__)

STATUSES = ("ok", "diverged", "error")


@dataclass
class RunResult:
    """Outcome of one run: what ``summary.json`` and ``timeseries.csv`` are written from."""

    status: str               # "ok" | "diverged" | "error"
    message: str
    wall_time_s: float        # s, from unit start-up to the end of the run
    simulated_time_s: float   # s, last communication point reached
    scene: dict               # the resolved scene
    series: TimeSeries


def communication_times(stop: float, step: float) -> np.ndarray:
    """Communication points 0, h, 2h, ..., stop (s); the last interval is shortened to land on stop."""
    n = max(1, math.ceil(stop / step - 1e-9))
    times = np.arange(n + 1, dtype=float) * step
    times[-1] = stop
    return times


def new_series(scene: dict) -> TimeSeries:
    """An empty series with the scene's probe and hinge columns."""
    return TimeSeries([p["name"] for p in scene["probes"]], [j["name"] for j in hinge_joints(scene)])


def _record(series: TimeSeries, unit: Any, topology: Any, probes: list[dict], t: float) -> None:
    e, _ = unit.get_outputs()
    positions = np.array([topology.point_position(e, p["body"], p["span"], p["chord"]) for p in probes],
                         dtype=float).reshape(len(probes), 3)
    monitors = unit.monitors()
    series.append(t, positions, monitors.get("fold_angles_deg", {}),
                  monitors.get("energy", np.nan), monitors.get("constraint_residual", np.nan),
                  kinetic_energy=monitors.get("kinetic_energy", np.nan))


def _classify(err: BaseException, unit_error: type, phase: str) -> tuple[str, str]:
    """(status, message) for a failure during ``phase``."""
    diverged = getattr(err, "diverged", False) or "diverged" in str(err)
    if isinstance(err, (unit_error, SolverDiverged)) and diverged:
        return "diverged", str(err)
    if isinstance(err, KeyboardInterrupt):
        return "error", f"interrupted by the user during {phase}"
    if isinstance(err, unit_error):
        return "error", f"{phase}: {err}"
    return "error", f"{phase}: {type(err).__name__}: {err}"


def run_scene(scene: dict, backend: str = "fmu", fmu_dir: Path | None = None,
              progress: Progress | None = None, units: ModuleType | Any = None,
              topology: Any = None) -> RunResult:
    """Run a structure-only scene; never raises for a failure of the unit, returns its status.

    ``units`` (default ``orchestrator.units``) provides ``make_unit`` and ``UnitError``;
    ``topology`` (default ``Topology.from_scene(scene)``) maps coordinates to probe positions.
    Both are parameters so that the loop can be tested without the physics.
    """
    start = _time.perf_counter()
    if units is None:
        units = importlib.import_module("orchestrator.units")  # lazy: loads fmpy and the slaves
    if topology is None:
        from structure_fmu.topology import Topology  # lazy: the physics package

        topology = Topology.from_scene(scene)
    series = new_series(scene)
    stop = scene["time"]["stop"]
    status, message, reached = "ok", "", 0.0
    unit = None
    phase = "starting the structure unit"
    try:
        unit = units.make_unit(kind="structure", scene=scene, backend=backend, fmu_dir=fmu_dir)
        if unit.n != topology.n_coordinates:
            raise RuntimeError(f"the unit has {unit.n} coordinates but the scene's topology has "
                               f"{topology.n_coordinates}: rebuild the FMUs (wingsim build)")
        q = np.zeros(unit.n)
        times = communication_times(stop, scene["coupling"]["step"])
        phase = "reading the initial outputs"
        _record(series, unit, topology, scene["probes"], times[0])
        for t0, t1 in zip(times[:-1], times[1:]):
            phase = f"the step from t = {t0:.6g} s"
            unit.set_inputs(q)
            unit.do_step(t0, t1 - t0)
            _record(series, unit, topology, scene["probes"], t1)
            reached = t1
            if progress is not None:
                progress.update(t1)
        message = f"reached t = {stop:g} s in {len(times) - 1} communication steps"
    except (Exception, KeyboardInterrupt) as err:
        log.debug("run failed during %s", phase, exc_info=True)
        status, message = _classify(err, units.UnitError, phase)
    finally:
        if unit is not None:
            try:
                unit.terminate()
            except Exception as err:  # the samples are already recorded: report, keep the status
                message += f" (terminating the unit failed: {err})"
    if progress is not None:
        progress.finish(reached, status)
    return RunResult(status, message, _time.perf_counter() - start, float(reached), scene, series)
