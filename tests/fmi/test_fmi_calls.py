"""Every FMI call answered as the FMI 2.0 standard says (deploy_rigid, structure and aero units).

Each call a generic host may make wrongly is made on the slave classes in-process (as the direct backend
drives them) and on the built FMUs through fmpy's FMU2Slave: the call is refused (an error logged naming
the problem, no exception; through the FMU's shim the status is fmi2Error, which fmpy raises as
FMICallException), the process goes on, and the unit is exactly as it was: a unit that saw the refused
calls and a unit that did not give bit-identical outputs.
"""
import importlib
import json
import math
import os
import pickle
import shutil
import sys
from pathlib import Path

import numpy as np
import pytest
from fmpy import extract, read_model_description
from fmpy.fmi1 import FMICallException, calloc, free
from fmpy.fmi2 import (FMU2Slave, fmi2CallbackAllocateMemoryTYPE, fmi2CallbackFreeMemoryTYPE,
                       fmi2CallbackFunctions, fmi2CallbackLoggerTYPE)

from orchestrator.build import native_binary
from orchestrator.scene.load import load_scene
from orchestrator.run.port import FMU_FILES, KINDS
from fmu_common.fmi_slave import SCENE_RESOURCE
from fmu_common.specs import StructureUnitSpec
from fmu_common.wing_spec import StructureSpec
from structure_fmu.solver import StructureSolver
from fmu_common.topology import Topology
from repository import SCENES

H = 1e-3  # communication step, s
ERROR = 3  # fmi2Error


class Direct:
    """A slave class instantiated in-process, as orchestrator.run.units' direct backend does. Every call
    records what the slave logged in `last` = (None, [(status, message)]); an exception fails the test."""

    backend = "direct"

    def __init__(self, kind, scene, folder):
        module, name = KINDS[kind].slave
        folder.mkdir(parents=True, exist_ok=True)
        (folder / SCENE_RESOURCE).write_text(json.dumps(scene), encoding="utf-8")
        self.slave = getattr(importlib.import_module(module), name)(instance_name=kind, resources=str(folder))
        self.vr = {v.name: vr for vr, v in self.slave.vars.items()}
        self.last = (None, [])

    def _call(self, method, *args):
        result = getattr(self.slave, method)(*args)
        queue = self.slave.log_queue
        self.last = (None, [(int(m.status), m.msg.replace("%%", "%")) for m in queue])
        queue.clear()
        return result

    def setup(self, t0=0.0):
        return self._call("setup_experiment", t0)

    def enter(self):
        return self._call("enter_initialization_mode")

    def exit(self):
        return self._call("exit_initialization_mode")

    def step(self, t, h):
        return self._call("do_step", t, h)

    def terminate(self):
        return self._call("terminate")

    def get_real(self, vrs):
        return self._call("get_real", list(vrs))

    def set_real(self, vrs, values):
        return self._call("set_real", list(vrs), [float(v) for v in values])

    def get_integer(self, vrs):
        return self._call("get_integer", list(vrs))

    def get_boolean(self, vrs):
        return self._call("get_boolean", list(vrs))

    def get_string(self, vrs):
        return self._call("get_string", list(vrs))

    def set_integer(self, vrs, values):
        return self._call("set_integer", list(vrs), list(values))

    def set_boolean(self, vrs, values):
        return self._call("set_boolean", list(vrs), list(values))

    def set_string(self, vrs, values):
        return self._call("set_string", list(vrs), list(values))

    def get_state(self):
        return self._call("_get_fmu_state")

    def set_state(self, state):
        return self._call("_set_fmu_state", state)

    def serialize(self, state):
        return self._call("_fmu_state_to_bytes", state)

    def deserialize(self, data):
        return self._call("_fmu_state_from_bytes", data)

    def close(self):
        pass


class Fmpy(Direct):
    """The built FMU through fmpy's FMU2Slave; `last` = (status of the call, [(status, message)])."""

    backend = "fmu"

    def __init__(self, fmu_path, name):
        md = read_model_description(str(fmu_path))
        self.dir = extract(str(fmu_path))
        inner = native_binary.inner_name(md.coSimulation.modelIdentifier)
        self.shim = (Path(self.dir) / native_binary.PLATFORM_DIR / inner).is_file()
        self.vr = {v.name: v.valueReference for v in md.modelVariables}
        self.log, self.last = [], (0, [])

        def logger(env, instance, status, category, message):
            self.log.append((int(status), (message or b"").decode("utf-8", "replace").replace("%%", "%")))
        self._callbacks = fmi2CallbackFunctions()
        self._callbacks.logger = fmi2CallbackLoggerTYPE(logger)
        self._callbacks.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
        self._callbacks.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
        self.fmu = FMU2Slave(guid=md.guid, unzipDirectory=self.dir, instanceName=name,
                             modelIdentifier=md.coSimulation.modelIdentifier)
        self.fmu.instantiate(callbacks=self._callbacks, loggingOn=True)

    def _call(self, method, *args):
        mark = len(self.log)
        try:
            result, status = getattr(self.fmu, method)(*args), 0
        except FMICallException as exc:
            result, status = None, exc.status
        self.last = (status, self.log[mark:])
        return result

    def setup(self, t0=0.0):
        return self._call("setupExperiment", None, t0)

    def enter(self):
        return self._call("enterInitializationMode")

    def exit(self):
        return self._call("exitInitializationMode")

    def step(self, t, h):
        return self._call("doStep", t, h)

    def terminate(self):
        return self._call("terminate")

    def reset(self):
        return self._call("reset")

    def get_real(self, vrs):
        return self._call("getReal", list(vrs))

    def set_real(self, vrs, values):
        return self._call("setReal", list(vrs), [float(v) for v in values])

    def get_integer(self, vrs):
        return self._call("getInteger", list(vrs))

    def get_boolean(self, vrs):
        return self._call("getBoolean", list(vrs))

    def get_string(self, vrs):
        values = self._call("getString", list(vrs))
        return None if values is None else [v.decode("utf-8") for v in values]

    def set_integer(self, vrs, values):
        return self._call("setInteger", list(vrs), list(values))

    def set_boolean(self, vrs, values):
        return self._call("setBoolean", list(vrs), list(values))

    def set_string(self, vrs, values):
        return self._call("setString", list(vrs), list(values))

    def get_state(self):
        return self._call("getFMUstate")

    def set_state(self, state):
        return self._call("setFMUstate", state)

    def serialize(self, state):
        return self._call("serializeFMUstate", state)

    def deserialize(self, data):
        return self._call("deSerializeFMUstate", data)

    def close(self):
        self.fmu.freeInstance()
        # pythonfmu put <dir>/resources first on sys.path at instantiation: take it out with the folder
        resources = os.path.normpath(os.path.join(self.dir, "resources"))
        sys.path[:] = [p for p in sys.path if os.path.normpath(p) != resources]
        shutil.rmtree(self.dir, ignore_errors=True)


def refused(unit, *words):
    """The last call was refused: an error logged that contains `words`, no exception; through the shim
    the call returned fmi2Error (with pythonfmu's own binary fmi2OK, or fmi2Discard for a step)."""
    status, messages = unit.last
    errors = " | ".join(m for s, m in messages if s == ERROR)
    assert errors, f"the call was not refused: {messages}"
    for word in words:
        assert word in errors, f"{word!r} not in {errors!r}"
    if unit.backend == "fmu":
        assert status in ({ERROR} if unit.shim else {0, 2}), (status, errors)
    return errors


def accepted(unit):
    status, messages = unit.last
    assert status in (None, 0) and not [m for s, m in messages if s >= 2], messages


@pytest.fixture(scope="module")
def scene():
    return load_scene(SCENES / "deploy_rigid.toml")


@pytest.fixture(scope="module")
def fmu_dir(built_fmus):
    return built_fmus("deploy_rigid")


@pytest.fixture
def make(scene, fmu_dir, tmp_path):
    made = []

    def make(backend, kind, name=None):
        name = name or f"{kind}{len(made)}"
        if backend == "direct":
            unit = Direct(kind, scene, tmp_path / name)
        else:
            unit = Fmpy(fmu_dir / FMU_FILES[kind], name)
        made.append(unit)
        return unit
    yield make
    for unit in made:
        unit.close()


def initialize(unit, t0=0.0):
    for call in (lambda: unit.setup(t0), unit.enter, unit.exit):
        call()
        accepted(unit)


def set_inputs(unit, kind, scene):
    """Structure: a constant Q; aero: the scene's initial coordinates and a small heave rate."""
    n = Topology.from_spec(StructureSpec.from_scene(scene)).n_coordinates
    if kind == "structure":
        vrs, values = [unit.vr[f"Q[{k}]"] for k in range(1, n + 1)], np.full(n, 0.01)
    else:
        de = np.zeros(n)
        de[2::9] = 0.1  # every node's r_z rate, m/s
        vrs = [unit.vr[f"{b}[{k}]"] for b in ("e", "de") for k in range(1, n + 1)]
        values = np.concatenate([Topology.from_spec(StructureSpec.from_scene(scene)).initial_coordinates(), de])
    unit.set_real(vrs, values)
    accepted(unit)


def outputs(unit):
    """Every Real variable of the unit (outputs, inputs and parameters), in value-reference order."""
    values = unit.get_real(sorted(vr for name, vr in unit.vr.items() if name != "topology_hash"))
    accepted(unit)
    return np.array(values)


BACKENDS_AND_KINDS = [(b, k) for b in ("direct", "fmu") for k in ("structure", "aero")]


@pytest.mark.parametrize("backend,kind", BACKENDS_AND_KINDS)
def test_get_and_set_of_the_wrong_type_are_refused(make, scene, backend, kind):
    unit = make(backend, kind)
    e1, hv = unit.vr["e[1]"], unit.vr["topology_hash"]
    assert unit.get_integer([e1]) in ([0], None)
    refused(unit, "fmi2GetInteger", f"{e1} (Real e[1]) is not an Integer variable")
    assert unit.get_boolean([e1, hv]) in ([False, False], None)
    refused(unit, "fmi2GetBoolean", f"{e1} (Real e[1])", f"{hv} (String topology_hash)")
    assert unit.get_string([e1]) in ([""], None)
    refused(unit, "fmi2GetString", "(Real e[1]) is not a String variable")
    values = unit.get_real([hv])
    assert values is None or math.isnan(values[0])
    refused(unit, "fmi2GetReal", f"{hv} (String topology_hash) is not a Real variable")
    unit.get_integer([4_000_000_000])  # an unsigned reference beyond the C int range
    refused(unit, "4000000000 (no such variable)")
    for setter in (unit.set_integer, unit.set_boolean):
        setter([e1], [1])
        refused(unit, "(Real e[1]) is not a")
    unit.set_string([hv], ["another topology"])
    refused(unit, "fmi2SetString", "topology_hash is a constant")
    unit.set_string([e1], ["x"])
    refused(unit, "(Real e[1]) is not a String variable")
    # the one String: read, unchanged by the refused set; the unit then runs as usual
    assert unit.get_string([hv]) == [Topology.from_spec(StructureSpec.from_scene(scene)).topology_hash]
    accepted(unit)
    initialize(unit)
    set_inputs(unit, kind, scene)
    unit.step(0.0, H)
    accepted(unit)
    assert np.all(np.isfinite(outputs(unit)))


@pytest.mark.parametrize("backend,kind", BACKENDS_AND_KINDS)
def test_refused_calls_leave_the_unit_exactly_as_it_was(make, scene, backend, kind):
    unit, reference = make(backend, kind), make(backend, kind)
    unit.step(0.0, H)
    refused(unit, "fmi2DoStep", "not initialized yet")
    unit.exit()
    refused(unit, "fmi2ExitInitializationMode", "after fmi2EnterInitializationMode")
    unit.terminate()
    refused(unit, "fmi2Terminate", "not initialized yet")
    for u in (unit, reference):
        u.setup(0.0)
        u.enter()
        accepted(u)
    unit.enter()
    refused(unit, "fmi2EnterInitializationMode", "in initialization mode")
    unit.step(0.0, H)
    refused(unit, "fmi2DoStep", "in initialization mode")
    for u in (unit, reference):
        u.exit()
        accepted(u)
    for call, words in ((unit.exit, "fmi2ExitInitializationMode"), (unit.enter, "fmi2EnterInitializationMode"),
                        (lambda: unit.setup(1.0), "fmi2SetupExperiment")):
        call()
        refused(unit, words, "the unit is initialized")
    if kind == "structure":
        tunables = StructureSolver.tunable_parameters(StructureUnitSpec.from_scene(scene))
        name, default = "structure.step", tunables["structure.step"][0]
    else:
        name, default = "flow.speed", float(scene["flow"]["speed"])
    unit.set_real([unit.vr[name]], [default + 1.0])
    refused(unit, "fmi2SetReal", name, "after initialization")
    assert unit.get_real([unit.vr[name]]) == [default]

    for k in range(3):
        t = k * H
        for u in (unit, reference):
            set_inputs(u, kind, scene)
        before = outputs(unit)
        for h in (0.0, -H, math.nan, math.inf):
            assert not unit.step(t, h)
            refused(unit, "fmi2DoStep", "step size", "not a finite number > 0")
        for point in (math.nan, math.inf):
            unit.step(point, H)
            refused(unit, "fmi2DoStep", "communication point", "not a finite number")
        unit.step(t + 5.0, H)  # a 5 s gap: refused, never integrated in one call
        refused(unit, "fmi2DoStep", f"t = {t + 5.0!r} s is not the unit's time", "ahead by 5 s")
        if k:
            unit.step(t - H, H)  # the last step again without restoring a state
            refused(unit, "fmi2DoStep", f"t = {t - H!r} s is not the unit's time", "behind by 0.001 s")
        assert np.array_equal(outputs(unit), before)
        for u in (unit, reference):
            u.step(t, H)
            accepted(u)
        assert np.array_equal(outputs(unit), outputs(reference))

    for u in (unit, reference):
        u.terminate()
        accepted(u)
    unit.step(3 * H, H)
    refused(unit, "fmi2DoStep", "terminated")
    unit.set_real([unit.vr["e[1]" if kind == "aero" else "Q[1]"]], [1.0])
    refused(unit, "fmi2SetReal", "only before fmi2Terminate")
    unit.terminate()
    refused(unit, "fmi2Terminate", "terminated")
    assert np.array_equal(outputs(unit), outputs(reference))  # values can still be read after terminate


@pytest.mark.parametrize("backend", ["direct", "fmu"])
def test_the_communication_point_is_the_start_time_plus_the_solver_time(make, scene, backend):
    unit = make(backend, "structure")
    t0 = 2.0
    initialize(unit, t0)
    set_inputs(unit, "structure", scene)
    unit.step(0.0, H)
    refused(unit, f"t = 0.0 s is not the unit's time {t0!r} s")
    unit.step(t0, H)
    accepted(unit)
    # a point off by round-off (well inside TIME_TOLERANCE) is the unit's time; one off by 1 us is not
    unit.step(t0 + H + 5e-10, H)
    accepted(unit)
    unit.step(t0 + 2 * H + 1e-6, H)
    refused(unit, "ahead by 1e-06 s")


@pytest.mark.parametrize("backend", ["direct", "fmu"])
def test_states_that_are_not_this_units_are_refused(make, scene, backend, tmp_path):
    unit = make(backend, "structure")
    aero = make("direct", "aero")
    initialize(unit)
    initialize(aero)
    set_inputs(unit, "structure", scene)
    unit.step(0.0, H)
    saved = unit.get_state()
    unit.step(H, H)
    after_two = outputs(unit)
    if backend == "direct":
        for state, words in ((None, "not a state of this unit (a NoneType)"),
                             ([1, 2], "not a state of this unit (a list)"),
                             ({"error": "the state could not be saved"}, "the state could not be saved"),
                             (aero.get_state(), "a state of the aero unit, not of the structure unit")):
            unit.set_state(state)
            refused(unit, "fmi2SetFMUstate", words)
    elif unit.shim:  # pythonfmu's own binary (no C compiler at build time) cannot check a NULL state
        unit.set_state(None)  # the FMU's shim refuses it before Python sees it
        refused(unit, "fmi2SetFMUstate", "NULL")
    assert np.array_equal(outputs(unit), after_two)

    marker = tmp_path / "unpickling ran code"

    class RunsCode:
        def __reduce__(self):
            return (os.mkdir, (str(marker),))
    for data, words in ((b"garbage", "the bytes do not hold a state of this unit"),
                        (pickle.dumps(RunsCode()), "refers to posix.mkdir, which no unit state holds"),
                        (pickle.dumps([1, 2]), "not a state of this unit (a list)"),
                        (aero.serialize(aero.get_state()), "a state of the aero unit, not of the structure unit")):
        state = unit.deserialize(data)
        refused(unit, "fmi2DeSerializeFMUstate", words)
        if backend == "direct":  # the FMU drops the refused state (the shim); in-process it is refused when set
            unit.set_state(state)
            refused(unit, "fmi2SetFMUstate", words)
    assert not marker.exists()
    assert np.array_equal(outputs(unit), after_two)

    # a state of this unit, as bytes and back, still repeats the step bit for bit
    restored = unit.deserialize(unit.serialize(saved))
    accepted(unit)
    unit.set_state(restored)
    accepted(unit)
    unit.step(H, H)
    accepted(unit)
    assert np.array_equal(outputs(unit), after_two)


def test_with_two_instances_of_an_fmu_garbage_is_refused_when_set(make, scene):
    """pythonfmu deserializes on the slave class: with two live instances of one FMU the refusal cannot be
    told to the calling one at fmi2DeSerializeFMUstate, so the state it returns is refused when set."""
    unit, other = make("fmu", "structure"), make("fmu", "structure")
    initialize(unit)
    set_inputs(unit, "structure", scene)
    unit.step(0.0, H)
    before = outputs(unit)
    state = unit.deserialize(b"garbage")
    accepted(unit)
    unit.set_state(state)
    refused(unit, "fmi2SetFMUstate", "the bytes do not hold a state of this unit")
    assert not [m for s, m in other.log if s >= 2]  # nothing was logged on the other instance
    assert np.array_equal(outputs(unit), before)
    unit.step(H, H)
    accepted(unit)


def test_reset_returns_the_fmu_to_the_state_after_instantiation(make, scene):
    unit = make("fmu", "structure")
    runs = []
    for _ in range(2):
        initialize(unit)
        set_inputs(unit, "structure", scene)
        for k in range(3):
            unit.step(k * H, H)
            accepted(unit)
        runs.append(outputs(unit))
        unit.terminate()
        accepted(unit)
        unit.reset()
        accepted(unit)
        unit.step(0.0, H)
        refused(unit, "fmi2DoStep", "not initialized yet")
    assert np.array_equal(runs[0], runs[1])


FOREIGN_STATES = [  # (unit, the scene's override for the unit that saves the state, words of the refusal)
    ("aero", "aero.model=strip", "aero.model = 'strip', this unit runs aero.model = 'uvlm-flat'"),
    ("aero", "aero.model=uvlm-prescribed", "aero.model = 'uvlm-prescribed', this unit runs aero.model = 'uvlm-flat'"),
    ("aero", "aero.chordwise_panels=3", "state.solver.model.gamma is float64 (42,), this unit's float64 (28,)"),
    ("structure", "structure.integrator=generalized-alpha",
     "structure.integrator = 'generalized-alpha', this unit runs structure.integrator = 'rk4'"),
]


def _stepped_twice(unit, kind, scene):
    """Initialize `unit`, step it once and save its state, step again: (the saved state, the outputs after two
    steps)."""
    initialize(unit)
    set_inputs(unit, kind, scene)
    unit.step(0.0, H)
    accepted(unit)
    saved = unit.get_state()
    unit.step(H, H)
    accepted(unit)
    return saved, outputs(unit)


def _repeats_the_second_step(unit, saved, after_two):
    """The unit, set back to `saved` (a state of its own), repeats its second step bit for bit."""
    unit.set_state(saved)
    accepted(unit)
    unit.step(H, H)
    accepted(unit)
    assert np.array_equal(outputs(unit), after_two)


@pytest.mark.parametrize("backend", ["direct", "fmu"])
@pytest.mark.parametrize("kind,override,words", FOREIGN_STATES, ids=[o for _, o, _ in FOREIGN_STATES])
def test_a_state_of_another_model_integrator_or_size_is_refused_naming_the_mismatch(make, scene, backend, kind,
                                                                                   override, words, tmp_path):
    """A state saved by a unit of another aero model, integrator or lattice (same unit, same topology) is read
    (fmi2DeSerializeFMUstate) and refused when set (fmi2SetFMUstate returns fmi2Error through the shim), and the
    unit goes on from its own state."""
    unit = make(backend, kind)
    other = Direct(kind, load_scene(SCENES / "deploy_rigid.toml", [override]), tmp_path / "other")
    saved, after_two = _stepped_twice(unit, kind, scene)
    _stepped_twice(other, kind, other.slave.scene)
    foreign = unit.deserialize(other.serialize(other.get_state()))
    accepted(unit)
    unit.set_state(foreign)
    refused(unit, "fmi2SetFMUstate refused", words, "state unchanged")
    assert np.array_equal(outputs(unit), after_two)
    _repeats_the_second_step(unit, saved, after_two)


@pytest.mark.parametrize("backend", ["direct", "fmu"])
@pytest.mark.parametrize("kind", ["structure", "aero"])
def test_a_state_holding_nan_is_refused_and_the_unit_goes_on_from_its_own(make, scene, backend, kind):
    """The unit's own state, serialized, with one number of its solver state made NaN: refused at
    fmi2DeSerializeFMUstate (fmi2Error through the shim, which drops it) and, in-process, at fmi2SetFMUstate."""
    unit = make(backend, kind)
    saved, after_two = _stepped_twice(unit, kind, scene)
    state = pickle.loads(unit.serialize(saved))
    accepted(unit)
    if kind == "structure":
        state["solver"][0].dq[1] = np.nan
        where = "state['solver'][0].dq[1] = nan"
    else:
        state["solver"].model.gamma[2] = np.nan
        where = "state['solver'].model.gamma[2] = nan"
    restored = unit.deserialize(pickle.dumps(state))
    refused(unit, "fmi2DeSerializeFMUstate refused", f"not finite: {where}")
    if backend == "direct":
        unit.set_state(restored)
        refused(unit, "fmi2SetFMUstate refused", f"not finite: {where}", "state unchanged")
    assert np.array_equal(outputs(unit), after_two)
    _repeats_the_second_step(unit, saved, after_two)
