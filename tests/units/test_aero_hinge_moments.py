"""The aerodynamic moment about a hinge's axis (aero_fmu/hinge_moments.py, `AeroSolver.hinge_moments`): the pure
functions against moments and axes worked out by hand; the whole unit against the generalized force Q on a
virtual rotation of the outboard body (virtual work, another path through the code: the lattice's S^T), against
thin-airfoil theory for a slender plate hinged along a spanwise line, and zero in still air."""
import numpy as np
import pytest

from aero_fmu.hinge_moments import HingeLine, hinge_axis, hinge_moment, hinge_moments, panel_selection
from aero_fmu.solver import AeroSolver
from fmu_common.scene_schema import resolve_scene
from fmu_common.vectors import cross
from fmu_common.specs import AeroUnitSpec
from orchestrator.scene.load import load_scene
from repository import SCENES


# --- the pure functions, by hand ----------------------------------------------------------------------------

POINTS = np.array([[1.0, 0.0, 0.0], [0.0, 2.0, 0.0], [0.0, 0.0, 5.0]])
FORCES = np.array([[0.0, 0.0, 2.0], [0.0, 0.0, -1.0], [1.0, 0.0, 0.0]])


@pytest.mark.parametrize("axis, expected", [([1, 0, 0], -3.0), ([0, 1, 0], 3.0), ([0, 0, 1], 1.0),
                                            ([0, -1, 0], -3.0), (np.array([1, 1, 0]) / np.sqrt(2), 0.0)])
def test_the_moment_about_an_axis_is_the_one_worked_by_hand(axis, expected):
    # about x_h = (0, 1, 0): (1,-1,0) x (0,0,2) = (-2,-2,0); (0,1,0) x (0,0,-1) = (-1,0,0); (0,-1,5) x (1,0,0) =
    # (0,5,1); the sum (-3, 3, 1) N m, projected on the axis
    assert hinge_moment(POINTS, FORCES, [0.0, 1.0, 0.0], axis) == pytest.approx(expected, abs=1e-15)


def test_a_point_anywhere_on_the_axis_gives_the_same_moment():
    # moving x_h along a = x changes nothing; moving it off the axis by (0, 0, 1) changes the moment by
    # -a . ((0,0,1) x sum F) = -x . ((0,0,1) x (1,0,1)) = -x . (0,1,0) = 0 here, so move it along y instead:
    # -x . ((0,1,0) x (1,0,1)) = -x . (1,0,-1) = -1
    assert hinge_moment(POINTS, FORCES, [7.0, 1.0, 0.0], [1, 0, 0]) == pytest.approx(-3.0, abs=1e-14)
    assert hinge_moment(POINTS, FORCES, [0.0, 2.0, 0.0], [1, 0, 0]) == pytest.approx(-4.0, abs=1e-14)


def test_the_axis_turns_with_the_parent_tip_frame():
    # the parent's tip node at r = (1, 2, 3) with r_x = 2 (0, 0, 1) (stretched) and r_y = (1, 0, 0): the unit frame
    # x = (0, 0, 1), y = (1, 0, 0), z = x x y = (0, 1, 0); the axis' span, chord, normal components map to them
    e = np.zeros(18)
    e[9:18] = [1, 2, 3, 0, 0, 2, 1, 0, 0]
    for components, expected in [([0, 1, 0], [1, 0, 0]), ([1, 0, 0], [0, 0, 1]), ([0, 0, 1], [0, 1, 0]),
                                 ([1, 1, 0], np.array([1, 0, 1]) / np.sqrt(2))]:
        axis = np.asarray(components, float) / np.linalg.norm(components)
        point, turned = hinge_axis(e, HingeLine("h", 1, 0, axis, np.arange(0)))
        np.testing.assert_allclose(point, [1, 2, 3], rtol=0, atol=0)
        np.testing.assert_allclose(turned, expected, rtol=0, atol=1e-15)
    # with the ground the axis is global and the point the child's root node
    point, turned = hinge_axis(e, HingeLine("h", None, 0, np.array([0.0, 1.0, 0.0]), np.arange(0)))
    np.testing.assert_array_equal(point, [0, 0, 0])
    np.testing.assert_array_equal(turned, [0, 1, 0])


def test_consecutive_panels_are_read_as_a_slice_of_the_same_rows():
    assert panel_selection(np.arange(4, 9)) == slice(4, 9)
    for scattered in (np.array([0, 2, 3]), np.array([3, 2]), np.arange(0)):
        np.testing.assert_array_equal(panel_selection(scattered), scattered)
    rng = np.random.default_rng(5)
    points, forces, e = rng.standard_normal((5, 3)), rng.standard_normal((5, 3)), rng.standard_normal(18)
    axis = np.array([0.3, 0.9, 0.2]) / np.linalg.norm([0.3, 0.9, 0.2])
    by_slice, by_index = (hinge_moments([HingeLine("h", 1, 0, axis, panels)], e, points, forces)["h"]
                          for panels in (panel_selection(np.arange(1, 4)), np.arange(1, 4)))
    assert by_slice == by_index


def test_the_axis_and_the_moment_are_those_of_the_vector_formulas_to_round_off():
    """hinge_axis (on Python floats) and hinge_moment (from the moments sum_p (x_p - x_h) F_p^T) against the
    formulas a0 x + a1 r_y + a2 x cross r_y normalized, and a . sum_p (x_p - x_h) x F_p, written on numpy arrays
    with np.linalg.norm and fmu_common.vectors.cross: the same numbers but for the order of the sums, so within a
    few units of round-off of the terms summed (eps |x_p - x_h| |F_p| each), on random frames, axes and forces."""
    rng = np.random.default_rng(11)
    eps = np.finfo(float).eps
    for _ in range(200):
        e, axis = rng.standard_normal(18) * rng.uniform(0.1, 10.0), rng.standard_normal(3)
        axis /= np.linalg.norm(axis)
        r_x, r_y = e[12:15], e[15:18]
        x = r_x / np.linalg.norm(r_x)
        turned = axis[0] * x + axis[1] * r_y + axis[2] * cross(x, r_y)
        point, unit = hinge_axis(e, HingeLine("h", 1, 0, axis, np.arange(0)))
        np.testing.assert_array_equal(point, e[9:12])
        np.testing.assert_allclose(unit, turned / np.linalg.norm(turned), rtol=0, atol=8 * eps)
        points = rng.standard_normal((int(rng.integers(1, 40)), 3)) * rng.uniform(0.1, 10.0)
        forces = rng.standard_normal((len(points), 3)) * rng.uniform(0.1, 10.0, (len(points), 1))
        arms = points - np.asarray(point)
        reference = float(cross(arms, forces).sum(axis=0) @ np.asarray(unit))
        scale = float(np.sum(np.linalg.norm(arms, axis=1) * np.linalg.norm(forces, axis=1)))
        assert abs(hinge_moment(points, forces, point, unit) - reference) <= 8 * eps * scale


# --- the unit ----------------------------------------------------------------------------------------------

def _solver(scene, **parameters):
    spec = AeroUnitSpec.from_scene(scene)
    values = {name: v[0] for name, v in AeroSolver.tunable_parameters(spec).items()}
    return AeroSolver(spec, {**values, **parameters})


@pytest.mark.parametrize("model", ["uvlm-flat", "uvlm-prescribed", "strip"])
def test_the_hinge_moment_is_the_generalized_force_on_a_rotation_of_the_outboard_body(model):
    """deploy_rigid folded at 170 deg, the flow turned out of the chord: Q . dE = M dtheta for the virtual rotation
    dE of the outer body's nodes about the hinge (dr = a x (r - x_h), dr_x = a x r_x, dr_y = a x r_y), with a and x_h
    taken from the scene's geometry by hand (the inner body clamped along z, chord x; the hinge about its chord at
    its tip z = 0.15 m). Q is the lattice's S^T F (Otsuka et al. 2019, Eq. 12), not the hinge-moment code: they
    agree to round-off."""
    scene = load_scene(SCENES / "deploy_rigid.toml", [f"aero.model={model}"])
    solver = _solver(scene, **{"flow.direction[2]": 0.1, "flow.direction[3]": 0.05})
    e = solver.topology.initial_coordinates()
    for k in (1, 2):
        solver.advance(k * 1e-3, e, np.zeros_like(e))
    a, x_h = np.array([1.0, 0.0, 0.0]), np.array([0.0, 0.0, 0.15])
    dE = np.zeros_like(e)
    for node in solver.topology.bodies["outer"].nodes:
        r, r_x, r_y = e[9 * node:9 * node + 9].reshape(3, 3)
        dE[9 * node:9 * node + 9] = np.concatenate([np.cross(a, r - x_h), np.cross(a, r_x), np.cross(a, r_y)])
    moment = solver.hinge_moments()["fold"]
    assert abs(moment) > 1e-3                         # N m: a real load, not round-off
    assert moment == pytest.approx(float(solver.Q @ dE), rel=1e-12)


def test_still_air_gives_no_hinge_moment():
    scene = load_scene(SCENES / "deploy_rigid.toml")
    solver = _solver(scene, **{"flow.speed": 0.0})
    assert solver.hinge_moments() == {"fold": 0.0}    # before the first step
    e = solver.topology.initial_coordinates()
    solver.advance(1e-3, e, np.zeros_like(e))
    assert solver.hinge_moments() == {"fold": 0.0}


def plate_hinged_along_span(axis_position, model, aspect_ratio=1000.0, chord=1.0):
    """A flat rectangular plate, span along y, chord along x, hinged to the ground about the span axis y through its
    reference line at `axis_position` (fraction of the chord from the leading edge); the prescribed panels of
    test_aero_vlm.py's slender wing (M = 4, N = 100)."""
    section = {"chord": chord, "axis_position": axis_position, "thickness": 0.01, "density": 100.0,
               "youngs_modulus": 1e9, "torsional_rigidity": 1.0}
    body = {"name": "plate", "length": aspect_ratio * chord, "root": [0, 0, 0], "span_axis": [0, 1, 0],
            "chord_axis": [1, 0, 0], "section": section}
    joint = {"type": "revolute", "name": "pitch", "child": "plate", "axis": [0, 1, 0]}
    return resolve_scene({"time": {"stop": 1.0},
                          "structure": {"fidelity": "rigid", "bodies": [body], "joints": [joint]},
                          "aero": {"model": model, "chordwise_panels": 4, "spanwise_panels": 100,
                                   "wake_length": float("inf")},
                          "flow": {"speed": 10.0, "density": 1.2}}, "plate")


@pytest.mark.parametrize("model", ["uvlm-flat", "strip"])
@pytest.mark.parametrize("axis_position", [0.0, 0.5])
def test_a_slender_plate_hinged_along_its_span_carries_its_lift_at_the_quarter_chord(model, axis_position):
    """Thin-airfoil theory: a flat plate at incidence alpha carries the normal force N = q c 2 pi sin(alpha) per
    span at its quarter chord. The plate (AR 1000) meets a flow tilted up by alpha = 3 deg (direction (cos, 0, sin):
    nose up); hinged about +y through the leading edge (axis_position 0) the moment is (c/4 x) x (N z) . y =
    -N c/4, through mid-chord +N c/4. Tolerance 1%, as test_aero_vlm.py's slope of the same slender wing: the
    finite span lowers the lift by about 2 (1 + tau) / AR, a few tenths of a percent (strip theory by its Helmbold
    factor, 0.2%), the tilted flat wake and the normal force by O(alpha^2); the lattice places the 2D centre of
    pressure at c/4 exactly for any M (lumped vortices at the panels' quarter chords). The wake is semi-infinite:
    a 50-chord one would lower the lift by its starting vortex, 1 / 100 of it in 2D. Measured: moment / (-N c/4)
    0.9953 (uvlm-flat, either hinge), 0.9980 (strip); lever arm moment / (the unit's own normal force) c/4 within
    3e-5."""
    alpha = np.radians(3.0)
    chord, span, q = 1.0, 1000.0, 0.5 * 1.2 * 10.0**2
    solver = _solver(plate_hinged_along_span(axis_position, model),
                     **{"flow.direction[1]": np.cos(alpha), "flow.direction[2]": 0.0,
                        "flow.direction[3]": np.sin(alpha)})
    e = solver.topology.initial_coordinates()
    solver.advance(0.01, e, np.zeros_like(e))
    normal_force = q * chord * span * 2 * np.pi * np.sin(alpha)          # N, thin-airfoil theory
    expected = -(0.25 - axis_position) * chord * normal_force            # N m about +y
    moment = solver.hinge_moments()["pitch"]
    assert moment == pytest.approx(expected, rel=0.01), (moment, expected)
    # the lever arm alone, on the unit's own normal force: the centre of pressure at c/4 within the tip effects
    force = solver.panel_forces()[1].sum(axis=0)
    assert moment / force[2] == pytest.approx(-(0.25 - axis_position) * chord, rel=1e-3)
