"""Standalone FMUs (`wingsim build --standalone`, orchestrator/build/standalone.py): a unit that carries its Python
runtime and runs it in a worker process of its own.

What is checked, against behaviour or an independent number:
- what the FMU holds: linux64 binaries only, and every library any of its binaries needs is in the FMU or is a
  system C library (read from the binaries' dynamic sections, not from a list the build wrote);
- the coupled deployment through the standalone FMUs equals, bit for bit, the same run through the ordinary FMUs
  (the same code and arithmetic in another process);
- the host is left as it was: its BLAS thread counts, signal masks and handlers (the ordinary FMU, which runs in
  the host's interpreter, changes the BLAS threads: the check sees a change where there is one);
- a worker that dies (killed, or crashing in a compiled kernel) gives the host fmi2Fatal with the reason logged,
  and the host lives; no worker is left after fmi2FreeInstance, after the host exits, or after it is killed
  with SIGKILL (the process table is read).
The slow set adds every shipped scene built standalone (its first steps equal the ordinary FMUs'), a host
whose Python has numpy 1.26 and no scipy, two builds from different sources in one process, and two instances
stepping in parallel in libcosim; tests/fmi/test_no_python.py runs the FMUs on a system without Python.
"""
import hashlib
import json
import os
import signal
import struct
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest
from fmpy import extract

from fmi_hosts import all_gone, processes
from fmu_common.c_library import record_file
from orchestrator.build import runtime
from orchestrator.run.master import run_scene
from orchestrator.scene.load import load_scene
from repository import SCENES

HOST = Path(__file__).resolve().parent / "fmpy_host.py"
FATAL = 4


@pytest.fixture(scope="module")
def rigid(standalone_fmus):
    return standalone_fmus("deploy_rigid")


def host(folder, *actions, env=None, timeout=300):
    """Run fmpy_host.py on the unpacked FMU `folder`; its JSON lines, one per action, in order."""
    proc = subprocess.run([sys.executable, str(HOST), str(folder), *actions], capture_output=True, text=True,
                          timeout=timeout, env=env)
    assert proc.returncode == 0, proc.stderr
    return [json.loads(line) for line in proc.stdout.splitlines()]


def workers_of(folder) -> list[int]:
    """The processes running a program of the unpacked FMU `folder` (its workers), from the process table."""
    return processes(lambda command: command.split(b"\0")[0].startswith(f"{folder}/".encode()))


def test_the_fmu_carries_linux64_binaries_and_every_library_they_need(rigid, tmp_path):
    for name in ("structure", "aero"):
        fmu = rigid / f"{name}.fmu"
        with zipfile.ZipFile(fmu) as z:
            platforms = {n.split("/")[1] for n in z.namelist() if n.startswith("binaries/") and n.count("/") > 1}
        assert platforms == {"linux64"}
        folder = Path(extract(str(fmu), str(tmp_path / name)))
        linux = folder / "binaries" / "linux64"
        assert (linux / f"{name}_worker").is_file() and (linux / f"{name}_pythonfmu.so").is_file()
        bundled = {p.name for p in folder.rglob("*") if p.is_file()}
        for binary in (p for p in folder.rglob("*") if p.is_file() and runtime._is_elf(p)):
            needed, _ = runtime._dynamic(binary)
            outside = [lib for lib in needed if lib not in bundled and lib not in runtime.SYSTEM_LIBRARIES]
            assert not outside, f"{binary.relative_to(folder)} needs {outside} from outside the FMU"
        assert not any(p.name.endswith((".py", ".h", ".c")) for p in (linux / "runtime").rglob("*"))


def test_the_coupled_deployment_equals_the_ordinary_fmus_bit_for_bit(rigid, built_fmus):
    scene = load_scene(SCENES / "deploy_rigid.toml")
    ordinary = run_scene(scene, backend="fmu", fmu_dir=built_fmus("deploy_rigid"))
    standalone = run_scene(scene, backend="fmu", fmu_dir=rigid)
    assert ordinary.status == standalone.status == "ok"
    assert standalone.latch_times == ordinary.latch_times
    assert ordinary.series.columns == standalone.series.columns
    assert np.array_equal(ordinary.series.table(), standalone.series.table())


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(p.stem for p in SCENES.glob("*.toml")))
def test_every_shipped_scene_builds_standalone_and_runs_as_the_ordinary_fmus(name, tmp_path):
    """Each shipped scene, cut to its first ten communication steps, through its standalone FMUs and through its
    ordinary ones: the same code in another process, so the same numbers bit for bit."""
    from orchestrator.build.fmus import build_fmus
    step = load_scene(SCENES / f"{name}.toml")["coupling"]["step"]
    scene = load_scene(SCENES / f"{name}.toml", [f"time.stop={10 * step!r}"])
    ordinary, standalone = tmp_path / "ordinary", tmp_path / "standalone"
    build_fmus(scene, ordinary)
    build_fmus(scene, standalone, standalone=True)
    first = run_scene(scene, backend="fmu", fmu_dir=ordinary)
    second = run_scene(scene, backend="fmu", fmu_dir=standalone)
    assert first.status == second.status == "ok", (first.status, second.status)
    assert len(first.series.table()) >= 10
    assert first.series.columns == second.series.columns
    assert np.array_equal(first.series.table(), second.series.table())


def test_the_host_keeps_its_blas_threads_and_signals(rigid, built_fmus, tmp_path):
    env = {k: v for k, v in os.environ.items() if not k.startswith(("OPENBLAS_", "OMP_", "MKL_"))}
    before, instantiated, stepped, after = host(extract(str(rigid / "structure.fmu"), str(tmp_path / "s")), "host",
                                                "instantiate", "step:5", "host", env=env)
    assert instantiated["status"] == 0 and stepped["status"] == 0
    assert after["blas"] == before["blas"] and after["masks"] == before["masks"]
    assert after["handlers"] == before["handlers"]
    # the ordinary FMU runs in the host's interpreter and limits its BLAS to one thread: a change the check sees
    before, _, after = host(extract(str(built_fmus("deploy_rigid") / "structure.fmu"), str(tmp_path / "o")), "host",
                            "instantiate", "host", env=env)
    assert max(n for _, n in before["blas"]) > 1, "the host's BLAS must have several threads to begin with"
    assert after["blas"] != before["blas"]


@pytest.mark.parametrize("signum", [signal.SIGKILL, signal.SIGSEGV])
def test_a_killed_worker_gives_fmi2Fatal_with_the_reason_and_the_host_lives(rigid, tmp_path, signum):
    folder = extract(str(rigid / "structure.fmu"), str(tmp_path / "s"))
    _, stepped, _, died, refused, _ = host(folder, "instantiate", "step:3", f"kill:{int(signum)}", "step:1", "step:1",
                                           "free")
    assert stepped["status"] == 0
    assert died["status"] == refused["status"] == FATAL
    assert any(f"killed by signal {int(signum)}" in text for _, _, text in died["log"]), died["log"]
    assert not workers_of(folder)


def test_a_kernel_that_crashes_kills_the_worker_not_the_host(rigid, tmp_path):
    folder = Path(extract(str(rigid / "aero.fmu"), str(tmp_path / "a")))
    # the kernel of deploy_rigid's uvlm-flat step
    for library in (folder / "resources" / "aero_fmu").glob("flat_wake_step-*.so"):
        offset, size = _text_section(library)
        data = bytearray(library.read_bytes())
        data[offset:offset + size] = b"\x0f\x0b" * (size // 2) + b"\x0f" * (size % 2)   # ud2: an illegal instruction
        library.write_bytes(bytes(data))
        # a kernel that crashes, not a damaged file: its digest record says these are the bytes compiled
        record_file(library).write_text(hashlib.sha256(bytes(data)).hexdigest() + "\n")
    out = host(folder, "instantiate", "step:1", "free")        # the host lives on: it exits 0 (`host`)
    # the uvlm-flat unit loads its kernel's library while it is instantiated (its constructors run code of the
    # library's .text): the worker dies there, fmi2Instantiate returns no instance (the host's status 3) with the
    # fatal message, and the step is refused as well
    crashed = [entry for entry in out if any("killed by signal 4" in text for _, _, text in entry["log"])]
    assert crashed and crashed[0]["action"] == "instantiate" and crashed[0]["status"] == 3, out
    assert [entry["action"] for entry in out] == ["instantiate", "step:1", "free"] and out[1]["status"] >= 3, out
    assert not workers_of(folder)


def test_no_worker_outlives_free_exit_or_a_killed_host(rigid, tmp_path):
    for ending in ("free", "exit"):
        folder = extract(str(rigid / "structure.fmu"), str(tmp_path / ending))
        out = host(folder, "instantiate", "workers", ending)
        assert len(out[1]["pids"]) == 1
        if ending == "free":
            assert out[2]["log"] == [], "fmi2FreeInstance must end the worker cleanly, without a message"
        assert _gone(folder), f"a worker is left after the host's {ending}"
    folder = extract(str(rigid / "structure.fmu"), str(tmp_path / "killed"))
    proc = subprocess.Popen([sys.executable, str(HOST), folder, "instantiate", "step:2", "wait"],
                            stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    try:
        lines = [json.loads(proc.stdout.readline()) for _ in range(3)]
        assert lines[-1]["action"] == "wait" and len(workers_of(folder)) == 1
        proc.send_signal(signal.SIGKILL)
        proc.wait(timeout=60)
    finally:
        proc.kill()
    assert _gone(folder), "a worker is left after its host was killed with SIGKILL"


def test_a_scene_s_units_share_one_worker_and_two_instances_of_one_fmu_do_not(rigid, tmp_path):
    """The structure and aero FMUs of one build run in one worker of this process (one interpreter, as they
    would in one Python); a second instance of the structure FMU gets a worker of its own, so that a host can
    step the two in parallel; every worker ends with the last instance it serves, reaped (no zombie)."""
    folders = {name: extract(str(rigid / f"{name}.fmu"), str(tmp_path / name)) for name in ("structure", "aero")}
    units = {name: _fmu2slave(folder, name) for name, folder in folders.items()}
    second = _fmu2slave(folders["structure"], "second")

    def workers() -> set[int]:
        return {pid for folder in folders.values() for pid in workers_of(folder)} & set(_children())
    try:
        for unit in units.values():
            unit.instantiate()
        assert len(workers()) == 1
        second.instantiate()
        seen = workers()
        assert len(seen) == 2
    finally:
        for unit in (*units.values(), second):
            unit.freeInstance()
    assert not any(Path(f"/proc/{pid}").exists() for pid in seen), "a worker is left, or not reaped (a zombie)"


def _fmu2slave(folder, name):
    from fmpy import read_model_description
    from fmpy.fmi2 import FMU2Slave
    md = read_model_description(folder)
    return FMU2Slave(guid=md.guid, unzipDirectory=folder, modelIdentifier=md.coSimulation.modelIdentifier,
                     instanceName=name)


def _children() -> list[int]:
    """This process's child processes, zombies included (state Z: ended and not reaped)."""
    pids = []
    for task in Path(f"/proc/{os.getpid()}/task").iterdir():
        pids += [int(p) for p in (task / "children").read_text().split()]
    return pids


def _gone(folder, patience=30.0) -> bool:
    """Whether the workers of `folder` are all gone, waiting up to `patience` s for the kernel to end them."""
    return all_gone(lambda: workers_of(folder), patience)


def _text_section(library: Path) -> tuple[int, int]:
    """(file offset, size) of the .text section of an ELF64 file."""
    data = library.read_bytes()
    shoff, = struct.unpack_from("<Q", data, 0x28)
    shentsize, shnum, shstrndx = struct.unpack_from("<HHH", data, 0x3A)
    sections = [struct.unpack_from("<IIQQQQIIQQ", data, shoff + k * shentsize) for k in range(shnum)]
    names = sections[shstrndx][4]
    for name, _, _, _, offset, size, *_ in sections:
        if data[names + name:data.index(b"\0", names + name)] == b".text":
            return offset, size
    raise AssertionError(f"{library} has no .text section")
