"""Wings with a planform for the aero tests, and the lifting-line theory of a straight wing (not a test module).

Every wing spans y from -b/2 to b/2 with its chords along +x (n = r_x x r_y = -z): bodies with span_axis +y,
each clamped at its own root (the aero unit needs only the geometry). A free stream at incidence alpha is
V (cos alpha, 0, -sin alpha): V . n > 0, so the wing lifts along (-sin alpha, 0, -cos alpha), the direction
`lift_direction` returns.
"""
import numpy as np

from fmu_common.scene_schema import resolve_scene
from fmu_common.topology import Topology
from fmu_common.wing_spec import StructureSpec

SECTION = {"thickness": 0.01, "density": 100.0, "youngs_modulus": 1e9, "torsional_rigidity": 1.0}
RHO = 1.2


def stream(alpha_deg, speed=1.0):
    """The free stream (3,) m/s at incidence alpha_deg."""
    alpha = np.radians(alpha_deg)
    return speed * np.array([np.cos(alpha), 0.0, -np.sin(alpha)])


def lift_direction(alpha_deg):
    """The unit lift direction (3,) of `stream(alpha_deg)`."""
    alpha = np.radians(alpha_deg)
    return np.array([-np.sin(alpha), 0.0, -np.cos(alpha)])


def wing_scene(bodies, aero=None, fidelity="rigid"):
    """The resolved scene of `bodies` (body tables without joints), each clamped at its root."""
    raw = {"time": {"stop": 1.0},
           "structure": {"fidelity": fidelity, "bodies": bodies,
                         "joints": [{"type": "clamp", "body": b["name"]} for b in bodies]}}
    if aero is not None:
        raw["aero"] = aero
        raw["flow"] = {"speed": 1.0, "density": RHO, "direction": [1.0, 0.0, 0.0]}
    return resolve_scene(raw, "planform_wing")


def topology_of(scene):
    """The aero unit's topology of a resolved scene."""
    return Topology.from_spec(StructureSpec.from_scene(scene))


def body(name, root_y, length, chord, chord_tip, axis_position=0.25, **keys):
    """A body table along +y from (0, root_y, 0) with a tapered plate section; `keys` more body keys
    (sweep_deg, twist_deg) or section keys (airfoil)."""
    section = dict(SECTION, chord=chord, chord_tip=chord_tip, axis_position=axis_position)
    if "airfoil" in keys:
        section["airfoil"] = keys.pop("airfoil")
    return {"name": name, "length": length, "root": [0.0, root_y, 0.0], "span_axis": [0.0, 1.0, 0.0],
            "chord_axis": [1.0, 0.0, 0.0], "section": section, **keys}


def tapered_wing(span, root_chord, tip_chord, sweep_deg=0.0, axis_position=0.25, airfoil=None):
    """Body tables of a straight-tapered wing of `span` b, mirror-symmetric about y = 0: "left" from the left tip
    to the centre, "right" from the centre to the right tip, the leading edge swept back by sweep_deg on both
    halves, the reference line at axis_position of the tip chords (the right half's root takes the position
    where the left half's leading edge ends)."""
    half = 0.5 * span
    lead_centre = -axis_position * tip_chord - half * np.tan(np.radians(sweep_deg))   # y_LE at the centre
    extra = {} if airfoil is None else {"airfoil": airfoil}
    return [body("left", -half, half, tip_chord, root_chord, axis_position, sweep_deg=-sweep_deg, **extra),
            body("right", 0.0, half, root_chord, tip_chord, -lead_centre / root_chord, sweep_deg=sweep_deg,
                 **extra)]


def elliptic_wing(aspect_ratio, bodies_per_half, tip_fraction=0.02, airfoil=None):
    """Body tables of an elliptic planform with a straight quarter-chord line, root chord 1 m: span
    b = pi A / 4 (A = b^2 / S of the ellipse), stations y_k = b/2 sin(pi k / (2 K)) (closer toward the tips),
    chord c(y) = sqrt(1 - (2 y / b)^2) at each station (tip_fraction at the tips, where the ellipse's is 0)
    and linear between them; and b."""
    span = np.pi * aspect_ratio / 4.0
    eta = np.sin(0.5 * np.pi * np.arange(bodies_per_half + 1) / bodies_per_half)
    y = 0.5 * span * np.concatenate([-eta[::-1], eta[1:]])
    chord = np.maximum(np.sqrt(np.clip(1.0 - (2.0 * y / span) ** 2, 0.0, None)), tip_fraction)
    extra = {} if airfoil is None else {"airfoil": airfoil}
    return [body(f"b{k}", float(y[k]), float(y[k + 1] - y[k]), float(chord[k]), float(chord[k + 1]), **extra)
            for k in range(len(y) - 1)], span


def lifting_line(chord, span, alpha, terms=100):
    """Prandtl's lifting line for a straight, untwisted, symmetric wing by Glauert's series (Anderson 2017,
    Ch. 5): Gamma(theta) = 2 b V sum_n A_n sin(n theta), y = -b/2 cos(theta), the odd n, collocated at
    `terms` stations of the half span with the 2D slope 2 pi.

    Args:
        chord: c(y), m, a function of an array.
        span: b, m.
        alpha: the incidence, rad.
        terms: the number of odd terms.

    Returns:
        (terms,) the coefficients A_1, A_3, ...; CL = pi A A_1 with A = b^2 / S.
    """
    theta = 0.5 * np.pi * (np.arange(1, terms + 1) - 0.5) / terms
    odd = 2 * np.arange(terms) + 1
    mu = chord(-0.5 * span * np.cos(theta)) * 2 * np.pi / (4 * span)
    matrix = np.sin(np.outer(theta, odd)) * (1 + np.outer(mu / np.sin(theta), odd))
    return np.linalg.solve(matrix, mu * alpha)


def lifting_line_circulation(coefficients, span, y, speed=1.0):
    """Gamma (m^2/s) at stations y (m) of the lifting-line solution `coefficients` (odd terms)."""
    theta = np.arccos(-2.0 * np.asarray(y) / span)
    odd = 2 * np.arange(len(coefficients)) + 1
    return 2 * span * speed * np.sin(np.outer(theta, odd)) @ coefficients


def folded_wing_scene(model, wake_length=None):
    """The resolved scene of a tapered, swept, twisted, cambered (NACA 2412) two-body wing folded 60 deg about a
    hinge skewed 15 deg from the chord, 3 x 4 panels per body, in a 10 m/s stream off the chord plane; aero.model
    `model`, aero.wake_length `wake_length` chords (None: the default)."""
    skew = np.radians(15.0)
    bodies = [body("inner", 0.0, 1.0, 0.5, 0.4, 0.3, twist_deg=-2.0, airfoil="naca2412", sweep_deg=4.0),
              {"name": "tip", "length": 0.4, "twist_deg": -2.0,
               "section": dict(body("x", 0, 1, 0.4, 0.25)["section"], axis_position=0.2, airfoil="naca2412")}]
    aero = {"model": model, "chordwise_panels": 3, "spanwise_panels": 4}
    if wake_length is not None:
        aero["wake_length"] = wake_length
    raw = {"time": {"stop": 1.0}, "coupling": {"step": 0.01},
           "structure": {"fidelity": "rigid", "bodies": bodies,
                         "joints": [{"type": "clamp", "body": "inner"},
                                    {"type": "revolute", "name": "fold", "parent": "inner", "child": "tip",
                                     "axis": [np.cos(skew), np.sin(skew), 0.0], "initial_angle_deg": 60.0,
                                     "stiffness": 1.0}]},
           "aero": aero, "flow": {"speed": 10.0, "direction": [1.0, 0.0, 0.1]}}
    return resolve_scene(raw, "folded")
