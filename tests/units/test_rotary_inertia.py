"""The section's rotary inertia rho I_yy (Otsuka et al. 2022, Table 4) in the ANCF mass matrix: the kinetic energy
1/2 rho I_yy int |dr'/dt|^2 dx of a Rayleigh beam, checked on an element against its own integral and a rigid
turn, and on the small oscillations of a rigid bar pendulum."""
import numpy as np
import pytest
from scipy.special import ellipk

from fmu_common.scene_schema import resolve_scene
from fmu_common.specs import StructureUnitSpec
from fmu_common.shape_functions import hermite
from fmu_common.vectors import rotation_about
from structure_fmu import element
from structure_fmu.solver import StructureSolver

ONE = np.ones(1)


def rotary_only(length, rotary):
    """The element mass matrix of the rotary term alone (no translational mass), (18, 18)."""
    zero = np.zeros(1)
    return element.mass_matrix(length * ONE, zero, zero, zero, rotary * ONE)[0]


def test_rotary_term_is_the_integral_of_the_slope_rate():
    """1/2 de^T M de of the rotary term equals 1/2 rho I_yy int_0^l |S' de|^2 dx, the integral taken by a
    200-point midpoint rule of the Hermite slopes."""
    length, rotary = 0.7, 0.3
    rng = np.random.default_rng(2)
    de = rng.standard_normal(18)
    x = (np.arange(200) + 0.5) / 200
    _, dN, _, _ = hermite(x, length)
    v = de.reshape(6, 3)
    slope_rate = dN @ v[[0, 1, 3, 4]]                       # dr'/dt at the points, (200, 3)
    reference = 0.5 * rotary * length * np.mean(np.sum(slope_rate**2, axis=1))
    assert 0.5 * de @ rotary_only(length, rotary) @ de == pytest.approx(reference, rel=1e-4)


def test_rotary_term_of_rigid_turns():
    """A rigid turn at rate omega about an axis across the span (the chord or the normal) has the rotary energy
    1/2 rho I_yy l omega^2; a turn about the span itself (torsion) none. Without the argument the matrix is
    the one of the translational mass alone."""
    length, rotary, omega = 0.4, 0.2, 3.0
    e = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [length, 0, 0], [1, 0, 0], [0, 1, 0]], dtype=float)
    arms = e - np.array([e[0], [0, 0, 0], [0, 0, 0], e[0], [0, 0, 0], [0, 0, 0]])
    M = rotary_only(length, rotary)
    for axis, expected in (([0, 1, 0], 0.5 * rotary * length * omega**2), ([0, 0, 1], 0.5 * rotary * length * omega**2),
                           ([1, 0, 0], 0.0)):
        de = np.cross(omega * np.array(axis, dtype=float), arms).ravel()
        assert 0.5 * de @ M @ de == pytest.approx(expected, abs=1e-14)
    mu = np.array([1.3])
    plain = element.mass_matrix(length * ONE, mu, 0.1 * mu, 0.01 * mu)
    assert np.array_equal(plain, element.mass_matrix(length * ONE, mu, 0.1 * mu, 0.01 * mu, None))
    assert np.array_equal(plain + rotary_only(length, rotary),
                          element.mass_matrix(length * ONE, mu, 0.1 * mu, 0.01 * mu, rotary * ONE))


LENGTH, CHORD, MU, ROTARY, G = 1.0, 0.3, 1.0, 0.05, 9.8
AMPLITUDE = np.radians(1.0)


def pendulum(axis):
    """A rigid bar hanging from a revolute joint to the ground at the origin, along -Z, chord along X, normal
    along -Y (span x chord), reference line at mid-chord (no first moment), displaced by AMPLITUDE about the
    joint's `axis` (the chord X, or the normal -Y) and released; gravity -Z."""
    section = {"chord": CHORD, "torsional_rigidity": 1.0, "axial_stiffness": 1e6, "bending_stiffness_flap": 1.0,
               "bending_stiffness_chord": 1.0, "mass_per_length": MU, "rotary_inertia": ROTARY}
    turn = rotation_about(np.asarray(axis, dtype=float), AMPLITUDE)
    body = {"name": "bar", "length": LENGTH, "root": [0, 0, 0], "span_axis": list(turn @ [0, 0, -1]),
            "chord_axis": list(turn @ [1, 0, 0]), "section": section}
    joint = {"type": "revolute", "name": "pin", "child": "bar", "axis": axis,
             "initial_angle_deg": float(np.degrees(AMPLITUDE))}
    return resolve_scene({"time": {"stop": 1.0}, "structure": {
        "fidelity": "rigid", "integrator": "rk4", "step": 1e-3, "gravity": [0, 0, -G], "bodies": [body],
        "joints": [joint]}}, "pendulum")


@pytest.mark.parametrize("axis, chord_term", [([1, 0, 0], 0.0), ([0, -1, 0], MU * LENGTH * CHORD**2 / 12)],
                         ids=["about_chord", "about_normal"])
def test_rigid_pendulum_period_includes_the_rotary_inertia(axis, chord_term):
    """T = 4 sqrt(I / (m g L/2)) K(sin^2(amplitude/2)) with I = m L^2 / 3 + the chord's m c^2 / 12 (a turn about
    the normal moves the chord; about the chord it does not) + rho I_yy L; the rotary term alone changes T by
    7%. Measured between the fold angle's downward zero crossings over two periods (RK4 at 1 ms)."""
    mass = MU * LENGTH
    inertia = mass * LENGTH**2 / 3 + chord_term + ROTARY * LENGTH
    expected = 4 * np.sqrt(inertia / (mass * G * LENGTH / 2)) * ellipk(np.sin(AMPLITUDE / 2) ** 2)
    solver = StructureSolver(StructureUnitSpec.from_scene(pendulum(axis)))
    times, angles = [0.0], [solver.fold_angles_deg()["pin"]]
    while solver.time < 2.2 * expected:
        solver.advance(solver.time + solver.step_size)
        times.append(solver.time)
        angles.append(solver.fold_angles_deg()["pin"])
    times, angles = np.array(times), np.array(angles)
    i = np.flatnonzero((angles[:-1] > 0) & (angles[1:] <= 0))
    crossings = times[i] + angles[i] / (angles[i] - angles[i + 1]) * (times[i + 1] - times[i])
    assert len(crossings) >= 2
    assert np.diff(crossings).mean() == pytest.approx(expected, rel=1e-8)     # measured 2e-10
