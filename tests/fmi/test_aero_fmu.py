"""The aero FMU and the coupled run: build and validation, fmu vs direct backends, bad input, topology
check, rollback, and the Gauss-Seidel / Jacobi exchange order of the master."""
import json
import os
import subprocess
import sys
import types
import zipfile

import numpy as np
import pytest
from fmpy import read_model_description
from fmpy.validation import validate_fmu

from orchestrator.run import units as real_units
from orchestrator.build.fmus import build_fmus, fmus_up_to_date
from orchestrator.cli import fmu_dir as run_fmu_dir  # a fixture below is named fmu_dir
from orchestrator.run.master import CouplingError, check_connection, run_scene
from orchestrator.scene.load import load_scene
from orchestrator.run.port import UnitError
from orchestrator.run.units import make_unit
from fmu_common.topology import Topology
from fmu_common.wing_spec import StructureSpec
from repository import SCENES
from stand_in_units import DictMonitors
from subprocesses import simulate_in_fresh_python, wingsim

# Otsuka et al. 2019, Sec. VI.D, shortened: 5 communication steps of 0.1 s, a short wake
HEAVE = ["time.stop=0.5", "aero.wake_length=3"]
H = 0.1


def heave_scene(*overrides):
    return load_scene(SCENES / "heaving_wing.toml", [*HEAVE, *overrides])


@pytest.fixture(scope="module")
def scene():
    return heave_scene()


@pytest.fixture(scope="module")
def fmu_dir(built_fmus):
    out = built_fmus("heaving_wing", *HEAVE)
    assert sorted(p.name for p in out.iterdir()) == ["aero.fmu", "structure.fmu"]
    return out


@pytest.fixture
def units(scene, fmu_dir):
    made = []

    def make(kind, backend, **kw):
        made.append(make_unit(kind, kw.pop("scene", scene), backend, kw.pop("fmu_dir", fmu_dir), **kw))
        return made[-1]
    yield make
    for u in reversed(made):
        u.terminate()


def coupled(structure, aero, steps, t0=0.0, q=None, lift=False):
    """The master's Gauss-Seidel loop by hand: Q and CL (and the lift) after each step."""
    q = np.zeros(structure.n) if q is None else q
    qs, cls, lifts = [], [], []
    for k in range(steps):
        t = t0 + k * H
        structure.set_inputs(q)
        structure.do_step(t, H)
        aero.set_inputs(*structure.get_outputs())
        aero.do_step(t, H)
        q, = aero.get_outputs()
        qs.append(q)
        m = aero.monitors()
        cls.append(m["CL"])
        lifts.append(m["lift"])
    return (np.array(qs), np.array(cls)) + ((np.array(lifts),) if lift else ())


# --- build ----------------------------------------------------------------------------------------

def test_aero_fmu_builds_validates_and_declares_its_variables(scene, fmu_dir):
    fmu = fmu_dir / "aero.fmu"
    assert validate_fmu(str(fmu)) == []
    names = zipfile.ZipFile(fmu).namelist()
    for member in ("resources/scene.json", "resources/aero_slave.py", "resources/aero_fmu/solver.py",
                   "resources/fmu_common/topology.py", "binaries/linux64/aero.so"):
        assert member in names
    assert "resources/structure_slave.py" not in names      # distinct slave module names (docs/fmu.md)
    assert fmus_up_to_date(scene, fmu_dir)
    assert not fmus_up_to_date({**scene, "aero": {**scene["aero"], "chordwise_panels": 3}}, fmu_dir)
    md = read_model_description(str(fmu))
    assert md.coSimulation.canGetAndSetFMUstate and md.coSimulation.canSerializeFMUstate
    topology = Topology.from_spec(StructureSpec.from_scene(scene))
    n = topology.n_coordinates
    v = {x.name: x for x in md.modelVariables}
    for k, (name, causality) in enumerate([("e", "input"), ("de", "input"), ("Q", "output")]):
        group = [v[f"{name}[{i}]"] for i in range(1, n + 1)]
        assert [x.valueReference for x in group] == list(range(k * n, (k + 1) * n))  # contiguous
        assert {x.causality for x in group} == {causality}
    assert [v[f"e[{i}]"].unit for i in range(1, 10)] == ["m"] * 3 + ["1"] * 6
    assert [v[f"de[{i}]"].unit for i in range(1, 10)] == ["m/s"] * 3 + ["1/s"] * 6
    assert [v[f"Q[{i}]"].unit for i in range(1, 10)] == ["N"] * 3 + ["N.m"] * 6
    assert [v[x].valueReference for x in ("CL", "lift", "wake_panels")] == [3 * n, 3 * n + 1, 3 * n + 2]
    assert (v["CL"].unit, v["lift"].unit, v["lift"].causality) == ("1", "N", "output")
    for name in ("flow.speed", "flow.density", "flow.direction[1]"):
        assert (v[name].causality, v[name].variability) == ("parameter", "fixed")
    assert float(v["flow.speed"].start) == scene["flow"]["speed"]
    assert v["topology_hash"].type == "String" and v["topology_hash"].start == topology.topology_hash
    structure_md = read_model_description(str(fmu_dir / "structure.fmu"))
    assert {x.name: x.start for x in structure_md.modelVariables}["topology_hash"] == topology.topology_hash


def test_each_fmu_embeds_the_shared_package_and_its_own_never_the_other_unit(fmu_dir):
    """aero.fmu holds fmu_common and aero_fmu and no module of the structure unit (its solver, integrators,
    element...); structure.fmu holds fmu_common and structure_fmu, no aero_fmu; both the same fmu_common.
    (pythonfmu's builder adds its own package to every FMU.)"""
    def python_files(fmu):
        with zipfile.ZipFile(fmu) as z:
            return {n: z.read(n) for n in z.namelist() if n.startswith("resources/") and n.endswith(".py")}

    aero, structure = python_files(fmu_dir / "aero.fmu"), python_files(fmu_dir / "structure.fmu")
    package = lambda name: name.split("/")[1] if name.count("/") > 1 else "(slave script)"
    assert {package(n) for n in aero} == {"(slave script)", "pythonfmu", "fmu_common", "aero_fmu"}
    assert {package(n) for n in structure} == {"(slave script)", "pythonfmu", "fmu_common", "structure_fmu"}
    assert not [n for n in aero if "structure" in n or "integrators" in n]
    assert not [n for n in structure if "aero" in n]
    shared = lambda files: {n: data for n, data in files.items() if package(n) == "fmu_common"}
    assert shared(aero) == shared(structure) and "resources/fmu_common/fmi_slave.py" in shared(aero)


def test_the_aero_fmu_alone_never_imports_the_structure_unit(fmu_dir, tmp_path):
    """In a fresh host where structure_fmu is installed (and so importable), simulating aero.fmu imports
    fmu_common and aero_fmu from the FMU and no structure_fmu module at all."""
    code = ("import json, sys, fmpy\n"
            f"fmpy.simulate_fmu({str(fmu_dir / 'aero.fmu')!r}, stop_time=0.2, output_interval=0.1)\n"
            "ours = ('fmu_common', 'aero_fmu', 'structure_fmu')\n"
            "print(json.dumps({m: getattr(sys.modules[m], '__file__', None) for m in sys.modules"
            " if m.split('.')[0] in ours}))\n")
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    out = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, env=env, capture_output=True, text=True,
                         timeout=300)
    assert out.returncode == 0, out.stderr
    modules = json.loads(out.stdout.splitlines()[-1])
    assert "fmu_common.topology" in modules and "aero_fmu.solver" in modules
    assert not [m for m in modules if m.startswith("structure_fmu")]
    assert all(f"resources{os.sep}" in (path or "resources" + os.sep) for path in modules.values())


def test_aero_fmu_runs_alone_in_a_fresh_host_from_its_embedded_packages(fmu_dir, tmp_path, monkeypatch):
    """Any FMI host: the aero FMU alone, inputs at their start values (the scene's initial geometry). Its C
    kernel is compiled into it by the build: it runs with no C compiler and an empty kernel cache, which it
    leaves empty."""
    from aero_fmu.biot_savart import C_SOURCE
    from fmu_common.c_library import library_name

    with zipfile.ZipFile(fmu_dir / "aero.fmu") as z:
        assert f"resources/aero_fmu/{library_name(C_SOURCE)}" in z.namelist()
    cache = tmp_path / "cache"
    monkeypatch.setenv("CC", str(tmp_path / "no-such-cc"))
    monkeypatch.setenv("WINGSIM_CACHE_DIR", str(cache))
    monkeypatch.setenv("WINGSIM_KERNELS", "compiled")
    solver_file, cl = simulate_in_fresh_python(fmu_dir / "aero.fmu", 0.3, 0.1, "aero_fmu.solver", "CL", tmp_path)
    assert f"resources{os.sep}aero_fmu" in solver_file
    assert np.isfinite(cl)
    assert not cache.exists()


# --- the two backends -----------------------------------------------------------------------------

def test_fmu_and_direct_backends_give_the_same_CL_and_Q(units):
    runs = {b: coupled(units("structure", b), units("aero", b), 5) for b in ("fmu", "direct")}
    (q_f, cl_f), (q_d, cl_d) = runs["fmu"], runs["direct"]
    assert np.max(np.abs(q_f - q_d)) <= 1e-10 and np.max(np.abs(cl_f - cl_d)) <= 1e-10
    assert np.max(np.abs(q_f)) > 0 and np.all(np.isfinite(cl_f))       # the heaving wing is loaded


def test_the_aero_fmu_publishes_each_hinge_moment_its_solver_computes(built_fmus):
    # deploy_rigid's aero FMU (uvlm-flat), fed the folded wing's coordinates in a flow turned out of the chord
    # (tunable parameters, set before initialization): hinge_moment_fold through fmpy against AeroSolver in-process
    from aero_fmu.solver import AeroSolver
    from fmu_common.specs import AeroUnitSpec

    scene = load_scene(SCENES / "deploy_rigid.toml")
    turned = {"flow.direction[2]": 0.1, "flow.direction[3]": 0.05}
    spec = AeroUnitSpec.from_scene(scene)
    solver = AeroSolver(spec, {**{k: v[0] for k, v in AeroSolver.tunable_parameters(spec).items()}, **turned})
    e = solver.topology.initial_coordinates()
    de = np.zeros_like(e)
    h = scene["coupling"]["step"]
    aero = make_unit("aero", scene, "fmu", built_fmus("deploy_rigid"), parameters=turned)
    try:
        assert aero.monitors()["hinge_moments"] == {"fold": 0.0}
        for k in range(3):
            aero.set_inputs(e, de)
            aero.do_step(k * h, h)
            solver.advance(k * h + h, e, de)
        published = aero.monitors()["hinge_moments"]
    finally:
        aero.terminate()
    assert list(published) == ["fold"] and abs(published["fold"]) > 1e-4
    assert published["fold"] == pytest.approx(solver.hinge_moments()["fold"], rel=1e-12, abs=1e-15)


def test_a_coupled_run_records_each_hinge_moment_the_aero_unit_publishes():
    # deploy_rigid, 5 ms, direct backend: the master's column hinge_moment_fold is the aero unit's output, the
    # aero solver replayed in-process on the recorded inputs gives the same values, and summary.json has them
    from aero_fmu.solver import AeroSolver
    from fmu_common.specs import AeroUnitSpec
    from orchestrator.output.results import summarize

    scene = load_scene(SCENES / "deploy_rigid.toml", ["time.stop=0.005"])
    result = run_scene(scene, backend="direct")
    assert result.status == "ok", result.message
    recorded = result.series.column("hinge_moment_fold")
    assert result.series.columns[-3:] == ["hinge_moment_fold", "CL", "lift"] and recorded[0] == 0.0
    solver = AeroSolver(AeroUnitSpec.from_scene(scene))
    replayed = []
    inputs = result.aero_inputs
    for t, h, e, de in zip(inputs.t, inputs.h, inputs.e, inputs.de):
        solver.advance(t + h, e, de)
        replayed.append(solver.hinge_moments()["fold"])
    np.testing.assert_array_equal(recorded[1:], replayed)
    assert np.max(np.abs(recorded)) > 0            # the folded outer body in the flow is loaded once it moves
    summary = summarize(result)["aero"]["hinge_moments"]["fold"]
    assert summary == {"final": recorded[-1], "min": recorded[1:].min(), "max": recorded[1:].max()}


def test_master_fmu_and_direct_runs_record_the_same_CL(scene, fmu_dir):
    results = {b: run_scene(scene, backend=b, fmu_dir=fmu_dir) for b in ("fmu", "direct")}
    for r in results.values():
        assert r.status == "ok", r.message
        assert r.series.columns[-2:] == ["CL", "lift"]
        assert len(r.series) == 6 and np.all(np.isfinite(r.series.CL))
    np.testing.assert_allclose(results["fmu"].series.CL, results["direct"].series.CL, rtol=0, atol=1e-10)
    np.testing.assert_allclose(results["fmu"].series.lift, results["direct"].series.lift, rtol=0, atol=1e-10)


def test_replay_of_the_aero_fmu_reproduces_its_CL_bit_for_bit(scene, fmu_dir):
    """The wake picture replays the aero unit in-process (orchestrator/output/wake_view.py): through fmpy the unit
    gets exactly the recorded e, de and step times, so the replay's CL is the FMU's, bit for bit."""
    from orchestrator.output.wake_view import replay

    result = run_scene(scene, backend="fmu", fmu_dir=fmu_dir)
    assert result.status == "ok", result.message
    snapshots, _, _ = replay(scene, result.aero_inputs, range(len(result.aero_inputs)))
    assert np.array_equal([s.outputs["CL"] for s in snapshots], result.series.CL[1:])


# --- bad input ------------------------------------------------------------------------------------

@pytest.mark.parametrize("backend", ["fmu", "direct"])
@pytest.mark.parametrize("block, bad", [("e", np.nan), ("de", np.inf)])
def test_non_finite_input_to_the_aero_unit_is_reported_and_host_survives(units, backend, block, bad):
    structure, aero = units("structure", backend), units("aero", backend)
    coupled(structure, aero, 2)
    q0, = aero.get_outputs()
    saved = aero.get_state()
    e, de = structure.get_outputs()
    (e if block == "e" else de)[4] = bad
    aero.set_inputs(e, de)
    with pytest.raises(UnitError) as info:
        aero.do_step(2 * H, H)
    word = "NaN" if np.isnan(bad) else "inf"
    assert f"{block}[5]" in str(info.value) and word in str(info.value) and not info.value.diverged
    assert np.array_equal(aero.get_outputs()[0], q0)           # state unchanged
    aero.set_state(saved)                                       # and the host goes on
    aero.set_inputs(*structure.get_outputs())
    aero.do_step(2 * H, H)
    assert np.all(np.isfinite(aero.get_outputs()[0]))


def test_nan_into_the_aero_unit_mid_run_stops_the_master_with_its_reason(scene, fmu_dir):
    def make_unit(**kwargs):
        unit = real_units.make_unit(**kwargs)
        if kwargs["kind"] == "aero":
            send, calls = unit.set_inputs, [0]

            def set_inputs(e, de):
                calls[0] += 1
                e = np.array(e, dtype=float)
                if calls[0] >= 3:     # call 1 at t = 0, calls 2, 3 after the steps from 0 and 0.1 s
                    e[4] = np.nan
                send(e, de)
            unit.set_inputs = set_inputs
        return unit
    fake = types.SimpleNamespace(make_unit=make_unit, UnitError=real_units.UnitError)
    result = run_scene(scene, backend="fmu", fmu_dir=fmu_dir, units=fake)
    assert result.status == "error"
    assert "e[5]" in result.message and "NaN" in result.message and "aero" in result.message
    np.testing.assert_allclose(result.series.time, [0.0, 0.1])   # samples before the failing step kept


# --- topology check -------------------------------------------------------------------------------

def test_units_of_different_topology_are_refused_before_the_run(scene, fmu_dir, tmp_path):
    other = heave_scene("structure.bodies.wing.length=999.0")      # another structure, its own FMUs
    build_fmus(other, tmp_path)

    def make_unit(**kwargs):
        if kwargs["kind"] == "aero":
            kwargs.update(scene=other, fmu_dir=tmp_path)
        return real_units.make_unit(**kwargs)
    fake = types.SimpleNamespace(make_unit=make_unit, UnitError=real_units.UnitError)
    result = run_scene(scene, backend="fmu", fmu_dir=fmu_dir, units=fake)
    assert result.status == "error" and len(result.series) == 0 and result.simulated_time_s == 0.0
    assert "topolog" in result.message and "rebuild both FMUs from one scene" in result.message
    assert Topology.from_spec(StructureSpec.from_scene(scene)).topology_hash in result.message


def test_the_aero_fmu_refuses_the_coordinates_of_another_wing_at_its_first_step(scene, fmu_dir, tmp_path):
    """A host that compares no topology_hash hands the aero FMU (heaving wing, span 1000 m) the initial e of a
    structure of span 500 m: fmi2DoStep answers fmi2Error (fmi2Discard through pythonfmu's own binary, which has
    no error status for a step), the log at error status names this unit's scene and hash, the node that is off
    with both positions, and the unit lives on: the right e is then accepted (aero_fmu.pairing)."""
    from fmpy.fmi1 import FMICallException, calloc, free
    from fmpy.fmi2 import (FMU2Slave, fmi2CallbackAllocateMemoryTYPE, fmi2CallbackFreeMemoryTYPE,
                           fmi2CallbackFunctions, fmi2CallbackLoggerTYPE)
    from orchestrator.build import native_binary

    own = Topology.from_spec(StructureSpec.from_scene(scene))
    other = Topology.from_spec(StructureSpec.from_scene(heave_scene("structure.bodies.wing.length=500.0")))
    assert other.n_coordinates == own.n_coordinates
    log = []

    def logger(env, instance, status, category, message):
        log.append((int(status), (message or b"").decode("utf-8", "replace")))
    callbacks = fmi2CallbackFunctions()
    callbacks.logger = fmi2CallbackLoggerTYPE(logger)
    callbacks.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
    callbacks.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
    with zipfile.ZipFile(fmu_dir / "aero.fmu") as z:
        z.extractall(tmp_path / "aero")
    md = read_model_description(str(tmp_path / "aero" / "modelDescription.xml"))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    e_refs = [vr[f"e[{k}]"] for k in range(1, own.n_coordinates + 1)]
    aero = FMU2Slave(guid=md.guid, unzipDirectory=str(tmp_path / "aero"),
                     modelIdentifier=md.coSimulation.modelIdentifier, instanceName="aero")
    aero.instantiate(callbacks=callbacks)
    aero.setupExperiment(startTime=0.0)
    aero.enterInitializationMode()
    aero.exitInitializationMode()
    aero.setReal(e_refs, other.initial_coordinates().tolist())
    mark = len(log)
    with pytest.raises(FMICallException) as refused:
        aero.doStep(0.0, H)
    assert refused.value.status == (3 if native_binary.unavailable_reason() is None else 2)
    errors = [text for status, text in log[mark:] if status == 3]
    assert len(errors) == 1, log[mark:]
    text = errors[0]
    tip = 9 * own.node_names.index("wing.1")
    assert "aero unit rejected its input" in text and "node wing.1" in text
    assert "(" + ", ".join(f"{v:.6g}" for v in own.initial_coordinates()[tip:tip + 3]) + ")" in text
    assert "(" + ", ".join(f"{v:.6g}" for v in other.initial_coordinates()[tip:tip + 3]) + ")" in text
    assert "scene 'heaving_wing'" in text and own.topology_hash in text and "1000 m" in text
    assert aero.getReal([vr["wake_panels"]]) == [0.0]              # state unchanged: no step taken
    aero.setReal(e_refs, own.initial_coordinates().tolist())
    aero.doStep(0.0, H)                                            # the right structure's e: accepted
    assert not [text for status, text in log[mark + 1:] if status >= 2]
    aero.terminate()
    aero.freeInstance()


def test_check_connection_compares_hash_and_size():
    unit = lambda h, n: types.SimpleNamespace(topology_hash=h, n=n, label=f"unit {h}")
    check_connection(unit("abc", 18), unit("abc", 18))
    with pytest.raises(CouplingError, match="abc vs abd"):
        check_connection(unit("abc", 18), unit("abd", 18))
    with pytest.raises(CouplingError, match="18 coordinates but the aero unit 27"):
        check_connection(unit("abc", 18), unit("abc", 27))


def test_a_stale_aero_fmu_is_refused(scene, fmu_dir):
    changed = {**scene, "aero": {**scene["aero"], "wake_length": 4.0}}   # not tunable: another build
    with pytest.raises(UnitError, match=r"aero\.wake_length.*rebuild"):
        make_unit("aero", changed, "fmu", fmu_dir)


# --- rollback -------------------------------------------------------------------------------------

def test_rollback_of_the_aero_unit_reproduces_steps_exactly_through_fmpy(units):
    structure, aero = units("structure", "fmu"), units("aero", "fmu")
    coupled(structure, aero, 2)
    s_saved, a_saved = structure.get_state(), aero.get_state()
    q_saved, = aero.get_outputs()
    q1, cl1 = coupled(structure, aero, 3, t0=2 * H, q=q_saved)
    for _ in range(2):   # the same state can be restored more than once
        structure.set_state(s_saved)
        aero.set_state(a_saved)
        q2, cl2 = coupled(structure, aero, 3, t0=2 * H, q=q_saved)
        assert np.array_equal(q1, q2) and np.array_equal(cl1, cl2)
    # --serialize-state: bytes out and back in (the wake included)
    data = aero.serialize_state(a_saved)
    assert isinstance(data, bytes) and data
    structure.set_state(s_saved)
    aero.set_state(aero.deserialize_state(data))
    q3, cl3 = coupled(structure, aero, 3, t0=2 * H, q=q_saved)
    assert np.array_equal(q1, q3) and np.array_equal(cl1, cl3)


def test_parameters_of_the_aero_unit_are_applied_in_both_backends(scene, units):
    density = 2.0 * scene["flow"]["density"]
    runs = {b: coupled(units("structure", b), units("aero", b, parameters={"flow.density": density}), 3,
                       lift=True) for b in ("fmu", "direct")}
    _, cl_ref, lift_ref = coupled(units("structure", "direct"), units("aero", "direct"), 3, lift=True)
    _, cl_f, lift_f = runs["fmu"]
    _, cl_d, lift_d = runs["direct"]
    np.testing.assert_allclose(lift_f, lift_d, rtol=0, atol=1e-10)
    assert np.max(np.abs(lift_ref)) > 0
    np.testing.assert_allclose(lift_d, 2.0 * lift_ref, rtol=1e-9, atol=1e-12)   # lift ~ density
    np.testing.assert_allclose(cl_d, cl_ref, rtol=1e-9, atol=1e-12)             # CL is not
    with pytest.raises(UnitError, match="unknown parameter"):
        units("aero", "direct", parameters={"flow.sped": 1.0})


# --- the exchange order of the master, with stand-in units -----------------------------------------

class _Structure(DictMonitors):
    n, topology_hash, kind = 9, "h", "structure"

    def __init__(self, log):
        self.log, self.t = log, 0.0

    def get_outputs(self):
        return np.full(self.n, self.t), np.full(self.n, 10 * self.t)

    def set_inputs(self, q):
        self.log.append(("structure.set_inputs", float(q[0])))

    def do_step(self, t, h):
        self.log.append(("structure.do_step", t))
        self.t = t + h

    def monitors(self):
        return {"energy": 0.0, "kinetic_energy": 0.0, "constraint_residual": 0.0, "fold_angles_deg": {}}

    def terminate(self):
        pass


class _Aero(_Structure):
    kind = "aero"

    def __init__(self, log):
        super().__init__(log)
        self.e = None

    def get_outputs(self):
        return (np.full(self.n, 100 + self.t),)

    def set_inputs(self, e, de):
        self.e = float(e[0])
        self.log.append(("aero.set_inputs", self.e))

    def do_step(self, t, h):
        self.log.append(("aero.do_step", t))
        self.t = t + h

    def monitors(self):
        return {"CL": self.t, "lift": 2 * self.t, "wake_panels": 0.0}


class _Topology:
    n_coordinates = 9
    n_nodes = 1


def _fake_run(algorithm):
    log = []
    scene = {"name": "fake", "time": {"stop": 0.2}, "coupling": {"step": 0.1, "algorithm": algorithm},
             "aero": {"model": "uvlm-flat"}, "probes": [], "strain_gauges": [],
             "record": {"probes": "acceleration", "monitors": "all"},
             "structure": {"joints": [], "step": 0.1}}
    made = {"structure": _Structure(log), "aero": _Aero(log)}
    fake = types.SimpleNamespace(make_unit=lambda **kw: made[kw["kind"]], UnitError=UnitError)
    result = run_scene(scene, backend="direct", units=fake, topology=_Topology())
    assert result.status == "ok", result.message
    return log, result


def test_gauss_seidel_steps_the_structure_then_the_aero_unit_with_the_new_coordinates():
    log, result = _fake_run("gauss-seidel")
    assert log == [("aero.set_inputs", 0.0),                                 # initial e at t = 0
                   ("structure.set_inputs", 100.0), ("structure.do_step", 0.0),   # Q(0)
                   ("aero.set_inputs", 0.1), ("aero.do_step", 0.0),              # e(0.1)
                   ("structure.set_inputs", 100.1), ("structure.do_step", 0.1),   # Q(0.1)
                   ("aero.set_inputs", 0.2), ("aero.do_step", 0.1)]
    np.testing.assert_allclose(result.series.CL, [0.0, 0.1, 0.2])
    np.testing.assert_allclose(result.series.lift, [0.0, 0.2, 0.4])


def test_jacobi_steps_both_units_from_the_outputs_at_the_start_of_the_step():
    log, _ = _fake_run("jacobi")
    assert log == [("aero.set_inputs", 0.0),
                   ("structure.set_inputs", 100.0), ("aero.do_step", 0.0), ("structure.do_step", 0.0),
                   ("aero.set_inputs", 0.1),
                   ("structure.set_inputs", 100.1), ("aero.do_step", 0.1), ("structure.do_step", 0.1),
                   ("aero.set_inputs", 0.2)]


# --- end to end -----------------------------------------------------------------------------------

def test_strip_theory_scene_runs_end_to_end(tmp_path):
    out = tmp_path / "out"
    proc = wingsim("run", SCENES / "steady_wing.toml", "--set", "aero.model=strip", "--out", out, cwd=tmp_path)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "ok" and summary["scene"]["aero"]["model"] == "strip"
    assert summary["aero"]["model"] == "strip" and 0.2 < summary["aero"]["CL_final"] < 0.6   # 5 deg, AR 8
    header = (out / "timeseries.csv").read_text().splitlines()[0].split(",")
    assert header[0] == "time [s]" and header[-2:] == ["CL [-]", "lift [N]"]
    assert (out / "lift_coefficient.png").stat().st_size > 1000
    variant = load_scene(SCENES / "steady_wing.toml", ["aero.model=strip"])
    file_scene = load_scene(SCENES / "steady_wing.toml")
    assert (tmp_path / run_fmu_dir(variant, file_scene) / "aero.fmu").is_file()   # a --set variant's own folder
