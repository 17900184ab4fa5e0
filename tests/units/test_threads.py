"""One BLAS thread in a process that runs a unit, also where the host imported numpy first."""
import json
import os
import subprocess
import sys

import pytest

from repository import SCENES

BLAS_VARIABLES = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS", "BLIS_NUM_THREADS")

# A host that loads numpy and scipy's BLAS with their default pools, then instantiates a unit in-process
# (the direct backend: the slave class, as an FMI host's fmi2Instantiate does through the FMU).
HOST = """
import json, sys
import numpy, scipy.linalg
from threadpoolctl import threadpool_info
from orchestrator.scene.load import load_scene
from orchestrator.run.units import make_unit

blas = lambda: [(i["filepath"], i["num_threads"]) for i in threadpool_info() if i["user_api"] == "blas"]
before = blas()
unit = make_unit(sys.argv[1], load_scene(sys.argv[2], sys.argv[3:]), "direct", None)
print(json.dumps({"before": before, "after": blas()}))
"""


@pytest.mark.parametrize("kind, scene, overrides", [
    ("structure", "deploy_rigid.toml", []),
    ("aero", "heaving_wing.toml", ["time.stop=0.2"]),
])
def test_constructing_a_unit_limits_an_already_loaded_blas_to_one_thread(kind, scene, overrides, tmp_path):
    env = {k: v for k, v in os.environ.items() if k not in BLAS_VARIABLES}
    out = subprocess.run([sys.executable, "-c", HOST, kind, str(SCENES / scene), *overrides], cwd=tmp_path,
                         env=env, capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    pools = json.loads(out.stdout.splitlines()[-1])
    assert len(pools["after"]) >= 2                              # numpy's BLAS and scipy's
    assert {threads for _, threads in pools["after"]} == {1}
    if (os.cpu_count() or 1) > 1:   # the host's pools started with more threads: the unit changed them
        assert all(threads > 1 for _, threads in pools["before"])
