"""The run loop: the structure unit alone, or coupled with the aero unit.

Steps the units from t = 0 to ``time.stop`` with the communication step ``coupling.step`` (the last
step shortened to land on ``time.stop``) and records at every communication point: probe global
positions (m), fold angles (degrees), energy (J), kinetic energy (J), constraint residual and, with an
aero unit, the lift coefficient CL (-) and the lift (N). A failure never loses the samples recorded
before it.

Structure only (``aero.model = "none"``): the generalized force Q = 0 is held.

With an aero unit, explicit coupling at the same communication points (DESIGN §6); before the run both
units' ``topology_hash`` must agree, else the run is refused (status "error") before any step.

- ``gauss-seidel`` (staggered, the default): for each step [t, t + h]: the structure steps with the Q
  of the aero unit at t; the aero unit then steps with the structure's new e, de at t + h, and its Q
  at t + h is held for the next structure step. At t = 0 the aero unit gets the structure's initial
  e, de and its Q is its initial output (zero: no circulation yet). A prescribed-motion structure
  ignores Q, but Q is still passed (and checked by the structure unit).
- ``jacobi``: both units step from the outputs at t (the aero unit with e, de of t held), then exchange.

The unit interface (``orchestrator.units``): ``make_unit(kind, scene, backend, fmu_dir)`` returns a
unit with ``n``, ``topology_hash``, ``get_outputs()`` (structure: ``(e, de)``; aero: ``(Q,)``),
``set_inputs(...)`` (structure: ``Q``; aero: ``e, de``), ``do_step(t, h)`` (raises ``UnitError`` on an
FMI error or discard, with the unit's logged reason), ``monitors()`` (structure: ``energy``,
``kinetic_energy``, ``constraint_residual``, ``fold_angles_deg``; aero: ``CL``, ``lift``, ...) and
``terminate()``.

With an aero unit the run also keeps, in memory, the inputs of every aero step (``AeroInputs``: t, h, e, de
as the aero unit was given them), so that the aero unit can be replayed in-process after the run, e.g. for
the 3D picture of wing and wake (``orchestrator.wake_view``): with explicit coupling the aero unit's
state is a deterministic function of these inputs.
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
from orchestrator.timeseries import AERO_COLUMNS, TimeSeries
from structure_fmu.errors import SolverDiverged

log = logging.getLogger(__name__)

STATUSES = ("ok", "diverged", "error")
ALGORITHMS = ("gauss-seidel", "jacobi")


class CouplingError(RuntimeError):
    """The units cannot be connected (different topologies or sizes); raised before any step."""


@dataclass
class AeroInputs:
    """The aero unit's steps in order: each ``do_step(t, h)`` (s) with the e (m, 1) and de (m/s, 1/s),
    (n,) each, it held at that step. The tunable parameters were the unit's defaults (``run_scene`` sets
    none). Recording stops (``complete`` False) once ``max_values`` numbers are held (about 8 bytes each):
    a replay then covers only the recorded steps. Explicit coupling only: a master that repeats steps
    (implicit coupling, rollback) must record only the accepted iterate of each step."""

    t: list[float]
    h: list[float]
    e: list[np.ndarray]
    de: list[np.ndarray]
    complete: bool = True
    max_values: int = 20_000_000

    @classmethod
    def empty(cls) -> "AeroInputs":
        return cls([], [], [], [])

    def __len__(self) -> int:
        return len(self.t)

    def append(self, t: float, h: float, e: np.ndarray, de: np.ndarray) -> None:
        if not self.complete:
            return
        if (len(self.t) + 1) * 2 * len(e) > self.max_values:
            self.complete = False
            return
        self.t.append(float(t))
        self.h.append(float(h))
        self.e.append(np.array(e, dtype=float))
        self.de.append(np.array(de, dtype=float))


@dataclass
class RunResult:
    """Outcome of one run: what ``summary.json`` and ``timeseries.csv`` are written from."""

    status: str               # "ok" | "diverged" | "error"
    message: str
    wall_time_s: float        # s, from unit start-up to the end of the run
    simulated_time_s: float   # s, last communication point reached
    scene: dict               # the resolved scene
    series: TimeSeries
    aero_inputs: AeroInputs | None = None   # the aero unit's steps (aero scenes), for a replay


def communication_times(stop: float, step: float) -> np.ndarray:
    """Communication points 0, h, 2h, ..., stop (s); the last interval is shortened to land on stop."""
    n = max(1, math.ceil(stop / step - 1e-9))
    times = np.arange(n + 1, dtype=float) * step
    times[-1] = stop
    return times


def has_aero(scene: dict) -> bool:
    """True when the scene couples an aero unit (``aero.model`` is not "none")."""
    return scene.get("aero", {}).get("model", "none") != "none"


def new_series(scene: dict) -> TimeSeries:
    """An empty series with the scene's probe and hinge columns (and CL, lift for an aero scene)."""
    return TimeSeries([p["name"] for p in scene["probes"]], [j["name"] for j in hinge_joints(scene)],
                      aero=has_aero(scene))


def _record(series: TimeSeries, e: np.ndarray, structure: Any, aero: Any, topology: Any, probes: list[dict],
            t: float) -> None:
    positions = np.array([topology.point_position(e, p["body"], p["span"], p["chord"]) for p in probes],
                         dtype=float).reshape(len(probes), 3)
    monitors = structure.monitors()
    loads = None
    if aero is not None:
        aero_monitors = aero.monitors()
        loads = {name: aero_monitors.get(name, np.nan) for name in AERO_COLUMNS}
    series.append(t, positions, monitors.get("fold_angles_deg", {}),
                  monitors.get("energy", np.nan), monitors.get("constraint_residual", np.nan),
                  kinetic_energy=monitors.get("kinetic_energy", np.nan), aero=loads)


def check_connection(structure: Any, aero: Any) -> None:
    """CouplingError unless the two units carry the same structural topology (DESIGN §3)."""
    a, b = str(structure.topology_hash), str(aero.topology_hash)
    name = lambda unit, kind: getattr(unit, "label", kind)
    if a != b:
        raise CouplingError(
            f"the {name(structure, 'structure')} and {name(aero, 'aero')} units carry different structural "
            f"topologies (topology_hash {a} vs {b}): they were built from different scenes; rebuild both "
            "FMUs from one scene (wingsim build SCENE). Nothing was run.")
    if structure.n != aero.n:
        raise CouplingError(f"the structure unit has {structure.n} coordinates but the aero unit {aero.n}; "
                            "rebuild both FMUs from one scene (wingsim build SCENE). Nothing was run.")


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
    """Run a scene (structure alone or coupled with the aero unit); never raises for a failure of a
    unit, returns its status.

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
    algorithm = scene.get("coupling", {}).get("algorithm", "gauss-seidel")
    status, message, reached = "ok", "", 0.0
    structure = aero = None
    aero_inputs = AeroInputs.empty() if has_aero(scene) else None
    phase = "starting the structure unit"
    try:
        if has_aero(scene) and algorithm not in ALGORITHMS:
            raise CouplingError(f"coupling.algorithm = {algorithm!r} is not implemented; use one of "
                                f"{', '.join(ALGORITHMS)}")
        structure = units.make_unit(kind="structure", scene=scene, backend=backend, fmu_dir=fmu_dir)
        if structure.n != topology.n_coordinates:
            raise RuntimeError(f"the unit has {structure.n} coordinates but the scene's topology has "
                               f"{topology.n_coordinates}: rebuild the FMUs (wingsim build)")
        if has_aero(scene):
            phase = "starting the aero unit"
            aero = units.make_unit(kind="aero", scene=scene, backend=backend, fmu_dir=fmu_dir)
            phase = "connecting the structure and aero units"
            check_connection(structure, aero)
        q = np.zeros(structure.n)
        times = communication_times(stop, scene["coupling"]["step"])
        phase = "reading the initial outputs"
        e, de = structure.get_outputs()
        if aero is not None:
            aero.set_inputs(e, de)
            aero_e, aero_de = e, de                  # what the aero unit holds
            q, = aero.get_outputs()
        _record(series, e, structure, aero, topology, scene["probes"], times[0])
        for t0, t1 in zip(times[:-1], times[1:]):
            phase = f"the step from t = {t0:.6g} s"
            structure.set_inputs(q)
            if aero is not None and algorithm == "jacobi":
                aero.do_step(t0, t1 - t0)           # with e, de of t0, set at the end of the last step
                aero_inputs.append(t0, t1 - t0, aero_e, aero_de)
            structure.do_step(t0, t1 - t0)
            e, de = structure.get_outputs()
            if aero is not None:
                if algorithm == "jacobi":
                    q, = aero.get_outputs()
                    aero.set_inputs(e, de)
                    aero_e, aero_de = e, de
                else:                                # gauss-seidel: the aero unit sees the new e, de
                    aero.set_inputs(e, de)
                    aero.do_step(t0, t1 - t0)
                    aero_inputs.append(t0, t1 - t0, e, de)
                    q, = aero.get_outputs()
            _record(series, e, structure, aero, topology, scene["probes"], t1)
            reached = t1
            if progress is not None:
                progress.update(t1)
        message = f"reached t = {stop:g} s in {len(times) - 1} communication steps"
        if aero is not None:
            message += f" ({algorithm} coupling with the {scene['aero']['model']} aero unit)"
    except (Exception, KeyboardInterrupt) as err:
        log.debug("run failed during %s", phase, exc_info=True)
        status, message = _classify(err, units.UnitError, phase)
    finally:
        for unit in (aero, structure):
            if unit is not None:
                try:
                    unit.terminate()
                except Exception as err:  # the samples are already recorded: report, keep the status
                    message += f" (terminating the {getattr(unit, 'kind', 'structure')} unit failed: {err})"
    if progress is not None:
        progress.finish(reached, status)
    return RunResult(status, message, _time.perf_counter() - start, float(reached), scene, series, aero_inputs)
