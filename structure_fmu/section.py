"""Cross-section properties of a wing body, from a rectangular plate or given explicitly, constant or varying
along the span.

A section varies along the body where its table gives tip values (`<name>_tip` for the keys of
fmu_common.scene_schema.TAPERED): the chord, the plate thickness and the explicit properties (EA, EI_yy, EI_zz,
GJ, rho A, rho I_yy) vary linearly from the root (s = 0) to the tip (s = 1), s the fraction of the body's length;
a plate's derived properties then follow the plate formulas of the local chord c(s) and thickness h(s) (EI_zz =
E h c^3 / 12 is of degree 4 in s where both vary), `section_at`. The elements integrate them at Gauss points
(`element_points`).
"""
import math
from dataclasses import dataclass

import numpy as np

from fmu_common.errors import SceneError
from fmu_common.schema import MISSING
from fmu_common.scene_schema import EXPLICIT, PLATE, TAPERED
from fmu_common.wing_spec import SectionSpec


@dataclass(frozen=True)
class Section:
    """Beam section about the reference line (y = 0, y toward the trailing edge).

    axial (EA, N), flap (EI_yy, N m^2, out of the wing plane), chordwise (EI_zz, N m^2),
    torsion (GJ, N m^2), mass_per_length (rho A, kg/m), first_moment (rho Q_z, kg),
    chord_inertia (rho I_zz, kg m), chord (m), axis_position (reference line, fraction of chord from the
    leading edge), thickness (h, m; None for a section given by explicit stiffnesses), rotary_inertia (rho I_yy,
    kg m: the rotary inertia of the section about its chord axis, kinetic energy 1/2 rho I_yy |dr'/dt|^2 per unit
    length, Otsuka et al. 2022, Table 4; element.mass_matrix), youngs_modulus (E, Pa) and poissons_ratio (nu) of
    a plate (None for a section given by explicit stiffnesses; the shear-deformable element integrates E over the
    plate, shear_element), leading_edge (m: the leading edge's y from the reference line, -a c unless a swept
    planform moves the chord, `section_at`).
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
    youngs_modulus: float | None = None
    poissons_ratio: float | None = None
    leading_edge: float | None = None

    @property
    def stiffness(self):
        """(EA N, EI_yy N m^2, EI_zz N m^2, GJ N m^2), the element's stiffness tuple."""
        return (self.axial, self.flap, self.chordwise, self.torsion)


def section_from_spec(spec: SectionSpec) -> Section:
    """Build the root's Section from a body's section table (`section_at` s = 0); errors name its key.

    Args:
        spec: the section table (fmu_common.wing_spec.SectionSpec), SI units.
    """
    return section_at(spec, 0.0)


def varies(spec: SectionSpec) -> bool:
    """Whether the section of `spec` varies along the body (a tip value is given).

    Args:
        spec: the section table (fmu_common.wing_spec.SectionSpec).
    """
    return bool(spec.tips)


def section_at(spec: SectionSpec, s: float, leading_edge: float | None = None) -> Section:
    """The Section at the fraction s of the body's length from its root (0: root, 1: tip); errors name its key.

    The keys of TAPERED are linear in s between their root and tip values (SectionSpec.tip). A rectangular plate
    (local chord c, thickness h, density rho, Young's modulus E) gives EA = E c h, EI_yy = E c h^3 / 12,
    EI_zz = E h c^3 / 12, rho A = rho c h; explicit values override these. The mass is spread uniformly over the
    local chord, the reference line at the same fraction a of it. SceneError if a derived property is not a finite
    number > 0 (a product of finite values may overflow or underflow).

    Args:
        spec: the section table (fmu_common.wing_spec.SectionSpec), SI units.
        s: fraction of the body's length from the root, in [0, 1].
        leading_edge: the leading edge's offset from the reference line along r_y at s, m (a swept planform's,
            fmu_common.planform.Planform.leading_edge); None: -a c, the reference line at the fraction a of the chord.
            The mass spreads over the chord from there, so its first moment and chord inertia follow the sweep.
    """
    local = {name: _linear(getattr(spec, name), spec.tip(name), s) for name in TAPERED}
    chord, axis, h = local["chord"], spec.axis_position, local["thickness"]
    derived = {}
    if h is not None:
        E, rho = spec.youngs_modulus, spec.density
        derived = {"axial_stiffness": E * chord * h, "bending_stiffness_flap": E * chord * h**3 / 12,
                   "bending_stiffness_chord": E * h * chord**3 / 12, "mass_per_length": rho * chord * h}
    given = {name: local[name] for name in EXPLICIT}
    values = {name: value if value is not None else derived[name] for name, value in given.items()}
    for name, value in values.items():
        if not (math.isfinite(value) and value > 0):
            plate = {k: getattr(spec, k) for k in ("chord", *PLATE) if getattr(spec, k) is not None}
            raise SceneError(spec.key, plate | dict(spec.tips), f"a section whose {name} (derived from the plate: "
                                                                f"{value:g}) is a finite number > 0")
    mu = values["mass_per_length"]
    lead = -axis * chord if leading_edge is None else float(leading_edge)
    trail = lead + chord
    return Section(axial=values["axial_stiffness"], flap=values["bending_stiffness_flap"],
                   chordwise=values["bending_stiffness_chord"], torsion=local["torsional_rigidity"],
                   mass_per_length=mu, first_moment=mu * (trail**2 - lead**2) / (2 * chord),
                   chord_inertia=mu * (trail**3 - lead**3) / (3 * chord), chord=chord, axis_position=axis,
                   thickness=h, rotary_inertia=local["rotary_inertia"], youngs_modulus=spec.youngs_modulus,
                   poissons_ratio=spec.poissons_ratio if h is not None else None, leading_edge=lead)


def _linear(root, tip, s):
    """root + s (tip - root); None where the root is not given."""
    return None if root is None else root + s * (tip - root)


def element_points(specs, fractions, leading_edges=None):
    """The Sections of elements at their Gauss points (`section_at`), (n, g) nested lists.

    Args:
        specs: (n,) the SectionSpec of each element's body.
        fractions: (n, g) the Gauss points' fractions of their body's length from its root.
        leading_edges: (n, g) the leading edge's offset from the reference line at those points, m (`section_at`);
            None: the reference line at the fraction axis_position of every chord.
    """
    fractions = np.asarray(fractions)
    leads = np.full(fractions.shape, None) if leading_edges is None else np.asarray(leading_edges)
    return [[section_at(spec, float(s), lead) for s, lead in zip(row, leads_row)]
            for spec, row, leads_row in zip(specs, fractions, leads)]


SHEET_DERIVED = ("axial_stiffness", "bending_stiffness_chord")
"""The explicit section properties the shear-deformable element derives from the plate itself (its continuum over
the chord and thickness gives EA and EI_zz)."""


def require_plate(spec: SectionSpec, fidelity_name: str) -> None:
    """SceneError naming the key unless `spec` is a plate without the overrides the shear-deformable element
    cannot follow (SHEET_DERIVED): that element integrates E over the plate's chord and thickness.

    Args:
        spec: the section table (fmu_common.wing_spec.SectionSpec).
        fidelity_name: the structure's fidelity, for the message.
    """
    if spec.thickness is None:
        raise SceneError(f"{spec.key}.thickness", MISSING, f"a plate (thickness, density, youngs_modulus) with "
                                                        f"structure.fidelity = '{fidelity_name}': its element "
                                                        "integrates E over the plate's chord and thickness")
    for name in SHEET_DERIVED:
        if getattr(spec, name) is not None:
            raise SceneError(f"{spec.key}.{name}", getattr(spec, name),
                             f"absent with structure.fidelity = '{fidelity_name}' (its element derives it from the "
                             "plate's E, chord and thickness)")
