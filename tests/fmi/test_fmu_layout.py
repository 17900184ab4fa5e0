"""A model description edited after the build (two value references or two names swapped) fails
`wingsim validate` naming the variables, and `wingsim run` refuses the FMU before any step; the FMU as
built passes. The layout compared against comes from the slave class, never from the FMU's files."""
import json
import shutil
import xml.etree.ElementTree as ET
import zipfile

import pytest
from fmpy import read_model_description

from orchestrator.cli import main
from orchestrator.run.layout import Variable, mismatches
from orchestrator.run.master import run_scene
from orchestrator.scene.load import load_scene
from orchestrator.run.port import UnitError
from orchestrator.run.units import make_unit
from fmu_common.interface import fmi_name
from fmu_common.wing_spec import StructureSpec
from fmu_common.topology import Topology
from repository import SCENES

SCENE = SCENES / "deploy_rigid.toml"


@pytest.fixture(scope="module")
def built(built_fmus):
    """(scene, folder holding structure.fmu and aero.fmu of deploy_rigid as built)."""
    return load_scene(SCENE), built_fmus("deploy_rigid")


def _rewrite(fmu, dest, edit_description=None, edit_build_info=None):
    """Copy the FMU zip to `dest`, with modelDescription.xml (an ElementTree root) and build_info.json (a
    dict) edited in place by the given functions, every other entry unchanged."""
    with zipfile.ZipFile(fmu) as src, zipfile.ZipFile(dest, "w", zipfile.ZIP_DEFLATED) as out:
        for info in src.infolist():
            data = src.read(info)
            if info.filename == "modelDescription.xml" and edit_description:
                root = ET.fromstring(data)
                edit_description(root)
                data = ET.tostring(root, encoding="utf-8", xml_declaration=True)
            elif info.filename == "resources/build_info.json" and edit_build_info:
                build_info = json.loads(data)
                edit_build_info(build_info)
                data = json.dumps(build_info).encode()
            out.writestr(info, data)
    return dest


def _swap(a, b, attribute):
    """An edit_description that swaps `attribute` of the ScalarVariables named a and b."""
    def edit(root):
        va, vb = (next(v for v in root.iter("ScalarVariable") if v.get("name") == n) for n in (a, b))
        x, y = va.get(attribute), vb.get(attribute)
        va.set(attribute, y)
        vb.set(attribute, x)
    return edit


def _tampered(built, tmp_path, attribute, **edits):
    """A folder with the aero FMU as built and a structure FMU whose fold angle and energy have their
    `attribute` swapped; (folder, fold angle name, its value reference, energy's value reference)."""
    scene, folder = built
    fold = fmi_name(f"fold_angle_{Topology.from_spec(StructureSpec.from_scene(scene)).hinge_names[0]}")
    vr = {v.name: v.valueReference for v in read_model_description(str(folder / "structure.fmu")).modelVariables}
    out = tmp_path / "tampered"
    out.mkdir()
    shutil.copy(folder / "aero.fmu", out / "aero.fmu")
    _rewrite(folder / "structure.fmu", out / "structure.fmu", _swap(fold, "energy", attribute), **edits)
    return out, fold, vr[fold], vr["energy"]


def test_untampered_fmus_pass_validate_and_start(built, capsys):
    scene, folder = built
    assert main(["validate", str(folder / "structure.fmu"), str(folder / "aero.fmu")]) == 0
    assert capsys.readouterr().out.count(": ok (") == 2
    make_unit("structure", scene, "fmu", folder).terminate()


@pytest.mark.parametrize("attribute", ["valueReference", "name"])
def test_swapped_declaration_fails_validate_naming_both_variables(built, tmp_path, capsys, attribute):
    folder, fold, vr_fold, vr_energy = _tampered(built, tmp_path, attribute)
    assert main(["validate", str(folder / "structure.fmu")]) == 1
    out = capsys.readouterr().out
    assert "FAILED" in out
    # each variable is declared at the other's value reference; the unit registers it at its own
    assert f"declares {fold} with valueReference {vr_energy}" in out
    assert f"registers it with {vr_fold}" in out
    assert f"declares energy with valueReference {vr_fold}" in out
    if attribute == "name":  # the unit attribute stayed with the XML element: deg and J are swapped too
        assert "unit J" in out and "unit deg" in out


@pytest.mark.parametrize("attribute", ["valueReference", "name"])
def test_run_refuses_a_swapped_declaration_before_any_step(built, tmp_path, attribute):
    scene, _ = built
    folder, fold, _, _ = _tampered(built, tmp_path, attribute)
    with pytest.raises(UnitError, match="refused") as err:
        make_unit("structure", scene, "fmu", folder)
    assert fold in str(err.value) and "energy" in str(err.value)

    stepped = []

    class Counting:
        UnitError = UnitError

        @staticmethod
        def make_unit(**kwargs):
            unit = make_unit(**kwargs)
            step = unit.do_step
            unit.do_step = lambda t, h: (stepped.append(t), step(t, h))
            return unit

    result = run_scene(scene, backend="fmu", fmu_dir=folder, units=Counting)
    assert result.status == "error" and fold in result.message and "energy" in result.message
    assert stepped == [] and result.simulated_time_s == 0.0


def test_wingsim_run_exits_1_on_a_tampered_fmu(built, tmp_path, monkeypatch, capsys):
    scene, _ = built
    folder, fold, _, _ = _tampered(built, tmp_path, "valueReference")
    work = tmp_path / "work"
    (work / "fmus").mkdir(parents=True)
    shutil.copytree(folder, work / "fmus" / scene["name"])   # where `wingsim run` looks for them
    monkeypatch.chdir(work)
    assert main(["run", str(SCENE), "--out", "out"]) == 1
    summary = json.loads((work / "out" / "summary.json").read_text())
    assert summary["status"] == "error" and fold in summary["message"]
    assert summary["simulated_time_s"] == 0.0


def test_a_build_from_other_sources_is_reported_as_stale_not_as_tampering(built, tmp_path, capsys):
    """When build_info says the FMU came from other sources, a differing layout is a stale build."""
    def other_sources(info):
        info["sources_sha256"] = "0" * 64
    folder, fold, _, _ = _tampered(built, tmp_path, "valueReference", edit_build_info=other_sources)
    assert main(["validate", str(folder / "structure.fmu")]) == 1
    out = capsys.readouterr().out
    assert "built from other sources" in out and "rebuild" in out and fold in out


def test_mismatches_name_missing_and_undeclared_variables():
    real = Variable(0, "output", "continuous", "Real", "m")
    reported = {"a": real, "b": Variable(1, "output", "continuous", "Real", "J")}
    declared = {"a": real, "c": Variable(1, "output", "continuous", "Real", "J")}
    found = mismatches(declared, reported, "structure")
    assert len(found) == 2
    assert any("declares c" in line and "does not have" in line for line in found)
    assert any("unit's b" in line and "not declared" in line for line in found)
    assert mismatches(reported, dict(reported), "structure") == []
