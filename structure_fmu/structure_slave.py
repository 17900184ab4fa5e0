"""FMI 2.0 co-simulation slave of the structure unit (pythonfmu), a thin adapter over StructureSolver.

No physics lives here: every number comes from `structure_fmu.solver.StructureSolver` (docs/solver_api.md).
The resolved scene is read from the resource `scene.json` (inside the FMU, or the folder given as
`resources` when the class is instantiated in-process by the `direct` backend).

Variables, with value references laid out contiguously so that get/set are numpy fancy indexing
(n = Topology.n_coordinates, H = number of hinges, P = number of probes, G = number of strain gauges;
s = 3n+2H+4, the first sensor output):

| vr                | name                      | causality / variability  | unit                              |
|-------------------|---------------------------|--------------------------|-----------------------------------|
| 0 .. n-1          | e[1] .. e[n]              | output, continuous       | m for r, 1 for r_x, r_y           |
| n .. 2n-1         | de[1] .. de[n]            | output, continuous       | m/s for r, 1/s for r_x, r_y       |
| 2n .. 3n-1        | Q[1] .. Q[n]              | input, continuous (0)    | N for r, N.m for r_x, r_y         |
| 3n .. 3n+H-1      | fold_angle_<hinge>        | output, continuous       | deg                               |
| 3n+H              | energy                    | output, continuous       | J                                 |
| 3n+H+1            | kinetic_energy            | output, continuous       | J                                 |
| 3n+H+2            | constraint_residual       | output, continuous       | 1                                 |
| 3n+H+3            | external_work             | output, continuous       | J                                 |
| 3n+H+4 .. 3n+2H+3 | latch_time_<hinge>        | output, discrete         | s                                 |
| s .. s+3P-1       | <probe>_x, _y, _z         | output, continuous       | m (global frame)                  |
| s+3P .. s+6P-1    | <probe>_vx, _vy, _vz      | output, continuous       | m/s (global frame)                |
| s+6P .. s+9P-1    | <probe>_ax, _ay, _az      | output, continuous       | m/s2 (global frame)               |
| s+9P .. s+9P+G-1  | <gauge>                   | output, continuous       | 1 (surface strain)                |
| then              | <joint>_point_mismatch, <joint>_axis_product, <joint>_axis_error | output, continuous | m, 1, 1 |
| then              | <tunable parameter>       | parameter, fixed         | as StructureSolver declares       |
| last              | topology_hash (String)    | output, constant         | -                                 |

Per node the 9 coordinates are r (3), r_x (3), r_y (3) in the global frame; Q is work-conjugate to e,
hence N for r and N.m (= J) for the dimensionless gradients.

The probes and strain gauges are those of the scene, in its order, named as the columns of wingsim's
timeseries.csv (quoted by `fmi_name` where a name is not an identifier); the solver computes them
(`structure_fmu.sensors`): a probe's position and velocity are its shape row on e and de, a gauge's strain
is its surface distance times the flap curvature.

latch_time_<hinge> is the time (FMI time, s) at which the hinge latched: its fold angle reached the stop
within an internal step of the solver, interpolated linearly in that step (StructureSolver). It is
LATCH_PENDING (-1 s) until then, and stays so for a hinge without a stop. The master reads the
deployment time from it instead of from the fold angles at the communication points, which the latch
arrests within a step.

Errors (fmu_common/fmi_slave.py lists every refused call): after construction no FMI call raises. A
refused call logs its reason at error status and returns with the state unchanged; through the FMU's
shim it answers fmi2Error. `do_step` is refused before initialization and after terminate, for a step size
that is not finite and > 0, and for a communication point that is not the unit's time (FMI start time +
solver time): a gap is never integrated in one call, a step is never repeated without restoring a state.
A non-finite Q, `InputError`, `SolverDiverged` or any other failure in the step is logged the same way and
`do_step` returns False with the state unchanged; the host can roll back or stop. Hosts of pythonfmu's own
binary (no shim) get fmi2OK or fmi2Discard and must treat an error-status log message as a failed call
(orchestrator.run.units does).
"""
from __future__ import annotations

# first: inside an FMU, one message names every package the Python it runs in lacks (fmu_common/dependencies.py)
from fmu_common import dependencies  # noqa: F401
import numpy as np
from pythonfmu import DefaultExperiment, Fmi2Causality, Fmi2Initial, Fmi2Variability

# Only functions and the abstract SolverSlave are imported: pythonfmu's builder picks the one concrete
# Fmi2Slave subclass of this module. Absolute imports: inside the FMU this script sits at the top of
# resources/, which pythonfmu puts on sys.path, beside the embedded packages.
from fmu_common.fmi_slave import COORDINATE_UNITS, SolverSlave, coordinate_description, fmi_name, read_scene
from fmu_common.specs import StructureUnitSpec
from structure_fmu.solver import StructureSolver

LATCH_PENDING = -1.0
"""Value (s) of latch_time_<hinge> until the hinge latches. Latch times are at or after the start time,
which wingsim's master sets to 0."""


class StructureSlave(SolverSlave):
    author = "wingsim"
    description = "Structure unit: ANCF or strain-based wing bodies, joints, actuators and latches (wingsim)"
    label = "structure unit"
    solver_class = StructureSolver

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.scene = read_scene(self.resources, self.label)
        self.spec = StructureUnitSpec.from_scene(self.scene)
        self.modelName = "structure"
        self._start(StructureSolver.tunable_parameters(self.spec))
        self.topology = self._solver.topology
        self.topology_hash = str(self.topology.topology_hash)
        n = self.n = int(self.topology.n_coordinates)
        self.hinges = list(self.topology.hinge_names)

        nh, npar = len(self.hinges), len(self.tunables)
        self.sl_e, self.sl_de, self.sl_q = slice(0, n), slice(n, 2 * n), slice(2 * n, 3 * n)
        self.input_blocks = [("Q", self.sl_q, "generalized force on")]
        self.sl_fold = slice(3 * n, 3 * n + nh)
        self.i_energy, self.i_kinetic, self.i_residual = 3 * n + nh, 3 * n + nh + 1, 3 * n + nh + 2
        self.i_work = 3 * n + nh + 3
        self.sl_latch = slice(3 * n + nh + 4, 3 * n + 2 * nh + 4)
        self.sensor_names = self._solver.sensors.output_names()
        self.sl_sensor = slice(self.sl_latch.stop, self.sl_latch.stop + len(self.sensor_names))
        self.joint_monitor_names = self._solver.joint_monitor_names()
        self.sl_joint = slice(self.sl_sensor.stop, self.sl_sensor.stop + len(self.joint_monitor_names))
        self.sl_par = slice(self.sl_joint.stop, self.sl_joint.stop + npar)
        self._real = np.zeros(self.sl_par.stop)
        self._real[self.sl_par] = list(self.defaults.values())
        self._settable = np.zeros(self._real.size, dtype=bool)
        self._settable[self.sl_q] = True
        self._settable[self.sl_par] = True
        self._publish()
        self._register(n)

        stop, step = self.scene["time"]["stop"], self.scene["coupling"]["step"]
        self.default_experiment = DefaultExperiment(start_time=0.0, stop_time=stop, step_size=step)

    def _register(self, n):
        out = dict(causality=Fmi2Causality.output, variability=Fmi2Variability.continuous,
                   initial=Fmi2Initial.exact)
        for k in range(n):
            node, comp, vec = coordinate_description(self.topology, k)
            self._reg(f"e[{k + 1}]", k, COORDINATE_UNITS[vec][0], f"node {node} {comp}", **out)
        for k in range(n):
            node, comp, vec = coordinate_description(self.topology, k)
            self._reg(f"de[{k + 1}]", n + k, COORDINATE_UNITS[vec][1], f"rate of node {node} {comp}", **out)
        for k in range(n):
            node, comp, vec = coordinate_description(self.topology, k)
            self._reg(f"Q[{k + 1}]", 2 * n + k, COORDINATE_UNITS[vec][2], f"generalized force on node {node} {comp}",
                      causality=Fmi2Causality.input, variability=Fmi2Variability.continuous, start=0.0)
        for j, hinge in enumerate(self.hinges):
            self._reg(fmi_name(f"fold_angle_{hinge}"), self.sl_fold.start + j, "deg",
                      f"fold angle of hinge {hinge} (child root r_x from parent tip r_x, about r_y)", **out)
        self._reg("energy", self.i_energy, "J", "energy monitor of the structure solver", **out)
        self._reg("kinetic_energy", self.i_kinetic, "J", "kinetic energy of the structure (1/2 de^T M de)",
                  **out)
        self._reg("constraint_residual", self.i_residual, "1", "constraint residual monitor (max norm)", **out)
        self._reg("external_work", self.i_work, "J", "work of the point loads and Q since the start: energy minus "
                                                     "it changes only by damping and driven motions", **out)
        for j, hinge in enumerate(self.hinges):
            self._reg(fmi_name(f"latch_time_{hinge}"), self.sl_latch.start + j, "s",
                      f"time hinge {hinge} latched at its stop angle ({LATCH_PENDING:g} until then)",
                      **{**out, "variability": Fmi2Variability.discrete})
        for j, (name, unit, text) in enumerate(self._solver.sensors.output_declarations()):
            self._reg(fmi_name(name), self.sl_sensor.start + j, unit, text, **out)
        for j, name in enumerate(self.joint_monitor_names):
            point = name.endswith("_point_mismatch")
            text = ("distance between the parent's tip and the child's root" if point else
                    "axis condition of the joint, 0 while it holds")
            self._reg(fmi_name(name), self.sl_joint.start + j, "m" if point else "1", text, **out)
        self._register_parameters_and_hash("aero unit")

    def _publish(self):
        """Copy the solver's state and monitors into the output slots of the value buffer."""
        s = self._solver
        self._real[self.sl_e] = s.e
        self._real[self.sl_de] = s.de
        if self.hinges:
            angles = s.fold_angles_deg()
            self._real[self.sl_fold] = [angles[h] for h in self.hinges]
        m = s.monitors()
        self._real[self.i_energy] = m["energy"]
        self._real[self.i_kinetic] = m["kinetic_energy"]
        self._real[self.i_residual] = m["constraint_residual"]
        self._real[self.i_work] = m["external_work"]
        self._real[self.sl_latch] = [self._t0 + m["latch_times"][h] if h in m["latch_times"] else LATCH_PENDING
                                     for h in self.hinges]
        self._real[self.sl_sensor] = s.sensor_outputs()
        joints = s.joint_monitors()
        self._real[self.sl_joint] = [joints[name] for name in self.joint_monitor_names]
