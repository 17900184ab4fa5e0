"""Instantiate/free cycles keep a host's memory flat: pythonfmu's fmi2Instantiate runs the slave script again for
every instance and keeps what that run binds (fmu_common/fmi_slave.py), which `SolverSlave`'s metaclass and the
slave scripts' module imports reduce to a few hundred bytes per instance."""
import os
import subprocess
import sys

WARM_UP = 200       # cycles before the first measurement: lazy imports, caches filled once, allocator arenas (the
                    # resident size grows by about 0.7 MB once within the first 200 cycles, then by about 1.5 kB a
                    # cycle)
CYCLES = 200
LIMIT_KB = 1024     # at most 5 kB per cycle; the slave class that each cycle left behind was about 10 kB

CYCLE_CODE = """
import gc, sys
from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave

def resident_kb():
    gc.collect()
    return int(open("/proc/self/status").read().split("VmRSS:")[1].split()[0])

folder = extract(sys.argv[1])
md = read_model_description(folder)

def cycle(i):
    fmu = FMU2Slave(guid=md.guid, unzipDirectory=folder, modelIdentifier=md.coSimulation.modelIdentifier,
                    instanceName=f"unit{i}")
    fmu.instantiate()
    fmu.setupExperiment(startTime=0.0)
    fmu.enterInitializationMode()
    fmu.exitInitializationMode()
    fmu.terminate()
    fmu.freeInstance()      # fmi2FreeInstance, and the library unloaded

for i in range(int(sys.argv[2])):
    cycle(i)
before = resident_kb()
for i in range(int(sys.argv[3])):
    cycle(i)
print(resident_kb() - before)
"""


def test_instantiate_free_cycles_through_fmpy_keep_memory_flat(built_fmus):
    """200 cycles of fmpy's FMU2Slave (instantiate, initialize, terminate, free) of the structure FMU, in a Python
    that never imported our packages, after WARM_UP cycles: the resident memory grows by less than 1 MB (the
    slave class each cycle left behind made it 1.2 MB; now about 0.3 MB)."""
    fmu = built_fmus("deploy_rigid", "aero.model=none") / "structure.fmu"
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    proc = subprocess.run([sys.executable, "-c", CYCLE_CODE, str(fmu), str(WARM_UP), str(CYCLES)], env=env,
                          capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr
    growth_kb = int(proc.stdout.split()[-1])
    assert growth_kb < LIMIT_KB, f"{growth_kb} kB over {CYCLES} cycles"
