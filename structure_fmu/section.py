"""Cross-section properties of a wing body, from a rectangular plate or given explicitly."""
import math
from dataclasses import dataclass

from fmu_common.errors import SceneError
from fmu_common.scene_schema import EXPLICIT, PLATE
from fmu_common.wing_spec import SectionSpec


@dataclass(frozen=True)
class Section:
    """Beam section about the reference line (y = 0, y toward the trailing edge).

    axial (EA, N), flap (EI_yy, N m^2, out of the wing plane), chordwise (EI_zz, N m^2),
    torsion (GJ, N m^2), mass_per_length (rho A, kg/m), first_moment (rho Q_z, kg),
    chord_inertia (rho I_zz, kg m), chord (m), axis_position (reference line, fraction of chord from the
    leading edge), thickness (h, m; None for a section given by explicit stiffnesses), rotary_inertia (rho I_yy,
    kg m: the rotary inertia of the section about its chord axis, kinetic energy 1/2 rho I_yy |dr'/dt|^2 per unit
    length, Otsuka et al. 2022, Table 4; element.mass_matrix).
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
    rotary_inertia: float = 0.0

    @property
    def stiffness(self):
        """(EA N, EI_yy N m^2, EI_zz N m^2, GJ N m^2), the element's stiffness tuple."""
        return (self.axial, self.flap, self.chordwise, self.torsion)


def section_from_spec(spec: SectionSpec) -> Section:
    """Build a Section from a body's section table; errors name its key.

    A rectangular plate (chord c, thickness h, density rho, Young's modulus E) gives EA = E c h,
    EI_yy = E c h^3 / 12, EI_zz = E h c^3 / 12, rho A = rho c h; explicit values override these.
    The mass is spread uniformly over the chord. SceneError if a derived property is not a finite number > 0
    (a product of finite values may overflow or underflow).

    Args:
        spec: the section table (fmu_common.wing_spec.SectionSpec), SI units.
    """
    chord, axis, h = spec.chord, spec.axis_position, spec.thickness
    derived = {}
    if h is not None:
        E, rho = spec.youngs_modulus, spec.density
        derived = {"axial_stiffness": E * chord * h, "bending_stiffness_flap": E * chord * h**3 / 12,
                   "bending_stiffness_chord": E * h * chord**3 / 12, "mass_per_length": rho * chord * h}
    given = {name: getattr(spec, name) for name in EXPLICIT}
    values = {name: value if value is not None else derived[name] for name, value in given.items()}
    for name, value in values.items():
        if not (math.isfinite(value) and value > 0):
            plate = {k: getattr(spec, k) for k in ("chord", *PLATE) if getattr(spec, k) is not None}
            raise SceneError(spec.key, plate, f"a section whose {name} (derived from the plate: {value:g}) is a "
                                              "finite number > 0")
    mu = values["mass_per_length"]
    lead, trail = -axis * chord, (1.0 - axis) * chord
    return Section(axial=values["axial_stiffness"], flap=values["bending_stiffness_flap"],
                   chordwise=values["bending_stiffness_chord"], torsion=spec.torsional_rigidity,
                   mass_per_length=mu, first_moment=mu * (trail**2 - lead**2) / (2 * chord),
                   chord_inertia=mu * (trail**3 - lead**3) / (3 * chord), chord=chord, axis_position=axis,
                   thickness=h, rotary_inertia=spec.rotary_inertia)
