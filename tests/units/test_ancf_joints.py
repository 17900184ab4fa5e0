"""Ball, universal and revolute joints in the rigid and flexible ANCF fidelities, with a parent body and with the
ground (structure_fmu/topology.py, constraints.py `AxisProduct`, joints.py, joint_monitors.py).

Each check has its own reference: finite differences for the constraint rows and the fold angle's gradient,
the conservation of energy, the joint's number of degrees of freedom, the relative rotation of the two node
frames for the fold angle, and a second formulation of the same chord-axis revolute (shared chord against
axis-product rows) for the hinge.
"""
import numpy as np
import pytest

from fmu_common.errors import SceneError
from fmu_common.specs import StructureUnitSpec
from fmu_common.scene_schema import resolve_scene
from structure_fmu.joint_monitors import joint_monitors
from structure_fmu.joints import hinge_angle_gradient
from structure_fmu.solver import StructureSolver

# explicit properties: soft enough for RK4 at 1e-4 s with two elements per body
SECTION = {"chord": 0.1, "axis_position": 0.3, "torsional_rigidity": 50.0, "axial_stiffness": 1e5,
           "bending_stiffness_flap": 20.0, "bending_stiffness_chord": 200.0, "mass_per_length": 1.0}
# the joint between A's tip and B's root; B starts along +Z (A along +X), as in Otsuka et al. 2022, Sec. 4. The
# revolute axis lies in the span-normal plane of both bodies: exact in the flexible fidelity too (AxisProduct)
JOINTS = {
    "ball": {"type": "ball", "orientation_deg": [0, -90, 0]},
    "universal": {"type": "universal", "parent_axis": [0, 1, 0], "child_axis": [0, 0, 1],
                  "orientation_deg": [0, -90, 0]},
    "revolute": {"type": "revolute", "axis": [0.6, 0.0, 0.8], "orientation_deg": [0, -70, 0],
                 "initial_angle_deg": 40, "stiffness": 0.5, "damping": 0.0, "torque": 0.1},
    "chord": {"type": "revolute", "initial_angle_deg": 30, "stiffness": 0.5, "torque": 0.1},
}
# the same joints holding a single body B to the ground (global axes)
GROUND_JOINTS = {
    "ball": {"type": "ball"},
    "universal": {"type": "universal", "parent_axis": [0, 0, 1], "child_axis": [1, 0.5, -0.3]},
    "revolute": {"type": "revolute", "axis": [0.6, 0.0, 0.8], "initial_angle_deg": 40, "stiffness": 0.5,
                 "torque": 0.1},
    "chord": {"type": "revolute", "axis": [0, 1, 0], "initial_angle_deg": 30, "stiffness": 0.5, "torque": 0.1},
}
DOF = {"ball": 3, "universal": 2, "revolute": 1, "chord": 1}
# an axis with a chord component, and an orientation about all three directions (rigid fidelity)
SKEWED = {"axis": [0.3, 0.5, 0.8], "orientation_deg": [10, 20, 30]}


def section(**changes):
    return {**SECTION, **changes}


def scene(joint, fidelity, ground=False, integrator="rk4", step=1e-4, body_section=None, **changes):
    """A double pendulum: body A (1 m along +X) on a ball joint at the origin, body B (0.8 m) on `joint` at A's tip;
    with `ground`, body B alone on the joint to the ground at (0.1, 0.2, 0.3). Gravity along -Y."""
    body_section = body_section or SECTION
    if ground:
        bodies = [{"name": "B", "length": 0.8, "root": [0.1, 0.2, 0.3], "span_axis": [1, 0, 0.3],
                   "chord_axis": [0, 1, 0], "section": body_section}]
        joints = [{**GROUND_JOINTS[joint], "name": "j", "child": "B", **changes}]
    else:
        bodies = [{"name": "A", "length": 1.0, "root": [0, 0, 0], "span_axis": [1, 0, 0], "chord_axis": [0, 1, 0],
                   "section": SECTION},
                  {"name": "B", "length": 0.8, "section": body_section}]
        joints = [{"type": "ball", "name": "root", "child": "A"},
                  {**JOINTS[joint], "name": "j", "parent": "A", "child": "B", **changes}]
    return resolve_scene({"time": {"stop": 1.0}, "structure": {
        "fidelity": fidelity, "integrator": integrator, "step": step, "elements_per_body": 2,
        "gravity": [0.0, -9.8, 0.0], "bodies": bodies, "joints": joints}}, "joints")


def unit_frame(e, node):
    """[x, y, z] (3, 3) columns of a node: x = r_x / |r_x|, y = r_y, z = x x y."""
    _, rx, ry = np.asarray(e).reshape(-1, 3, 3)[node]
    x = rx / np.linalg.norm(rx)
    return np.column_stack([x, ry, np.cross(x, ry)])


def relative_angle(solver):
    """The revolute's fold angle from the rotation between the two node frames: R = F_A^T F_B O^T is the turn
    R(a, theta) of JointLine, and theta = atan2(a . axial(R), (tr R - 1) / 2), axial(R) = sin(theta) a."""
    top = solver.topology
    line = top.joint_lines[-1]
    parent = np.eye(3) if line.parent is None else unit_frame(solver.e, top.bodies[line.parent].nodes[-1])
    R = parent.T @ unit_frame(solver.e, top.bodies[line.child].nodes[0]) @ line.orientation.T
    axial = 0.5 * np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])
    return np.arctan2(axial @ line.axis, 0.5 * (np.trace(R) - 1))


@pytest.mark.parametrize("integrator", ["rk4", "generalized-alpha"])
@pytest.mark.parametrize("ground", [False, True], ids=["parent", "ground"])
@pytest.mark.parametrize("fidelity", ["rigid", "flexible"])
@pytest.mark.parametrize("joint", list(JOINTS))
def test_joints_hold_while_the_bodies_swing(joint, fidelity, ground, integrator):
    step = 1e-4 if integrator == "rk4" else 1e-3
    solver = StructureSolver(StructureUnitSpec.from_scene(scene(joint, fidelity, ground, integrator, step)))
    solver.advance(0.03)
    monitors = solver.monitors()
    assert monitors["kinetic_energy"] > 1e-4          # J: it moved (on the ground's chord axis by its actuator)
    assert monitors["constraint_residual"] < 1e-10
    top = solver.topology
    e = solver.e
    root = e.reshape(-1, 3, 3)[top.bodies["B"].nodes[0]]
    if ground:          # the root point (and a chord axis) stay where they started
        assert np.array_equal(root[0], [0.1, 0.2, 0.3])
        if joint == "chord":
            assert np.array_equal(root[2], [0.0, 1.0, 0.0])
        return
    joint_values = joint_monitors(top.joint_lines, top.bodies, e)
    assert joint_values["j_point_mismatch"] < 1e-12
    if joint == "universal":
        assert abs(joint_values["j_axis_product"]) < 1e-10
    if joint in ("revolute", "chord"):
        assert joint_values["j_axis_error"] < 1e-10


@pytest.mark.parametrize("fidelity", ["rigid", "flexible"])
@pytest.mark.parametrize("joint", list(JOINTS) + ["skewed"])
def test_energy_of_the_released_double_pendulum_is_conserved(joint, fidelity):
    """Released from rest under gravity: RK4 at 1e-4 s keeps the total energy within 1e-10 (rigid) and 5e-9
    (flexible: 1e-9 measured, the same for every joint, from the bodies' stiff modes) of the largest kinetic
    energy over 0.06 s. The rigid revolutes carry their spring actuator (K theta + T_const, no damping; its
    potential is in the energy); on the flexible bodies its point torque excites the joint's stiff local modes,
    whose RK4 error at this step (2e-6 of the kinetic energy, falling as h^4) would hide the joint's, so they
    swing freely there."""
    changes = SKEWED if joint == "skewed" else {}
    if fidelity == "flexible" and joint in ("revolute", "chord", "skewed"):
        changes = {**changes, "stiffness": 0.0, "torque": 0.0}
    resolved = scene("revolute" if joint == "skewed" else joint, fidelity, **changes)
    solver = StructureSolver(StructureUnitSpec.from_scene(resolved))
    start = solver.monitors()["energy"]
    drift, kinetic = 0.0, 0.0
    for k in range(1, 7):
        solver.advance(0.01 * k)
        monitors = solver.monitors()
        drift = max(drift, abs(monitors["energy"] - start))
        kinetic = max(kinetic, monitors["kinetic_energy"])
    assert kinetic > 0.2                           # J: the bodies fell a tenth of their length
    assert drift < (1e-10 if fidelity == "rigid" else 5e-9) * kinetic


@pytest.mark.parametrize("ground", [False, True], ids=["parent", "ground"])
@pytest.mark.parametrize("fidelity", ["rigid", "flexible"])
def test_fold_angle_about_a_skewed_axis_is_the_relative_rotation_of_the_frames(fidelity, ground):
    """In the flexible fidelity the axis is exact when it lies in the span-normal plane of both bodies: the
    parent's axis and the child's orientation are chosen so."""
    changes = SKEWED if fidelity == "rigid" and not ground else {}
    resolved = scene("revolute", fidelity, ground, "generalized-alpha", 2e-3, **changes)
    solver = StructureSolver(StructureUnitSpec.from_scene(resolved))
    assert solver.fold_angles_deg()["j"] == pytest.approx(40.0, abs=1e-12)
    angles = []
    for k in range(1, 6):
        solver.advance(0.02 * k)
        angles.append(np.radians(solver.fold_angles_deg()["j"]))
        assert angles[-1] == pytest.approx(relative_angle(solver), abs=1e-10)
    assert np.ptp(angles) > 0.02                   # rad: the joint turned


@pytest.mark.parametrize("fidelity", ["rigid", "flexible"])
@pytest.mark.parametrize("ground", [False, True], ids=["parent", "ground"])
def test_chord_revolute_by_a_shared_chord_equals_the_axis_product_rows(ground, fidelity):
    """The same physical joint two ways: B's chord along the axis (r_y shared with A's, or prescribed on the
    ground, no constraint row) and B turned half a turn about its span (its chord opposite to the axis: two
    axis-product rows, the fold angle from the frames). With the reference line at mid-chord the two bodies are
    the same (no first moment), so the fold angles agree to the integrator's error."""
    mid = section(axis_position=0.5)
    # B turned half a turn about its span: its chord and normal reversed, the same physical body
    turned = {"span_axis": [1, 0, 0.3], "chord_axis": [0, -1, 0]} if ground else {"orientation_deg": [180, 0, 0]}
    shared = StructureSolver(StructureUnitSpec.from_scene(scene("chord", fidelity, ground, body_section=mid)))
    flipped_scene = scene("chord", fidelity, ground, body_section=mid)
    if ground:
        flipped_scene["structure"]["bodies"][0].update(turned)
    else:
        flipped_scene["structure"]["joints"][1].update(turned)
    flipped = StructureSolver(StructureUnitSpec.from_scene(flipped_scene))
    # the turned body's free r_y adds three coordinates, its unit length and the two axis rows three constraints
    assert shared.model.constraints.count + 3 == flipped.model.constraints.count
    assert len(shared.state.q) + 3 == len(flipped.state.q)
    worst = 0.0
    for k in range(1, 6):
        for solver in (shared, flipped):
            solver.advance(0.01 * k)
        worst = max(worst, abs(shared.fold_angles_deg()["j"] - flipped.fold_angles_deg()["j"]))
    assert abs(shared.fold_angles_deg()["j"] - 30.0) > 0.1     # deg: it turned
    assert worst < 1e-10                                         # deg (measured 1e-12)


@pytest.mark.parametrize("joint", list(JOINTS))
def test_each_joint_leaves_its_degrees_of_freedom(joint):
    """A rigid body on a joint to the ground: free coordinates minus constraints = the joint's rotations
    (ball 3, universal 2, revolute 1); a flexible body of two elements adds its deformation: the stretch of the
    root r_x and the free nodes' 9 coordinates minus their two internal constraints, 7 per node."""
    rigid = StructureSolver(StructureUnitSpec.from_scene(scene(joint, "rigid", ground=True)))
    assert len(rigid.state.q) - rigid.model.constraints.count == DOF[joint]
    flexible = StructureSolver(StructureUnitSpec.from_scene(scene(joint, "flexible", ground=True)))
    assert len(flexible.state.q) - flexible.model.constraints.count == DOF[joint] + 1 + 2 * 7


def test_universal_on_a_rigid_child_is_not_over_constrained():
    """The rank check of StructureSolver refuses dependent constraint rows; the universal joint's row and
    the rigid child's unit-length and orthogonality rows are independent."""
    solver = StructureSolver(StructureUnitSpec.from_scene(scene("universal", "rigid")))
    E = solver.e
    G = solver.model.constraints.jacobian(E)
    assert np.linalg.matrix_rank(G) == G.shape[0] == 7


def test_universal_with_axes_not_perpendicular_names_the_child_axis():
    with pytest.raises(SceneError) as err:
        StructureSolver(StructureUnitSpec.from_scene(scene("universal", "rigid", child_axis=[0, 1, 1])))
    assert err.value.key == "structure.joints.j.child_axis"


@pytest.mark.parametrize("case", ["universal", "revolute", "ground_universal", "ground_revolute"])
def test_axis_rows_derivatives_match_finite_differences(case):
    """Jacobian on q, rate, the velocity term and the exact Hessian of the axis-product rows, off the constraint
    manifold, against central differences of the residual (quartic: the differences are exact to round-off
    and s^2 terms)."""
    ground = case.startswith("ground")
    model = StructureSolver(StructureUnitSpec.from_scene(scene(case.removeprefix("ground_"), "flexible", ground))).model
    cons = model.constraints
    axes = cons.axes
    assert axes.count == (1 if case.endswith("universal") else 2)
    rng = np.random.default_rng(3)
    q = model.T.T @ model.top.initial_coordinates() + 0.2 * rng.standard_normal(model.T.shape[1])
    E = model.coordinates(q, np.zeros_like(q), 0.0)[0]
    offset = E - model.T @ q
    rows = slice(cons.count - axes.count, cons.count)
    phi = lambda x: cons.residual(model.T @ x + offset)[rows]
    s = 1e-5
    columns = np.array([(phi(q + s * u) - phi(q - s * u)) / (2 * s) for u in np.eye(q.size)]).T
    assert np.allclose(cons.jacobian(E)[rows], columns, rtol=0, atol=1e-8)
    dE = rng.standard_normal(E.size)
    along = lambda k: cons.residual(E + k * s * dE)[rows]
    assert np.allclose(cons.rate(E, dE)[rows], (along(1) - along(-1)) / (2 * s), rtol=0, atol=1e-8)
    s2 = 1e-3
    along = lambda k: cons.residual(E + k * s2 * dE)[rows]
    second = (-along(2) + 16 * along(1) - 30 * along(0) + 16 * along(-1) - along(-2)) / (12 * s2**2)
    assert np.allclose(cons.velocity_quadratic(dE, E)[rows], second, rtol=1e-6, atol=1e-6)
    lam = rng.standard_normal(cons.count)
    weighted = np.zeros(cons.count)
    weighted[rows] = lam[rows]
    hessian = cons.hessian_sum(weighted, E)
    grad = lambda x: weighted @ _gradient_on_E(cons, x)
    numeric = np.array([(grad(E + s * u) - grad(E - s * u)) / (2 * s) for u in np.eye(E.size)])
    assert np.allclose(hessian, numeric, rtol=0, atol=1e-6)


def _gradient_on_E(cons, E):
    """dPhi/dE (count, n) by the rows' own gradient, scattered on E (the Hessian test's reference differences
    this)."""
    axes = cons.axes
    out = np.zeros((cons.count, E.size))
    grad = axes.gradient(E)
    for i, index in enumerate(axes._index):
        np.add.at(out[cons.count - axes.count + i], index, grad[i])
    return out


@pytest.mark.parametrize("case", ["parent", "ground", "shared_chord"])
def test_fold_angle_gradient_matches_finite_differences(case):
    """The gradient of the skewed-axis fold angle (the actuator's generalized force is -torque times it) on its
    distinct E indices, also where r_y is shared by the two nodes (a chord axis with an orientation about it)."""
    if case == "shared_chord":
        solver = StructureSolver(StructureUnitSpec.from_scene(scene("chord", "flexible", orientation_deg=[0, 25, 0])))
    else:
        solver = StructureSolver(StructureUnitSpec.from_scene(scene("revolute", "flexible", ground=case == "ground")))
    hinge = solver.topology.hinges[0]
    assert hinge.axis_slot is None
    rng = np.random.default_rng(5)
    E = solver.e + 0.05 * rng.standard_normal(solver.e.size)
    theta, idx, grad = hinge_angle_gradient(hinge, E)
    assert len(set(idx.tolist())) == len(idx)
    s = 1e-6
    for k, i in enumerate(idx):
        step = np.zeros_like(E)
        step[i] = s
        numeric = (hinge_angle_gradient(hinge, E + step)[0] - hinge_angle_gradient(hinge, E - step)[0]) / (2 * s)
        assert grad[k] == pytest.approx(numeric, abs=1e-7)
    others = np.setdiff1d(np.arange(E.size), idx)
    E2 = E.copy()
    E2[others] += 0.1
    assert hinge_angle_gradient(hinge, E2)[0] == theta    # nothing else moves it


def test_monitors_measure_a_displaced_joint():
    """joint_monitors on coordinates moved by hand: the child's root shifted by d gives |d|; the child turned by
    phi about A's normal (global Z at t = 0) moves B's normal, the universal's child axis, from -X to
    (-cos phi, -sin phi, 0), so the product with the parent axis (A's chord, Y) is -sin phi; the revolute's
    axis, B's chord, goes from Y to (-sin phi, cos phi, 0): |u_A - u_B| = 2 sin(phi / 2)."""
    phi, d = 0.3, np.array([1e-3, -2e-3, 0.5e-3])
    c, s = np.cos(phi), np.sin(phi)
    turn = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
    for joint, name, expected in (("universal", "j_axis_product", -s), ("chord", "j_axis_error", 2 * np.sin(phi / 2))):
        top = StructureSolver(StructureUnitSpec.from_scene(scene(joint, "rigid"))).topology
        e = top.initial_coordinates().reshape(-1, 3, 3)
        root = top.bodies["B"].nodes[0]
        e[root, 0] += d
        e[root, 1:] = e[root, 1:] @ turn.T
        values = joint_monitors(top.joint_lines, top.bodies, e.ravel())
        assert set(values) == {"j_point_mismatch", name}       # the ground's ball joint has no monitor
        assert values["j_point_mismatch"] == pytest.approx(np.linalg.norm(d), rel=1e-12)
        assert values[name] == pytest.approx(expected, rel=1e-12)
