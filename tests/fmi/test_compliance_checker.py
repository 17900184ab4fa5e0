"""The FMUs in the FMI Compliance Checker, a plain C FMI host, started with an empty environment.

The checker (modelica-tools/FMUComplianceChecker, a static build; tests/repository.py says where it is
looked for) loads the FMU as system tools do: dlopen with RTLD_LOCAL, no Python in the process. It checks
the model description, then instantiates and co-simulates the FMU with the start values of its inputs,
writing every output. A clean run reports "0 Warning(s)" and "0 Error(s)" and no fatal error; its numbers
equal the same communication points replayed through fmpy (tests/fmi/fmpy_replay.py, in the same empty
environment) bit for bit.
"""
import zipfile
from pathlib import Path

import pytest

from fmi_hosts import assert_clean, assert_replayed_by_fmpy, check
from orchestrator.build import native_binary
from orchestrator.scene.load import load_scene
from repository import SCENES
pytestmark = pytest.mark.skipif(native_binary.unavailable_reason() is not None,
                                reason=f"the FMUs keep pythonfmu's binary, which a host without Python cannot load: "
                                       f"{native_binary.unavailable_reason()}")


@pytest.mark.parametrize("scene", ["deploy_rigid", "deploy_flexible"])
@pytest.mark.parametrize("unit", ["structure", "aero"])
def test_fmu_passes_the_compliance_checker_in_an_empty_environment(fmu_checker, built_fmus, scene, unit, tmp_path):
    fmu = built_fmus(scene) / f"{unit}.fmu"
    assert native_binary.inner_name(unit) in _binaries(fmu)  # the shim is the FMU's binary
    out_csv = tmp_path / "out.csv"
    assert_clean(check(fmu_checker, fmu, out_csv, 1e-3, 0.02))
    assert_replayed_by_fmpy(fmu, out_csv, rows=21)


def test_the_hosts_python_variables_do_not_redirect_the_fmus_python(fmu_checker, built_fmus, tmp_path):
    """PYTHONHOME/PYTHONPATH of the host's environment, and the system's own python3 first on PATH, are
    not used: the run is the same as in the empty environment."""
    fmu = built_fmus("deploy_rigid") / "structure.fmu"
    clean, hostile = tmp_path / "clean.csv", tmp_path / "hostile.csv"
    assert_clean(check(fmu_checker, fmu, clean, 1e-3, 0.005))
    env = {"PYTHONHOME": str(tmp_path / "nowhere"), "PYTHONPATH": str(tmp_path / "nowhere"), "PATH": "/usr/bin:/bin"}
    assert_clean(check(fmu_checker, fmu, hostile, 1e-3, 0.005, env=env))
    assert hostile.read_bytes() == clean.read_bytes()


@pytest.mark.slow
@pytest.mark.parametrize("unit", ["structure", "aero"])
def test_deploy_rigid_passes_the_checker_over_its_default_experiment(fmu_checker, built_fmus, unit, tmp_path):
    fmu = built_fmus("deploy_rigid") / f"{unit}.fmu"
    out_csv = tmp_path / "out.csv"
    assert_clean(check(fmu_checker, fmu, out_csv, 1e-3, 0.3))
    assert_replayed_by_fmpy(fmu, out_csv, rows=301)


ALL_UNITS = [(path.stem, overrides, unit) for path in sorted(SCENES.glob("*.toml"))
             for overrides in ([()] + ([("aero.model=strip",), ("aero.model=uvlm-prescribed",)]
                                       if path.stem == "deploy_rigid" else []))
             for unit in (["structure", "aero"] if load_scene(path)["aero"]["model"] != "none" else ["structure"])]


@pytest.mark.parametrize("scene, overrides, unit", ALL_UNITS,
                         ids=[f"{s}{''.join('-' + o for o in ov)}-{u}" for s, ov, u in ALL_UNITS])
def test_every_fmu_of_every_scene_passes_the_checker(fmu_checker, built_fmus, scene, overrides, unit, tmp_path):
    # the model description of every unit of every shipped scene (each fidelity, aero model, probes, gauges,
    # joints), and five communication steps of the scene's own step from the start values of its inputs
    fmu = built_fmus(scene, *overrides) / f"{unit}.fmu"
    step = load_scene(SCENES / f"{scene}.toml", list(overrides))["coupling"]["step"]
    assert_clean(check(fmu_checker, fmu, tmp_path / "out.csv", step, 5 * step))


def _binaries(fmu: Path) -> set[str]:
    with zipfile.ZipFile(fmu) as z:
        return {Path(n).name for n in z.namelist() if n.startswith(native_binary.PLATFORM_DIR + "/")}
