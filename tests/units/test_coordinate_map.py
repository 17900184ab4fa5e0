"""The structure model's gathered coordinate map (structure_fmu.coordinate_map) against the dense products it
replaces: E = T q + P p, T^T F, generalized-alpha's reduced tangent T^T (K + H + gamma' C) T + beta' M_q, and the
constraint Jacobian G T against complex-step derivatives of the constraints, on random states of scenes with every
kind of map: shared slots, a slider's direction, rigid bodies' combined slots, prescribed motion, pins, joint axis
rows, hinges, both damping models, the shear-deformable element."""
from pathlib import Path

import numpy as np
import pytest

from fmu_common.specs import StructureUnitSpec
from orchestrator.scene.load import load_scene
from structure_fmu import coordinate_map
from structure_fmu.coordinate_map import CoordinateMap
from structure_fmu.solver import StructureSolver

SCENES = Path(__file__).resolve().parents[2] / "scenes"
CASES = {
    "deploy_flexible": [],                                          # hinge actuator, mass-proportional damping
    "deploy_wind_tunnel_2019": [],                                  # deformation damping of two bodies
    "spin_up": [],                                                  # prescribed root motion
    "rotating_beam": [],                                            # linear (pin) rows
    "scissor_wing": [],                                             # rigid: slots combining coordinates, rows left out
    "scissor_wing_flexible": [],                                    # a slider: weights other than 1
    "flared_wingtip": [],                                           # joint axis rows
    "shear_deformable": ["structure.fidelity=shear-deformable"],    # Peng et al. 2019's element
}
SCENE_OF = {"shear_deformable": "deploy_flexible"}


@pytest.fixture(params=["as chosen", "gathers"])
def route(request, monkeypatch):
    """Each map applied as its size chooses (dense products below DENSE_ENTRIES), then by gathers at every size."""
    if request.param == "gathers":
        monkeypatch.setattr(coordinate_map, "DENSE_ENTRIES", 0)
    return request.param


def _model(case):
    scene = load_scene(SCENES / f"{SCENE_OF.get(case, case)}.toml", ["time.stop=0.001", *CASES[case]])
    return StructureSolver(StructureUnitSpec.from_scene(scene)).model


def _state(model, seed):
    rng = np.random.default_rng(seed)
    q0 = model.initial_coordinates()
    q = q0 + 0.05 * rng.standard_normal(len(q0))
    return q, rng.standard_normal(len(q0)), rng.standard_normal(model.constraint_count), rng


def _relative(value, reference):
    return np.abs(value - reference).max(initial=0.0) / max(np.abs(reference).max(initial=0.0), np.finfo(float).tiny)


@pytest.mark.parametrize("case", CASES)
def test_gathered_coordinates_and_forces_are_the_dense_products(case, route):
    """E, dE, p'', the reduced force and the accelerations of E against T q + P p and T^T F - T^T M_E P p''."""
    model = _model(case)
    q, dq, _, rng = _state(model, 1)
    t = 0.37
    p, dp, ddp = model.prescribed(t)
    E, dE, _ = model.coordinates(q, dq, t)
    assert _relative(E, model.T @ q + model.P @ p) <= 1e-15
    assert _relative(dE, model.T @ dq + model.P @ dp) <= 1e-15
    Q = rng.standard_normal(model.n)
    F = model.force_q(q, dq, t, Q, {})[0]
    reference = model.T.T @ model.force_E(E, dE, t, Q, {}) - model.mass_prescribed @ ddp
    assert _relative(F, reference) <= 1e-12
    ddq = rng.standard_normal(len(q))
    assert _relative(model.acceleration_E(q, dq, ddq, t), model.T @ ddq + model.P @ ddp) <= 1e-15


@pytest.mark.parametrize("latched", [False, True])
@pytest.mark.parametrize("case", CASES)
def test_reduced_tangent_is_the_dense_congruence(case, latched):
    """iteration_matrix assembled into (n_q, n_q) against T^T (K_E + sum lambda_i H_i + gamma' C_E) T + beta' M_q
    formed densely from tangent_E and the constraints' hessian_sum, latched and free hinges."""
    model = _model(case)
    q, dq, lam, _ = _state(model, 2)
    latches = {h.name: latched for h in model.hinges}
    beta_p, gamma_p, t = 3.1e5, 4.2e2, 0.21
    S, E = model.iteration_matrix(t, q, dq, latches, lam, beta_p, gamma_p)
    E_ref, dE, _ = model.coordinates(q, dq, t)
    K, C = model.tangent_E(E_ref, dE, latches)
    multipliers = np.zeros(model.constraints.count)
    multipliers[model._rows if model._rows is not None else slice(None)] = lam
    if model.constraints.count:
        K = K + model.constraints.hessian_sum(multipliers, E_ref)
    reference = model.T.T @ (K + gamma_p * C) @ model.T + beta_p * model.mass_q
    assert np.array_equal(E, E_ref)
    assert _relative(S, reference) <= 1e-12


@pytest.mark.parametrize("case", [*CASES, "double_pendulum"])
def test_constraint_jacobian_is_the_complex_step_derivative(case):
    """G_q = dPhi/dq by complex steps along each column of T (exact to round-off for these polynomial rows),
    also for the strain-based model, which shares the constraints."""
    if case == "double_pendulum":
        scene = load_scene(SCENES / "double_pendulum.toml", ["time.stop=0.001"])
        model = StructureSolver(StructureUnitSpec.from_scene(scene)).model
        E = model.top.initial_coordinates() + 0.05 * np.random.default_rng(3).standard_normal(model.n)
        T = model.T
    else:
        model = _model(case)
        q, dq, _, _ = _state(model, 3)
        E, _, _ = model.coordinates(q, dq, 0.0)
        T = model.T
    step = 1e-30
    reference = np.stack([model.constraints.residual(E + 1j * step * T[:, k]).imag / step
                          for k in range(T.shape[1])], axis=1)
    assert _relative(model.constraints.jacobian(E), reference) <= 1e-12


def test_map_of_a_general_T(route):
    """A T with several entries per row, repeated columns and prescribed (zero) rows: every operation against
    the dense products."""
    rng = np.random.default_rng(4)
    T = rng.standard_normal((12, 5)) * (rng.random((12, 5)) < 0.3)
    T[3] = 0.0
    T[7] = T[2]
    cmap = CoordinateMap(T)
    q, F, offset = rng.standard_normal(5), rng.standard_normal(12), rng.standard_normal(12)
    X = rng.standard_normal((12, 12))
    assert _relative(cmap.apply(q, offset), T @ q + offset) <= 1e-15
    assert _relative(cmap.transpose_apply(F), T.T @ F) <= 1e-15
    assert _relative(cmap.congruence(X), T.T @ X @ T) <= 1e-14
    idx = np.array([2, 7, 9])
    block = rng.standard_normal((3, 3))
    sparse = np.zeros((12, 12))
    sparse[np.ix_(idx, idx)] = block
    assembly = cmap.assembly(idx[:, None] * 12 + idx[None, :])
    assert _relative(cmap.reduce(assembly, block), T.T @ sparse @ T) <= 1e-14
