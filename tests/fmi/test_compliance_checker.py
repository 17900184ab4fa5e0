"""The FMUs in the FMI Compliance Checker, a plain C FMI host, started with an empty environment.

The checker (modelica-tools/FMUComplianceChecker, a static build beside the repository in
shared/tools/fmucheck) loads the FMU as system tools do: dlopen with RTLD_LOCAL, no Python in the
process. It checks the model description, then instantiates and co-simulates the FMU with the start
values of its inputs, writing every output. A clean run reports "0 Warning(s)" and "0 Error(s)" and
no fatal error; its numbers equal the same communication points replayed through fmpy
(tests/fmpy_replay.py, in the same empty environment) bit for bit.
"""
import re
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

from orchestrator import native_binary
from orchestrator.build import build_fmus
from orchestrator.scene import load_scene

ROOT = Path(__file__).resolve().parents[1]
CHECKER = ROOT.parent / "shared" / "tools" / "fmucheck" / "fmuCheck.linux64"
REPLAY = Path(__file__).with_name("fmpy_replay.py")

pytestmark = [
    pytest.mark.skipif(not CHECKER.is_file(), reason=f"the FMI Compliance Checker is not installed at {CHECKER}"),
    pytest.mark.skipif(native_binary.unavailable_reason() is not None,
                       reason=f"the FMUs keep pythonfmu's binary, which a host without Python cannot load: "
                              f"{native_binary.unavailable_reason()}"),
]


@pytest.fixture(scope="module")
def fmus(tmp_path_factory):
    """scene name -> folder with its structure.fmu and aero.fmu."""
    built = {}
    for name in ("deploy_rigid", "deploy_flexible"):
        out = tmp_path_factory.mktemp(name)
        build_fmus(load_scene(ROOT / "scenes" / f"{name}.toml"), out)
        built[name] = out
    return built


def check(fmu: Path, out_csv: Path, step: float, stop: float, env: dict | None = None) -> subprocess.CompletedProcess:
    """The checker on `fmu`, as a system tool starts it: an empty environment (or `env`), warnings logged."""
    return subprocess.run([str(CHECKER), "-k", "cs", "-h", repr(step), "-s", repr(stop), "-l", "3",
                           "-o", str(out_csv), str(fmu)],
                          env=env or {}, capture_output=True, text=True, timeout=600)


def assert_clean(proc: subprocess.CompletedProcess) -> None:
    text = proc.stdout + proc.stderr
    assert proc.returncode == 0, text
    assert re.search(r"Checker reported:\s+0 Warning\(s\)\s+0 Error\(s\)", text), text
    assert re.search(r"FMU reported:\s+0 warning\(s\) and error\(s\)", text), text
    assert "Fatal" not in text and "FATAL" not in text, text


def assert_replayed_by_fmpy(fmu: Path, out_csv: Path, rows: int) -> None:
    proc = subprocess.run([sys.executable, str(REPLAY), str(fmu), str(out_csv)],
                          env={}, capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert f"rows={rows}" in proc.stdout
    assert "max_abs_difference=0.0" in proc.stdout, proc.stdout


@pytest.mark.parametrize("scene", ["deploy_rigid", "deploy_flexible"])
@pytest.mark.parametrize("unit", ["structure", "aero"])
def test_fmu_passes_the_compliance_checker_in_an_empty_environment(fmus, scene, unit, tmp_path):
    fmu = fmus[scene] / f"{unit}.fmu"
    assert native_binary.inner_name(unit) in _binaries(fmu)  # the shim is the FMU's binary
    out_csv = tmp_path / "out.csv"
    assert_clean(check(fmu, out_csv, 1e-3, 0.02))
    assert_replayed_by_fmpy(fmu, out_csv, rows=21)


def test_the_hosts_python_variables_do_not_redirect_the_fmus_python(fmus, tmp_path):
    """PYTHONHOME/PYTHONPATH of the host's environment, and the system's own python3 first on PATH, are
    not used: the run is the same as in the empty environment."""
    fmu = fmus["deploy_rigid"] / "structure.fmu"
    clean, hostile = tmp_path / "clean.csv", tmp_path / "hostile.csv"
    assert_clean(check(fmu, clean, 1e-3, 0.005))
    env = {"PYTHONHOME": str(tmp_path / "nowhere"), "PYTHONPATH": str(tmp_path / "nowhere"), "PATH": "/usr/bin:/bin"}
    assert_clean(check(fmu, hostile, 1e-3, 0.005, env=env))
    assert hostile.read_bytes() == clean.read_bytes()


@pytest.mark.slow
@pytest.mark.parametrize("unit", ["structure", "aero"])
def test_deploy_rigid_passes_the_checker_over_its_default_experiment(fmus, unit, tmp_path):
    fmu = fmus["deploy_rigid"] / f"{unit}.fmu"
    out_csv = tmp_path / "out.csv"
    assert_clean(check(fmu, out_csv, 1e-3, 0.3))
    assert_replayed_by_fmpy(fmu, out_csv, rows=301)


def _binaries(fmu: Path) -> set[str]:
    with zipfile.ZipFile(fmu) as z:
        return {Path(n).name for n in z.namelist() if n.startswith(native_binary.PLATFORM_DIR + "/")}
