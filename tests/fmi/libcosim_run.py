"""Run wingsim's structure and aero FMUs in another FMI 2.0 master, the Open Simulation Platform's libcosim.

    python tests/fmi/libcosim_run.py FMU_DIR STEP STOP

Connects e[i], de[i] (structure -> aero) and Q[i] (aero -> structure) for every coordinate, steps libcosim's
fixed-step algorithm (all units step, then values are exchanged: Jacobi), and prints the structure unit's
output `latch_time_fold` (the time the `fold` hinge latched; -1 until then) at the end as
`deployment_time_s=<value>`.
Run as a separate process: libcosim may crash at interpreter exit after a slave failure (docs/fmu.md, libcosim), and
once even after a complete run ("corrupted double-linked list", SIGABRT, after the result was printed: 1 of
the CI runs; 0 of 36 runs here). So the script leaves by os._exit once its answer is printed and flushed,
skipping the interpreter's teardown of libcosim's objects.
"""
import os
import sys
from pathlib import Path

from fmpy import read_model_description
from libcosimpy.CosimExecution import CosimExecution
from libcosimpy.CosimLogging import CosimLogLevel, log_output_level
from libcosimpy.CosimObserver import CosimObserver
from libcosimpy.CosimSlave import CosimLocalSlave


def main(fmu_dir: Path, step: float, stop: float) -> None:
    log_output_level(CosimLogLevel.ERROR)
    refs = {unit: {v.name: v.valueReference
                   for v in read_model_description(str(fmu_dir / f"{unit}.fmu")).modelVariables}
            for unit in ("structure", "aero")}
    execution = CosimExecution.from_step_size(int(round(step * 1e9)))   # nanoseconds
    structure = execution.add_local_slave(CosimLocalSlave(str(fmu_dir / "structure.fmu"), "structure"))
    aero = execution.add_local_slave(CosimLocalSlave(str(fmu_dir / "aero.fmu"), "aero"))
    n = sum(1 for name in refs["structure"] if name.startswith("e["))
    for i in range(1, n + 1):
        for name in (f"e[{i}]", f"de[{i}]"):
            execution.connect_real_variables(structure, refs["structure"][name], aero, refs["aero"][name])
        execution.connect_real_variables(aero, refs["aero"][f"Q[{i}]"], structure, refs["structure"][f"Q[{i}]"])
    observer = CosimObserver.create_last_value()
    execution.add_observer(observer)
    latch = refs["structure"]["latch_time_fold"]
    for k in range(int(round(stop / step))):
        if not execution.step(1):
            raise SystemExit(f"libcosim step failed at t = {step * k:g} s")
    latch_time = observer.last_real_values(structure, [latch])[0]
    del execution
    if latch_time < 0:
        raise SystemExit("the fold hinge never latched")
    print(f"deployment_time_s={float(latch_time)!r}")


if __name__ == "__main__":
    main(Path(sys.argv[1]), float(sys.argv[2]), float(sys.argv[3]))
    sys.stdout.flush()
    os._exit(0)
