"""The run loop: the structure unit alone, or coupled with the aero unit.

Steps the units from t = 0 to ``time.stop`` with the communication step ``coupling.step`` (the last
step shortened to land on ``time.stop``) and records at every communication point: probe global
positions (m), velocities and accelerations, fold angles (degrees), energy (J), kinetic energy (J), constraint
residual and, with an aero unit, each hinge's aerodynamic moment about its axis (N m), the lift coefficient CL
(-) and the lift (N). The units are asked only for what the scene's ``record`` table asks for
(``recorded_rows``): they compute an output only when it is read, so a probe's acceleration or the energy that
no one records costs nothing, and its columns hold NaN. A failure never loses the samples recorded before it.

The run: make the units; with an aero unit, check that both carry the same ``topology_hash``
(docs/architecture.md; else the run is refused with status "error" before any step); make the coupling
scheme of ``coupling.algorithm`` (``orchestrator.run.coupling``: ``StructureAlone`` for ``aero.model = "none"``,
``GaussSeidel``, ``Jacobi``, ``Implicit``); record t = 0 after the scheme's initial exchange; then for each
communication step the scheme's ``advance(t0, t1)`` and a record at t1. With implicit coupling the record
also holds the iterations taken and the accepted residual (``timeseries.csv`` columns
``coupling_iterations``, ``coupling_residual``; ``summary.json`` ``coupling``).

Failures are classified from typed signals, never from message text: status "diverged" for a
``UnitError`` with ``diverged`` True (the unit logged its failure in the category
``DIVERGED_CATEGORY``), a ``SolverDiverged`` or a ``CouplingDiverged``; "error" for every other failure.
An explicitly coupled run that diverged after its first step gets ``coupling.explicit_coupling_hint`` appended.

The unit interface (``orchestrator.run.units``): ``make_unit(kind, scene, backend, fmu_dir)`` returns a
unit with ``n``, ``topology_hash``, ``get_outputs()`` (structure: ``(e, de)``; aero: ``(Q,)``),
``set_inputs(...)`` (structure: ``Q``; aero: ``e, de``), ``do_step(t, h)`` (raises ``UnitError`` on an
FMI error or discard, with the unit's logged reason), ``monitors()`` (structure: ``energy``,
``kinetic_energy``, ``constraint_residual``, ``fold_angles_deg``, ``latch_times``, ``probe_positions``,
``probe_velocities``, ``probe_accelerations``, ``strains``, all outputs of the unit: the master computes no
sensor itself; aero: ``CL``, ``lift``, ...),
``monitor_values()`` and ``monitor_layout`` (the same outputs as one vector and where each row lies in it:
what the master records from, ``orchestrator.run.recording``),
``get_state()`` / ``set_state(state)`` (implicit coupling only) and ``terminate()``. ``make_unit`` also takes
``reads`` (the rows to record, ``recorded_rows``) and ``monitors_with_outputs`` (read them in the call that reads
the output blocks: under explicit coupling every state whose outputs are exchanged is recorded, so each unit is
read once per step; an implicit coupling reads them apart, so that its rejected iterates compute none).

With an aero unit the run also keeps, in memory, the inputs of every aero step (``AeroInputs``: t, h, e, de
as the aero unit was given them; with implicit coupling those of the accepted iterate only), so that the
aero unit can be replayed in-process after the run, e.g. for the 3D picture of wing and wake
(``orchestrator.output.wake_view``): with explicit coupling the aero unit's state is a deterministic function of
these inputs; with implicit coupling too, up to the aero unit's reuse of its factorization within a
rigid-motion tolerance across the rejected iterates (about 1e-10 relative, see ``orchestrator.output.wake_view``).

Every run also keeps, in memory, the structure unit's exchanged coordinates E at the communication points
(``StructureCoordinates``, the structure unit's output ``e``, read after the step like the monitors), for the
picture of the mechanism at several instants (``orchestrator.output.mechanism_view``).
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

from orchestrator.run.coupling import AeroInputs, CouplingDiverged, make_scheme
from orchestrator.run.progress import Progress
from orchestrator.run.recording import Recorder
from orchestrator.scene.load import hinge_joints, joint_monitor_names
from orchestrator.run.timeseries import PROBE_ROWS, TimeSeries
from orchestrator.scene.columns import AERO_COLUMNS, MONITOR_COLUMNS
from fmu_common.choices import aero_model
from fmu_common.errors import SolverDiverged
from fmu_common.scene_bounds import AERO_INPUT_RECORD_VALUES
from fmu_common.scene_schema import PROBE_RECORDS

log = logging.getLogger(__name__)

STATUSES = ("ok", "diverged", "error", "interrupted")
STEPPING = "stepping"   # the phase of a communication step, named with its start time if it fails

STRUCTURE_RECORD_VALUES = AERO_INPUT_RECORD_VALUES
"""The structure coordinates are recorded up to about this many numbers (8 bytes each), the bound of the aero
inputs' record (``fmu_common.scene_bounds.memory_estimate`` counts both)."""


class CouplingError(RuntimeError):
    """The units cannot be connected (different topologies or sizes); raised before any step."""


@dataclass
class StructureCoordinates:
    """The structure unit's exchanged coordinates E at communication points: ``t`` (s) and ``e`` ((n,) each,
    9 per node: r (m), r_x and r_y (-), global frame; ``fmu_common.topology``).

    Bounded: every ``stride``-th communication point is kept (t = 0 first), with ``stride`` the smallest that
    keeps the whole run within ``STRUCTURE_RECORD_VALUES`` numbers (``for_run``; 1, every point, unless the
    run is very long). Past that bound the record is thinned, not stopped: the latest point is always kept
    as well, so the record ends where the run stopped (the end, or the last point before a failure)."""

    stride: int = 1
    t: list = field(default_factory=list)
    e: list = field(default_factory=list)
    _count: int = field(default=0, init=False, repr=False)                 # points offered so far
    _tail_off_stride: bool = field(default=False, init=False, repr=False)  # the last kept point is there only
                                                                           # because it is the latest

    @classmethod
    def for_run(cls, points: int, n: int, max_values: int = STRUCTURE_RECORD_VALUES) -> "StructureCoordinates":
        """The record of a run of ``points`` communication points with ``n`` coordinates each, within about
        ``max_values`` numbers."""
        return cls(stride=max(1, math.ceil(points * n / max_values)))

    def __len__(self) -> int:
        return len(self.t)

    def append(self, t: float, e: np.ndarray) -> None:
        """Offer the E (n,) at communication point t (s); kept if on the stride or, until the next one, as
        the latest."""
        if self._tail_off_stride:
            self.t.pop()
            self.e.pop()
        self._tail_off_stride = self._count % self.stride != 0
        self._count += 1
        self.t.append(float(t))
        self.e.append(np.array(e, dtype=float))


@dataclass
class RunResult:
    """Outcome of one run: what ``summary.json`` and ``timeseries.csv`` are written from."""

    status: str               # "ok" | "diverged" | "error" | "interrupted" (Ctrl-C, SIGTERM)
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
    structure_coordinates: StructureCoordinates | None = None   # the structure's E at communication points


def communication_times(stop: float, step: float) -> np.ndarray:
    """Communication points 0, h, 2h, ..., stop (s); the last interval is shortened to land on stop."""
    n = max(1, math.ceil(stop / step - 1e-9))
    times = np.arange(n + 1, dtype=float) * step
    times[-1] = stop
    return times


def has_aero(scene: dict) -> bool:
    """True when the scene couples an aero unit (``aero.model`` is not "none": it builds a unit,
    ``fmu_common.choices.AeroModel``)."""
    return aero_model(scene["aero"]["model"]).builds_unit


def is_implicit(scene: dict) -> bool:
    """True when the scene couples an aero unit implicitly (``coupling.algorithm = "implicit"``)."""
    return has_aero(scene) and scene["coupling"]["algorithm"] == "implicit"


def new_series(scene: dict) -> TimeSeries:
    """An empty series with the scene's probe, hinge and strain gauge columns (and CL, lift for an aero
    scene, and coupling_iterations, coupling_residual for an implicit one)."""
    return TimeSeries([p["name"] for p in scene["probes"]], [j["name"] for j in hinge_joints(scene)],
                      aero=has_aero(scene), coupling=is_implicit(scene),
                      strain_names=[g["name"] for g in scene["strain_gauges"]], joint_names=joint_monitor_names(scene))


def recorded_rows(scene: dict) -> dict[str, tuple[str, ...]]:
    """{unit kind: the keys of its output rows (``structure_fmu.interface``, ``aero_fmu.interface``) the run reads
    and records} for ``scene``: what its ``record`` table asks for (``record.probes``: the probes' positions, up to
    their velocities or accelerations; ``record.monitors``: with or without the energies), the fold angles, latch
    times, strain gauges and joint monitors, and for the aero unit its CL, lift and hinge moments. A unit computes
    only the outputs read (fmu_common.fmi_slave)."""
    record = scene["record"]
    probes = PROBE_ROWS[:PROBE_RECORDS.index(record["probes"]) + 1]
    monitors = MONITOR_COLUMNS if record["monitors"] == "all" else ("constraint_residual",)
    return {"structure": ("fold_angles_deg", "latch_times", *probes, "strains", "joints", *monitors),
            "aero": (*AERO_COLUMNS, "hinge_moments")}


def check_connection(structure: Any, aero: Any) -> None:
    """CouplingError unless the two units carry the same structural topology (docs/architecture.md)."""
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


def is_divergence(err: BaseException, unit_error: type) -> bool:
    """True when ``err`` is a typed divergence signal: a ``unit_error`` whose ``diverged`` is True (set by
    ``orchestrator.run.units`` from the unit's log category, never from its text), a ``SolverDiverged`` or a
    ``CouplingDiverged``."""
    if isinstance(err, (SolverDiverged, CouplingDiverged)):
        return True
    return isinstance(err, unit_error) and getattr(err, "diverged", False) is True


def _classify(err: BaseException, unit_error: type, phase: str) -> tuple[str, str]:
    """(status, message) for a failure during ``phase``."""
    if is_divergence(err, unit_error):
        return "diverged", str(err)
    if isinstance(err, KeyboardInterrupt):
        return "interrupted", f"interrupted ({err or 'SIGINT'}) during {phase}"
    if isinstance(err, unit_error):
        return "error", f"{phase}: {err}"
    return "error", f"{phase}: {type(err).__name__}: {err}"


def run_scene(scene: dict, backend: str = "fmu", fmu_dir: Path | None = None,
              progress: Progress | None = None, units: ModuleType | Any = None,
              topology: Any = None) -> RunResult:
    """Run a scene (structure alone or coupled with the aero unit); never raises for a failure of a
    unit, returns its status.

    ``units`` (default ``orchestrator.run.units``) provides ``make_unit`` and ``UnitError``;
    ``topology`` (default the scene's ``fmu_common.topology.Topology``) gives the number of coordinates the
    structure unit must have (``n_coordinates``).
    Both are parameters so that the loop can be tested without the physics.
    ``backend="fmu"`` needs ``fmu_dir``, the folder of the scene's built FMUs: ValueError without it, before
    anything runs (``wingsim.run(scene, backend="fmu")`` builds them when needed).
    """
    if backend == "fmu" and fmu_dir is None:
        raise ValueError("run_scene(backend='fmu') needs fmu_dir, the folder of the scene's built FMUs (wingsim build "
                         "SCENE writes them; wingsim.run(scene, backend='fmu') builds them when needed); "
                         "backend='direct' runs the units in this process without FMUs")
    start = _time.perf_counter()
    if units is None:
        units = importlib.import_module("orchestrator.run.units")  # lazy: loads fmpy and the slaves
    if topology is None:
        from fmu_common.wing_spec import StructureSpec  # lazy: numpy only when needed
        from fmu_common.topology import Topology

        topology = Topology.from_spec(StructureSpec.from_scene(scene))
    series = new_series(scene)
    stop = scene["time"]["stop"]
    status, message, reached, stepping, latch_times = "ok", "", 0.0, None, {}
    structure = aero = scheme = recorder = None
    aero_inputs = AeroInputs.empty() if has_aero(scene) else None
    coordinates = None
    phase = "starting the structure unit"
    try:
        reads = recorded_rows(scene)
        # an explicit coupling records every state whose outputs it reads: the monitors come in the same read; an
        # implicit one reads the outputs of iterates it rejects, which must compute no monitor
        together = not is_implicit(scene)
        structure = units.make_unit(kind="structure", scene=scene, backend=backend, fmu_dir=fmu_dir,
                                    reads=reads["structure"], monitors_with_outputs=together)
        if structure.n != topology.n_coordinates:
            raise RuntimeError(f"the unit has {structure.n} coordinates but the scene's topology has "
                               f"{topology.n_coordinates}: rebuild the FMUs (wingsim build)")
        if has_aero(scene):
            phase = "starting the aero unit"
            aero = units.make_unit(kind="aero", scene=scene, backend=backend, fmu_dir=fmu_dir, reads=reads["aero"],
                                   monitors_with_outputs=together)
            phase = "connecting the structure and aero units"
            check_connection(structure, aero)
        times = communication_times(stop, scene["coupling"]["step"])
        coordinates = StructureCoordinates.for_run(len(times), structure.n)
        phase = "reading the initial outputs"
        recorder = Recorder(series, structure, aero)
        series.reserve(len(times))
        scheme = make_scheme(scene, structure, aero, aero_inputs)
        start_coupling = scheme.start()
        e = structure.get_outputs()[0]   # the structure's e after the scheme's initial exchange
        recorder.record(times[0], start_coupling)
        coordinates.append(times[0], e)
        stepping_start = _time.perf_counter()
        for k in range(1, len(times)):
            t0, t1 = float(times[k - 1]), float(times[k])
            phase = STEPPING                  # named with t0 only if the step fails
            step_coupling = scheme.advance(t0, t1)
            e = structure.get_outputs()[0]
            recorder.record(t1, step_coupling)
            coordinates.append(t1, e)
            reached = t1
            if progress is not None:
                progress.update(t1)
            stepping = _time.perf_counter() - stepping_start
        message = f"reached t = {stop:g} s in {len(times) - 1} communication steps"
        if aero is not None:
            message += (f" ({scheme.name} coupling with the {scene['aero']['model']} aero unit"
                        f"{scheme.statistics()})")
    except (Exception, KeyboardInterrupt) as err:
        log.debug("run failed during %s", phase, exc_info=True)
        if phase is STEPPING:
            phase = f"the step from t = {t0:.6g} s"
        status, message = _classify(err, units.UnitError, phase)
        if status == "diverged" and scheme is not None:
            message = scheme.explain_divergence(message, series)
    finally:
        for unit in (aero, structure):
            if unit is not None:
                try:
                    unit.terminate()
                except Exception as err:  # the samples are already recorded: report, keep the status
                    message += f" (terminating the {getattr(unit, 'kind', 'structure')} unit failed: {err})"
    if recorder is not None:
        latch_times = recorder.latch_times()
    if progress is not None:
        progress.finish(reached, status)
    return RunResult(status, message, _time.perf_counter() - start, float(reached), scene, series, aero_inputs,
                     stepping, latch_times, coordinates)
