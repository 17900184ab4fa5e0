"""The one-degree-of-freedom scissor-array reference (tests/scissor_mechanism.py) against a brute-force kinetic
energy of the bars, the work of the loads measured on the geometry, and the travel time by quadrature of the
energy integral."""
import numpy as np
import pytest
from scipy.integrate import quad

import scissor_mechanism as scissor

L, M, F = 1.0, 2700.0 * 1.0 * 0.02 * 0.005, 50.0       # m, kg (aluminium 20 x 5 mm), N
ROTARY = M * 0.02**2 / 12                                # kg m: rho I of the 20 mm side turning in the plane
# A tilted frame: d, h_ax and their normal, an origin off zero, and gravity with a part out of the plane.
D = np.array([0.8, 0.5, 0.33]) / np.linalg.norm([0.8, 0.5, 0.33])
H = np.cross([0.2, -0.1, 1.0], D)
H /= np.linalg.norm(H)
NORMAL = np.cross(D, H)
ORIGIN = np.array([0.3, -1.2, 0.7])
GRAVITY = -2.0 * D - 6.0 * H + 7.0 * NORMAL                 # m/s^2
RUN = dict(L=L, m=M, F=F, gravity=GRAVITY, d=D, h_ax=H, rotary=ROTARY)


def bars(theta, n, L=L, origin=ORIGIN, d=D, h=H):
    """(start, end) of every bar (m, world), written from the SLE definitions: up_i from origin + i w d to
    origin + (i+1) w d + H h, down_i from origin + i w d + H h to origin + (i+1) w d."""
    w, height = L * np.cos(theta), L * np.sin(theta)
    out = []
    for i in range(n):
        out.append((origin + i * w * d, origin + (i + 1) * w * d + height * h))
        out.append((origin + i * w * d + height * h, origin + (i + 1) * w * d))
    return out


def brute_force_inertia(theta, n, rotary, step=1e-5):
    """2 T at theta' = 1 rad/s (kg m^2): the bars' mass spread along their length, each material point's velocity
    by a central difference of its position in theta, 1/2 m int_0^1 |v(s)|^2 ds by 3-point Gauss-Legendre (exact
    for the quadratic |v(s)|^2), plus 1/2 rho I L omega^2 with omega the difference of the bar's angle in the
    plane."""
    nodes, weights = np.polynomial.legendre.leggauss(3)
    s, weights = (nodes + 1) / 2, weights / 2

    def material(theta):
        return [(p + s[:, None] * (q - p), np.arctan2((q - p) @ H, (q - p) @ D)) for p, q in bars(theta, n)]

    total = 0.0
    for (x1, a1), (x0, a0) in zip(material(theta + step), material(theta - step)):
        v, omega = (x1 - x0) / (2 * step), (a1 - a0) / (2 * step)
        total += 0.5 * M * weights @ np.sum(v * v, axis=1) + 0.5 * rotary * L * omega**2
    return 2 * total


def measured_work(theta, theta0, n, gravity=GRAVITY):
    """Work (J) since theta0: F along -h on a_1 (the start of down_0) plus gravity on every bar's centre."""
    now, start = bars(theta, n), bars(theta0, n)
    work = F * -H @ (now[1][0] - start[1][0])
    for (p, q), (p0, q0) in zip(now, start):
        work += M * gravity @ ((p + q) / 2 - (p0 + q0) / 2)
    return work


@pytest.mark.parametrize("n", [1, 2, 3, 5])
def test_points_are_the_pins_of_the_bars(n):
    theta = 0.7
    p = scissor.points(theta, n, L, ORIGIN, D, H)
    assert set(p) == {f"a{k}" for k in range(1, n + 2)} | {f"b{k}" for k in range(1, n + 2)} \
        | {f"c{k}" for k in range(1, n + 1)}
    for i in range(n):
        (up0, up1), (down0, down1) = bars(theta, n)[2 * i: 2 * i + 2]
        assert np.abs(np.array([up0 - p[f"b{i + 1}"], up1 - p[f"a{i + 2}"], down0 - p[f"a{i + 1}"],
                                down1 - p[f"b{i + 2}"]])).max() < 1e-15
        # the mid pivot is the midpoint of both bars, each of length L
        assert np.abs(np.array([(up0 + up1) / 2, (down0 + down1) / 2]) - p[f"c{i + 1}"]).max() < 1e-15
        assert np.linalg.norm(up1 - up0) == pytest.approx(L, abs=1e-15)
        assert np.linalg.norm(down1 - down0) == pytest.approx(L, abs=1e-15)
    assert np.abs(p["b1"] - ORIGIN).max() < 1e-15
    assert np.linalg.norm(np.cross(p["a1"] - ORIGIN, H)) < 1e-15             # a_1 on the slider's line
    assert (p["a1"] - ORIGIN) @ H == pytest.approx(L * np.sin(theta), abs=1e-15)
    thetas = np.array([[0.2, 0.5], [0.9, 1.3]])
    assert scissor.points(thetas, n, L, ORIGIN, D, H)[f"a{n + 1}"].shape == (2, 2, 3)


@pytest.mark.parametrize("n", [1, 2, 3, 5])
@pytest.mark.parametrize("rotary", [0.0, ROTARY, 0.4])
def test_inertia_equals_a_brute_force_kinetic_energy(n, rotary):
    for theta in (0.05, 0.4, 0.9, 1.3, 1.5):
        J, _ = scissor.inertia(theta, n, L, M, rotary)
        assert J == pytest.approx(brute_force_inertia(theta, n, rotary), rel=1e-7)


def test_inertia_of_one_sle_is_a_lever_and_a_ladder():
    """n = 1: the up bar turns about b_1 (m L^2 / 3); the down bar's ends slide along d and h, so it turns about
    the corner (w, H) at L / 2 from its centre (m L^2 / 4 + m L^2 / 12): J = 2 m L^2 / 3 at every angle."""
    J, dJ = scissor.inertia(np.linspace(0.1, 1.4, 7), 1, L, M)
    assert np.abs(J - 2 * M * L**2 / 3).max() < 1e-15 and np.abs(dJ).max() == 0.0


@pytest.mark.parametrize("n", [1, 3, 6])
def test_inertia_derivative_is_the_central_difference(n):
    step = 1e-5
    for theta in (0.05, 0.4, 0.9, 1.3, 1.5):
        _, dJ = scissor.inertia(theta, n, L, M, ROTARY)
        difference = (scissor.inertia(theta + step, n, L, M, ROTARY)[0]
                      - scissor.inertia(theta - step, n, L, M, ROTARY)[0]) / (2 * step)
        assert abs(dJ - difference) < 1e-8 * scissor.inertia(theta, n, L, M, ROTARY)[0]


@pytest.mark.parametrize("n", [1, 3])
def test_kinetic_energy_equals_the_work_of_the_force_and_gravity(n):
    theta0 = np.radians(75.0)
    t_end = scissor.time_to_angle(theta0, np.radians(15.0), n, **RUN)
    run = scissor.simulate(theta0, t_end, n, t_eval=np.linspace(0.0, t_end, 41), **RUN)
    assert run.stop is None and run.theta[-1] == pytest.approx(np.radians(15.0), rel=1e-9)
    energies = scissor.energy(run.theta, run.dtheta, theta0, n, **RUN)
    work = np.array([measured_work(theta, theta0, n) for theta in run.theta])
    assert energies.kinetic.max() > 5.0
    assert np.abs(energies.kinetic - work).max() < 1e-10 * energies.kinetic.max()
    assert np.abs(energies.balance).max() < 1e-10 * energies.kinetic.max()
    assert np.abs(energies.work_force + energies.work_gravity - work).max() < 1e-12 * energies.kinetic.max()
    assert np.abs(scissor.slider_travel(run.theta, theta0, L) * F - energies.work_force).max() == 0.0


@pytest.mark.parametrize("gravity", [(0.0, 0.0, 0.0), 9.81 * NORMAL])
def test_without_force_or_in_plane_gravity_the_array_stays_at_rest(gravity):
    run = scissor.simulate(1.1, 2.0, 3, L, M, 0.0, gravity=gravity, d=D, h_ax=H, t_eval=np.linspace(0, 2, 11))
    assert np.abs(run.theta - 1.1).max() < 1e-15 and np.abs(run.dtheta).max() < 1e-15 and run.stop is None


@pytest.mark.parametrize("n", [1, 3])
def test_the_start_from_rest_accelerates_at_Q_over_J(n):
    """From rest theta''' = 0, so theta(t) - theta0 = (Q/J) t^2 / 2 + c t^4 + O(t^6): the samples at t and 2 t
    give Q/J = (16 dtheta(t) - dtheta(2 t)) / (6 t^2), and likewise (8 theta'(t) - theta'(2 t)) / (6 t). Q by a
    central difference of the work measured on the geometry, J by the brute-force kinetic energy."""
    theta0, step, t = 1.2, 1e-5, 2e-3
    Q = (measured_work(theta0 + step, theta0, n) - measured_work(theta0 - step, theta0, n)) / (2 * step)
    expected = Q / brute_force_inertia(theta0, n, ROTARY)
    run = scissor.simulate(theta0, 2 * t, n, t_eval=[0.0, t, 2 * t], **RUN)
    moved = run.theta - theta0
    assert (16 * moved[1] - moved[2]) / (6 * t**2) == pytest.approx(expected, rel=1e-7)
    assert (8 * run.dtheta[1] - run.dtheta[2]) / (6 * t) == pytest.approx(expected, rel=1e-7)
    assert 2 * moved[1] / t**2 == pytest.approx(expected, rel=1e-3)     # the t^2 term dominates


def quadrature_time(theta0, theta1, n, gravity=GRAVITY):
    """t = int sqrt(J / (2 W)) dtheta from theta1 to theta0 (the energy integral J theta'^2 / 2 = W from rest);
    W ~ (theta0 - theta) near the start, so theta = theta0 - u^2 makes the integrand 2 u sqrt(J / (2 W)) smooth."""
    def integrand(u):
        theta = theta0 - u * u
        return 2 * u * np.sqrt(brute_force_inertia(theta, n, ROTARY) / (2 * measured_work(theta, theta0, n, gravity)))
    value, _ = quad(integrand, 0.0, np.sqrt(theta0 - theta1), epsabs=0, epsrel=1e-12, limit=200)
    return value


@pytest.mark.parametrize("n", [1, 3])
def test_the_deployment_time_equals_the_energy_quadrature(n):
    theta0, theta1 = np.radians(75.0), np.radians(10.0)
    expected = quadrature_time(theta0, theta1, n)
    assert scissor.time_to_angle(theta0, theta1, n, **RUN) == pytest.approx(expected, rel=1e-9)
    run = scissor.simulate(theta0, expected, n, t_eval=[expected], **RUN)
    assert run.theta[-1] == pytest.approx(theta1, rel=1e-8)


def test_the_integration_stops_cleanly_at_the_flat_and_the_folded_configurations():
    theta0 = np.radians(20.0)
    run = scissor.simulate(theta0, 10.0, 3, t_eval=np.linspace(0, 10, 1001), **RUN)
    assert run.stop == "flat" and run.theta.min() >= 0.0 and run.t[-1] <= run.stop_time < run.t[-1] + 0.01
    assert run.stop_time == pytest.approx(quadrature_time(theta0, 0.0, 3), rel=1e-9)
    # gravity pulling a_1 away from b_1 (along +h) and no force: the array folds up
    rising = scissor.simulate(1.0, 10.0, 3, L, M, 0.0, gravity=9.81 * H, d=D, h_ax=H)
    assert rising.stop == "folded" and rising.theta[-1] == pytest.approx(np.pi / 2, abs=1e-12)
    assert rising.stop_time == pytest.approx(rising.t[-1], abs=1e-15)
    assert scissor.simulate(1.0, 0.1, 3, **RUN).stop is None


@pytest.mark.parametrize("call, word", [
    (lambda: scissor.simulate(0.0, 1.0, 3, **RUN), "theta0"),
    (lambda: scissor.simulate(np.pi / 2, 1.0, 3, **RUN), "theta0"),
    (lambda: scissor.simulate(1.0, 0.0, 3, **RUN), "t_end"),
    (lambda: scissor.simulate(1.0, 1.0, 0, **RUN), "n "),
    (lambda: scissor.simulate(1.0, 1.0, 2.5, **RUN), "n "),
    (lambda: scissor.simulate(1.0, 1.0, 3, **{**RUN, "L": -1.0}), "L must"),
    (lambda: scissor.simulate(1.0, 1.0, 3, **{**RUN, "m": 0.0}), "m must"),
    (lambda: scissor.simulate(1.0, 1.0, 3, **{**RUN, "F": -5.0}), "F must"),
    (lambda: scissor.simulate(1.0, 1.0, 3, **{**RUN, "rotary": -1.0}), "rotary"),
    (lambda: scissor.simulate(1.0, 1.0, 3, **{**RUN, "d": 2 * D}), "d must be a unit"),
    (lambda: scissor.simulate(1.0, 1.0, 3, **{**RUN, "h_ax": D}), "perpendicular"),
    (lambda: scissor.simulate(1.0, 1.0, 3, **{**RUN, "gravity": (0.0, 9.8)}), "gravity"),
    (lambda: scissor.simulate(1.0, 1.0, 3, t_eval=[0.0, 2.0], **RUN), "t_eval"),
    (lambda: scissor.points(1.0, 3, L, ORIGIN, D, 2 * H), "h_ax"),
])
def test_bad_input_is_refused_naming_the_argument(call, word):
    with pytest.raises(ValueError, match=word):
        call()


def test_an_angle_never_reached_is_an_error():
    with pytest.raises(RuntimeError, match="did not reach"):
        scissor.time_to_angle(1.0, 0.5, 3, L, M, 0.0, t_max=1.0)
