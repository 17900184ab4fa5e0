"""The shear-deformable element (Peng et al. 2019, Eqs. 1-10) against closed-form strains, Timoshenko beam theory
(static tip deflection and the frequency equation) and the elastica."""
import numpy as np
import pytest
from scipy.linalg import eigh, expm
from scipy.optimize import brentq

from elastica import elastica_tip
from structure_fmu import element, shear_element
from test_element import assert_rigid_motion_free_and_objective, straight

RNG = np.random.default_rng(5)
E_AL, G_AL, RHO_AL = 70e9, 26.3e9, 2700.0      # aluminium, Pa and kg/m^3


def plate(chord, thickness, count=1, leading_edge=None):
    """Section rows (count, 7) of an aluminium plate about its mid-chord (or a given leading edge y)."""
    lead = -chord / 2 if leading_edge is None else leading_edge
    flap = E_AL * chord * thickness**3 / 12
    return np.tile([E_AL, G_AL, chord, lead, thickness, flap, 0.4 * flap], (count, 1))


def test_rigid_motion_gives_zero_elastic_force_and_objectivity():
    assert_rigid_motion_free_and_objective(shear_element, plate(0.02, 0.005), E_AL * 0.02 * 0.005)


def tapered(section, rng):
    """Section rows (n, 7) made to vary along each element: (n, VARYING_POINTS, 7), the chord, leading edge,
    thickness, EI_yy and GJ scaled by random factors in [0.5, 2] at the Gauss points (E and G, the material's,
    constant)."""
    factors = rng.uniform(0.5, 2.0, (len(section), element.VARYING_POINTS, 7))
    factors[..., :2] = 1.0
    return section[:, None, :] * factors


@pytest.mark.parametrize("varies", [False, True])
def test_sheet_force_and_tangent_are_the_complex_step_derivatives(varies):
    """-dU/de and d^2U/de^2 of the sheet against complex steps of its energy and force, its section per element or
    varying along the span: exact to round-off."""
    l = np.array([0.3, 0.5, 0.05])
    section = plate(0.02, 0.005, 3, leading_edge=-0.004)      # reference line off the centroid: every term
    if varies:
        section = tapered(section, RNG)
    e = np.stack([straight(x) for x in l]) + 0.05 * RNG.standard_normal((3, 18))
    h = 1e-30
    perturbed = np.repeat(e[None].astype(complex), 18, axis=0)
    perturbed[np.arange(18), :, np.arange(18)] += 1j * h
    many = (np.tile(l, 18), np.tile(section, (18,) + (1,) * (section.ndim - 1)))
    gradient = shear_element.sheet_energy(perturbed.reshape(-1, 18), *many).imag.reshape(18, 3).T / h
    force = shear_element.sheet_force(e, l, section)
    np.testing.assert_allclose(-force, gradient, rtol=0, atol=1e-12 * np.abs(force).max())
    complex_step = -np.moveaxis(shear_element.sheet_force(perturbed.reshape(-1, 18), *many).imag.reshape(18, 3, 18),
                                0, 2) / h
    jac = shear_element.sheet_jacobian(e, l, section)
    np.testing.assert_allclose(jac, complex_step, rtol=0, atol=1e-12 * np.abs(complex_step).max())


@pytest.mark.parametrize("varies", [False, True])
@pytest.mark.parametrize("kernel", ["sheet_force", "sheet_jacobian"])
def test_the_c_kernels_equal_the_numpy_reference(monkeypatch, kernel, varies):
    """shear_element_kernels.c against the numpy forms on random elements and sections (per element, or varying
    along the span): equal to 1e-12."""
    rng = np.random.default_rng(17)
    length = rng.uniform(0.02, 0.5, 6)
    e = np.stack([straight(x) for x in length]) + 0.1 * rng.standard_normal((6, 18))
    section = plate(0.02, 0.005, 6) * rng.uniform(0.5, 2.0, (6, 7))
    if varies:
        section = tapered(section, rng)
    results = {}
    for kind in ("numpy", "compiled"):
        monkeypatch.setenv("WINGSIM_KERNELS", kind)
        results[kind] = getattr(shear_element, kernel)(e, length, section)
    assert np.abs(results["numpy"]).max() > 0
    assert np.abs(results["compiled"] - results["numpy"]).max() <= 1e-12 * np.abs(results["numpy"]).max()


def test_uniform_stretch_and_shear_give_the_green_strain_energies():
    """A uniform stretch lambda: U = 1/2 E A l eps^2 with the Green strain eps = (lambda^2 - 1) / 2; a uniform
    shear turning r_y by gamma_0 towards r_x: the engineering strain r_x . r_y = sin gamma_0 and
    U = 1/2 G A l sin^2 gamma_0 (the full shear energy: Peng et al. 2019, Eqs. 7 and 9 as printed give half)."""
    c, h, l = 0.02, 0.005, 0.3
    section, A = plate(c, h), c * h
    stretch = 1.01
    e = straight(l).reshape(6, 3)
    e[3, 0] *= stretch
    e[[1, 4], 0] = stretch
    green = (stretch**2 - 1) / 2
    assert shear_element.sheet_energy(e.reshape(1, 18), [l], section)[0] == pytest.approx(
        0.5 * E_AL * A * l * green**2, rel=1e-12)
    gamma0 = 0.03
    e = straight(l).reshape(6, 3)
    e[[2, 5]] = [np.sin(gamma0), np.cos(gamma0), 0.0]
    assert shear_element.sheet_energy(e.reshape(1, 18), [l], section)[0] == pytest.approx(
        0.5 * G_AL * A * l * np.sin(gamma0) ** 2, rel=1e-12)


def clamped_cantilever(length, section, count):
    """A straight cantilever along x of `count` elements, the chord along y, clamped at x = 0: (coordinates (9 (n +
    1),), element dofs (n, 18), element lengths (n,), the free coordinates)."""
    nodes = np.zeros((count + 1, 9))
    nodes[:, 0], nodes[:, 3], nodes[:, 7] = np.linspace(0.0, length, count + 1), 1.0, 1.0
    dofs = np.array([np.arange(9 * k, 9 * k + 18) for k in range(count)])
    return nodes.ravel(), dofs, np.full(count, length / count), np.arange(9, 9 * (count + 1))


def static_tip(length, section, count, tip_force, steps=1):
    """The tip displacement (3,) of the cantilever under a dead tip force (3,), N: Newton on the assembled force of
    shear_element, the load in `steps` equal increments."""
    x, dofs, lengths, free = clamped_cantilever(length, section, count)
    sections = np.tile(section, (count, 1))
    n = len(x)
    entries = (dofs[:, :, None] * n + dofs[:, None, :]).ravel()
    for step in range(1, steps + 1):
        load = np.zeros(n)
        load[n - 9:n - 6] = tip_force * step / steps
        for _ in range(50):
            force = load.copy()
            np.add.at(force, dofs, shear_element.elastic_force(x[dofs], lengths, sections))
            K = np.bincount(entries, shear_element.elastic_jacobian(x[dofs], lengths, sections).ravel(),
                            n * n).reshape(n, n)
            dx = np.linalg.solve(K[np.ix_(free, free)], force[free])
            x[free] += dx
            if np.abs(dx).max() < 1e-13 * length:
                break
        else:
            raise AssertionError("Newton did not converge")
    return x[n - 9:n - 6] - np.array([length, 0.0, 0.0])


@pytest.mark.parametrize("slenderness", [2.0, 5.0, 20.0, 200.0])
def test_thick_cantilever_tip_deflection_is_timoshenko_beam_theory(slenderness):
    """A tip load in the chord's plane, 16 elements, small load: F L^3 / (3 E I) + F L / (G A) (Timoshenko, with
    the shear coefficient 1 of a shear strain uniform across the section), within 0.3% at every slenderness L / c;
    at L / c = 2 and 5 that is 14% and 2.6% beyond Euler-Bernoulli, which the element must not give; slender, both
    agree (converging to F L^3 / (3 E I))."""
    c, h = 0.02, 0.005
    length, I, A = slenderness * c, h * c**3 / 12, c * h
    force = 1e-6 * E_AL * I / length**2
    tip = static_tip(length, plate(c, h), 16, np.array([0.0, force, 0.0]))
    bending = force * length**3 / (3 * E_AL * I)
    timoshenko = bending + force * length / (G_AL * A)
    assert tip[1] == pytest.approx(timoshenko, rel=3e-3)
    if slenderness <= 5:
        assert abs(tip[1] / bending - 1) > 5 * 3e-3
    else:
        assert tip[1] == pytest.approx(bending, rel=3e-3 + (timoshenko / bending - 1))


def test_tip_deflection_converges_at_second_order():
    """Slender (L / c = 50): the error against Euler-Bernoulli falls by 4 with each halving of the elements (the
    curvature constant per element in the shear-free limit; no shear locking)."""
    c, h = 0.02, 0.005
    length, I = 50 * c, h * c**3 / 12
    force = 1e-6 * E_AL * I / length**2
    exact = force * length**3 / (3 * E_AL * I) + force * length / (G_AL * c * h)
    load = np.array([0.0, force, 0.0])
    errors = [static_tip(length, plate(c, h), count, load)[1] / exact - 1 for count in (4, 8, 16)]
    assert errors[0] / errors[1] == pytest.approx(4.0, rel=0.02)
    assert errors[1] / errors[2] == pytest.approx(4.0, rel=0.02)


@pytest.mark.parametrize("parameter", [1.0, 10.0])
def test_large_deflection_matches_elastica(parameter):
    """Slender (L / c = 100, shear and stretch below 1e-4 of the deflection), 32 elements, a dead tip load
    P L^2 / EI = 1 and 10 in the chord's plane: the tip within 0.5% of the inextensible elastica (measured
    3.4e-4 and 1.3e-3; with 16 elements 4.2e-3 and 1.9e-2: r_y interpolated linearly between nodes turned apart
    shortens, and the transverse strain stiffens elements long against c / (kappa l))."""
    c, h = 0.01, 0.005
    length, I = 100 * c, h * c**3 / 12
    force = parameter * E_AL * I / length**2
    tip = static_tip(length, plate(c, h), 32, np.array([0.0, force, 0.0]), steps=1 + int(parameter) // 3)
    dx, dz = elastica_tip(parameter)
    expected = length * np.array([dx, dz, 0.0])
    assert np.linalg.norm(tip - expected) < 5e-3 * np.linalg.norm(expected)


def timoshenko_frequencies(length, E, G, rho, A, I, count):
    """The lowest `count` natural frequencies (rad/s) of a clamped-free Timoshenko beam (shear coefficient 1, with
    rotary inertia): the roots of its frequency equation, det of the two free-end conditions EI theta'(L) = 0 and
    G A (w'(L) - theta(L)) = 0 on the solutions with w(0) = theta(0) = 0 of
    G A (w'' - theta') = -rho A omega^2 w, E I theta'' + G A (w' - theta) = -rho I omega^2 theta,
    by the exact transfer matrix expm(A(omega) L) and brentq on a fine frequency grid."""
    def determinant(omega):
        system = np.zeros((4, 4))          # y = [w, w', theta, theta']
        system[0, 1] = system[2, 3] = 1.0
        system[1, 0], system[1, 3] = -rho * omega**2 / G, 1.0
        system[3, 1], system[3, 2] = -G * A / (E * I), G * A / (E * I) - rho * omega**2 / E
        end = expm(system * length)[:, [1, 3]]              # from w'(0), theta'(0)
        conditions = np.array([end[3], end[1] - end[2]])
        return np.linalg.det(conditions)
    euler = np.sqrt(E * I / (rho * A * length**4))
    grid = np.linspace(0.5, 70.0, 400) * euler       # the third Euler-Bernoulli root is 61.7
    values = [determinant(w) for w in grid]
    roots = [brentq(determinant, a, b, xtol=1e-12 * euler) for a, b, fa, fb in
             zip(grid[:-1], grid[1:], values[:-1], values[1:]) if fa * fb < 0]
    return np.array(roots[:count])


@pytest.mark.parametrize("slenderness", [4.0, 20.0])
def test_bending_frequencies_are_timoshenko_frequency_equation(slenderness):
    """Clamped cantilever, 32 elements, linearized at rest: the three lowest in-plane bending frequencies (the
    coordinates r.y, r_x.y, r_y.x, decoupled from the others at rest about the centroid) within 0.5% of the roots
    of Timoshenko's frequency equation, the first within 0.05% (measured: 3.5e-4, 2.5e-3, 4.5e-3 at L / c = 4;
    2.0e-4, 1.4e-3, 3.3e-3 at 20; second order in the element length); at L / c = 4 the first is 4% below
    Euler-Bernoulli's 1.8751^2."""
    c, h, count = 0.02, 0.005, 32
    length, I, A = slenderness * c, h * c**3 / 12, c * h
    x, dofs, lengths, free = clamped_cantilever(length, plate(c, h), count)
    n = len(x)
    sections = np.tile(plate(c, h), (count, 1))
    one = np.ones(count)
    masses = element.mass_matrix(lengths, RHO_AL * A * one, 0 * one, RHO_AL * h * c**3 / 12 * one)
    M, K = np.zeros((n, n)), np.zeros((n, n))
    for d, m, k in zip(dofs, masses, shear_element.elastic_jacobian(x[dofs], lengths, sections)):
        M[np.ix_(d, d)] += m
        K[np.ix_(d, d)] += k
    in_plane = free[np.isin(free % 9, [1, 4, 6])]         # r.y, r_x.y, r_y.x
    omega = np.sqrt(eigh(K[np.ix_(in_plane, in_plane)], M[np.ix_(in_plane, in_plane)], eigvals_only=True)[:3])
    reference = timoshenko_frequencies(length, E_AL, G_AL, RHO_AL, A, I, 3)
    np.testing.assert_allclose(omega, reference, rtol=5e-3)
    assert omega[0] == pytest.approx(reference[0], rel=5e-4)
    euler = 1.8751**2 * np.sqrt(E_AL * I / (RHO_AL * A * length**4))
    if slenderness < 5:
        assert omega[0] < 0.97 * euler
