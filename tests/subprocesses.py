"""Running wingsim and FMUs in separate Python processes, for the tests (not a test module)."""
import os
import subprocess
import sys
from pathlib import Path

import orchestrator

CODE_ROOT = Path(orchestrator.__file__).resolve().parents[1]   # the sources under test


def wingsim(*args, cwd):
    """`python -m orchestrator ARGS` in `cwd` as CI runs it (CI=true, no debug tracebacks)."""
    env = {**os.environ, "PYTHONPATH": str(CODE_ROOT), "CI": "true"}
    env.pop("WINGSIM_DEBUG", None)
    return subprocess.run([sys.executable, "-m", "orchestrator", *map(str, args)], cwd=cwd, env=env,
                          capture_output=True, text=True, timeout=600)


def simulate_in_fresh_python(fmu, stop, interval, module, variable, cwd, timeout=300):
    """fmpy.simulate_fmu in a Python that never imported our packages (no PYTHONPATH): returns the file
    `module` was imported from (it must be the FMU's embedded copy) and the last value of `variable`."""
    code = ("import sys, fmpy\n"
            f"r = fmpy.simulate_fmu({str(fmu)!r}, stop_time={stop!r}, output_interval={interval!r})\n"
            f"print(sys.modules[{module!r}].__file__)\n"
            f"print(r[{variable!r}][-1])\n")
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    out = subprocess.run([sys.executable, "-c", code], cwd=cwd, env=env, capture_output=True, text=True,
                         timeout=timeout)
    assert out.returncode == 0, out.stderr
    module_file, value = out.stdout.split()[-2:]
    return module_file, float(value)
