"""Directions of any finite, non-zero length mean the direction written: components near 1e308 (whose length
overflows) or near 1e-308 (whose squares underflow) give the same structure as the unit vector."""
import numpy as np
import pytest

from fmu_common.specs import StructureUnitSpec
from fmu_common.vectors import unit
from orchestrator.scene.load import load_scene
from repository import SCENES
from structure_fmu.topology import StructureTopology


def topology(scene, *overrides):
    loaded = load_scene(SCENES / f"{scene}.toml", ["aero.model=none", *overrides])
    return StructureTopology.from_spec(StructureUnitSpec.from_scene(loaded).structure)


@pytest.mark.parametrize("scale", [1e308, 1e-310, 3.0])
def test_unit_of_a_direction_at_any_scale(scale):
    """[0.75, 1, 0] / 1.25 = [0.6, 0.8, 0], whatever factor it is written with (1e-310 is subnormal: 44 bits)."""
    np.testing.assert_allclose(unit([0.75 * scale, scale, 0.0]), [0.6, 0.8, 0.0], rtol=1e-12)


@pytest.mark.parametrize("bad", [[0.0, 0.0, 0.0], [np.inf, 0.0, 0.0], [np.nan, 1.0, 0.0]])
def test_no_unit_of_a_zero_or_non_finite_vector(bad):
    with pytest.raises(ValueError, match="no direction"):
        unit(bad)


@pytest.mark.parametrize("axis", ["[0, 1e308, 0]", "[0, 1e-310, 0]"])
def test_a_revolute_axis_of_any_length_is_the_unit_axis(axis):
    """deploy_rigid's hinge about its chord, written [0, 1, 0] in the scene: the same hinge axis and the same
    initial nodes (the outer body starts folded 170 deg about it)."""
    reference, scaled = topology("deploy_rigid"), topology("deploy_rigid", f"structure.joints.fold.axis={axis}")
    for expected, line in zip(reference.joint_lines, scaled.joint_lines):
        np.testing.assert_allclose(line.axis, expected.axis, rtol=0, atol=1e-15)
    np.testing.assert_allclose(np.array(scaled.node_initial), np.array(reference.node_initial), rtol=0, atol=1e-15)


def test_a_scissor_chain_and_its_sliders_keep_the_directions_written():
    """scissor_array's chain deploys along [1, 0, 0] with its height along [0, 1, 0], its first upper end on a
    slider across the chain (a_1's point is the start plus a free scalar along the height axis): written 1e308
    times longer, the same nodes and the same coordinate map, a_1 sliding along [0, 1, 0]."""
    reference = topology("scissor_array")
    scaled = topology("scissor_array", "structure.scissors.array.direction=[1e308, 0, 0]",
                      "structure.scissors.array.height_axis=[0, 1e308, 0]")
    np.testing.assert_allclose(np.array(scaled.node_initial), np.array(reference.node_initial), rtol=0, atol=1e-12)
    assert [slot.signature() for slot in scaled.slots] == [slot.signature() for slot in reference.slots]
    a1 = 3 * reference.node_at("", "array_down1", 0.0)
    for top in (reference, scaled):
        (direction,) = top.slots[a1].along.values()
        np.testing.assert_allclose(direction, [0.0, 1.0, 0.0], rtol=0, atol=1e-15)
