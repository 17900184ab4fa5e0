"""Cross-section properties of a wing body, from a rectangular plate or given explicitly."""
from dataclasses import dataclass

from fmu_common.errors import SceneError, reject_unknown_keys
from fmu_common.topology import SECTION_TABLE, chord_line


@dataclass(frozen=True)
class Section:
    """Beam section about the reference line (y = 0, y toward the trailing edge).

    axial (EA, N), flap (EI_yy, N m^2, out of the wing plane), chordwise (EI_zz, N m^2),
    torsion (GJ, N m^2), mass_per_length (rho A, kg/m), first_moment (rho Q_z, kg),
    chord_inertia (rho I_zz, kg m), chord (m), axis_position (reference line, fraction of chord from the
    leading edge), thickness (h, m; None for a section given by explicit stiffnesses).
    """

    axial: float
    flap: float
    chordwise: float
    torsion: float
    mass_per_length: float
    first_moment: float
    chord_inertia: float
    chord: float
    axis_position: float
    thickness: float | None = None

    @property
    def stiffness(self):
        return (self.axial, self.flap, self.chordwise, self.torsion)


_PLATE = ("thickness", "density", "youngs_modulus")
_EXPLICIT = ("axial_stiffness", "bending_stiffness_flap", "bending_stiffness_chord", "mass_per_length")
_ALLOWED = ("chord", "axis_position", "torsional_rigidity", *_PLATE, *_EXPLICIT)


def _positive(key, table, name):
    value = table.get(name)
    if not isinstance(value, (int, float)) or isinstance(value, bool) or not value > 0:
        raise SceneError(f"{key}.{name}", value, "a number > 0")
    return float(value)


def section_from_scene(key: str, table: dict) -> Section:
    """Build a Section from a scene table; `key` is its dotted scene key for error messages.

    A rectangular plate (chord c, thickness h, density rho, Young's modulus E) gives EA = E c h,
    EI_yy = E c h^3 / 12, EI_zz = E h c^3 / 12, rho A = rho c h; explicit values override these.
    The mass is spread uniformly over the chord.
    """
    if not isinstance(table, dict):
        raise SceneError(key, table, SECTION_TABLE)
    reject_unknown_keys(table, key, _ALLOWED)
    chord, axis = chord_line(key, table)
    torsion = _positive(key, table, "torsional_rigidity")
    derived, h = {}, None
    if any(name in table for name in _PLATE):
        h, rho, E = (_positive(key, table, name) for name in _PLATE)
        derived = {"axial_stiffness": E * chord * h, "bending_stiffness_flap": E * chord * h**3 / 12,
                   "bending_stiffness_chord": E * h * chord**3 / 12, "mass_per_length": rho * chord * h}
    values = {}
    for name in _EXPLICIT:
        if name in table:
            values[name] = _positive(key, table, name)
        elif name in derived:
            values[name] = derived[name]
        else:
            raise SceneError(f"{key}.{name}", None,
                             "required unless thickness, density and youngs_modulus describe a plate")
    mu = values["mass_per_length"]
    lead, trail = -axis * chord, (1.0 - axis) * chord
    return Section(axial=values["axial_stiffness"], flap=values["bending_stiffness_flap"],
                   chordwise=values["bending_stiffness_chord"], torsion=torsion, mass_per_length=mu,
                   first_moment=mu * (trail**2 - lead**2) / (2 * chord),
                   chord_inertia=mu * (trail**3 - lead**3) / (3 * chord), chord=chord, axis_position=axis,
                   thickness=h)
