"""The scene schema: every key of a scene file, declared once, and `resolve_scene`, which checks a raw scene
against it and returns the resolved scene.

SI units throughout (s, m, kg, N, Pa, m/s, kg/m^3); angles in degrees where the key says `_deg`. Each key
has a type, a unit, a default (or is required), what is allowed and a one-line description; docs/scenes.md
is generated from these declarations (`orchestrator.scene.docs`). Numbers are finite unless a key says inf
is allowed. The resolved scene is a plain, JSON-serialisable dict with every key present (None where a key
has no value, e.g. a hinge without a stop) and every default filled, also the defaults that depend on
another table (a probe's chord is its body's axis position); optional tables ([structure.motion], [load],
[wing], [motion]) are absent when not given. The units receive it complete and set no defaults of their own.

What `resolve_scene` checks: types, ranges, unknown keys (everywhere), unique names, the rules inside one
table (a plate section needs all three of thickness, density and Young's modulus), references that a
default needs (a probe's body), and the size bounds (`fmu_common.scene_bounds`); it expands the scissor chains
of `structure.scissors` into bodies, joints and probes (`fmu_common.scissors`). The relations between tables
that building the units checks stay there: a joint's bodies exist, parent-child joints form a tree, a body root
carries one joint, a mass, pin or slider sits at a node and a pin's two nodes coincide (`fmu_common.topology`,
`structure_fmu.topology`, `structure_fmu.pins`), and a probe lies within its body (`orchestrator.scene.load`).
"""
from __future__ import annotations

import copy

import numpy as np

from . import choices
from .errors import SceneError
from .scene_bounds import (DENSE_AERO, DENSE_STRUCTURE, MAX_CHORDWISE_PANELS, MAX_COUPLING_ITERATIONS,
                           MAX_ELEMENTS_PER_BODY, MAX_SPANWISE_PANELS, MAX_WAKE_ROWS, check_sizes)
from .airfoil import naca_camber
from .planform import Planform
from .scissors import expand_scissors
from .vectors import unit
from .fmi_units import fmi_unit
from .schema import (MISSING, REQUIRED, Absent, Choice, Integer, Name, Number, Table, Tables, Text, Variants,
                     Vector, is_number, item_label)

ALGORITHMS = ("gauss-seidel", "jacobi", "implicit")
ACCELERATIONS = ("aitken", "iqn-ils")
AERO_MODELS = tuple(choices.AERO_MODELS)
SPAN_CORRECTIONS = ("helmbold", "none")
WAKE_FAR_FIELDS = ("treecode", "exact")
FIDELITIES = tuple(choices.FIDELITIES)
PARENT_JOINTS = ("revolute", "ball", "universal")
PIN_AXES = ("chord", "normal", "free")
SCISSOR_ENDS = ("free", "pin", "slide_across", "slide_along")
MAX_SCISSORS = 50
"""The joint types that may join a parent body's tip to a child's root (the others hold a root to the ground)."""
INTEGRATORS = choices.INTEGRATORS
GAUGE_CURVATURES = ("model", "cubic")
DAMPING_MODELS = ("deformation", "mass-proportional")
PROBE_RECORDS = ("position", "velocity", "acceleration")
MONITOR_RECORDS = ("all", "constraints")

PLATE = ("thickness", "density", "youngs_modulus")
EXPLICIT = ("axial_stiffness", "bending_stiffness_flap", "bending_stiffness_chord", "mass_per_length")
TAPERED = ("chord", "thickness", "torsional_rigidity", "rotary_inertia", *EXPLICIT)
"""The section keys that may vary linearly along a body: each has a key `<name>_tip` with its tip value."""


def positive(unit, doc, default=REQUIRED, **options):
    """A Number > 0.

    Args:
        unit: its unit.
        doc: its one-line description.
        default: REQUIRED, or the value when not given.
        **options: more Number fields (tunable, inf, why).
    """
    return Number(unit, default, doc, low=0.0, low_open=True, **options)


def non_negative(unit, doc, default=REQUIRED, tunable=False):
    """A Number >= 0.

    Args:
        unit: its unit.
        doc: its one-line description.
        default: REQUIRED, or the value when not given.
        tunable: whether it is an FMI parameter.
    """
    return Number(unit, default, doc, low=0.0, tunable=tunable)


def fraction(doc, default):
    """A Number in [0, 1], a fraction of the chord from the leading edge.

    Args:
        doc: its one-line description.
        default: the value when not given.
    """
    return Number("fraction of chord from the leading edge", default, doc, low=0.0, high=1.0)


def angle(doc, default, limit=180.0):
    """A Number of degrees in (-limit, limit).

    Args:
        doc: its one-line description.
        default: the value when not given, deg.
        limit: deg.
    """
    return Number("deg", default, doc, low=-limit, high=limit, low_open=True, high_open=True)


# --- rules inside one table -----------------------------------------------------------------------

def _section_rule(key: str, section: dict) -> None:
    """A plate needs all three plate keys; without a plate every explicit property is required."""
    plate = [name for name in PLATE if section[name] is not None]
    if plate and len(plate) < len(PLATE):
        missing = next(name for name in PLATE if section[name] is None)
        raise SceneError(f"{key}.{missing}", MISSING, f"required with {', '.join(plate)}: thickness, density and "
                                                      "youngs_modulus describe a rectangular plate together")
    if not plate:
        for name in EXPLICIT:
            if section[name] is None:
                raise SceneError(f"{key}.{name}", MISSING,
                                 "required unless thickness, density and youngs_modulus describe a plate")


def _tip_rule(key: str, section: dict) -> None:
    """A tip value varies a value given at the root: thickness_tip needs the plate's thickness, an explicit
    property's tip its root value (a plate-derived root would vary by the plate's formula, not linearly)."""
    for name in TAPERED:
        if section[f"{name}_tip"] is not None and section[name] is None:
            raise SceneError(f"{key}.{name}_tip", section[f"{name}_tip"],
                             f"absent unless {key}.{name} gives the root value it varies from")


def _airfoil_rule(key: str, section: dict) -> None:
    """A camber line the aero unit can build: a NACA 4-digit designation."""
    if section["airfoil"] is not None:
        try:
            naca_camber(section["airfoil"])
        except ValueError as error:
            raise SceneError(f"{key}.airfoil", section["airfoil"], str(error)) from None


def _planform_rule(key: str, body: dict) -> None:
    """The reference line (the beam) stays within the chord: a sweep that carries the leading edge behind it, or
    the trailing edge ahead of it, at the tip is refused."""
    section = body["section"]
    chord_tip = section["chord_tip"] if section["chord_tip"] is not None else section["chord"]
    planform = Planform.of(body["length"], section["chord"], chord_tip, section["axis_position"], body["sweep_deg"])
    lead = planform.leading_edge_tip
    if lead > 1e-12 * chord_tip or lead + chord_tip < -1e-12 * chord_tip:
        side = "leading edge lies behind" if lead > 0 else "trailing edge lies ahead of"
        raise SceneError(f"{key}.sweep_deg", body["sweep_deg"],
                         f"a sweep that keeps the reference line within the chord: at the tip the {side} it by "
                         f"{abs(lead if lead > 0 else lead + chord_tip):.4g} m (the lattice would leave the beam); "
                         "sweep the beam itself with span_axis or a joint's orientation_deg")


def _slider_rule(key: str, slider: dict) -> None:
    """A slider keeps its node on a line or on a plane: exactly one of the two."""
    given = [name for name in ("line", "plane_normal") if slider[name] is not None]
    if len(given) != 1:
        raise SceneError(f"{key}.line", slider["line"], "exactly one of line (the node stays on a line) and "
                                                       "plane_normal (on a plane)")


def _other_rule(key: str, joint: dict) -> None:
    """other_span places the joint on `other`: without `other` (the ground) it must stay 0."""
    if joint["other"] is None and joint["other_span"] != 0.0:
        raise SceneError(f"{key}.other_span", joint["other_span"], "0 without `other` (the ground has no nodes); "
                                                                  "give `other`, the body it is on")


def _motion_rule(key: str, motion: dict) -> None:
    """alpha_deg is a constant pitch: it excludes the oscillating pitch and the heave."""
    if motion["alpha_deg"] != 0.0:
        for other in ("pitch_amplitude_deg", "heave_amplitude"):
            if motion[other] != 0.0:
                raise SceneError(f"{key}.alpha_deg", motion["alpha_deg"],
                                 f"0 when {other} is given (alpha_deg is a constant pitch of a wing that does not "
                                 "heave; an oscillating pitch is pitch_amplitude_deg)")


# --- the declarations -----------------------------------------------------------------------------

SECTION = Table({
    "chord": positive("m", "chord c"),
    "chord_tip": positive("m", "chord at the tip; the chord varies linearly from section.chord at the root",
                          Absent("section.chord: a constant chord")),
    "axis_position": fraction("position a of the reference line (the beam axis)", 0.5),
    "torsional_rigidity": positive("N m^2", "GJ"),
    "torsional_rigidity_tip": positive("N m^2", "GJ at the tip; GJ varies linearly from the root's",
                                       Absent("section.torsional_rigidity: a constant GJ")),
    "thickness": positive("m", "plate thickness h", Absent("no plate: the explicit properties below")),
    "thickness_tip": positive("m", "plate thickness at the tip; h varies linearly from section.thickness at the "
                                   "root (the plate's properties follow their formulas of the local c and h)",
                              Absent("section.thickness: a constant thickness")),
    "density": positive("kg/m^3", "plate material density rho", Absent("no plate")),
    "youngs_modulus": positive("Pa", "plate Young's modulus E", Absent("no plate")),
    "axial_stiffness": positive("N", "EA; overrides the plate's", Absent("E c h of the plate")),
    "axial_stiffness_tip": positive("N", "EA at the tip; EA varies linearly from section.axial_stiffness at the "
                                         "root", Absent("section.axial_stiffness: a constant EA")),
    "bending_stiffness_flap": positive("N m^2", "EI_yy, out of the wing plane; overrides the plate's",
                                       Absent("E c h^3 / 12 of the plate")),
    "bending_stiffness_flap_tip": positive("N m^2", "EI_yy at the tip; EI_yy varies linearly from "
                                                    "section.bending_stiffness_flap at the root",
                                           Absent("section.bending_stiffness_flap: a constant EI_yy")),
    "bending_stiffness_chord": positive("N m^2", "EI_zz, in the chord plane; overrides the plate's",
                                        Absent("E h c^3 / 12 of the plate")),
    "bending_stiffness_chord_tip": positive("N m^2", "EI_zz at the tip; EI_zz varies linearly from "
                                                     "section.bending_stiffness_chord at the root",
                                            Absent("section.bending_stiffness_chord: a constant EI_zz")),
    "mass_per_length": positive("kg/m", "rho A, spread uniformly over the chord; overrides the plate's",
                                Absent("rho c h of the plate")),
    "mass_per_length_tip": positive("kg/m", "rho A at the tip; rho A varies linearly from section.mass_per_length "
                                            "at the root", Absent("section.mass_per_length: a constant rho A")),
    "poissons_ratio": Number("-", 0.0, "plate Poisson's ratio nu: the shear modulus G = E / (2 (1 + nu)) of "
                                      "structure.fidelity = 'shear-deformable' (0: Peng et al. 2019's)", low=0.0,
                             high=0.5, high_open=True),
    "rotary_inertia": non_negative("kg m", "rho I_yy: rotary inertia of the section about its chord axis per unit "
                                           "length (Otsuka et al. 2022, Table 4), kinetic energy 1/2 rho I_yy "
                                           "|dr'/dt|^2 (a thin plate's rho c h^3 / 12 is negligible)", 0.0),
    "rotary_inertia_tip": non_negative("kg m", "rho I_yy at the tip; rho I_yy varies linearly from "
                                               "section.rotary_inertia at the root",
                                       Absent("section.rotary_inertia: a constant rho I_yy")),
    "airfoil": Text("-", Absent("a flat plate: no camber"), "camber line of the aerodynamic surface: a NACA 4-digit "
                                                            "designation such as 'naca2412' (its thickness is not "
                                                            "modelled; docs/aero.md, Planform)"),
}, doc="Cross-section of the body: a rectangular plate (thickness, density, youngs_modulus) or explicit "
       "properties, which override the plate's; a key `*_tip` makes its property vary linearly along the body from "
       "the root's value to the tip's", rules=(_section_rule, _tip_rule, _airfoil_rule))

BODY = Table({
    "name": Name("-", REQUIRED, "body name, referenced by joints, masses, loads, probes and strain gauges"),
    "length": positive("m", "length along the span"),
    "root": Vector("m", Absent("[0, 0, 0]; a hinge's child starts at its parent's tip and takes none"),
                   "initial position of the root of the reference line (not for a hinge's child)"),
    "span_axis": Vector("-", Absent("[1, 0, 0]; a hinge's child: its parent's, turned by the hinge"),
                        "initial direction of r_x, the span (not for a hinge's child)", nonzero=True),
    "chord_axis": Vector("-", Absent("[0, 1, 0]; a hinge's child: its parent's, which the hinge shares"),
                         "direction of r_y from the leading to the trailing edge, perpendicular to span_axis "
                         "(a hinge's child: its parent's, if given)", nonzero=True),
    "damping": non_negative("1/s", "alpha: damping of deformation or of all motion (structure.damping_model)",
                            0.0, tunable=True),
    "elements": Integer("-", Absent("structure.elements_per_body; 1 in the rigid and prescribed fidelities"),
                        "elements along this body: a rigid body stays rigid whatever its count, its nodes are where "
                        "pins, sliders, masses and loads can sit", low=1, high=MAX_ELEMENTS_PER_BODY,
                        why=DENSE_STRUCTURE),
    "angular_velocity": Vector("rad/s", Absent("at rest"), "initial rigid rotation rate about the root, global "
                                                            "frame"),
    "sweep_deg": angle("leading-edge sweep: the angle in the body's plane from span_axis to the leading edge, "
                       "positive toward the trailing edge (the leading edge starts a c ahead of the root); the "
                       "reference line must stay within every chord (docs/aero.md, Planform)",
                       Absent("the reference line stays at section.axis_position of every chord"), limit=90.0),
    "twist_deg": angle("twist of the tip section relative to the root section, nose up, linear along the body, "
                       "about the reference line; a hinge's child starts with its parent's tip twist (a root body "
                       "with none)", 0.0, limit=90.0),
    "dihedral_deg": angle("tilt of span_axis about chord_axis toward the section normal span_axis x chord_axis "
                          "(not for a hinge's child: its joint's orientation_deg [0, -dihedral, 0] gives it)", 0.0,
                          limit=90.0),
    "section": SECTION,
}, rules=(_planform_rule,),
   doc="One table per body, in any order (a hinge's parent need not come first); `section.*` is the table "
       "`section = { ... }` of the body")

_BODY_REF = "name of a body of structure.bodies"
_JOINT_BODIES = {
    "parent": Name("-", Absent("the ground: the child's root stays at its `root`, its frame from its own axes"),
                   "the body at whose tip the joint sits"),
    "child": Name("-", REQUIRED, "the body whose root the joint carries"),
}
_ORIENTATION = Vector("deg", [0.0, 0.0, 0.0], "the child's initial orientation relative to the parent's tip frame, "
                                              "a rotation vector (axis x angle) in that frame's span, chord, normal "
                                              "components; with the ground it must stay 0 (the child's span_axis "
                                              "and chord_axis give it)")
JOINT = Variants("type", {
    "clamp": Table({"body": Name("-", REQUIRED, _BODY_REF)}, doc="the root node of `body` is fixed"),
    "pin": Table({
        "name": Name("-", Absent("unnamed: messages name it by its index"), "joint name"),
        "body": Name("-", REQUIRED, _BODY_REF),
        "span": non_negative("m", "position of the pinned node from the body root; must be a node of the body", 0.0),
        "other": Name("-", Absent("the ground: the point stays where it starts"),
                      "the body the point is shared with"),
        "other_span": non_negative("m", "position of the shared node on `other` from its root; must be a node", 0.0),
        "axis": Choice("-", "chord", "rotation axis: about the chord r_y (shared by the two nodes), about the "
                                     "section normal r_x x r_y, or free (a ball: only the point is shared)",
                       options=PIN_AXES),
    }, doc="a point shared by the node of `body` at `span` and the node of `other` at `other_span` (or fixed in "
           "space), free to rotate about one axis or fully (shared coordinates, Peng et al. 2019, Eqs. 13-14); "
           "the two nodes must coincide at t = 0", rules=(_other_rule,)),
    "driven": Table({
        "body": Name("-", REQUIRED, _BODY_REF),
        "law": Choice("-", "spin_up", "angle law: spin_up is Otsuka et al. 2019, Eq. 27", options=("spin_up",)),
        "omega": Number("rad/s", REQUIRED, "final angular speed"),
        "ramp_time": positive("s", "time to reach omega"),
    }, doc="the root of `body` is a clamp rotating about its chord axis r_y by the angle law"),
    "revolute": Table({
        "name": Name("-", REQUIRED, "joint name: the `fold_angle_<name>` column and the parameters "
                                    "`structure.joints.<name>.stiffness`, `.damping`, `.torque`"),
        **_JOINT_BODIES,
        "axis": Vector("-", [0.0, 1.0, 0.0], "rotation axis: components along the parent's tip span, chord and "
                                             "normal (with the ground: global); the default is the chord",
                       nonzero=True),
        "orientation_deg": _ORIENTATION,
        "initial_angle_deg": angle("fold angle at t = 0 (in (-180, 180) like the fold angle, which wraps at "
                                   "+-180)", 0.0),
        "stiffness": non_negative("N m/rad", "actuator stiffness K", 0.0, tunable=True),
        "damping": non_negative("N m s/rad", "actuator damping C", 0.0, tunable=True),
        "torque": Number("N m", 0.0, "actuator constant torque T_const", tunable=True),
        "stop_angle_deg": angle("latch: when the fold angle first reaches it, from either side, K is multiplied "
                                "by latch_factor (Otsuka et al. 2022, Sec. 5); the fold angle wraps at +-180, so "
                                "a stop outside (-180, 180) would never be reached", Absent("no latch")),
        "latch_factor": Number("-", 1e4, "factor on K once latched", low=1.0),
    }, doc="revolute joint (Otsuka et al. 2022, Sec. 3.1) between the tip of `parent` (or the ground) and the root "
           "of `child`, about `axis`; the fold angle theta turns the child about the axis (right hand), and the "
           "actuator torque K theta + C dtheta/dt + T_const acts to decrease it"),
    "ball": Table({
        "name": Name("-", REQUIRED, "joint name: its `<name>_point_mismatch` monitor"),
        **_JOINT_BODIES,
        "orientation_deg": _ORIENTATION,
    }, doc="ball joint (Otsuka et al. 2022, Sec. 3.3): the child's root shares the point of the parent's tip (or "
           "stays at its root position on the ground) and turns freely"),
    "universal": Table({
        "name": Name("-", REQUIRED, "joint name: its `<name>_point_mismatch` and `<name>_axis_product` monitors"),
        **_JOINT_BODIES,
        "parent_axis": Vector("-", [0.0, 1.0, 0.0], "the cross's axis fixed in the parent: components along its "
                                                    "tip span, chord and normal (with the ground: global)",
                              nonzero=True),
        "child_axis": Vector("-", [0.0, 0.0, 1.0], "the cross's axis fixed in the child: components along its root "
                                                   "span, chord and normal; perpendicular to parent_axis at t = 0",
                             nonzero=True),
        "orientation_deg": _ORIENTATION,
    }, doc="universal joint (Otsuka et al. 2022, Sec. 3.2, Eq. 18): shared point, and parent_axis stays "
           "perpendicular to child_axis"),
    "slider": Table({
        "name": Name("-", REQUIRED, "joint name"),
        "body": Name("-", REQUIRED, _BODY_REF),
        "span": non_negative("m", "position of the node from the body root; must be a node of the body", 0.0),
        "line": Vector("-", Absent("none: plane_normal gives a plane"), "direction of the line: global components, "
                       "or with `other` components along that node's span, chord and normal", nonzero=True),
        "plane_normal": Vector("-", Absent("none: line gives a line"), "normal of the plane; components as for "
                               "line", nonzero=True),
        "other": Name("-", Absent("the ground: the line or plane is fixed in space"),
                      "the body that carries the line or plane"),
        "other_span": non_negative("m", "the node of `other` whose frame carries the line or plane; must be a node",
                                   0.0),
    }, doc="the node of `body` at `span` stays on a line or plane through its position at t = 0, fixed in space or "
           "in the frame of a node of `other` (ANCF fidelities); it holds no root", rules=(_slider_rule, _other_rule)),
}, doc="what holds a body's root (at most one joint per root), a pin at any node, or a slider")

def _scissor_rule(key: str, chain: dict) -> None:
    """The height axis is perpendicular to the direction; bars have an even element count (a mid-length node)."""
    d, h = unit(chain["direction"]), unit(chain["height_axis"])    # any length: scaled before the product
    if abs(d @ h) > 1e-9:
        raise SceneError(f"{key}.height_axis", chain["height_axis"], "a direction perpendicular to direction")
    if chain["elements_per_bar"] is not None and chain["elements_per_bar"] % 2:
        raise SceneError(f"{key}.elements_per_bar", chain["elements_per_bar"], "an even count: the mid-length pivot "
                                                                              "is a node")


_SCISSOR_END = lambda where: Choice("-", "free", f"the {where}: free, pinned to the ground (about the chord), or "
                                                 "kept on a line through its start across the chain (along "
                                                 "height_axis) or along it (along direction)", options=SCISSOR_ENDS)
SCISSOR = Table({
    "name": Name("-", REQUIRED, "chain name: its bars are <name>_up<i> and <name>_down<i> (i = 1..count), its "
                                "pins and probes <name>_a<i>, <name>_b<i>, <name>_c<i>"),
    "count": Integer("-", REQUIRED, "scissor-like elements (SLEs) in the chain", low=1, high=MAX_SCISSORS,
                     why="each SLE adds two bodies"),
    "bar_length": positive("m", "length of each bar, pinned to its partner at mid-length"),
    "initial_angle_deg": Number("deg", REQUIRED, "angle theta between the bars and direction at t = 0 (90: folded, "
                                                 "0: flat); deploying decreases it", low=0.0, high=90.0,
                                low_open=True, high_open=True),
    "origin": Vector("m", [0.0, 0.0, 0.0], "position of the first lower end b_1"),
    "direction": Vector("-", [1.0, 0.0, 0.0], "direction d in which the chain deploys", nonzero=True),
    "height_axis": Vector("-", [0.0, 1.0, 0.0], "direction h from the lower ends b_i to the upper ends a_i, "
                                                "perpendicular to direction; the pins turn about d x h, every "
                                                "bar's chord", nonzero=True),
    "elements_per_bar": Integer("-", Absent("2 in the rigid fidelity; structure.elements_per_body rounded up to "
                                            "even in the flexible one"), "elements of each bar (even)", low=2,
                                high=MAX_ELEMENTS_PER_BODY, why=DENSE_STRUCTURE),
    "damping": non_negative("1/s", "alpha of each bar (structure.damping_model)", 0.0),
    "start_lower": _SCISSOR_END("lower end b_1 of the first SLE"),
    "start_upper": _SCISSOR_END("upper end a_1 of the first SLE"),
    "end_upper": _SCISSOR_END("upper end a_{count+1} of the last SLE"),
    "end_lower": _SCISSOR_END("lower end b_{count+1} of the last SLE"),
    "section": SECTION,
}, doc="A planar chain of scissor-like elements (Peng et al. 2019, Sec. 2): two bars pinned at mid-length, "
       "chained at their ends; expanded into bodies, pins, sliders and probes (fmu_common.scissors)",
    rules=(_scissor_rule,))

MASS = Table({
    "body": Name("-", REQUIRED, _BODY_REF),
    "span": non_negative("m", "position from the body root; must be a node of the body", 0.0),
    "mass": positive("kg", "lumped mass"),
}, doc="A point mass at a node")

_LOAD_AT = {
    "span": non_negative("m", "position from the body root, at most the body length"),
    "chord": fraction("where on the chord the force acts", Absent("the body's section.axis_position")),
}
_RAMP = {"ramp_time": positive("s", "ramp time t_s of the cosine ramp", 1.0)}
_LAW_DOC = "constant: applied from t = 0; cosine_ramp: F (1 - cos(pi t / t_s)) / 2 up to t_s (Otsuka et al. " \
           "2019, Eq. 26)"
LOAD = Variants("law", {
    "constant": Table({"body": Name("-", REQUIRED, _BODY_REF), **_LOAD_AT,
                       "force": Vector("N", REQUIRED, "force, global frame")}),
    "cosine_ramp": Table({"body": Name("-", REQUIRED, _BODY_REF), **_LOAD_AT,
                          "force": Vector("N", REQUIRED, "force, global frame"), **_RAMP}),
}, default="constant", doc=_LAW_DOC)

_LOAD_CASE = {
    "parameter": non_negative("-", "P L^2 / EI_yy of the body: the force magnitude P in units of its flap "
                                   "stiffness (the root's, where the section varies) and length"),
    "direction": Vector("-", REQUIRED, "direction of the force, global frame", nonzero=True),
    "body": Name("-", Absent("the last body of structure.bodies"), _BODY_REF),
    "span": non_negative("m", "position from the body root", Absent("the body's length: its tip")),
    "chord": fraction("where on the chord the force acts", Absent("the body's section.axis_position")),
}
_LOAD_CASE_LAWS = {"constant": Table(dict(_LOAD_CASE)), "cosine_ramp": Table({**_LOAD_CASE, **_RAMP})}

MOTION = Table({
    "heave_amplitude": Number("m", 0.0, "heave h(t) = heave_amplitude sin(frequency t) along heave_axis"),
    "pitch_amplitude_deg": Number("deg", 0.0, "pitch(t) = pitch_amplitude_deg sin(frequency t + phase) about the "
                                              "span axis through pitch_axis_position"),
    "frequency": non_negative("rad/s", "circular frequency of heave and pitch", 0.0),
    "phase_deg": Number("deg", 0.0, "phase of the pitch ahead of the heave"),
    "pitch_axis_position": fraction("where the pitch axis crosses the chord",
                                    Absent("each body's section.axis_position")),
    "heave_axis": Vector("-", Absent("each body's section normal r_x x r_y"), "heave direction", nonzero=True),
    "alpha_deg": angle("constant nose-up pitch (angle of attack); excludes pitch_amplitude_deg and "
                       "heave_amplitude", 0.0, limit=90.0),
}, doc="Only with `structure.fidelity = \"prescribed\"`, and then required: every body moves rigidly by this "
       "law, no structural solver runs", optional=True, rules=(_motion_rule,))

PROBE = Table({
    "name": Name("-", REQUIRED, "column prefix in timeseries.csv and key in summary.json: the structure "
                                "FMU outputs and the run records `<name>_x/_y/_z` (m), `<name>_vx/_vy/_vz` "
                                "(m/s) and `<name>_ax/_ay/_az` (m/s^2)"),
    "body": Name("-", REQUIRED, _BODY_REF),
    "span": non_negative("m", "position from the body root, at most the body length"),
    "chord": fraction("where on the chord", Absent("the body's section.axis_position")),
}, doc="A material point whose position is recorded")

STRAIN_GAUGE = Table({
    "name": Name("-", REQUIRED, "column name in timeseries.csv, output of the structure FMU, key in "
                                "summary.json strain_gauges"),
    "body": Name("-", REQUIRED, _BODY_REF),
    "span": non_negative("m", "position from the body root, at most the body length"),
    "surface_distance": positive("m", "distance from the reference line to the gauged surface",
                                 Absent("half the body's section.thickness at the gauge's span (linear to "
                                        "section.thickness_tip); required without a thickness")),
    "curvature": Choice("-", "model", "the curvature it reads: model, the fidelity's own (the ANCF element's cubic "
                                      "field; the strain-based element's constant kappa_y, as Otsuka et al. 2022, "
                                      "Sec. 5 read it); cubic, the cubic interpolation of the nodal vectors, the same "
                                      "instrument in every fidelity", options=GAUGE_CURVATURES),
}, doc="A surface strain gauge: surface_distance x the bending curvature out of the wing plane (Otsuka et "
       "al. 2022, Sec. 5)")

SCENE = Table({
    "name": Name("-", Absent("the scene file's name without .toml"),
                 "scene name: the folders `fmus/<name>/` and `results/<name>/`"),
    "description": Text("-", "", "free text, with the source case (e.g. Otsuka et al. 2019, Sec. VI.A)"),
    "time": Table({"stop": positive("s", "end time")}),
    "coupling": Table({
        "step": positive("s", "communication step; the units take their own internal steps inside it", 1e-3),
        "algorithm": Choice("-", "gauss-seidel", "how the units exchange e, de and Q (with an aero unit)",
                            options=ALGORITHMS),
        "tolerance": positive("-", "implicit only: a step is accepted when ||Q_new - Q_used|| / max(||Q_new||, "
                                   "1e-12) is below it", 1e-6),
        "max_iterations": Integer("-", 50, "implicit only: iterations per communication step before the run "
                                           "stops as diverged", low=1, high=MAX_COUPLING_ITERATIONS,
                                  why="each implicit iteration repeats the step of both units; refine coupling.step "
                                      "instead"),
        "acceleration": Choice("-", "aitken", "implicit only: aitken (dynamic relaxation) or iqn-ils (interface "
                                              "quasi-Newton, as in preCICE)", options=ACCELERATIONS),
        "relaxation": Number("-", 0.5, "implicit only: relaxation factor omega_0 of the first update of each "
                                       "step", low=0.0, high=1.0, low_open=True),
    }),
    "flow": Table({
        "speed": non_negative("m/s", "free-stream speed", 0.0, tunable=True),
        "density": non_negative("kg/m^3", "air density", 1.2, tunable=True),
        "direction": Vector("-", Absent("the chord_axis of the first body that is not a hinge's child"),
                            "free-stream direction: the air velocity is speed x direction / |direction|",
                            nonzero=True, tunable=True),
    }),
    "aero": Table({
        "model": Choice("-", "none", "aerodynamic model; none builds no aero unit", options=AERO_MODELS),
        "chordwise_panels": Integer("-", 2, "M vortex rings along the chord of each body", low=1,
                                    high=MAX_CHORDWISE_PANELS, why=DENSE_AERO),
        "spanwise_panels": Integer("-", 7, "N vortex rings (strips for strip theory) along the span of each body",
                                   low=1, high=MAX_SPANWISE_PANELS, why=DENSE_AERO),
        "wake_length": positive("chords", "wake truncation L_w; inf: semi-infinite flat-wake legs, and a shed wake "
                                          f"kept whole up to {MAX_WAKE_ROWS} rows", 5.0, inf=True),
        "step": positive("s", "internal aero step: the aero side of multi-rate coupling",
                         Absent("one aero step per communication step")),
        "wake_far_field": Choice("-", "treecode", "uvlm-free only: how the wake's corners are convected: treecode "
                                                  "(a cluster of segments beyond aero.wake_opening enters by its "
                                                  "monopole and dipole, Barnes and Hut 1986; near segments exact) or "
                                                  "exact (every segment summed); the collocation points always sum "
                                                  "the wake exactly", options=WAKE_FAR_FIELDS),
        "wake_opening": Number("-", 0.3, "treecode opening parameter theta: a cluster of segments of radius rho is "
                                         "far from a point at distance d when rho < theta d (smaller: closer to "
                                         "exact, slower)", low=0.0, high=1.0, low_open=True, high_open=True),
        "span_correction": Choice("-", "helmbold", "strip theory only: helmbold scales the 2D lift slope 2 pi "
                                                   "by A / (2 + sqrt(A^2 + 4)) (Helmbold 1942); none keeps 2D "
                                                   "strips", options=SPAN_CORRECTIONS),
    }),
    "structure": Table({
        "fidelity": Choice("-", "flexible", "prescribed (rigid motion by a law), rigid (one ANCF element per body, "
                                            "Otsuka et al. 2019, Eq. 17), flexible (ANCF), shear-deformable (ANCF "
                                            "with shear in the chord plane, Peng et al. 2019; plate sections) or "
                                            "strain-based (constant strains per element, Otsuka et al. 2022)",
                           options=FIDELITIES),
        "elements_per_body": Integer("-", 4, "elements per body (flexible, shear-deformable and strain-based "
                                             "fidelities)", low=1,
                                     high=MAX_ELEMENTS_PER_BODY, why=DENSE_STRUCTURE),
        "integrator": Choice("-", "generalized-alpha", "time integrator", options=INTEGRATORS),
        "step": positive("s", "internal time step; the last one in a communication step is shortened to land "
                              "on it", 1e-4, tunable=True),
        "rho_inf": Number("-", 0.8, "spectral radius at infinity of generalized-alpha", low=0.0, high=1.0),
        "damping_model": Choice("-", "deformation", "what each body's damping alpha acts on: deformation "
                                                    "(zero for rigid motion) or mass-proportional (all motion, as "
                                                    "Otsuka et al. 2019, Sec. II.C write it)",
                                options=DAMPING_MODELS),
        "gravity": Vector("m/s^2", [0.0, 0.0, 0.0], "gravity vector, global frame", tunable=True),
        "bodies": Tables(BODY, "body", doc="at least one, here or from structure.scissors"),
        "joints": Tables(JOINT, "joint"),
        "scissors": Tables(SCISSOR, "scissor chain"),
        "masses": Tables(MASS, "lumped mass"),
        "loads": Tables(LOAD, "point load"),
        "motion": MOTION,
    }),
    "probes": Tables(PROBE, "probe"),
    "strain_gauges": Tables(STRAIN_GAUGE, "strain gauge"),
    "record": Table({
        "probes": Choice("-", "acceleration", "what the run records of each probe: its position; also its velocity; "
                                              "also its acceleration (for which the structure unit solves its "
                                              "constrained equations of motion once more at each communication "
                                              "point). The columns not recorded hold nan", options=PROBE_RECORDS),
        "monitors": Choice("-", "all", "the structure's monitors the run records: all; or constraints, the "
                                       "constraint residual and the joint monitors without energy, kinetic_energy "
                                       "and external_work (the potential energy sums the strain energy of every "
                                       "element at each communication point): their columns hold nan and "
                                       "summary.json's energy_drift is null", options=MONITOR_RECORDS),
    }, doc="What the run reads from the units and records at each communication point (timeseries.csv); a unit "
           "computes only the outputs read. Fold angles, latch times, strain gauges, the aero unit's CL, lift and "
           "hinge moments are always recorded"),
    "load": Variants("law", _LOAD_CASE_LAWS, default="constant", doc=_LAW_DOC, optional=True),
    "motion": Table({
        "reduced_frequency": non_negative("-", "k = omega c / (2 V): becomes structure.motion.frequency = "
                                               "2 k V / c (V = flow.speed, c = chord of the first body)"),
        "amplitude": non_negative("chords", "heave amplitude: becomes structure.motion.heave_amplitude = "
                                            "amplitude x c"),
    }, doc="Shorthand: a heaving wing in the papers' non-dimensional terms (see below)", optional=True),
    "wing": Table({
        "chord": positive("m", "becomes section.chord of the only body", Absent("not set by [wing]")),
        "aspect_ratio": positive("-", "span / chord: becomes the length of the only body = aspect_ratio x chord",
                                 Absent("not set by [wing]")),
        "alpha_deg": angle("constant angle of attack: becomes structure.motion.alpha_deg",
                           Absent("not set by [wing]"), limit=90.0),
    }, doc="Shorthand: a one-body rectangular wing (see below)", optional=True),
})
"""The whole scene."""


# --- resolving --------------------------------------------------------------------------------------

def resolve_scene(raw: dict, default_name: str) -> dict:
    """The resolved scene of the raw scene: checked against SCENE, every default filled, the size bounds checked.

    Raises SceneError at the first bad key. `raw` is not modified; resolving a resolved scene returns it unchanged.

    Args:
        raw: the raw scene, a TOML table with the overrides applied.
        default_name: the scene's `name` when not given.
    """
    raw = copy.deepcopy(raw)
    if not isinstance(raw, dict):
        raise SceneError("<top level>", raw, "a TOML table")
    scene = SCENE.resolve("", raw)
    expand_scissors(scene, _resolve_item)
    if not scene["structure"]["bodies"]:
        raise SceneError("structure.bodies", MISSING, "at least one body (an array of tables [[structure.bodies]], "
                                                      "or a chain [[structure.scissors]])")
    if scene["name"] is None:
        scene["name"] = SCENE.keys["name"].check("name", default_name)
    fill_derived_defaults(scene)
    check_sizes(scene)
    return scene


MASTER_TABLES = ("record",)
"""Top-level tables only the master reads (what it records): no unit reads them, so no FMU's build depends on
them (`orchestrator.build.fmus.build_digest`)."""


def without_tunables(scene: dict) -> dict:
    """The resolved scene with the value of every tunable key blanked (`fmu_common.schema.TUNABLE`).

    What an FMU's build depends on. Two scenes that differ only in tunable keys run on the same FMUs, which the
    master gives the tunable values as parameters.

    Args:
        scene: the resolved scene.
    """
    return SCENE.blanked(scene)


def tunable_parameters(scene: dict, section: str) -> dict[str, tuple[float, str, str]]:
    """The tunable keys of the resolved scene in `section`, in schema order.

    A parameter is named by its dotted key (`structure.joints.fold.stiffness`), a vector's components by
    `key[1]` .. `key[3]` (x, y, z); the unit is the key's, in FMI's notation (`fmu_common.fmi_units.fmi_unit`).

    Args:
        scene: the resolved scene.
        section: "structure" (the structure unit's) or "flow" (the aero unit's).

    Returns:
        {FMI parameter name: (value, unit, description)}.
    """
    out = {}
    for key, declaration, value in SCENE.tunables("", scene):
        if key.split(".")[0] != section:
            continue
        unit = fmi_unit(declaration.unit)
        if isinstance(declaration, Vector):
            for i, (axis, component) in enumerate(zip("xyz", value)):
                out[f"{key}[{i + 1}]"] = (float(component), unit, f"{declaration.doc}: {axis} component")
        else:
            out[key] = (float(value), unit, declaration.doc)
    return out


def parameter_values(declared: dict[str, tuple[float, str, str]], given: dict | None) -> dict[str, float]:
    """The values a solver runs with: the declared tunable parameters' defaults, replaced by those `given`.

    Args:
        declared: {name: (default, unit, description)}, as `tunable_parameters` returns them.
        given: {name: value} set by a host, SI units; None: none.

    Returns:
        {name: value} of every declared parameter, floats.

    Raises:
        SceneError: a given name that is not declared, or a value that is not a finite real number.
    """
    values = {name: float(default) for name, (default, _, _) in declared.items()}
    for name, value in (given or {}).items():
        if name not in values:
            raise SceneError(name, value, f"one of the tunable parameters {sorted(values)}")
        if not is_number(value) and not (isinstance(value, np.floating) and np.isfinite(value)):
            raise SceneError(name, value, "a finite number")
        values[name] = float(value)
    return values


def _resolve_item(section: str, key: str, raw: dict) -> dict:
    """One raw table of the array `section` (structure.bodies, structure.joints or probes) resolved at `key`."""
    item = {"bodies": BODY, "joints": JOINT, "probes": PROBE}[section]
    return item.resolve(key, raw)


def _bodies_by_name(scene: dict) -> dict[str, dict]:
    return {body["name"]: body for body in scene["structure"]["bodies"]}


def _body_of(scene: dict, key: str, name: str) -> dict:
    """The body named `name`, referenced at dotted key `key`; SceneError listing the bodies otherwise."""
    bodies = _bodies_by_name(scene)
    if name not in bodies:
        raise SceneError(key, name, f"the name of a body in structure.bodies: {', '.join(map(repr, bodies))}")
    return bodies[name]


def joint_parents(scene: dict) -> dict[str, str]:
    """child body -> parent body of every joint that joins two bodies.

    Args:
        scene: the resolved scene.
    """
    return {j["child"]: j["parent"] for j in scene["structure"]["joints"]
            if j["type"] in PARENT_JOINTS and j["parent"] is not None}


def fill_derived_defaults(scene: dict) -> None:
    """Fill, in place, the defaults that depend on another table (the `Absent` texts of SCENE say which).

    A jointed child's frame is its parent's tip frame turned by the joint (`fmu_common.topology`): its chord_axis
    stays None unless given, and the topology checks a given one.

    Args:
        scene: the resolved scene, changed in place.
    """
    structure = scene["structure"]
    children = joint_parents(scene)
    for body in structure["bodies"]:
        if body["name"] not in children:
            for key, default in (("root", [0.0, 0.0, 0.0]), ("span_axis", [1.0, 0.0, 0.0]),
                                 ("chord_axis", [0.0, 1.0, 0.0])):
                if body[key] is None:
                    body[key] = default
    bodies = _bodies_by_name(scene)
    roots = [b for b in structure["bodies"] if b["name"] not in children]
    if scene["flow"]["direction"] is None and roots:
        scene["flow"]["direction"] = list(roots[0]["chord_axis"])
    for load in structure["loads"]:
        if load["chord"] is None and load["body"] in bodies:     # an unknown body is the topology's to report
            load["chord"] = bodies[load["body"]]["section"]["axis_position"]
    load = scene.get("load")
    if load is not None:
        if load["body"] is None:
            load["body"] = structure["bodies"][-1]["name"]
        body = _body_of(scene, "load.body", load["body"])
        if load["span"] is None:
            load["span"] = body["length"]
        if load["chord"] is None:
            load["chord"] = body["section"]["axis_position"]
    for index, probe in enumerate(scene["probes"]):
        body = _body_of(scene, f"probes.{item_label(index, probe)}.body", probe["body"])
        if probe["chord"] is None:
            probe["chord"] = body["section"]["axis_position"]
    for index, gauge in enumerate(scene["strain_gauges"]):
        key = f"strain_gauges.{item_label(index, gauge)}"
        body = _body_of(scene, f"{key}.body", gauge["body"])
        if gauge["surface_distance"] is None:
            thickness = body["section"]["thickness"]
            if thickness is None:
                raise SceneError(f"{key}.surface_distance", MISSING,
                                 f"required: body '{body['name']}' has no section.thickness (a distance > 0 from "
                                 "the reference line to the gauged surface, m)")
            tip = body["section"]["thickness_tip"]
            if tip is not None:         # the plate's thickness at the gauge, linear from the root's to the tip's
                thickness += (tip - thickness) * gauge["span"] / body["length"]
            gauge["surface_distance"] = 0.5 * thickness
