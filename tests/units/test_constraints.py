"""The constraint Jacobian on the free coordinates, the constraint rate and the velocity term, each
against finite differences of the residual Phi (exact for these quadratic constraints up to round-off)."""
import numpy as np
import pytest

from orchestrator.scene.load import load_scene
from structure_fmu.solver import StructureSolver
from fmu_common.specs import StructureUnitSpec
from repository import SCENES


@pytest.mark.parametrize("scene", ["deploy_rigid", "deploy_flexible", "rotating_beam"])
def test_jacobian_rate_and_velocity_term_match_finite_differences(scene):
    # rotating_beam has fixed-plane rows and a prescribed (moving) root; deploy_* have unit and
    # orthogonality rows only
    model = StructureSolver(StructureUnitSpec.from_scene(load_scene(SCENES / f"{scene}.toml"))).model
    cons = model.constraints
    rng = np.random.default_rng(7)
    q0 = model.T.T @ model.top.initial_coordinates()
    q = q0 + 0.1 * rng.standard_normal(q0.size)           # off the constraint manifold: G_q depends on E
    E = model.coordinates(q, np.zeros_like(q), 0.3)[0]
    offset = E - model.T @ q
    phi = lambda x: cons.residual(model.T @ x + offset)
    s = 1e-4
    columns = [(phi(q + s * u) - phi(q - s * u)) / (2 * s) for u in np.eye(q.size)]
    G = cons.jacobian(E)
    assert G.shape == (cons.count, q.size)
    assert np.allclose(G, np.array(columns).T, rtol=0, atol=1e-9)

    dE = rng.standard_normal(E.size)
    along = lambda k: cons.residual(E + k * s * dE)
    assert np.allclose(cons.rate(E, dE), (along(1) - along(-1)) / (2 * s), rtol=0, atol=1e-8)
    assert np.allclose(cons.velocity_quadratic(dE, E), (along(1) - 2 * along(0) + along(-1)) / s**2,
                       rtol=1e-6, atol=1e-6)
