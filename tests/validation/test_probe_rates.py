"""Probe velocities and accelerations as a run records them (timeseries.csv, read back by column name) against
independent numbers: the analytic kinematics of a rigid body in known rotation (omega x r, the tangential
alpha x r and the centripetal omega x (omega x r)), and the time derivatives of the recorded positions and
velocities by central differences at the recording step (Richardson-extrapolated where the integrator is
fourth-order), for RK4 on a rigid pendulum and for generalized-alpha on a flexible beam."""

import numpy as np

from orchestrator.output.results import read_timeseries, write_results
from orchestrator.run.master import run_scene
from orchestrator.scene.load import load_scene
from repository import SCENES

FREE_SPIN = """
name = "free_spin"
[time]
stop = 0.3
[coupling]
step = 1e-3
[structure]
fidelity = "rigid"
integrator = "rk4"
step = 1e-4
[[structure.bodies]]
name = "bar"
length = 1.0
root = [0.2, -0.1, 0.0]
angular_velocity = [0.0, 0.0, 5.0]
section = { chord = 0.05, thickness = 0.01, density = 7800.0, youngs_modulus = 210e9, torsional_rigidity = 1e3 }
[[structure.joints]]
type = "pin"
body = "bar"
axis = "normal"
[[probes]]
name = "tip_le"
body = "bar"
span = 1.0
chord = 0.0
[[probes]]
name = "mid"
body = "bar"
span = 0.4
"""


def recorded(scene, tmp_path):
    """{column: samples} of the run's timeseries.csv, and its header; the run must reach its stop."""
    result = run_scene(scene, backend="direct")
    assert result.status == "ok", result.message
    write_results(result, tmp_path)
    samples, units = read_timeseries(tmp_path / "timeseries.csv")
    return {name: samples[name] for name in samples.dtype.names}, list(samples.dtype.names)


def probe(columns, name, kind=""):
    """(samples, 3) of the columns <name>_<kind>x, _<kind>y, _<kind>z."""
    return np.column_stack([columns[f"{name}_{kind}{axis}"] for axis in "xyz"])


def rigid_rotation(r, axis, omega, alpha):
    """Velocity and acceleration of the points r (samples, 3), m, relative to a point of a fixed axis, of a rigid body
    turning about it at the rate omega (samples,) rad/s and the angular acceleration alpha (samples,) rad/s^2."""
    w, a = np.outer(omega, axis), np.outer(alpha, axis)
    v = np.cross(w, r)
    return v, np.cross(a, r) + np.cross(w, v)


def central(values, h, k=1):
    """d/dt of samples (m, 3) at the spacing h (s) by central differences over +-k samples, at samples k .. m-k-1."""
    return (values[2 * k:] - values[:-2 * k]) / (2 * k * h)


def test_a_freely_spinning_bar_records_omega_cross_r_and_the_centripetal_acceleration(tmp_path):
    """A rigid bar pinned about z at its root, spinning at 5 rad/s without gravity or load: every material point
    turns at constant omega, v = omega x r and a = -omega^2 r (r from the pin); one probe off the reference line
    (the leading edge, 25 mm), one on it. Measured: 5e-12 m/s and 5e-11 m/s^2, the 12 significant digits of the CSV."""
    scene_file = tmp_path / "free_spin.toml"
    scene_file.write_text(FREE_SPIN)
    columns, header = recorded(load_scene(scene_file), tmp_path)
    assert header[1:1 + 18] == [f"{p}_{kind}{axis}" for kind in ("", "v", "a") for p in ("tip_le", "mid")
                                for axis in "xyz"]
    t, pin, omega = columns["time"], np.array([0.2, -0.1, 0.0]), 5.0
    turn = omega * t
    for name, start in (("tip_le", [1.0, -0.025, 0.0]), ("mid", [0.4, 0.0, 0.0])):
        r = np.column_stack([np.cos(turn) * start[0] - np.sin(turn) * start[1],
                             np.sin(turn) * start[0] + np.cos(turn) * start[1], 0 * t])
        v, a = rigid_rotation(r, [0.0, 0.0, 1.0], np.full_like(t, omega), np.zeros_like(t))
        np.testing.assert_allclose(probe(columns, name) - pin, r, rtol=0, atol=1e-9)   # the known rotation
        np.testing.assert_allclose(probe(columns, name, "v"), v, rtol=0, atol=1e-9 * omega)
        np.testing.assert_allclose(probe(columns, name, "a"), a, rtol=0, atol=1e-9 * omega**2)


def test_a_driven_rigid_spin_up_records_the_tangential_and_centripetal_accelerations(tmp_path):
    """scenes/spin_up.toml with rigid bars, generalized-alpha: the beam turns about y by the prescribed
    theta(t) = omega_s / T_s (t^2 / 2 + (T_s / 2 pi)^2 (cos(2 pi t / T_s) - 1)) (Otsuka et al. 2019, Eq. 27),
    differentiated here by hand; the tip (10 m out) has v = theta' y x r and a = theta'' y x r + theta' y x v.
    Measured: equal to the 12 significant digits timeseries.csv carries."""
    scene = load_scene(SCENES / "spin_up.toml", ["structure.fidelity=rigid", "time.stop=6", "coupling.step=0.01"])
    columns, _ = recorded(scene, tmp_path)
    t, (joint,) = columns["time"], scene["structure"]["joints"]
    ws, ts, c = joint["omega"], joint["ramp_time"], 2 * np.pi / joint["ramp_time"]
    theta = ws / ts * (t**2 / 2 + (np.cos(c * t) - 1) / c**2)
    omega, alpha = ws / ts * (t - np.sin(c * t) / c), ws / ts * (1 - np.cos(c * t))
    length = scene["structure"]["bodies"][0]["length"]
    r = length * np.column_stack([np.cos(theta), 0 * t, -np.sin(theta)])   # e_x turned about y by theta
    v, a = rigid_rotation(r, [0.0, 1.0, 0.0], omega, alpha)
    # both terms count: the tangential L theta'' reaches 4.6 m/s^2, the centripetal L theta'^2 15 m/s^2
    assert length * alpha.max() > 4 and length * omega.max()**2 > 10
    for kind, exact in (("", r), ("v", v), ("a", a)):   # the prescribed motion, to the CSV's 12 digits
        np.testing.assert_allclose(probe(columns, "tip", kind), exact, rtol=0, atol=1e-11 * np.abs(exact).max())


def test_a_rigid_pendulum_records_the_derivatives_of_its_positions(tmp_path):
    """scenes/pendulum_rigid.toml from 90 deg, RK4 at 1e-4 s, recorded every 1 ms for 0.5 s (the tip reaches
    5.4 m/s and 29 m/s^2). The Richardson extrapolation (4 D_h - D_2h) / 3 of the central differences of the
    recorded positions (velocities) is the derivative to O(h^4), about h^4 |x^(5)| / 30 < 1e-10 here, and the
    12 significant digits of the CSV add about 1e-9: the recorded velocity (acceleration) must match it to
    1e-7 of its peak (measured 2.6e-10 and 6.4e-10). The plain central difference misses by h^2 |x'''| / 6,
    7e-6 and 1.5e-5 of the peaks: the check tells an O(h^2) error apart."""
    scene = load_scene(SCENES / "pendulum_rigid.toml", ["time.stop=0.5", "coupling.step=1e-3",
                                                         "structure.step=1e-4"])
    columns, _ = recorded(scene, tmp_path)
    h = scene["coupling"]["step"]
    x, v, a = (probe(columns, "tip", kind) for kind in ("", "v", "a"))
    for values, derivative in ((x, v), (v, a)):
        extrapolated = (4 * central(values, h)[1:-1] - central(values, h, 2)) / 3
        peak = np.abs(derivative).max()
        assert np.abs(extrapolated - derivative[2:-2]).max() <= 1e-7 * peak
        assert np.abs(central(values, h) - derivative[1:-1]).max() > 1e-6 * peak   # the check has the resolution


def test_a_flexible_spin_up_records_the_derivatives_of_its_positions(tmp_path):
    """scenes/spin_up.toml (9 flexible elements, generalized-alpha at the scene's 5 ms, rho_inf = 0.8) over 3 s,
    recorded every 5 ms: the recorded velocity is the derivative of the recorded positions within the central
    difference's own error, estimated by the difference between the spans h and 2h (D_2h - D_h is three times
    the O(h^2) error of D_h; measured 7.3e-6 m/s against 1.4e-5 m/s); the recorded acceleration is the
    derivative of the recorded velocity within 1e-3 of its peak (measured 1.4e-4 in isolated spikes, well above
    the O(h^2) error of the difference, 2e-5 m/s^2 against the peak 1.8 m/s^2; a Newton tolerance 1000 times
    tighter halves the spikes: the stopping error of the iteration shows in the accelerations)."""
    scene = load_scene(SCENES / "spin_up.toml", ["time.stop=3", "coupling.step=0.005"])
    columns, _ = recorded(scene, tmp_path)
    h = scene["coupling"]["step"]
    x, v, a = (probe(columns, "tip", kind) for kind in ("", "v", "a"))
    fine, coarse = central(x, h)[1:-1], central(x, h, 2)
    assert np.abs(fine - v[2:-2]).max() <= np.abs(coarse - fine).max()
    assert np.abs(central(v, h) - a[1:-1]).max() <= 1e-3 * np.abs(a).max()
