"""Co-simulation units as the master sees them, over two backends running the same slave code.

`make_unit(kind, scene, backend, fmu_dir)` returns a `Unit` of kind "structure" or "aero":

    unit.kind                   "structure" | "aero"
    unit.n                      number of ANCF coordinates (length of e, de, Q)
    unit.topology_hash          str, compared with the other units' before connecting
    unit.get_outputs()          the output blocks, fresh ndarrays (n,) each:
                                  structure: (e, de)  m and 1 / m/s and 1/s
                                  aero:      (Q,)     N and N m
    unit.set_inputs(*blocks)    the input blocks, (n,) each:
                                  structure: set_inputs(Q)      generalized force, N and N m
                                  aero:      set_inputs(e, de)  the structure's coordinates and rates
    unit.do_step(t, h)          advance from t to t + h (s); raises UnitError with the unit's logged reason
    unit.monitors()             structure: {"energy": J, "kinetic_energy": J, "constraint_residual": -,
                                            "fold_angles_deg": {hinge: deg},
                                            "latch_times": {hinge: s, for the hinges latched so far},
                                            "probe_positions": {probe: (3,) m, global frame},
                                            "probe_velocities": {probe: (3,) m/s, global frame},
                                            "strains": {gauge: surface strain, -}}
                                (the structure unit's outputs <probe>_x.., <probe>_vx.., <gauge> of the
                                scene's probes and strain gauges)
                                aero: {"CL": -, "lift": N, "wake_panels": count, ...every scalar output}
    unit.get_state(), unit.set_state(s)    complete state for rollback (opaque; FMU states are freed
                                when the object is garbage collected or the unit terminated)
    unit.terminate()            end the simulation and free the instance (idempotent, never raises)

Backends: "fmu" loads `fmu_dir/<kind>.fmu` with fmpy (FMU2Slave), every get/set batched over precomputed
value-reference arrays and ctypes buffers, every status checked, log messages captured; "direct"
instantiates the same slave class (`StructureSlave`, `AeroSlave`) in-process and drives it through the
same calls. Both start at t = 0 (FMI start time) and are initialized by `make_unit`.
"""
from __future__ import annotations

import importlib
import json
import os
import re
import shutil
import sys
import tempfile
import weakref
from ctypes import byref
from dataclasses import dataclass
from pathlib import Path
from typing import NamedTuple

import numpy as np

from fmu_common.fmi_slave import DIVERGED_CATEGORY, SCENE_RESOURCE
from structure_fmu.sensors import output_names as sensor_output_names
from structure_fmu.structure_slave import LATCH_PENDING


class UnitError(RuntimeError):
    """A unit call failed. The message carries the unit's own logged reason.

    `diverged` is True when the unit reported a diverging state (summary status "diverged"): it logged the
    failure in the category `DIVERGED_CATEGORY`, whatever the message says.
    """

    def __init__(self, message: str, diverged: bool = False):
        super().__init__(message)
        self.diverged = diverged


class LogEntry(NamedTuple):
    """One message a unit logged: its fmi2Status (0 OK .. 4 Fatal), category and text ('%' undoubled)."""

    status: int
    category: str
    text: str


def _reported_divergence(entries) -> bool:
    """True when one of the log entries is the unit's divergence signal (its category, not its text)."""
    return any(entry.category == DIVERGED_CATEGORY for entry in entries)


@dataclass(frozen=True)
class UnitKind:
    """What distinguishes the unit kinds; everything else is one code path."""

    fmu_file: str
    slave: tuple[str, str]            # (module, class) of the slave, for the direct backend
    inputs: tuple[str, ...]           # indexed input blocks, each [1..n]
    outputs: tuple[str, ...]          # indexed output blocks, each [1..n]
    monitors: tuple[str, ...]         # scalar Real outputs read by monitors() (all required)
    scene_sections: tuple[str, ...]   # scene sections an FMU must have been built from (else stale)
    hinge_monitors: bool = False      # fold_angle_<hinge> and latch_time_<hinge> outputs, per hinge of the scene
    sensor_monitors: bool = False     # <probe>_x.._vz and <gauge> outputs, per probe and gauge of the scene
    extra_monitors: bool = False      # also every other scalar Real output (not a parameter)


KINDS = {
    "structure": UnitKind("structure.fmu", ("structure_fmu.structure_slave", "StructureSlave"), ("Q",),
                          ("e", "de"), ("energy", "kinetic_energy", "constraint_residual"),
                          ("structure", "probes", "strain_gauges"), hinge_monitors=True, sensor_monitors=True),
    "aero": UnitKind("aero.fmu", ("aero_fmu.aero_slave", "AeroSlave"), ("e", "de"), ("Q",),
                     ("CL", "lift", "wake_panels"), ("structure", "aero", "flow"), extra_monitors=True),
}
FMU_FILES = {kind: spec.fmu_file for kind, spec in KINDS.items()}
_ERROR = 3  # fmi2Error: a call that logged a message at this status (or worse) failed
_INDEXED = re.compile(r"^(e|de|Q)\[(\d+)\]$")


def make_unit(kind: str, scene: dict, backend: str, fmu_dir, parameters: dict | None = None,
              instance_name: str | None = None) -> "Unit":
    """Create, set up and initialize a unit of `kind` ("structure" or "aero") for `scene`.

    backend: "fmu" (fmu_dir/<kind>.fmu through fmpy) or "direct" (the slave class in-process; fmu_dir
    unused). parameters: optional {tunable name: value} set before initialization (names as in
    StructureSolver / AeroSolver.tunable_parameters). Raises UnitError on any failure, naming what was wrong.
    """
    if kind not in KINDS:
        raise UnitError(f"unit kind {kind!r} is not available; available: {', '.join(KINDS)}")
    spec = KINDS[kind]
    # Import the host's packages first: an FMU loaded in this process then shares them instead of importing
    # its embedded copy from a temporary folder that is deleted at terminate().
    try:
        importlib.import_module(spec.slave[0])
    except ImportError as exc:
        raise UnitError(f"the {kind} unit cannot be loaded: {spec.slave[0]} does not import ({exc})") from exc
    name = instance_name or kind
    if backend == "fmu":
        port = _FmuPort(Path(fmu_dir) / spec.fmu_file, scene, name, spec)
    elif backend == "direct":
        port = _DirectPort(scene, name, spec)
    else:
        raise UnitError(f"backend {backend!r} is not known; use 'fmu' or 'direct'")
    try:
        return Unit(port, scene, parameters or {}, kind)
    except BaseException:
        port.close()
        raise


class Unit:
    """A structure or aero unit driven through a port (fmpy FMU or in-process slave); see the module
    docstring."""

    def __init__(self, port, scene: dict, parameters: dict, kind: str = "structure"):
        from fmu_common.fmi_slave import fmi_name
        from fmu_common.topology import Topology

        self._port = port
        self.kind = kind
        self._spec = spec = KINDS[kind]
        self.backend = port.backend
        vr = port.value_references()
        idx = {(m.group(1), int(m.group(2))): v for name, v in vr.items() if (m := _INDEXED.match(name))}
        self.n = n = sum(1 for (block, _) in idx if block == spec.outputs[0])
        try:
            block_vr = {b: [idx[(b, i)] for i in range(1, n + 1)] for b in (*spec.outputs, *spec.inputs)}
        except KeyError as exc:
            raise UnitError(f"{port.label}: variable {exc.args[0][0]}[{exc.args[0][1]}] missing "
                            f"(n = {n} from {spec.outputs[0]}[...])") from None
        self.hinges = list(Topology.from_scene(scene).hinge_names) if spec.hinge_monitors else []
        missing = [f"{kind}_{h}" for h in self.hinges for kind in ("fold_angle", "latch_time")
                   if fmi_name(f"{kind}_{h}") not in vr]
        if missing:
            raise UnitError(f"{port.label}: no output {missing[0]}; the unit does not match the scene (rebuild "
                            "the FMU)")
        self.probes = [p["name"] for p in scene["probes"]] if spec.sensor_monitors else []
        self.gauges = [g["name"] for g in scene["strain_gauges"]] if spec.sensor_monitors else []
        sensor_names = sensor_output_names(self.probes, self.gauges)
        absent = [m for m in (*spec.monitors, *sensor_names) if fmi_name(m) not in vr]
        if absent:
            raise UnitError(f"{port.label}: no output {absent[0]}; the unit does not match the scene (rebuild "
                            "the FMU)")
        monitors = list(spec.monitors)
        if spec.extra_monitors:
            known = {v for b in block_vr.values() for v in b}
            monitors += [name for name in port.scalar_outputs() if name not in monitors and vr[name] not in known]
        self._monitor_names = monitors
        output_vrs = [v for b in spec.outputs for v in block_vr[b]]
        monitor_vrs = ([vr[fmi_name(f"fold_angle_{h}")] for h in self.hinges]
                       + [vr[fmi_name(f"latch_time_{h}")] for h in self.hinges] + [vr[name] for name in monitors]
                       + [vr[fmi_name(name)] for name in sensor_names])
        # get_outputs reads the monitors in the same call and keeps them until the unit steps or is set
        # (its outputs change only then): one fmi2GetReal per unit and step instead of two
        self._get_out = port.reader(output_vrs + monitor_vrs)
        self._n_outputs, self._monitor_values = len(output_vrs), None
        self._set_in = port.writer([v for b in spec.inputs for v in block_vr[b]])
        self._get_mon = port.reader(monitor_vrs)
        self.topology_hash = port.get_string(vr["topology_hash"])

        port.setup()
        if parameters:
            names = {p: fmi_name(p) for p in parameters}
            unknown = [p for p, f in names.items() if f not in vr]
            if unknown:
                raise UnitError(f"{port.label}: unknown parameter(s) {', '.join(unknown)}")
            port.writer([vr[names[p]] for p in parameters])(np.array(list(parameters.values()), float))
        port.initialize()

    @property
    def label(self) -> str:
        return self._port.label

    def get_outputs(self) -> tuple[np.ndarray, ...]:
        """The output blocks in order (structure: e, de; aero: Q), fresh arrays."""
        out = self._get_out()  # a fresh array, not the transfer buffer
        self._monitor_values = out[self._n_outputs:]
        return tuple(out[k * self.n:(k + 1) * self.n] for k in range(len(self._spec.outputs)))

    def set_inputs(self, *blocks) -> None:
        """The input blocks in order (structure: Q; aero: e, de), each of shape (n,)."""
        names = self._spec.inputs
        if len(blocks) != len(names):
            raise UnitError(f"{self._port.label}: set_inputs takes {', '.join(names)} "
                            f"({len(names)} arrays), got {len(blocks)}")
        arrays = [np.asarray(b, dtype=float) for b in blocks]
        for name, a in zip(names, arrays):
            if a.shape != (self.n,):
                raise UnitError(f"{self._port.label}: {name} has shape {a.shape}, expected ({self.n},)")
        self._monitor_values = None
        self._set_in(arrays[0] if len(arrays) == 1 else np.concatenate(arrays))

    def do_step(self, t: float, h: float) -> None:
        self._monitor_values = None
        self._port.do_step(float(t), float(h))

    def monitors(self) -> dict:
        m = self._get_mon() if self._monitor_values is None else self._monitor_values
        h = len(self.hinges)
        angles, latch_times = m[:h], m[h:2 * h]          # the order of monitor_vrs in __init__
        k, p = 2 * h + len(self._monitor_names), 3 * len(self.probes)
        out = {name: float(v) for name, v in zip(self._monitor_names, m[2 * h:k])}
        if self._spec.hinge_monitors:
            out["fold_angles_deg"] = {name: float(a) for name, a in zip(self.hinges, angles)}
            out["latch_times"] = {name: float(t) for name, t in zip(self.hinges, latch_times) if t != LATCH_PENDING}
        if self._spec.sensor_monitors:
            positions, velocities = m[k:k + p].reshape(-1, 3).copy(), m[k + p:k + 2 * p].reshape(-1, 3).copy()
            out["probe_positions"] = dict(zip(self.probes, positions))
            out["probe_velocities"] = dict(zip(self.probes, velocities))
            out["strains"] = {name: float(v) for name, v in zip(self.gauges, m[k + 2 * p:])}
        return out

    def get_state(self):
        return self._port.get_state()

    def set_state(self, state) -> None:
        self._monitor_values = None
        self._port.set_state(state)

    def serialize_state(self, state) -> bytes:
        """A state from get_state() as bytes (fmi2SerializeFMUstate for the fmu backend)."""
        return self._port.serialize_state(state)

    def deserialize_state(self, data: bytes):
        """The inverse of serialize_state: a state usable with set_state()."""
        return self._port.deserialize_state(data)

    def terminate(self) -> None:
        self._port.close()


# ---- fmpy backend -----------------------------------------------------------------------------------
class _FmuState:
    """An fmi2FMUstate of one instance, freed when collected (or when the instance goes away first)."""

    def __init__(self, port: "_FmuPort", handle):
        self._port, self.handle = weakref.ref(port), handle
        port._live_states.add(self)

    def free(self):
        port = self._port()
        if self.handle is not None and port is not None and port._fmu is not None:
            try:
                port._fmu.fmi2FreeFMUstate(port._fmu.component, byref(self.handle))
            except Exception:  # noqa: BLE001 - freeing is best effort
                pass
        self.handle = None

    def __del__(self):
        self.free()


class _FmuPort:
    backend = "fmu"

    def __init__(self, fmu_path: Path, scene: dict, instance_name: str, spec: UnitKind = KINDS["structure"]):
        from fmpy import extract, read_model_description
        from fmpy.fmi1 import calloc, free
        from fmpy.fmi2 import (FMU2Slave, fmi2CallbackAllocateMemoryTYPE, fmi2CallbackFreeMemoryTYPE,
                               fmi2CallbackFunctions, fmi2CallbackLoggerTYPE)

        self.label = f"{instance_name} ({fmu_path.name}, fmu)"
        self._fmu = None
        self._dir = None
        self._live_states = weakref.WeakSet()
        self._initialized = False
        self.log: list[LogEntry] = []
        if not fmu_path.is_file():
            raise UnitError(f"{self.label}: {fmu_path} not found; build it first (wingsim build SCENE)")
        try:
            md = read_model_description(str(fmu_path))
            self._dir = extract(str(fmu_path))
        except Exception as exc:
            self.close()
            raise UnitError(f"{self.label}: cannot read {fmu_path}: {exc}") from exc
        try:
            self._check_scene(scene, spec.scene_sections)
            self._check_layout(md, spec)
        except UnitError:
            self.close()
            raise
        self._vr = {v.name: v.valueReference for v in md.modelVariables}
        self._scalar_outputs = [v.name for v in md.modelVariables if v.causality == "output"
                                and v.type == "Real" and not _INDEXED.match(v.name)]

        def logger(env, inst, status, category, message):
            # The FMU's printf-style message arrives unformatted: fmpy's formatting proxy (addLoggerProxy) is
            # not used, as it keeps ONE logger for the whole process (messages of every instance would go to
            # the last one registered, and into freed memory once that one is gone). The slave doubles '%'.
            text = message.decode("utf-8", "replace") if message else ""
            self.log.append(LogEntry(int(status), category.decode("utf-8", "replace") if category else "",
                                     text.replace("%%", "%")))

        self._callbacks = fmi2CallbackFunctions()
        self._callbacks.logger = fmi2CallbackLoggerTYPE(logger)
        self._callbacks.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
        self._callbacks.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
        fmu = FMU2Slave(guid=md.guid, unzipDirectory=self._dir,
                        modelIdentifier=md.coSimulation.modelIdentifier, instanceName=instance_name)
        try:
            self._call("fmi2Instantiate", fmu.instantiate, callbacks=self._callbacks, loggingOn=True)
        except UnitError:
            self.close()
            raise
        self._fmu = fmu

    def _check_scene(self, scene: dict, sections: tuple[str, ...]) -> None:
        """Refuse an FMU built from a different scene than `scene` in `sections` (stale build)."""
        try:
            built = json.loads(Path(self._dir, "resources", "scene.json").read_text(encoding="utf-8"))
        except OSError as exc:
            raise UnitError(f"{self.label}: resources/scene.json missing ({exc}); rebuild the FMU") from exc
        keys = []
        for section in sections:
            want = json.loads(json.dumps(scene.get(section)))
            if built.get(section) != want:
                keys += _differing_keys(built.get(section), want, section)
        if keys:
            raise UnitError(f"{self.label} was built from a different scene (differs at {', '.join(keys[:5])}); "
                            "rebuild it (wingsim build SCENE)")

    def _check_layout(self, md, spec: UnitKind) -> None:
        """Refuse an FMU whose model description declares its variables otherwise than its unit's code
        registers them (names, value references, causality, variability, type, unit: `orchestrator.layout`)."""
        from orchestrator.layout import check

        kind = next(k for k, s in KINDS.items() if s == spec)
        problems = check(md, kind, Path(self._dir, "resources"))
        if problems:
            raise UnitError(f"{self.label}: refused: " + "; ".join(problems))

    def _reasons(self, since: int) -> str:
        msgs = [" ".join(m.split()) for s, _, m in self.log[since:] if s >= 1 and m]
        return "; ".join(msgs) if msgs else "no reason logged by the unit"

    def _call(self, what: str, fn, *args, **kwargs):
        """fn(*args); UnitError if it fails (fmpy raises on a status above warning) or logs an error."""
        mark = len(self.log)
        try:
            result = fn(*args, **kwargs)
        except Exception as exc:
            raise UnitError(f"{self.label}: {what} failed ({exc}): {self._reasons(mark)}",
                            diverged=_reported_divergence(self.log[mark:])) from None
        if any(entry.status >= _ERROR for entry in self.log[mark:]):
            raise UnitError(f"{self.label}: {what} failed: {self._reasons(mark)}",
                            diverged=_reported_divergence(self.log[mark:]))
        return result

    def value_references(self) -> dict[str, int]:
        return dict(self._vr)

    def scalar_outputs(self) -> list[str]:
        """Names of the Real outputs that are not indexed blocks, in value-reference order."""
        return list(self._scalar_outputs)

    def reader(self, vrs: list[int]):
        from fmpy.fmi2 import fmi2Real, fmi2ValueReference
        n = len(vrs)
        vr_arr, buf = (fmi2ValueReference * n)(*vrs), (fmi2Real * n)()
        view = np.ctypeslib.as_array(buf)

        def read() -> np.ndarray:
            self._call("fmi2GetReal", self._fmu.fmi2GetReal, self._fmu.component, vr_arr, n, buf)
            return view.copy()
        return read

    def writer(self, vrs: list[int]):
        from fmpy.fmi2 import fmi2Real, fmi2ValueReference
        n = len(vrs)
        vr_arr, buf = (fmi2ValueReference * n)(*vrs), (fmi2Real * n)()
        view = np.ctypeslib.as_array(buf)

        def write(values: np.ndarray) -> None:
            view[:] = values
            self._call("fmi2SetReal", self._fmu.fmi2SetReal, self._fmu.component, vr_arr, n, buf)
        return write

    def get_string(self, vr: int) -> str:
        return self._call("fmi2GetString", self._fmu.getString, [vr])[0].decode("utf-8")

    def setup(self) -> None:
        self._call("fmi2SetupExperiment", self._fmu.setupExperiment, startTime=0.0)
        self._call("fmi2EnterInitializationMode", self._fmu.enterInitializationMode)

    def initialize(self) -> None:
        self._call("fmi2ExitInitializationMode", self._fmu.exitInitializationMode)
        self._initialized = True

    def do_step(self, t: float, h: float) -> None:
        from fmpy.fmi2 import fmi2False
        self._call(f"fmi2DoStep(t = {t:.6g} s, h = {h:.6g} s)", self._fmu.fmi2DoStep,
                   self._fmu.component, t, h, fmi2False)

    def get_state(self) -> _FmuState:
        return _FmuState(self, self._call("fmi2GetFMUstate", self._fmu.getFMUstate))

    def set_state(self, state: _FmuState) -> None:
        if not isinstance(state, _FmuState) or state._port() is not self or state.handle is None:
            raise UnitError(f"{self.label}: set_state needs a live state from this unit's get_state()")
        self._call("fmi2SetFMUstate", self._fmu.setFMUstate, state.handle)

    def serialize_state(self, state: _FmuState) -> bytes:
        return bytes(self._call("fmi2SerializeFMUstate", self._fmu.serializeFMUstate, state.handle))

    def deserialize_state(self, data: bytes) -> _FmuState:
        return _FmuState(self, self._call("fmi2DeSerializeFMUstate", self._fmu.deSerializeFMUstate, data))

    def close(self) -> None:
        if self._fmu is not None:
            for s in list(self._live_states):  # states are freed while the instance still exists
                s.free()
            fmu, self._fmu = self._fmu, None
            for fn in ((fmu.terminate,) if self._initialized else ()) + (fmu.freeInstance,):
                try:
                    fn()
                except Exception:  # noqa: BLE001 - e.g. terminate after a fatal status; free anyway
                    pass
        if self._dir is not None:
            # pythonfmu put <dir>/resources first on sys.path at instantiation: take it out with the folder
            resources = os.path.normpath(os.path.join(self._dir, "resources"))
            sys.path[:] = [p for p in sys.path if os.path.normpath(p) != resources]
            shutil.rmtree(self._dir, ignore_errors=True)
            self._dir = None


# ---- in-process backend -----------------------------------------------------------------------------
class _DirectPort:
    backend = "direct"

    def __init__(self, scene: dict, instance_name: str, spec: UnitKind = KINDS["structure"]):
        module = importlib.import_module(spec.slave[0])
        slave_class = getattr(module, spec.slave[1])

        self.label = f"{instance_name} (direct)"
        self._slave = None
        self._tmp = tempfile.TemporaryDirectory(prefix="wingsim_direct_")
        Path(self._tmp.name, SCENE_RESOURCE).write_text(json.dumps(scene), encoding="utf-8")
        self.log: list[LogEntry] = []
        self._slave = self._call("instantiate", slave_class, instance_name=instance_name,
                                 resources=self._tmp.name)

    def _call(self, what: str, fn, *args, ok_on_false: bool = True, **kwargs):
        slave = self._slave
        try:
            result = fn(*args, **kwargs)
        except Exception as exc:  # noqa: BLE001 - as fmi2Fatal through the FMU: report, never crash
            reasons = _warnings_and_errors(self._drain(slave))
            raise UnitError(f"{self.label}: {what} failed ({type(exc).__name__}: {exc})"
                            + (f": {reasons}" if reasons else "")) from exc
        new = self._drain(slave)
        if any(entry.status >= _ERROR for entry in new) or (result is False and not ok_on_false):
            reasons = _warnings_and_errors(new) or "no reason logged by the unit"
            raise UnitError(f"{self.label}: {what} failed: {reasons}", diverged=_reported_divergence(new))
        return result

    def _drain(self, slave) -> list[LogEntry]:
        """Move the slave's queued log messages to self.log; returns them."""
        if slave is None:
            return []
        # the slave doubles '%' for the FMI logger's printf formatting: undo it as that logger would
        new = [LogEntry(int(m.status), m.category or "", m.msg.replace("%%", "%")) for m in slave.log_queue]
        slave.log_queue.clear()
        self.log += new
        return new

    def value_references(self) -> dict[str, int]:
        return {v.name: vr for vr, v in self._slave.vars.items()}

    def scalar_outputs(self) -> list[str]:
        """Names of the Real outputs that are not indexed blocks, in value-reference order."""
        from pythonfmu import Fmi2Causality, Real
        return [v.name for _, v in sorted(self._slave.vars.items()) if isinstance(v, Real)
                and v.causality == Fmi2Causality.output and not _INDEXED.match(v.name)]

    def reader(self, vrs: list[int]):
        vrs = list(vrs)

        def read() -> np.ndarray:
            return np.array(self._call("get_real", self._slave.get_real, vrs))
        return read

    def writer(self, vrs: list[int]):
        vrs = list(vrs)

        def write(values: np.ndarray) -> None:
            self._call("set_real", self._slave.set_real, vrs, np.asarray(values, float).tolist())
        return write

    def get_string(self, vr: int) -> str:
        return self._call("get_string", self._slave.get_string, [vr])[0]

    def setup(self) -> None:
        self._call("setup_experiment", self._slave.setup_experiment, 0.0, None, None)
        self._call("enter_initialization_mode", self._slave.enter_initialization_mode)

    def initialize(self) -> None:
        self._call("exit_initialization_mode", self._slave.exit_initialization_mode)

    def do_step(self, t: float, h: float) -> None:
        self._call(f"do_step(t = {t:.6g} s, h = {h:.6g} s)", self._slave.do_step, t, h, ok_on_false=False)

    def get_state(self):
        return self._call("get_fmu_state", self._slave._get_fmu_state)

    def set_state(self, state) -> None:
        self._call("set_fmu_state", self._slave._set_fmu_state, state)

    def serialize_state(self, state) -> bytes:
        return self._call("fmu_state_to_bytes", self._slave._fmu_state_to_bytes, state)

    def deserialize_state(self, data: bytes):
        return self._call("fmu_state_from_bytes", self._slave._fmu_state_from_bytes, data)

    def close(self) -> None:
        slave, self._slave = self._slave, None
        if slave is not None:
            try:
                slave.terminate()
            except Exception:  # noqa: BLE001
                pass
        if self._tmp is not None:
            self._tmp.cleanup()
            self._tmp = None


def _warnings_and_errors(entries: list[LogEntry]) -> str:
    """The texts of the warnings and errors among `entries`, joined by '; '."""
    return "; ".join(entry.text for entry in entries if entry.status >= 1)


def _differing_keys(a, b, prefix: str) -> list[str]:
    """Dotted keys at which two JSON-like values differ."""
    if isinstance(a, dict) and isinstance(b, dict):
        out = []
        for k in list(a) + [k for k in b if k not in a]:
            out += _differing_keys(a.get(k), b.get(k), f"{prefix}.{k}")
        return out
    if isinstance(a, list) and isinstance(b, list) and len(a) == len(b):
        out = []
        for i, (x, y) in enumerate(zip(a, b)):
            out += _differing_keys(x, y, f"{prefix}[{i}]")
        return out
    return [] if a == b else [prefix]
