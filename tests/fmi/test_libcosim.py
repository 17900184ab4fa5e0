"""The same FMUs in another FMI 2.0 master: libcosim (Open Simulation Platform) through libcosimpy."""
import json
import re
import subprocess
import sys
from pathlib import Path

import pytest

from orchestrator.build import build_fmus
from orchestrator.cli import main
from orchestrator.scene import load_scene

OVERRIDES = ["aero.model=uvlm-flat", "flow.speed=10", "time.stop=0.25", "coupling.step=0.001"]


def test_rigid_deployment_in_libcosim_matches_wingsim(tmp_path):
    scene = load_scene("scenes/deploy_rigid.toml", OVERRIDES)
    build_fmus(scene, tmp_path / "fmus")
    proc = subprocess.run([sys.executable, str(Path(__file__).with_name("libcosim_run.py")), str(tmp_path / "fmus"),
                           "0.001", "0.25"], capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    cosim = float(re.search(r"deployment_time_s=(\S+)", proc.stdout).group(1))
    args = ["run", "scenes/deploy_rigid.toml", "--backend", "fmu", "--out", str(tmp_path / "out")]
    for item in OVERRIDES + ["coupling.algorithm=jacobi"]:
        args += ["--set", item]
    assert main(args) == 0
    wingsim = json.loads((tmp_path / "out" / "summary.json").read_text())["deployment_time_s"]
    # libcosim's fixed-step algorithm exchanges like wingsim's Jacobi coupling: same FMUs, same answer
    assert cosim == pytest.approx(wingsim, rel=0.02)
    assert cosim == pytest.approx(wingsim, rel=1e-9)
