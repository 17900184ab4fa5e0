"""Pins at any node and closed kinematic loops (structure_fmu/pins.py).

A parallelogram four-bar hanging under gravity (two cranks of length L pinned to the ground at O_1 and O_2 = O_1 +
D x, a coupler of length D pinned to both crank tips) has one degree of freedom, the crank angle phi from x: the
cranks turn about their pinned ends (kinetic energy m L^2 phi'^2 / 6 each) and the coupler translates with speed
L phi' (m_c L^2 phi'^2 / 2), so (2 m / 3 + m_c) L^2 phi'' = -(m + m_c) g L cos(phi), solved by scipy. The
coupler's second pin closes the loop: shared coordinates in the flexible fidelity, three rows in the rigid one
(one of them redundant in the plane).
"""
import copy

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from fmu_common.errors import SceneError
from fmu_common.specs import StructureUnitSpec
from fmu_common.wing_spec import StructureSpec
from orchestrator.scene.load import resolve_scene
from structure_fmu.solver import StructureSolver
from structure_fmu.topology import StructureTopology

L, D, G, MU = 0.5, 0.8, 9.81, 2.0          # m, m, m/s^2, kg/m
START = np.radians(-60.0)
SECTION = {"chord": 0.05, "torsional_rigidity": 1e6, "axial_stiffness": 1e9, "bending_stiffness_flap": 1e6,
           "bending_stiffness_chord": 1e6, "mass_per_length": MU}


def four_bar(fidelity="rigid", integrator="rk4"):
    """The hanging parallelogram: cranks from (0, 0, 0) and (D, 0, 0) at phi_0 below x, coupler between their tips;
    every pin about z (the chord of every body)."""
    tip = L * np.array([np.cos(START), np.sin(START), 0.0])
    span = [np.cos(START), np.sin(START), 0.0]
    body = lambda name, length, root, axis: {"name": name, "length": length, "root": list(root), "span_axis": axis,
                                             "chord_axis": [0.0, 0.0, 1.0], "section": dict(SECTION)}
    pin = lambda name, body_name, span=0.0, other=None, other_span=0.0: {
        "type": "pin", "name": name, "body": body_name, "span": span, "other": other, "other_span": other_span}
    return resolve_scene({
        "time": {"stop": 1.0},
        "structure": {"fidelity": fidelity, "integrator": integrator, "step": 1e-4, "gravity": [0.0, -G, 0.0],
                      "elements_per_body": 2, "rho_inf": 1.0,
                      "bodies": [body("left", L, [0, 0, 0], span), body("right", L, [D, 0, 0], span),
                                 body("coupler", D, tip, [1.0, 0.0, 0.0])],
                      "joints": [pin("O1", "left"), pin("O2", "right"), pin("A", "coupler", 0.0, "left", L),
                                 pin("B", "coupler", D, "right", L)]},
        "probes": [{"name": "A", "body": "coupler", "span": 0.0}],
    }, "four_bar")


def crank_reference(times):
    """(x, y) (m) of the left crank's tip, L (cos phi, sin phi), from the one-degree-of-freedom equation."""
    m, m_c = MU * L, MU * D
    rhs = lambda t, y: [y[1], -(m + m_c) * G * L * np.cos(y[0]) / ((2 * m / 3 + m_c) * L**2)]
    phi = solve_ivp(rhs, (0.0, times[-1]), [START, 0.0], t_eval=times, rtol=1e-12, atol=1e-12, method="DOP853").y[0]
    return L * np.column_stack([np.cos(phi), np.sin(phi)])


def pin_nodes(top, scene):
    """(name, node a, node b) of every pin between two bodies."""
    return [(j["name"], top.node_at("", j["body"], j["span"]), top.node_at("", j["other"], j["other_span"]))
            for j in scene["structure"]["joints"] if j["type"] == "pin" and j["other"] is not None]


def shared(top, a, b):
    """Whether the r slots of nodes a and b are the same combination of free and prescribed vectors."""
    return top.slots[3 * a].signature() == top.slots[3 * b].signature()


@pytest.mark.parametrize("fidelity, integrator, tolerance", [
    ("rigid", "rk4", 1e-8), ("rigid", "generalized-alpha", 2e-6), ("flexible", "generalized-alpha", 2e-5)])
def test_a_parallelogram_four_bar_swings_as_its_one_dof_model(fidelity, integrator, tolerance):
    """The loop closed by rows (rigid) or by shared coordinates (flexible, stiff): the crank tip follows the
    pendulum equation over 0.5 s (RK4 to 1e-8 m; generalized-alpha at rho_inf = 1 is second order: 2e-6 m at
    1e-4 s; the stiff flexible bars add their static deflection)."""
    scene = four_bar(fidelity, integrator)
    solver = StructureSolver(StructureUnitSpec.from_scene(scene))
    times = np.linspace(0.0, 0.5, 6)
    tip = []
    for t in times:
        solver.advance(t)
        tip.append(solver.sensors.positions(solver.e)[0])
        assert solver.monitors()["constraint_residual"] < 1e-9
    tip = np.array(tip)
    np.testing.assert_allclose(tip[:, :2], crank_reference(times), atol=tolerance)
    assert np.abs(tip[:, 2]).max() < 1e-12


def test_a_rigid_loop_keeps_one_closing_row_out_and_a_flexible_one_none():
    """Rigid: 3 bodies x (r, r_x) free = 18 coordinates; the ground pins fix two points and the first coupler pin
    moves the coupler's point, so the second closes the loop with three rows of which the out-of-plane one
    repeats the others; 18 - 17 independent rows = 1 degree of freedom. Flexible: every pin is shared."""
    rigid = StructureSolver(StructureUnitSpec.from_scene(four_bar("rigid"))).model
    assert rigid.T.shape[1] - rigid.constraint_count == 1
    assert rigid.constraints.count - rigid.constraint_count == 1
    top = rigid.top
    assert [shared(top, a, b) for _, a, b in pin_nodes(top, four_bar())] == [True, False]
    flexible_scene = four_bar("flexible", "generalized-alpha")
    flexible = StructureSolver(StructureUnitSpec.from_scene(flexible_scene)).model
    assert flexible.constraints.count == flexible.constraint_count
    assert all(shared(flexible.top, a, b) for _, a, b in pin_nodes(flexible.top, flexible_scene))


def test_shared_pivots_coincide_to_round_off_through_a_run():
    """Every pin of a flexible or shear-deformable scissor chain is a shared coordinate: its two nodes coincide to
    1e-12 m while the chain deploys (the rows of the rigid chain's closing pins hold to the projection's 1e-9);
    the shear-deformable chain, whose slider is a coordinate too, has no constraint row."""
    for fidelity, closing in (("flexible", 1e-12), ("shear-deformable", 1e-12), ("rigid", 1e-9)):
        scene = scissor_chain(fidelity)
        solver = StructureSolver(StructureUnitSpec.from_scene(scene))
        top = solver.model.top
        pins = pin_nodes(top, scene)
        if fidelity != "rigid":
            assert all(shared(top, a, b) for _, a, b in pins)
        if fidelity == "shear-deformable":
            assert solver.model.constraint_count == 0
        solver.advance(0.05)
        X = solver.e.reshape(-1, 3)
        for name, a, b in pins:
            bound = 1e-12 if shared(top, a, b) else closing
            assert np.linalg.norm(X[3 * a] - X[3 * b]) < bound, name
        assert np.linalg.norm(X[3 * top.node_at("", "s_down1", 0.0)][0]) < 1e-12    # a_1 on the y axis


def scissor_chain(fidelity="flexible", **chain):
    return resolve_scene({
        "time": {"stop": 0.1},
        "structure": {"fidelity": fidelity, "integrator": "generalized-alpha", "step": 1e-4, "elements_per_body": 2,
                      "scissors": [{"name": "s", "count": 2, "bar_length": 1.0, "initial_angle_deg": 60.0,
                                    "start_lower": "pin", "start_upper": "slide_across",
                                    "section": {"chord": 0.005, "thickness": 0.02, "density": 2700.0,
                                                "youngs_modulus": 70e9, "torsional_rigidity": 18.3}, **chain}],
                      "loads": [{"body": "s_down1", "span": 0.0, "force": [0.0, -50.0, 0.0]}]},
    }, "chain")


def test_a_loop_that_does_not_close_is_refused_naming_the_pin_and_the_gap():
    scene = copy.deepcopy(four_bar())
    scene["structure"]["bodies"][1]["root"] = [D + 0.001, 0.0, 0.0]     # the right crank 1 mm too far right
    with pytest.raises(SceneError) as err:
        StructureTopology.from_spec(StructureSpec.from_scene(scene))
    assert err.value.key == "structure.joints.B"
    assert err.value.value == "0.001 m apart"


def test_a_pin_off_the_nodes_is_refused_naming_its_span():
    scene = copy.deepcopy(four_bar())
    scene["structure"]["joints"][2]["other_span"] = 0.3           # the left crank's nodes: 0, 0.25, 0.5 m
    with pytest.raises(SceneError) as err:
        StructureTopology.from_spec(StructureSpec.from_scene(scene))
    assert err.value.key == "structure.joints.A.other_span"
    assert "a node position of body 'left'" in err.value.allowed


@pytest.mark.parametrize("joint", [{"type": "pin", "name": "J", "body": "left", "span": L, "other_span": 0.5},
                                   {"type": "slider", "name": "J", "body": "left", "span": L, "line": [0, 1, 0],
                                    "other_span": 0.5}])
def test_an_other_span_without_an_other_body_is_refused(joint):
    raw = copy.deepcopy(four_bar())
    raw["structure"]["joints"].append(joint)
    with pytest.raises(SceneError) as err:
        resolve_scene(raw, "x")
    assert err.value.key == "structure.joints.J.other_span"


def test_a_pin_about_the_chord_needs_the_same_chord_at_both_nodes():
    scene = copy.deepcopy(four_bar())
    scene["structure"]["bodies"][2]["chord_axis"] = [0.0, 0.6, 0.8]
    with pytest.raises(SceneError) as err:
        StructureTopology.from_spec(StructureSpec.from_scene(scene))
    assert err.value.key == "structure.joints.A.axis"


def test_pins_anywhere_are_refused_in_the_strain_based_fidelity_naming_the_key():
    scene = copy.deepcopy(four_bar())
    scene["structure"]["fidelity"] = "strain-based"
    scene["structure"]["bodies"] = scene["structure"]["bodies"][:2]
    scene["structure"]["joints"] = [scene["structure"]["joints"][0],
                                    {**scene["structure"]["joints"][1], "span": L / 2}]
    with pytest.raises(SceneError) as err:
        StructureTopology.from_spec(StructureSpec.from_scene(scene))
    assert err.value.key == "structure.joints.O2.span"


def test_a_scissor_chain_expands_to_named_bars_pins_sliders_and_probes():
    """Two SLEs at 60 deg: four bars, the mid-length and junction pins, the ends, and a probe per named point at
    the geometry of the chain (w = L cos 60 deg = 0.5 m apart, H = L sin 60 deg high)."""
    scene = scissor_chain()
    names = [b["name"] for b in scene["structure"]["bodies"]]
    assert names == ["s_up1", "s_down1", "s_up2", "s_down2"]
    joints = {j["name"]: j for j in scene["structure"]["joints"]}
    assert sorted(joints) == ["s_a1_slider", "s_a2", "s_b1_pin", "s_b2", "s_c1", "s_c2"]
    assert joints["s_a1_slider"]["line"] == [0.0, 1.0, 0.0]
    assert all(b["elements"] == 2 for b in scene["structure"]["bodies"])
    top = StructureTopology.from_spec(StructureSpec.from_scene(scene))
    E = top.initial_coordinates()
    H = np.sin(np.radians(60.0))
    expected = {"a1": [0, H, 0], "a2": [0.5, H, 0], "a3": [1.0, H, 0], "b1": [0, 0, 0], "b2": [0.5, 0, 0],
                "b3": [1.0, 0, 0], "c1": [0.25, H / 2, 0], "c2": [0.75, H / 2, 0]}
    for probe in scene["probes"]:
        point = top.point_position(E, probe["body"], probe["span"], probe["chord"])
        np.testing.assert_allclose(point, expected[probe["name"][2:]], atol=1e-15)
    assert resolve_scene(scene, "chain") == scene              # resolving again adds nothing


def test_a_scissor_chain_refuses_clashing_names_and_odd_bars():
    raw = {"time": {"stop": 0.1},
           "structure": {"bodies": [{"name": "s_up1", "length": 1.0, "section": dict(SECTION)}],
                         "scissors": [{"name": "s", "count": 1, "bar_length": 1.0, "initial_angle_deg": 45.0,
                                       "section": dict(SECTION)}]}}
    with pytest.raises(SceneError) as err:
        resolve_scene(raw, "x")
    assert err.value.key == "structure.scissors.s.name"
    raw["structure"]["bodies"] = []
    raw["structure"]["scissors"][0]["elements_per_bar"] = 3
    with pytest.raises(SceneError) as err:
        resolve_scene(raw, "x")
    assert err.value.key == "structure.scissors.s.elements_per_bar"


def test_a_loop_of_parent_child_joints_is_refused_pointing_to_pins():
    """Revolute, ball and universal joints place a child at its parent's tip: a loop of them has no start."""
    raw = copy.deepcopy(four_bar())
    raw["structure"]["joints"] = [{"type": "ball", "name": "AB", "parent": "left", "child": "right"},
                                  {"type": "ball", "name": "BA", "parent": "right", "child": "left"}]
    for body in raw["structure"]["bodies"][:2]:
        body["root"] = body["span_axis"] = body["chord_axis"] = None
    with pytest.raises(SceneError) as err:
        StructureTopology.from_spec(StructureSpec.from_scene(resolve_scene(raw, "x")))
    assert err.value.key == "structure.joints" and "close a loop with a pin" in err.value.allowed
