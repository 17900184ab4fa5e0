"""The `structure` table of a resolved scene as frozen, typed specs: bodies with their sections, joints with their
actuators, lumped masses, point loads, the `[load]` case and the prescribed motion.

Read once from the resolved scene (`StructureSpec.from_scene`, fmu_common.scene_schema.resolve_scene), so that
the units never parse the scene dict. SI units (m, kg, N, s); angles in degrees where a field says `_deg`;
vectors are tuples of 3 floats in the global frame unless a field says otherwise. Every item keeps `key`, its
dotted scene key (`structure.bodies.outer`), so that an error names what the user wrote. Defaults are those the
resolved scene holds: nothing is filled in here.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

from .choices import Fidelity, fidelity
from .scene_bounds import body_elements
from .scene_schema import TAPERED
from .schema import item_label

Vector = tuple[float, float, float]


def _vector(value) -> Vector | None:
    return None if value is None else tuple(value)


@dataclass(frozen=True)
class SectionSpec:
    """A body's cross-section table: chord c (m), reference line at axis_position a (fraction of the chord from
    the leading edge), torsional rigidity GJ (N m^2), rotary inertia rho I_yy (kg m); a rectangular plate
    (thickness h, m; density rho, kg/m^3; Young's modulus E, Pa; Poisson's ratio nu) and explicit properties EA
    (N), EI_yy, EI_zz (N m^2), rho A (kg/m), each None when not given (structure_fmu.section derives the missing
    ones); `tips` the tip values of the keys of scene_schema.TAPERED that vary linearly along the body
    ((name, value) pairs, each given as `<name>_tip`; empty: a constant section)."""

    key: str
    chord: float
    axis_position: float
    torsional_rigidity: float
    thickness: float | None
    density: float | None
    youngs_modulus: float | None
    axial_stiffness: float | None
    bending_stiffness_flap: float | None
    bending_stiffness_chord: float | None
    mass_per_length: float | None
    rotary_inertia: float
    poissons_ratio: float = 0.0
    tips: tuple = ()

    def tip(self, name: str) -> float | None:
        """The value of the property `name` at the tip: its `<name>_tip`, else the root's (None where the root's is
        not given).

        Args:
            name: a key of scene_schema.TAPERED.
        """
        return dict(self.tips).get(name, getattr(self, name))

    @classmethod
    def from_table(cls, key: str, table: dict) -> "SectionSpec":
        """The spec of a resolved section table.

        Args:
            key: the table's dotted key, for errors.
            table: the resolved section table, SI units.
        """
        return cls(key, table["chord"], table["axis_position"], table["torsional_rigidity"], table["thickness"],
                   table["density"], table["youngs_modulus"], table["axial_stiffness"],
                   table["bending_stiffness_flap"], table["bending_stiffness_chord"], table["mass_per_length"],
                   table["rotary_inertia"], table["poissons_ratio"],
                   tuple((name, table[f"{name}_tip"]) for name in TAPERED if table.get(f"{name}_tip") is not None))


@dataclass(frozen=True)
class PlanformSpec:
    """A body's planform keys (docs/aero.md, Planform) beside its section's chords (SectionSpec.chord and its tip):
    leading-edge sweep_deg (deg; None: the reference line at axis_position of every chord), twist_deg of the tip
    relative to the root (deg, nose up), dihedral_deg (deg, a tilt of span_axis about chord_axis) and the camber
    line `airfoil` (a NACA 4-digit designation; None: flat)."""

    sweep_deg: float | None = None
    twist_deg: float = 0.0
    dihedral_deg: float = 0.0
    airfoil: str | None = None

    @classmethod
    def from_table(cls, body: dict) -> "PlanformSpec":
        """The planform keys of a resolved body table.

        Args:
            body: the resolved body table.
        """
        return cls(body["sweep_deg"], body["twist_deg"], body["dihedral_deg"], body["section"]["airfoil"])


@dataclass(frozen=True)
class BodySpec:
    """A body: length (m) along the span, `elements` ANCF elements (its own count, else the fidelity's: the
    count the topology builds), damping alpha (1/s); at t = 0 its root (m), span_axis and chord_axis (-), each
    None for a jointed child (its parent's tip frame gives them; a given chord_axis is checked), and an initial
    rigid rotation rate angular_velocity (rad/s, about the root) or None; its planform (PlanformSpec)."""

    key: str
    name: str
    length: float
    elements: int
    damping: float
    root: Vector | None
    span_axis: Vector | None
    chord_axis: Vector | None
    angular_velocity: Vector | None
    section: SectionSpec
    planform: PlanformSpec = PlanformSpec()


# --- joints ----------------------------------------------------------------------------------------

@dataclass(frozen=True)
class JointSpec:
    """A joint of structure.joints; `kind` is its scene `type`."""

    kind: ClassVar[str] = ""
    key: str

    def holds_root(self) -> bool:
        """Whether the joint holds its body's root (at most one per root): a clamp, a driven root, a revolute,
        ball or universal joint, or a pin of the root node to the ground; not a slider, nor a pin elsewhere or
        between two bodies."""
        return True

    def body_references(self) -> tuple[tuple[str, str], ...]:
        """(field, body name) of every body the joint names."""
        return ()


@dataclass(frozen=True)
class ClampSpec(JointSpec):
    """The root node of `body` is fixed."""

    kind: ClassVar[str] = "clamp"
    body: str

    def body_references(self):
        return (("body", self.body),)


@dataclass(frozen=True)
class DrivenSpec(JointSpec):
    """The root of `body` turns about its chord axis r_y by the spin-up law (Otsuka et al. 2019, Eq. 27) to the
    final speed omega (rad/s) in ramp_time (s)."""

    kind: ClassVar[str] = "driven"
    body: str
    law: str
    omega: float
    ramp_time: float

    def body_references(self):
        return (("body", self.body),)


@dataclass(frozen=True)
class PinSpec(JointSpec):
    """A point shared by the node of `body` at `span` (m) and the node of `other` at other_span (m), or fixed in
    space (other None), turning about `axis`: "chord", "normal" or "free" (Peng et al. 2019, Eqs. 13-14)."""

    kind: ClassVar[str] = "pin"
    name: str | None
    body: str
    span: float
    other: str | None
    other_span: float
    axis: str

    def holds_root(self):
        return self.other is None and self.span == 0.0

    def body_references(self):
        return (("body", self.body), ("other", self.other))


@dataclass(frozen=True)
class SliderSpec(JointSpec):
    """The node of `body` at `span` (m) stays on a line (direction `line`) or a plane (plane_normal) through its
    position at t = 0: global components, or with `other` components along the span, chord and normal of that
    body's node at other_span (m)."""

    kind: ClassVar[str] = "slider"
    name: str
    body: str
    span: float
    line: Vector | None
    plane_normal: Vector | None
    other: str | None
    other_span: float

    def holds_root(self):
        return False

    def body_references(self):
        return (("body", self.body), ("other", self.other))


@dataclass(frozen=True)
class ActuatorSpec:
    """A revolute joint's spring actuator (Otsuka et al. 2022, Secs. 3.1, 5): torque K theta + C dtheta/dt +
    T_const acting to decrease the fold angle theta; stiffness K (N m/rad), damping C (N m s/rad), torque T_const
    (N m); latch: once theta reaches stop_angle_deg (deg; None: no latch), K is multiplied by latch_factor."""

    stiffness: float
    damping: float
    torque: float
    stop_angle_deg: float | None
    latch_factor: float


@dataclass(frozen=True)
class ParentJointSpec(JointSpec):
    """A joint between the tip of `parent` (None: the ground) and the root of `child`; orientation_deg is the
    child's initial orientation relative to the parent's tip frame, a rotation vector (deg) in that frame's span,
    chord, normal components (fmu_common.topology.JointLine)."""

    name: str
    parent: str | None
    child: str
    orientation_deg: Vector

    def body_references(self):
        return (("parent", self.parent), ("child", self.child))


@dataclass(frozen=True)
class RevoluteSpec(ParentJointSpec):
    """A revolute joint about `axis` (parent tip span, chord, normal components; with the ground global), its fold
    angle initial_angle_deg (deg) at t = 0 and its actuator (Otsuka et al. 2022, Sec. 3.1)."""

    kind: ClassVar[str] = "revolute"
    axis: Vector
    initial_angle_deg: float
    actuator: ActuatorSpec


@dataclass(frozen=True)
class BallSpec(ParentJointSpec):
    """A ball joint: the child's root shares the parent's tip point (Otsuka et al. 2022, Sec. 3.3)."""

    kind: ClassVar[str] = "ball"


@dataclass(frozen=True)
class UniversalSpec(ParentJointSpec):
    """A universal joint: shared point, parent_axis (parent tip frame components) perpendicular to child_axis
    (child root frame components) (Otsuka et al. 2022, Sec. 3.2, Eq. 18)."""

    kind: ClassVar[str] = "universal"
    parent_axis: Vector
    child_axis: Vector


def joint_spec(key: str, table: dict) -> JointSpec:
    """The JointSpec of the resolved joint table.

    Args:
        key: the table's dotted key.
        table: the resolved joint table.
    """
    kind = table["type"]
    if kind == "clamp":
        return ClampSpec(key, table["body"])
    if kind == "driven":
        return DrivenSpec(key, table["body"], table["law"], table["omega"], table["ramp_time"])
    if kind == "pin":
        return PinSpec(key, table["name"], table["body"], table["span"], table["other"], table["other_span"],
                       table["axis"])
    if kind == "slider":
        return SliderSpec(key, table["name"], table["body"], table["span"], _vector(table["line"]),
                          _vector(table["plane_normal"]), table["other"], table["other_span"])
    common = (key, table["name"], table["parent"], table["child"], _vector(table["orientation_deg"]))
    if kind == "revolute":
        actuator = ActuatorSpec(table["stiffness"], table["damping"], table["torque"], table["stop_angle_deg"],
                                table["latch_factor"])
        return RevoluteSpec(*common, _vector(table["axis"]), table["initial_angle_deg"], actuator)
    if kind == "ball":
        return BallSpec(*common)
    return UniversalSpec(*common, _vector(table["parent_axis"]), _vector(table["child_axis"]))


# --- masses, loads, motion --------------------------------------------------------------------------

@dataclass(frozen=True)
class MassSpec:
    """A lumped mass (kg) at the node of `body` at `span` (m from its root)."""

    key: str
    body: str
    span: float
    mass: float


@dataclass(frozen=True)
class LoadSpec:
    """A point force (N, global frame) at `span` (m from the root of `body`) and `chord` (fraction of the chord
    from the leading edge): constant from t = 0, or with ramp_time t_s (s) the cosine ramp
    F (1 - cos(pi t / t_s)) / 2 up to t_s (Otsuka et al. 2019, Eq. 26); ramp_time None for a constant load."""

    key: str
    body: str
    span: float
    chord: float
    force: Vector
    ramp_time: float | None


@dataclass(frozen=True)
class LoadCaseSpec:
    """The `[load]` case: a point load of magnitude P = parameter EI_yy / L^2 of its body (flap stiffness EI_yy,
    length L) along `direction` (global), at `span` (m) and `chord` (fraction) of `body`, constant or with the
    cosine ramp of ramp_time (s; None: constant), as `LoadSpec`."""

    key: str
    parameter: float
    direction: Vector
    body: str
    span: float
    chord: float
    ramp_time: float | None


@dataclass(frozen=True)
class MotionSpec:
    """`structure.motion`, the law every body follows in the prescribed fidelity: heave h(t) = heave_amplitude
    (m) sin(frequency t) along heave_axis (None: each body's section normal), pitch pitch_amplitude_deg (deg)
    sin(frequency t + phase_deg) about the span axis through pitch_axis_position (fraction of the chord; None:
    each body's reference line); frequency in rad/s; alpha_deg a constant nose-up pitch (deg)."""

    key: str
    heave_amplitude: float
    pitch_amplitude_deg: float
    frequency: float
    phase_deg: float
    pitch_axis_position: float | None
    heave_axis: Vector | None
    alpha_deg: float


def _ramp(table: dict) -> float | None:
    return table["ramp_time"] if table["law"] == "cosine_ramp" else None


# --- the structure table ------------------------------------------------------------------------------

@dataclass(frozen=True)
class StructureSpec:
    """The resolved `structure` table and the `[load]` case: the fidelity (its traits, fmu_common.choices),
    elements_per_body, the integrator's name (structure_fmu.integrators), internal step (s), rho_inf of
    generalized-alpha, damping_model, gravity (m/s^2, global), and the tables in the scene's order (bodies as
    written: a hinge's parent need not come first)."""

    fidelity: Fidelity
    elements_per_body: int
    integrator: str
    step: float
    rho_inf: float
    damping_model: str
    gravity: Vector
    bodies: tuple[BodySpec, ...]
    joints: tuple[JointSpec, ...]
    masses: tuple[MassSpec, ...]
    loads: tuple[LoadSpec, ...]
    motion: MotionSpec | None
    load_case: LoadCaseSpec | None

    @classmethod
    def from_scene(cls, scene: dict) -> "StructureSpec":
        """The spec of the resolved scene's `structure` table and its `[load]` case.

        Args:
            scene: the resolved scene.
        """
        structure = scene["structure"]
        bodies = []
        for i, body in enumerate(structure["bodies"]):
            key = f"structure.bodies.{item_label(i, body)}"
            bodies.append(BodySpec(key, body["name"], body["length"], body_elements(structure, body), body["damping"],
                                   _vector(body["root"]), _vector(body["span_axis"]), _vector(body["chord_axis"]),
                                   _vector(body["angular_velocity"]),
                                   SectionSpec.from_table(f"{key}.section", body["section"]),
                                   PlanformSpec.from_table(body)))
        joints = [joint_spec(f"structure.joints.{item_label(i, joint)}", joint)
                  for i, joint in enumerate(structure["joints"])]
        masses = [MassSpec(f"structure.masses.{i}", m["body"], m["span"], m["mass"])
                  for i, m in enumerate(structure["masses"])]
        loads = [LoadSpec(f"structure.loads.{i}", load["body"], load["span"], load["chord"], _vector(load["force"]),
                          _ramp(load)) for i, load in enumerate(structure["loads"])]
        motion = structure.get("motion")          # optional tables: absent unless given
        if motion is not None:
            motion = MotionSpec("structure.motion", motion["heave_amplitude"], motion["pitch_amplitude_deg"],
                                motion["frequency"], motion["phase_deg"], motion["pitch_axis_position"],
                                _vector(motion["heave_axis"]), motion["alpha_deg"])
        case = scene.get("load")
        if case is not None:
            case = LoadCaseSpec("load", case["parameter"], _vector(case["direction"]), case["body"], case["span"],
                                case["chord"], _ramp(case))
        return cls(fidelity(structure["fidelity"]), structure["elements_per_body"], structure["integrator"],
                   structure["step"], structure["rho_inf"], structure["damping_model"],
                   _vector(structure["gravity"]), tuple(bodies), tuple(joints), tuple(masses), tuple(loads), motion,
                   case)

    def revolutes(self) -> list[RevoluteSpec]:
        """The revolute joints, in the scene's order."""
        return [j for j in self.joints if isinstance(j, RevoluteSpec)]
