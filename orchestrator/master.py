"""The run loop: the structure unit alone, or coupled with the aero unit.

Steps the units from t = 0 to ``time.stop`` with the communication step ``coupling.step`` (the last
step shortened to land on ``time.stop``) and records at every communication point: probe global
positions (m), fold angles (degrees), energy (J), kinetic energy (J), constraint residual and, with an
aero unit, the lift coefficient CL (-) and the lift (N). A failure never loses the samples recorded
before it.

Structure only (``aero.model = "none"``): the generalized force Q = 0 is held.

With an aero unit the units are coupled at the same communication points (DESIGN §6); before the run
both units' ``topology_hash`` must agree, else the run is refused (status "error") before any step.
At t = 0 the aero unit gets the structure's initial e, de and its Q is its initial output (zero: no
circulation yet). A prescribed-motion structure ignores Q, but Q is still passed (and checked by the
structure unit). ``coupling.algorithm``:

- ``gauss-seidel`` (staggered, explicit, the default): for each step [t, t + h]: the structure steps
  with the Q of the aero unit at t; the aero unit then steps with the structure's new e, de at t + h,
  and its Q at t + h is held for the next structure step.
- ``jacobi`` (explicit): both units step from the outputs at t (the aero unit with e, de of t held),
  then exchange.
  A run of either that diverges after its first step gets ``explicit_coupling_hint`` appended to its message.
- ``implicit``: each step is repeated until the interface force agrees with the motion it produces,
  i.e. a fixed point Q = H(Q) of one Gauss-Seidel pass H: Q_used -> structure step with Q_used held
  over [t, t + h] -> e, de at t + h -> aero step -> Q_new at t + h. Per step:

  1. save both units' states (``get_state``); the first iterate Q_used is the accepted Q at t;
  2. the structure steps with Q_used, the aero unit with its new e, de, giving Q_new;
  3. r = Q_new - Q_used; the step is accepted when ||r|| / max(||Q_new||, ``acceleration.RESIDUAL_FLOOR``) is below
     ``coupling.tolerance`` (2-norms over all n coordinates, N and N m mixed as the unit gives them);
     Q_new is then the Q at t + h, the first iterate of the next step;
  4. else both units are rolled back (``set_state``) and the step is repeated with the next Q_used
     from the acceleration (``coupling.acceleration``), both starting with a relaxed first update
     Q_used + omega_0 r, omega_0 = ``coupling.relaxation``:
     ``aitken``: Aitken's dynamic relaxation (Kuettler and Wall 2008):
     omega_k = -omega_(k-1) r_(k-1).(r_k - r_(k-1)) / |r_k - r_(k-1)|^2, Q_used += omega_k r_k;
     ``iqn-ils``: interface quasi-Newton with an inverse Jacobian from a least-squares model
     (Degroote, Bathe and Vierendeels 2009; as in preCICE, Bungartz et al. 2016, Mehl et al. 2016)
     built from this step's iterations only (``IQNILS``).
  5. after ``coupling.max_iterations`` iterations without convergence (or a non-finite residual, or a
     failed rollback) the run stops with status "diverged", naming the step, the residual and a hint;
     the samples of the accepted steps are kept.

  Recorded per step: the iterations taken and the accepted residual (``timeseries.csv`` columns
  ``coupling_iterations``, ``coupling_residual``; ``summary.json`` ``coupling``). A prescribed-motion
  structure (which ignores Q) still iterates: Q converges to the aero force of the prescribed motion.

The unit interface (``orchestrator.units``): ``make_unit(kind, scene, backend, fmu_dir)`` returns a
unit with ``n``, ``topology_hash``, ``get_outputs()`` (structure: ``(e, de)``; aero: ``(Q,)``),
``set_inputs(...)`` (structure: ``Q``; aero: ``e, de``), ``do_step(t, h)`` (raises ``UnitError`` on an
FMI error or discard, with the unit's logged reason), ``monitors()`` (structure: ``energy``,
``kinetic_energy``, ``constraint_residual``, ``fold_angles_deg``, ``latch_times``, ``probe_positions``,
``probe_velocities``, ``strains``, all outputs of the unit: the master computes no sensor itself; aero:
``CL``, ``lift``, ...),
``get_state()`` / ``set_state(state)`` (implicit coupling only) and ``terminate()``.

With an aero unit the run also keeps, in memory, the inputs of every aero step (``AeroInputs``: t, h, e, de
as the aero unit was given them; with implicit coupling those of the accepted iterate only), so that the
aero unit can be replayed in-process after the run, e.g. for the 3D picture of wing and wake
(``orchestrator.wake_view``): with explicit coupling the aero unit's state is a deterministic function of
these inputs; with implicit coupling too, up to the aero unit's reuse of its factorization within a
rigid-motion tolerance across the rejected iterates (about 1e-10 relative, see ``orchestrator.wake_view``).
"""

from __future__ import annotations

import importlib
import logging
import math
import time as _time
from dataclasses import dataclass, field
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np

from orchestrator.acceleration import interface_residual, make_acceleration
from orchestrator.progress import Progress
from orchestrator.scene import hinge_joints
from orchestrator.timeseries import AERO_COLUMNS, COUPLING_COLUMNS, TimeSeries
from structure_fmu.errors import SolverDiverged

log = logging.getLogger(__name__)

STATUSES = ("ok", "diverged", "error")
ALGORITHMS = ("gauss-seidel", "jacobi", "implicit")
EXPLICIT = ("gauss-seidel", "jacobi")
HINT_WINDOW = 20        # communication steps compared by explicit_coupling_hint


class CouplingError(RuntimeError):
    """The units cannot be connected (different topologies or sizes); raised before any step."""


class CouplingDiverged(RuntimeError):
    """The implicit coupling did not converge in a step, or could not roll the units back (status
    "diverged")."""

    diverged = True


@dataclass
class AeroInputs:
    """The aero unit's steps in order: each ``do_step(t, h)`` (s) with the e (m, 1) and de (m/s, 1/s),
    (n,) each, it held at that step. The tunable parameters were the unit's defaults (``run_scene`` sets
    none). Recording stops (``complete`` False) once ``max_values`` numbers are held (about 8 bytes each):
    a replay then covers only the recorded steps. With implicit coupling only the accepted iterate of each
    step is recorded (the rejected iterates were rolled back)."""

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


# ---- implicit coupling: the accelerations -------------------------------------------------------------
def _rollback(units: tuple, states: tuple, t0: float, iteration: int) -> None:
    for unit, state in zip(units, states):
        try:
            unit.set_state(state)
        except Exception as err:
            raise CouplingDiverged(
                f"implicit coupling: rolling the {getattr(unit, 'kind', 'unit')} unit back to t = {t0:.6g} s "
                f"for iteration {iteration} failed: {err}. Hint: the unit must support fmi2SetFMUstate "
                "(canGetAndSetFMUstate); use coupling.algorithm = 'gauss-seidel' otherwise") from err


def implicit_step(structure: Any, aero: Any, t0: float, h: float, q: np.ndarray, acceleration: Any,
                  tolerance: float, max_iterations: int):
    """One implicit communication step [t0, t0 + h] from the accepted Q at t0 (module docstring).

    Returns (e, de, q_new, iterations, residual) of the accepted iterate, both units then at t0 + h;
    raises CouplingDiverged when it does not converge in ``max_iterations`` or cannot roll back.
    """
    states = (structure.get_state(), aero.get_state())
    acceleration.start()
    x = np.array(q, dtype=float)
    residual = math.inf
    for k in range(1, max_iterations + 1):
        if k > 1:
            _rollback((structure, aero), states, t0, k)
        structure.set_inputs(x)
        structure.do_step(t0, h)
        e, de = structure.get_outputs()
        aero.set_inputs(e, de)
        aero.do_step(t0, h)
        q_new, = aero.get_outputs()
        residual = interface_residual(q_new, x)
        if residual < tolerance:
            return e, de, q_new, k, residual
        if not math.isfinite(residual):
            break
        x = acceleration.update(x, q_new)
    kind = getattr(acceleration, "name", type(acceleration).__name__)
    raise CouplingDiverged(
        f"implicit coupling diverged in the step from t = {t0:.6g} s to {t0 + h:.6g} s: interface residual "
        f"{residual:.3g} after {k} iterations (coupling.tolerance = {tolerance:g}, "
        f"coupling.max_iterations = {max_iterations}, coupling.acceleration = {kind!r}). Hint: reduce coupling.step, "
        "try coupling.acceleration = 'iqn-ils' or a smaller coupling.relaxation, or raise "
        "coupling.max_iterations")


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
    stepping_wall_time_s: float | None = None   # s, of the communication steps alone (units loaded and
                                                # initialized before): / simulated time = real-time factor
    latch_times: dict = field(default_factory=dict)   # s, {hinge: time it latched}, as the structure unit
                                                      # reported at the last recorded communication point


def communication_times(stop: float, step: float) -> np.ndarray:
    """Communication points 0, h, 2h, ..., stop (s); the last interval is shortened to land on stop."""
    n = max(1, math.ceil(stop / step - 1e-9))
    times = np.arange(n + 1, dtype=float) * step
    times[-1] = stop
    return times


def has_aero(scene: dict) -> bool:
    """True when the scene couples an aero unit (``aero.model`` is not "none")."""
    return scene.get("aero", {}).get("model", "none") != "none"


def is_implicit(scene: dict) -> bool:
    """True when the scene couples an aero unit implicitly (``coupling.algorithm = "implicit"``)."""
    return has_aero(scene) and scene.get("coupling", {}).get("algorithm") == "implicit"


def new_series(scene: dict) -> TimeSeries:
    """An empty series with the scene's probe, hinge and strain gauge columns (and CL, lift for an aero
    scene, and coupling_iterations, coupling_residual for an implicit one)."""
    return TimeSeries([p["name"] for p in scene["probes"]], [j["name"] for j in hinge_joints(scene)],
                      aero=has_aero(scene), coupling=is_implicit(scene),
                      strain_names=[g["name"] for g in scene.get("strain_gauges", [])])


def _record(series: TimeSeries, structure: Any, aero: Any, t: float,
            coupling: tuple[int, float] | None = None) -> dict:
    """Append one sample of the units' outputs; returns the hinges' latch times (s) the structure unit
    reports. The probes' positions and the gauges' strains are the structure unit's own outputs."""
    monitors = structure.monitors()
    loads = None
    if aero is not None:
        aero_monitors = aero.monitors()
        loads = {name: aero_monitors.get(name, np.nan) for name in AERO_COLUMNS}
    probes, strains = monitors.get("probe_positions", {}), monitors.get("strains", {})
    unread = [p for p in series.probe_names if p not in probes] + [g for g in series.strain_names if g not in strains]
    if unread:
        raise RuntimeError(f"the structure unit reports no output for the probe or strain gauge {unread[0]!r}: "
                           "rebuild the FMUs (wingsim build)")
    positions = np.array([probes[p] for p in series.probe_names], dtype=float).reshape(-1, 3)
    series.append(t, positions, monitors.get("fold_angles_deg", {}),
                  monitors.get("energy", np.nan), monitors.get("constraint_residual", np.nan),
                  kinetic_energy=monitors.get("kinetic_energy", np.nan), aero=loads,
                  coupling=None if coupling is None else dict(zip(COUPLING_COLUMNS, coupling)),
                  strains=strains)
    return monitors.get("latch_times", {})


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


def explicit_coupling_hint(series: TimeSeries, algorithm: str, window: int = HINT_WINDOW) -> str:
    """Text appended to the message of an explicitly coupled run that diverged. The unit that stopped it
    names its own symptom (often the structure's Newton iteration), but the exchange itself can be what
    grew: the added-mass instability, or aeroelastic feedback through the lagged force. The swing
    (max - min) of the lift (N; not CL, which is 0 in still air) over the last `window` communication
    points, against the `window` before, tells the two apart (fewer samples: halves of them, at least 5
    each); implicit coupling removes the exchange's own instability (docs/stability.md). Empty when the
    run failed in its first communication step: the structure then moved under the force of its initial
    state alone, and no exchange had happened that could have grown."""
    lift = series.column("lift")
    lift = lift[np.isfinite(lift)]
    if lift.size < 2:
        return ""
    text = (f" Explicit {algorithm} coupling can itself be unstable (added mass, or feedback through the lagged "
            "aero force)")
    window = min(window, lift.size // 2)
    if window >= 5:
        last, before = np.ptp(lift[-window:]), np.ptp(lift[-2 * window:-window])
        text += (f": the lift swung over {last:.3g} N in the last {window} communication steps against "
                 f"{before:.3g} N in the {window} before")
    return text + '; if it grew, try coupling.algorithm = "implicit".'


def _classify(err: BaseException, unit_error: type, phase: str) -> tuple[str, str]:
    """(status, message) for a failure during ``phase``."""
    diverged = getattr(err, "diverged", False) or "diverged" in str(err)
    if isinstance(err, (unit_error, SolverDiverged, CouplingDiverged)) and diverged:
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
    ``topology`` (default ``Topology.from_scene(scene)``) gives the number of coordinates the structure unit
    must have (``n_coordinates``).
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
    status, message, reached, stepping, latch_times = "ok", "", 0.0, None, {}
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
        implicit = aero is not None and algorithm == "implicit"
        if implicit:
            coupling = scene["coupling"]
            acceleration = make_acceleration(coupling)
            tolerance, max_iterations = coupling.get("tolerance", 1e-6), coupling.get("max_iterations", 50)
            total_iterations = most_iterations = 0
        latch_times = _record(series, structure, aero, times[0],
                              coupling=(0, np.nan) if implicit else None)
        stepping_start = _time.perf_counter()
        for t0, t1 in zip(times[:-1], times[1:]):
            phase = f"the step from t = {t0:.6g} s"
            step_coupling = None
            if implicit:
                e, de, q, iterations, residual = implicit_step(structure, aero, t0, t1 - t0, q, acceleration,
                                                               tolerance, max_iterations)
                aero_inputs.append(t0, t1 - t0, e, de)     # the accepted iterate only
                total_iterations += iterations
                most_iterations = max(most_iterations, iterations)
                step_coupling = (iterations, residual)
            else:
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
            latch_times = _record(series, structure, aero, t1, coupling=step_coupling)
            reached = t1
            if progress is not None:
                progress.update(t1)
            stepping = _time.perf_counter() - stepping_start
        message = f"reached t = {stop:g} s in {len(times) - 1} communication steps"
        if aero is not None:
            message += f" ({algorithm} coupling with the {scene['aero']['model']} aero unit"
            if implicit:
                message += (f", {coupling.get('acceleration', 'aitken')}: {total_iterations / (len(times) - 1):.3g} "
                            f"iterations per step, at most {most_iterations}")
            message += ")"
    except (Exception, KeyboardInterrupt) as err:
        log.debug("run failed during %s", phase, exc_info=True)
        status, message = _classify(err, units.UnitError, phase)
        if status == "diverged" and aero is not None and algorithm in EXPLICIT:
            message = message.rstrip(" .") + "." + explicit_coupling_hint(series, algorithm)
    finally:
        for unit in (aero, structure):
            if unit is not None:
                try:
                    unit.terminate()
                except Exception as err:  # the samples are already recorded: report, keep the status
                    message += f" (terminating the {getattr(unit, 'kind', 'structure')} unit failed: {err})"
    if progress is not None:
        progress.finish(reached, status)
    return RunResult(status, message, _time.perf_counter() - start, float(reached), scene, series, aero_inputs,
                     stepping, latch_times)
