"""The structure unit's topology: the shared one (fmu_common.topology) plus joints, sections, motions,
masses and loads, and the map to reduced coordinates.

Exchanged coordinates E (length 9 n_nodes): per node r, r_x, r_y (Otsuka et al. 2019, Eq. 3), each 3-vector a
"slot" (slots.py): a linear combination of free vectors q_j, free scalars s_j along constant directions (a
slider's travel) and prescribed vectors p_j(t), so that E = T q + P p(t), q the free vectors and then the
scalars.

Joint points are not Lagrange constraints here but shared or prescribed coordinates (the master/slave
elimination of Peng et al. 2019, Sec. 3). A ball, universal or revolute joint shares r between the parent's tip
node and the child's root node (with the ground: r is prescribed at the child's root); a revolute joint about
the chord of both bodies also shares r_y (with the ground: prescribed); a rigid body has r = r^A + s r_x^A,
r_x = r_x^A, r_y = r_y^A at every node s along it, the linear rows of Otsuka et al. 2019, Eq. (17); a clamp or
driven root is prescribed; pins and sliders at any node are pins.py's (a slider on a fixed line or plane is a
point eliminated for one or two scalars). What remains as Lagrange constraints is nonlinear: unit length and
orthogonality (Otsuka et al. 2019, Eqs. 6, 17), the axis products of universal joints and of revolute joints
about any other axis (constraints.py `AxisProduct`), the rows of sliders carried by another body, and the
linear rows of pins that close a loop of rigid bodies and of fixed sliders whose node has no point vector left
to eliminate.

Coordinates and constraints per joint at the child's root node (free 3-vectors x 3 coordinates; constraint rows
including the node's own unit-length and orthogonality rows), the same with a parent and with the ground:
  joint                  coordinates   constraints rigid   constraints flexible
  ball                   6             3                   2
  universal              6             4                   3
  revolute, chord axis   3             2                   1
  revolute, other axis   6             5                   4
(a flexible node keeps the axial stretch |r_x| free: one more degree of freedom than the joint's own).
"""
from dataclasses import asdict, dataclass

import numpy as np

from fmu_common import topology
from fmu_common.errors import SceneError
from fmu_common.choices import fidelity_names
from fmu_common.wing_spec import ParentJointSpec, SectionSpec, StructureSpec
from fmu_common.vectors import perpendiculars, unit

from .constraints import AxisProduct, LinearRow
from .joint_rows import SlidingRow
from .joints import hinge_angle
from .motion import Fixed, HeavePitch, SpinUp
from .pins import add_pins, add_sliders
from .section import Section, require_plate, section_from_spec
from .slots import RX, RY, R, Slot, compact



@dataclass
class StructureBody(topology.Body):
    """A Body with its beam section (stiffness, mass; the root's), the section table it comes from (a section that
    varies along the span: structure_fmu.section.section_at) and its damping alpha (1/s)."""

    section: Section = None
    damping: float = 0.0
    section_spec: SectionSpec = None


@dataclass(frozen=True)
class PointLoad:
    """A point force (3,) N, global frame, at the point (x, y) (m, along the span and the chord from the
    reference line) of element `element`: constant, or ramped up over ramp_time (s) by Otsuka et al. 2019,
    Eq. 26 (`structure_fmu.model.StructureModel.load_factor`)."""

    element: int
    x: float
    y: float
    force: np.ndarray
    ramp_time: float | None


CHORD_TOLERANCE = 1e-12
"""A revolute axis within this of the chord in both frames shares (with the ground: prescribes) r_y."""


@dataclass
class Hinge:
    """A revolute joint's fold angle (joints.py) and actuator. A chord-axis hinge without orientation has the
    shared r_y slot axis_slot; any other (axis_slot None) measures its angle with axis, reference and
    child_reference."""

    name: str
    parent_slot: int | None   # r_x slot of the parent's tip node (None: the ground)
    child_slot: int           # r_x slot of the child's root node
    axis_slot: int | None     # shared r_y slot of a chord-axis hinge, else None
    initial_angle: float      # rad
    stiffness: float          # K, N m/rad
    damping: float            # C, N m s/rad
    torque: float             # T_const, N m
    stop_angle: float | None  # rad, latch angle
    latch_factor: float
    axis: np.ndarray | None = None             # a, parent frame components (with the ground: global)
    reference: np.ndarray | None = None        # p perpendicular to a, parent frame components
    child_reference: np.ndarray | None = None  # O^T p, child frame components


class StructureTopology(topology.Topology):
    """The shared topology plus joints, sections, motions, masses and loads, and the affine map
    q, p(t) -> E."""

    def __init__(self):
        super().__init__()
        self.slots: list[Slot] = []
        self.free_initial: list[np.ndarray] = []
        self.free_is_position: list[bool] = []
        self.scalar_initial: list[float] = []                      # free scalars along directions, m
        self.prescribed_initial: list[np.ndarray] = []
        self.prescribed_is_position: list[bool] = []
        self.prescribed_motion: list[int] = []
        self.motions: list = []
        self.hinges: list[Hinge] = []
        self.unit_slots: list[int] = []
        self.orthogonal_slots: list[tuple[int, int]] = []
        self.linear_rows: list[LinearRow] = []                     # sum_k c_k slot_k . n = offset
        self.sliding_rows: list[SlidingRow] = []                   # a point on a line or plane of another body
        self.axis_products: list[AxisProduct] = []                 # joint rows v_A(a) . v_B(b) = 0
        self.masses: list[tuple[int, float]] = []                  # (node, kg)
        self.angular_velocity: dict[str, np.ndarray] = {}          # initial rigid rotation rate, rad/s
        self.loads: list[PointLoad] = []

    # ------------------------------------------------------------------ construction
    @classmethod
    def from_spec(cls, structure: StructureSpec) -> "StructureTopology":
        """Build the topology of a scene's structure table; raises SceneError naming the key.

        Args:
            structure: the structure table (fmu_common.wing_spec.StructureSpec).
        """
        top = super().from_spec(structure)
        motion = structure.motion
        if top.fidelity.moved_by_law and motion is None:
            raise SceneError("structure.motion", None, "a table with the prescribed heave/pitch law")
        if not top.fidelity.moved_by_law and motion is not None:
            given = {name: value for name, value in asdict(motion).items() if name != "key"}
            raise SceneError("structure.motion", given, f"only with structure.fidelity = "
                             f"'{fidelity_names(lambda f: f.moved_by_law)}' (the {top.fidelity.name} structure "
                             "moves by its dynamics)")
        specs = {body.name: body for body in structure.bodies}
        for name, body in top.bodies.items():      # parents before children
            top._add_coordinates(body, specs[name], motion)
        add_pins(top, structure.joints)
        add_sliders(top, structure.joints)
        top._add_constraints()
        top._add_masses(structure.masses)
        for load in structure.loads:
            top._add_load(load.key, load.body, load.span, load.chord, np.array(load.force, dtype=float),
                          load.ramp_time)
        if structure.load_case is not None:
            top._add_load_case(structure.load_case)
        return top

    def _new_body(self, spec):
        if self.fidelity.shear_deformable:
            require_plate(spec.section, self.fidelity.name)
        section = section_from_spec(spec.section)
        return StructureBody(spec.name, spec.length, section.chord, section.axis_position, section=section,
                             damping=spec.damping, section_spec=spec.section)

    def _new_free(self, value, position=False):
        """A slot of a new free vector with initial `value` (3,); `position`: a point (m), else a gradient."""
        self.free_initial.append(np.asarray(value, float))
        self.free_is_position.append(position)
        return Slot(free={len(self.free_initial) - 1: 1.0})

    def new_scalar(self, direction):
        """A slot d s of a new free scalar s (m, 0 at t = 0) along a constant direction d.

        Args:
            direction: d (3,), unit, global frame.
        """
        self.scalar_initial.append(0.0)
        return Slot(along={len(self.scalar_initial) - 1: np.asarray(direction, float)})

    def _new_prescribed(self, value, is_position, motion):
        self.prescribed_initial.append(np.asarray(value, float))
        self.prescribed_is_position.append(is_position)
        self.prescribed_motion.append(motion)
        return Slot(prescribed={len(self.prescribed_initial) - 1: 1.0})

    def new_fixed(self, value, is_position):
        """A slot of a new prescribed vector that stays at `value`, under a Fixed motion of its own.

        Args:
            value: (3,) m for a point, else 1, global frame.
            is_position: whether the vector is a point (else a gradient).
        """
        self.motions.append(Fixed())
        return self._new_prescribed(value, is_position, len(self.motions) - 1)

    def _add_coordinates(self, body, spec, motion_spec):
        """The slots of the body's nodes: its root joint decides whether the root is free, shared or
        prescribed; the other nodes are free (flexible) or follow the root (rigid, prescribed)."""
        r0, x0, y0 = body.root, body.span_axis, body.chord_axis
        if spec.angular_velocity is not None:
            self.angular_velocity[body.name] = np.array(spec.angular_velocity, dtype=float)
        joint = self.root_joints.get(body.name)
        kind = joint.kind if joint else None
        first_node = body.nodes[0]
        motion = None
        if self.fidelity.moved_by_law:
            motion = self._prescribed_motion(motion_spec, r0, x0, y0, body)
        elif kind == "clamp":
            motion = len(self.motions)
            self.motions.append(Fixed())
        elif kind == "driven":
            motion = len(self.motions)       # law "spin_up", the only one (Otsuka et al. 2019, Eq. 27)
            self.motions.append(SpinUp(y0, r0, joint.omega, joint.ramp_time))
        if motion is not None:
            root = [self._new_prescribed(r0, True, motion), self._new_prescribed(x0, False, motion),
                    self._new_prescribed(y0, False, motion)]
        elif isinstance(joint, ParentJointSpec):
            root = self._add_joint(joint, first_node, r0, x0, y0)
        else:   # free, or pinned (pins.py shares its point afterwards)
            root = [self._new_free(r0, position=True), self._new_free(x0), self._new_free(y0)]
        self.slots += root
        n_el = len(body.elements)
        for i, node in enumerate(body.nodes[1:], start=1):
            if self.fidelity.deformable:   # strain-based too: its E has the same node slots
                r_i, x_i, y_i = self.node_initial[node]
                self.slots += [self._new_free(r_i, position=True), self._new_free(x_i), self._new_free(y_i)]
            else:   # rigid or prescribed: linear rows of Otsuka et al. 2019, Eq. (17), at any node
                self.slots += [root[R].plus(root[RX], body.length * i / n_el), root[RX], root[RY]]

    def _prescribed_motion(self, spec, r0, x0, y0, body):
        """The HeavePitch law of `structure.motion` for `body` (its own section normal and reference line where
        the table leaves heave_axis and pitch_axis_position out)."""
        heave_axis = np.cross(x0, y0) if spec.heave_axis is None else np.asarray(spec.heave_axis, float)
        pivot_fraction = body.axis_position if spec.pitch_axis_position is None else spec.pitch_axis_position
        pivot = r0 + y0 * body.chord_offset(pivot_fraction)
        # the static angle of attack is applied to the initial geometry by the caller's chord_axis;
        # alpha_deg adds a constant nose-up pitch (rotation about -x0 lifts the leading edge toward +n)
        alpha = np.radians(spec.alpha_deg)
        amplitude, phase = np.radians(spec.pitch_amplitude_deg), np.radians(spec.phase_deg)
        frequency = spec.frequency
        if alpha != 0.0:     # the schema refuses alpha_deg with an oscillating pitch or a heave
            amplitude, frequency, phase = alpha, 0.0, np.pi / 2
        self.motions.append(HeavePitch(unit(heave_axis), -x0, pivot, spec.heave_amplitude,
                                       amplitude, frequency, phase))
        return len(self.motions) - 1

    def _add_joint(self, spec, root_node, r0, x0, y0):
        """The root slots [r, r_x, r_y] of a child on a ball, universal or revolute joint (`JointLine`), with its
        axis-product rows and, for a revolute, its Hinge."""
        line = next(j for j in self.joint_lines if j.child == spec.child)
        if line.parent is None:          # the ground: the root point (and a chord axis) stay where they start
            tip_x = None
            point = self.new_fixed(r0, True)
            chord = lambda: self.new_fixed(y0, False)
        else:
            tip = self.bodies[line.parent].nodes[-1]
            tip_x = 3 * tip + RX
            point = self.slots[3 * tip + R]
            chord = lambda: self.slots[3 * tip + RY]
        child_x = 3 * root_node + RX
        shared_chord = line.kind == "revolute" and _along_chord(line)
        root = [point, self._new_free(x0), chord() if shared_chord else self._new_free(y0)]
        if line.kind == "universal":
            self.axis_products.append(AxisProduct(tip_x, line.axis, child_x, line.child_axis))
        if line.kind == "revolute":
            if not shared_chord:
                for p in perpendiculars(line.orientation.T @ line.axis):
                    self.axis_products.append(AxisProduct(tip_x, line.axis, child_x, p))
            self._add_hinge(spec, line, tip_x, child_x, shared_chord)
        return root

    def _add_hinge(self, spec, line, parent_slot, child_slot, shared_chord):
        actuator = spec.actuator
        stop = None if actuator.stop_angle_deg is None else np.radians(actuator.stop_angle_deg)
        stiffness, damping, torque, latch = actuator.stiffness, actuator.damping, actuator.torque, actuator.latch_factor
        reference = perpendiculars(line.axis)[0]
        if shared_chord and parent_slot is not None and np.array_equal(line.orientation, np.eye(3)):
            # the chord-axis hinge: the angle between the gradients r_x about the shared r_y (joints.py)
            hinge = Hinge(line.name, parent_slot, child_slot, parent_slot + 1, line.initial_angle, stiffness,
                          damping, torque, stop, latch)
        else:
            hinge = Hinge(line.name, parent_slot, child_slot, None, line.initial_angle, stiffness, damping, torque,
                          stop, latch, line.axis, reference, line.orientation.T @ reference)
        self.hinges.append(hinge)

    def _add_constraints(self):
        """Nonlinear internal constraints, each once per distinct slot combination (Otsuka et al. 2019, Eqs. 6, 17)."""
        seen = set()

        def add(kind, slots):
            rows = [self.slots[s] for s in slots]
            if not any(row.free for row in rows):
                return   # fully prescribed: nothing to constrain
            signature = (kind,) + tuple(sorted(row.signature() for row in rows))
            if signature in seen:
                return
            seen.add(signature)
            if kind == "unit":
                self.unit_slots.append(slots[0])
            else:
                self.orthogonal_slots.append(tuple(slots))

        if self.fidelity.shear_deformable:      # r_y is free: its length and angle to r_x are strains
            return
        for body in self.bodies.values():
            nodes = body.nodes if self.fidelity.deformable else body.nodes[:1]
            for node in nodes:
                if not self.fidelity.deformable:     # |r_x| = 1 (Otsuka et al. 2019, Eq. 17); prescribed: no row
                    add("unit", [3 * node + RX])
                add("unit", [3 * node + RY])
                add("orthogonal", [3 * node + RX, 3 * node + RY])

    def compact_free(self):
        """Drop the free vectors that no slot uses any more (eliminated by a pin) and renumber the rest."""
        self.free_initial, self.free_is_position = compact(self.slots, self.free_initial, self.free_is_position)

    def node_at(self, key, body_name, span):
        """The node of body `body_name` at `span`; SceneError naming `key` otherwise.

        Args:
            key: the scene key the span was read from, for the error.
            body_name: the body's name.
            span: distance from the body's root, m.
        """
        body = self.bodies[body_name]
        n_el = len(body.elements)
        position = span / body.length * n_el
        index = int(round(position))
        if abs(position - index) > 1e-9 or not 0 <= index <= n_el:
            allowed = [round(body.length * i / n_el, 12) for i in range(n_el + 1)]
            raise SceneError(key, span, f"a node position of body '{body_name}' (m from its root): {allowed}")
        return body.nodes[index]

    def _add_masses(self, masses):
        for spec in masses:
            self._check_body(f"{spec.key}.body", spec.body)
            self.masses.append((self.node_at(f"{spec.key}.span", spec.body, spec.span), spec.mass))

    def _add_load(self, key, body_name, span, chord, force, ramp_time):
        """A point load `force` (3,) N at `span` (m) and `chord` (fraction) of body `body_name`, constant (ramp_time
        None) or with the cosine ramp of ramp_time (s); SceneError naming `key` for an unknown body or a span
        beyond its length."""
        body = self.bodies[self._check_body(f"{key}.body", body_name)]
        if span > body.length:
            raise SceneError(f"{key}.span", span, f"0 <= span <= {body.length:g} (m, the length of body "
                                                  f"'{body.name}')")
        index, x, y = self.locate(body_name, span, chord)
        self.loads.append(PointLoad(index, x, y, force, ramp_time))

    def _check_body(self, key, name):
        """`name` if it is a body's, else SceneError naming `key`."""
        if name not in self.bodies:
            raise SceneError(key, name, f"one of the bodies {sorted(self.bodies)}")
        return name

    def _add_load_case(self, spec):
        """`[load]`: a point load given by the non-dimensional parameter P L^2 / (EI_yy) of its body (the
        resolved scene names the body, span and chord)."""
        body = self.bodies[self._check_body("load.body", spec.body)]
        direction = np.asarray(spec.direction, dtype=float)
        magnitude = spec.parameter * body.section.flap / body.length**2
        force = magnitude * unit(direction)
        if not np.all(np.isfinite(force)):
            raise SceneError("load.parameter", spec.parameter, f"a value whose force P = parameter x EI_yy / L^2 is "
                                                              f"finite (it overflows: {magnitude:g} N)")
        self._add_load(spec.key, spec.body, spec.span, spec.chord, force, spec.ramp_time)

    # ------------------------------------------------------------------ queries
    @property
    def n_free(self):
        """Number of free coordinates n_q: 3 per free vector, 1 per free scalar."""
        return 3 * len(self.free_initial) + len(self.scalar_initial)

    def maps(self):
        """(T, P): E = T q + P p(t), dense (9 n_nodes, n_free) and (9 n_nodes, 3 n_prescribed); T's columns are the
        free vectors' (3 each, kron I3) and then the free scalars' (their directions)."""
        n_slots = len(self.slots)
        t_vec = np.zeros((n_slots, len(self.free_initial)))
        p_vec = np.zeros((n_slots, len(self.prescribed_initial)))
        directions = np.zeros((n_slots, 3, len(self.scalar_initial)))
        for s, slot in enumerate(self.slots):
            for j, c in slot.free.items():
                t_vec[s, j] = c
            for j, c in slot.prescribed.items():
                p_vec[s, j] = c
            for j, d in slot.along.items():
                directions[s, :, j] = d
        T = np.hstack([np.kron(t_vec, np.eye(3)), directions.reshape(3 * n_slots, -1)])
        return T, np.kron(p_vec, np.eye(3))

    def initial_free(self):
        """q at t = 0: the free vectors stacked (m and 1, global frame), then the free scalars (m), (n_q,)."""
        return np.concatenate([*self.free_initial, np.array(self.scalar_initial, float)])

    def fold_angles(self, e):
        """Fold angle of each revolute joint: the child's signed angle about the axis relative to the parent.

        joints.py computes it.

        Args:
            e: (n,) exchanged coordinates, global frame.

        Returns:
            {joint: rad}.
        """
        e = np.asarray(e)
        return {h.name: hinge_angle(h, e) for h in self.hinges}


def _along_chord(line):
    """Whether a revolute JointLine's axis is the chord of both frames (with the ground: of the child's),
    within CHORD_TOLERANCE: then r_y is shared (prescribed) and no axis-product row is needed."""
    chord = np.array([0.0, 1.0, 0.0])
    child = np.linalg.norm(line.orientation.T @ line.axis - chord) <= CHORD_TOLERANCE
    return child and (line.parent is None or np.linalg.norm(line.axis - chord) <= CHORD_TOLERANCE)
