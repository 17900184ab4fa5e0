"""Sliders: a node kept on a fixed line or plane. A ladder (a uniform bar) whose foot slides on the floor and
whose top slides on the wall, released from rest, against its one-degree-of-freedom equation of motion:
(m L^2 / 3) theta'' = -m g (L / 2) cos(theta), theta the angle from the floor (the bar's rotational inertia about
its centre m L^2 / 12 plus that of its centre, which moves on a circle of radius L / 2), solved by scipy."""
import numpy as np
import pytest
from scipy.integrate import solve_ivp

from fmu_common.errors import SceneError
from fmu_common.specs import StructureUnitSpec
from orchestrator.scene.load import resolve_scene
from structure_fmu.solver import StructureSolver

LENGTH, START, G = 2.0, np.radians(60.0), 9.81


def ladder(fidelity="rigid", heading=0.0, **slider):
    """The ladder scene: its top at (0, 0, L sin theta_0) on the wall line x = y = 0 (along z), its foot at
    L cos theta_0 (cos psi, sin psi, 0) on the floor line through it along (cos psi, sin psi, 0), psi = `heading`
    (rad); a stiff explicit section for the flexible case."""
    top = [0.0, 0.0, LENGTH * np.sin(START)]
    along = np.array([np.cos(heading), np.sin(heading), 0.0])
    span = (np.cos(START) * along + [0.0, 0.0, -np.sin(START)]).tolist()
    return resolve_scene({
        "time": {"stop": 0.5},
        "structure": {"fidelity": fidelity, "integrator": "rk4", "step": 1e-4, "gravity": [0.0, 0.0, -G],
                      "elements_per_body": 2,
                      "bodies": [{"name": "ladder", "length": LENGTH, "root": top, "span_axis": span,
                                  "chord_axis": [-along[1], along[0], 0.0],
                                  "section": {"chord": 0.05, "torsional_rigidity": 1e6, "axial_stiffness": 1e9,
                                              "bending_stiffness_flap": 1e6, "bending_stiffness_chord": 1e6,
                                              "mass_per_length": 2.0}}],
                      "joints": [{"type": "slider", "name": "wall", "body": "ladder", "line": [0, 0, 1]},
                                 {"type": "slider", "name": "floor", "body": "ladder", "span": LENGTH,
                                  "line": along.tolist(), **slider}]},
        "probes": [{"name": "foot", "body": "ladder", "span": LENGTH}],
    }, "ladder")


def foot_reference(times):
    """x (m) of the foot, L cos(theta(t)), from the one-degree-of-freedom equation (module docstring)."""
    rhs = lambda t, y: [y[1], -1.5 * G / LENGTH * np.cos(y[0])]
    solution = solve_ivp(rhs, (0.0, times[-1]), [START, 0.0], t_eval=times, rtol=1e-12, atol=1e-12, method="DOP853")
    return LENGTH * np.cos(solution.y[0])


@pytest.mark.parametrize("fidelity, tolerance", [("rigid", 1e-8), ("flexible", 1e-5)])
def test_a_ladder_slides_down_as_its_one_dof_model(fidelity, tolerance):
    """The rigid ladder to 1e-8 m (RK4 at 1e-4 s); the flexible (stiff) one within 1e-5 m of the rigid model."""
    scene = ladder(fidelity)
    if fidelity == "flexible":
        scene["structure"]["integrator"] = "generalized-alpha"
    solver = StructureSolver(StructureUnitSpec.from_scene(scene))
    times = np.linspace(0.0, 0.5, 11)
    foot = []
    for t in times:
        solver.advance(t)
        foot.append(solver.sensors.positions(solver.e)[0])
        assert solver.monitors()["constraint_residual"] < 1e-9
    foot = np.array(foot)
    np.testing.assert_allclose(foot[:, 0], foot_reference(times), atol=tolerance)
    assert np.abs(foot[:, 2]).max() < 1e-9 and np.abs(foot[:, 1]).max() < 1e-9     # on the floor line


@pytest.mark.parametrize("floor, scalars", [({}, 1), ({"line": None, "plane_normal": [0.0, 0.0, 1.0]}, 2)])
def test_a_fixed_slider_on_an_oblique_line_or_a_plane_is_a_coordinate_not_a_row(floor, scalars):
    """The flexible ladder turned 35 deg about the wall, its foot on the oblique floor line (or anywhere on the
    floor plane z = 0): each slider's node is its start plus free scalars along the line (one) or the plane (two),
    so the model solves only the nodes' own rows (3 nodes: 3 r_x . r_y and 3 |r_y|, Otsuka et al. 2019, Eq. 6) on
    27 - 2 (the wall) - (3 - scalars) coordinates; the foot stays on the floor to round-off and its distance from
    the wall is L cos(theta) of the one-degree-of-freedom model within 1e-5 m (the stiff bar's deflection)."""
    heading = np.radians(35.0)
    scene = ladder("flexible", heading, **floor)
    scene["structure"]["integrator"] = "generalized-alpha"
    solver = StructureSolver(StructureUnitSpec.from_scene(scene))
    assert solver.model.constraint_count == 6
    assert len(solver.state.q) == 27 - 2 - (3 - scalars)
    times = np.linspace(0.0, 0.5, 11)
    foot = []
    for t in times:
        solver.advance(t)
        foot.append(solver.sensors.positions(solver.e)[0])
    foot = np.array(foot)
    along = np.array([np.cos(heading), np.sin(heading), 0.0])
    np.testing.assert_allclose(foot @ along, foot_reference(times), atol=1e-5)
    assert np.abs(foot[:, 2]).max() < 1e-12
    if scalars == 1:       # on the line: no component across it
        assert np.abs(foot @ [-along[1], along[0], 0.0]).max() < 1e-12


def test_a_slider_needs_exactly_one_of_line_and_plane():
    with pytest.raises(SceneError, match=r"structure\.joints\.floor\.line"):
        ladder(plane_normal=[0, 0, 1])


def test_a_slider_is_refused_in_the_strain_based_fidelity_naming_it():
    with pytest.raises(SceneError, match=r"structure\.joints\.wall\.type"):
        StructureSolver(StructureUnitSpec.from_scene(ladder("strain-based")))
