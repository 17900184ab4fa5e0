"""The structural topology both units build from a scene: bodies, nodes, elements and their initial geometry.

Each body is a beam of ANCF elements along its reference line (`structure.elements_per_body` of them, one
for a rigid or prescribed body: Otsuka et al. 2019, Sec. IV), with its chord c (m) and the reference line at
a fraction a of the chord from the leading edge. A node carries r (m), r_x and r_y (-) in the global frame
(Otsuka et al. 2019, Eq. 3); the exchanged coordinates E (9 n_nodes,) stack them node after node. A body
starts at its `root` along `span_axis` with the chord along `chord_axis`, or, jointed to a parent, at its
parent's tip node in the parent's tip frame turned by the joint (`JointLine`).

The units compare `topology_hash`: the same hash, the same nodes, elements, lengths, chords and joints.
What only the structure needs (sections' stiffness and mass, joints as shared or prescribed coordinates,
motions, masses, loads) is the structure unit's `StructureTopology`, which extends this class.
"""
import hashlib
import json
from dataclasses import dataclass, field

import numpy as np

from .airfoil import FLAT, naca_camber
from .choices import Fidelity
from .errors import SceneError
from .planform import Planform
from .shape_functions import hermite, shape_row
from .wing_spec import BodySpec, JointSpec, ParentJointSpec, RevoluteSpec, StructureSpec, UniversalSpec
from .vectors import rotation_about, unit

@dataclass
class Body:
    """A body of the wing: length (m), chord c (m) at the root, reference line at axis_position a (fraction of
    the root chord from the leading edge), global element and node indices (root first), its frame at t = 0:
    root position (m), unit span direction and chord direction (-), and its planform
    (fmu_common.planform.Planform: taper, sweep, twist, camber)."""

    name: str
    length: float
    chord: float
    axis_position: float
    elements: list = field(default_factory=list)
    nodes: list = field(default_factory=list)
    root: np.ndarray = None
    span_axis: np.ndarray = None
    chord_axis: np.ndarray = None
    planform: Planform = None

    def chord_offset(self, chord_fraction, span=0.0):
        """y (m) of the point at `chord_fraction` of the chord at `span` (m from the root) of the flat planform.

        Args:
            chord_fraction: 0 at the leading edge, 1 at the trailing edge.
            span: m from the root.
        """
        if self.planform is None:
            return (chord_fraction - self.axis_position) * self.chord
        return float(self.planform.chord_offset(span, chord_fraction))


@dataclass(frozen=True)
class JointLine:
    """A revolute, ball or universal joint between the tip node of body `parent` (None: the ground) and the root
    node of body `child` (Otsuka et al. 2022, Sec. 3), in frames F = [span, chord, normal] (columns, the
    normal = span x chord):

    the child's root frame is F_child = F_parent R(axis, theta) orientation, with R(axis, theta) the rotation
    by the fold angle theta about the unit `axis` (revolute; parent-frame components) and `orientation` (3, 3)
    the child's frame relative to the parent's at theta = 0; with the ground, F_parent = I (global
    components). `child_axis` (universal) is the cross's axis in the child's frame; `initial_angle` (rad) the
    revolute's theta at t = 0."""

    name: str
    kind: str
    parent: str | None
    child: str
    axis: np.ndarray
    child_axis: np.ndarray
    orientation: np.ndarray
    initial_angle: float

    def child_frame(self, parent_frame: np.ndarray, angle: float | None = None) -> np.ndarray:
        """F_child for the parent's tip frame and the fold angle.

        Args:
            parent_frame: (3, 3) the parent's tip frame, global frame.
            angle: the fold angle, rad; None: the initial.

        Returns:
            (3, 3) global frame.
        """
        theta = self.initial_angle if angle is None else angle
        turn = rotation_about(self.axis, theta) if self.kind == "revolute" else np.eye(3)
        return parent_frame @ turn @ self.orientation


class Topology:
    """Nodes, elements, bodies and hinges of a scene's `structure` table, with their initial geometry: what
    the aero unit needs of the structure, and what `topology_hash` digests."""

    def __init__(self):
        self.bodies: dict[str, Body] = {}
        self.node_names: list[str] = []
        self.node_initial: list[np.ndarray] = []      # (3, 3) r, r_x, r_y per node at t = 0
        self.element_nodes: list[tuple[int, int]] = []
        self.element_body: list[str] = []
        self.joint_lines: list[JointLine] = []
        self.root_joints: dict[str, JointSpec] = {}      # body -> the joint that holds its root
        self.fidelity: Fidelity | None = None           # fmu_common.choices, from the spec

    # ------------------------------------------------------------------ construction
    @classmethod
    def from_spec(cls, structure: StructureSpec):
        """The topology of a scene's structure table.

        Raises SceneError naming the key for a relation between tables the schema does not check (joints' bodies,
        joint tree).

        Args:
            structure: the structure table (fmu_common.wing_spec.StructureSpec).
        """
        top = cls()
        top.fidelity = structure.fidelity
        bodies = {body.name: body for body in structure.bodies}
        parent_of = top._parse_joints(structure.joints, bodies)
        for name in _body_order(bodies, parent_of):
            top._add_body(bodies[name])
        return top

    def _parse_joints(self, joints, bodies) -> dict:
        """Fill `root_joints`; return child body -> parent body of every joint that joins two bodies."""
        parent_of = {}
        for joint in joints:
            for field_name, name in joint.body_references():
                if name is not None and name not in bodies:
                    raise SceneError(f"{joint.key}.{field_name}", name, f"one of the bodies {sorted(bodies)}")
            if not joint.holds_root():    # a node shared or kept on a line: the structure unit's
                continue
            jointed = isinstance(joint, ParentJointSpec)
            target = joint.child if jointed else joint.body
            if target in self.root_joints:
                raise SceneError(joint.key, target, "a body root can carry only one joint")
            self.root_joints[target] = joint
            if jointed:
                if joint.name in bodies:     # <name>.damping would be the parameter of both
                    raise SceneError(f"{joint.key}.name", joint.name, "a joint name that is not a body's: both "
                                     "name parameters of the structure unit (<name>.damping)")
                if joint.parent == joint.child:
                    raise SceneError(f"{joint.key}.child", joint.child, "a body other than the parent")
                if joint.parent is not None:
                    parent_of[joint.child] = joint.parent
        return parent_of

    def _new_body(self, spec: BodySpec) -> Body:
        """The Body of `spec` (its section read for the chord line)."""
        return Body(spec.name, spec.length, spec.section.chord, spec.section.axis_position)

    def _add_body(self, spec: BodySpec):
        name, key, length, n_el = spec.name, spec.key, spec.length, spec.elements
        body = self._new_body(spec)
        joint = self.root_joints.get(name)
        line = None
        if isinstance(joint, ParentJointSpec):
            line = self._joint_line(joint, spec)
            self.joint_lines.append(line)
        parent = self.bodies[line.parent] if line is not None and line.parent is not None else None
        body.planform = _planform(spec, parent)
        if parent is not None:
            if spec.planform.dihedral_deg != 0.0:
                raise SceneError(f"{key}.dihedral_deg", spec.planform.dihedral_deg, "0 for a hinge's child: its "
                                 "joint's orientation_deg [0, -dihedral, 0] turns it about its chord axis")
            tip = self.bodies[line.parent].nodes[-1]
            r0, x_parent, y_parent = self.node_initial[tip]
            frame = line.child_frame(_frame(x_parent, y_parent))
            x0, y0 = frame[:, 0], frame[:, 1]
            for field_name in ("root", "span_axis"):
                if getattr(spec, field_name) is not None:
                    raise SceneError(f"{key}.{field_name}", list(getattr(spec, field_name)),
                                     "not allowed: a jointed child starts at its parent's tip, in its parent's tip "
                                     "frame turned by the joint (orientation_deg, initial_angle_deg)")
            given = spec.chord_axis
            if given is not None and np.linalg.norm(unit(given) - y0) > 1e-9:
                raise SceneError(f"{key}.chord_axis", list(given), f"the chord axis the joint gives the child, "
                                 f"{[round(float(v), 12) for v in y0]}, or none")
        else:
            r0 = np.array(spec.root, dtype=float)
            x0 = unit(spec.span_axis)
            y0 = unit(spec.chord_axis)
            if abs(x0 @ y0) > 1e-9:
                raise SceneError(f"{key}.chord_axis", list(spec.chord_axis), "a direction perpendicular to span_axis")
            x0 = dihedral_span_axis(x0, y0, spec.planform.dihedral_deg)
        body.root, body.span_axis, body.chord_axis = r0, x0, y0
        first_node = len(self.node_names)
        positions = [r0 + x0 * length * i / n_el for i in range(n_el + 1)]
        _check_node_spacing(key if spec.root is not None else None, spec, positions)
        for i in range(n_el + 1):
            self.node_names.append(f"{name}.{i}")
            self.node_initial.append(np.array([positions[i], x0, y0]))
            body.nodes.append(first_node + i)
        for i in range(n_el):
            body.elements.append(len(self.element_nodes))
            self.element_nodes.append((first_node + i, first_node + i + 1))
            self.element_body.append(name)
        self.bodies[name] = body

    def _joint_line(self, joint: ParentJointSpec, child: BodySpec) -> JointLine:
        """The JointLine of `joint`; SceneError naming its key for an orientation with the ground or a universal
        joint whose axes are not perpendicular at t = 0."""
        key, kind, parent = joint.key, joint.kind, joint.parent
        rotation = np.radians(np.asarray(joint.orientation_deg, dtype=float))
        if parent is None and np.any(rotation):
            raise SceneError(f"{key}.orientation_deg", list(joint.orientation_deg), "[0, 0, 0] with the ground: the "
                             "child's span_axis and chord_axis give its orientation")
        angle = np.linalg.norm(rotation)
        orientation = rotation_about(rotation / angle, angle) if angle > 0 else np.eye(3)
        axis = child_axis = np.zeros(3)
        initial = 0.0
        if isinstance(joint, RevoluteSpec):
            axis, initial = unit(joint.axis), np.radians(joint.initial_angle_deg)
        elif isinstance(joint, UniversalSpec):
            axis, child_axis = unit(joint.parent_axis), unit(joint.child_axis)
        if parent is None:      # the ground: the child's own axes give its frame at t = 0
            chord_axis = unit(child.chord_axis)
            start = _frame(dihedral_span_axis(unit(child.span_axis), chord_axis, child.planform.dihedral_deg),
                           chord_axis)
            turn = rotation_about(axis, initial) if kind == "revolute" else np.eye(3)
            orientation = turn.T @ start
        if kind == "universal" and abs(axis @ orientation @ child_axis) > 1e-9:
            raise SceneError(f"{key}.child_axis", list(joint.child_axis), "an axis perpendicular to parent_axis at "
                             f"t = 0 (their product is {float(axis @ orientation @ child_axis):.3g})")
        return JointLine(joint.name, kind, parent, joint.child, axis, child_axis, orientation, initial)

    # ------------------------------------------------------------------ queries
    @property
    def n_nodes(self):
        """Number of nodes."""
        return len(self.node_names)

    @property
    def n_coordinates(self):
        """n = 9 n_nodes, the length of the exchanged coordinates E."""
        return 9 * self.n_nodes

    @property
    def hinge_names(self):
        """Names of the revolute joints: each has a fold angle."""
        return [j.name for j in self.joint_lines if j.kind == "revolute"]

    def element_lengths(self):
        """Length (m) of each element, (n_elements,)."""
        return np.array([self.bodies[b].length / len(self.bodies[b].elements) for b in self.element_body])

    def element_dofs(self):
        """E indices of each element's 18 coordinates, (n_elements, 18)."""
        a, b = np.array(self.element_nodes).T
        base = np.arange(9)
        return np.concatenate([9 * a[:, None] + base, 9 * b[:, None] + base], axis=1)

    def initial_coordinates(self):
        """E at t = 0 from the scene geometry, (9 n_nodes,)."""
        return np.concatenate([v.ravel() for v in self.node_initial])

    def locate(self, body_name, span, chord_fraction):
        """The element and element coordinates of a material point.

        Args:
            body_name: the body's name.
            span: distance from the body's root, m.
            chord_fraction: 0 at the leading edge, 1 at the trailing edge.

        Returns:
            (element index, x (m), y (m)).
        """
        body = self.bodies[body_name]
        n_el = len(body.elements)
        l_el = body.length / n_el
        k = min(int(span / l_el), n_el - 1)
        return body.elements[k], span - k * l_el, body.chord_offset(chord_fraction, span)

    def point_rows(self, body, span, chord_fraction=0.0):
        """Scalar shape rows of the material point at `span` and `chord_fraction` of `body`.

        They act on X = E.reshape(-1, 3).

        Otsuka et al. 2019, Eq. 2 (S = kron(s, I_3))

        rows @ X gives its position r(x, y) (m), and on the reference line at that span r' (-), r'' (1/m) along the
        span and r_y (-).

        Args:
            body: the body's name.
            span: distance from the body's root, m.
            chord_fraction: 0 at the leading edge, 1 at the trailing edge.

        Returns:
            (4, 3 n_nodes).
        """
        k, x, y = self.locate(body, span, chord_fraction)
        a, b = self.element_nodes[k]
        length = self.bodies[body].length / len(self.bodies[body].elements)
        _, dN, ddN, L = hermite(x / length, length)
        rows = np.zeros((4, 6))                     # on the element's [r^A, r_x^A, r_y^A, r^B, r_x^B, r_y^B]
        rows[0] = shape_row(x, y, length)
        rows[1:3, [0, 1, 3, 4]] = dN, ddN
        rows[3, [2, 5]] = L
        out = np.zeros((4, 3 * self.n_nodes))
        out[:, [3 * a, 3 * a + 1, 3 * a + 2, 3 * b, 3 * b + 1, 3 * b + 2]] = rows
        return out

    def point_position(self, e, body, span, chord_fraction):
        """Global position of the material point at `span` and `chord_fraction` of `body`.

        Args:
            e: (n,) exchanged coordinates, m and 1, global frame.
            body: the body's name.
            span: distance from the body's root, m.
            chord_fraction: 0 at the leading edge, 1 at the trailing edge.

        Returns:
            (3,) m, global frame.
        """
        return self.point_rows(body, span, chord_fraction)[0] @ np.asarray(e, dtype=float).reshape(-1, 3)

    @property
    def topology_hash(self):
        """Hex digest of what both units must agree on: nodes, elements, lengths, chords, axes, joints."""
        data = {
            "nodes": self.node_names,
            "elements": self.element_nodes,
            "bodies": {n: [b.length, b.chord, b.axis_position, len(b.elements)] for n, b in self.bodies.items()},
            "planforms": {n: [b.planform.chord_tip, b.planform.leading_edge_tip, b.planform.twist_root,
                              b.planform.twist_tip, b.planform.camber.m, b.planform.camber.p]
                          for n, b in self.bodies.items()},
            "hinges": self.hinge_names,
            "joints": [[j.name, j.kind, j.parent, j.child] for j in self.joint_lines],
        }
        return hashlib.sha256(json.dumps(data, sort_keys=True).encode()).hexdigest()[:16]


def dihedral_span_axis(span_axis, chord_axis, dihedral_deg):
    """The span axis tilted by the dihedral Gamma about the chord axis toward the section normal n = x0 x y0:
    cos(Gamma) x0 + sin(Gamma) n.

    Args:
        span_axis: (3,) unit x0.
        chord_axis: (3,) unit y0, perpendicular to x0.
        dihedral_deg: Gamma, deg.

    Returns:
        (3,) unit.
    """
    gamma = np.radians(dihedral_deg)
    return np.cos(gamma) * span_axis + np.sin(gamma) * np.cross(span_axis, chord_axis)


def _planform(spec: BodySpec, parent: Body | None) -> Planform:
    """The Planform of a body spec; a hinge's child starts with its parent's tip twist."""
    keys, section = spec.planform, spec.section
    chord_tip = section.tip("chord")
    twist_root = 0.0 if parent is None else float(np.degrees(parent.planform.twist_tip))
    camber = FLAT if keys.airfoil is None else naca_camber(keys.airfoil)
    return Planform.of(spec.length, section.chord, chord_tip, section.axis_position, keys.sweep_deg, twist_root,
                       keys.twist_deg, camber)


NODE_SPACING_TOLERANCE = 1e-6
"""Relative error allowed in the distance between neighbouring nodes at t = 0 against length / elements: a root
(or a parent's tip) so far from the origin that double precision cannot hold the element length is refused."""


def _check_node_spacing(key: str | None, spec: BodySpec, positions: list[np.ndarray]) -> None:
    """SceneError unless the initial node positions of a body are finite and each element as long as the scene
    says, after the arithmetic that places them (r0 + x0 L i / n): a root of 1e17 m and a body of 1 m give
    nodes that coincide, a root of 1e308 m and a body of 1e308 m an infinite tip.

    Args:
        key: the body's dotted key if it gives its root (which is then named), else None (a hinge's child, placed
            at its parent's tip: its length is named).
        spec: the body's spec.
        positions: (elements + 1) positions (3,), m, global frame.
    """
    spacing = spec.length / spec.elements
    with np.errstate(over="ignore", invalid="ignore"):
        gaps = np.linalg.norm(np.diff(np.array(positions), axis=0) / spacing, axis=1)   # scaled: no overflow
        if np.all(np.isfinite(positions)) and np.all(np.abs(gaps - 1.0) <= NODE_SPACING_TOLERANCE):
            return
    where = "its root" if key is not None else "its parent's tip"
    name, value = (f"{key}.root", list(spec.root)) if key is not None else (f"{spec.key}.length", spec.length)
    raise SceneError(name, value, f"a body whose nodes, {spacing:g} m apart, stay finite and apart in double "
                                  f"precision at {where} ({np.max(np.abs(positions[0])):g} m from the origin)")


def _frame(span, chord) -> np.ndarray:
    """[span, chord, normal] (3, 3), columns, normal = span x chord."""
    return np.column_stack([span, chord, np.cross(span, chord)])



def _body_order(bodies, parent_of):
    """Body names, every parent before its children; SceneError for a closed loop of parent-child joints."""
    order, placed = [], set()
    while len(order) < len(bodies):
        progress = False
        for name in bodies:
            parent = parent_of.get(name)
            if name not in placed and (parent is None or parent in placed):
                order.append(name)
                placed.add(name)
                progress = True
        if not progress:
            loop = sorted(set(bodies) - placed)
            raise SceneError("structure.joints", loop, "revolute, ball and universal joints that form a tree (no "
                                                       "closed loop of parents and children: close a loop with a pin)")
    return order
