"""OpenModelica's OMSimulator (a C++ FMI/SSP host, ``../shared/tools/omsimulator/``) runs what `wingsim export`
writes, as exported: from its command line under an empty environment (as a system tool starts it) and through
its Python API, and the aero unit of another fidelity swaps into the package with one command.

The reference is libcosim on the same package (tests/fmi/ssp_run.py): both step every unit from the outputs of
the last communication point, then exchange (Jacobi), from the same start (each exchanges the initial outputs
during initialization), so the same FMUs doing the same arithmetic end with the same outputs, but for the
communication points, which each tool forms its own way (a few machine epsilons of t apart) and which a unit
that iterates (Newton, to a tolerance) may answer with differences at that tolerance. OMSimulator's result
file holds 12 significant digits; RTOL is far above both and far below any change of the physics. An output is
compared on the scale of its element's outputs in the same unit: a moment about an axis of symmetry or an
acceleration at rest is round-off of that scale.
Neither tool finds an algebraic loop: no output of either unit depends directly on an input (their model
descriptions declare ``dependencies=""``), which OMSimulator's log shows.
"""
from __future__ import annotations

import csv
import os
import re
import subprocess
import sys
import zipfile
from pathlib import Path

import fmpy
import pytest

from orchestrator.run.master import run_scene
from orchestrator.scene.load import load_scene
from repository import OMSIMULATOR, SCENES
from subprocesses import wingsim

SSP_RUN = Path(__file__).with_name("ssp_run.py")
API_RUN = Path(__file__).with_name("omsimulator_run.py")
RTOL = 1e-9
SSD = "http://ssp-standard.org/SSP1/SystemStructureDescription"
SSC = "http://ssp-standard.org/SSP1/SystemStructureCommon"
ALGEBRAIC_LOOP = re.compile(r"Alg\. loop", re.I)
AERO_SCENES = sorted(p.stem for p in SCENES.glob("*.toml") if load_scene(p)["aero"]["model"] != "none")


@pytest.fixture(scope="session")
def omsimulator() -> Path:
    """OMSimulator's executable; the test is skipped where it is not installed."""
    binary = OMSIMULATOR / "bin" / "OMSimulator"
    if not binary.is_file():
        pytest.skip(f"OMSimulator is not installed at {binary}")
    return binary


def export(folder: Path, scene: str, *args: str) -> Path:
    """`wingsim export` of scenes/<scene>.toml in `folder` (its default output folders); the package's path."""
    out = wingsim("export", SCENES / f"{scene}.toml", *args, cwd=folder)
    assert out.returncode == 0, out.stdout + out.stderr
    return folder / next(line for line in out.stdout.split() if line.endswith(".ssp"))


def by_element(columns: dict[str, float], elements=("structure_unit", "aero_unit")) -> dict[str, float]:
    """{"<element>.<variable>": value} from result columns named "<model>[.<system>].<element>.<variable>"."""
    named = {}
    for column, value in columns.items():
        for element in elements:
            head, found, variable = column.partition(f".{element}.")
            if found:
                named[f"{element}.{variable}"] = value
    return named


def last_row(result: Path) -> dict[str, float]:
    """The last row of an OMSimulator CSV result file, by element and variable (non-numeric columns left out)."""
    with result.open(newline="") as handle:
        rows = list(csv.DictReader(handle, skipinitialspace=True))
    assert rows, f"{result} holds no rows"
    values = {}
    for name, text in rows[-1].items():
        try:
            values[name.strip()] = float(text)
        except ValueError:
            pass
    return {"time": values.pop("time"), **by_element(values)}


def run_cli(omsimulator: Path, ssp: Path, stop: float, folder: Path) -> tuple[str, dict[str, float]]:
    """OMSimulator's command line on `ssp` to `stop` (s) with an empty environment; (its log, the last row)."""
    out, result = oms_cli(omsimulator, ssp, stop, folder)
    log = out.stdout + out.stderr
    assert out.returncode == 0 and not re.search(r"^error:", log, re.M), log
    return log, last_row(result)


def oms_cli(omsimulator: Path, ssp: Path, stop: float, folder: Path) -> tuple[subprocess.CompletedProcess, Path]:
    """OMSimulator's command line on `ssp` to `stop` (s) with an empty environment: (the process, its result file)."""
    result = folder / f"{ssp.stem}_oms.csv"
    out = subprocess.run(["env", "-i", str(omsimulator), f"--stopTime={stop!r}", f"--resultFile={result}", str(ssp)],
                         cwd=folder, capture_output=True, text=True, timeout=1800)
    return out, result


def run_libcosim(ssp: Path, *parameters: str) -> dict[str, float]:
    """libcosim on `ssp` to its stop time: every Real output at the end, by element, and `parameters`."""
    out = subprocess.run([sys.executable, str(SSP_RUN), "libcosim", str(ssp), *parameters], capture_output=True,
                         text=True, timeout=1800)
    assert out.returncode == 0, out.stdout + out.stderr
    return {k: float(v) for k, v in re.findall(r"^(\S+)=(\S+)$", out.stdout, re.M)}


def output_units(ssp: Path) -> dict[str, str]:
    """{"<element>.<output>": unit} of every output connector of the package's SSD."""
    from lxml import etree

    with zipfile.ZipFile(ssp) as z:
        root = etree.fromstring(z.read("SystemStructure.ssd"))
    units = {}
    for component in root.iterfind(f".//{{{SSD}}}Component"):
        for connector in component.iterfind(f"{{{SSD}}}Connectors/{{{SSD}}}Connector[@kind='output']"):
            real = connector.find(f"{{{SSC}}}Real")
            units[f"{component.get('name')}.{connector.get('name')}"] = real.get("unit") or ""
    return units


def assert_same_outputs(oms: dict[str, float], cosim: dict[str, float], ssp: Path,
                        rtol: dict[str, float] | None = None) -> None:
    """Every output libcosim reports is in OMSimulator's result and equal to RTOL (or `rtol` of its FMI unit, None
    to leave the unit out) of its scale: the largest magnitude among the outputs of its element in the same unit
    (a moment about an axis of symmetry, an acceleration at rest are round-off, with no scale of their own)."""
    units = output_units(ssp)
    rtol = dict.fromkeys(set(units.values()), RTOL) | (rtol or {})
    outputs = {k: v for k, v in cosim.items() if k in units and rtol[units[k]] is not None}
    assert len(outputs) > 10 and set(outputs) <= set(oms), sorted(set(outputs) - set(oms))[:5]
    scale: dict[tuple, float] = {}
    for name, value in outputs.items():
        group = (name.split(".")[0], units[name])
        scale[group] = max(scale.get(group, 0.0), abs(value))
    ratio = {name: abs(oms[name] - value) / (scale[name.split(".")[0], units[name]] or 1.0)
             for name, value in outputs.items()}
    off = [(name, oms[name], outputs[name], ratio[name]) for name in outputs if ratio[name] > rtol[units[name]]]
    assert not off, off[:5]
    worst = max(ratio, key=ratio.get)
    print(f"\n{len(outputs)} outputs; largest |OMSimulator - libcosim| / scale {ratio[worst]:.1e} ({worst})")


def stop_time(ssp: Path) -> float:
    from lxml import etree

    with zipfile.ZipFile(ssp) as z:
        root = etree.fromstring(z.read("SystemStructure.ssd"))
    return float(root.find(f"{{{SSD}}}DefaultExperiment").get("stopTime"))


@pytest.fixture(scope="module")
def deploy_rigid(tmp_path_factory) -> Path:
    return export(tmp_path_factory.mktemp("oms_deploy_rigid"), "deploy_rigid")


@pytest.fixture(scope="module")
def libcosim_deploy_rigid(deploy_rigid) -> dict[str, float]:
    return run_libcosim(deploy_rigid, "structure.joints.fold.torque", "flow.speed")


def test_the_command_line_runs_the_package_as_libcosim_does_with_no_algebraic_loop(omsimulator, deploy_rigid,
                                                                                   libcosim_deploy_rigid, tmp_path):
    log, oms = run_cli(omsimulator, deploy_rigid, stop_time(deploy_rigid), tmp_path)
    assert not ALGEBRAIC_LOOP.search(log), log
    assert oms["time"] == pytest.approx(0.3, abs=1e-12)
    assert_same_outputs(oms, libcosim_deploy_rigid, deploy_rigid)
    assert 0.15 < oms["structure_unit.latch_time_fold"] < 0.25   # it deployed within the run


def test_the_python_api_runs_the_package_as_libcosim_does(omsimulator, deploy_rigid, libcosim_deploy_rigid,
                                                          tmp_path):
    result = tmp_path / "api.csv"
    env = {**os.environ, "PYTHONPATH": str(OMSIMULATOR / "lib")}
    out = subprocess.run([sys.executable, str(API_RUN), str(deploy_rigid), repr(stop_time(deploy_rigid)),
                          str(result), "structure.joints.fold.torque", "flow.speed"],
                         cwd=tmp_path, env=env, capture_output=True, text=True, timeout=1800)
    log = out.stdout + out.stderr
    assert out.returncode == 0 and not re.search(r"^error:", log, re.M), log
    assert not ALGEBRAIC_LOOP.search(log), log
    # the parameter bindings reached the units under their dotted names, beside elements of other names
    bound = {k: float(v) for k, v in re.findall(r"^(\S+)=(\S+)$", out.stdout, re.M)}
    assert bound == {"structure_unit.structure.joints.fold.torque": 0.043, "aero_unit.flow.speed": 10.0}
    assert_same_outputs(last_row(result), libcosim_deploy_rigid, deploy_rigid)


def test_the_strip_aero_unit_swaps_into_the_package_without_rebuilding_the_structure(omsimulator, deploy_rigid,
                                                                                      tmp_path):
    folder = deploy_rigid.parents[2]           # where deploy_rigid was exported: fmus/ and export/ inside
    structure = folder / "fmus" / "deploy_rigid" / "structure.fmu"
    before = structure.stat().st_mtime_ns, structure.read_bytes()
    built = wingsim("build", SCENES / "deploy_rigid.toml", "--set", "aero.model=strip", "--unit", "aero", cwd=folder)
    assert built.returncode == 0, built.stdout + built.stderr
    (aero,) = [folder / line for line in built.stdout.split()]
    assert aero.name == "aero.fmu" and not (aero.parent / "structure.fmu").exists()   # only the unit asked for
    swapped = export(folder, "deploy_rigid", "--aero", str(aero))
    assert swapped.parent != deploy_rigid.parent and deploy_rigid.is_file()   # its own folder: nothing overwritten
    assert (structure.stat().st_mtime_ns, structure.read_bytes()) == before
    with zipfile.ZipFile(swapped) as z:
        assert z.read("resources/structure_unit.fmu") == before[1]
        assert z.read("resources/aero_unit.fmu") == aero.read_bytes()
        ssd = z.read("SystemStructure.ssd").decode()
    assert "strip" in ssd and "uvlm-flat" not in ssd   # the package says which aero model it couples

    log, oms = run_cli(omsimulator, swapped, stop_time(swapped), tmp_path)
    assert not ALGEBRAIC_LOOP.search(log), log
    # the reference: wingsim's master, Jacobi coupled as OMSimulator, with the strip model set in the scene
    reference = run_scene(load_scene(SCENES / "deploy_rigid.toml", ["aero.model=strip", "coupling.algorithm=jacobi"]),
                          backend="direct")
    assert reference.status == "ok", reference.message
    assert oms["structure_unit.latch_time_fold"] == pytest.approx(reference.latch_times["fold"], rel=RTOL)
    uvlm = run_cli(omsimulator, deploy_rigid, stop_time(deploy_rigid), tmp_path)[1]
    assert abs(oms["structure_unit.latch_time_fold"] - uvlm["structure_unit.latch_time_fold"]) > 1e-3   # swapped
    # the same command wrote wing.fmu of the swapped units, which couples as Jacobi too (docs/fmu.md)
    container = fmpy.simulate_fmu(str(swapped.with_name("wing.fmu")), stop_time=stop_time(swapped))
    assert container["latch_time_fold"][-1] == pytest.approx(reference.latch_times["fold"], rel=RTOL)
    assert "(strip)" in fmpy.read_model_description(str(swapped.with_name("wing.fmu"))).modelName


GAUSS_SEIDEL_ONLY = ("scissor_wing_flexible",)
"""Scenes stable only in wingsim's Gauss-Seidel order (the scene's header): an exported package couples as Jacobi
(docs/fmu.md), where they diverge as `wingsim run --set coupling.algorithm=jacobi` does (the test below)."""


SETTLED_RTOL = 1e-6
SETTLED = ("hale_wing",)
"""Scenes that end settled near rest, where their outputs are the remainder of the structure's Newton iteration
(stopped at relative tolerances of 1e-9 on q and VELOCITY_TOLERANCE = 1e-8 on q', structure_fmu.integrators): the
two hosts form their communication points a few ulps apart (OMSimulator adds the step sizes, libcosim counts
nanoseconds), which moves where an iteration stops. For the light, long HALE wing this gives up to 4e-7 of the lift
between the hosts, and the tip accelerations of its stiff axial direction (EA 1e8 N) move by 1e-3 of their size
when wingsim's own step moves by one ulp. These scenes are held to SETTLED_RTOL on positions, forces, moments,
energies and coefficients, a thousand times finer than the 1 mm to which the scene's header says its wing has
settled; their velocities (of the points, m/s, and of the gradients, 1/s) and accelerations at rest are not
compared."""


@pytest.mark.slow
@pytest.mark.parametrize("scene", [s for s in AERO_SCENES if s != "deploy_rigid" and s not in GAUSS_SEIDEL_ONLY])
def test_every_aero_scene_runs_in_omsimulator_as_in_libcosim(omsimulator, scene, tmp_path):
    ssp = export(tmp_path, scene)
    log, oms = run_cli(omsimulator, ssp, stop_time(ssp), tmp_path)
    assert not ALGEBRAIC_LOOP.search(log), log
    settled = {"m/s": None, "1/s": None, "m/s2": None} | dict.fromkeys(("m", "N", "N.m", "J", "1"), SETTLED_RTOL)
    assert_same_outputs(oms, run_libcosim(ssp), ssp, settled if scene in SETTLED else None)


@pytest.mark.slow
@pytest.mark.parametrize("scene", GAUSS_SEIDEL_ONLY)
def test_a_scene_stable_only_in_gauss_seidel_order_diverges_in_omsimulator_as_wingsim_under_jacobi(
        omsimulator, scene, tmp_path):
    # OMSimulator's master exchanges as Jacobi: its structure unit fails at the same time, with the same Newton
    # numbers, as wingsim's own Jacobi run of the scene
    reference = run_scene(load_scene(SCENES / f"{scene}.toml", ["coupling.algorithm=jacobi"]), backend="direct")
    assert reference.status == "diverged", reference.message
    divergence = re.search(r"(solver diverged at t = \S+ s: Newton iteration diverged \([^)]*\))", reference.message)
    assert divergence, reference.message
    ssp = export(tmp_path, scene)
    out, _ = oms_cli(omsimulator, ssp, stop_time(ssp), tmp_path)
    assert divergence.group(1) in out.stdout + out.stderr, out.stdout + out.stderr


def test_a_structure_only_package_runs_as_wingsim_runs_it(omsimulator, tmp_path):
    ssp = export(tmp_path, "deploy_rigid", "--set", "aero.model=none")
    log, oms = run_cli(omsimulator, ssp, stop_time(ssp), tmp_path)
    reference = run_scene(load_scene(SCENES / "deploy_rigid.toml", ["aero.model=none"]), backend="direct")
    assert reference.status == "ok", reference.message
    assert oms["structure_unit.latch_time_fold"] == pytest.approx(reference.latch_times["fold"], rel=RTOL)


def test_an_aero_unit_of_another_geometry_put_into_the_package_by_hand_refuses_the_first_step(
        omsimulator, deploy_rigid, tmp_path):
    # a tool that compares no topology_hash (OMSimulator does not) still cannot pair the wrong units: the aero
    # unit of a wing with a longer outer body, put in the package in place of the scene's own, refuses the
    # structure's coordinates at its first step, naming its own node and the one it received
    built = wingsim("build", SCENES / "deploy_rigid.toml", "--set", "structure.bodies.outer.length=0.2", "--unit",
                    "aero", cwd=tmp_path)
    assert built.returncode == 0, built.stderr
    mismatched = tmp_path / "mismatched.ssp"
    with zipfile.ZipFile(deploy_rigid) as source, zipfile.ZipFile(mismatched, "w") as target:
        for info in source.infolist():
            data = source.read(info)
            if info.filename == "resources/aero_unit.fmu":
                data = (tmp_path / built.stdout.split()[0]).read_bytes()
            target.writestr(info, data)
    out = subprocess.run(["env", "-i", str(omsimulator), "--stopTime=0.3", f"--resultFile={tmp_path / 'm.csv'}",
                          str(mismatched)], cwd=tmp_path, capture_output=True, text=True, timeout=600)
    log = out.stdout + out.stderr
    refusal = next((line for line in log.splitlines() if line.startswith("error:") and "aero unit" in line), "")
    assert "do not fit this aero unit's lattice" in refusal and "node outer.1" in refusal, log
    assert "scene 'deploy_rigid'" in refusal and "0.35 m" in refusal, refusal   # its own wing: 0.15 + 0.2 m
    assert "fmi2_doStep failed" in log   # it stopped there: no step was taken on the wrong wing
