"""Sliders on another body: a node kept on a line or plane carried by the frame of a node of another body
(structure_fmu.pins.add_sliders, joint_rows.SlidingRow).

On a clamped body the carried line is a fixed line, so the motion equals that of the fixed-line slider along the
same global line. On a spinning rod, a bead's distance r from the axis obeys r'' = omega(t)^2 r: the rod pushes
on the bead only across the rod, so nothing acts along it in the rotating frame but the centrifugal force (a
frictionless bead; the derivation and the bound it leaves are in `test_a_bead_slides_out_along_a_spinning_rod`).
"""
import numpy as np
import pytest
from scipy.integrate import solve_ivp

from fmu_common.errors import SceneError
from fmu_common.specs import StructureUnitSpec
from fmu_common.vectors import perpendiculars, rotation_about
from orchestrator.scene.load import resolve_scene
from structure_fmu.solver import StructureSolver

PROJECTION_TOLERANCE = 1e-13
"""m: RK4 projects q onto Phi = 0 until max |Phi| is below this (`integrators.project`)."""

# ----------------------------------------------------------------------------------------------- a clamped frame

FRAME = rotation_about(np.array([1.0, 2.0, 2.0]) / 3.0, 0.7)
"""The clamped body's initial (span, chord, normal) as columns: a frame along no global axis."""
COMPONENTS = np.array([2.0, -1.0, 2.0]) / 3.0
"""The slider's line (or plane normal) in that frame's span, chord, normal components."""
AXIS = FRAME @ COMPONENTS
"""The same direction in global components."""
GRAVITY = 9.81 * (AXIS + perpendiculars(AXIS)[0]) / np.sqrt(2.0)
"""m/s^2: half along the line and half across it (for a plane: half across it, half along it)."""
SECTION = {"chord": 0.1, "torsional_rigidity": 50.0, "axial_stiffness": 1e6, "bending_stiffness_flap": 30.0,
           "bending_stiffness_chord": 200.0, "mass_per_length": 1.5}
"""A bar soft enough to bend: as a 1 m cantilever it would sag m g L^3 / (8 EI) = 0.06 m under its weight."""


def guided_bar(fidelity="rigid", kind="line", carried=True, stop=0.5, **slider):
    """A clamped body `frame` and a free bar whose root slides on a line (or plane) through its start, carried by
    the frame's node at `other_span` (`carried`) or fixed in space along the same global direction; the bar starts
    turning (angular_velocity) so that it moves in three dimensions."""
    guide = {"type": "slider", "name": "guide", "body": "bar", "span": 0.0}
    if carried:
        guide.update({kind: COMPONENTS.tolist(), "other": "frame", **slider})
    else:
        guide[kind] = AXIS.tolist()
    integrator = "rk4" if fidelity == "rigid" else "generalized-alpha"
    return resolve_scene({
        "time": {"stop": stop},
        "structure": {"fidelity": fidelity, "integrator": integrator, "step": 1e-3, "gravity": GRAVITY.tolist(),
                      "elements_per_body": 2,
                      "bodies": [{"name": "frame", "length": 0.5, "root": [0.3, -0.2, 0.5],
                                  "span_axis": FRAME[:, 0].tolist(), "chord_axis": FRAME[:, 1].tolist(),
                                  "section": SECTION},
                                 {"name": "bar", "length": 1.0, "root": [0.4, 0.1, 0.2], "span_axis": [0.0, 0.6, -0.8],
                                  "chord_axis": [1.0, 0.0, 0.0], "angular_velocity": [1.0, 0.5, -0.3],
                                  "section": SECTION}],
                      "joints": [{"type": "clamp", "body": "frame"}, guide]},
        "probes": [{"name": "root", "body": "bar", "span": 0.0}, {"name": "tip", "body": "bar", "span": 1.0},
                   {"name": "edge", "body": "bar", "span": 1.0, "chord": 0.0}],
    }, "guided_bar")


def probe_history(scene, times):
    """Probe positions (n_times, n_probes, 3), m, at `times`."""
    solver = StructureSolver(StructureUnitSpec.from_scene(scene))
    history = []
    for t in times:
        solver.advance(t)
        history.append(solver.sensors.positions(solver.e))
    return np.array(history)


@pytest.mark.parametrize("kind", ["line", "plane_normal"])
@pytest.mark.parametrize("fidelity, stop, other_span", [("rigid", 1.0, 0.5), ("flexible", 0.5, 0.0)])
def test_a_line_of_a_clamped_body_is_the_fixed_line_along_it(fidelity, stop, other_span, kind):
    """The same motion of the bar to 1e-9 m with the line (plane) carried by the clamped body as with the fixed
    one. A rigid body's frame is the same at every node (here its tip); a flexible one's is fixed at its clamped
    root only."""
    times = np.linspace(0.0, stop, 11)
    carried = probe_history(guided_bar(fidelity, kind, True, stop, other_span=other_span), times)
    fixed = probe_history(guided_bar(fidelity, kind, False, stop), times)
    np.testing.assert_allclose(carried, fixed, rtol=0.0, atol=1e-9)
    root = carried[:, 0] - carried[0, 0]
    across = np.cross(root, AXIS) if kind == "line" else root @ AXIS
    assert np.abs(across).max() < 1e-9                                  # on the line (plane) through its start
    assert np.linalg.norm(root[-1]) > 0.1                               # and it moved along it


# ----------------------------------------------------------------------------------------------- a spinning rod

SPIN, RAMP = 4.0, 0.25        # rad/s, s: the rod's final rate omega_s and the spin-up time T_s
START = 0.2                   # m, the bead's distance from the axis at t = 0
BEAD_LENGTH = 0.1             # m, l: the length of the bead's body B
BEAD_MASS, BODY_MASS = 1.0, 1e-8     # kg: M lumped at B's root, m_B spread along B
STOP = 0.5                    # s


def spin_rate(t):
    """omega(t) (rad/s) and omega'(t) (rad/s^2) of the spin-up law, Otsuka et al. 2019, Eq. (27), written out here
    apart from motion.SpinUp: the derivatives of theta = omega_s / T_s [t^2 / 2 + (T_s / 2 pi)^2
    (cos(2 pi t / T_s) - 1)] up to T_s, omega_s after."""
    t = np.asarray(t, float)
    c = 2.0 * np.pi / RAMP
    ramping = t < RAMP
    rate = np.where(ramping, SPIN / RAMP * (t - np.sin(c * t) / c), SPIN)
    return rate, np.where(ramping, SPIN / RAMP * (1.0 - np.cos(c * t)), 0.0)


def bead_on_rod():
    """The rod (rigid, root at the origin, span along x) driven about its chord axis y through its root; the bead
    B (rigid) with its root at x = START on the rod's span, its span along z, the mass M lumped at that root,
    which slides along the rod's span. No gravity."""
    section = lambda mass_per_length: {"chord": 0.1, "torsional_rigidity": 1.0, "axial_stiffness": 1.0,
                                       "bending_stiffness_flap": 1.0, "bending_stiffness_chord": 1.0,
                                       "mass_per_length": mass_per_length}
    return resolve_scene({
        "time": {"stop": STOP},
        "structure": {"fidelity": "rigid", "integrator": "rk4", "step": 1e-3, "gravity": [0.0, 0.0, 0.0],
                      "bodies": [{"name": "rod", "length": 1.0, "root": [0.0, 0.0, 0.0], "span_axis": [1.0, 0.0, 0.0],
                                  "chord_axis": [0.0, 1.0, 0.0], "section": section(1.0)},
                                 {"name": "bead", "length": BEAD_LENGTH, "root": [START, 0.0, 0.0],
                                  "span_axis": [0.0, 0.0, 1.0], "chord_axis": [1.0, 0.0, 0.0],
                                  "section": section(BODY_MASS / BEAD_LENGTH)}],
                      "joints": [{"type": "driven", "body": "rod", "omega": SPIN, "ramp_time": RAMP},
                                 {"type": "slider", "name": "on_rod", "body": "bead", "line": [1.0, 0.0, 0.0],
                                  "other": "rod"}],
                      "masses": [{"body": "bead", "mass": BEAD_MASS}]},
        "probes": [{"name": "bead", "body": "bead", "span": 0.0}],
    }, "bead_on_rod")


def test_a_bead_slides_out_along_a_spinning_rod():
    """r(t) against r'' = omega(t)^2 r, r(0) = START, r'(0) = 0 (scipy DOP853), within the bound below; the
    constraint residual at the projection's tolerance.

    Why r'' = omega^2 r, and how closely. The rod's span e turns about the axis: e' = omega n, n' = -omega e. The
    bead's point is P = r e; B's centre of mass is at rho = (l / 2) b from P (b: B's span); the whole of B, centre
    of mass R_c = r e + mu rho with mu = m_B / (M + m_B), is pushed by the rod only across e (the slider's rows
    are normal to the line), so e . R_c'' = 0. Its coordinate s = e . R_c along the rod then obeys
        s'' = omega^2 s + g,   g = mu (omega' n . rho + 2 omega n . rho' - 2 omega^2 e . rho),
    and r = s - mu e . rho; at t = 0, rho is normal to e and all is at rest: s(0) = START, s'(0) = 0, the
    reference's start. So |g| <= mu (l / 2) (|omega'| + 2 omega^2 + 2 omega |b'|). B swings about P as a pendulum
    in the field -a_P, |a_P| <= A: its kinetic energy about P, T >= (m_B l^2 / 6) |b'|^2, grows at most as
    m_B A (l / 2) |b'|, so sqrt(T) <= A t sqrt(6 m_B) / 4 and |b'| <= 3 A t / (2 l). The Green's function of
    y'' = omega(t)^2 y is at most sinh(omega_s (t - tau)) / omega_s (omega <= omega_s), hence
        |r - r_ref| <= G (cosh(omega_s t) - 1) / omega_s^2 + mu l / 2,
        G = mu [(l / 2) (max |omega'| + 2 omega_s^2) + (3 / 2) omega_s A t].
    a_P = (r'' - omega^2 r) e + (2 r' omega + r omega') n; A is 1.01 times the reference's largest
    |2 r' omega + r omega'|, the 1% standing for the line part and for the simulated r, r' in place of the
    reference's (both differences of order mu). With m_B = 1e-8 M the bound is below 1e-7 m; RK4's own error at
    this step, of fourth order, is orders of magnitude smaller."""
    times = np.linspace(0.0, STOP, 21)
    fine = np.linspace(0.0, STOP, 5001)
    rhs = lambda t, y: [y[1], spin_rate(t)[0] ** 2 * y[0]]
    reference = solve_ivp(rhs, (0.0, STOP), [START, 0.0], method="DOP853", rtol=1e-12, atol=1e-14,
                          max_step=RAMP / 20, dense_output=True)
    r_ref = reference.sol(times)[0]
    r_fine, dr_fine = reference.sol(fine)
    rate, rate_change = spin_rate(fine)
    transverse = 1.01 * np.abs(2.0 * dr_fine * rate + r_fine * rate_change).max()
    mu = BODY_MASS / (BEAD_MASS + BODY_MASS)
    half = BEAD_LENGTH / 2.0
    forcing = mu * (half * (2.0 * SPIN / RAMP + 2.0 * SPIN**2) + 1.5 * SPIN * transverse * times)
    bound = forcing * (np.cosh(SPIN * times) - 1.0) / SPIN**2 + mu * half

    solver = StructureSolver(StructureUnitSpec.from_scene(bead_on_rod()))
    rod_root = solver.topology.bodies["rod"].nodes[0]
    r = []
    for t in times:
        solver.advance(t)
        span = solver.e.reshape(-1, 3, 3)[rod_root, 1]                 # e, the rod's r_x
        r.append(solver.sensors.positions(solver.e)[0] @ span)
        assert solver.monitors()["constraint_residual"] <= PROJECTION_TOLERANCE
    assert bound.max() < 1e-7 and r_ref[-1] > 2.0 * START               # a bound far below the travel
    assert np.all(np.abs(np.array(r) - r_ref) <= bound)


# ----------------------------------------------------------------------------------------------- bad input

@pytest.mark.parametrize("fidelity, slider, key", [
    ("rigid", {"other_span": 0.3}, "other_span"),                        # the frame's nodes are at 0 and 0.5 m
    ("flexible", {"other_span": 0.3}, "other_span"),                     # at 0, 0.25 and 0.5 m
    ("rigid", {"other": "bar"}, "other"),                   # a rigid bar's line moves with its own node
    ("rigid", {"other": "bar", "other_span": 1.0}, "other"),
    ("flexible", {"other": "bar"}, "other_span"),                        # the bar's root on its own root's line
    ("strain-based", {}, "type"),
])
def test_a_bad_slider_on_a_body_is_refused_naming_the_key(fidelity, slider, key):
    with pytest.raises(SceneError, match=rf"structure\.joints\.guide\.{key}\b"):
        StructureSolver(StructureUnitSpec.from_scene(guided_bar(fidelity, **slider)))
