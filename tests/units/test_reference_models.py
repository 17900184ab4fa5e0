"""The independent reference models of the validation cases (tests/rigid_double_pendulum.py,
tests/finite_segment_chain.py) against conservation laws and closed-form numbers."""
import numpy as np
import pytest
from scipy.linalg import eigh

import finite_segment_chain as chain_model
import rigid_double_pendulum as pendulum

TWO_SECONDS = np.linspace(0.0, 2.0, 201)


@pytest.fixture(scope="module")
def pendulum_runs():
    return {joint: pendulum.simulate(joint, TWO_SECONDS) for joint in pendulum.JOINTS}


@pytest.mark.parametrize("joint", pendulum.JOINTS)
def test_pendulum_conserves_energy_and_vertical_angular_momentum(pendulum_runs, joint):
    run = pendulum_runs[joint]
    assert run.kinetic.max() > 50.0          # J: the bars really fell
    assert np.max(np.abs(run.energy - run.energy[0])) < 1e-8 * run.kinetic.max()
    # gravity along -Y and the pivot's force exert no torque about the vertical axis through the pivot
    spin = np.linalg.norm(run.angular_momentum, axis=1).max()
    assert np.max(np.abs(run.angular_momentum[:, 1])) < 1e-8 * spin


@pytest.mark.parametrize("joint", pendulum.JOINTS)
def test_pendulum_joints_hold(pendulum_runs, joint):
    run = pendulum_runs[joint]
    assert run.point_mismatch.max() < 1e-8
    if joint == "universal":
        assert np.max(np.abs(run.ya_zb)) < 1e-8
        assert np.max(np.abs(run.ya_xb)) > 0.9            # the free product of the cross does swing
    if joint == "revolute":
        assert run.revolute_axis.max() < 1e-8
    if joint == "ball":
        assert run.revolute_axis.max() > 0.5              # nothing holds B's orientation


@pytest.mark.parametrize("joint", pendulum.JOINTS)
def test_pendulum_starts_with_the_hand_derived_tip_acceleration(joint):
    """From rest, A turns about Z and B about X; F is the pin force on B along +Y. The ball joint leaves B's
    spin about its own axis (Z) free; the universal and revolute joints make B spin with A about Z, adding B's
    axial inertia m a^2 / 6 to A's: (I_O + I_s) alpha_A = -m g L/2 - F L, m (L alpha_A - L/2 alpha_B) = F - m g,
    I_c alpha_B = F L/2, and the tip accelerates along Y by L (alpha_A - alpha_B)."""
    L, a, g = pendulum.LENGTH, pendulum.SIDE, 9.8
    m = pendulum.DENSITY * a**2 * L
    I_O, I_c = m * L**2 / 3 + m * a**2 / 12, m * L**2 / 12 + m * a**2 / 12
    I_s = 0.0 if joint == "ball" else m * a**2 / 6
    alpha_A, alpha_B, F = np.linalg.solve([[I_O + I_s, 0, L], [m * L, -m * L / 2, -1], [0, I_c, -L / 2]],
                                          [-m * g * L / 2, -m * g, 0])
    t = 1e-3
    moved = np.diff(pendulum.tip_track(joint, [0.0, t]), axis=0)[0]
    assert 2 * moved[1] / t**2 == pytest.approx(L * (alpha_A - alpha_B), rel=1e-5)
    assert np.abs(moved[[0, 2]]).max() < 1e-4 * abs(moved[1])


def test_pendulum_refuses_an_unknown_joint():
    with pytest.raises(ValueError, match="'hinge'"):
        pendulum.tip_track("hinge", TWO_SECONDS)


@pytest.mark.parametrize("bodies", [1, 2])
def test_chain_newton_euler_accelerations_equal_the_mass_matrix_ones(bodies):
    c = chain_model.chain(7, bodies=bodies)
    rng = np.random.default_rng(3)
    theta, omega = rng.normal(size=c.size), 3 * rng.normal(size=c.size)
    lagrange = chain_model.lagrange_accelerations(c, theta, omega)
    assert np.max(np.abs(chain_model.accelerations(c, theta, omega) - lagrange)) < 1e-10 * np.abs(lagrange).max()


def observed_orders(segments, errors):
    return np.log2(np.abs(errors[:-1] / errors[1:])) / np.log2(np.asarray(segments[1:]) / segments[:-1])


SEGMENTS = [10, 20, 40, 80]


def static_cantilever_errors(clamp_factor):
    """Linear static tip deflection (m) of body A alone under its weight, minus q L^4 / (8 EI)."""
    q = chain_model.RHO_A * chain_model.GRAVITY
    exact = q * chain_model.LENGTH**4 / (8 * chain_model.EI)
    errors = []
    for n in SEGMENTS:
        c = chain_model.chain(n, bodies=1, clamp_factor=clamp_factor)
        theta = np.linalg.solve(c.K, -chain_model.GRAVITY * c.w)     # the gravity moments about theta = 0
        errors.append(-(c.l @ theta) / exact - 1)                      # linear: Z_tip = sum l theta
    return np.array(errors)


def test_chain_static_cantilever_converges_to_q_L4_over_8EI_at_second_order():
    errors = static_cantilever_errors(2.0)
    assert abs(errors[-1]) < 2e-4
    assert observed_orders(SEGMENTS, errors) == pytest.approx(2.0, abs=0.01)
    # the clamp spring of EI / l instead of 2 EI / l only converges at first order
    assert observed_orders(SEGMENTS, static_cantilever_errors(1.0))[-1] == pytest.approx(1.0, abs=0.05)


def test_chain_first_bending_frequency_converges_to_euler_bernoulli():
    exact = 1.8751040687**2 * np.sqrt(chain_model.EI / (chain_model.RHO_A * chain_model.LENGTH**4))  # rad/s
    errors = []
    for n in SEGMENTS:
        c = chain_model.chain(n, bodies=1, rho_i=0.0)
        # gravity adds no stiffness about the straight line: d2/dtheta2 of g w sin(theta) vanishes at 0
        lowest = eigh(c.K, chain_model.mass_matrix(c, np.zeros(c.size)), eigvals_only=True, subset_by_index=[0, 0])
        errors.append(np.sqrt(lowest[0]) / exact - 1)
    errors = np.array(errors)
    assert abs(errors[-1]) < 1e-4
    assert observed_orders(SEGMENTS, errors) == pytest.approx(2.0, abs=0.02)


def test_chain_two_body_run_conserves_energy():
    c = chain_model.chain(8)
    times = np.linspace(0.0, 5.0, 101)
    states = chain_model.simulate(c, times)
    n = c.size
    energies = np.array([chain_model.energy(c, y[:n], y[n:]) for y in states.T])
    kinetic = np.array([0.5 * y[n:] @ chain_model.mass_matrix(c, y[:n]) @ y[n:] for y in states.T])
    assert kinetic.max() > 100.0
    assert np.max(np.abs(energies - energies[0])) < 1e-7 * kinetic.max()
    assert chain_model.free_end(c, states[:n])[1].min() < -10.0     # B swung down through the hinge


def test_richardson_recovers_a_known_limit_and_order():
    segments = np.array([5, 10, 20, 40])
    limit, order, _ = chain_model.richardson(segments, 3.0 + 2.0 / segments**2)
    assert (limit, order) == (pytest.approx(3.0, abs=1e-12), pytest.approx(2.0, abs=1e-9))
    limit, _, error = chain_model.richardson(segments, 3.0 + 2.0 / segments**2 + 5.0 / segments**3)
    assert 0 < abs(limit - 3.0) <= error
    with pytest.raises(ValueError, match="twice"):
        chain_model.richardson([5, 10, 30], [1.0, 0.5, 0.25])


def test_chain_rms_converges_at_second_order_on_coarse_chains():
    """The faster sibling of the slow extrapolation below."""
    result = chain_model.extrapolated_rms((3, 6, 12))
    print(result)
    assert result.order == pytest.approx(2.0, abs=0.3)


@pytest.mark.slow
def test_chain_rms_extrapolates_with_a_small_error():
    result = chain_model.extrapolated_rms()
    print(result)
    assert result.order == pytest.approx(2.0, abs=0.02)
    assert result.error < 1e-6 * result.value
