"""Steady vortex-lattice method with a flat horseshoe wake (Otsuka et al. 2019, Sec. V) against closed-form and
reference values. The wing is a prescribed-fidelity structure scene (tests/units/test_prescribed.py): one flat
rectangular body, span along y, chord along x (n = r_x x r_y = -z), at a static angle of attack from the
motion's alpha_deg (nose up toward n), in a free stream along +x.

Lattice sizes (M chordwise x N spanwise) and why: the ring lattice is exact in 2D for any M; in 3D the
lift slope of these wings converges like 1/N in the span (measured for AR 4: 3.6878, 3.6484, 3.6284,
3.6183 at M = 4, N = 32..256, the differences halving; cosine spacing changed them by < 0.1%) and hardly
depends on M (M = 4, 8, 16 at N = 512 differ by 0.07%), so we take M = 8 and N = 128, 256 and also check
the Richardson extrapolation 2 CL(256) - CL(128). Measured (alpha = 1 deg): AR 4: 3.6305, 3.6205 ->
3.6104; AR 8: 4.6067, 4.5955 -> 4.5844 per radian, i.e. the converged lattice lies 1.4% and 1.0% below
the issue's reference values 3.66 and 4.63, inside its 2% tolerance. An independent loop-based planar VLM
(horseshoe wake in the wing plane) reproduced our values to O(alpha^2).
"""
import numpy as np
import pytest

from aero_fmu import biot_savart
from aero_fmu.lattice import Lattice
from fmu_common.specs import StructureUnitSpec
from fmu_common.wing_spec import StructureSpec
from fmu_common.specs import AeroUnitSpec
from aero_fmu.vlm import SteadyVLM, bound_segments, ring_segments, steady_lift
from fmu_common.scene_schema import resolve_scene
from fmu_common.vectors import rotation_about
from structure_fmu.solver import StructureSolver
from fmu_common.topology import Topology
from repository import SCENES

RHO, SPEED = 1.2, 10.0
U = np.array([SPEED, 0.0, 0.0])


def wing_scene(aspect_ratio, alpha_deg=0.0, chord=1.0, fidelity="prescribed", elements=1):
    body = {"name": "wing", "length": aspect_ratio * chord, "span_axis": [0, 1, 0], "chord_axis": [1, 0, 0],
            "section": {"chord": chord, "thickness": 0.01, "density": 100.0, "youngs_modulus": 1e9,
                        "torsional_rigidity": 1.0}}
    structure = {"fidelity": fidelity, "bodies": [body]}
    if fidelity == "prescribed":
        structure["motion"] = {"alpha_deg": alpha_deg, "pitch_axis_position": 0.25}
    else:
        structure["elements_per_body"] = elements
    return resolve_scene({"time": {"stop": 1.0}, "structure": structure}, "wing")


def wing_at(aspect_ratio, alpha_deg, chord=1.0):
    """(topology, E) of the prescribed wing at t = 0 (the pitch law holds alpha from the start)."""
    solver = StructureSolver(StructureUnitSpec.from_scene(wing_scene(aspect_ratio, alpha_deg, chord)))
    return solver.topology, solver.e


def lift_slope(aspect_ratio, M, N, alpha_deg=1.0):
    """C_L / alpha (1/rad). CL is odd in alpha; the O(alpha^2) bias at 1 degree is about 4e-4."""
    top, E = wing_at(aspect_ratio, alpha_deg)
    CL, _, _ = steady_lift(top, E, M, N, U, RHO)
    return CL / np.radians(alpha_deg)


def test_lift_slope_of_a_very_slender_wing_is_two_pi():
    """AR = 1000, M = 4, N = 100: thin-airfoil theory gives dCL/dalpha = 2 pi in 2D; the finite span lowers
    it by about 2 (1 + tau) / AR (lifting line), a few tenths of a percent. Required: within 1% of 2 pi."""
    slope = lift_slope(1000, 4, 100)
    assert slope == pytest.approx(2 * np.pi, rel=0.01)
    assert slope < 2 * np.pi


@pytest.mark.parametrize("aspect_ratio, reference", [(4, 3.66), (8, 4.63)])
def test_lift_slope_of_rectangular_wings(aspect_ratio, reference):
    """Rectangular flat wings of AR 4 and 8: converged lifting-surface lift slopes 3.66 and 4.63 per radian
    required within 2%. M = 8, N = 128 and 256 (1024 and 2048 panels); the Richardson
    extrapolation 2 CL(256) - CL(128) (first-order convergence in N) must be within 2% too, and the two
    grids must agree within 0.5% (converged)."""
    coarse = lift_slope(aspect_ratio, 8, 128)
    fine = lift_slope(aspect_ratio, 8, 256)
    extrapolated = 2 * fine - coarse
    assert abs(fine / coarse - 1) < 0.005
    assert fine == pytest.approx(reference, rel=0.02)
    assert extrapolated == pytest.approx(reference, rel=0.02)


def test_rotating_the_wing_or_the_flow_gives_the_same_solution():
    """The wake follows the free stream, so pitching the wing by alpha (structure motion) and pitching the
    flow by -alpha about the same axis are the same configuration: equal CL and circulations to 1e-10.
    Also: a flexible 4-element model of the same undeformed wing gives the prescribed 1-element result
    (every lattice point is mapped to its own element)."""
    alpha = 3.0
    top, E = wing_at(4, alpha)
    CL, gamma, _ = steady_lift(top, E, 4, 12, U, RHO)
    top0, E0 = wing_at(4, 0.0)
    pivot_axis = -np.array([0.0, 1.0, 0.0])             # the motion pitches about -x0 (topology.py)
    U_rotated = rotation_about(pivot_axis, -np.radians(alpha)) @ U
    CL0, gamma0, _ = steady_lift(top0, E0, 4, 12, U_rotated, RHO)
    assert CL0 == pytest.approx(CL, rel=1e-10)
    np.testing.assert_allclose(gamma0, gamma, rtol=1e-10, atol=1e-12 * np.abs(gamma).max())
    flexible = Topology.from_spec(StructureSpec.from_scene(wing_scene(4, fidelity="flexible", elements=4)))
    CL4, gamma4, _ = steady_lift(flexible, flexible.initial_coordinates(), 4, 12, U_rotated, RHO)
    assert CL4 == pytest.approx(CL0, rel=1e-12)
    np.testing.assert_allclose(gamma4, gamma0, rtol=1e-10, atol=1e-12 * np.abs(gamma).max())


def test_pressure_forces_agree_with_kutta_joukowski():
    """Otsuka et al. 2019, Eqs. (23), (25) (pressure jump from the circulation gradient, normal to the panel) against
    rho Gamma V x dl on the bound segments: the lifts agree to O(alpha^2) (cos^2 alpha of the normal
    pressure force vs. the free-stream-normal Kutta-Joukowski force); at 1 degree within 1e-3. The total
    lift is positive along the wing normal side, with positive circulations."""
    top, E = wing_at(4, 1.0)
    vlm = SteadyVLM(top, 4, 16)
    solution = vlm.solve(E, U, RHO)
    kj = vlm.segment_forces(solution, U, RHO).sum(axis=0)
    normal = np.array([0.0, 0.0, -1.0])
    assert solution.lift > 0 and np.all(solution.gamma > 0)
    assert kj @ normal == pytest.approx(solution.lift, rel=1e-3)
    assert solution.forces.sum(axis=0) @ normal == pytest.approx(solution.lift, rel=1e-3)


def test_zero_flow_speed_gives_zero_force_and_no_nan():
    """Still air is legal (deployment at 0 m/s): Gamma = 0, forces = 0, C_L = 0, with no floating-point
    exception raised anywhere (no 0/0 in the wake direction, the lift axis or C_L)."""
    top, E = wing_at(4, 2.0)
    with np.errstate(all="raise"):
        CL, gamma, forces = steady_lift(top, E, 4, 8, np.zeros(3), RHO)
    assert CL == 0.0
    assert np.all(gamma == 0.0) and np.all(forces == 0.0)


def test_single_ring_far_field_is_a_dipole():
    """A plane vortex ring of circulation Gamma and area A is, far away, a doublet of moment
    m = Gamma A e (e by the right-hand rule of the circulation): v = (3 (m . R^) R^ - m) / (4 pi R^3), error
    O((h/R)^2). Our ring (1 x 1 lattice, side h = 0.1 m) circulates (i, j) -> (i+1, j) -> ..., so e = -n:
    checked at R = 100 h in several directions to 1e-3."""
    h = 0.1
    top = Topology.from_spec(StructureSpec.from_scene(wing_scene(1, chord=h)))
    lattice = Lattice(top, 1, 1)
    geometry = lattice.geometry(top.initial_coordinates())
    ring = bound_segments(ring_segments(lattice), geometry.corners)
    centre = geometry.corners.mean(axis=0)
    m = -h * h * geometry.normal[0]
    directions = np.array([[0, 0, 1], [1, 0, 0], [0, 1, 0], [1, 2, -2], [-3, 1, 0.5]], dtype=float)
    R = 100 * h * directions / np.linalg.norm(directions, axis=1, keepdims=True)
    v = biot_savart.influence(centre + R, ring.starts, ring.ends, ring.weights)[:, :, 0]
    r = np.linalg.norm(R, axis=1, keepdims=True)
    dipole = (3 * (R @ m)[:, None] * R / r**2 - m) / (4 * np.pi * r**3)
    np.testing.assert_allclose(v, dipole, rtol=0, atol=1e-3 * np.abs(dipole).max())


def test_wake_length_and_matrix_reuse():
    """A finite flat wake converges to the semi-infinite one (the starting vortex 50 chords behind changes
    C_L by less than 1e-3 relative). `SteadyVLM` keeps the bound influence matrix while E is unchanged and
    the LU while the flow direction is unchanged too: a new speed reuses both, and the result scales."""
    top, E = wing_at(4, 1.0)
    CL_inf, _, _ = steady_lift(top, E, 4, 16, U, RHO)
    CL_50, _, _ = steady_lift(top, E, 4, 16, U, RHO, wake_length=50.0)
    assert CL_50 == pytest.approx(CL_inf, rel=1e-3) and CL_50 != CL_inf
    vlm = SteadyVLM(top, 4, 16)
    first = vlm.solve(E, U, RHO)
    bound, full = vlm._bound[1], vlm._full[1]
    second = vlm.solve(E.copy(), 2 * U, RHO)
    assert vlm._bound[1] is bound and vlm._full[1] is full
    assert second.CL == pytest.approx(first.CL, rel=1e-12)
    np.testing.assert_allclose(second.gamma, 2 * first.gamma, rtol=1e-12)
    vlm.solve(E, U + [0, 0, 1.0], RHO)
    assert vlm._bound[1] is bound and vlm._full[1] is not full


def test_scene_wake_length_inf_is_the_semi_infinite_flat_wake():
    """aero.wake_length = inf (TOML `inf`) passes the scene check, and the uvlm-flat aero unit then has
    semi-infinite horseshoe legs: once steady (second step, fixed wing) its C_L is the steady VLM's with
    semi-infinite legs (`SteadyVLM`, a separate implementation), and differs from the 50-chord wake's."""
    from aero_fmu.solver import AeroSolver
    from orchestrator.scene.load import load_scene

    scene = load_scene(SCENES / "steady_wing.toml", overrides=["aero.wake_length=inf"])
    assert scene["aero"]["wake_length"] == np.inf
    structure = StructureSolver(StructureUnitSpec.from_scene(scene))
    e, de = structure.e, structure.de
    aero = AeroSolver(AeroUnitSpec.from_scene(scene))
    for t in (0.0, 0.01, 0.02):
        aero.advance(t, e, de)
    CL_inf, _, _ = steady_lift(aero.topology, e, 4, 16, aero.U, aero.density)
    CL_50, _, _ = steady_lift(aero.topology, e, 4, 16, aero.U, aero.density, wake_length=50.0)
    assert aero.outputs()["CL"] == pytest.approx(CL_inf, rel=1e-9)
    assert abs(aero.outputs()["CL"] - CL_50) > 1e-6 * CL_inf
