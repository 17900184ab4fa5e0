"""The structure unit's topology: the shared one (fmu_common.topology) plus joints, sections, motions,
masses and loads, and the map to reduced coordinates.

Exchanged coordinates E (length 9 n_nodes): per node r, r_x, r_y (000 Eq. 3). Each 3-vector "slot"
s = 3 node + k (k = 0 r, 1 r_x, 2 r_y) occupies E[3s:3s+3].

Joints are not Lagrange constraints here but shared or prescribed coordinates (the master/slave
elimination of 004 Sec. 3): a slot is a linear combination of free vectors q_j and prescribed vectors
p_j(t), so E = (T kron I3) q + (P kron I3) p(t). A hinge shares r and r_y between the parent's tip node
and the child's root node; a rigid body (one element) has r^B = r^A + l r_x^A, r_x^B = r_x^A,
r_y^B = r_y^A, the linear rows of 000 Eq. (17); a clamp or driven root is prescribed. What remains as
Lagrange constraints is nonlinear: unit length and orthogonality (000 Eqs. 6, 17), see constraints.py.
"""
from dataclasses import dataclass, field

import numpy as np

from fmu_common import topology
from fmu_common.errors import SceneError, checked_number, checked_vector, reject_unknown_keys

from .joints import fold_angle, hinge_coordinates
from .motion import Fixed, HeavePitch, SpinUp
from .section import Section, section_from_scene

R, RX, RY = 0, 1, 2  # slot kinds


@dataclass
class StructureBody(topology.Body):
    """A Body with its beam section (stiffness, mass) and its damping alpha (1/s)."""

    section: Section = None
    damping: float = 0.0


@dataclass
class Hinge:
    name: str
    parent_slot: int        # r_x slot of the parent's tip node
    child_slot: int         # r_x slot of the child's root node
    axis_slot: int          # shared r_y slot
    initial_angle: float    # rad
    stiffness: float        # K, N m/rad
    damping: float          # C, N m s/rad
    torque: float           # T_const, N m
    stop_angle: float | None  # rad, latch angle
    latch_factor: float


@dataclass
class _Slot:
    free: dict = field(default_factory=dict)        # free vector index -> coefficient
    prescribed: dict = field(default_factory=dict)  # prescribed vector index -> coefficient

    def plus(self, other, factor):
        out = _Slot(dict(self.free), dict(self.prescribed))
        for src, dst in ((other.free, out.free), (other.prescribed, out.prescribed)):
            for j, c in src.items():
                dst[j] = dst.get(j, 0.0) + factor * c
        return out

    def signature(self):
        return (tuple(sorted((j, round(c, 12)) for j, c in self.free.items())),
                tuple(sorted((j, round(c, 12)) for j, c in self.prescribed.items())))


_LOAD_KEYS = {"parameter", "body", "span", "chord", "direction", "law", "ramp_time"}
_MOTION_KEYS = {"heave_amplitude", "pitch_amplitude_deg", "frequency", "phase_deg", "pitch_axis_position",
                "heave_axis", "alpha_deg"}


class StructureTopology(topology.Topology):
    """The shared topology plus joints, sections, motions, masses and loads, and the affine map
    q, p(t) -> E."""

    def __init__(self):
        super().__init__()
        self.slots: list[_Slot] = []
        self.free_initial: list[np.ndarray] = []
        self.prescribed_initial: list[np.ndarray] = []
        self.prescribed_is_position: list[bool] = []
        self.prescribed_motion: list[int] = []
        self.motions: list = []
        self.hinges: list[Hinge] = []
        self.unit_slots: list[int] = []
        self.orthogonal_slots: list[tuple[int, int]] = []
        self.fixed_directions: list[tuple[int, np.ndarray]] = []   # slot . n = 0
        self.masses: list[tuple[int, float]] = []                  # (node, kg)
        self.angular_velocity: dict[str, np.ndarray] = {}          # initial rigid rotation rate, rad/s
        self.loads: list[dict] = []

    # ------------------------------------------------------------------ construction
    @classmethod
    def from_scene(cls, scene: dict) -> "StructureTopology":
        """Build the topology of `scene["structure"]`; raises SceneError naming the key."""
        top = super().from_scene(scene)
        structure = scene["structure"]
        checked_vector("structure.gravity", structure.get("gravity", [0.0, 0.0, 0.0]))
        motion_spec = structure.get("motion")
        if top.fidelity == "prescribed" and not isinstance(motion_spec, dict):
            raise SceneError("structure.motion", motion_spec, "a table with the prescribed heave/pitch law")
        for key, spec in top._body_specs(structure):
            top._add_coordinates(top.bodies[spec["name"]], key, spec, motion_spec)
        top._add_constraints()
        top._add_masses_and_loads(structure)
        if "load" in scene:
            top._add_load_case(scene["load"])
        return top

    def _new_body(self, key, spec, name, length):
        section = section_from_scene(f"{key}.section", spec.get("section"))
        damping = checked_number(f"{key}.damping", spec.get("damping", 0.0), "a damping alpha >= 0 (1/s)",
                                 lambda v: v >= 0)
        return StructureBody(name, length, section.chord, section.axis_position, section=section, damping=damping)

    def _body_specs(self, structure):
        """(dotted key, table) of every body, in the order of `bodies` (parents before children)."""
        keyed = {spec["name"]: (f"structure.bodies[{i}]", spec) for i, spec in enumerate(structure["bodies"])}
        return [keyed[name] for name in self.bodies]

    def _new_free(self, value):
        self.free_initial.append(np.asarray(value, float))
        return _Slot(free={len(self.free_initial) - 1: 1.0})

    def _new_prescribed(self, value, is_position, motion):
        self.prescribed_initial.append(np.asarray(value, float))
        self.prescribed_is_position.append(is_position)
        self.prescribed_motion.append(motion)
        return _Slot(prescribed={len(self.prescribed_initial) - 1: 1.0})

    def _add_coordinates(self, body, key, spec, motion_spec):
        """The slots of the body's nodes: its root joint decides whether the root is free, shared or
        prescribed; the other nodes are free (flexible) or follow the root (rigid, prescribed)."""
        r0, x0, y0 = body.root, body.span_axis, body.chord_axis
        if "angular_velocity" in spec:
            self.angular_velocity[body.name] = checked_vector(f"{key}.angular_velocity", spec["angular_velocity"])
        joint_key, joint = self.root_joints.get(body.name, (None, None))
        kind = joint["type"] if joint else None
        first_node = body.nodes[0]
        motion = None
        if self.fidelity == "prescribed":
            motion = self._prescribed_motion(motion_spec, r0, x0, y0, body)
        elif kind == "clamp":
            motion = len(self.motions)
            self.motions.append(Fixed())
        elif kind == "driven":
            if joint.get("law", "spin_up") != "spin_up":
                raise SceneError(f"{joint_key}.law", joint.get("law"), "spin_up (000 Eq. 27)")
            omega = checked_number(f"{joint_key}.omega", joint.get("omega"), "an angular speed (rad/s)")
            ramp = checked_number(f"{joint_key}.ramp_time", joint.get("ramp_time"), "a time > 0 (s)", lambda v: v > 0)
            motion = len(self.motions)
            self.motions.append(SpinUp(y0, r0, omega, ramp))
        if motion is not None:
            root = [self._new_prescribed(r0, True, motion), self._new_prescribed(x0, False, motion),
                    self._new_prescribed(y0, False, motion)]
        elif kind == "hinge":
            tip = self.bodies[joint["parent"]].nodes[-1]
            tip_slot = 3 * tip
            root = [self.slots[tip_slot + R], self._new_free(x0), self.slots[tip_slot + RY]]
            self._add_hinge(joint_key, joint, tip, first_node)
        elif kind == "pin":
            axis = joint.get("axis", "chord")
            if axis not in ("chord", "normal"):
                raise SceneError(f"{joint_key}.axis", axis, "chord (rotation about r_y) or normal (about r_x x r_y)")
            fixed = len(self.motions)
            self.motions.append(Fixed())
            if axis == "chord":
                root = [self._new_prescribed(r0, True, fixed), self._new_free(x0), self._new_prescribed(y0, False, fixed)]
            else:
                root = [self._new_prescribed(r0, True, fixed), self._new_free(x0), self._new_free(y0)]
                normal = np.cross(x0, y0)
                self.fixed_directions += [(3 * first_node + RX, normal), (3 * first_node + RY, normal)]
        else:
            root = [self._new_free(r0), self._new_free(x0), self._new_free(y0)]
        self.slots += root
        for node in body.nodes[1:]:
            if self.fidelity == "flexible":
                r_i, x_i, y_i = self.node_initial[node]
                self.slots += [self._new_free(r_i), self._new_free(x_i), self._new_free(y_i)]
            else:   # rigid or prescribed: linear rows of 000 Eq. (17)
                self.slots += [root[R].plus(root[RX], body.length), root[RX], root[RY]]

    def _prescribed_motion(self, spec, r0, x0, y0, body):
        reject_unknown_keys(spec, "structure.motion", _MOTION_KEYS)
        key = "structure.motion"
        get = lambda name, default: checked_number(f"{key}.{name}", spec.get(name, default))
        heave_axis = checked_vector(f"{key}.heave_axis", spec.get("heave_axis", list(np.cross(x0, y0))), unit=True)
        pivot_fraction = get("pitch_axis_position", body.axis_position)
        pivot = r0 + y0 * body.chord_offset(pivot_fraction)
        # the static angle of attack is applied to the initial geometry by the caller's chord_axis;
        # alpha_deg adds a constant nose-up pitch (rotation about -x0 lifts the leading edge toward +n)
        alpha = np.radians(get("alpha_deg", 0.0))
        amplitude = np.radians(get("pitch_amplitude_deg", 0.0))
        if alpha != 0.0 and amplitude != 0.0:
            raise SceneError(f"{key}.alpha_deg", spec.get("alpha_deg"), "0 when pitch_amplitude_deg is given")
        frequency = get("frequency", 0.0)
        phase = np.radians(get("phase_deg", 0.0))
        if alpha != 0.0:
            amplitude, frequency, phase = alpha, 0.0, np.pi / 2
        self.motions.append(HeavePitch(heave_axis, -x0, pivot, get("heave_amplitude", 0.0), amplitude,
                                       frequency, phase))
        return len(self.motions) - 1

    def _add_hinge(self, key, spec, tip_node, root_node):
        line = next(h for h in self.hinge_lines if h.child == spec["child"])   # name and initial angle checked
        stiffness = checked_number(f"{key}.stiffness", spec.get("stiffness", 0.0), "K >= 0 (N m/rad)",
                                   lambda v: v >= 0)
        damping = checked_number(f"{key}.damping", spec.get("damping", 0.0), "C >= 0 (N m s/rad)", lambda v: v >= 0)
        torque = checked_number(f"{key}.torque", spec.get("torque", 0.0), "T_const (N m)")
        stop = spec.get("stop_angle_deg")
        # in (-180, 180) deg like the fold angle itself, which wraps at +-180 (a stop outside is never reached)
        stop = None if stop is None else np.radians(checked_number(f"{key}.stop_angle_deg", stop,
                                                                   "an angle in (-180, 180) deg",
                                                                   lambda v: -180 < v < 180))
        latch = checked_number(f"{key}.latch_factor", spec.get("latch_factor", 1e4), "a factor >= 1", lambda v: v >= 1)
        self.hinges.append(Hinge(line.name, 3 * tip_node + RX, 3 * root_node + RX, 3 * tip_node + RY,
                                 line.initial_angle, stiffness, damping, torque, stop, latch))

    def _add_constraints(self):
        """Nonlinear internal constraints, each once per distinct slot combination (000 Eqs. 6, 17)."""
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

        for body in self.bodies.values():
            nodes = body.nodes if self.fidelity == "flexible" else body.nodes[:1]
            for node in nodes:
                if self.fidelity == "rigid":
                    add("unit", [3 * node + RX])
                add("unit", [3 * node + RY])
                add("orthogonal", [3 * node + RX, 3 * node + RY])

    def _node_at(self, key, body_name, span):
        body = self.bodies[body_name]
        n_el = len(body.elements)
        position = span / body.length * n_el
        index = int(round(position))
        if abs(position - index) > 1e-9 or not 0 <= index <= n_el:
            allowed = [round(body.length * i / n_el, 12) for i in range(n_el + 1)]
            raise SceneError(key, span, f"a node position of body '{body_name}' (m from its root): {allowed}")
        return body.nodes[index]

    def _add_masses_and_loads(self, structure, key=None):
        for i, spec in enumerate(structure.get("masses", [])):
            item = f"structure.masses[{i}]"
            if spec.get("body") not in self.bodies:
                raise SceneError(f"{item}.body", spec.get("body"), f"one of the bodies {sorted(self.bodies)}")
            mass = checked_number(f"{item}.mass", spec.get("mass"), "a mass > 0 (kg)", lambda v: v > 0)
            self.masses.append((self._node_at(f"{item}.span", spec["body"], spec.get("span", 0.0)), mass))
        for i, spec in enumerate(structure.get("loads", [])):
            item = key or f"structure.loads[{i}]"
            if spec.get("body") not in self.bodies:
                raise SceneError(f"{item}.body", spec.get("body"), f"one of the bodies {sorted(self.bodies)}")
            body = self.bodies[spec["body"]]
            span = checked_number(f"{item}.span", spec.get("span"), f"0 <= span <= {body.length} (m)",
                                  lambda v: 0 <= v <= body.length)
            chord = spec.get("chord", body.axis_position)
            law = spec.get("law", "constant")
            if law not in ("constant", "cosine_ramp"):
                raise SceneError(f"{item}.law", law, "constant or cosine_ramp (000 Eq. 26)")
            ramp = checked_number(f"{item}.ramp_time", spec.get("ramp_time", 1.0), "a time > 0 (s)", lambda v: v > 0)
            index, x, y = self.locate(spec["body"], span, checked_number(f"{item}.chord", chord))
            self.loads.append({"element": index, "x": x, "y": y, "law": law, "ramp_time": ramp,
                               "force": checked_vector(f"{item}.force", spec.get("force"))})

    def _add_load_case(self, spec):
        """`[load]`: a point load given by the non-dimensional parameter P L^2 / (EI_yy) of its body."""
        if not isinstance(spec, dict):
            raise SceneError("load", spec, "a table with parameter, direction and optionally body, span, law")
        reject_unknown_keys(spec, "load", _LOAD_KEYS)
        body_name = spec.get("body", list(self.bodies)[-1])
        if body_name not in self.bodies:
            raise SceneError("load.body", body_name, f"one of the bodies {sorted(self.bodies)}")
        body = self.bodies[body_name]
        parameter = checked_number("load.parameter", spec.get("parameter"), "P L^2 / (E I) >= 0", lambda v: v >= 0)
        direction = checked_vector("load.direction", spec.get("direction"), unit=True)
        magnitude = parameter * body.section.flap / body.length**2
        load = {"body": body_name, "span": spec.get("span", body.length), "force": list(magnitude * direction),
                "law": spec.get("law", "constant"), "ramp_time": spec.get("ramp_time", 1.0)}
        if "chord" in spec:
            load["chord"] = spec["chord"]
        self._add_masses_and_loads({"loads": [load]}, key="load")

    # ------------------------------------------------------------------ queries
    @property
    def n_free(self):
        return 3 * len(self.free_initial)

    def maps(self):
        """(T, P): E = T q + P p(t), dense (9 n_nodes, 3 n_free) and (9 n_nodes, 3 n_prescribed)."""
        n_slots = len(self.slots)
        t_vec = np.zeros((n_slots, len(self.free_initial)))
        p_vec = np.zeros((n_slots, len(self.prescribed_initial)))
        for s, slot in enumerate(self.slots):
            for j, c in slot.free.items():
                t_vec[s, j] = c
            for j, c in slot.prescribed.items():
                p_vec[s, j] = c
        return np.kron(t_vec, np.eye(3)), np.kron(p_vec, np.eye(3))

    def initial_free(self):
        return np.concatenate(self.free_initial) if self.free_initial else np.zeros(0)

    def fold_angles(self, e):
        """Fold angle of each hinge (rad): angle from the parent's tip r_x to the child's r_x about r_y."""
        e = np.asarray(e)
        return {h.name: fold_angle(e[hinge_coordinates(h)]) for h in self.hinges}
