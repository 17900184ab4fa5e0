"""The aero unit's pairing check (aero_fmu.pairing): at its first step it refuses an e whose node positions are not
those of its own wing geometry, naming both, and never a structure of its own scene, at rest or already moving.

Expectations are the scenes' own numbers: deploy_flexible's two bodies of 0.15 m (reference length 0.3 m, so a
geometric tolerance of 0.3 mm), a shift of known size, a rigid rotation of known rate."""
import math

import numpy as np
import pytest

from aero_fmu.pairing import GEOMETRIC_TOLERANCE, MOTION_SAFETY, prescribed_pose_allowance
from aero_fmu.solver import AeroSolver
from fmu_common.errors import InputError
from fmu_common.specs import AeroUnitSpec, StructureUnitSpec
from fmu_common.topology import Topology
from fmu_common.wing_spec import StructureSpec
from orchestrator.scene.load import load_scene
from repository import SCENES
from structure_fmu.solver import StructureSolver

H = 1e-3                       # s, deploy_flexible's coupling.step
SPAN = 0.15 + 0.15             # m, deploy_flexible: inner and outer bodies of 0.15 m
GEOMETRIC = 1e-3 * SPAN        # m


def scene(name="deploy_flexible", *overrides):
    return load_scene(SCENES / f"{name}.toml", list(overrides))


def aero_of(s):
    return AeroSolver(AeroUnitSpec.from_scene(s))


def node_index(topology, name):
    return topology.node_names.index(name)


def test_constants_are_the_documented_rule():
    assert GEOMETRIC_TOLERANCE == 1e-3 and MOTION_SAFETY == 2.0
    assert aero_of(scene()).pairing.reference_length == pytest.approx(SPAN, rel=1e-15)


@pytest.mark.parametrize("factor, accepted", [(0.99, True), (1.01, False)])
def test_a_node_shifted_just_inside_or_outside_the_geometric_tolerance(factor, accepted):
    """Node outer.3 shifted along the chord (x) by 0.99 or 1.01 times 1e-3 of the span, the wing at rest."""
    aero = aero_of(scene())
    e = aero.topology.initial_coordinates()
    k = 9 * node_index(aero.topology, "outer.3")
    own = e[k:k + 3].copy()
    e[k] += factor * GEOMETRIC
    de = np.zeros_like(e)
    if accepted:
        aero.advance(H, e, de)
        assert aero.time == H
        return
    with pytest.raises(InputError) as refused:
        aero.advance(H, e, de)
    text = str(refused.value)
    assert "node outer.3" in text and f"e[{k + 1}]..e[{k + 3}]" in text
    assert "(" + ", ".join(f"{v:.6g}" for v in own) + ")" in text                       # its own position
    assert "(" + ", ".join(f"{v:.6g}" for v in e[k:k + 3]) + ")" in text                # the received one
    assert f"{factor * GEOMETRIC:.4g} m apart" in text and f"tolerance {GEOMETRIC:.3g} m" in text
    assert "scene 'deploy_flexible'" in text and aero.topology.topology_hash in text
    assert "16 nodes" in text and f"{2 * 2 * 7} panels" in text                         # 2 bodies x M = 2 x N = 7
    assert "connect the structure unit built from the same scene geometry" in text
    assert aero.time == 0.0 and not aero.state.started                                  # state unchanged
    aero.advance(H, aero.topology.initial_coordinates(), de)                             # the right one: accepted
    assert aero.time == H


@pytest.mark.parametrize("factor, accepted", [(0.99, True), (1.01, False)])
def test_the_motion_over_the_step_is_allowed_for(factor, accepted):
    """Node outer.7 moving at 1 m/s along y: it may be up to 1e-3 span + 2 x 1 m/s x 1 ms from its start."""
    aero = aero_of(scene())
    e = aero.topology.initial_coordinates()
    de = np.zeros_like(e)
    k = 9 * node_index(aero.topology, "outer.7")
    de[k + 1] = 1.0
    e[k + 1] += factor * (GEOMETRIC + 2.0 * 1.0 * H)
    if accepted:
        aero.advance(H, e, de)
    else:
        with pytest.raises(InputError, match=r"node outer\.7"):
            aero.advance(H, e, de)


@pytest.mark.parametrize("omega", [5.0, 50.0, 500.0])
def test_a_wing_spinning_about_its_root_is_accepted(omega):
    """The whole wing turned rigidly about the x axis through the clamped root by omega h (rad/s x s), with the
    rates omega x (r, r_x, r_y) at the end of the step: the hinge 0.15 m out moves 0.15 omega h (2.5 to 250 times
    the geometric tolerance), within the motion allowance 2 |v| h."""
    aero = aero_of(scene())
    E = aero.topology.initial_coordinates().reshape(-1, 3)
    axis = np.array([1.0, 0.0, 0.0]) * omega
    angle = omega * H
    c, s = math.cos(angle), math.sin(angle)
    R = np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])
    e = E @ R.T                                   # the root is at the origin: r, r_x, r_y all turn alike
    de = np.cross(axis, e)
    assert np.linalg.norm(e[0::3] - E[0::3], axis=1).max() > 2 * GEOMETRIC
    aero.advance(H, e.ravel(), de.ravel())
    assert aero.time == H


def first_exchange(structure_scene, algorithm):
    """(e, de) a structure solver of `structure_scene` hands over first: at t0 (jacobi) or at t0 + h."""
    structure = StructureSolver(StructureUnitSpec.from_scene(structure_scene))
    if algorithm == "gauss-seidel":
        structure.advance(H)
    return structure.e.copy(), structure.de.copy()


@pytest.mark.parametrize("algorithm", ["jacobi", "gauss-seidel"])
def test_the_structure_of_the_same_scene_is_accepted(algorithm):
    """deploy_flexible's structure, released from rest by its spring: the largest distance / tolerance of the
    shipped scenes (about 0.3 after one step)."""
    s = scene()
    aero = aero_of(s)
    e, de = first_exchange(s, algorithm)
    assert aero.pairing.ratios(e, de, H).max() < 0.5
    aero.advance(H, e, de)


@pytest.mark.parametrize("override, node", [
    ("structure.bodies.outer.length=0.2", "outer.7"),              # another span
    ("structure.joints.fold.initial_angle_deg=175", "outer.7"),    # another fold angle (the same topology_hash)
    ("structure.bodies.inner.root=[0.0, 0.02, 0.0]", "inner.0"),   # the root 20 mm off along y
])
@pytest.mark.parametrize("algorithm", ["jacobi", "gauss-seidel"])
def test_a_structure_of_another_geometry_is_refused_naming_both(override, node, algorithm):
    """The first e of deploy_flexible's structure with one geometric value changed, handed to the aero unit of the
    scene as shipped. The node named is the first (in node order) of those farthest off relative to tolerance;
    its received position is the other structure's, its own this scene's initial one."""
    s, other = scene(), scene("deploy_flexible", override)
    aero = aero_of(s)
    e, de = first_exchange(other, algorithm)
    with pytest.raises(InputError) as refused:
        aero.advance(H, e, de)
    text = str(refused.value)
    own = Topology.from_spec(StructureSpec.from_scene(s)).initial_coordinates().reshape(-1, 9)[:, :3]
    i = node_index(aero.topology, node)
    distance = np.linalg.norm(e.reshape(-1, 9)[i, :3] - own[i])
    assert distance > 10 * GEOMETRIC
    assert f"node {node} " in text and f"{distance:.4g} m apart" in text
    assert "(" + ", ".join(f"{v:.6g}" for v in own[i]) + ")" in text
    assert "(" + ", ".join(f"{v:.6g}" for v in e.reshape(-1, 9)[i, :3]) + ")" in text


def test_another_node_layout_with_the_same_number_of_coordinates_is_refused():
    """cantilever_static with 15 elements has 16 nodes like deploy_flexible (2 bodies x 7 elements): the same n,
    another wing (one 2 m beam along y instead of two 0.15 m bodies along z)."""
    other = scene("cantilever_static", "structure.elements_per_body=15")
    aero = aero_of(scene())
    e, de = first_exchange(other, "jacobi")
    assert e.size == aero.topology.n_coordinates
    with pytest.raises(InputError, match="do not fit this aero unit's lattice"):
        aero.advance(H, e, de)


def test_only_the_first_step_is_checked_and_a_restored_initial_state_is_checked_again():
    aero = aero_of(scene())
    E0 = aero.topology.initial_coordinates()
    de = np.zeros_like(E0)
    initial = aero.get_state()
    aero.advance(H, E0, de)
    far = E0.copy()
    far[9 * 15 + 1] += 100 * GEOMETRIC           # outer.7 moved 30 mm: a deformation later in a run
    aero.advance(2 * H, far, de)
    aero.set_state(initial)
    with pytest.raises(InputError, match=r"node outer\.7"):
        aero.advance(H, far, de)


def test_a_prescribed_pitch_about_another_axis_is_allowed_for():
    """sudden_start pitched by alpha_deg = 5 about the quarter chord: its nodes (on the reference line, at
    axis_position a of the chord c = 1 m) start 2 sin(2.5 deg) |0.25 - a| c from this unit's initial ones, and
    the structure of that scene is accepted."""
    s = load_scene(SCENES / "sudden_start.toml", ["structure.motion.pitch_axis_position=0.25"])
    a = s["structure"]["bodies"][0]["section"]["axis_position"]
    assert a != 0.25
    topology = Topology.from_spec(StructureSpec.from_scene(s))
    expected = 2.0 * math.sin(math.radians(2.5)) * abs(0.25 - a) * 1.0
    np.testing.assert_allclose(prescribed_pose_allowance(topology, StructureSpec.from_scene(s)), expected,
                               rtol=1e-14)
    aero = aero_of(s)
    h = s["coupling"]["step"]
    structure = StructureSolver(StructureUnitSpec.from_scene(s))
    e, de = structure.e.copy(), structure.de.copy()
    moved = np.linalg.norm(e.reshape(-1, 9)[:, :3] - topology.initial_coordinates().reshape(-1, 9)[:, :3], axis=1)
    np.testing.assert_allclose(moved, expected, rtol=1e-9)       # the structure did pitch its nodes so
    assert expected > 1e-3 * 4.0                                  # beyond the geometric tolerance of the 4 m span
    aero.advance(h, e, de)
