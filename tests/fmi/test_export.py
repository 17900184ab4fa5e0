"""`wingsim export`: the coupled system of deploy_rigid as an SSP 1.0 package and as one FMU (wing.fmu), run in
other tools against wingsim's own master.

The reference for the deployment time is ``run_scene`` with ``coupling.algorithm = "jacobi"``: every other host
here exchanges like Jacobi (both units step from the outputs at t, then the outputs are copied), read from their
code: libcosim's fixed-step algorithm (as tests/fmi/test_libcosim.py compares), fmpy's ``simulate_ssp`` (its loop
steps every component, then applies the connections), and wing.fmu's binary (orchestrator/export/container.c: each
internal step, every unit steps, then the connections are copied). libcosim and the container exchange the
initial outputs once at initialization, as the master does; fmpy's ``simulate_ssp`` starts every connection at
0.0 instead, which the coupled system cannot take (the xfail below), so it runs the structure-only package. The
same FMUs doing the same arithmetic then differ only in how each host forms the communication points: k h in
the master, integer nanoseconds in libcosim, a running sum t += h in fmpy and in the FMI Compliance Checker.
Those differ by at most N machine epsilons of t (N = 500 steps at most here: 500 x 2.2e-16 x 0.3 s = 3e-14 s),
and the structure unit steps to the point it is given; TIME_TOL is over 30 times that.
"""
from __future__ import annotations

import importlib.util
import re
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest
from lxml import etree

from fmi_hosts import UnitSpec, assert_clean, assert_replayed_by_fmpy, check, fmpy_run, run_c_host
from fmu_common.topology import Topology
from fmu_common.wing_spec import StructureSpec
from orchestrator.build import native_binary
from orchestrator.cli import fmu_dir, main
from orchestrator.run.master import run_scene
from orchestrator.scene.load import hinge_joints, load_scene
from repository import SCENES
from subprocesses import wingsim

SCENE = SCENES / "deploy_rigid.toml"
SSP_RUN = Path(__file__).with_name("ssp_run.py")
SCHEMA = Path(importlib.util.find_spec("fmpy").origin).parent / "ssp" / "schema"
NS = {"ssd": "http://ssp-standard.org/SSP1/SystemStructureDescription",
      "ssc": "http://ssp-standard.org/SSP1/SystemStructureCommon",
      "ssv": "http://ssp-standard.org/SSP1/SystemStructureParameterValues",
      "osp": "http://opensimulationplatform.com/SSP/OSPAnnotations"}
TIME_TOL = 1e-12   # s: the communication points' round-off (module docstring)
STILL_AIR = ["aero.model=none"]


def export(folder: Path, *overrides: str, out: str = "export") -> dict[str, Path]:
    """`wingsim export` of deploy_rigid in a fresh process in `folder` into folder/`out` (its FMUs go to
    folder/fmus/<folder>/, ``orchestrator.cli.fmu_dir``)."""
    args = ["export", SCENE, "--out", folder / out]
    for item in overrides:
        args += ["--set", item]
    out = wingsim(*args, cwd=folder)
    assert out.returncode == 0, out.stdout + out.stderr
    written = [Path(line) for line in out.stdout.split()]
    assert [p.name for p in written] == ["deploy_rigid.ssp", "wing.fmu"]
    fmus = folder / fmu_dir(load_scene(SCENE, overrides), load_scene(SCENE))   # where export built them
    return {"ssp": folder / written[0], "container": folder / written[1], "fmus": fmus}


@pytest.fixture(scope="module")
def coupled(tmp_path_factory) -> dict[str, Path]:
    return export(tmp_path_factory.mktemp("export"))


@pytest.fixture(scope="module")
def still_air(tmp_path_factory) -> dict[str, Path]:
    return export(tmp_path_factory.mktemp("export_still"), *STILL_AIR)


@pytest.fixture(scope="module")
def jacobi(coupled) -> float:
    """Deployment time (s) of wingsim's master with Jacobi coupling on the exported FMUs."""
    scene = load_scene(SCENE, ["coupling.algorithm=jacobi"])
    result = run_scene(scene, backend="fmu", fmu_dir=coupled["fmus"])
    assert result.status == "ok", result.message
    return result.latch_times["fold"]


def ssd_of(ssp: Path) -> etree._Element:
    with zipfile.ZipFile(ssp) as z:
        return etree.fromstring(z.read("SystemStructure.ssd"))


def run_tool(tool: str, ssp: Path, *parameters: str) -> dict[str, float]:
    out = subprocess.run([sys.executable, str(SSP_RUN), tool, str(ssp), *parameters], capture_output=True,
                         text=True, timeout=600)
    assert out.returncode == 0, out.stdout + out.stderr
    return {k: float(v) for k, v in re.findall(r"^(\S+)=(\S+)$", out.stdout, re.M)}


# ---- the package ----------------------------------------------------------------------------------------
def test_the_package_holds_the_system_structure_and_both_fmus(coupled):
    with zipfile.ZipFile(coupled["ssp"]) as z:
        assert sorted(z.namelist()) == ["SystemStructure.ssd", "resources/aero_unit.fmu",
                                        "resources/structure_unit.fmu"]
        for kind in ("structure", "aero"):   # the FMUs `run` uses, unchanged
            assert z.read(f"resources/{kind}_unit.fmu") == (coupled["fmus"] / f"{kind}.fmu").read_bytes()


def test_the_ssd_validates_against_the_ssp_schema(coupled):
    root = ssd_of(coupled["ssp"])
    schema = etree.XMLSchema(file=str(SCHEMA / "SystemStructureDescription.xsd"))
    assert schema.validate(root), schema.error_log
    # the inline parameter sets are only laxly checked by the SSD schema: check them against their own
    values = etree.XMLSchema(file=str(SCHEMA / "SystemStructureParameterValues.xsd"))
    sets = root.findall(".//ssv:ParameterSet", NS)
    assert len(sets) == 2
    for parameter_set in sets:
        assert values.validate(etree.ElementTree(parameter_set)), values.error_log
    # and fmpy reads it with its own validation
    from fmpy.ssp.ssd import find_components, get_connections, read_ssd
    ssd = read_ssd(str(coupled["ssp"]))
    assert [c.name for c in find_components(ssd.system)] == ["structure_unit", "aero_unit"]
    n = Topology.from_spec(StructureSpec.from_scene(load_scene(SCENE))).n_coordinates
    assert len(get_connections(ssd.system)) == 3 * n


def test_every_coupling_connection_and_nothing_else(coupled):
    n = Topology.from_spec(StructureSpec.from_scene(load_scene(SCENE))).n_coordinates
    expected = {("structure_unit", f"{b}[{k}]", "aero_unit", f"{b}[{k}]") for b in ("e", "de") for k in range(1, n + 1)}
    expected |= {("aero_unit", f"Q[{k}]", "structure_unit", f"Q[{k}]") for k in range(1, n + 1)}
    connections = [(c.get("startElement"), c.get("startConnector"), c.get("endElement"), c.get("endConnector"))
                   for c in ssd_of(coupled["ssp"]).findall("ssd:System/ssd:Connections/ssd:Connection", NS)]
    assert len(connections) == len(expected) == 3 * n
    assert set(connections) == expected
    # every connection joins an output to an input, with the same unit at both ends
    connectors = {(c.getparent().getparent().get("name"), c.get("name")): c
                  for c in ssd_of(coupled["ssp"]).findall(".//ssd:Component/ssd:Connectors/ssd:Connector", NS)}
    for start, out, end, into in connections:
        a, b = connectors[(start, out)], connectors[(end, into)]
        assert (a.get("kind"), b.get("kind")) == ("output", "input")
        assert a.find("ssc:Real", NS).get("unit") == b.find("ssc:Real", NS).get("unit") is not None


def test_parameters_carry_the_scene_values_and_the_experiment_its_times(coupled):
    scene = load_scene(SCENE)
    root = ssd_of(coupled["ssp"])
    bound = {}
    for component in root.findall("ssd:System/ssd:Elements/ssd:Component", NS):
        declared = {c.get("name") for c in component.findall("ssd:Connectors/ssd:Connector[@kind='parameter']", NS)}
        values = {p.get("name"): float(p.find("ssv:Real", NS).get("value"))
                  for p in component.findall(".//ssv:Parameter", NS)}
        assert set(values) == declared and declared   # every parameter connector bound, and only those
        bound[component.get("name")] = values
    fold = next(j for j in hinge_joints(scene) if j["name"] == "fold")
    assert {k: bound["structure_unit"][f"structure.joints.fold.{k}"] for k in ("stiffness", "damping", "torque")} == \
        {k: fold[k] for k in ("stiffness", "damping", "torque")}
    assert [bound["structure_unit"][f"structure.gravity[{i}]"] for i in (1, 2, 3)] == scene["structure"]["gravity"]
    assert bound["structure_unit"]["structure.step"] == scene["structure"]["step"]
    assert bound["aero_unit"]["flow.speed"] == scene["flow"]["speed"] == 10.0
    assert bound["aero_unit"]["flow.density"] == scene["flow"]["density"]
    experiment = root.find("ssd:DefaultExperiment", NS)
    assert (float(experiment.get("startTime")), float(experiment.get("stopTime"))) == (0.0, scene["time"]["stop"])
    step = experiment.find("ssd:Annotations/ssc:Annotation[@type='com.opensimulationplatform']/osp:Algorithm/"
                           "osp:FixedStepAlgorithm", NS)
    assert float(step.get("baseStepSize")) == scene["coupling"]["step"]


def test_a_structure_only_scene_is_the_structure_alone(still_air):
    root = ssd_of(still_air["ssp"])
    assert [c.get("name") for c in root.findall("ssd:System/ssd:Elements/ssd:Component", NS)] == ["structure_unit"]
    assert root.find("ssd:System/ssd:Connections", NS) is None
    # Q is held at its start value 0, as `wingsim run` holds it: no input connectors left dangling
    assert root.findall(".//ssd:Connector[@kind='input']", NS) == []
    with zipfile.ZipFile(still_air["ssp"]) as z:
        assert sorted(z.namelist()) == ["SystemStructure.ssd", "resources/structure_unit.fmu"]


def test_bad_input_exits_2_before_anything_is_built(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert main(["export", str(tmp_path / "missing.toml")]) == 2
    assert "missing.toml" in capsys.readouterr().err
    assert main(["export", str(SCENE), "--set", "flow.speed=-1"]) == 2
    assert "flow.speed" in capsys.readouterr().err
    (tmp_path / "a_file").write_text("")
    assert main(["export", str(SCENE), "--out", str(tmp_path / "a_file")]) == 2
    assert "--out" in capsys.readouterr().err
    assert not (tmp_path / "fmus").exists()


def test_each_variant_is_exported_into_its_own_folder_and_says_what_it_is(coupled):
    # without --out: export/<scene>/ for the scene as its file writes it, export/<scene>-<digest>/ for a variant
    folder = coupled["fmus"].parents[1]
    default = wingsim("export", SCENE, cwd=folder)
    assert default.returncode == 0, default.stderr
    first = [folder / line for line in default.stdout.split()]
    assert [p.parent.relative_to(folder) for p in first] == [Path("export/deploy_rigid")] * 2
    written = {p: p.read_bytes() for p in first}
    variants = []
    for speed in ("12", "14"):
        out = wingsim("export", SCENE, "--set", f"flow.speed={speed}", cwd=folder)
        assert out.returncode == 0, out.stderr
        ssp, container = [folder / line for line in out.stdout.split()]
        assert ssp.parent == container.parent and ssp.parent.name.startswith("deploy_rigid-")
        variants.append(ssp.parent)
        description = ssd_of(ssp).find("ssd:System", NS).get("description")
        # the override, not the scene file's text (which says 10 m/s)
        assert f"flow.speed={speed}" in description and "10 m/s" not in description
        assert ssd_of(ssp).find(".//ssv:Parameter[@name='flow.speed']/ssv:Real", NS).get("value") == f"{speed}.0"
    assert len(set(variants)) == 2 and first[0].parent not in variants
    assert {p: p.read_bytes() for p in first} == written   # no variant overwrote the scene's own export
    assert "10 m/s" in ssd_of(first[0]).find("ssd:System", NS).get("description")


def test_a_unit_the_scene_does_not_build_or_a_foreign_aero_fmu_is_refused_naming_the_option(coupled, tmp_path):
    out = wingsim("build", SCENE, "--set", "aero.model=none", "--unit", "aero", cwd=tmp_path)
    assert out.returncode == 2 and "--unit" in out.stderr and not (tmp_path / "fmus").exists(), out.stderr
    structure = coupled["fmus"] / "structure.fmu"
    out = wingsim("export", SCENE, "--aero", structure, cwd=tmp_path)
    assert out.returncode == 2 and "--aero" in out.stderr and "structure unit" in out.stderr, out.stderr
    out = wingsim("export", SCENE, "--aero", tmp_path / "missing.fmu", cwd=tmp_path)
    assert out.returncode == 2 and "--aero" in out.stderr and "missing.fmu" in out.stderr, out.stderr
    assert not (tmp_path / "fmus").exists() and not (tmp_path / "export").exists()


def test_an_aero_unit_of_another_geometry_is_not_swapped_in(coupled, tmp_path):
    built = wingsim("build", SCENE, "--set", "structure.bodies.outer.length=0.2", "--unit", "aero", cwd=tmp_path)
    assert built.returncode == 0, built.stderr
    (aero,) = [tmp_path / line for line in built.stdout.split()]
    out = wingsim("export", SCENE, "--aero", aero, cwd=tmp_path)
    assert out.returncode == 1, out.stdout + out.stderr
    # both FMUs and both topologies named
    structure_hash = Topology.from_spec(StructureSpec.from_scene(load_scene(SCENE))).topology_hash
    other = load_scene(SCENE, ["structure.bodies.outer.length=0.2"])
    other_hash = Topology.from_spec(StructureSpec.from_scene(other)).topology_hash
    assert structure_hash != other_hash
    assert all(str(x) in out.stderr for x in (structure_hash, other_hash, aero.name, "structure.fmu")), out.stderr


# ---- the package in other tools -------------------------------------------------------------------------
def test_libcosim_runs_the_package_to_the_jacobi_deployment_time(coupled, jacobi, tmp_path):
    cosim = run_tool("libcosim", coupled["ssp"], "structure.joints.fold.torque", "flow.speed")
    # libcosim took its step from the package's annotation: 300 steps reached the stop time
    assert cosim["time_s"] == pytest.approx(0.3, abs=TIME_TOL)
    assert cosim["deployment_time_s"] == pytest.approx(jacobi, abs=TIME_TOL)
    assert 0.15 < jacobi < 0.25   # it deployed within the run (the fold hinge latched)
    assert (cosim["structure.joints.fold.torque"], cosim["flow.speed"]) == (0.043, 10.0)

    # libcosim applies the package's parameter bindings: change two of them in the SSD, not in the FMUs
    changed = tmp_path / "changed.ssp"
    with zipfile.ZipFile(coupled["ssp"]) as source, zipfile.ZipFile(changed, "w") as target:
        for info in source.infolist():
            data = source.read(info)
            if info.filename == "SystemStructure.ssd":
                root = etree.fromstring(data)
                for name, value in (("structure.joints.fold.torque", "0.05"), ("flow.speed", "12.5")):
                    root.find(f".//ssv:Parameter[@name='{name}']/ssv:Real", NS).set("value", value)
                data = etree.tostring(root, xml_declaration=True, encoding="utf-8")
            target.writestr(info, data)
    cosim_changed = run_tool("libcosim", changed, "structure.joints.fold.torque", "flow.speed")
    assert (cosim_changed["structure.joints.fold.torque"], cosim_changed["flow.speed"]) == (0.05, 12.5)
    assert cosim_changed["deployment_time_s"] < cosim["deployment_time_s"] - 1e-3   # more torque: sooner


def test_fmpy_simulate_ssp_runs_the_structure_only_package_to_wingsim_s_deployment(still_air):
    by_fmpy = run_tool("fmpy", still_air["ssp"])
    assert by_fmpy["steps"] == 300
    result = run_scene(load_scene(SCENE, STILL_AIR), backend="fmu", fmu_dir=still_air["fmus"])
    assert result.status == "ok", result.message
    assert by_fmpy["deployment_time_s"] == pytest.approx(result.latch_times["fold"], abs=TIME_TOL)


@pytest.mark.xfail(strict=True, reason="fmpy 0.3.32's simulate_ssp starts every connection at 0.0 instead of "
                   "the FMUs' initial outputs, so the aero unit's first step gets e = 0 (every node at the "
                   "origin, zero-area panels) and refuses it; libcosim runs the same package")
def test_fmpy_simulate_ssp_runs_the_coupled_package_to_the_jacobi_deployment_time(coupled, jacobi):
    assert run_tool("fmpy", coupled["ssp"])["deployment_time_s"] == pytest.approx(jacobi, abs=TIME_TOL)


# ---- wing.fmu ---------------------------------------------------------------------------------------------
STEP = 1e-3   # s, deploy_rigid's coupling.step: the container's internal step
NO_CHECKER_BINARY = pytest.mark.skipif(
    native_binary.unavailable_reason() is not None,
    reason=f"the units keep pythonfmu's binary, which a host without Python cannot load: "
           f"{native_binary.unavailable_reason()}")


def unpacked(fmu: Path, folder: Path) -> Path:
    with zipfile.ZipFile(fmu) as z:
        z.extractall(folder)
    return folder


def test_the_container_exposes_the_units_outputs_and_parameters(coupled):
    from fmpy import read_model_description
    from fmpy.validation import validate_fmu

    assert validate_fmu(str(coupled["container"])) == []
    md = read_model_description(str(coupled["container"]))
    declared = {v.name: v for v in md.modelVariables}
    units = {kind: read_model_description(str(coupled["fmus"] / f"{kind}.fmu")) for kind in ("structure", "aero")}
    coupling = re.compile(r"^(e|de|Q)\[\d+\]$")
    for unit in units.values():
        for v in unit.modelVariables:
            if v.type != "Real" or coupling.match(v.name) or v.causality not in ("output", "parameter"):
                continue
            assert declared[v.name].causality == v.causality, v.name
            assert declared[v.name].unit == v.unit, v.name
            if v.causality == "parameter":
                assert float(declared[v.name].start) == float(v.start), v.name
    scene = load_scene(SCENE)
    for name in ["latch_time_fold", "fold_angle_fold", "CL", "lift"] + [
            f"{p['name']}_{c}" for p in scene["probes"] for c in "xyz"]:
        assert declared[name].causality == "output", name
    assert not any(coupling.match(name) for name in declared)   # the coupling stays inside
    assert declared["time"].valueReference == 0 and declared["time"].causality == "independent"
    assert float(md.defaultExperiment.stopTime) == scene["time"]["stop"]
    # any host step: no internal step the host must follow, and no state to save or restore
    cs = md.coSimulation
    assert cs.modelIdentifier == "wing"
    assert cs.canHandleVariableCommunicationStepSize and cs.fixedInternalStepSize is None
    assert not cs.canGetAndSetFMUstate and not cs.canSerializeFMUstate
    # it has no inputs: no output depends directly on one, which it declares; its model name names both units'
    assert md.outputs and all(u.dependencies == [] for u in md.outputs)
    assert all(unit.modelName in md.modelName for unit in units.values())


def test_the_container_holds_its_binary_and_the_unit_fmus_unpacked_whole(coupled):
    with zipfile.ZipFile(coupled["container"]) as z:
        entries = {info.filename: info for info in z.infolist()}
        # its own binary, for linux64 only, executable
        assert [name for name in entries if name.startswith("binaries/")] == ["binaries/linux64/wing.so"]
        assert entries["binaries/linux64/wing.so"].external_attr >> 16 & 0o111
        expected = {"modelDescription.xml", "binaries/linux64/wing.so", "resources/container.txt"}
        for kind in ("structure", "aero"):
            with zipfile.ZipFile(coupled["fmus"] / f"{kind}.fmu") as unit:
                files = [info for info in unit.infolist() if not info.is_dir()]
                for info in files:   # every file of the unit FMU, same bytes, same permissions
                    inside = entries[f"resources/{kind}/{info.filename}"]
                    assert z.read(inside) == unit.read(info), info.filename
                    assert inside.external_attr == info.external_attr, info.filename
                expected |= {f"resources/{kind}/{info.filename}" for info in files}
                # the shim is executable in the unit FMU, so the permissions kept are not all alike
                assert unit.getinfo(f"binaries/linux64/{kind}.so").external_attr >> 16 & 0o111
        assert set(entries) == expected


def test_fmpy_runs_the_container_to_the_jacobi_deployment_time(coupled, jacobi):
    from fmpy import simulate_fmu

    result = simulate_fmu(str(coupled["container"]), stop_time=0.3, output_interval=0.001,
                          output=["latch_time_fold", "fold_angle_fold", "lift"])
    assert result["time"][-1] == pytest.approx(0.3, abs=TIME_TOL)
    assert result["latch_time_fold"][-1] == pytest.approx(jacobi, abs=TIME_TOL)
    assert result["fold_angle_fold"][0] == pytest.approx(170.0) and abs(result["fold_angle_fold"][-1]) < 5.0
    # a parameter set on the container reaches the unit: without air (flow.density = 0) the wing has no lift
    vacuum = simulate_fmu(str(coupled["container"]), stop_time=0.02, output_interval=0.001, output=["lift"],
                          start_values={"flow.density": 0.0})
    assert np.all(vacuum["lift"] == 0.0) and np.any(result["lift"][:21] != 0.0)


def internal_steps(t: float, big_h: float, h: float) -> list[tuple[float, float]]:
    """The internal steps (t_k, h_k) of a host step from t over big_h as container.c's header says: steps of h from
    t (t_k = t + k h), the last one ending at t + big_h, a remainder within 1e-9 h joining the last step."""
    end, steps = t + big_h, []
    for k in range(10**6):
        tk = t + k * h
        if end - tk <= h * (1 + 1e-9):
            return steps + [(tk, end - tk)]
        steps.append((tk, h))
    raise AssertionError("unreachable")


class JacobiReference:
    """The two unit FMUs driven through fmpy as the container documents its coupling: the initial outputs
    copied once after initialization, then per internal step both units step from the inputs they hold and
    every connection is copied (all outputs read, then all inputs set)."""

    def __init__(self, fmus: Path, folder: Path):
        from fmpy import read_model_description
        from fmpy.fmi2 import FMU2Slave

        self.units, self.refs = {}, {}
        for kind in ("structure", "aero"):
            md = read_model_description(str(fmus / f"{kind}.fmu"))
            slave = FMU2Slave(guid=md.guid, unzipDirectory=str(unpacked(fmus / f"{kind}.fmu", folder / kind)),
                              modelIdentifier=md.coSimulation.modelIdentifier, instanceName=kind)
            slave.instantiate()
            slave.setupExperiment(startTime=0.0)
            slave.enterInitializationMode()
            slave.exitInitializationMode()
            self.units[kind] = slave
            self.refs[kind] = {v.name: v.valueReference for v in md.modelVariables}
        n = sum(1 for name in self.refs["structure"] if name.startswith("e["))
        self.block = {b: [f"{b}[{k}]" for k in range(1, n + 1)] for b in ("e", "de", "Q")}
        self.exchange()

    def get(self, kind: str, names: list[str]) -> list[float]:
        return self.units[kind].getReal([self.refs[kind][name] for name in names])

    def exchange(self) -> None:
        e, de, q = self.get("structure", self.block["e"]), self.get("structure", self.block["de"]), \
            self.get("aero", self.block["Q"])
        self.units["aero"].setReal([self.refs["aero"][name] for name in self.block["e"] + self.block["de"]], e + de)
        self.units["structure"].setReal([self.refs["structure"][name] for name in self.block["Q"]], q)

    def host_step(self, t: float, big_h: float) -> None:
        for tk, hk in internal_steps(t, big_h, STEP):
            for slave in self.units.values():
                slave.doStep(tk, hk)
            self.exchange()

    def outputs(self, names: list[str]) -> list[float]:
        """The named outputs, each read from the unit that declares it."""
        return [self.get("structure" if name in self.refs["structure"] else "aero", [name])[0] for name in names]

    def free(self) -> None:
        for slave in self.units.values():
            slave.terminate()
            slave.freeInstance()


def test_a_tunable_variant_is_exported_on_the_same_fmus_with_its_own_parameter_values(coupled):
    # structure.joints.fold.torque is tunable: the variant's package carries the FMUs of the scene itself and
    # binds its own value; its container sets that value on the unit, whatever the unit was built with
    from fmpy import simulate_fmu

    torque = "structure.joints.fold.torque"
    variant = export(coupled["fmus"].parents[1], f"{torque}=0.05", out="variant")   # where the scene was exported
    assert variant["fmus"] == coupled["fmus"]
    with zipfile.ZipFile(variant["ssp"]) as z:
        bound = float(etree.fromstring(z.read("SystemStructure.ssd")).find(
            f".//ssv:Parameter[@name='{torque}']/ssv:Real", NS).get("value"))
        fmus = {kind: z.read(f"resources/{kind}_unit.fmu") for kind in ("structure", "aero")}
    assert bound == 0.05
    assert fmus == {kind: (coupled["fmus"] / f"{kind}.fmu").read_bytes() for kind in ("structure", "aero")}
    # the reference: wingsim's master, Jacobi coupled as the container, on FMUs built from the variant's scene
    scene = load_scene(SCENE, [f"{torque}=0.05", "coupling.algorithm=jacobi"])
    reference = run_scene(scene, backend="direct")
    result = simulate_fmu(str(variant["container"]), stop_time=0.3, output_interval=0.001,
                          output=["latch_time_fold"])
    assert result["latch_time_fold"][-1] == pytest.approx(reference.latch_times["fold"], abs=TIME_TOL)


def test_a_host_step_of_2_5_internal_steps_is_the_documented_sequence_of_internal_steps(coupled, tmp_path):
    """Host steps H = 2.5 coupling.step: the container's outputs at every communication point equal, bit for
    bit, the two unit FMUs driven through fmpy with internal steps h, h, h/2 per host step (JacobiReference)."""
    from fmpy import read_model_description
    from fmpy.fmi2 import FMU2Slave

    big_h, host_steps = 2.5 * STEP, 120   # to 0.3 s
    assert [hk / STEP for _, hk in internal_steps(0.0, big_h, STEP)] == pytest.approx([1.0, 1.0, 0.5], rel=1e-12)
    md = read_model_description(str(coupled["container"]))
    names = [v.name for v in md.modelVariables if v.causality == "output"]
    refs = [v.valueReference for v in md.modelVariables if v.causality == "output"]
    wing = FMU2Slave(guid=md.guid, unzipDirectory=str(unpacked(coupled["container"], tmp_path / "wing")),
                     modelIdentifier="wing", instanceName="wing")
    wing.instantiate()
    wing.setupExperiment(startTime=0.0)
    wing.enterInitializationMode()
    wing.exitInitializationMode()
    t, container = 0.0, [wing.getReal(refs)]
    for _ in range(host_steps):
        wing.doStep(t, big_h)
        t += big_h
        container.append(wing.getReal(refs))
    assert wing.getReal([0]) == [t]   # `time`: the container's own
    wing.terminate()
    wing.freeInstance()

    reference = JacobiReference(coupled["fmus"], tmp_path / "units")
    t, expected = 0.0, [reference.outputs(names)]
    for _ in range(host_steps):
        reference.host_step(t, big_h)
        t += big_h
        expected.append(reference.outputs(names))
    reference.free()
    np.testing.assert_array_equal(np.array(container), np.array(expected))
    latch = np.array(container)[:, names.index("latch_time_fold")]
    assert 0.15 < latch[-1] < 0.25   # it deployed: the comparison covers the latch


def test_a_communication_point_that_is_not_the_container_s_time_is_refused(coupled, tmp_path):
    from fmpy import read_model_description
    from fmpy.fmi1 import FMICallException, calloc, free
    from fmpy.fmi2 import (FMU2Slave, fmi2CallbackAllocateMemoryTYPE, fmi2CallbackFreeMemoryTYPE,
                           fmi2CallbackFunctions, fmi2CallbackLoggerTYPE)

    log = []
    callbacks = fmi2CallbackFunctions()
    callbacks.logger = fmi2CallbackLoggerTYPE(lambda env, name, status, category, message:
                                              log.append((status, message.decode())))
    callbacks.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
    callbacks.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
    md = read_model_description(str(coupled["container"]))
    wing = FMU2Slave(guid=md.guid, unzipDirectory=str(unpacked(coupled["container"], tmp_path / "wing")),
                     modelIdentifier="wing", instanceName="wing")
    wing.instantiate(callbacks=callbacks)
    wing.setupExperiment(startTime=0.0)
    wing.enterInitializationMode()
    wing.exitInitializationMode()
    wing.doStep(0.0, 0.6 * STEP)
    with pytest.raises(FMICallException) as refused:   # a gap of one step
        wing.doStep(0.6 * STEP + STEP, STEP)
    assert refused.value.status == 3
    assert log[-1][0] == 3 and "is not the container's time" in log[-1][1]
    wing.doStep(0.6 * STEP, STEP)   # from its time it steps on
    assert wing.getReal([0]) == [0.6 * STEP + STEP]
    wing.terminate()
    wing.freeInstance()


FAILING_HOST = r"""
import ctypes, math, sys
from fmpy import read_model_description
from fmpy.fmi1 import FMICallException, calloc, free
from fmpy.fmi2 import (FMU2Slave, fmi2CallbackAllocateMemoryTYPE, fmi2CallbackFreeMemoryTYPE, fmi2CallbackFunctions,
                       fmi2CallbackLoggerTYPE)

folder, case = sys.argv[1], sys.argv[2]
def logger(env, name, status, category, message):
    print(f"log {status} {message.decode()}", flush=True)
callbacks = fmi2CallbackFunctions()
callbacks.logger = fmi2CallbackLoggerTYPE(logger)
callbacks.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
callbacks.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
md = read_model_description(folder + "/modelDescription.xml")
vr = {v.name: v.valueReference for v in md.modelVariables}
wing = FMU2Slave(guid=md.guid, unzipDirectory=folder, modelIdentifier="wing", instanceName="wing")

def call(name, *args):
    try:
        getattr(wing, name)(*args)
        print(f"status {name} 0", flush=True)
    except FMICallException as e:
        print(f"status {name} {e.status}", flush=True)

if case == "null":   # the binary called with no instance and with a pointer that is not one
    lib = ctypes.CDLL(folder + "/binaries/linux64/wing.so")
    foreign = ctypes.create_string_buffer(4096)
    for label, component in (("NULL", None), ("foreign", ctypes.addressof(foreign))):
        lib.fmi2DoStep.argtypes = [ctypes.c_void_p, ctypes.c_double, ctypes.c_double, ctypes.c_int]
        lib.fmi2GetReal.argtypes = [ctypes.c_void_p, ctypes.c_void_p, ctypes.c_size_t, ctypes.c_void_p]
        lib.fmi2Terminate.argtypes = lib.fmi2FreeInstance.argtypes = [ctypes.c_void_p]
        value, ref = ctypes.c_double(), ctypes.c_uint(0)
        print(f"status {label} fmi2DoStep {lib.fmi2DoStep(component, 0.0, 1e-3, 1)}")
        print(f"status {label} fmi2GetReal {lib.fmi2GetReal(component, ctypes.byref(ref), 1, ctypes.byref(value))}")
        print(f"status {label} fmi2Terminate {lib.fmi2Terminate(component)}")
        lib.fmi2FreeInstance(component)
else:
    try:
        wing.instantiate(callbacks=callbacks)
        print("status instantiate 0", flush=True)
    except Exception:
        print("status instantiate NULL", flush=True)
    if case != "guid":
        wing.setupExperiment(startTime=0.0)
        wing.setReal([vr["structure.joints.fold.torque"]], [float(sys.argv[3])])
        wing.enterInitializationMode()
        call("exitInitializationMode")
        call("doStep", 0.0, 1e-3)
        call("doStep", 0.0, 1e-3)
        wing.freeInstance()
print("the host lives on", flush=True)
"""


def failing_host(folder: Path, *args: str) -> tuple[dict[str, str], list[tuple[int, str]]]:
    """FAILING_HOST on the unpacked container `folder` in a fresh Python; ({call: status}, [(status, message)])
    after asserting that it ended normally."""
    out = subprocess.run([sys.executable, "-c", FAILING_HOST, str(folder), *args], capture_output=True, text=True,
                         timeout=300)
    assert out.returncode == 0, out.stdout + out.stderr
    assert out.stdout.rstrip().endswith("the host lives on"), out.stdout + out.stderr
    statuses = dict(line.split(" ", 1)[1].rsplit(" ", 1) for line in out.stdout.splitlines()
                    if line.startswith("status "))
    log = [(int(line.split(" ", 2)[1]), line.split(" ", 2)[2]) for line in out.stdout.splitlines()
           if line.startswith("log ")]
    return statuses, log


def test_a_unit_that_refuses_its_guid_makes_instantiate_fail_and_the_host_lives(coupled, tmp_path):
    folder = unpacked(coupled["container"], tmp_path / "wing")
    configuration = folder / "resources" / "container.txt"
    guid = re.search(r"^unit structure structure (\S+)$", configuration.read_text(), re.M).group(1)
    configuration.write_text(configuration.read_text().replace(guid, "not-the-structure-s-guid"))
    statuses, log = failing_host(folder, "guid")
    assert statuses == {"instantiate": "NULL"}
    # the unit's own refusal (orchestrator/build/fmi_shim.c names both GUIDs), prefixed with its name, then
    # the container's
    assert any(status == 3 and message.startswith("structure: ") and "not-the-structure-s-guid" in message
               and guid in message for status, message in log), log
    assert any(status == 3 and message.startswith("unit structure: fmi2Instantiate returned NULL")
               for status, message in log), log


def test_a_unit_that_refuses_a_parameter_makes_initialization_fail_and_the_host_lives(coupled, tmp_path):
    statuses, log = failing_host(unpacked(coupled["container"], tmp_path / "wing"), "nan", "nan")
    assert statuses["instantiate"] == "0"
    assert statuses["exitInitializationMode"] == "3"
    assert any(message.startswith("structure: ") and "structure.joints.fold.torque" in message
               for _, message in log), log
    assert statuses["doStep"] == "3"   # the container does not step after a failed initialization


def test_a_unit_that_diverges_makes_the_step_fail_and_the_host_lives(coupled, tmp_path):
    """A fold torque of 1e6 N.m (0.043 in the scene) accelerates the wing beyond what the structure's explicit
    integrator can follow in its step: the structure unit refuses the step as diverged, and the container says
    so with fmi2Error; the next step is refused, naming the failure."""
    statuses, log = failing_host(unpacked(coupled["container"], tmp_path / "wing"), "torque", "1e6")
    assert statuses["exitInitializationMode"] == "0"
    assert statuses["doStep"] == "3"
    messages = [message for status, message in log if status == 3]
    assert any(m.startswith("structure: ") and "diverged" in m for m in messages), log
    assert any(m.startswith("unit structure: fmi2DoStep(t = 0 s, h = 0.001 s) returned fmi2Error") for m in messages)
    assert "fmi2DoStep: refused: an earlier call failed (unit structure: fmi2DoStep" in messages[-1]


def test_a_null_or_foreign_component_gives_fmi2error(coupled, tmp_path):
    statuses, _ = failing_host(unpacked(coupled["container"], tmp_path / "wing"), "null")
    assert statuses == {f"{label} {call}": "3" for label in ("NULL", "foreign")
                        for call in ("fmi2DoStep", "fmi2GetReal", "fmi2Terminate")}


def test_export_without_a_c_compiler_writes_the_package_and_refuses_wing_fmu(coupled, tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(coupled["fmus"].parents[1])   # where export built the FMUs: nothing to rebuild
    monkeypatch.setenv("CC", str(tmp_path / "no-such-cc"))
    out = tmp_path / "export"
    assert main(["export", str(SCENE), "--out", str(out)]) == 1
    err = capsys.readouterr().err
    assert f"{out / 'wing.fmu'} not written" in err and "no C compiler" in err and "no-such-cc" in err
    assert sorted(p.name for p in out.iterdir()) == ["deploy_rigid.ssp"]   # nothing partial


def test_the_container_in_the_c_host_with_an_empty_environment(c_host, coupled, jacobi, tmp_path):
    """The C host of tests/fmi/c_host/ runs wing.fmu as its only unit with no environment but the variables
    that choose this process's numeric kernels (fmi_hosts.numeric_env); fmpy's FMU2Slave makes the same calls
    in this process: equal outputs, bit for bit."""
    folder = unpacked(coupled["container"], tmp_path / "wing")
    unit = UnitSpec.read("wing", folder)
    unit.outputs = [(vr, name) for vr, name in unit.outputs
                    if name in ("latch_time_fold", "fold_angle_fold", "energy", "CL", "lift")]
    steps, h = 300, 0.001
    c = run_c_host(c_host, [unit], steps, h, steps * h, ["run"], tmp_path / "host")["run"]
    np.testing.assert_array_equal(c, fmpy_run([unit], steps, h, steps * h))
    latch = 1 + [name for _, name in unit.outputs].index("latch_time_fold")
    assert c[-1, latch] == pytest.approx(jacobi, abs=TIME_TOL)


@NO_CHECKER_BINARY
def test_the_container_passes_the_compliance_checker_with_its_default_options(fmu_checker, coupled, tmp_path):
    """No -h, no -s: the checker runs the DefaultExperiment to 0.3 s in 500 steps of 0.6 ms (its default of 500
    output points), not a multiple of the internal step, and shortens its last step to land on the stop time,
    as it does for an FMU that declares canHandleVariableCommunicationStepSize. The deployment time equals
    wingsim's master with Jacobi coupling at that step (in-process slaves, no FMU)."""
    out_csv = tmp_path / "out.csv"
    assert_clean(subprocess.run([str(fmu_checker), "-l", "3", "-o", str(out_csv), str(coupled["container"])],
                                env={}, capture_output=True, text=True, timeout=600))
    rows = np.genfromtxt(out_csv, delimiter=",", names=True)
    stop = load_scene(SCENE)["time"]["stop"]
    assert (rows["time"][0], rows["time"][-1]) == (0.0, stop)
    assert rows["fold_angle_fold"][0] == pytest.approx(170.0) and abs(rows["fold_angle_fold"][-1]) < 5.0
    step = stop / 500
    master = run_scene(load_scene(SCENE, ["coupling.algorithm=jacobi", f"coupling.step={step!r}"]), backend="direct")
    assert master.status == "ok", master.message
    assert rows["latch_time_fold"][-1] == pytest.approx(master.latch_times["fold"], abs=TIME_TOL)


@NO_CHECKER_BINARY
def test_the_container_in_the_checker_equals_fmpy_s_replay_bit_for_bit(fmu_checker, coupled, tmp_path):
    out_csv = tmp_path / "out.csv"
    assert_clean(check(fmu_checker, coupled["container"], out_csv, 1e-3, 0.02))
    # the same numbers through fmpy, for every output; not for the container's own `time` variable, a running
    # sum of its steps, which the replay would compare with the checker's time column (1e-17 apart)
    lines = out_csv.read_text().split("\n", 1)
    assert lines[0].startswith('"time",')
    outputs_only = tmp_path / "outputs.csv"
    outputs_only.write_text('"checker_time"' + lines[0][len('"time"'):] + "\n" + lines[1])
    assert_replayed_by_fmpy(coupled["container"], outputs_only, rows=21)
