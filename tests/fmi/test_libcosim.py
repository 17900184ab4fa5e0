"""The same FMUs in another FMI 2.0 master: libcosim (Open Simulation Platform) through libcosimpy."""
import re
import subprocess
import sys
from pathlib import Path

import pytest

from orchestrator.run.master import run_scene
from orchestrator.scene.load import load_scene
from repository import SCENES

OVERRIDES = ["aero.model=uvlm-flat", "flow.speed=10", "time.stop=0.25", "coupling.step=0.001"]


def test_rigid_deployment_in_libcosim_matches_wingsim(built_fmus):
    fmus = built_fmus("deploy_rigid")   # the run's overrides change no section the FMUs are built from
    proc = subprocess.run([sys.executable, str(Path(__file__).with_name("libcosim_run.py")), str(fmus),
                           "0.001", "0.25"], capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    cosim = float(re.search(r"deployment_time_s=(\S+)", proc.stdout).group(1))
    result = run_scene(load_scene(SCENES / "deploy_rigid.toml", [*OVERRIDES, "coupling.algorithm=jacobi"]),
                       backend="fmu", fmu_dir=fmus)
    assert result.status == "ok", result.message
    wingsim = result.latch_times["fold"]
    # libcosim's fixed-step algorithm exchanges like wingsim's Jacobi coupling: same FMUs, same answer
    assert cosim == pytest.approx(wingsim, rel=1e-9)
