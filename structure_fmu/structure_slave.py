"""FMI 2.0 co-simulation slave of the structure unit (pythonfmu), a thin adapter over StructureSolver.

No physics lives here: every number comes from `structure_fmu.solver.StructureSolver` (docs/solver_api.md).
The resolved scene is read from the resource `scene.json` (inside the FMU, or the folder given as
`resources` when the class is instantiated in-process by the `direct` backend).

Its variables are the rows of `structure_fmu.interface.STRUCTURE`, laid out, registered and published by
`fmu_common.fmi_slave.SolverSlave`: the coupling blocks e, de (outputs) and Q (input), the monitors and sensors,
the tunable parameters and `topology_hash`, with value references contiguous in that order. The generated
table of docs/fmu.md ("Structure FMU") lists them with their units.

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

# Modules, not classes, are imported: pythonfmu's fmi2Instantiate runs this script once more and keeps, for each
# class the run binds, a list it never frees (fmu_common/fmi_slave.py); the slave class is then the only one, and
# `SolverSlave`'s metaclass makes it the module's own. Pythonfmu's builder picks the one concrete Fmi2Slave
# subclass of this module. Absolute imports: inside the FMU this script sits at the top of resources/, which
# pythonfmu puts on sys.path, beside the embedded packages.
import fmu_common.fmi_slave
import fmu_common.specs
import structure_fmu.interface
import structure_fmu.solver


class StructureSlave(fmu_common.fmi_slave.SolverSlave):
    """The structure unit's FMI 2.0 co-simulation slave over StructureSolver."""

    author = "wingsim"
    label = structure_fmu.interface.STRUCTURE.unit
    model_name = "structure"
    solver_class = structure_fmu.solver.StructureSolver
    spec_class = fmu_common.specs.StructureUnitSpec
    interface = structure_fmu.interface.STRUCTURE
