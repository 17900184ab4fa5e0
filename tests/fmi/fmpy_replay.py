"""Replay an FMI host's output CSV through fmpy: the same FMU, the same communication points, compared.

    python tests/fmi/fmpy_replay.py FMU CSV

CSV is a host's result file (a "time" column and one column per Real variable, as the FMI Compliance
Checker writes with `-o`). The FMU is instantiated with fmpy's FMU2Slave, initialized with the start
values, and stepped from each time of the CSV to the next (h = t[k+1] - t[k]); the Real variables of the
CSV are read after initialization and after every step. Prints `max_abs_difference=<value>` (0 when
every number is equal bit for bit) and `rows=<count>`.
Run it with the same environment as the host (e.g. empty): OpenBLAS picks its kernels from the
environment, and another kernel may round differently in the last bit.
"""
import csv
import sys

import numpy as np
from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave


def replay(fmu: str, table: str) -> tuple[float, int]:
    md = read_model_description(fmu)
    reals = {v.name: v.valueReference for v in md.modelVariables if v.type == "Real"}
    with open(table, newline="") as f:
        rows = list(csv.reader(f))
    header = rows[0]
    columns = [i for i, name in enumerate(header) if name in reals]
    times = [float(row[0]) for row in rows[1:]]
    expected = np.array([[float(row[i]) for i in columns] for row in rows[1:]])
    refs = [reals[header[i]] for i in columns]
    slave = FMU2Slave(guid=md.guid, unzipDirectory=extract(fmu),
                      modelIdentifier=md.coSimulation.modelIdentifier, instanceName="replay")
    slave.instantiate()
    slave.setupExperiment(startTime=times[0])
    slave.enterInitializationMode()
    slave.exitInitializationMode()
    got = [slave.getReal(refs)]
    for t, t_next in zip(times[:-1], times[1:]):
        slave.doStep(t, t_next - t)
        got.append(slave.getReal(refs))
    slave.terminate()
    slave.freeInstance()
    return float(np.max(np.abs(np.array(got) - expected))), len(times)


if __name__ == "__main__":
    difference, count = replay(sys.argv[1], sys.argv[2])
    print(f"max_abs_difference={difference!r}")
    print(f"rows={count}")
