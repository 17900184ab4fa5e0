"""The command line refuses before it runs and leaves nothing behind: ``--out`` checked first, summary.json
written before the big files, a sweep that goes on past a run it cannot write, SIGTERM handled like Ctrl-C,
sweep workers that die with their parent, and FMU folders keyed by the resolved scene."""
from __future__ import annotations

import csv
import errno
import json
import os
import signal
import subprocess
import sys
import time
import uuid
import zipfile
from pathlib import Path

import pytest

import orchestrator.run.master
import orchestrator.output.results
from orchestrator.build.fmus import build_digest, embedded_scene
from orchestrator.cli import FMU_ROOT, fmu_dir, main
from orchestrator.run.master import RunResult, new_series
from orchestrator.output.results import read_timeseries, summarize
from orchestrator.scene.load import load_scene
from orchestrator.files import process_record
from orchestrator.output.run_record import finish_record, start_record
from orchestrator.sweep import combinations, finished_summary, parse_grid
from subprocesses import CODE_ROOT
from repository import SCENES

SCENE = SCENES / "deploy_rigid.toml"
STILL = ["--set", "aero.model=none", "--set", "time.stop=0.02", "--backend", "direct"]
CONTRACT_STATUSES = {"ok", "diverged", "error"}
MARKER = "WINGSIM_TEST_MARKER"
WAIT_S = 30.0   # bound on every wait for a process (the machine may be busy)


def no_space(*args, **kwargs):
    raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))


# --- --out is checked before anything runs --------------------------------------------------------------

COMMANDS = {
    "run": ["run", SCENE, *STILL],
    "sweep": ["sweep", SCENE, "--set", "aero.model=none", "--grid", "flow.speed=0,10"],
    "export": ["export", SCENE],
    "build": ["build", SCENE],
}


def refused(command, out, tmp_path, capsys, monkeypatch):
    """Exit code and stderr of `wingsim COMMAND --out OUT` in tmp_path; asserts that nothing was written."""
    monkeypatch.chdir(tmp_path)
    before = sorted(p.name for p in tmp_path.iterdir())
    code = main([*map(str, COMMANDS[command]), "--out", str(out)])
    err = capsys.readouterr().err
    assert sorted(p.name for p in tmp_path.iterdir()) == before   # no fmus/, results/ or export/
    return code, err


@pytest.mark.parametrize("command", COMMANDS)
def test_out_that_is_a_file_is_refused(command, tmp_path, capsys, monkeypatch):
    out = tmp_path / "a_file"
    out.write_text("")
    code, err = refused(command, out, tmp_path, capsys, monkeypatch)
    assert code == 2
    assert err == f"error: --out {str(out)!r}: is a file; give a folder (it is created if missing)\n"


@pytest.mark.parametrize("command", COMMANDS)
def test_out_below_a_file_is_refused(command, tmp_path, capsys, monkeypatch):
    (tmp_path / "a_file").write_text("")
    out = tmp_path / "a_file" / "deeper" / "results"
    code, err = refused(command, out, tmp_path, capsys, monkeypatch)
    assert code == 2
    assert err == (f"error: --out {str(out)!r}: is below {str(tmp_path / 'a_file')!r}, which is a file, "
                   "not a folder\n")


def test_out_in_a_read_only_folder_is_refused(tmp_path, capsys, monkeypatch):
    locked = tmp_path / "locked"
    locked.mkdir(mode=0o555)
    try:
        probe = locked / "probe"
        probe.touch()
        probe.unlink()
        pytest.skip("permission bits do not stop this user (root) from writing; "
                    "test_out_the_kernel_refuses_to_write_in_is_refused covers a read-only folder")
    except PermissionError:
        pass
    for out in (locked, locked / "results"):
        code, err = refused("run", out, tmp_path, capsys, monkeypatch)
        assert code == 2 and err.startswith(f"error: --out {str(out)!r}: cannot write there: Permission denied")


@pytest.mark.skipif(not Path("/sys/kernel").is_dir(), reason="needs Linux's /sys, read-only also for root")
def test_out_the_kernel_refuses_to_write_in_is_refused(tmp_path, capsys, monkeypatch):
    # sysfs refuses new files even to root: a read-only folder whatever the user
    for command in COMMANDS:
        code, err = refused(command, Path("/sys/kernel"), tmp_path, capsys, monkeypatch)
        assert code == 2 and err.startswith("error: --out '/sys/kernel': cannot write there: ")
        assert len(err.splitlines()) == 1


def test_a_missing_out_folder_is_created(tmp_path, capsys, monkeypatch):
    out = tmp_path / "new" / "deeper"
    monkeypatch.chdir(tmp_path)
    assert main([*map(str, COMMANDS["run"]), "--out", str(out)]) == 0
    assert json.loads((out / "summary.json").read_text())["status"] == "ok"
    assert not [p for p in out.iterdir() if p.name.startswith(".")]   # no probe or temporary file left


# --- summary.json first, the big files after --------------------------------------------------------------

def test_the_summary_is_written_before_the_run_and_completed_before_the_timeseries(tmp_path, capsys, monkeypatch):
    out = tmp_path / "out"
    seen = {}
    real_run = orchestrator.run.master.run_scene
    real_timeseries = orchestrator.output.results.write_timeseries

    def run_scene(scene, **kwargs):
        seen["at run"] = json.loads((out / "summary.json").read_text())
        seen["scene"] = scene
        return real_run(scene, **kwargs)

    def write_timeseries(series, path):
        seen["at timeseries"] = json.loads((out / "summary.json").read_text())
        real_timeseries(series, path)

    monkeypatch.setattr(orchestrator.run.master, "run_scene", run_scene)
    monkeypatch.setattr(orchestrator.output.results, "write_timeseries", write_timeseries)
    monkeypatch.chdir(tmp_path)
    assert main([*map(str, COMMANDS["run"]), "--out", str(out)]) == 0
    started = seen["at run"]
    assert started["status"] == "running" and started["scene"] == seen["scene"]
    assert started["scene"]["aero"]["model"] == "none" and started["scene"]["time"]["stop"] == 0.02
    assert seen["at timeseries"]["status"] == "ok" and seen["at timeseries"]["simulated_time_s"] == 0.02
    final = json.loads((out / "summary.json").read_text())
    assert final == seen["at timeseries"] and final["status"] in CONTRACT_STATUSES


def test_a_full_disk_loses_the_timeseries_not_the_summary(tmp_path, capsys, monkeypatch):
    out = tmp_path / "out"
    monkeypatch.setattr(orchestrator.output.results, "write_timeseries", no_space)
    monkeypatch.chdir(tmp_path)
    assert main([*map(str, COMMANDS["run"]), "--out", str(out)]) == 1
    err = capsys.readouterr().err
    assert f"error: cannot write {out / 'timeseries.csv'}: No space left on device" in err
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "ok" and summary["simulated_time_s"] == 0.02
    assert summary["message"].endswith("(timeseries.csv not written: No space left on device)")
    # no partial or temporary file, the lock released; run.json says the folder is not complete
    assert sorted(p.name for p in out.iterdir()) == ["run.json", "summary.json"]
    assert json.loads((out / "run.json").read_text())["complete"] is False


def test_a_disk_full_from_the_start_keeps_the_started_summary(tmp_path, capsys, monkeypatch):
    out = tmp_path / "out"
    real_write = orchestrator.output.results.write_file
    writes = []

    def fill_after_first(path, write):   # the disk fills up after the summary written before the run
        writes.append(Path(path).name)
        real_write(path, write if len(writes) == 1 else no_space)

    monkeypatch.setattr(orchestrator.output.results, "write_file", fill_after_first)
    monkeypatch.chdir(tmp_path)
    assert main([*map(str, COMMANDS["run"]), "--out", str(out)]) == 1
    assert f"error: cannot write {out / 'summary.json'}: No space left on device" in capsys.readouterr().err
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "running" and summary["scene"]["time"]["stop"] == 0.02
    assert writes == ["summary.json", "summary.json"]   # the timeseries is not tried after the summary failed


def test_a_summary_that_cannot_be_written_stops_before_the_run(tmp_path, capsys, monkeypatch):
    ran = []
    real_write = orchestrator.output.results.write_file
    monkeypatch.setattr(orchestrator.output.results, "write_file", lambda path, write: real_write(path, no_space))
    monkeypatch.setattr(orchestrator.run.master, "run_scene", lambda *a, **k: ran.append(a))
    monkeypatch.chdir(tmp_path)
    assert main([*map(str, COMMANDS["run"]), "--out", str(tmp_path / "out")]) == 1
    assert capsys.readouterr().err == (f"error: cannot write {tmp_path / 'out' / 'summary.json'}: "
                                       "No space left on device; nothing was run\n")
    assert ran == []


# --- a sweep goes on past what it cannot write -----------------------------------------------------------

def test_a_sweep_goes_on_past_an_unwritable_run_folder_a_full_disk_and_a_diverged_run(tmp_path, capsys,
                                                                                       monkeypatch):
    # stiffness 1e7 N m/rad with RK4 at 1 ms is far beyond the explicit stability limit: run 2 diverges
    grid = "structure.joints.fold.stiffness=0.02,0.026,1e7"
    names = [run.name for run in combinations(parse_grid([grid]))]
    out = tmp_path / "sweep"
    (out / "runs").mkdir(parents=True)
    (out / "runs" / names[0]).write_text("")          # run 0's folder is taken by a file

    real_timeseries = orchestrator.output.results.write_timeseries

    def full_for_run_1(series, path):
        if Path(path).parent.name == names[1]:
            no_space()
        real_timeseries(series, path)

    monkeypatch.setattr(orchestrator.output.results, "write_timeseries", full_for_run_1)
    monkeypatch.chdir(tmp_path)
    code = main(["sweep", str(SCENE), "--set", "aero.model=none", "--set", "time.stop=0.05", "--set",
                 "structure.step=1e-3", "--grid", grid, "--jobs", "1", "--out", str(out)])
    assert code == 1
    with (out / "sweep.csv").open(newline="") as handle:
        rows = list(csv.DictReader(handle))
    assert [row["status"] for row in rows] == ["error", "error", "diverged"]
    assert rows[0]["message"] == f"cannot write {out / 'runs' / names[0]}: File exists; not run"
    assert rows[1]["message"].startswith(f"cannot write {out / 'runs' / names[1] / 'timeseries.csv'}: "
                                         "No space left on device (the run itself: ok: ")
    assert "diverged" in rows[2]["message"]
    # run 1's summary is complete; run 2's results are all there
    assert json.loads((out / "runs" / names[1] / "summary.json").read_text())["status"] == "ok"
    assert not (out / "runs" / names[1] / "timeseries.csv").exists()
    assert (out / "runs" / names[2] / "timeseries.csv").read_text().startswith("time [s],")


def test_resume_reruns_a_run_that_was_running_or_lost_its_timeseries(tmp_path):
    run = combinations(parse_grid(["flow.speed=0"]), ["aero.model=none"])[0]
    run.scene = load_scene(SCENE, run.overrides)
    run_dir = tmp_path / run.name
    run_dir.mkdir()
    record = start_record(run_dir, process_record(), run.overrides, sweep={"backend": "direct", "plots": False})
    summary = summarize(RunResult("ok", "", 1.0, 0.3, run.scene, new_series(run.scene)))
    (run_dir / "summary.json").write_text(json.dumps(summary))
    (run_dir / "timeseries.csv").write_text("time\n")
    assert finished_summary(run, run_dir, "direct") is None            # run.json not completed: rerun
    finish_record(run_dir, record, [run_dir / "summary.json"])
    assert finished_summary(run, run_dir, "direct") is None            # no timeseries.csv written: rerun
    finish_record(run_dir, record, [run_dir / "summary.json", run_dir / "timeseries.csv"])
    assert finished_summary(run, run_dir, "direct") == summary          # complete: skipped
    assert finished_summary(run, run_dir, "fmu") is None               # another backend: rerun
    assert finished_summary(run, run_dir, "direct", plots=True) is None   # plots asked for, none made: rerun
    (run_dir / "timeseries.csv").write_text("time\n0\n")
    assert finished_summary(run, run_dir, "direct") is None            # changed since: rerun
    (run_dir / "summary.json").write_text(json.dumps({**summary, "status": "running"}))
    finish_record(run_dir, record, [run_dir / "summary.json", run_dir / "timeseries.csv"])
    assert finished_summary(run, run_dir, "direct") is None            # stopped during the run: rerun


# --- signals: SIGTERM like Ctrl-C, no orphans --------------------------------------------------------------

def start(*args, cwd, marker):
    """`python -m orchestrator ARGS` as tests/subprocesses.wingsim runs it, not waited for; every process it
    starts inherits MARKER=marker in its environment."""
    env = {**os.environ, "PYTHONPATH": str(CODE_ROOT), "CI": "true", MARKER: marker}
    env.pop("WINGSIM_DEBUG", None)
    return subprocess.Popen([sys.executable, "-m", "orchestrator", *map(str, args)], cwd=cwd, env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def ended(proc: subprocess.Popen, what: str) -> str:
    """stderr of `proc` once it has exited, within WAIT_S (killed and failed after that)."""
    try:
        return proc.communicate(timeout=WAIT_S)[1]
    except subprocess.TimeoutExpired as late:
        proc.kill()
        raise AssertionError(f"{what} had not exited {WAIT_S:g} s after the signal: {proc.communicate()[1]}") from late


def _proc(pid: int, name: str) -> bytes:
    return Path(f"/proc/{pid}/{name}").read_bytes()


def marked(marker: str) -> dict[int, str]:
    """Live (not zombie) processes whose environment holds MARKER=marker: {pid: command line}."""
    found = {}
    tag = f"{MARKER}={marker}".encode()
    for entry in os.listdir("/proc"):
        if not entry.isdigit():
            continue
        try:
            if tag not in _proc(int(entry), "environ").split(b"\0"):
                continue
            state = _proc(int(entry), "stat").rsplit(b")", 1)[1].split()[0]
            if state not in (b"Z", b"X"):
                found[int(entry)] = _proc(int(entry), "cmdline").replace(b"\0", b" ").decode()
        except OSError:   # gone meanwhile
            continue
    return found


def children(pid: int) -> dict[int, str]:
    """Live children of `pid` (by PPid in /proc/<child>/status): {pid: command line}."""
    found = {}
    for entry in os.listdir("/proc"):
        if not entry.isdigit():
            continue
        try:
            status = _proc(int(entry), "status").decode()
            ppid = int(status.split("PPid:")[1].split()[0])
            if ppid == pid and "State:\tZ" not in status:
                found[int(entry)] = _proc(int(entry), "cmdline").replace(b"\0", b" ").decode()
        except (OSError, IndexError, ValueError):
            continue
    return found


def wait_for(condition, what: str, timeout: float = WAIT_S):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        value = condition()
        if value:
            return value
        time.sleep(0.05)
    raise AssertionError(f"waited {timeout:g} s for {what}")


def initialized(pid: int) -> bool:
    """The worker's initializer has run: its last act, ignoring SIGINT, shows in /proc/<pid>/status
    (SigIgn, a bit mask of the ignored signals, bit 1 << (signum - 1))."""
    try:
        status = _proc(pid, "status").decode()
        return bool(int(status.split("SigIgn:")[1].split()[0], 16) & 1 << (signal.SIGINT - 1))
    except (OSError, IndexError, ValueError):
        return False


def sweep_with_two_workers(tmp_path):
    """A sweep of two long still-air runs on two workers, once both workers are initialized (they then
    take a run each) and multiprocessing's resource tracker has started: (process, marker,
    {pid: command line} of its children)."""
    marker = uuid.uuid4().hex
    proc = start("sweep", SCENE, "--set", "aero.model=none", "--set", "time.stop=200", "--grid",
                 "flow.speed=0,10", "--jobs", "2", "--out", tmp_path / "sweep", cwd=tmp_path, marker=marker)

    def started():
        kids = children(proc.pid)
        workers = [pid for pid, c in kids.items() if "multiprocessing" in c and "resource_tracker" not in c]
        tracker = [c for c in kids.values() if "resource_tracker" in c]
        return kids if len(workers) == 2 and all(map(initialized, workers)) and len(tracker) == 1 else None

    try:
        kids = wait_for(started, "two sweep workers and the resource tracker")
    except AssertionError as missing:
        proc.kill()
        raise AssertionError(proc.communicate()[1]) from missing
    assert set(kids) <= set(marked(marker))   # the marker reaches them: it finds them after the parent dies
    return proc, marker, kids


def test_sigterm_to_a_sweep_writes_what_it_has_and_leaves_no_process(tmp_path):
    proc, marker, _ = sweep_with_two_workers(tmp_path)
    proc.send_signal(signal.SIGTERM)
    err = ended(proc, "the sweep (its runs take minutes: it must stop them, not wait for them)")
    assert proc.returncode == 143, err
    assert "sweep: interrupted (SIGTERM) after 0/2 runs" in err and "error: interrupted (SIGTERM)" in err
    assert "Traceback" not in err
    wait_for(lambda: not marked(marker), "the workers and the resource tracker to exit")
    assert (tmp_path / "sweep" / "sweep.csv").read_text().startswith("index,flow.speed,status,")
    runs = list((tmp_path / "sweep" / "runs").iterdir())
    assert len(runs) == 2
    for run in runs:   # killed while running: the started summary stays
        assert json.loads((run / "summary.json").read_text())["status"] == "running"


def test_sigkill_to_a_sweep_leaves_no_process(tmp_path):
    proc, marker, kids = sweep_with_two_workers(tmp_path)
    proc.kill()
    ended(proc, "the sweep")
    assert proc.returncode == -signal.SIGKILL
    assert any("resource_tracker" in command for command in kids.values())
    wait_for(lambda: not marked(marker), "the workers and the resource tracker to exit")


@pytest.mark.parametrize("signum, code", [(signal.SIGTERM, 143), (signal.SIGINT, 130)])
def test_a_signal_to_a_run_writes_its_results_so_far(signum, code, tmp_path):
    out = tmp_path / "out"
    proc = start("run", SCENE, "--set", "aero.model=none", "--set", "time.stop=200", "--backend", "direct",
                 "--out", out, cwd=tmp_path, marker=uuid.uuid4().hex)
    wait_for(lambda: (out / "summary.json").exists(), "the summary written before the run")
    proc.send_signal(signum)
    err = ended(proc, "the run")
    assert proc.returncode == code, err
    assert "Traceback" not in err
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "interrupted" and "interrupted" in summary["message"]
    assert summary["simulated_time_s"] < 200
    assert (out / "timeseries.csv").read_text().startswith("time [s],")


# --- FMU folders of --set variants ------------------------------------------------------------------------

def test_fmu_folders_are_keyed_by_what_the_fmus_are_built_from():
    written = load_scene(SCENE)
    assert fmu_dir(written, written) == FMU_ROOT / "deploy_rigid"   # where `wingsim build` puts them
    # tunable keys are parameters of the FMUs built for the file's scene
    assert fmu_dir(load_scene(SCENE, ["flow.speed=8", "structure.joints.fold.torque=0.1"]), written) == fmu_dir(
        written, written)
    coarse, fine = load_scene(SCENE, ["aero.spanwise_panels=5"]), load_scene(SCENE, ["aero.spanwise_panels=9"])
    assert fmu_dir(coarse, written) == FMU_ROOT / f"deploy_rigid-{build_digest(coarse)[:12]}"
    assert fmu_dir(coarse, written) != fmu_dir(fine, written)
    assert fmu_dir(load_scene(SCENE, ["aero.spanwise_panels=5", "flow.speed=8"]), written) == fmu_dir(coarse, written)
    assert fmu_dir(written, None) == FMU_ROOT / f"deploy_rigid-{build_digest(written)[:12]}"   # no valid file scene


def test_concurrent_runs_of_two_variants_both_succeed(tmp_path):
    panels = ("5", "6")
    procs = [start("run", SCENE, "--set", f"aero.spanwise_panels={n}", "--set", "time.stop=0.02", "--out",
                   tmp_path / f"out{n}", cwd=tmp_path, marker=uuid.uuid4().hex) for n in panels]
    for proc in procs:
        _, err = proc.communicate(timeout=600)
        assert proc.returncode == 0, err
    for n in panels:
        summary = json.loads((tmp_path / f"out{n}" / "summary.json").read_text())
        assert summary["status"] == "ok" and summary["scene"]["aero"]["spanwise_panels"] == int(n)
        folder = tmp_path / fmu_dir(load_scene(SCENE, [f"aero.spanwise_panels={n}", "time.stop=0.02"]),
                                    load_scene(SCENE))
        for unit in ("structure.fmu", "aero.fmu"):   # each variant's FMUs carry its own scene
            assert zipfile.is_zipfile(folder / unit)
            assert embedded_scene(folder / unit)["aero"]["spanwise_panels"] == int(n)


def test_concurrent_runs_of_tunable_variants_share_one_build(tmp_path):
    # flow.speed is tunable: both runs need the FMUs of one folder, which one of them builds while the other
    # waits (orchestrator.build.fmus.build_lock); each runs its own speed on them
    speeds = ("8", "12")
    procs = [start("run", SCENE, "--set", f"flow.speed={speed}", "--set", "time.stop=0.02", "--out",
                   tmp_path / f"out{speed}", cwd=tmp_path, marker=uuid.uuid4().hex) for speed in speeds]
    errors = [proc.communicate(timeout=600)[1] for proc in procs]
    assert [proc.returncode for proc in procs] == [0, 0], errors
    assert sum(err.count("building the FMUs") for err in errors) == 1, errors
    lift = {}
    for speed in speeds:
        summary = json.loads((tmp_path / f"out{speed}" / "summary.json").read_text())
        assert summary["status"] == "ok" and summary["scene"]["flow"]["speed"] == float(speed)
        lift[speed] = float(read_timeseries(tmp_path / f"out{speed}" / "timeseries.csv")[0]["lift"][-1])
    assert lift["8"] != lift["12"]   # each run got its own speed


def test_ctrl_c_on_the_fmu_backend_is_recorded_as_interrupted(tmp_path):
    """SIGINT while the FMUs run: the signal reaches the slave's Python inside an FMI call, which the FMI layer
    turns into fmi2Fatal; the run is still recorded as interrupted (not as an error quoting the FMU), exit 130."""
    overrides = ["--set", "aero.model=none", "--set", "time.stop=200"]
    out = tmp_path / "out"
    built = subprocess.run([sys.executable, "-m", "orchestrator", "build", SCENE, *overrides], cwd=tmp_path,
                           env={**os.environ, "PYTHONPATH": str(CODE_ROOT)}, capture_output=True, text=True)
    assert built.returncode == 0, built.stderr
    proc = start("run", SCENE, *overrides, "--out", out, cwd=tmp_path, marker=uuid.uuid4().hex)
    wait_for(lambda: b"structure.so" in _proc(proc.pid, "maps"), "the structure FMU's binary loaded")
    time.sleep(1.0)   # into the steps (an earlier signal is an interruption too, before the first step)
    proc.send_signal(signal.SIGINT)
    err = ended(proc, "the run")
    assert proc.returncode == 130, err
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "interrupted" and summary["message"].startswith("interrupted (SIGINT)")
    assert "Fatal" not in summary["message"] and "Traceback" not in err
    assert summary["simulated_time_s"] < 200
    assert f"t = {summary['simulated_time_s']:.4g} / 200 s" in err and err.endswith(": interrupted\n")   # progress
