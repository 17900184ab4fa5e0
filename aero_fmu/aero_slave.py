"""FMI 2.0 co-simulation slave of the aero unit (pythonfmu), a thin adapter over AeroSolver.

No physics lives here: every number comes from `aero_fmu.solver.AeroSolver` (docs/aero_api.md). The
resolved scene is read from the resource `scene.json` (inside the FMU, or the folder given as `resources`
when the class is instantiated in-process by the `direct` backend). The structural topology, and so n and
`topology_hash`, come from `fmu_common.topology.Topology` exactly as in the structure unit.

The module name differs from the structure unit's (`structure_slave`): pythonfmu imports the slave script
by its file name, and two FMUs in one process need distinct names (docs/fmu.md).

Variables, value references laid out contiguously so that get/set are numpy fancy indexing
(n = Topology.n_coordinates, K = number of extra scalar outputs of the solver, P = tunable parameters):

| vr                | name                      | causality / variability  | unit                              |
|-------------------|---------------------------|--------------------------|-----------------------------------|
| 0 .. n-1          | e[1] .. e[n]              | input, continuous        | m for r, 1 for r_x, r_y           |
| n .. 2n-1         | de[1] .. de[n]            | input, continuous (0)    | m/s for r, 1/s for r_x, r_y       |
| 2n .. 3n-1        | Q[1] .. Q[n]              | output, continuous       | N for r, N.m for r_x, r_y         |
| 3n                | CL                        | output, continuous       | 1 (lift / (q S_ref))              |
| 3n+1              | lift                      | output, continuous       | N                                 |
| 3n+2              | wake_panels               | output, continuous       | 1 (a count, published as Real)    |
| 3n+3 .. 3n+2+K    | other scalar outputs of AeroSolver.outputs(), in its order (e.g. drag, moments) |
| 3n+3+K ..         | <tunable parameter>       | parameter, fixed         | as AeroSolver declares            |
| last              | topology_hash (String)    | output, constant         | -                                 |

The start values of e are the scene's initial coordinates (Topology.initial_coordinates), of de zero; a
host sets both from the structure unit before each step. Q is work-conjugate to e (Otsuka et al. 2019, Eq. 12).
Parameters are AeroSolver.tunable_parameters(spec); the defaults of flow.direction_x/_y/_z are the
resolved scene's `flow.direction`, normalized.

Errors, exactly as the structure slave (fmu_common/fmi_slave.py lists every refused call): after
construction no FMI call raises. A refused call logs its reason at error status and returns with the state
unchanged; through the FMU's shim it answers fmi2Error. `do_step` is refused before initialization and
after terminate, for a step size that is not finite and > 0, and for a communication point that is not the
unit's time (FMI start time + aero time). A non-finite e or de, `InputError`, `SolverDiverged` or any
other failure in the step is logged the same way and `do_step` returns False, with the state unchanged.
"""
from __future__ import annotations

# first: inside an FMU, one message names every package the Python it runs in lacks (fmu_common/dependencies.py)
from fmu_common import dependencies  # noqa: F401

import math

import numpy as np
from pythonfmu import DefaultExperiment, Fmi2Causality, Fmi2Initial, Fmi2Variability

# Only functions and the abstract SolverSlave are imported: pythonfmu's builder picks the one concrete
# Fmi2Slave subclass of this module. Absolute imports: inside the FMU this script sits at the top of
# resources/, which pythonfmu puts on sys.path, beside the embedded packages.
from aero_fmu.solver import AeroSolver
from fmu_common.fmi_slave import COORDINATE_UNITS, SolverSlave, coordinate_description, fmi_name, read_scene
from fmu_common.specs import AeroUnitSpec

REQUIRED_OUTPUTS = ("CL", "lift", "wake_panels")
# unit and description of every scalar output of AeroSolver.outputs() (aero_fmu/loads.py); the unit refuses
# to register an output missing here rather than publish it without a unit
_OUTPUT_UNITS = {
    "CL": ("1", "lift coefficient: lift / (1/2 rho V^2 S_ref), 0 at zero dynamic pressure"),
    "lift": ("N", "aerodynamic force along the lift axis (normal to the free stream)"),
    "wake_panels": ("1", "number of wake panels (a count, as Real)"),
    "drag": ("N", "aerodynamic force along the free stream"),
    "CD": ("1", "drag coefficient"),
    "side_force": ("N", "aerodynamic side force"),
    "moment_x": ("N.m", "aerodynamic moment about global x"),
    "moment_y": ("N.m", "aerodynamic moment about global y"),
    "moment_z": ("N.m", "aerodynamic moment about global z"),
    "CM": ("1", "moment coefficient"),
}


def _scalar_output_names(outputs: dict) -> list[str]:
    """The required outputs first, then every other finite-or-not real scalar of AeroSolver.outputs()."""
    extra = [k for k, v in outputs.items() if k not in REQUIRED_OUTPUTS
             and isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, bool)]
    return [*REQUIRED_OUTPUTS, *extra]


class AeroSlave(SolverSlave):
    author = "wingsim"
    description = "Aero unit: UVLM (flat, prescribed or free wake) or strip theory on the ANCF wing (wingsim)"
    label = "aero unit"
    solver_class = AeroSolver

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.scene = read_scene(self.resources, self.label)
        self.spec = AeroUnitSpec.from_scene(self.scene)
        self.modelName = "aero"
        tunables = AeroSolver.tunable_parameters(self.spec)
        self._start(tunables)
        self.topology = self._solver.topology
        self.topology_hash = str(self.topology.topology_hash)
        n = self.n = int(self.topology.n_coordinates)
        self.output_names = _scalar_output_names(self._solver.outputs())

        k, npar = len(self.output_names), len(self.tunables)
        self.sl_e, self.sl_de, self.sl_q = slice(0, n), slice(n, 2 * n), slice(2 * n, 3 * n)
        self.input_blocks = [("e", self.sl_e, ""), ("de", self.sl_de, "rate of")]
        self.sl_out = slice(3 * n, 3 * n + k)
        self.sl_par = slice(3 * n + k, 3 * n + k + npar)
        self._real = np.zeros(self.sl_par.stop)
        self._real[self.sl_e] = self.topology.initial_coordinates()
        self._real[self.sl_par] = list(self.defaults.values())
        self._settable = np.zeros(self._real.size, dtype=bool)
        self._settable[self.sl_e] = True
        self._settable[self.sl_de] = True
        self._settable[self.sl_par] = True
        self._publish()
        self._register(n)

        stop, step = self.scene["time"]["stop"], self.scene["coupling"]["step"]
        self.default_experiment = DefaultExperiment(start_time=0.0, stop_time=stop, step_size=step)

    def _register(self, n):
        out = dict(causality=Fmi2Causality.output, variability=Fmi2Variability.continuous,
                   initial=Fmi2Initial.exact)
        inp = dict(causality=Fmi2Causality.input, variability=Fmi2Variability.continuous)
        for k in range(n):
            node, comp, vec = coordinate_description(self.topology, k)
            self._reg(f"e[{k + 1}]", k, COORDINATE_UNITS[vec][0], f"node {node} {comp}",
                      start=float(self._real[k]), **inp)
        for k in range(n):
            node, comp, vec = coordinate_description(self.topology, k)
            self._reg(f"de[{k + 1}]", n + k, COORDINATE_UNITS[vec][1], f"rate of node {node} {comp}", start=0.0, **inp)
        for k in range(n):
            node, comp, vec = coordinate_description(self.topology, k)
            self._reg(f"Q[{k + 1}]", 2 * n + k, COORDINATE_UNITS[vec][2],
                      f"generalized aerodynamic force on node {node} {comp}", **out)
        for j, name in enumerate(self.output_names):
            if name not in _OUTPUT_UNITS:
                raise ValueError(f"{self.label}: AeroSolver output {name!r} has no unit declared in "
                                 "aero_slave._OUTPUT_UNITS")
            unit, text = _OUTPUT_UNITS[name]
            self._reg(fmi_name(name), self.sl_out.start + j, unit, text, **out)
        self._register_parameters_and_hash("structure unit")

    def _publish(self):
        """Copy the solver's Q and scalar outputs into the output slots of the value buffer."""
        s = self._solver
        self._real[self.sl_q] = s.Q
        outputs = s.outputs()
        self._real[self.sl_out] = [float(outputs.get(name, math.nan)) for name in self.output_names]
