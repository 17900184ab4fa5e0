"""Sections that vary along the span (section.*_tip) against independent numbers: a tapered plate cantilever's
static tip deflection against the unit-load integral of M/EI along the span (scipy's quad of the closed-form M(x)
and EI(x)), its first bending frequency against a Rayleigh-Ritz solution of (EI w'')'' = omega^2 rho A w written
here, and a rigid tapered body's mass, first moment and inertia against their integrals over the trapezoid, in
every structural fidelity that deforms (and the rigid one for the inertia)."""
import numpy as np
import pytest
from numpy.polynomial.legendre import Legendre, leggauss
from scipy.integrate import dblquad, quad
from scipy.linalg import eigh

from fmu_common.errors import SceneError
from fmu_common.scene_schema import resolve_scene
from fmu_common.specs import StructureUnitSpec
from structure_fmu.modes import natural_frequencies
from structure_fmu.solver import StructureSolver

LENGTH = 1.0
ROOT_CHORD, TIP_CHORD = 0.1, 0.04                 # m
ROOT_THICKNESS, TIP_THICKNESS = 0.004, 0.003      # m
E, RHO = 70e9, 2700.0                             # aluminium, Pa and kg/m^3
TAPERED = {"chord": ROOT_CHORD, "chord_tip": TIP_CHORD, "thickness": ROOT_THICKNESS, "thickness_tip": TIP_THICKNESS,
           "density": RHO, "youngs_modulus": E, "torsional_rigidity": 100.0}
DEFORMING = ("flexible", "shear-deformable", "strain-based")


def chord(x):
    return ROOT_CHORD + (TIP_CHORD - ROOT_CHORD) * x / LENGTH


def thickness(x):
    return ROOT_THICKNESS + (TIP_THICKNESS - ROOT_THICKNESS) * x / LENGTH


def flap_stiffness(x):
    return E * chord(x) * thickness(x) ** 3 / 12


def chord_stiffness(x):
    return E * thickness(x) * chord(x) ** 3 / 12


def mass_per_length(x):
    return RHO * chord(x) * thickness(x)


def cantilever(fidelity, elements, section=TAPERED, load=None, gravity=(0.0, 0.0, 0.0), sweep_deg=None):
    """A cantilever along x, the chord along y, clamped at its root, with a tip load (3,) N or a gravity (3,), its
    leading edge swept by sweep_deg (None: the reference line at axis_position of every chord)."""
    body = {"name": "wing", "length": LENGTH, "section": section}
    if sweep_deg is not None:
        body["sweep_deg"] = sweep_deg
    structure = {"fidelity": fidelity, "elements_per_body": elements, "gravity": list(gravity),
                 "bodies": [body],
                 "joints": [{"type": "clamp", "body": "wing"}]}
    if load is not None:
        structure["loads"] = [{"body": "wing", "span": LENGTH, "force": list(load)}]
    return resolve_scene({"time": {"stop": 1.0}, "structure": structure}, "tapered_cantilever")


def static_coordinates(solver):
    """The exchanged coordinates E (n,) of the static equilibrium of `solver`'s structure: Newton on the model's
    reduced force and tangent, with its constraint rows (the ANCF element's |r_y| = 1) by Lagrange multipliers."""
    model, rest = solver.model, np.zeros(len(solver.model.initial_coordinates()))
    q = model.initial_coordinates().copy()
    m = model.constraint_count
    multipliers = np.zeros(m)
    for _ in range(30):
        force, coordinates, _, _ = model.force_q(q, rest, 1.0, np.zeros(model.n), {})
        K, _ = model.iteration_matrix(1.0, q, rest, {}, multipliers, 0.0, 0.0)
        G = model.constraint_jacobian(q, coordinates)
        matrix = np.block([[K, G.T], [G, np.zeros((m, m))]])
        step = np.linalg.solve(matrix, np.concatenate([force - G.T @ multipliers,
                                                       -model.constraint_residual(q, coordinates)]))
        q += step[:len(q)]
        multipliers += step[len(q):]
        if np.abs(step).max() < 1e-15:
            break
    return model.coordinates(q, rest, 1.0)[0]


def static_tip(scene):
    """The tip displacement (3,) m of `scene`'s structure in static equilibrium (`static_coordinates`)."""
    solver = StructureSolver(StructureUnitSpec.from_scene(scene))
    tip = 9 * solver.topology.bodies["wing"].nodes[-1]
    initial = solver.model.coordinates(solver.model.initial_coordinates(), np.zeros(solver.model.T.shape[1]), 1.0)[0]
    return static_coordinates(solver)[tip:tip + 3] - initial[tip:tip + 3]


def unit_load_deflection(moment, stiffness):
    """The tip deflection int_0^L M(x) (L - x) / EI(x) dx of a cantilever under the bending moment M(x) (the unit
    load's moment is L - x), by quad."""
    return quad(lambda x: moment(x) * (LENGTH - x) / stiffness(x), 0.0, LENGTH, epsabs=0.0, epsrel=1e-12)[0]


def assert_converges(errors, final, order):
    """Relative errors at 2, 4, 8 (...) elements: each halving of the elements divides the error by at least
    2^order / 1.5 (the order's rate, with room for the pre-asymptotic range), the last below `final`."""
    errors = np.abs(errors)
    assert np.all(errors[1:] < errors[:-1] * 1.5 / 2 ** order), errors
    assert errors[-1] < final, errors


LOAD = 1e-3         # N: deflections of 1e-5 L, where the beams are linear to 1e-10


STRAIN_BASED_FINAL = 5e-3
"""The strain-based fidelity's constant strains per element: its relative error at 8 elements stays below this."""


@pytest.mark.parametrize("fidelity, order, final", [("flexible", 3, 1e-4), ("shear-deformable", 3, 1e-4),
                                                    ("strain-based", 1.5, STRAIN_BASED_FINAL)])
def test_tapered_cantilever_flap_deflection_under_a_tip_load_is_the_integral_of_m_over_ei(fidelity, order, final):
    """EI_yy = E c h^3 / 12 of the local chord and thickness (a quartic in x): the ANCF elements converge at third
    order or better (measured 2.3e-3, 1.9e-4, 1.3e-5 at 2, 4, 8 elements), the strain-based fidelity's constant
    curvatures at 1.5 or better (2.1e-2, 7.0e-3, 1.9e-3)."""
    reference = unit_load_deflection(lambda x: LOAD * (LENGTH - x), flap_stiffness)
    errors = [static_tip(cantilever(fidelity, n, load=(0.0, 0.0, LOAD)))[2] / reference - 1 for n in (2, 4, 8)]
    assert_converges(errors, final, order)


@pytest.mark.parametrize("fidelity, order, final", [("flexible", 2.5, 1e-4), ("strain-based", 1, STRAIN_BASED_FINAL)])
def test_tapered_cantilever_chordwise_deflection_under_a_tip_load_is_the_integral_of_m_over_ei(fidelity, order,
                                                                                               final):
    """In the chord plane EI_zz = E h c^3 / 12 (a quartic in x, the cube of the chord; measured, flexible: 6.2e-3,
    8.0e-4, 6.4e-5 at 2, 4, 8 elements; strain-based 2.4e-2, 1.1e-2, 3.2e-3)."""
    reference = unit_load_deflection(lambda x: LOAD * (LENGTH - x), chord_stiffness)
    errors = [static_tip(cantilever(fidelity, n, load=(0.0, LOAD, 0.0)))[1] / reference - 1 for n in (2, 4, 8)]
    assert_converges(errors, final, order)


def test_tapered_shear_deformable_chordwise_deflection_adds_the_shear_integral():
    """The shear-deformable element's sheet bends in the chord plane with its shear: the unit-load integral of
    M/EI_zz plus int V / (G c h) dx (Timoshenko, shear coefficient 1: the element's shear strain is uniform across
    the chord), converging at second order (measured 3.2e-3, 8.6e-4, 2.2e-4 at 8, 16, 32 elements)."""
    shear = quad(lambda x: LOAD / (E / 2 * chord(x) * thickness(x)), 0.0, LENGTH, epsabs=0.0, epsrel=1e-12)[0]
    reference = unit_load_deflection(lambda x: LOAD * (LENGTH - x), chord_stiffness) + shear
    errors = [static_tip(cantilever("shear-deformable", n, load=(0.0, LOAD, 0.0)))[1] / reference - 1
              for n in (8, 16, 32)]
    assert_converges(errors, 1e-3, 2)


GRAVITY = 9.81e-3   # m/s^2: a thousandth of g keeps the deflection at 3e-5 L, where the beam is linear


def weight_moment(x):
    """M(x) = int_x^L rho A(s) g (s - x) ds of the own weight, by quad."""
    return quad(lambda s: mass_per_length(s) * GRAVITY * (s - x), x, LENGTH, epsabs=0.0, epsrel=1e-12)[0]


@pytest.mark.parametrize("fidelity, order, final", [("flexible", 3, 1e-4), ("shear-deformable", 3, 1e-4),
                                                    ("strain-based", 2, STRAIN_BASED_FINAL)])
def test_tapered_cantilever_deflection_under_its_own_weight_is_the_integral_of_m_over_ei(fidelity, order, final):
    """rho A = rho c h (quadratic in x) loads the beam, EI_yy (quartic) carries it (measured, flexible: 7.3e-4,
    6.4e-5, 4.4e-6 at 2, 4, 8 elements; strain-based 1.0e-2, 2.1e-3, 4.8e-4)."""
    reference = unit_load_deflection(weight_moment, flap_stiffness)
    errors = [static_tip(cantilever(fidelity, n, gravity=(0.0, 0.0, GRAVITY)))[2] / reference - 1
              for n in (2, 4, 8)]
    assert_converges(errors, final, order)


def rayleigh_ritz_first_frequency(terms):
    """The first bending frequency (rad/s) of the clamped-free beam (EI_yy w'')'' = omega^2 rho A w by Rayleigh-Ritz
    on the polynomials of degree 2 .. terms + 1 with w(0) = w'(0) = 0, as phi_k = s^2 P_k(2 s - 1), s = x/L,
    k = 0 .. terms - 1 (P_k Legendre's: the span of the powers s^2 .. s^(terms + 1), whose mass matrix is too
    ill-conditioned at 12 terms for a Cholesky factorization): K_ij = int EI phi_i'' phi_j'' dx,
    M_ij = int rho A phi_i phi_j dx by 40-point Gauss quadrature (exact for these polynomials)."""
    xi, w = leggauss(40)
    x, w = 0.5 * LENGTH * (xi + 1.0), 0.5 * LENGTH * w
    s = x / LENGTH
    legendre = [Legendre.basis(k, domain=[0.0, 1.0]) for k in range(terms)]
    p, dp, ddp = (np.stack([q.deriv(d)(s) if d else q(s) for q in legendre], axis=1) for d in (0, 1, 2))
    shape = s[:, None] ** 2 * p
    curvature = (2.0 * p + 4.0 * s[:, None] * dp + s[:, None] ** 2 * ddp) / LENGTH**2
    stiffness = curvature.T @ (curvature * (flap_stiffness(x) * w)[:, None])
    mass = shape.T @ (shape * (mass_per_length(x) * w)[:, None])
    return np.sqrt(eigh(stiffness, mass, eigvals_only=True)[0])


def test_the_rayleigh_ritz_reference_is_converged():
    """10 and 12 polynomial terms agree to 1e-10 (measured 1.3e-12): the reference below is converged."""
    assert rayleigh_ritz_first_frequency(10) == pytest.approx(rayleigh_ritz_first_frequency(12), rel=1e-10)


@pytest.mark.parametrize("fidelity, order, final", [("flexible", 3, 1e-5), ("shear-deformable", 3, 1e-5),
                                                    ("strain-based", 2, STRAIN_BASED_FINAL)])
def test_tapered_cantilever_first_frequency_is_the_rayleigh_ritz_one(fidelity, order, final):
    """The model's lowest natural frequency (the first flap bending: torsion and chordwise bending are far above)
    against Rayleigh-Ritz (measured, flexible: 3.6e-4, 3.6e-5, 2.6e-6 at 2, 4, 8 elements; strain-based 1.5e-2,
    3.9e-3, 9.8e-4)."""
    reference = rayleigh_ritz_first_frequency(12)
    errors = [natural_frequencies(StructureSolver(StructureUnitSpec.from_scene(cantilever(fidelity, n))), count=1)[0]
              / reference - 1 for n in (2, 4, 8)]
    assert_converges(errors, final, order)


AXIS = 0.25     # the reference line a quarter chord behind the leading edge: the first moment about it is not zero


def rigid_mass_matrix(sweep_deg=None):
    """The 6 x 6 mass matrix of the tapered plate's rigid motions (v, omega) about the root, its reference line
    along x and chord along y: int int rho h(x) B^T B dy dx over the trapezoid y in [-a c(x), (1 - a) c(x)] (swept:
    from the leading edge y_LE(x) = -a c_r + x tan(sweep) over the chord c(x)), B = [I, -[p]x] at p = (x, y, 0),
    plus the rotary inertia int rho I_yy(x) dx on omega_y and omega_z (the Rayleigh term turns with the span
    direction), by dblquad."""
    if sweep_deg is None:
        lead = lambda x: -AXIS * chord(x)
    else:
        lead = lambda x: -AXIS * ROOT_CHORD + x * np.tan(np.radians(sweep_deg))
    def integrand(y, x, i, j):
        p = np.array([x, y, 0.0])
        B = np.hstack([np.eye(3), -np.array([[0.0, -p[2], p[1]], [p[2], 0.0, -p[0]], [-p[1], p[0], 0.0]])])
        return RHO * thickness(x) * (B.T @ B)[i, j]
    matrix = np.zeros((6, 6))
    for i in range(6):
        for j in range(i, 6):
            matrix[i, j] = matrix[j, i] = dblquad(integrand, 0.0, LENGTH, lead, lambda x: lead(x) + chord(x),
                                                  args=(i, j), epsabs=0.0, epsrel=1e-13)[0]
    rotary = quad(lambda x: 1e-4 + (3e-4 - 1e-4) * x / LENGTH, 0.0, LENGTH)[0]
    matrix[4, 4] += rotary
    matrix[5, 5] += rotary
    return matrix


@pytest.mark.parametrize("fidelity, elements", [("rigid", 1), ("flexible", 3)])
@pytest.mark.parametrize("sweep_deg", [None, 1.0])
def test_a_tapered_body_has_the_mass_centre_and_inertia_of_its_trapezoid(fidelity, elements, sweep_deg):
    """The kinetic energy of every rigid motion (v, omega) of the body, 1/2 dE^T M_E dE with dE the nodal vectors'
    rates (v + omega x r, omega x r_x, omega x r_y), against the integrals over the plate: the mass, the first
    moments (the centre) and the inertia tensor, exact (rho A ~ c h, rho Q_z ~ c^2 h, rho I_zz ~ c^3 h and the
    rotary inertia integrated exactly at the Gauss points): equal to 1e-12. A swept leading edge moves the chord,
    and the mass with it, about the reference line."""
    section = dict(TAPERED, axis_position=AXIS, rotary_inertia=1e-4, rotary_inertia_tip=3e-4)
    solver = StructureSolver(StructureUnitSpec.from_scene(cantilever(fidelity, elements, section,
                                                                     sweep_deg=sweep_deg)))
    model = solver.model
    nodes = model.top.initial_coordinates().reshape(-1, 3, 3)       # per node: r, r_x, r_y
    rates = np.zeros((len(nodes), 3, 3, 6))                          # d(node vectors) / d(v, omega)
    for k, (r, rx, ry) in enumerate(nodes):
        rates[k, 0, :, :3] = np.eye(3)
        for slot, vector in enumerate((r, rx, ry)):
            rates[k, slot, :, 3:] = -np.array([[0.0, -vector[2], vector[1]], [vector[2], 0.0, -vector[0]],
                                               [-vector[1], vector[0], 0.0]])
    R = rates.reshape(-1, 6)
    reference = rigid_mass_matrix(sweep_deg)
    np.testing.assert_allclose(R.T @ model.mass_E @ R, reference, rtol=0, atol=1e-12 * np.abs(reference).max())
    assert reference[0, 0] == pytest.approx(quad(mass_per_length, 0.0, LENGTH)[0], rel=1e-13)


EXPLICIT_SECTION = {"chord": 0.1, "torsional_rigidity": 1.0, "axial_stiffness": 1e6, "bending_stiffness_flap": 1.0,
                    "bending_stiffness_chord": 10.0, "mass_per_length": 0.3}


@pytest.mark.parametrize("section, tip", [(dict(EXPLICIT_SECTION, thickness_tip=0.002), "thickness_tip"),
                                          (dict(TAPERED, mass_per_length_tip=0.5), "mass_per_length_tip"),
                                          (dict(TAPERED, bending_stiffness_chord_tip=5.0),
                                           "bending_stiffness_chord_tip")])
def test_a_tip_value_without_the_root_value_it_varies_from_is_refused_naming_the_key(section, tip):
    """thickness_tip needs a plate's thickness; an explicit property's tip needs its root value (a plate's derived
    property varies by the plate's formula, not linearly): refused before anything runs, naming the tip key."""
    with pytest.raises(SceneError) as err:
        cantilever("flexible", 2, section)
    assert err.value.key == f"structure.bodies.wing.section.{tip}"


ROOT_GJ, TIP_GJ = 100.0, 40.0       # N m^2


def torsional_rigidity(x):
    return ROOT_GJ + (TIP_GJ - ROOT_GJ) * x / LENGTH


def tip_twist(fidelity, elements, couple):
    """The tip's twist (rad) and the torque (N m) of a couple of tip forces +-couple (N) along z at the leading and
    trailing edges, on the tapered plate whose GJ varies linearly: the torque from the loads' chord offsets as the
    structure applies them, the twist from the tip's r_y."""
    section = dict(TAPERED, torsional_rigidity=ROOT_GJ, torsional_rigidity_tip=TIP_GJ)
    scene = resolve_scene({"time": {"stop": 1.0}, "structure": {
        "fidelity": fidelity, "elements_per_body": elements, "bodies": [{"name": "wing", "length": LENGTH,
                                                                         "section": section}],
        "joints": [{"type": "clamp", "body": "wing"}],
        "loads": [{"body": "wing", "span": LENGTH, "chord": edge, "force": [0.0, 0.0, sign * couple]}
                  for edge, sign in ((0.0, -1.0), (1.0, 1.0))]}}, "twisted_cantilever")
    solver = StructureSolver(StructureUnitSpec.from_scene(scene))
    torque = sum(load.y * load.force[2] for load in solver.model.loads)
    deformed = static_coordinates(solver)
    tip = 9 * solver.topology.bodies["wing"].nodes[-1]
    chord_vector = deformed[tip + 6:tip + 9]
    return np.arctan2(chord_vector[2], chord_vector[1]), torque


@pytest.mark.parametrize("fidelity", DEFORMING)
def test_tapered_cantilever_twist_under_a_tip_torque_is_the_integral_of_t_over_gj(fidelity):
    """GJ linear from root to tip: the twist T int_0^L dx / GJ(x) (quad); each element twists uniformly with its
    mean GJ (the arithmetic mean where the exact compliance is the harmonic one), so the error falls at second
    order (measured 2.0e-2, 5.2e-3, 1.3e-3 at 2, 4, 8 elements in each fidelity)."""
    compliance = quad(lambda x: 1.0 / torsional_rigidity(x), 0.0, LENGTH, epsabs=0.0, epsrel=1e-12)[0]
    errors = []
    for n in (2, 4, 8):
        twist, torque = tip_twist(fidelity, n, 1e-3)
        errors.append(twist / (torque * compliance) - 1)
    assert_converges(errors, 2e-3, 2)


def test_a_strain_gauge_on_a_tapered_plate_reads_the_local_half_thickness():
    """A gauge's default surface distance is half the plate's thickness where it sits: h(x) / 2 of the linear
    thickness, at the root, a third of the span and the tip."""
    scene = resolve_scene({"time": {"stop": 1.0},
                           "structure": {"bodies": [{"name": "wing", "length": LENGTH, "section": TAPERED}],
                                         "joints": [{"type": "clamp", "body": "wing"}]},
                           "strain_gauges": [{"name": f"g{k}", "body": "wing", "span": x}
                                             for k, x in enumerate((0.0, LENGTH / 3, LENGTH))]}, "gauged")
    distances = [g["surface_distance"] for g in scene["strain_gauges"]]
    assert distances == pytest.approx([thickness(x) / 2 for x in (0.0, LENGTH / 3, LENGTH)], rel=1e-15)
