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
    unit.monitors()             the output rows of the unit's table (structure_fmu.interface,
                                aero_fmu.interface) it reads (make_unit's `reads`, default every one), under
                                the row's key, in the row's units:
                                  a row of one variable: its value ("energy": J, "CL": -, ...);
                                  a row of one name per item: {item: value} ("fold_angles_deg": {hinge: deg},
                                    "latch_times": {hinge: s, for the hinges latched so far}, "strains":
                                    {gauge: -}, "joints": {<joint>_point_mismatch: m, <joint>_axis_...: -});
                                  a row of k names per item: {item: (k,)} ("probe_positions": {probe: (3,) m,
                                    global frame}, "probe_velocities", "probe_accelerations")
                                the items of the scene (`scene_items`): its hinges, probes, strain gauges and
                                joint monitors; the master computes none of them itself
    unit.monitor_values()       the same rows as one fresh vector, in one read of the unit (what the master
                                records from, `orchestrator.run.recording`), laid out as
    unit.monitor_layout         says: a `MonitorRow` (key, items, width, slice, pending mark) per row read
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

from fmu_common.interface import OUTPUT, fmi_name
from orchestrator.run.port import KINDS, Port, UnitError, UnitKind
from orchestrator.run.recording import MonitorRow, monitor_dict
from structure_fmu.interface import GAUGES, HINGES, JOINT_MONITORS, PROBES


def scene_items(scene: dict) -> dict[str, list[str]]:
    """{placeholder: the scene's names it stands for} of the per-item rows of the unit tables: its hinges,
    probes, strain gauges and joint monitors, in the scene's order (the unit lays them out in its own; the master
    reads them by name)."""
    from orchestrator.scene.load import hinge_joints, joint_monitor_names

    return {HINGES.placeholder: [j["name"] for j in hinge_joints(scene)],
            PROBES.placeholder: [p["name"] for p in scene["probes"]],
            GAUGES.placeholder: [g["name"] for g in scene["strain_gauges"]],
            JOINT_MONITORS.placeholder: joint_monitor_names(scene)}


def _block_size(name: str, vr: dict) -> int:
    """n: the number of entries name[1], name[2], ... the unit declares."""
    n = 0
    while f"{name}[{n + 1}]" in vr:
        n += 1
    return n


def make_unit(kind: str, scene: dict, backend: str, fmu_dir, parameters: dict | None = None,
              instance_name: str | None = None, check_layout: bool = True, reads=None,
              monitors_with_outputs: bool = False) -> "Unit":
    """Create, set up and initialize a unit of `kind` ("structure" or "aero") for `scene`.

    backend: "fmu" (fmu_dir/<kind>.fmu through fmpy) or "direct" (the slave class in-process; fmu_dir
    unused). Every tunable parameter (StructureSolver / AeroSolver.tunable_parameters: the scene's tunable
    keys) is set to the scene's value before initialization; `parameters` ({name: value}) overrides some.
    check_layout=False skips the fmu backend's layout check (`orchestrator.run.layout`) for a caller that has
    just made it. `reads`: the keys of the output rows `monitors()` reads (the unit computes an output only
    when read, fmu_common.fmi_slave); None: every row. `monitors_with_outputs`: read them with the output blocks, in
    one call (`Unit`). Raises UnitError on any failure, naming what was wrong.
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
        return Unit(port, scene, {**values, **(parameters or {})}, kind, reads=reads,
                    monitors_with_outputs=monitors_with_outputs)
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
    spec = slave_class.spec_class.from_scene(scene)
    return {name: float(v[0]) for name, v in slave_class.solver_class.tunable_parameters(spec).items()}


class Unit:
    """A structure or aero unit driven through a port (fmpy FMU or in-process slave); see the module
    docstring. Its variables are found by name in what the port declares (the model description): the blocks
    of its kind's table (`UnitKind.interface`; `spec` replaces KINDS[kind]'s), then the variables of the output
    rows it reads (`reads`, their keys; None: every row) for the scene's items: the unit computes only those.
    With `monitors_with_outputs` those rows are read in the call that reads the output blocks (get_outputs), and
    `monitor_values()` returns them until the unit steps, is set or is given inputs: for a coupling that records
    every state whose outputs it reads (an explicit one), one read per unit and step."""

    def __init__(self, port, scene: dict, parameters: dict, kind: str = "structure", spec: UnitKind | None = None,
                 reads=None, monitors_with_outputs: bool = False):
        self._port = port
        self.kind = kind
        self._spec = spec = KINDS[kind] if spec is None else spec
        self.backend = port.backend
        vr = port.value_references()
        blocks = spec.interface.blocks
        self.n = n = _block_size(blocks[0].name, vr)
        missing = [name for block in blocks for name in block.names(n) if name not in vr]
        if missing:
            raise UnitError(f"{port.label}: variable {missing[0]} missing (n = {n} from {blocks[0].name}[...])")
        items = scene_items(scene)
        rows = spec.interface.outputs
        if reads is not None:
            unknown = sorted(set(reads) - {row.key for row in rows})
            if unknown:
                raise UnitError(f"{port.label}: no output row {', '.join(unknown)} to read; the rows are "
                                f"{', '.join(row.key for row in rows)}")
            rows = [row for row in rows if row.key in reads]
        # where each row read lies in the vector of the monitors read (monitor_values)
        layout, monitor_names = [], []
        for row in rows:
            if row.items is not None and row.items.placeholder not in items:
                raise UnitError(f"{port.label}: the master does not know what {row.items.placeholder} stands for "
                                f"in a scene (output {row.names[0]})")
            row_items = None if row.items is None else tuple(items[row.items.placeholder])
            names = (list(row.names_of()) if row.items is None else
                     [name for item in row_items for name in row.names_of(item)])
            where = slice(len(monitor_names), len(monitor_names) + len(names))
            layout.append(MonitorRow(row.key, row_items, len(row.names), where, row.pending))
            monitor_names += names
        self.monitor_layout = tuple(layout)
        absent = [name for name in monitor_names if name not in vr]
        if absent:
            raise UnitError(f"{port.label}: no output {absent[0]}; the unit does not match the scene (rebuild "
                            "the FMU)")
        output_vrs = [vr[name] for block in blocks if block.causality == OUTPUT for name in block.names(n)]
        monitor_vrs = [vr[name] for name in monitor_names]
        # get_outputs reads the output blocks and keeps them until the unit steps or is set (its outputs change only
        # then), however often the coupling asks. The monitors are read apart, when recorded (the unit computes an
        # output only when read, so an implicit coupling's rejected iterates compute no monitor), or, with
        # monitors_with_outputs, in the same call as the output blocks: a coupling that records every step it
        # takes then makes one read per unit and step
        self._get_out = port.reader(output_vrs + monitor_vrs if monitors_with_outputs else output_vrs)
        self._with_outputs = len(output_vrs) if monitors_with_outputs else None
        self._monitored = None   # the monitors read with the output blocks, until the unit steps or is set
        self._output_blocks = [slice(k * n, (k + 1) * n) for k in range(len(spec.outputs))]
        self._input_names = spec.inputs
        self._values = self._monitored = None
        self._set_in = port.writer([vr[name] for block in blocks if block.causality != OUTPUT
                                    for name in block.names(n)])
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
            if self._with_outputs is not None:
                self._values, self._monitored = (self._values[:self._with_outputs],
                                                 self._values[self._with_outputs:])
        out = self._values
        return tuple([out[where].copy() for where in self._output_blocks])

    def set_inputs(self, *blocks) -> None:
        """The input blocks in order (structure: Q; aero: e, de), each of shape (n,)."""
        names = self._input_names
        if len(blocks) != len(names):
            raise UnitError(f"{self._port.label}: set_inputs takes {', '.join(names)} "
                            f"({len(names)} arrays), got {len(blocks)}")
        arrays = [np.asarray(b, dtype=float) for b in blocks]
        for name, a in zip(names, arrays):
            if a.shape != (self.n,):
                raise UnitError(f"{self._port.label}: {name} has shape {a.shape}, expected ({self.n},)")
        self._values = self._monitored = None
        self._set_in(arrays[0] if len(arrays) == 1 else np.concatenate(arrays))

    def do_step(self, t: float, h: float) -> None:
        self._values = self._monitored = None
        self._port.do_step(float(t), float(h))

    def monitor_values(self) -> np.ndarray:
        """The output rows read (`reads`), now, as one vector laid out as `monitor_layout` says, which the caller may
        keep (the unit never writes into it): one read of the unit (one fmi2GetReal through an FMU), or none when
        they came with the output blocks (`monitors_with_outputs`) since the unit last changed."""
        return self._get_mon() if self._monitored is None else self._monitored

    def monitors(self) -> dict:
        """The unit's outputs now, row by row of its table (module docstring; `recording.monitor_dict`)."""
        return monitor_dict(self.monitor_layout, self.monitor_values())

    def get_state(self):
        return self._port.get_state()

    def set_state(self, state) -> None:
        self._values = self._monitored = None
        self._port.set_state(state)

    def serialize_state(self, state) -> bytes:
        """A state from get_state() as bytes (fmi2SerializeFMUstate for the fmu backend)."""
        return self._port.serialize_state(state)

    def deserialize_state(self, data: bytes):
        """The inverse of serialize_state: a state usable with set_state()."""
        return self._port.deserialize_state(data)

    def terminate(self) -> None:
        self._port.close()
