"""FMI 2.0 co-simulation slave of the aero unit (pythonfmu), a thin adapter over AeroSolver.

No physics lives here: every number comes from `aero_fmu.solver.AeroSolver` (docs/aero_api.md). The
resolved scene is read from the resource `scene.json` (inside the FMU, or the folder given as `resources`
when the class is instantiated in-process by the `direct` backend). The structural topology, and so n and
`topology_hash`, come from `fmu_common.topology.Topology` exactly as in the structure unit.

The module name differs from the structure unit's (`structure_slave`): pythonfmu imports the slave script
by its file name, and two FMUs in one process need distinct names (docs/fmu.md).

Its variables are the rows of `aero_fmu.interface.AERO`, laid out, registered and published by
`fmu_common.fmi_slave.SolverSlave`: the coupling blocks e, de (inputs, starting at the scene's initial
coordinates and at 0) and Q (output, work-conjugate to e, Otsuka et al. 2019, Eq. 12), the scalar outputs of
AeroSolver.outputs(), the tunable parameters (AeroSolver.tunable_parameters(spec)) and `topology_hash`, with
value references contiguous in that order. The generated table of docs/fmu.md ("Aero FMU") lists them with
their units.

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

# Modules, not classes, are imported: pythonfmu's fmi2Instantiate runs this script once more and keeps, for each
# class the run binds, a list it never frees (fmu_common/fmi_slave.py); the slave class is then the only one, and
# `SolverSlave`'s metaclass makes it the module's own. Pythonfmu's builder picks the one concrete Fmi2Slave
# subclass of this module. Absolute imports: inside the FMU this script sits at the top of resources/, which
# pythonfmu puts on sys.path, beside the embedded packages.
import fmu_common.fmi_slave
import fmu_common.specs
import aero_fmu.interface
import aero_fmu.solver


class AeroSlave(fmu_common.fmi_slave.SolverSlave):
    """The aero unit's FMI 2.0 co-simulation slave over AeroSolver."""

    author = "wingsim"
    label = aero_fmu.interface.AERO.unit
    model_name = "aero"
    solver_class = aero_fmu.solver.AeroSolver
    spec_class = fmu_common.specs.AeroUnitSpec
    interface = aero_fmu.interface.AERO
