"""Messages say what is true: no deployment verdict for hinges that cannot latch; a folder is not "no such file";
a corrupted FMU is named by the file the user gave, never by the temporary folder it was unpacked in."""
import tempfile
import zipfile

from orchestrator.export.validate import validate
from orchestrator.output.results import deployment_time, latching_hinges
from orchestrator.scene.load import load_scene
from repository import SCENES
from subprocesses import wingsim


def test_only_hinges_with_a_stop_angle_latch():
    """two_body_003's hinge AB has no stop_angle_deg (the resolved scene holds None): it cannot latch, so the
    scene has no deployment time; deploy_rigid's fold stops at 0 deg."""
    assert latching_hinges(load_scene(SCENES / "two_body_003.toml")) == []
    assert deployment_time({}, load_scene(SCENES / "two_body_003.toml")) is None
    deploy = load_scene(SCENES / "deploy_rigid.toml")
    assert latching_hinges(deploy) == ["fold"]
    assert deployment_time({"fold": 0.16}, deploy) == 0.16


def test_a_run_without_a_stop_angle_says_nothing_of_deployment(tmp_path):
    proc = wingsim("run", SCENES / "two_body_003.toml", "--backend", "direct", "--set", "time.stop=0.005",
                   "--out", tmp_path / "out", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert "deploy" not in proc.stdout and "latch" not in proc.stdout


def test_validate_calls_a_folder_a_folder(tmp_path):
    folder = tmp_path / "structure.fmu"
    folder.mkdir()
    assert validate(folder).compliance == [f"a folder, not an FMU file: {folder}"]


def test_a_corrupted_fmu_is_named_by_the_file_given(built_fmus, tmp_path):
    """structure.fmu whose binary is overwritten with text: the message names tmp_path/broken.fmu and the binary
    inside it, and no temporary folder."""
    source = built_fmus("deploy_rigid", "aero.model=none") / "structure.fmu"
    broken = tmp_path / "broken.fmu"
    with zipfile.ZipFile(source) as given, zipfile.ZipFile(broken, "w") as out:
        for item in given.infolist():
            data = given.read(item)
            out.writestr(item, b"not a library" if item.filename == "binaries/linux64/structure.so" else data)
    problems = " ".join(validate(broken).compliance)
    assert f"{broken}:binaries/linux64/structure.so" in problems
    assert tempfile.gettempdir() + "/tmp" not in problems and "wingsim_validate_" not in problems
