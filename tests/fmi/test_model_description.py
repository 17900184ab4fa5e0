"""The model descriptions a system tool reads: every variable described, every Real with a unit that
UnitDefinitions defines (SI base units checked against their definitions), a DefaultExperiment from the
scene, a ModelStructure that declares no direct dependency of an output on an input and the InitialUnknowns
FMI 2.0 asks for, a modelName and description that say which scene, fidelity and aero model the FMU is, no
problems for fmpy's validation; pythonfmu installed at the version pyproject pins."""
import math
import tomllib
import zipfile
import xml.etree.ElementTree as ET

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


def _root(fmu) -> ET.Element:
    with zipfile.ZipFile(fmu) as z:
        return ET.fromstring(z.read("modelDescription.xml"))


def _initial(variable: ET.Element) -> str:
    """A variable's initial as FMI 2.0 defines it, its default where the attribute is absent (Table of
    causality x variability, section 2.2.7)."""
    if "initial" in variable.attrib:
        return variable.get("initial")
    causality, variability = variable.get("causality", "local"), variable.get("variability", "continuous")
    if variability == "constant" or causality == "parameter":
        return "exact"
    if causality in ("calculatedParameter", "output", "local"):
        return "calculated"
    return "none"       # input, independent


def test_outputs_depend_on_no_input_and_initial_unknowns_are_the_fmi2_ones(built):
    """Every output is listed in Outputs with dependencies="" (no direct dependency on an input; without the
    attribute FMI 2.0 reads "depends on every input"); InitialUnknowns lists exactly the outputs with initial
    approx or calculated and the calculated parameters (FMI 2.0, section 2.2.8), here none."""
    for fmu in built[1]:
        root = _root(fmu)
        variables = root.findall("ModelVariables/ScalarVariable")
        outputs = [i for i, v in enumerate(variables, 1) if v.get("causality") == "output"]
        unknowns = root.findall("ModelStructure/Outputs/Unknown")
        assert [int(u.get("index")) for u in unknowns] == outputs, fmu.name
        assert all(u.get("dependencies") == "" for u in unknowns), fmu.name
        assert all("dependenciesKind" not in u.attrib for u in unknowns), fmu.name
        required = {i for i, v in enumerate(variables, 1)
                    if (v.get("causality") == "output" and _initial(v) in ("approx", "calculated"))
                    or v.get("causality") == "calculatedParameter"}
        listed = {int(u.get("index")) for u in root.findall("ModelStructure/InitialUnknowns/Unknown")}
        assert listed == required, fmu.name
        md = read_model_description(str(fmu))       # as fmpy reads it: an empty list, not "every input"
        assert all(u.dependencies == [] for u in md.outputs), fmu.name


@pytest.fixture(scope="module")
def variants(built_fmus):
    """(overrides, {unit: model description root}) of deploy_rigid built as written, with aero.model=strip and
    with structure.fidelity=flexible."""
    out = []
    for overrides in [(), ("aero.model=strip",), ("structure.fidelity=flexible",)]:
        folder = built_fmus("deploy_rigid", *overrides)
        out.append((overrides, {unit: _root(folder / f"{unit}.fmu") for unit in ("structure", "aero")}))
    return out


def test_model_name_and_description_say_scene_fidelity_and_aero_model(variants):
    written = tomllib.loads((SCENES / "deploy_rigid.toml").read_text())
    aero_models = {(): "uvlm-flat", ("aero.model=strip",): "strip", ("structure.fidelity=flexible",): "uvlm-flat"}
    fidelities = {(): "rigid", ("aero.model=strip",): "rigid", ("structure.fidelity=flexible",): "flexible"}
    for overrides, roots in variants:
        for unit, root in roots.items():
            name, description = root.get("modelName"), root.get("description")
            assert root.find("CoSimulation").get("modelIdentifier") == unit, overrides
            assert name.startswith("deploy_rigid ") and unit in name, (overrides, name)
            # the scene's name, not the file's free text, which describes the scene as written (uvlm-flat)
            assert description.endswith("Scene deploy_rigid") and written["description"] not in description
            assert unit.capitalize() in description
        structure, aero = roots["structure"], roots["aero"]
        assert structure.get("modelName") == f"deploy_rigid structure ({fidelities[overrides]})"
        assert aero.get("modelName") == f"deploy_rigid aero ({aero_models[overrides]})"
        assert f"{fidelities[overrides]} fidelity" in structure.get("description")
        assert f"{written['structure']['integrator']} integrator" in structure.get("description")
        assert f"{aero_models[overrides]} aero model" in aero.get("description")
        panels = written["aero"]["chordwise_panels"], written["aero"]["spanwise_panels"]
        if aero_models[overrides] == "strip":
            assert f"{panels[1]} strips per body" in aero.get("description")
        else:
            assert f"{panels[0]} x {panels[1]} panels (chordwise x spanwise)" in aero.get("description")
    (_, default), (_, strip), (_, flexible) = variants
    assert default["aero"].get("modelName") != strip["aero"].get("modelName")
    assert default["aero"].get("description") != strip["aero"].get("description")
    assert default["structure"].get("modelName") != flexible["structure"].get("modelName")
    assert default["structure"].get("description") != flexible["structure"].get("description")


def test_fmpy_validation_finds_no_problems(built):
    for fmu in built[1]:
        assert validate_fmu(str(fmu)) == [], fmu.name


def test_installed_pythonfmu_is_the_pinned_version():
    import pythonfmu

    project = tomllib.loads((ROOT / "pyproject.toml").read_text())
    pins = [d for d in project["project"]["dependencies"] if d.startswith("pythonfmu")]
    assert pins == ["pythonfmu==0.7.0"]
    assert pythonfmu.__version__ == "0.7.0"
