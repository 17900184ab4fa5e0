"""Every write survives a kill or a neighbour (orchestrator.files): a process killed while it writes a PNG leaves
no truncated PNG under its name and a sweep's resume runs that run again; a second run into a busy folder is
refused naming the first, and a folder whose writer was killed is taken over with a note; builds of one FMU folder
run one after the other, and a run never pairs one build's model description with another's binary; concurrent
exports never share a temporary file; an export works whatever file system the temporary folder is on.

The independent references: the PNG format (a PNG ends with its IEND chunk, and matplotlib decodes it), the FMU's
own model description (the GUID its binary was compiled with), the process ids of the processes started here."""
from __future__ import annotations

import errno
import json
import os
import re
import signal
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

from orchestrator.build import standalone
from orchestrator.build.fmus import build_fmus, build_lock
from orchestrator.cli import main
from orchestrator.export import container, ssp
from orchestrator.export.system import coupled_system
from orchestrator.scene.load import load_scene
from repository import SCENES
from subprocesses import CODE_ROOT, wingsim

DEPLOY = SCENES / "deploy_rigid.toml"
PENDULUM = SCENES / "pendulum_rigid.toml"
STILL = ["--set", "aero.model=none", "--set", "time.stop=0.02"]
PNG_END = b"IEND\xaeB`\x82"     # the IEND chunk (length 0, type, CRC) that ends every PNG file
WAIT_S = 120.0                   # bound on every wait for a process (the machine may be busy)


def python(code: str, *args, cwd) -> subprocess.Popen:
    """`python -c CODE ARGS` with the sources under test, not waited for; stdin, stdout and stderr are pipes."""
    env = {**os.environ, "PYTHONPATH": str(CODE_ROOT), "CI": "true"}
    env.pop("WINGSIM_DEBUG", None)
    return subprocess.Popen([sys.executable, "-c", code, *map(str, args)], cwd=cwd, env=env, text=True,
                            stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE)


def finished(proc: subprocess.Popen, stdin: str = "") -> tuple[str, str]:
    """(stdout, stderr) of `proc` once it has exited, within WAIT_S."""
    try:
        return proc.communicate(stdin, timeout=WAIT_S)
    except subprocess.TimeoutExpired as late:
        proc.kill()
        raise AssertionError(f"the process had not exited after {WAIT_S:g} s: {proc.communicate()}") from late


def complete_png(path: Path) -> bool:
    from matplotlib.image import imread

    data = path.read_bytes()
    if not (data.startswith(b"\x89PNG\r\n\x1a\n") and data.endswith(PNG_END)):
        return False
    imread(path)   # decodes, or raises
    return True


# --- a kill while a PNG is written --------------------------------------------------------------------------

# wingsim in a process that kills itself (SIGKILL) halfway through the first PNG it writes into a folder whose
# name starts with sys.argv[1]: the bytes of the picture written, then cut short, as a kill mid-write leaves them
KILLED_WHILE_PLOTTING = """
import os, signal, sys
from matplotlib.figure import Figure
from orchestrator.cli import main

real = Figure.savefig
def savefig(self, fname, *args, **kwargs):
    real(self, fname, *args, **kwargs)
    if os.path.basename(os.path.dirname(os.path.abspath(fname))).startswith(sys.argv[1]):
        with open(fname, "r+b") as handle:
            handle.truncate(os.path.getsize(fname) // 2)
        os.kill(os.getpid(), signal.SIGKILL)
Figure.savefig = savefig
sys.exit(main(sys.argv[2:]))
"""


def test_a_kill_while_plotting_leaves_no_truncated_png_and_the_resume_runs_that_run_again(tmp_path):
    out = tmp_path / "sweep"
    args = ["sweep", DEPLOY, *STILL, "--grid", "structure.joints.fold.torque=0.3,0.4", "--jobs", "1", "--plots",
            "--out", out]
    killed = python(KILLED_WHILE_PLOTTING, "001_", *args, cwd=tmp_path)   # killed in run 1's plots
    finished(killed)
    assert killed.returncode == -signal.SIGKILL
    run0, run1 = sorted((out / "runs").iterdir())
    pngs = sorted(p for p in out.rglob("*.png") if not p.name.startswith("."))   # under their final names
    assert {p.parent for p in pngs} == {run0}          # run 0 has its plots; run 1 none under a final name
    assert all(complete_png(p) for p in pngs)
    assert list(run1.glob(".*.partial.png"))           # the half-written picture is a temporary file
    assert json.loads((run1 / "run.json").read_text())["complete"] is False

    done = wingsim(*args, cwd=tmp_path)                # the same command resumes
    assert done.returncode == 0, done.stderr
    assert "1/2 runs already done" in done.stderr
    assert "2 runs, 1 run now (ok 1), 1 already done" in done.stdout
    record = json.loads((run1 / "run.json").read_text())
    assert record["complete"] is True
    plots = sorted(p.name for p in run1.glob("*.png"))
    assert plots == sorted(p.name for p in run0.glob("*.png")) and "fold_angles.png" in plots
    assert all(complete_png(run1 / p) for p in plots)
    assert set(plots) <= set(record["files"])
    assert not list(out.rglob("*.partial*"))           # the killed writer's temporary file is gone


# --- a busy folder --------------------------------------------------------------------------------------------

# wingsim in a process that says "running" and waits for a line on stdin when its run starts
PAUSED_RUN = """
import sys
import orchestrator.run.master as master
from orchestrator.cli import main

real = master.run_scene
def run_scene(*args, **kwargs):
    print("running", flush=True)
    sys.stdin.readline()
    return real(*args, **kwargs)
master.run_scene = run_scene
sys.exit(main(sys.argv[1:]))
"""


def paused_run(out: Path, cwd: Path) -> subprocess.Popen:
    proc = python(PAUSED_RUN, "run", DEPLOY, *STILL, "--backend", "direct", "--out", out, cwd=cwd)
    assert proc.stdout.readline() == "running\n", finished(proc)
    return proc


def test_a_second_run_or_sweep_into_a_busy_folder_is_refused_naming_the_first(tmp_path, capsys, monkeypatch):
    out = tmp_path / "out"
    first = paused_run(out, tmp_path)
    second = wingsim("run", DEPLOY, *STILL, "--backend", "direct", "--set", "structure.joints.fold.torque=0.4",
                     "--out", out, cwd=tmp_path)
    assert second.returncode == 2, second.stderr
    holder = json.loads((out / "run.json").read_text())
    assert f"error: --out {str(out)!r}: busy: run {holder['run_id']} (pid {first.pid} on " in second.stderr
    monkeypatch.chdir(tmp_path)
    assert main(["sweep", str(DEPLOY), *STILL, "--grid", "flow.speed=0,1", "--out", str(out)]) == 2
    assert f"busy: run {holder['run_id']} (pid {first.pid} " in capsys.readouterr().err
    assert holder["pid"] == first.pid and not (out / "runs").exists()            # nothing of the others
    assert json.loads((out / "summary.json").read_text())["status"] == "running"
    _, err = finished(first, "\n")
    assert first.returncode == 0, err
    record = json.loads((out / "run.json").read_text())
    assert record["pid"] == first.pid and record["complete"] is True
    assert record["overrides"] == ["aero.model=none", "time.stop=0.02"]
    assert not (out / ".wingsim.lock").exists()                                  # released


def test_the_folder_of_a_killed_run_is_taken_over_with_a_note(tmp_path):
    out = tmp_path / "out"
    first = paused_run(out, tmp_path)
    killed_id = json.loads((out / "run.json").read_text())["run_id"]
    first.kill()
    finished(first)
    second = wingsim("run", DEPLOY, *STILL, "--backend", "direct", "--out", out, cwd=tmp_path)
    assert second.returncode == 0, second.stderr
    assert (f"note: taking over {out} from run {killed_id} (pid {first.pid} on " in second.stderr
            and "which ended without releasing it" in second.stderr)
    record = json.loads((out / "run.json").read_text())
    assert record["pid"] != first.pid and record["complete"] is True
    assert json.loads((out / "summary.json").read_text())["status"] == "ok"


# --- builds of one folder -------------------------------------------------------------------------------------

def guids(fmu: Path) -> tuple[str, bool]:
    """(the GUID of the FMU's model description, whether its Linux binary carries that GUID)."""
    with zipfile.ZipFile(fmu) as z:
        guid = re.search(r'guid="([^"]+)"', z.read("modelDescription.xml").decode()).group(1)
        identifier = re.search(r'modelIdentifier="([^"]+)"', z.read("modelDescription.xml").decode()).group(1)
        return guid, guid.encode() in z.read(f"binaries/linux64/{identifier}.so")


def test_a_build_waits_for_the_build_that_holds_its_folder(tmp_path):
    folder = tmp_path / "fmus"
    with build_lock(folder):   # this process builds there
        proc = subprocess.Popen([sys.executable, "-m", "orchestrator", "build", str(PENDULUM), "--out", str(folder)],
                                cwd=tmp_path, env={**os.environ, "PYTHONPATH": str(CODE_ROOT), "CI": "true"},
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        lines = []
        while not lines or "waiting for" not in lines[-1]:
            line = proc.stderr.readline()
            assert line, f"the build did not wait: {''.join(lines)}{finished(proc)}"
            lines.append(line)
        assert f"(pid {os.getpid()} on " in lines[-1] and str(folder) in lines[-1]
        assert not (folder / "structure.fmu").exists()
    _, err = finished(proc)
    assert proc.returncode == 0, err
    guid, carried = guids(folder / "structure.fmu")
    assert carried, guid


def test_a_run_pairs_the_model_description_and_the_binary_of_one_build(tmp_path, monkeypatch):
    # another build replaces the FMU while a run opens it: the run must not take the GUID of one and the binary
    # of the other (fmi2Instantiate refuses a GUID its binary was not compiled with)
    import fmpy

    from orchestrator.run.master import run_scene

    scene = load_scene(PENDULUM, ["time.stop=0.01"])
    folder, other = tmp_path / "fmus", tmp_path / "other"
    build_fmus(scene, folder)
    build_fmus(scene, other)
    assert guids(folder / "structure.fmu")[0] != guids(other / "structure.fmu")[0]
    real = fmpy.extract

    def rebuilt_then_extract(filename, *args, **kwargs):
        if (other / "structure.fmu").exists():
            os.replace(other / "structure.fmu", folder / "structure.fmu")
        return real(filename, *args, **kwargs)

    monkeypatch.setattr(fmpy, "extract", rebuilt_then_extract)
    result = run_scene(scene, backend="fmu", fmu_dir=folder)
    assert result.status == "ok", result.message


@pytest.mark.slow
@pytest.mark.skipif(standalone.unavailable_reason() is not None, reason=str(standalone.unavailable_reason()))
def test_concurrent_standalone_builds_of_one_scene_both_succeed_with_consistent_guids(tmp_path):
    # a standalone build rewrites its FMUs after building them: two at once used to share that rewrite
    procs = [python("import sys; from orchestrator.cli import main; sys.exit(main(sys.argv[1:]))", "build",
                    PENDULUM, "--standalone", "--out", tmp_path / "fmus", cwd=tmp_path) for _ in range(2)]
    errors = [finished(proc)[1] for proc in procs]
    assert [proc.returncode for proc in procs] == [0, 0], errors
    guid, carried = guids(tmp_path / "fmus" / "structure.fmu")
    assert carried, guid
    assert not [p.name for p in (tmp_path / "fmus").iterdir() if p.name.startswith(".")]   # no temporary or lock file


# --- exports --------------------------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def pendulum_system(tmp_path_factory):
    folder = tmp_path_factory.mktemp("pendulum_fmus")
    scene = load_scene(PENDULUM)
    build_fmus(scene, folder)
    return coupled_system(scene, folder)


@pytest.mark.parametrize("writer", ["container", "ssp"])
def test_concurrent_exports_into_one_file_do_not_share_a_temporary_file(pendulum_system, tmp_path, writer,
                                                                         monkeypatch):
    # a second export of the same file runs whole while the first is in the middle of writing its archive
    write = {"container": container.write_container, "ssp": ssp.write_ssp}[writer]
    hook = {"container": (container, "_copy_unit"), "ssp": (ssp, "system_structure")}[writer]
    path = tmp_path / ("wing.fmu" if writer == "container" else "pendulum_rigid.ssp")
    real, nested = getattr(*hook), []

    def with_another_export(*args):
        if not nested:
            nested.append(None)
            nested[0] = write(pendulum_system, path)
        return real(*args)

    monkeypatch.setattr(*hook, with_another_export)
    assert write(pendulum_system, path) == path
    assert nested == [path]
    with zipfile.ZipFile(path) as z:
        assert z.testzip() is None
        names = z.namelist()
    assert ("modelDescription.xml" in names) if writer == "container" else ("SystemStructure.ssd" in names)
    assert [p.name for p in tmp_path.iterdir()] == [path.name]   # no temporary file left


def test_an_export_does_not_rename_across_folders(tmp_path, capsys, monkeypatch):
    # the temporary folder on another file system: every rename that leaves its folder fails as the kernel
    # refuses a rename across file systems (EXDEV); the export must not need one
    real_replace, real_rename = os.replace, os.rename
    crossed = []

    def same_folder_only(real):
        def rename(src, dst, *args, **kwargs):
            if Path(os.fsdecode(src)).resolve().parent != Path(os.fsdecode(dst)).resolve().parent:
                crossed.append((src, dst))
                raise OSError(errno.EXDEV, os.strerror(errno.EXDEV), os.fsdecode(src), None, os.fsdecode(dst))
            return real(src, dst, *args, **kwargs)
        return rename

    monkeypatch.setattr(os, "replace", same_folder_only(real_replace))
    monkeypatch.setattr(os, "rename", same_folder_only(real_rename))
    monkeypatch.chdir(tmp_path)
    assert main(["export", str(PENDULUM), "--out", str(tmp_path / "export")]) == 0, capsys.readouterr().err
    assert crossed == []
    for name in ("pendulum_rigid.ssp", "wing.fmu"):
        assert zipfile.ZipFile(tmp_path / "export" / name).testzip() is None


SHM = Path("/dev/shm")


@pytest.mark.skipif(not SHM.is_dir() or not os.access(SHM, os.W_OK), reason="no /dev/shm to write")
def test_an_export_onto_another_file_system_than_the_temporary_folder(tmp_path):
    temporary = tmp_path / "tmp"
    temporary.mkdir()
    out = SHM / f"wingsim-export-{os.getpid()}-{tmp_path.name}"
    if os.stat(SHM).st_dev == os.stat(temporary).st_dev:
        pytest.skip("/dev/shm is on the same file system as the test folder here")
    env = {**os.environ, "PYTHONPATH": str(CODE_ROOT), "CI": "true", "TMPDIR": str(temporary)}
    try:
        done = subprocess.run([sys.executable, "-m", "orchestrator", "export", str(PENDULUM), "--out", str(out)],
                              cwd=tmp_path, env=env, capture_output=True, text=True, timeout=600)
        assert done.returncode == 0, done.stderr
        for name in ("pendulum_rigid.ssp", "wing.fmu"):
            assert zipfile.ZipFile(out / name).testzip() is None
        assert sorted(p.name for p in out.iterdir()) == ["pendulum_rigid.ssp", "wing.fmu"]
    finally:
        for path in out.glob("*") if out.is_dir() else ():
            path.unlink()
        if out.is_dir():
            out.rmdir()
