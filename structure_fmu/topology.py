"""Structural topology of a scene: bodies, nodes, elements, joints, and the map to reduced coordinates.

Exchanged coordinates E (length 9 n_nodes): per node r, r_x, r_y (000 Eq. 3). Each 3-vector "slot"
s = 3 node + k (k = 0 r, 1 r_x, 2 r_y) occupies E[3s:3s+3].

Joints are not Lagrange constraints here but shared or prescribed coordinates (the master/slave
elimination of 004 Sec. 3): a slot is a linear combination of free vectors q_j and prescribed vectors
p_j(t), so E = (T kron I3) q + (P kron I3) p(t). A hinge shares r and r_y between the parent's tip node
and the child's root node; a rigid body (one element) has r^B = r^A + l r_x^A, r_x^B = r_x^A,
r_y^B = r_y^A, the linear rows of 000 Eq. (17); a clamp or driven root is prescribed. What remains as
Lagrange constraints is nonlinear: unit length and orthogonality (000 Eqs. 6, 17), see constraints.py.
"""
import hashlib
import json
from dataclasses import dataclass, field

import numpy as np

from . import element
from .errors import SceneError, reject_unknown_keys
from .joints import fold_angle, hinge_coordinates
from .motion import Fixed, HeavePitch, SpinUp, rotation_about
from .section import section_from_scene

R, RX, RY = 0, 1, 2  # slot kinds


@dataclass
class Body:
    name: str
    length: float
    section: object
    damping: float
    elements: list          # global element indices
    nodes: list             # global node indices, root first


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


def _number(key, value, condition="a number", check=lambda v: True):
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not np.isfinite(value) or not check(value):
        raise SceneError(key, value, condition)
    return float(value)


def _vector(key, value, unit=False):
    if (not isinstance(value, (list, tuple)) or len(value) != 3
            or not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in value)):
        raise SceneError(key, value, "a list of three numbers")
    v = np.asarray(value, dtype=float)
    if unit:
        if np.linalg.norm(v) == 0:
            raise SceneError(key, value, "a non-zero direction")
        v = v / np.linalg.norm(v)
    return v


_BODY_KEYS = {"name", "length", "root", "span_axis", "chord_axis", "damping", "section", "angular_velocity"}
_LOAD_KEYS = {"parameter", "body", "span", "chord", "direction", "law", "ramp_time"}
_JOINT_KEYS = {
    "clamp": {"type", "body"},
    "pin": {"type", "body", "axis"},
    "driven": {"type", "body", "law", "omega", "ramp_time"},
    "hinge": {"type", "name", "parent", "child", "initial_angle_deg", "stiffness", "damping", "torque",
              "stop_angle_deg", "latch_factor"},
}
_MOTION_KEYS = {"heave_amplitude", "pitch_amplitude_deg", "frequency", "phase_deg", "pitch_axis_position",
                "heave_axis", "alpha_deg"}


class Topology:
    """Nodes, elements, bodies and joints of a scene, and the affine map q, p(t) -> E."""

    def __init__(self):
        self.bodies: dict[str, Body] = {}
        self.node_names: list[str] = []
        self.node_initial: list[np.ndarray] = []      # (3, 3) r, r_x, r_y per node
        self.element_nodes: list[tuple[int, int]] = []
        self.element_body: list[str] = []
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
        self.fidelity = "flexible"

    # ------------------------------------------------------------------ construction
    @classmethod
    def from_scene(cls, scene: dict) -> "Topology":
        """Build the topology of `scene["structure"]`; raises SceneError naming the key."""
        top = cls()
        structure = scene.get("structure")
        if not isinstance(structure, dict):
            raise SceneError("structure", structure, "a table describing bodies and joints")
        top.fidelity = structure.get("fidelity", "flexible")
        if top.fidelity not in ("prescribed", "rigid", "flexible"):
            raise SceneError("structure.fidelity", top.fidelity, "one of prescribed, rigid, flexible")
        n_el = structure.get("elements_per_body", 4)
        if isinstance(n_el, bool) or not isinstance(n_el, int) or n_el < 1:
            raise SceneError("structure.elements_per_body", n_el, "an integer >= 1")
        if top.fidelity != "flexible":
            n_el = 1   # 000 Sec. IV: one element per rigid body
        bodies = structure.get("bodies")
        if not isinstance(bodies, list) or not bodies:
            raise SceneError("structure.bodies", bodies, "a non-empty array of body tables")
        specs = {}
        for i, spec in enumerate(bodies):
            key = f"structure.bodies[{i}]"
            if not isinstance(spec, dict):
                raise SceneError(key, spec, "a table")
            reject_unknown_keys(spec, key, _BODY_KEYS)
            name = spec.get("name")
            if not isinstance(name, str) or not name or name in specs:
                raise SceneError(f"{key}.name", name, "a unique non-empty body name")
            specs[name] = (key, spec)
        joints = top._parse_joints(structure.get("joints", []), specs)
        gravity = structure.get("gravity", [0.0, 0.0, 0.0])
        _vector("structure.gravity", gravity)
        motion_spec = structure.get("motion")
        if top.fidelity == "prescribed" and not isinstance(motion_spec, dict):
            raise SceneError("structure.motion", motion_spec, "a table with the prescribed heave/pitch law")
        for name in top._body_order(specs, joints):
            top._add_body(name, specs[name], joints, n_el, motion_spec)
        top._add_constraints()
        top._add_masses_and_loads(structure)
        if "load" in scene:
            top._add_load_case(scene["load"])
        return top

    def _parse_joints(self, joints, specs):
        if not isinstance(joints, list):
            raise SceneError("structure.joints", joints, "an array of joint tables")
        root_joint, parent_of = {}, {}
        for i, spec in enumerate(joints):
            key = f"structure.joints[{i}]"
            kind = spec.get("type") if isinstance(spec, dict) else None
            if kind not in _JOINT_KEYS:
                raise SceneError(f"{key}.type", kind, f"one of {sorted(_JOINT_KEYS)}")
            reject_unknown_keys(spec, key, _JOINT_KEYS[kind])
            bodies = [spec.get("parent"), spec.get("child")] if kind == "hinge" else [spec.get("body")]
            for field_name, body in zip(("parent", "child") if kind == "hinge" else ("body",), bodies):
                if body not in specs:
                    raise SceneError(f"{key}.{field_name}", body, f"one of the bodies {sorted(specs)}")
            target = spec["child"] if kind == "hinge" else spec["body"]
            if target in root_joint:
                raise SceneError(key, target, "a body root can carry only one clamp, pin, driven or hinge joint")
            root_joint[target] = (key, spec)
            if kind == "hinge":
                if spec["parent"] == spec["child"]:
                    raise SceneError(f"{key}.child", spec["child"], "a body other than the parent")
                parent_of[spec["child"]] = spec["parent"]
        return {"root": root_joint, "parent": parent_of}

    def _body_order(self, specs, joints):
        order, placed = [], set()
        while len(order) < len(specs):
            progress = False
            for name in specs:
                parent = joints["parent"].get(name)
                if name not in placed and (parent is None or parent in placed):
                    order.append(name)
                    placed.add(name)
                    progress = True
            if not progress:
                loop = sorted(set(specs) - placed)
                raise SceneError("structure.joints", loop, "hinges must form a tree (no closed loops)")
        return order

    def _new_free(self, value):
        self.free_initial.append(np.asarray(value, float))
        return _Slot(free={len(self.free_initial) - 1: 1.0})

    def _new_prescribed(self, value, is_position, motion):
        self.prescribed_initial.append(np.asarray(value, float))
        self.prescribed_is_position.append(is_position)
        self.prescribed_motion.append(motion)
        return _Slot(prescribed={len(self.prescribed_initial) - 1: 1.0})

    def _add_body(self, name, key_spec, joints, n_el, motion_spec):
        key, spec = key_spec
        length = _number(f"{key}.length", spec.get("length"), "a length > 0 (m)", lambda v: v > 0)
        section = section_from_scene(f"{key}.section", spec.get("section"))
        damping = _number(f"{key}.damping", spec.get("damping", 0.0), "a damping alpha >= 0 (1/s)", lambda v: v >= 0)
        joint_key, joint = joints["root"].get(name, (None, None))
        kind = joint["type"] if joint else None
        if kind == "hinge":
            parent = self.bodies[joint["parent"]]
            tip = parent.nodes[-1]
            r0, x_parent, y0 = self.node_initial[tip]
            angle = np.radians(_number(f"{joint_key}.initial_angle_deg", joint.get("initial_angle_deg", 0.0)))
            y_unit = y0 / np.linalg.norm(y0)
            x0 = rotation_about(y_unit, angle) @ x_parent
            if "root" in spec or "span_axis" in spec:
                raise SceneError(f"{key}.root", spec.get("root", spec.get("span_axis")),
                                 "not allowed: a hinged body starts at its parent's tip")
        else:
            r0 = _vector(f"{key}.root", spec.get("root", [0.0, 0.0, 0.0]))
            x0 = _vector(f"{key}.span_axis", spec.get("span_axis", [1.0, 0.0, 0.0]), unit=True)
            y_raw = _vector(f"{key}.chord_axis", spec.get("chord_axis", [0.0, 1.0, 0.0]), unit=True)
            if abs(x0 @ y_raw) > 1e-9:
                raise SceneError(f"{key}.chord_axis", spec.get("chord_axis"), "a direction perpendicular to span_axis")
            y0 = y_raw
        x0 = x0 / np.linalg.norm(x0)
        if "angular_velocity" in spec:
            self.angular_velocity[name] = _vector(f"{key}.angular_velocity", spec["angular_velocity"])
        n_nodes = n_el + 1
        first_node = len(self.node_names)
        body = Body(name, length, section, damping, [], [])
        for i in range(n_nodes):
            self.node_names.append(f"{name}.{i}")
            self.node_initial.append(np.array([r0 + x0 * length * i / n_el, x0, y0]))
            body.nodes.append(first_node + i)
        # root node slots
        motion = None
        if self.fidelity == "prescribed":
            motion = self._prescribed_motion(motion_spec, r0, x0, y0, section)
        elif kind == "clamp":
            motion = len(self.motions)
            self.motions.append(Fixed())
        elif kind == "driven":
            if joint.get("law", "spin_up") != "spin_up":
                raise SceneError(f"{joint_key}.law", joint.get("law"), "spin_up (000 Eq. 27)")
            omega = _number(f"{joint_key}.omega", joint.get("omega"), "an angular speed (rad/s)")
            ramp = _number(f"{joint_key}.ramp_time", joint.get("ramp_time"), "a time > 0 (s)", lambda v: v > 0)
            motion = len(self.motions)
            self.motions.append(SpinUp(y0, r0, omega, ramp))
        if motion is not None:
            root = [self._new_prescribed(r0, True, motion), self._new_prescribed(x0, False, motion),
                    self._new_prescribed(y0, False, motion)]
        elif kind == "hinge":
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
        for i in range(1, n_nodes):
            if self.fidelity == "flexible":
                r_i, x_i, y_i = self.node_initial[first_node + i]
                self.slots += [self._new_free(r_i), self._new_free(x_i), self._new_free(y_i)]
            else:   # rigid or prescribed: linear rows of 000 Eq. (17)
                self.slots += [root[R].plus(root[RX], length), root[RX], root[RY]]
        for i in range(n_el):
            body.elements.append(len(self.element_nodes))
            self.element_nodes.append((first_node + i, first_node + i + 1))
            self.element_body.append(name)
        self.bodies[name] = body

    def _prescribed_motion(self, spec, r0, x0, y0, section):
        reject_unknown_keys(spec, "structure.motion", _MOTION_KEYS)
        key = "structure.motion"
        get = lambda name, default: _number(f"{key}.{name}", spec.get(name, default))
        heave_axis = _vector(f"{key}.heave_axis", spec.get("heave_axis", list(np.cross(x0, y0))), unit=True)
        pivot_fraction = get("pitch_axis_position", section.axis_position)
        pivot = r0 + y0 * section.chord_offset(pivot_fraction)
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
        name = spec.get("name")
        if not isinstance(name, str) or not name or any(h.name == name for h in self.hinges):
            raise SceneError(f"{key}.name", name, "a unique non-empty hinge name")
        stiffness = _number(f"{key}.stiffness", spec.get("stiffness", 0.0), "K >= 0 (N m/rad)", lambda v: v >= 0)
        damping = _number(f"{key}.damping", spec.get("damping", 0.0), "C >= 0 (N m s/rad)", lambda v: v >= 0)
        torque = _number(f"{key}.torque", spec.get("torque", 0.0), "T_const (N m)")
        stop = spec.get("stop_angle_deg")
        # in (-180, 180) deg like the fold angle itself, which wraps at +-180 (a stop outside is never reached)
        stop = None if stop is None else np.radians(_number(f"{key}.stop_angle_deg", stop, "an angle in (-180, 180) deg",
                                                            lambda v: -180 < v < 180))
        latch = _number(f"{key}.latch_factor", spec.get("latch_factor", 1e4), "a factor >= 1", lambda v: v >= 1)
        initial = np.radians(_number(f"{key}.initial_angle_deg", spec.get("initial_angle_deg", 0.0),
                                     "an angle in (-180, 180) deg", lambda v: -180 < v < 180))
        self.hinges.append(Hinge(name, 3 * tip_node + RX, 3 * root_node + RX, 3 * tip_node + RY, initial,
                                 stiffness, damping, torque, stop, latch))

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
            mass = _number(f"{item}.mass", spec.get("mass"), "a mass > 0 (kg)", lambda v: v > 0)
            self.masses.append((self._node_at(f"{item}.span", spec["body"], spec.get("span", 0.0)), mass))
        for i, spec in enumerate(structure.get("loads", [])):
            item = key or f"structure.loads[{i}]"
            if spec.get("body") not in self.bodies:
                raise SceneError(f"{item}.body", spec.get("body"), f"one of the bodies {sorted(self.bodies)}")
            body = self.bodies[spec["body"]]
            span = _number(f"{item}.span", spec.get("span"), f"0 <= span <= {body.length} (m)",
                           lambda v: 0 <= v <= body.length)
            chord = spec.get("chord", body.section.axis_position)
            law = spec.get("law", "constant")
            if law not in ("constant", "cosine_ramp"):
                raise SceneError(f"{item}.law", law, "constant or cosine_ramp (000 Eq. 26)")
            ramp = _number(f"{item}.ramp_time", spec.get("ramp_time", 1.0), "a time > 0 (s)", lambda v: v > 0)
            index, x, y = self.locate(spec["body"], span, _number(f"{item}.chord", chord))
            self.loads.append({"element": index, "x": x, "y": y, "law": law, "ramp_time": ramp,
                               "force": _vector(f"{item}.force", spec.get("force"))})

    def _add_load_case(self, spec):
        """`[load]`: a point load given by the non-dimensional parameter P L^2 / (EI_yy) of its body."""
        if not isinstance(spec, dict):
            raise SceneError("load", spec, "a table with parameter, direction and optionally body, span, law")
        reject_unknown_keys(spec, "load", _LOAD_KEYS)
        body_name = spec.get("body", list(self.bodies)[-1])
        if body_name not in self.bodies:
            raise SceneError("load.body", body_name, f"one of the bodies {sorted(self.bodies)}")
        body = self.bodies[body_name]
        parameter = _number("load.parameter", spec.get("parameter"), "P L^2 / (E I) >= 0", lambda v: v >= 0)
        direction = _vector("load.direction", spec.get("direction"), unit=True)
        magnitude = parameter * body.section.flap / body.length**2
        load = {"body": body_name, "span": spec.get("span", body.length), "force": list(magnitude * direction),
                "law": spec.get("law", "constant"), "ramp_time": spec.get("ramp_time", 1.0)}
        if "chord" in spec:
            load["chord"] = spec["chord"]
        self._add_masses_and_loads({"loads": [load]}, key="load")

    # ------------------------------------------------------------------ queries
    @property
    def n_nodes(self):
        return len(self.node_names)

    @property
    def n_coordinates(self):
        return 9 * self.n_nodes

    @property
    def n_free(self):
        return 3 * len(self.free_initial)

    @property
    def hinge_names(self):
        return [h.name for h in self.hinges]

    def element_lengths(self):
        return np.array([self.bodies[b].length / len(self.bodies[b].elements) for b in self.element_body])

    def element_dofs(self):
        """E indices of each element's 18 coordinates, (n_elements, 18)."""
        a, b = np.array(self.element_nodes).T
        base = np.arange(9)
        return np.concatenate([9 * a[:, None] + base, 9 * b[:, None] + base], axis=1)

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

    def initial_coordinates(self):
        """E at t = 0 from the scene geometry, (9 n_nodes,)."""
        return np.concatenate([v.ravel() for v in self.node_initial])

    def locate(self, body_name, span, chord_fraction):
        """(element index, x (m), y (m)) of a material point given by span (m) and chord fraction."""
        body = self.bodies[body_name]
        n_el = len(body.elements)
        l_el = body.length / n_el
        k = min(int(span / l_el), n_el - 1)
        return body.elements[k], span - k * l_el, body.section.chord_offset(chord_fraction)

    def point_rows(self, body, span, chord_fraction=0.0):
        """Scalar shape rows (4, 3 n_nodes) of the material point at `span` (m) and `chord_fraction` of
        `body`, acting on X = E.reshape(-1, 3) (000 Eq. 2, S = kron(s, I_3)): rows @ X gives its position
        r(x, y) (m), and on the reference line at that span r' (-), r'' (1/m) along the span and r_y (-)."""
        k, x, y = self.locate(body, span, chord_fraction)
        a, b = self.element_nodes[k]
        length = self.bodies[body].length / len(self.bodies[body].elements)
        _, dN, ddN, L = element.hermite(x / length, length)
        rows = np.zeros((4, 6))                     # on the element's [r^A, r_x^A, r_y^A, r^B, r_x^B, r_y^B]
        rows[0] = element.shape_row(x, y, length)
        rows[1:3, [0, 1, 3, 4]] = dN, ddN
        rows[3, [2, 5]] = L
        out = np.zeros((4, 3 * self.n_nodes))
        out[:, [3 * a, 3 * a + 1, 3 * a + 2, 3 * b, 3 * b + 1, 3 * b + 2]] = rows
        return out

    def point_position(self, e, body, span, chord_fraction):
        """Global position (m) of the material point at `span` (m) and `chord_fraction` of `body`."""
        return self.point_rows(body, span, chord_fraction)[0] @ np.asarray(e, dtype=float).reshape(-1, 3)

    def fold_angles(self, e):
        """Fold angle of each hinge (rad): angle from the parent's tip r_x to the child's r_x about r_y."""
        e = np.asarray(e)
        return {h.name: fold_angle(e[hinge_coordinates(h)]) for h in self.hinges}

    @property
    def topology_hash(self):
        """Hex digest of what both units must agree on: nodes, elements, lengths, chords, axes."""
        data = {
            "nodes": self.node_names,
            "elements": self.element_nodes,
            "bodies": {n: [b.length, b.section.chord, b.section.axis_position, len(b.elements)]
                       for n, b in self.bodies.items()},
            "hinges": self.hinge_names,
        }
        return hashlib.sha256(json.dumps(data, sort_keys=True).encode()).hexdigest()[:16]
