"""Tunable scene keys are FMU parameters: a scene that differs from the one its FMUs were built from in
tunable keys only runs on those FMUs, with its values set as parameters, exactly as on FMUs built from it;
`wingsim sweep --grid` over such a key builds one pair of FMUs.
"""
from __future__ import annotations

import numpy as np
import pytest
from fmpy import read_model_description

from fmu_common.scene_schema import tunable_parameters, without_tunables
from fmu_common.schema import TUNABLE
from orchestrator.build.fmus import build_digest
from orchestrator.run.master import run_scene
from orchestrator.scene.load import load_scene
from repository import SCENES
from subprocesses import wingsim

SCENE = SCENES / "deploy_rigid.toml"
SHORT = ["time.stop=0.02"]
# the tunable keys of deploy_rigid (two bodies inner and outer, one hinge fold), written out from the schema's
# declarations (docs/scenes.md: the keys marked tunable)
STRUCTURE_PARAMETERS = ["structure.step", "structure.gravity[1]", "structure.gravity[2]", "structure.gravity[3]",
                        "structure.bodies.inner.damping", "structure.bodies.outer.damping",
                        "structure.joints.fold.stiffness", "structure.joints.fold.damping",
                        "structure.joints.fold.torque"]
AERO_PARAMETERS = ["flow.speed", "flow.density", "flow.direction[1]", "flow.direction[2]", "flow.direction[3]"]
VARIANTS = [["flow.speed=14"], ["flow.density=0.9"], ["flow.direction=[2, 0, 0.2]"],
            ["structure.gravity=[0, 0, -3.71]"], ["structure.step=5e-5"],
            ["structure.joints.fold.stiffness=0.2", "structure.joints.fold.damping=0.01",
             "structure.joints.fold.torque=0.05"]]
# a body's damping acts on deformation only: a flexible wing shows it
FLEXIBLE, FLEXIBLE_SHORT = SCENES / "deploy_flexible.toml", ["time.stop=0.01"]
RECORD_VARIANTS = [["record.probes=position"], ["record.monitors=constraints"]]
FLEXIBLE_VARIANTS = [["structure.bodies.inner.damping=40"], ["structure.step=1e-4"]]


def _parameters(fmu) -> dict[str, float]:
    return {v.name: float(v.start) for v in read_model_description(str(fmu)).modelVariables
            if v.causality == "parameter"}


def test_the_fmu_parameters_are_the_scene_s_tunable_keys(built_fmus):
    scene = load_scene(SCENE, SHORT)
    folder = built_fmus("deploy_rigid", *SHORT)
    structure, aero = _parameters(folder / "structure.fmu"), _parameters(folder / "aero.fmu")
    assert list(structure) == STRUCTURE_PARAMETERS and list(aero) == AERO_PARAMETERS
    assert structure["structure.joints.fold.torque"] == scene["structure"]["joints"][1]["torque"]
    assert [structure[f"structure.gravity[{i}]"] for i in (1, 2, 3)] == scene["structure"]["gravity"]
    assert [aero[f"flow.direction[{i}]"] for i in (1, 2, 3)] == scene["flow"]["direction"]
    assert list(tunable_parameters(scene, "structure")) == STRUCTURE_PARAMETERS


def test_the_build_digest_ignores_exactly_the_tunable_keys():
    scene = load_scene(SCENE)
    blanked = without_tunables(scene)
    assert blanked["flow"] == {"speed": TUNABLE, "density": TUNABLE, "direction": TUNABLE}
    assert blanked["structure"]["joints"][1]["stiffness"] == TUNABLE
    assert blanked["structure"]["joints"][1]["stop_angle_deg"] == scene["structure"]["joints"][1]["stop_angle_deg"]
    assert blanked["structure"]["bodies"][0]["section"] == scene["structure"]["bodies"][0]["section"]
    assert scene["flow"]["speed"] != TUNABLE    # the scene itself is left as it was
    for overrides in VARIANTS:
        assert build_digest(load_scene(SCENE, overrides)) == build_digest(scene), overrides
    for overrides in (["aero.spanwise_panels=5"], ["structure.joints.fold.latch_factor=100"], ["time.stop=0.1"]):
        assert build_digest(load_scene(SCENE, overrides)) != build_digest(scene), overrides
    # what the master records no unit reads
    for overrides in RECORD_VARIANTS:
        assert build_digest(load_scene(SCENE, overrides)) == build_digest(scene), overrides


def test_a_variant_recording_less_runs_on_the_fmus_of_the_scene_as_on_its_own(built_fmus):
    overrides = [*SHORT, *RECORD_VARIANTS[0], *RECORD_VARIANTS[1]]
    variant = load_scene(SCENE, overrides)
    on_shared = run_scene(variant, backend="fmu", fmu_dir=built_fmus("deploy_rigid", *SHORT))
    on_own = run_scene(variant, backend="direct")
    assert on_shared.status == on_own.status == "ok", (on_shared.message, on_own.message)
    table = on_shared.series.table()
    assert np.array_equal(table, on_own.series.table(), equal_nan=True)      # bit for bit
    assert np.isnan(table).any() and not np.isnan(table).all()                # it recorded less, not nothing


@pytest.mark.parametrize("name, path, short, overrides",
                         [pytest.param("deploy_rigid", SCENE, SHORT, o, id=" ".join(o)) for o in VARIANTS]
                         + [pytest.param("deploy_flexible", FLEXIBLE, FLEXIBLE_SHORT, o, id=" ".join(o))
                            for o in FLEXIBLE_VARIANTS])
def test_a_tunable_variant_runs_on_the_fmus_of_the_scene_as_on_its_own(built_fmus, name, path, short, overrides):
    variant = load_scene(path, [*short, *overrides])
    folder = built_fmus(name, *short)                   # built from the scene, not the variant
    on_shared = run_scene(variant, backend="fmu", fmu_dir=folder)
    # reference: the slaves instantiated from the variant's own scene (what FMUs built from it run)
    on_own = run_scene(variant, backend="direct")
    on_scene = run_scene(load_scene(path, short), backend="direct")
    assert on_shared.status == on_own.status == "ok", (on_shared.message, on_own.message)
    assert np.array_equal(on_shared.series.table(), on_own.series.table())   # bit for bit
    assert not np.array_equal(on_shared.series.table(), on_scene.series.table())  # the variant took effect


def test_a_sweep_over_a_tunable_key_builds_once(tmp_path):
    proc = wingsim("sweep", SCENE, "--grid", "flow.speed=8,12", "--grid", "structure.joints.fold.torque=0.04,0.05",
                   "--set", "time.stop=0.01", "--backend", "fmu", "--jobs", "2", "--out", tmp_path / "out",
                   cwd=tmp_path)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert proc.stderr.count("building the FMUs") == 1, proc.stderr
    assert len(list((tmp_path / "out" / "fmus").iterdir())) == 1
    proc = wingsim("sweep", SCENE, "--grid", "aero.spanwise_panels=5,6", "--grid", "flow.speed=8,12",
                   "--set", "time.stop=0.01", "--backend", "fmu", "--jobs", "2", "--out", tmp_path / "other",
                   cwd=tmp_path)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert proc.stderr.count("building the FMUs") == 2, proc.stderr      # one per lattice, not per speed
