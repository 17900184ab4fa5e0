"""The standalone FMUs on a machine without Python (slow: a Debian root file system is made, four FMUs built).

The machine: a Debian 12 minimal root file system made with `debootstrap --variant=minbase` from the Debian
registry (with ICU 72 and libstdc++, which OMSimulator needs), /proc mounted, entered with `chroot` and started
with an empty environment (`env -i`): no Python, no numpy, nothing of the build machine's but what is copied in.
There, on the standalone FMUs of deploy_rigid and deploy_flexible:
- the FMI Compliance Checker passes every FMU, and writes what it writes on the build machine, bit for bit;
- our C host couples structure and aero for 300 steps: equal to `wingsim run` (the ordinary FMUs in this
  process), bit for bit;
- OMSimulator runs each FMU alone: the structure (Q held at 0) equals `wingsim run --set aero.model=none` (the
  still-air run of the same structure) at every communication point, and the aero unit (the wing held at its
  initial coordinates) equals the ordinary aero FMU driven the same way through fmpy in this process, both
  within 1e-12 of each quantity's largest magnitude: OMSimulator forms its communication points as a running
  sum t + h, the references as k h, so the units integrate steps that differ in the last bits.
Running these needs root (chroot, mount) and debootstrap (.ci/run installs it).
"""
import os
import shutil
import subprocess
import zipfile
from pathlib import Path

import numpy as np
import pytest
import scipy.io

from fmi_hosts import FmpyHost, UnitSpec, assert_clean, check, coupled_units, run_c_host
from orchestrator.run.master import run_scene
from orchestrator.scene.load import load_scene
from repository import OMSIMULATOR, SCENES

pytestmark = pytest.mark.slow

SCENES_RUN = ("deploy_rigid", "deploy_flexible")
STEPS = 300


@pytest.fixture(scope="module")
def debian(tmp_path_factory):
    """The root folder of a Debian 12 minbase system with /proc mounted (unmounted at the end)."""
    if os.geteuid() != 0:
        pytest.fail("this test makes a root file system and enters it with chroot: run it as root")
    if shutil.which("debootstrap") is None:
        pytest.fail("debootstrap is not installed (Debian: apt-get install debootstrap)")
    root = tmp_path_factory.mktemp("debian12") / "root"
    made = subprocess.run(["debootstrap", "--variant=minbase", "--include=libicu72,libstdc++6", "bookworm", str(root),
                           "http://deb.debian.org/debian"], capture_output=True, text=True, timeout=1800)
    assert made.returncode == 0, made.stdout[-3000:] + made.stderr[-3000:]
    pythons = [*root.glob("usr/*bin/python*"), *root.glob("usr/local/bin/python*"), *root.rglob("libpython*"),
               *root.glob("usr/lib/python3*"), *root.glob("usr/local/lib/python3*")]
    assert not pythons, f"the minimal system has a Python interpreter or library: {pythons[:5]}"
    subprocess.run(["mount", "-t", "proc", "proc", str(root / "proc")], check=True)
    try:
        yield root
    finally:
        subprocess.run(["umount", str(root / "proc")], check=False)


@pytest.fixture(scope="module")
def machine(debian, standalone_fmus, c_host, fmu_checker):
    """{"root": the system's root, scene: {kind: unpacked FMU folder in it}}, with the checker, the C host and
    OMSimulator copied to /work."""
    work = debian / "work"
    work.mkdir()
    shutil.copy(fmu_checker, work / "fmuCheck")
    shutil.copy(c_host, work / "fmi2_host")
    shutil.copytree(OMSIMULATOR, work / "omsimulator")
    out = {"root": debian}
    for name in SCENES_RUN:
        folder = standalone_fmus(name)
        out[name] = {}
        for kind in ("structure", "aero"):
            shutil.copy(folder / f"{kind}.fmu", work / f"{name}_{kind}.fmu")
            # modes as a zip tool leaves them: the FMU restores its own
            out[name][kind] = _unzipped(folder / f"{kind}.fmu", work / name / kind)
    return out


def inside(root: Path, *command, timeout=900) -> subprocess.CompletedProcess:
    """`command` (paths inside the system) run in it with an empty environment."""
    return subprocess.run(["chroot", str(root), "/usr/bin/env", "-i", *map(str, command)], capture_output=True,
                          text=True, timeout=timeout)


def in_root(root: Path, path: Path) -> str:
    return "/" + str(path.relative_to(root))


@pytest.mark.parametrize("name", SCENES_RUN)
def test_the_compliance_checker_passes_and_writes_what_it_writes_on_the_build_machine(machine, fmu_checker, name,
                                                                                      tmp_path):
    root = machine["root"]
    scene = load_scene(SCENES / f"{name}.toml")
    h = scene["coupling"]["step"]
    for kind in ("structure", "aero"):
        fmu = root / "work" / f"{name}_{kind}.fmu"
        there = inside(root, "/work/fmuCheck", "-k", "cs", "-h", repr(h), "-s", repr(STEPS * h), "-l", "3", "-o",
                       f"/work/{name}_{kind}.csv", in_root(root, fmu))
        assert_clean(there)
        here = check(fmu_checker, fmu, tmp_path / f"{kind}.csv", h, STEPS * h)
        assert_clean(here)
        assert (root / "work" / f"{name}_{kind}.csv").read_bytes() == (tmp_path / f"{kind}.csv").read_bytes()


@pytest.mark.parametrize("name", SCENES_RUN)
def test_the_c_host_couples_the_units_as_wingsim_run_does(machine, built_fmus, name, tmp_path):
    root = machine["root"]
    scene = load_scene(SCENES / f"{name}.toml", [f"time.stop={STEPS * 1e-3!r}"])
    h = scene["coupling"]["step"]
    assert h == 1e-3
    units = coupled_units(machine[name])
    host_folder = root / "work" / f"{name}_c_host"
    rows = run_c_host(Path("/work/fmi2_host"), [_relocated(u, root) for u in units], STEPS, h, STEPS * h, ["run"],
                      host_folder, root=root)["run"]
    result = run_scene(scene, "fmu", built_fmus(name))
    assert result.status == "ok", result.message
    np.testing.assert_array_equal(result.series.column("time"), rows[:, 0])
    names = [f"{u.name}.{n}" for u in units for _, n in u.outputs]
    compared = 0
    for column in result.series.columns:
        for unit in ("structure", "aero"):
            if f"{unit}.{column}" in names:
                index = 1 + names.index(f"{unit}.{column}")
                np.testing.assert_array_equal(result.series.column(column), rows[:, index], err_msg=f"{unit}.{column}")
                compared += 1
    assert compared >= 5


@pytest.mark.parametrize("name", SCENES_RUN)
def test_omsimulator_runs_each_unit_alone(machine, built_fmus, name):
    root = machine["root"]
    scene = load_scene(SCENES / f"{name}.toml")
    h, stop = scene["coupling"]["step"], scene["time"]["stop"]
    results = {}
    for kind in ("structure", "aero"):
        out = inside(root, "/work/omsimulator/bin/OMSimulator", "--mode=cs", f"--resultFile=/work/{name}_{kind}.mat",
                     f"/work/{name}_{kind}.fmu")
        assert out.returncode == 0 and "error:" not in out.stdout + out.stderr, out.stdout + out.stderr
        results[kind] = _read_mat(root / "work" / f"{name}_{kind}.mat")
    times = np.arange(round(stop / h) + 1) * h

    # the structure with Q = 0 is the still-air run of the same structure
    still = run_scene(load_scene(SCENES / f"{name}.toml", ["aero.model=none"]), "fmu",
                      built_fmus(name, "aero.model=none"))
    assert still.status == "ok", still.message
    structure = results["structure"]
    np.testing.assert_allclose(structure["time"], times, rtol=0, atol=1e-12)
    compared = [column for column in ("fold_angle_fold", "tip_z", "energy") if column in structure]
    assert compared, f"none of the structure's outputs compared is in OMSimulator's result: {sorted(structure)}"
    for column in compared:
        assert_close(structure[column], still.series.column(column), column)

    # the aero unit on the wing held at its initial coordinates, through fmpy here (the ordinary aero FMU)
    aero = UnitSpec.read("aero", _unzipped(built_fmus(name) / "aero.fmu", root.parent / f"{name}_aero_ordinary"))
    reference = FmpyHost([aero], len(times) - 1, h, stop)
    rows = np.array(reference.start() + reference.steps(0, len(times) - 1))
    reference.finish()
    for index, (_, output) in enumerate(aero.outputs, start=1):
        if output in ("CL", "lift") or output.startswith("Q["):
            assert_close(results["aero"][output], rows[:, index], output)


def assert_close(actual, desired, name) -> None:
    """Equal within 1e-12 of the largest magnitude of `desired` (module docstring)."""
    np.testing.assert_allclose(actual, desired, rtol=0, atol=1e-12 * np.max(np.abs(desired)), err_msg=name)


def _relocated(unit: UnitSpec, root: Path) -> UnitSpec:
    """`unit` as the system sees it: its folder under the system's root."""
    return UnitSpec(unit.name, Path(in_root(root, unit.folder)), unit.identifier, unit.guid, unit.outputs,
                    unit.connected, unit.fixed)


def _unzipped(fmu: Path, folder: Path) -> Path:
    with zipfile.ZipFile(fmu) as z:
        z.extractall(folder)
    return folder


def _read_mat(path: Path) -> dict[str, np.ndarray]:
    """{variable: values at the communication points} of an OMSimulator result file (MATLAB v4, the
    OpenModelica layout: names as a character matrix, dataInfo mapping each to a row of data_1 or data_2);
    a point OMSimulator recorded twice keeps its last value."""
    m = scipy.io.loadmat(path, chars_as_strings=False)
    names = ["".join(m["name"][:, i]).rstrip("\x00 ") for i in range(m["name"].shape[1])]
    data2 = m["data_2"]
    time = data2[0]
    last = np.r_[np.diff(time) != 0, True]
    out = {"time": time[last]}        # the abscissa (dataInfo 0)
    for k, name in enumerate(names):
        which, row = m["dataInfo"][0, k], m["dataInfo"][1, k]
        if which == 2:
            out[name] = (np.sign(row) * data2[abs(row) - 1])[last]
    return out
