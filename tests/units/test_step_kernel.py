"""The compiled structure step (structure_fmu/step_kernel.py, step_kernels.c) against the numpy path it replaces
(model.StructureModel's residual and iteration matrix, integrators.RK4).

A correction solves A d = r, A = [[S, b' G^T], [b' G, 0]] the iteration matrix and r = [M_q q'' - F + G_q^T lambda,
b' Phi] the residual (Peng et al. 2019, Fig. 3). The compiled correction d, read back from the updated q and
lambda, is checked by its backward error against the reference's A and r: |A d - r| must be round-off of the terms
(independent of A's condition number, 1e7 and more here). A compiled RK4 step gives the reference's state,
accelerations and multipliers to round-off. Whole runs on both paths take the same Newton iterations to the same
states.
"""
import numpy as np
import pytest

from structure_fmu import step_kernel
import structure_fmu.integrators as integrators
from fmu_common.specs import StructureUnitSpec
from orchestrator.scene.load import load_scene
from structure_fmu.integrators import RK4, GeneralizedAlpha, State
from structure_fmu.iteration_lu import IterationLU
from structure_fmu.step_kernel import StepKernel, kernel_for, unsupported
from structure_fmu.solver import StructureSolver
from repository import SCENES

EPS = np.finfo(float).eps

CASES = [("deploy_flexible", [], False), ("deploy_flexible", [], True),     # the hinge free, and latched
         ("scissor_array", [], False),                                       # a chord-axis hinge per scissor
         ("rotating_beam", [], False),                                       # linear constraint rows
         ("spin_up", [], False),                                             # a prescribed root motion
         ("deploy_rigid", ["structure.integrator=generalized-alpha"], False),   # rigid bodies: no elastic force
         ("deploy_flexible", ["structure.damping_model=deformation"], True),    # deformation damping
         ("hale_wing", [], False)]


def model_of(scene, overrides=()):
    return StructureSolver(StructureUnitSpec.from_scene(load_scene(SCENES / f"{scene}.toml", overrides))).model


def generic_inputs(scene, overrides, latched, seed):
    """(model, q, q', Q (n,), latches) of the scene at a generic state with a random generalized force."""
    model = model_of(scene, overrides)
    rng = np.random.default_rng(seed)
    q, v, _, _ = generic_state(model, rng)
    return model, q, v, rng.standard_normal(model.n), {hinge.name: latched for hinge in model.hinges}


def generic_state(model, rng):
    """A state off the solution: q about the initial coordinates, random rates, accelerations and multipliers."""
    q = model.initial_coordinates() + 0.01 * rng.standard_normal(len(model.initial_coordinates()))
    n_q, m = len(q), model.constraint_count
    return q, rng.standard_normal(n_q), 10.0 * rng.standard_normal(n_q), rng.standard_normal(m)


@pytest.mark.parametrize("scene, overrides, latched", CASES)
def test_a_correction_solves_the_reference_equations(scene, overrides, latched):
    model = model_of(scene, overrides)
    assert unsupported(model) is None
    rng = np.random.default_rng(1)
    q, dq, ddq, lam = generic_state(model, rng)
    t, beta_p, gamma_p = 0.0123, 3.1e7, 9.7e3          # generalized-alpha's at h = 2e-4 s, rho_inf = 0.8
    Q = rng.standard_normal(model.n)
    latches = {h.name: latched for h in model.hinges}
    # the reference: A and r from the numpy path
    S, E = model.iteration_matrix(t, q, dq, latches, lam, beta_p, gamma_p)
    G = model.constraint_jacobian(q, E)
    n_q, m = len(q), len(lam)
    A = np.block([[S, beta_p * G.T], [beta_p * G, np.zeros((m, m))]])
    F = model.force_q(q, dq, t, Q, latches)[0]
    inertia, coupling = model.mass_product(q, t, ddq), lam @ G
    r = np.concatenate([inertia - F + coupling, beta_p * model.constraint_residual(q, E)])
    # the compiled correction
    kernel = StepKernel.for_model(model, IterationLU(n_q, m, model.iteration_pattern()))
    kernel.prepare((t,), Q, latches)
    factorization = kernel.factor(q, dq, lam, beta_p, gamma_p)
    q1, dq1, ddq1, lam1 = q.copy(), dq.copy(), ddq.copy(), lam.copy()
    size = kernel.correct(q1, dq1, ddq1, lam1, beta_p, gamma_p, factorization)
    d = np.concatenate([q - q1, (lam - lam1) / beta_p])
    scale = np.abs(A).max() * np.abs(d).max() + max(np.abs(v).max() for v in (inertia, F, coupling, r))
    assert np.abs(A @ d - r).max() <= 1e3 * EPS * scale
    assert size == pytest.approx(np.abs(q - q1).max(), rel=1e-12)
    np.testing.assert_allclose(dq - dq1, gamma_p * (q - q1), rtol=1e-9, atol=1e-12 * np.abs(dq).max())
    np.testing.assert_allclose(ddq - ddq1, beta_p * (q - q1), rtol=1e-9, atol=1e-12 * np.abs(ddq).max())


@pytest.mark.parametrize("scene, overrides, latched", CASES)
def test_an_rk4_step_is_the_reference_step(scene, overrides, latched, monkeypatch):
    model, q, v, Q, latches = generic_inputs(scene, overrides, latched, 2)
    h = 1e-5
    state = State(0.0123, q, v, np.zeros_like(q), np.zeros_like(q), np.zeros(model.constraint_count), latches, {})
    assert kernel_for(model) is not None           # the compiled step runs
    compiled = RK4().step(model, state, h, Q)
    monkeypatch.setattr(step_kernel, "kernel_for", lambda model: None)
    reference = RK4().step(model, state, h, Q)
    for name in ("q", "dq", "ddq", "multipliers"):
        value, expected = getattr(compiled, name), getattr(reference, name)
        np.testing.assert_allclose(value, expected, rtol=0, atol=1e-12 * max(np.abs(expected).max(initial=0), 1.0),
                                   err_msg=name)


def run(scene, compiled, steps, monkeypatch, overrides=()):
    """A StructureSolver of the scene stepped `steps` times 1 ms in still air on the compiled or the numpy path:
    (E, Newton iterations)."""
    with monkeypatch.context() as patch:
        if not compiled:
            patch.setattr(step_kernel, "kernel_for", lambda model: None)
        solver = StructureSolver(StructureUnitSpec.from_scene(load_scene(SCENES / f"{scene}.toml", overrides)))
        Q = np.zeros(len(solver.e))
        for k in range(1, steps + 1):
            solver.advance(k * 1e-3, Q)
        integrator = solver.integrator
        return solver.e.copy(), integrator.newton_iterations if isinstance(integrator, GeneralizedAlpha) else None


@pytest.mark.parametrize("scene, steps", [("deploy_flexible", 40), ("rotating_beam", 40), ("spin_up", 40),
                                          ("deploy_rigid", 300), ("cantilever_large_deflection", 40)])
def test_runs_match_the_numpy_path(scene, steps, monkeypatch):
    E, iterations = run(scene, True, steps, monkeypatch)
    E_reference, iterations_reference = run(scene, False, steps, monkeypatch)
    assert iterations == iterations_reference
    np.testing.assert_allclose(E, E_reference, rtol=0, atol=1e-11 * np.abs(E_reference).max())


@pytest.mark.parametrize("scene, reason", [("two_body_003", "a strain-based model"),
                                           ("scissor_wing_flexible", "a revolute joint whose axis is not a shared "
                                                                     "chord"),
                                           ("flared_wingtip", "axis or sliding constraint rows"),
                                           ("heaving_wing", "no free coordinates")])
def test_other_models_take_the_numpy_path(scene, reason):
    model = model_of(scene)
    assert unsupported(model) == reason
    assert StepKernel.for_model(model, None) is None


def test_numpy_kernels_select_the_numpy_path(monkeypatch):
    monkeypatch.setenv("WINGSIM_KERNELS", "numpy")
    model = model_of("deploy_flexible")
    assert kernel_for(model) is None
    assert StepKernel.for_model(model, IterationLU(len(model.initial_coordinates()), model.constraint_count,
                                                     model.iteration_pattern())) is None


def test_a_factorization_of_the_other_path_is_made_again(monkeypatch):
    # a solver state saved on one path and restored on the other (a process with another $WINGSIM_KERNELS)
    # carries the other path's factorization in the integrator's memory; the step factorizes afresh
    solver = StructureSolver(StructureUnitSpec.from_scene(load_scene(SCENES / "deploy_flexible.toml")))
    Q = np.zeros(len(solver.e))
    solver.advance(2e-3, Q)
    saved = solver.get_state()
    solver.advance(3e-3, Q)
    compiled = solver.e.copy()
    solver.set_state(saved)
    integrator = solver.integrator
    assert integrator.memory[0][1].__class__ is step_kernel.Factorization
    monkeypatch.setattr(step_kernel, "kernel_for", lambda model: None)    # the numpy path from here on
    solver.advance(3e-3, Q)
    np.testing.assert_allclose(solver.e, compiled, rtol=0, atol=1e-11 * np.abs(compiled).max())


@pytest.mark.parametrize("scene, overrides, latched", CASES)
def test_index1_accelerations_are_the_reference(scene, overrides, latched, monkeypatch):
    # the probes' accelerations and the integrators' initial ones: integrators.constrained_accelerations
    model, q, v, Q, latches = generic_inputs(scene, overrides, latched, 3)
    compiled = integrators.constrained_accelerations(model, 0.0123, q, v, Q, latches)
    monkeypatch.setattr(step_kernel, "kernel_for", lambda model: None)
    reference = integrators.constrained_accelerations(model, 0.0123, q, v, Q, latches)
    for value, expected in zip(compiled, reference):
        np.testing.assert_allclose(value, expected, rtol=0, atol=1e-12 * max(np.abs(expected).max(initial=0), 1.0))


@pytest.mark.parametrize("kind", ["acceleration", "displacement"])
def test_the_compiled_predictor_is_the_numpy_one_bit_for_bit(kind):
    # a compiled step allowed no iteration returns its predictor (and a = a_known + (1 - alpha_f) / (1 - alpha_m) q'')
    model = model_of("deploy_flexible")
    rng = np.random.default_rng(4)
    q, dq, ddq, lam = generic_state(model, rng)
    state = State(0.01, q, dq, ddq, rng.standard_normal(len(q)), lam, {}, {})
    alpha, h = GeneralizedAlpha(0.8), 2e-4
    am, af, g, b = alpha.alpha_m, alpha.alpha_f, alpha.gamma, alpha.beta
    coefficients = (af, am, 1 - am, (1 - af) / (1 - am), h * (1 - g), h * g, h, h * h * (0.5 - b), h * h * b,
                    -(0.5 - b) / b, 1 - af)
    control = (1e8, 1e4, 1e-9, 10.0, 1.0, 0.0, 0, float(kind == "displacement"))
    status, compiled, iterations, *_ = kernel_for(model).alpha_step(state, coefficients, control, None)
    q_p, dq_p, ddq_p, a_known = alpha._predictor(state, h, kind)
    assert (status, iterations) == (5, 0)
    for value, expected in zip(compiled, (q_p, dq_p, ddq_p, a_known + (1 - af) / (1 - am) * ddq_p, lam)):
        assert np.array_equal(value, expected)


@pytest.mark.parametrize("scene, overrides, latched", CASES)
def test_a_state_is_evaluated_as_the_numpy_path_does(scene, overrides, latched):
    # solver.StructureSolver's checks and outputs: E, dE, the fold angles, the largest constraint residual
    model = model_of(scene, overrides)
    q, dq, _, _ = generic_state(model, np.random.default_rng(5))
    E, dE, angles, residual = kernel_for(model).evaluate(q, dq, 0.0123)
    E_reference, dE_reference, _ = model.coordinates(q, dq, 0.0123)
    for value, expected in ((E, E_reference), (dE, dE_reference)):
        np.testing.assert_allclose(value, expected, rtol=0, atol=4 * EPS * np.abs(expected).max())
    assert angles == pytest.approx(model.fold_angles(q, E_reference), rel=0, abs=1e-14)
    assert residual == pytest.approx(model.constraint_violation(q, E_reference), rel=1e-12, abs=1e-15)


def test_a_model_and_its_kernel_are_freed_together():
    # a unit instantiated and freed again and again (a host's instantiate/free cycles) leaves no model behind
    import gc
    import weakref
    model = model_of("deploy_flexible")
    assert kernel_for(model) is not None
    alive = weakref.ref(model)
    del model
    gc.collect()
    assert alive() is None
