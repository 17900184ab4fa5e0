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
                                            "external_work": J,
                                            "fold_angles_deg": {hinge: deg},
                                            "latch_times": {hinge: s, for the hinges latched so far},
                                            "probe_positions": {probe: (3,) m, global frame},
                                            "probe_velocities": {probe: (3,) m/s, global frame},
                                            "probe_accelerations": {probe: (3,) m/s2, global frame},
                                            "strains": {gauge: surface strain, -},
                                            "joints": {<joint>_point_mismatch: m, <joint>_axis_...: -}}
                                (the structure unit's outputs <probe>_x.., <probe>_vx.., <gauge> of the
                                scene's probes and strain gauges, and its joint monitors)
                                aero: {"CL": -, "lift": N, "wake_panels": count, ...every scalar output}
    unit.get_state(), unit.set_state(s)    complete state for rollback (opaque; FMU states are freed
                                when the object is garbage collected or the unit terminated)
    unit.terminate()            end the simulation and free the instance (idempotent, never raises)

Backends (a port each, behind `Unit`): "fmu" (`orchestrator.run.fmu_port`) loads `fmu_dir/<kind>.fmu` with
fmpy (FMU2Slave), every get/set batched over precomputed value-reference arrays and ctypes buffers, every
status checked, log messages captured; "direct" (`orchestrator.run.direct_port`) instantiates the same slave
class (`StructureSlave`, `AeroSlave`) in-process and drives it through the same calls. Both start at t = 0
(FMI start time) and are initialized by `make_unit`.
"""
from __future__ import annotations

import importlib
from pathlib import Path

import numpy as np

from orchestrator.run.port import INDEXED, KINDS, Port, UnitError
from structure_fmu.sensors import output_names as sensor_output_names
from structure_fmu.structure_slave import LATCH_PENDING


def make_unit(kind: str, scene: dict, backend: str, fmu_dir, parameters: dict | None = None,
              instance_name: str | None = None, check_layout: bool = True) -> "Unit":
    """Create, set up and initialize a unit of `kind` ("structure" or "aero") for `scene`.

    backend: "fmu" (fmu_dir/<kind>.fmu through fmpy) or "direct" (the slave class in-process; fmu_dir
    unused). Every tunable parameter (StructureSolver / AeroSolver.tunable_parameters: the scene's tunable
    keys) is set to the scene's value before initialization; `parameters` ({name: value}) overrides some.
    check_layout=False skips the fmu backend's layout check (`orchestrator.run.layout`) for a caller that has
    just made it. Raises UnitError on any failure, naming what was wrong.
    """
    if kind not in KINDS:
        raise UnitError(f"unit kind {kind!r} is not available; available: {', '.join(KINDS)}")
    spec = KINDS[kind]
    # Every tunable parameter at the scene's value: an FMU built from a scene that differs in tunable keys only
    # (orchestrator.build.fmus.build_digest) then runs this scene. This imports the host's packages first: an
    # FMU loaded in this process then shares them instead of importing its embedded copy from a temporary
    # folder that is deleted at terminate().
    values = scene_parameters(kind, scene)
    name = instance_name or kind
    port: Port
    if backend == "fmu":
        from orchestrator.run.fmu_port import FmuPort

        port = FmuPort(Path(fmu_dir) / spec.fmu_file, scene, name, kind, check_layout)
    elif backend == "direct":
        from orchestrator.run.direct_port import DirectPort

        port = DirectPort(scene, name, spec)
    else:
        raise UnitError(f"backend {backend!r} is not known; use 'fmu' or 'direct'")
    try:
        return Unit(port, scene, {**values, **(parameters or {})}, kind)
    except BaseException:
        port.close()
        raise


def scene_parameters(kind: str, scene: dict) -> dict[str, float]:
    """{parameter name: value} of the `kind` unit ("structure" | "aero") for `scene`: its tunable keys at the
    scene's values (StructureSolver / AeroSolver.tunable_parameters). Imports the unit's slave module first,
    so that an FMU loaded later in this process shares the host's packages; UnitError if it does not import."""
    spec = KINDS[kind]
    try:
        slave_class = getattr(importlib.import_module(spec.slave[0]), spec.slave[1])
    except ImportError as exc:
        raise UnitError(f"the {kind} unit cannot be loaded: {spec.slave[0]} does not import ({exc})") from exc
    return {name: float(v[0]) for name, v in slave_class.solver_class.tunable_parameters(scene).items()}


class Unit:
    """A structure or aero unit driven through a port (fmpy FMU or in-process slave); see the module
    docstring."""

    def __init__(self, port, scene: dict, parameters: dict, kind: str = "structure"):
        from fmu_common.fmi_slave import fmi_name
        from orchestrator.scene.load import hinge_joints, joint_monitor_names

        self._port = port
        self.kind = kind
        self._spec = spec = KINDS[kind]
        self.backend = port.backend
        vr = port.value_references()
        idx = {(m.group(1), int(m.group(2))): v for name, v in vr.items() if (m := INDEXED.match(name))}
        self.n = n = sum(1 for (block, _) in idx if block == spec.outputs[0])
        try:
            block_vr = {b: [idx[(b, i)] for i in range(1, n + 1)] for b in (*spec.outputs, *spec.inputs)}
        except KeyError as exc:
            raise UnitError(f"{port.label}: variable {exc.args[0][0]}[{exc.args[0][1]}] missing "
                            f"(n = {n} from {spec.outputs[0]}[...])") from None
        self.hinges = [j["name"] for j in hinge_joints(scene)] if spec.hinge_monitors else []
        missing = [f"{kind}_{h}" for h in self.hinges for kind in ("fold_angle", "latch_time")
                   if fmi_name(f"{kind}_{h}") not in vr]
        if missing:
            raise UnitError(f"{port.label}: no output {missing[0]}; the unit does not match the scene (rebuild "
                            "the FMU)")
        self.probes = [p["name"] for p in scene["probes"]] if spec.sensor_monitors else []
        self.gauges = [g["name"] for g in scene["strain_gauges"]] if spec.sensor_monitors else []
        self.joint_monitors = joint_monitor_names(scene) if spec.sensor_monitors else []
        sensor_names = sensor_output_names(self.probes, self.gauges) + self.joint_monitors
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
        # get_outputs reads the monitors in the same call and keeps both until the unit steps or is set (its
        # outputs change only then): one fmi2GetReal per unit and step, however often the master asks
        self._get_out = port.reader(output_vrs + monitor_vrs)
        self._n_outputs, self._values = len(output_vrs), None
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
        if self._values is None:
            self._values = self._get_out()  # a fresh array, not the transfer buffer
        out = self._values
        return tuple(out[k * self.n:(k + 1) * self.n].copy() for k in range(len(self._spec.outputs)))

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
        self._values = None
        self._set_in(arrays[0] if len(arrays) == 1 else np.concatenate(arrays))

    def do_step(self, t: float, h: float) -> None:
        self._values = None
        self._port.do_step(float(t), float(h))

    def monitors(self) -> dict:
        m = self._get_mon() if self._values is None else self._values[self._n_outputs:]
        h = len(self.hinges)
        angles, latch_times = m[:h], m[h:2 * h]          # the order of monitor_vrs in __init__
        k, p = 2 * h + len(self._monitor_names), 3 * len(self.probes)      # p: values per kind of probe output
        out = {name: float(v) for name, v in zip(self._monitor_names, m[2 * h:k])}
        if self._spec.hinge_monitors:
            out["fold_angles_deg"] = {name: float(a) for name, a in zip(self.hinges, angles)}
            out["latch_times"] = {name: float(t) for name, t in zip(self.hinges, latch_times) if t != LATCH_PENDING}
        if self._spec.sensor_monitors:
            for j, kind in enumerate(("probe_positions", "probe_velocities", "probe_accelerations")):
                out[kind] = dict(zip(self.probes, m[k + j * p:k + (j + 1) * p].reshape(-1, 3).copy()))
            g = k + 3 * p + len(self.gauges)
            out["strains"] = {name: float(v) for name, v in zip(self.gauges, m[k + 3 * p:g])}
            out["joints"] = {name: float(v) for name, v in zip(self.joint_monitors, m[g:])}
        return out

    def get_state(self):
        return self._port.get_state()

    def set_state(self, state) -> None:
        self._values = None
        self._port.set_state(state)

    def serialize_state(self, state) -> bytes:
        """A state from get_state() as bytes (fmi2SerializeFMUstate for the fmu backend)."""
        return self._port.serialize_state(state)

    def deserialize_state(self, data: bytes):
        """The inverse of serialize_state: a state usable with set_state()."""
        return self._port.deserialize_state(data)

    def terminate(self) -> None:
        self._port.close()
