"""Damping (Otsuka et al. 2019, Sec. II.C with the velocity restored): of deformation only (zero for rigid motion,
Otsuka et al. 2019, Sec. IV), or mass-proportional on all motion (structure.damping_model)."""
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from structure_fmu.damping import deformation_damping_force, deformation_damping_matrix
from fmu_common.specs import StructureUnitSpec
from structure_fmu.element import mass_matrix
from fmu_common.scene_schema import resolve_scene
from structure_fmu.solver import StructureSolver

RNG = np.random.default_rng(3)
ALPHA = 2.5


def body(nodes=4, length=0.3):
    """A bent, rotated beam body: coordinates E (9 m,) and its assembled mass matrix (9 m, 9 m)."""
    R = Rotation.from_rotvec([0.3, -0.8, 1.1]).as_matrix()
    s = np.linspace(0, length, nodes)
    r = np.stack([s, 0.02 * s**2, np.zeros_like(s)], 1)
    x = np.stack([np.ones_like(s), 0.04 * s, np.zeros_like(s)], 1)
    x /= np.linalg.norm(x, axis=1, keepdims=True)
    y = np.cross([0, 0, 1.0], x)
    E = (np.stack([r, x, y], 1) @ R.T).ravel()
    l = length / (nodes - 1)
    M = np.zeros((9 * nodes, 9 * nodes))
    for k, m in enumerate(mass_matrix(np.full(nodes - 1, l), np.full(nodes - 1, 0.14), np.full(nodes - 1, 0.01),
                                      np.full(nodes - 1, 3e-5))):
        M[9 * k:9 * k + 18, 9 * k:9 * k + 18] += m
    return E, M


def rigid_rates(E, velocity, omega):
    nodes = E.reshape(-1, 3, 3)
    rates = np.cross(omega, np.stack([nodes[:, 0] - nodes[0, 0], nodes[:, 1], nodes[:, 2]], 1))
    rates[:, 0] += velocity
    return rates.ravel()


def test_rigid_motion_is_not_damped():
    E, M = body()
    dE = rigid_rates(E, np.array([0.3, -1.0, 2.0]), np.array([4.0, -2.0, 7.0]))
    assert np.max(np.abs(deformation_damping_force(E, dE, M, ALPHA))) < 1e-12 * np.max(np.abs(M @ dE))


def test_clamped_body_gets_alpha_M_de_and_damping_dissipates():
    E, M = body()
    dE = RNG.standard_normal(E.size)
    dE[:9] = 0.0                           # root at rest: every motion is deformation
    F = deformation_damping_force(E, dE, M, ALPHA)
    np.testing.assert_allclose(F[9:], -ALPHA * (M @ dE)[9:], rtol=1e-12, atol=1e-14)
    dE = RNG.standard_normal(E.size)       # any motion: non-positive power
    assert dE @ deformation_damping_force(E, dE, M, ALPHA) <= 0.0


def test_matrix_free_force_equals_the_tangent_matrix_form():
    E, M = body()
    dE = RNG.standard_normal(E.size)
    np.testing.assert_allclose(deformation_damping_force(E, dE, M, ALPHA),
                               -deformation_damping_matrix(E, M, ALPHA) @ dE, rtol=1e-10, atol=1e-12)


@pytest.mark.parametrize("model", ["deformation", "mass-proportional"])
def test_spinning_free_plate_keeps_or_loses_its_spin_as_the_damping_model_says(model):
    """A free flexible plate spinning in its own plane. Mass-proportional damping (-alpha M de on all
    coordinates, Otsuka et al. 2019, Sec. II.C / Otsuka et al. 2022, Sec. 5 as written) is a drag -alpha v dm on
    every mass element, so the angular momentum decays as exp(-alpha t) and so does the spin; deformation
    damping leaves the rigid spin alone (Otsuka et al. 2019, Sec. IV)."""
    omega0, alpha = 2.0, 1.5
    solver = StructureSolver(StructureUnitSpec.from_scene(resolve_scene({"time": {"stop": 1.0}, "structure": {
        "fidelity": "flexible", "elements_per_body": 2, "integrator": "generalized-alpha", "step": 1e-3,
        "damping_model": model,
        "bodies": [{"name": "plate", "length": 0.6, "span_axis": [1, 0, 0], "chord_axis": [0, 1, 0],
                    "angular_velocity": [0.0, 0.0, omega0], "damping": alpha,
                    "section": {"chord": 0.1, "thickness": 0.01, "density": 2700.0, "youngs_modulus": 70e9,
                                "torsional_rigidity": 50.0}}],
        "joints": []}}, "spinning_plate")))
    solver.advance(1.0)
    spin = np.linalg.norm(solver.de[3:6])            # |d r_x / dt| of the root node, r_x a unit vector
    expected = omega0 * np.exp(-alpha * 1.0) if model == "mass-proportional" else omega0
    assert spin == pytest.approx(expected, rel=1e-4)
