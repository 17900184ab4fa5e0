"""Standalone FMUs in hosts that an ordinary FMU cannot serve (slow: a virtual environment is installed from the
package registry, a second copy of the sources is built, libcosim steps in threads).

- A Python host whose environment has numpy 1.26 and no scipy (fmpy in a fresh virtual environment) runs the
  standalone structure FMU, to the same numbers as this process; the ordinary FMU there fails at
  instantiation with one message naming every package it lacks and the interpreter.
- Two standalone FMUs built from different wingsim sources (a copy whose topology hash differs) run side by
  side in one host process, each with its own code: each reports the hash its own sources compute, in a
  worker of its own.
- Two instances of one standalone FMU step in parallel when libcosim steps them in parallel: the timelines
  their workers write (WINGSIM_WORKER_TRACE) overlap. libcosim sizes its thread pool by the CPUs it sees, less
  one, so on a two-CPU machine it steps one slave after the other; the test shows it four CPUs (the kernel's
  list of online CPUs bound over in a private mount namespace, which needs root).
- wing.fmu of standalone units (`wingsim export --standalone`) passes the FMI Compliance Checker with its
  default options in an empty environment, deploying as wing.fmu of the ordinary units does.
"""
import json
import os
import re
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest
from fmpy import extract

from fmi_hosts import assert_clean
from repository import SCENES
from subprocesses import CODE_ROOT

pytestmark = pytest.mark.slow

HOST = Path(__file__).resolve().parent / "fmpy_host.py"
PARALLEL = Path(__file__).resolve().parent / "libcosim_parallel.py"
STILL_AIR = ("deploy_rigid", "aero.model=none")
STRUCTURE_ONLY = "double_pendulum"     # a scene whose file has no aero unit


def test_a_host_with_numpy_1_26_and_no_scipy(standalone_fmus, built_fmus, tmp_path):
    venv = tmp_path / "host"
    subprocess.run([sys.executable, "-m", "venv", str(venv)], check=True, timeout=300)
    python = venv / "bin" / "python"
    install = subprocess.run([str(python), "-m", "pip", "install", "-q", "fmpy==0.3.22", "numpy==1.26.4"],
                             capture_output=True, text=True, timeout=1200)
    assert install.returncode == 0, install.stderr[-3000:]
    check = subprocess.run([str(python), "-c", "import numpy, importlib.util; print(numpy.__version__, "
                            "importlib.util.find_spec('scipy') is None)"], capture_output=True, text=True)
    assert check.stdout.split() == ["1.26.4", "True"], check.stdout + check.stderr
    actions = ("instantiate", "step:50", "read:tip_z", "read:fold_angle_fold", "free")

    def run(python_executable, fmu, folder):
        proc = subprocess.run([str(python_executable), str(HOST), extract(str(fmu), str(folder)), *actions],
                              capture_output=True, text=True, timeout=600)
        assert proc.returncode == 0, proc.stderr[-3000:]
        return [json.loads(line) for line in proc.stdout.splitlines()]

    there = run(python, standalone_fmus(*STILL_AIR) / "structure.fmu", tmp_path / "s_there")
    here = run(sys.executable, standalone_fmus(*STILL_AIR) / "structure.fmu", tmp_path / "s_here")
    assert [line["status"] for line in there] == [0, 0, 0, 0, None]
    assert [line.get("value") for line in there] == [line.get("value") for line in here]
    ordinary = run(python, built_fmus(*STILL_AIR) / "structure.fmu", tmp_path / "o_there")
    assert ordinary[0]["status"] >= 3
    messages = " ".join(text for _, _, text in ordinary[0]["log"])
    assert re.search(r"needs scipy, threadpoolctl, which the Python it runs in cannot import \(\S*host/bin/python",
                     messages), messages


def test_two_builds_from_different_sources_run_side_by_side(standalone_fmus, tmp_path):
    """The copy computes its topology hash with one more entry: its FMU must report that hash, and this
    checkout's FMU this checkout's, from one host process."""
    copy = tmp_path / "other"
    for package in ("fmu_common", "structure_fmu", "aero_fmu", "orchestrator"):
        shutil.copytree(CODE_ROOT / package, copy / package, ignore=shutil.ignore_patterns("__pycache__"))
    topology = copy / "fmu_common" / "topology.py"
    source = topology.read_text()
    assert '"hinges": self.hinge_names,' in source
    topology.write_text(source.replace('"hinges": self.hinge_names,', '"hinges": self.hinge_names, "other": 1,'))
    env = {**os.environ, "PYTHONPATH": str(copy)}
    scene = SCENES / f"{STRUCTURE_ONLY}.toml"
    built = subprocess.run([sys.executable, "-m", "orchestrator", "build", str(scene), "--standalone", "--out",
                            str(tmp_path / "other_fmus")], cwd=tmp_path, env=env, capture_output=True, text=True,
                           timeout=1800)
    assert built.returncode == 0, built.stderr[-3000:]
    expected = {}
    for name, path in (("this", CODE_ROOT), ("other", copy)):
        code = ("from orchestrator.scene.load import load_scene; from fmu_common.topology import Topology; "
                "from fmu_common.wing_spec import StructureSpec; "
                f"print(Topology.from_spec(StructureSpec.from_scene(load_scene({str(scene)!r}))).topology_hash)")
        out = subprocess.run([sys.executable, "-c", code], env={**os.environ, "PYTHONPATH": str(path)},
                             cwd=tmp_path, capture_output=True, text=True, timeout=300)
        assert out.returncode == 0, out.stderr
        expected[name] = out.stdout.strip()
    assert expected["this"] != expected["other"]
    folders = {"this": str(extract(str(standalone_fmus(STRUCTURE_ONLY) / "structure.fmu"), str(tmp_path / "this"))),
               "other": str(extract(str(tmp_path / "other_fmus" / "structure.fmu"), str(tmp_path / "other")))}
    code = f"""
import json, os
from pathlib import Path
from fmpy import read_model_description
from fmpy.fmi2 import FMU2Slave
hashes, units = {{}}, []
for name, folder in {folders!r}.items():
    md = read_model_description(folder)
    unit = FMU2Slave(guid=md.guid, unzipDirectory=folder, modelIdentifier=md.coSimulation.modelIdentifier,
                     instanceName=name)
    unit.instantiate()
    vr = next(v.valueReference for v in md.modelVariables if v.name == "topology_hash")
    hashes[name] = unit.getString([vr])[0].decode()
    units.append(unit)
workers = sum(len((t / "children").read_text().split()) for t in Path(f"/proc/{{os.getpid()}}/task").iterdir())
for unit in units:
    unit.freeInstance()
print(json.dumps({{"hashes": hashes, "workers": workers}}))
"""
    out = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stderr[-3000:]
    result = json.loads(out.stdout.splitlines()[-1])
    assert result["hashes"] == expected
    assert result["workers"] == 2


def test_two_instances_step_in_parallel_when_libcosim_steps_them_in_parallel(standalone_fmus, tmp_path):
    if os.geteuid() != 0:
        pytest.fail("showing libcosim four CPUs takes a private mount namespace: run this test as root")
    fmu = standalone_fmus("deploy_flexible", "aero.model=none") / "structure.fmu"
    online = tmp_path / "online"
    online.write_text("0-3\n")
    trace = tmp_path / "trace.txt"
    steps = 20
    command = (f"mount --bind {online} /sys/devices/system/cpu/online && "
               f"{sys.executable} {PARALLEL} {fmu} 0.001 {steps}")
    out = subprocess.run(["unshare", "-m", "sh", "-c", command], env={**os.environ, "WINGSIM_WORKER_TRACE": str(trace)},
                         cwd=tmp_path, capture_output=True, text=True, timeout=900)
    assert out.returncode == 0 and f"steps={steps}" in out.stdout, out.stdout + out.stderr
    steps_of: dict[str, list[tuple[int, int]]] = {}
    for line in trace.read_text().splitlines():
        pid, op, began, ended = line.split()
        if int(op) == 25:                                  # OP_DO_STEP (orchestrator/build/worker_channel.h)
            steps_of.setdefault(pid, []).append((int(began), int(ended)))
    assert len(steps_of) == 2 and all(len(v) == steps for v in steps_of.values()), steps_of.keys()
    first, second = steps_of.values()
    overlapping = sum(1 for a in first for b in second if a[0] < b[1] and b[0] < a[1])
    assert overlapping >= steps // 2, f"only {overlapping} of {steps} steps ran at the same time"


def test_the_container_of_standalone_units_passes_the_checker(fmu_checker, tmp_path):
    out = {}
    for kind, flags in (("ordinary", []), ("standalone", ["--standalone"])):
        proc = subprocess.run([sys.executable, "-m", "orchestrator", "export", str(SCENES / "deploy_rigid.toml"),
                               "--out", str(tmp_path / kind), *flags], cwd=tmp_path,
                              env={**os.environ, "PYTHONPATH": str(CODE_ROOT)}, capture_output=True, text=True,
                              timeout=1800)
        assert proc.returncode == 0, proc.stderr[-3000:]
        container = tmp_path / kind / "wing.fmu"
        with zipfile.ZipFile(container) as z:
            held = {name for name in z.namelist() if name.startswith("resources/structure/binaries/linux64/")}
        assert any(name.endswith("_worker") for name in held) == (kind == "standalone")
        checked = subprocess.run([str(fmu_checker), "-l", "3", "-o", str(tmp_path / f"{kind}.csv"), str(container)],
                                 env={}, capture_output=True, text=True, timeout=900)
        assert_clean(checked)
        out[kind] = (tmp_path / f"{kind}.csv").read_text()
    assert out["standalone"] == out["ordinary"]
