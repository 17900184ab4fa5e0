"""Pins and sliders: the joints that hold a node anywhere along a body, to a node of another body or to the
ground, in the rigid and flexible fidelities (Peng et al. 2019, Secs. 2-3).

A pin shares a point: the r slots of its two nodes are made equal by eliminating a free point vector
(slots.eliminate, Peng et al. 2019, Eqs. 13-14), so that the two nodes coincide to round-off. About the chord
(`axis = "chord"`) it also shares r_y; about the section normal it keeps the two normals parallel by two
axis-product rows (AxisProduct, with the ground two fixed-plane rows); `free` shares the point only. A flexible
node's point is its own free vector, so every pin of the flexible fidelity is eliminated, closed loops
included. A rigid body's nodes all follow one point and r_x (Otsuka et al. 2019, Eq. 17): its first pin moves
that point to the pin, and a pin that closes a kinematic loop of rigid bodies has no point vector left to
eliminate; it becomes three linear rows X_a - X_b = 0 (LinearRow). A planar loop makes one of them redundant
with the others, which the model drops (`model.independent_rows`).

A slider keeps a node's r on a line or plane through its position at t = 0. Fixed in space, the line (plane) is
affine, r = r_0 + d s (r_0 + d_1 s_1 + d_2 s_2), so the node's free point vector is eliminated for one (two) free
scalars, the slider's travel along d (slots.eliminate with that difference; the specification of a coordinate by
a linear map, as Peng et al. 2019, Secs. 2-3 do for pins): no constraint row, for any direction of the line. A
node whose r has no free point vector left (a second slider on it, or a rigid body whose point a pin or slider
already holds) keeps the slider as linear rows (r - r_0) . n = 0 instead. Carried by the frame of a node of
another body, the line moves with that node's gradients and the condition is cubic in E: rows (SlidingRow).
"""
import numpy as np

from fmu_common.choices import fidelity_names
from fmu_common.errors import SceneError
from fmu_common.wing_spec import PinSpec, SliderSpec
from fmu_common.vectors import perpendiculars, unit

from .constraints import AxisProduct, LinearRow
from .joint_rows import SlidingRow
from .motion import Fixed
from .slots import RX, RY, R, eliminate

GAP_TOLERANCE = 1e-9
"""m (a point) or - (a chord direction): how far the two sides of a pin may be apart at t = 0."""



def add_pins(top, joints) -> None:
    """Share the points (and chords) of the pins among `joints` in the StructureTopology `top`, or add their rows.

    SceneError naming the key for a pin on a point that is not a node, two sides apart at t = 0, or a pin the
    fidelity cannot hold.

    Args:
        top: the StructureTopology, changed in place.
        joints: the structure's joints (fmu_common.wing_spec).
    """
    for spec in (j for j in joints if isinstance(j, PinSpec)):
        key = spec.key
        if not top.fidelity.nodes_anywhere:
            if spec.holds_root():
                continue       # the strain-based root joint (strain_model); prescribed bodies follow their law
            where, value = ("other", spec.other) if spec.other is not None else ("span", spec.span)
            raise SceneError(f"{key}.{where}", value, f"a pin of a body's root to the ground in the "
                                                      f"{top.fidelity.name} fidelity (pins anywhere: "
                                                      f"{fidelity_names(lambda f: f.nodes_anywhere)})")
        a = top.node_at(f"{key}.span", spec.body, spec.span)
        b = None if spec.other is None else top.node_at(f"{key}.other_span", spec.other, spec.other_span)
        if a == b:
            raise SceneError(f"{key}.other_span", spec.other_span, "a node other than the pinned one")
        _Pin(top, key, a, b).add(spec.axis)
    top.compact_free()


class _Pin:
    """One pin between node a and node b (None: the ground) of the topology `top`."""

    def __init__(self, top, key, a, b):
        self.top, self.key, self.a, self.b = top, key, a, b

    def _normal(self, node):
        """The unit section normal r_x x r_y (3,) of `node` at t = 0."""
        _, x, y = self.top.node_initial[node]
        normal = np.cross(x, y)
        return normal / np.linalg.norm(normal)

    def add(self, axis):
        top, a, b = self.top, self.a, self.b
        self._share(R, "the two nodes coincide at t = 0", "m apart")
        if axis == "chord":
            self._share(RY, "the chord_axis of the two bodies at the pin is the same at t = 0 (the shared axis)",
                        "apart (unit vectors)")
        elif axis == "normal":
            normal = self._normal(a)
            if b is None:
                top.linear_rows += [LinearRow((3 * a + RX,), (1.0,), normal, 0.0),
                                    LinearRow((3 * a + RY,), (1.0,), normal, 0.0)]
                return
            gap = np.linalg.norm(np.cross(normal, self._normal(b)))
            if gap > GAP_TOLERANCE:
                raise SceneError(f"{self.key}.axis", "normal", f"section normals of the two bodies parallel at t = 0 "
                                                             f"(the angle between them is {np.degrees(gap):.3g} deg)")
            top.axis_products += [AxisProduct(3 * a + RX, np.array([0.0, 0.0, 1.0]), 3 * b + RX, c)
                                  for c in np.eye(3)[:2]]

    def _share(self, kind, allowed, unit):
        """Make slot `kind` of node a equal to node b's (or to its value at t = 0, fixed)."""
        top, a, b = self.top, self.a, self.b
        mine = top.slots[3 * a + kind]
        value = lambda slot: slot.value(top.free_initial, top.prescribed_initial, top.scalar_initial)
        theirs = top.new_fixed(value(mine), kind == R) if b is None else top.slots[3 * b + kind]
        gap = float(np.linalg.norm(value(mine) - value(theirs)))
        if gap > GAP_TOLERANCE:
            raise SceneError(self.key if kind == R else f"{self.key}.axis", f"{gap:.3g} {unit}", allowed)
        difference = mine.plus(theirs, -1.0)
        if not difference.free:     # already shared, or held by the ground on both sides
            moving = [j for j in difference.prescribed if not isinstance(top.motions[top.prescribed_motion[j]], Fixed)]
            if moving:
                raise SceneError(self.key, "both sides held", "a pin with a free side (both nodes already follow "
                                                              "prescribed motions)")
            return
        candidates = {j for j, point in enumerate(top.free_is_position) if point == (kind == R)}
        if eliminate(top.slots, difference, candidates) is not None:
            return
        # a closed loop of rigid bodies: X_a - X_b = 0 as rows (with the ground: X_a = X_0)
        slots, coefficients = ((3 * a + kind,), (1.0,)) if b is None else ((3 * a + kind, 3 * b + kind), (1.0, -1.0))
        offset = value(theirs) if b is None else np.zeros(3)
        top.linear_rows += [LinearRow(slots, coefficients, e, float(o)) for e, o in zip(np.eye(3), offset)]


def add_sliders(top, joints) -> None:
    """Keep each slider's node on its line or plane.

    Fixed: r = r_0 + sum_k d_k s_k with d_k along the line (one) or in the plane (two), by eliminating a free
    point vector of the node's r (`_slide_on_fixed`); on another body, rows (r - r_Q) . v_Q(n) = their values at
    t = 0 with n the line's two normals or the plane's one (SlidingRow).

    Args:
        top: the StructureTopology, changed in place.
        joints: the structure's joints (fmu_common.wing_spec).
    """
    for spec in (j for j in joints if isinstance(j, SliderSpec)):
        key = spec.key
        if not top.fidelity.nodes_anywhere:
            raise SceneError(f"{key}.type", "slider", f"a joint of the {fidelity_names(lambda f: f.nodes_anywhere)} "
                                                      f"fidelity (not {top.fidelity.name})")
        node = top.node_at(f"{key}.span", spec.body, spec.span)
        if spec.line is not None:
            normals = perpendiculars(unit(spec.line))
            directions = [unit(spec.line)]
        else:
            normals = [unit(spec.plane_normal)]
            directions = perpendiculars(normals[0])
        start = top.node_initial[node][0]
        if spec.other is None:
            _slide_on_fixed(top, node, start, directions, normals)
            continue
        if spec.other == spec.body and not top.fidelity.deformable:
            raise SceneError(f"{key}.other", spec.other, "a body other than the sliding one (a rigid body's line "
                                                         "moves with its node)")
        base = top.node_at(f"{key}.other_span", spec.other, spec.other_span)
        if base == node:
            raise SceneError(f"{key}.other_span", spec.other_span, "a node other than the sliding one")
        origin, x0, y0 = top.node_initial[base]
        frame = np.column_stack([x0, y0, np.cross(x0, y0)])
        offsets = [float((start - origin) @ frame @ n) for n in normals]
        top.sliding_rows += [SlidingRow(3 * node + R, 3 * base + R, 3 * base + RX, n, offset)
                             for n, offset in zip(normals, offsets)]
    top.compact_free()


def _slide_on_fixed(top, node, start, directions, normals) -> None:
    """r of `node` = start + sum_k d_k s_k: a free point vector of its slot solved for and substituted everywhere
    (slots.eliminate), the s_k new free scalars (m, 0 at t = 0); without a free point vector in the slot, the rows
    (r - start) . n = 0 for each of `normals`.

    Args:
        top: the StructureTopology, changed in place.
        node: the sliding node.
        start: (3,) its point at t = 0, m, global frame.
        directions: unit (3,) vectors along the line (one) or spanning the plane (two), global frame.
        normals: unit (3,) vectors perpendicular to them, global frame.
    """
    slot = top.slots[3 * node + R]
    candidates = {j for j in slot.free if top.free_is_position[j]}
    if not candidates:
        top.linear_rows += [LinearRow((3 * node + R,), (1.0,), n, float(n @ start)) for n in normals]
        return
    on_line = top.new_fixed(start, True)
    for d in directions:
        on_line = on_line.plus(top.new_scalar(d), 1.0)
    eliminate(top.slots, slot.plus(on_line, -1.0), candidates)
