"""The model descriptions a system tool reads: every variable described, every Real with a unit that
UnitDefinitions defines (SI base units checked against their definitions), a DefaultExperiment from the
scene, no problems for fmpy's validation; pythonfmu installed at the version pyproject pins."""
import math
import tomllib

import pytest
from fmpy import read_model_description
from fmpy.validation import validate_fmu

from orchestrator.scene.load import load_scene
from repository import ROOT, SCENES

# SI definitions (kg, m, s, rad exponents and factor to SI) of units the FMUs use
SI = {
    "m": ({"m": 1}, 1.0), "m/s": ({"m": 1, "s": -1}, 1.0), "1/s": ({"s": -1}, 1.0), "s": ({"s": 1}, 1.0),
    "N": ({"kg": 1, "m": 1, "s": -2}, 1.0), "N.m": ({"kg": 1, "m": 2, "s": -2}, 1.0),
    "J": ({"kg": 1, "m": 2, "s": -2}, 1.0), "deg": ({"rad": 1}, math.pi / 180), "kg/m3": ({"kg": 1, "m": -3}, 1.0),
    "m/s2": ({"m": 1, "s": -2}, 1.0), "1": ({}, 1.0),
    "N.m/rad": ({"kg": 1, "m": 2, "s": -2, "rad": -1}, 1.0), "N.m.s/rad": ({"kg": 1, "m": 2, "s": -1, "rad": -1}, 1.0),
}


@pytest.fixture(scope="module", params=["deploy_rigid", "deploy_flexible"])
def built(request, built_fmus):
    folder = built_fmus(request.param)
    return load_scene(SCENES / f"{request.param}.toml"), [folder / "structure.fmu", folder / "aero.fmu"]


def test_every_variable_described_and_every_real_has_a_defined_unit(built):
    _, fmus = built
    assert [f.name for f in fmus] == ["structure.fmu", "aero.fmu"]
    for fmu in fmus:
        md = read_model_description(str(fmu))
        units = {u.name: u for u in md.unitDefinitions}
        undescribed = [v.name for v in md.modelVariables if not (v.description or "").strip()]
        unitless = [v.name for v in md.modelVariables if v.type == "Real" and v.unit not in units]
        assert undescribed == [] and unitless == [], fmu.name
        assert next(v for v in md.modelVariables if v.name == "topology_hash").description
        assert set(units) <= set(SI), f"{fmu.name}: units without a definition to check: {set(units) - set(SI)}"
        for name, (exponents, factor) in SI.items():
            if name in units:
                base = units[name].baseUnit
                got = {k: getattr(base, k) for k in ("kg", "m", "s", "rad") if getattr(base, k)}
                assert got == exponents and math.isclose(base.factor, factor), name


def test_default_experiment_is_the_scenes(built):
    scene, fmus = built
    for fmu in fmus:
        experiment = read_model_description(str(fmu)).defaultExperiment
        assert experiment is not None, fmu.name
        assert float(experiment.startTime) == 0.0
        assert float(experiment.stopTime) == scene["time"]["stop"]
        assert float(experiment.stepSize) == scene["coupling"]["step"]


def test_fmpy_validation_finds_no_problems(built):
    for fmu in built[1]:
        assert validate_fmu(str(fmu)) == [], fmu.name


def test_installed_pythonfmu_is_the_pinned_version():
    import pythonfmu

    project = tomllib.loads((ROOT / "pyproject.toml").read_text())
    pins = [d for d in project["project"]["dependencies"] if d.startswith("pythonfmu")]
    assert pins == ["pythonfmu==0.7.0"]
    assert pythonfmu.__version__ == "0.7.0"
