"""The structure FMU: build, model description, fmu vs direct backend, bad input, rollback (deploy_rigid)."""
import json
import os
import zipfile
from xml.etree import ElementTree

import numpy as np
import pytest
from fmpy import read_model_description
from fmpy.validation import validate_fmu

from fmu_common.fmi_slave import DIVERGED_CATEGORY
from fmu_common.specs import StructureUnitSpec
from fmu_common.wing_spec import StructureSpec
from fmu_common.topology import Topology
from orchestrator.build.fmus import embedded_scene, fmus_up_to_date
from orchestrator.scene.load import joint_monitor_names, load_scene
from orchestrator.run.port import UnitError
from orchestrator.run.units import make_unit
from repository import SCENES
from structure_fmu.solver import StructureSolver
from subprocesses import simulate_in_fresh_python

H = 1e-3  # communication step, s
STILL_AIR = ["aero.model=none"]   # the structure unit alone


@pytest.fixture(scope="module")
def scene():
    return load_scene(SCENES / "deploy_rigid.toml", STILL_AIR)


@pytest.fixture(scope="module")
def fmu_dir(built_fmus):
    out = built_fmus("deploy_rigid", *STILL_AIR)
    assert [p.name for p in out.iterdir()] == ["structure.fmu"]
    return out


@pytest.fixture
def units(scene, fmu_dir):
    made = []

    def make(backend, **kw):
        made.append(make_unit("structure", scene, backend, fmu_dir, **kw))
        return made[-1]
    yield make
    for u in made:
        u.terminate()


def run(unit, steps, Q=None, t0=0.0):
    Q = np.zeros(unit.n) if Q is None else Q
    for k in range(steps):
        unit.set_inputs(Q)
        unit.do_step(t0 + k * H, H)
    return unit.get_outputs()


def test_build_embeds_scene_and_package_and_validates(scene, fmu_dir):
    fmu = fmu_dir / "structure.fmu"
    assert validate_fmu(str(fmu)) == []
    names = zipfile.ZipFile(fmu).namelist()
    for member in ("resources/scene.json", "resources/structure_slave.py", "resources/structure_fmu/solver.py",
                   "resources/structure_fmu/topology.py", "resources/fmu_common/topology.py",
                   "resources/fmu_common/fmi_slave.py", "binaries/linux64/structure.so"):
        assert member in names
    assert embedded_scene(fmu) == json.loads(json.dumps(scene))
    assert fmus_up_to_date(scene, fmu_dir)
    # a tunable key is a parameter of the same FMU; any other key needs another build
    assert fmus_up_to_date({**scene, "structure": {**scene["structure"], "step": 5e-5}}, fmu_dir)
    assert not fmus_up_to_date({**scene, "structure": {**scene["structure"], "rho_inf": 0.5}}, fmu_dir)
    md = read_model_description(str(fmu))
    assert md.coSimulation.canGetAndSetFMUstate and md.coSimulation.canSerializeFMUstate


def test_variables_match_topology(scene, fmu_dir):
    topology = Topology.from_spec(StructureSpec.from_scene(scene))
    n = topology.n_coordinates
    md = read_model_description(str(fmu_dir / "structure.fmu"))
    v = {x.name: x for x in md.modelVariables}
    for k, name in enumerate(["e", "de", "Q"]):
        group = [v[f"{name}[{i}]"] for i in range(1, n + 1)]
        assert [x.valueReference for x in group] == list(range(k * n, (k + 1) * n))  # contiguous layout
        assert sum(1 for x in v if x.startswith(f"{name}[")) == n
    assert {v[f"e[{i}]"].causality for i in range(1, n + 1)} == {"output"}
    assert {v[f"Q[{i}]"].causality for i in range(1, n + 1)} == {"input"}
    assert [v[f"e[{i}]"].unit for i in range(1, 10)] == ["m"] * 3 + ["1"] * 6
    assert [v[f"de[{i}]"].unit for i in range(1, 10)] == ["m/s"] * 3 + ["1/s"] * 6
    assert [v[f"Q[{i}]"].unit for i in range(1, 10)] == ["N"] * 3 + ["N.m"] * 6
    for hinge in topology.hinge_names:
        assert v[f"fold_angle_{hinge}"].unit == "deg"
    assert v["energy"].unit == "J" and v["constraint_residual"].causality == "output"
    kinetic = v["kinetic_energy"]
    assert (kinetic.type, kinetic.unit, kinetic.causality, kinetic.variability, kinetic.initial) == (
        "Real", "J", "output", "continuous", "exact")
    # the documented contiguous layout: fold angles, energy, kinetic_energy, constraint_residual, external_work, latch
    # times, probe positions and velocities and strain gauges (tests/units/test_sensors.py), joint monitors,
    # parameters
    h = len(topology.hinge_names)
    assert [v[f"fold_angle_{x}"].valueReference for x in topology.hinge_names] == list(range(3 * n, 3 * n + h))
    assert [v[x].valueReference for x in ("energy", "kinetic_energy", "constraint_residual", "external_work")] == [
        3 * n + h, 3 * n + h + 1, 3 * n + h + 2, 3 * n + h + 3]
    latch = [v[f"latch_time_{x}"] for x in topology.hinge_names]
    assert [x.valueReference for x in latch] == list(range(3 * n + h + 4, 3 * n + 2 * h + 4))
    assert {(x.unit, x.causality, x.variability, float(x.start)) for x in latch} == {("s", "output", "discrete", -1.0)}
    tunables = StructureSolver.tunable_parameters(StructureUnitSpec.from_scene(scene))
    sensors = 9 * len(scene["probes"]) + len(scene["strain_gauges"])
    joints = [v[name].valueReference for name in joint_monitor_names(scene)]
    assert joints == list(range(3 * n + 2 * h + 4 + sensors, 3 * n + 2 * h + 4 + sensors + len(joints)))
    first = 3 * n + 2 * h + 4 + sensors + len(joints)
    assert [v[name].valueReference for name in tunables] == list(range(first, first + len(tunables)))
    for name, (default, unit, _) in StructureSolver.tunable_parameters(StructureUnitSpec.from_scene(scene)).items():
        p = v[name]
        assert (p.causality, p.variability, p.unit) == ("parameter", "fixed", unit)
        assert float(p.start) == pytest.approx(default, rel=1e-15)
    assert v["topology_hash"].type == "String" and v["topology_hash"].start == topology.topology_hash


def test_fmu_and_direct_backends_agree(units):
    fmu, direct = units("fmu"), units("direct")
    assert fmu.n == direct.n and fmu.topology_hash == direct.topology_hash
    Q = np.zeros(fmu.n)
    Q[-9:-6] = [1e-3, 0.0, 0.0]  # a small force on the last node, through the input path
    e_f, de_f = run(fmu, 50, Q)
    e_d, de_d = run(direct, 50, Q)
    assert np.max(np.abs(e_f - e_d)) <= 1e-10 and np.max(np.abs(de_f - de_d)) <= 1e-10
    assert np.max(np.abs(de_f)) > 0  # it moved
    m_f, m_d = fmu.monitors(), direct.monitors()
    assert set(m_f) >= {"energy", "kinetic_energy", "constraint_residual", "fold_angles_deg", "latch_times"}
    assert set(m_d) == set(m_f)
    assert m_f["fold_angles_deg"] == pytest.approx(m_d["fold_angles_deg"], abs=1e-9)
    assert np.isfinite(m_f["energy"]) and m_f["constraint_residual"] < 1e-4
    assert m_f["kinetic_energy"] > 0 and m_f["kinetic_energy"] == pytest.approx(m_d["kinetic_energy"], rel=1e-9)


@pytest.mark.parametrize("backend", ["fmu", "direct"])
@pytest.mark.parametrize("bad", [np.nan, np.inf])
def test_non_finite_input_is_reported_and_host_survives(units, backend, bad):
    unit = units(backend)
    e0, _ = run(unit, 3)
    saved = unit.get_state()
    Q = np.zeros(unit.n)
    Q[4] = bad
    unit.set_inputs(Q)
    with pytest.raises(UnitError, match="NaN") as info:
        unit.do_step(3 * H, H)
    assert "Q[5]" in str(info.value) and not info.value.diverged
    # the host goes on: the unit still answers, can be rolled back and stepped with good input
    assert np.array_equal(unit.get_outputs()[0], e0)
    unit.set_state(saved)
    e, _ = run(unit, 2, t0=3 * H)
    assert np.all(np.isfinite(e))


@pytest.mark.parametrize("backend", ["fmu", "direct"])
def test_divergence_reaches_the_host_with_reason_and_hint(units, backend, monkeypatch):
    from fmu_common.errors import SolverDiverged
    unit = units(backend)  # the FMU in this process shares the host's structure_fmu modules

    def diverge(self, t_end, Q=None):  # '%s' checks the text is not taken as a printf format on the way
        raise SolverDiverged(0.001, "constraint residual 3 (100% %s over the limit)", "reduce structure.step")
    monkeypatch.setattr(StructureSolver, "advance", diverge)
    with pytest.raises(UnitError, match="diverged") as info:
        unit.do_step(0.0, H)
    assert info.value.diverged and "reduce structure.step" in str(info.value)
    assert "(100% %s over the limit)" in str(info.value)
    # the signal is the log category, not the text
    assert [e.category for e in unit._port.log if e.status >= 3] == [DIVERGED_CATEGORY]


@pytest.mark.parametrize("backend", ["fmu", "direct"])
def test_a_failure_whose_text_says_diverged_is_not_a_divergence(units, backend, monkeypatch):
    unit = units(backend)

    def fail(self, t_end, Q=None):
        raise RuntimeError("the tabulated load diverged from its source")
    monkeypatch.setattr(StructureSolver, "advance", fail)
    with pytest.raises(UnitError, match="the tabulated load diverged from its source") as info:
        unit.do_step(0.0, H)
    assert not info.value.diverged


def test_the_divergence_log_category_is_declared(fmu_dir):
    md = ElementTree.fromstring(zipfile.ZipFile(fmu_dir / "structure.fmu").read("modelDescription.xml"))
    assert DIVERGED_CATEGORY in [c.get("name") for c in md.iterfind("LogCategories/Category")]


@pytest.mark.parametrize("backend", ["fmu", "direct"])
def test_refused_parameter_is_reported(scene, fmu_dir, backend):
    hinge = Topology.from_spec(StructureSpec.from_scene(scene)).hinge_names[0]
    with pytest.raises(UnitError, match=f"structure.joints.{hinge}.stiffness"):
        make_unit("structure", scene, backend, fmu_dir, parameters={f"structure.joints.{hinge}.stiffness": -1.0})


def test_rollback_reproduces_a_step_exactly_through_fmpy(units):
    unit = units("fmu")
    run(unit, 20)
    saved = unit.get_state()
    e1, de1 = run(unit, 3, t0=20 * H)
    for _ in range(2):  # the same state can be restored more than once
        unit.set_state(saved)
        e2, de2 = run(unit, 3, t0=20 * H)
        assert np.array_equal(e1, e2) and np.array_equal(de1, de2)
    # --serialize-state: bytes out and back in
    data = unit.serialize_state(saved)
    assert isinstance(data, bytes) and data
    unit.set_state(unit.deserialize_state(data))
    e3, _ = run(unit, 3, t0=20 * H)
    assert np.array_equal(e1, e3)


def test_parameters_are_applied_in_both_backends(scene, units):
    hinge = Topology.from_spec(StructureSpec.from_scene(scene)).hinge_names[0]
    name = f"structure.joints.{hinge}.torque"
    value = 3.0 * StructureSolver.tunable_parameters(StructureUnitSpec.from_scene(scene))[name][0] + 0.05
    ref = run(units("direct"), 20)[0]
    e_f = run(units("fmu", parameters={name: value}), 20)[0]
    e_d = run(units("direct", parameters={name: value}), 20)[0]
    assert np.max(np.abs(e_f - e_d)) <= 1e-10
    assert np.max(np.abs(e_f - ref)) > 1e-8


def test_stale_or_missing_fmu_and_bad_arguments_are_refused(scene, fmu_dir, tmp_path):
    changed = {**scene, "structure": {**scene["structure"], "rho_inf": 0.5}}   # not tunable: another build
    with pytest.raises(UnitError, match=r"structure\.rho_inf.*rebuild"):
        make_unit("structure", changed, "fmu", fmu_dir)
    with pytest.raises(UnitError, match="not found"):
        make_unit("structure", scene, "fmu", tmp_path)
    with pytest.raises(UnitError, match="backend"):
        make_unit("structure", scene, "ssp", fmu_dir)
    with pytest.raises(UnitError, match="unknown parameter"):
        make_unit("structure", scene, "direct", fmu_dir, parameters={"no.such": 1.0})


def test_fmu_runs_in_a_fresh_host_from_its_embedded_package(fmu_dir, tmp_path):
    """A host that never imported structure_fmu: the slave must import the copy inside the FMU."""
    solver_file, angle = simulate_in_fresh_python(fmu_dir / "structure.fmu", 0.003, 0.001, "structure_fmu.solver",
                                                  "fold_angle_fold", tmp_path, timeout=120)
    assert f"resources{os.sep}structure_fmu" in solver_file
    assert 0.0 < angle <= 180.0
