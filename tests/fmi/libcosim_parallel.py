"""Step two instances of one FMU in libcosim, which steps its slaves in parallel threads (not a test module).

    python tests/fmi/libcosim_parallel.py FMU STEP STEPS

Adds the FMU twice (instances "first" and "second", inputs at their start values), steps libcosim's fixed-step
algorithm STEPS times and prints "steps=<n>". With WINGSIM_WORKER_TRACE set, a standalone FMU's workers write
when they served each call (fmi_worker.c), from which the test reads whether the two instances stepped at the
same time. Leaves by os._exit once its answer is printed (libcosim may crash in the interpreter's teardown,
libcosim_run.py).
"""
import os
import sys

from libcosimpy.CosimExecution import CosimExecution
from libcosimpy.CosimLogging import CosimLogLevel, log_output_level
from libcosimpy.CosimSlave import CosimLocalSlave


def main(fmu: str, step: float, steps: int) -> None:
    log_output_level(CosimLogLevel.ERROR)
    execution = CosimExecution.from_step_size(int(round(step * 1e9)))   # nanoseconds
    for name in ("first", "second"):
        execution.add_local_slave(CosimLocalSlave(fmu, name))
    for k in range(steps):
        if not execution.step(1):
            raise SystemExit(f"libcosim step failed at step {k}")
    del execution
    print(f"steps={steps}")


if __name__ == "__main__":
    main(sys.argv[1], float(sys.argv[2]), int(sys.argv[3]))
    sys.stdout.flush()
    os._exit(0)
