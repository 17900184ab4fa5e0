"""The generalized-alpha steps of a communication step in one compiled call (step_kernels.c alpha_steps, through
StructureSolver.advance) against the same steps taken one call each (`steps_in_one_call = False`), on a model constant
in time (deploy_flexible), one with a prescribed motion (spin_up) and one with a ramped load.

Each step of the call is the same alpha_step on the same inputs, so the states are the per-step run's bit for bit,
with the same Newton iterations and the same latch time; the external work agrees to round-off (its power is summed
in another order). Where the call stops (a latch, a step that fails the solver's checks) the per-step path takes the
step, as if the call had not been made: the latch time, the divergence message and the state kept are the per-step
run's. A saved state restored repeats its steps bit for bit (the call never writes into a factorization a saved
state holds).
"""
import numpy as np
import pytest

from fmu_common.errors import SolverDiverged
from fmu_common.specs import StructureUnitSpec
from orchestrator.scene.load import load_scene
from structure_fmu import step_kernel
from structure_fmu.solver import StructureSolver
from repository import SCENES

FIELDS = ("q", "dq", "ddq", "accel", "multipliers")


def solver_of(scene, one_call, overrides=()):
    solver = StructureSolver(StructureUnitSpec.from_scene(load_scene(SCENES / f"{scene}.toml", overrides)))
    solver.steps_in_one_call = one_call
    return solver


def counted_calls(monkeypatch):
    """The steps each StepKernel.alpha_steps call committed, in a list that grows as the calls are made."""
    committed, call = [], step_kernel.StepKernel.alpha_steps

    def counting(self, *args):
        taken = call(self, *args)
        committed.append(taken.committed)
        return taken
    monkeypatch.setattr(step_kernel.StepKernel, "alpha_steps", counting)
    return committed


def assert_same_state(a, b):
    assert a.t == b.t
    for name in FIELDS:
        assert np.array_equal(getattr(a, name), getattr(b, name)), name


def test_a_deployment_in_one_call_is_the_per_step_run(monkeypatch):
    # deploy_flexible's structure under a constant generalized force, through its latch (about 0.12 s)
    committed = counted_calls(monkeypatch)
    Q = 1e-3 * np.random.default_rng(7).standard_normal(solver_of("deploy_flexible", False).e.size)
    runs = []
    for one_call in (True, False):
        solver = solver_of("deploy_flexible", one_call)
        for k in range(1, 151):
            solver.advance(k * 1e-3, Q)
        runs.append(solver)
    one, per_step = runs
    assert_same_state(one.state, per_step.state)
    assert one.integrator.newton_iterations == per_step.integrator.newton_iterations
    assert one.state.latch_times == per_step.state.latch_times and "fold" in one.state.latch_times
    assert abs(one.state.work - per_step.state.work) <= 1e-12 * abs(per_step.state.work)
    assert per_step.state.work != 0.0
    # the calls took nearly every step: five per communication step, the start-up's and the latch's per step
    assert sum(committed) >= 0.95 * 5 * 150
    np.testing.assert_array_equal(one.e, per_step.e)


def test_a_restored_state_repeats_its_steps_bit_for_bit():
    solver = solver_of("deploy_flexible", True)
    Q = np.zeros(solver.e.size)
    for k in range(1, 21):
        solver.advance(k * 1e-3, Q)
    saved = solver.get_state()
    for k in range(21, 26):          # several calls: each factorizes into the buffers the call owns
        solver.advance(k * 1e-3, Q)
    first = solver.state.copy()
    solver.set_state(saved)
    for k in range(21, 26):
        solver.advance(k * 1e-3, Q)
    assert_same_state(solver.state, first)


def test_a_diverging_step_is_reported_as_the_per_step_run_reports_it(monkeypatch):
    # a generalized force far beyond the wing's strength, from a state past the start-up
    committed = counted_calls(monkeypatch)
    outcomes = []
    for one_call in (True, False):
        solver = solver_of("deploy_flexible", one_call)
        Q = np.zeros(solver.e.size)
        for k in range(1, 6):
            solver.advance(k * 1e-3, Q)
        Q[-3:] = 1e9
        with pytest.raises(SolverDiverged) as raised:
            solver.advance(6e-3, Q)
        outcomes.append((raised.value, solver.state))
    assert committed[-1] == 0         # the call stopped before the failing step, which the per-step path took
    (one, kept), (per_step, kept_per_step) = outcomes
    assert (one.time, one.reason) == (per_step.time, per_step.reason)
    assert_same_state(kept, kept_per_step)


@pytest.mark.parametrize("scene, stop, step", [
    ("spin_up", 2.0, 0.01),                       # a prescribed root motion: the terms of each step's time
    ("cantilever_large_deflection", 0.3, 0.002)])  # a ramped point load: its force and power at each step's time
def test_what_varies_in_time_is_taken_at_each_steps_time(scene, stop, step, monkeypatch):
    committed = counted_calls(monkeypatch)
    runs = []
    for one_call in (True, False):
        solver = solver_of(scene, one_call)
        for k in range(1, round(stop / step) + 1):
            solver.advance(k * step)
        runs.append(solver)
    one, per_step = runs
    assert one.model.varies_in_time
    assert_same_state(one.state, per_step.state)
    assert one.integrator.newton_iterations == per_step.integrator.newton_iterations
    assert abs(one.state.work - per_step.state.work) <= 1e-12 * abs(per_step.state.work)
    assert sum(committed) >= 0.9 * round(stop / step) * round(step / one.step_size)


def test_rk4_takes_one_call_per_step():
    solver = solver_of("deploy_rigid", True)
    solver.advance(1e-3)
    assert not solver.integrator.takes_steps(solver.model)
