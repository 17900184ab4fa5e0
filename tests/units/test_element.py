"""The 18-DoF ANCF element (Otsuka et al. 2019, Sec. II) against closed-form values."""
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from structure_fmu import element

RNG = np.random.default_rng(7)


def straight(length):
    """Undeformed element along x with chord along y: e of Otsuka et al. 2019, Eq. (3)."""
    return np.array([0, 0, 0, 1, 0, 0, 0, 1, 0, length, 0, 0, 1, 0, 0, 0, 1, 0], dtype=float)


def paper_mass_matrix(A, Qz, Izz, l):
    """Otsuka et al. 2019, Eq. (5) with its identity blocks restored (docs/references.md, known slips), scalar
    6x6 part times rho = 1."""
    upper = [
        [13 * A * l / 35, 11 * A * l**2 / 210, 7 * Qz * l / 20, 9 * A * l / 70, -13 * A * l**2 / 420, 3 * Qz * l / 20],
        [0, A * l**3 / 105, Qz * l**2 / 20, 13 * A * l**2 / 420, -A * l**3 / 140, Qz * l**2 / 30],
        [0, 0, Izz * l / 3, 3 * Qz * l / 20, -Qz * l**2 / 30, Izz * l / 6],
        [0, 0, 0, 13 * A * l / 35, -11 * A * l**2 / 210, 7 * Qz * l / 20],
        [0, 0, 0, 0, A * l**3 / 105, -Qz * l**2 / 20],
        [0, 0, 0, 0, 0, Izz * l / 3],
    ]
    m = np.array(upper)
    m = m + np.triu(m, 1).T
    return np.kron(m, np.eye(3))


def test_mass_matrix_equals_paper_eq5():
    l, A, Qz, Izz = 0.37, 2.1, 0.13, 0.045
    M = element.mass_matrix(np.array([l]), np.array([A]), np.array([Qz]), np.array([Izz]))[0]
    np.testing.assert_allclose(M, paper_mass_matrix(A, Qz, Izz, l), rtol=1e-13, atol=1e-15)


def test_mass_matrix_total_mass_and_moments():
    """Rigid translation carries rho A l; a uniform r_y rate pairs with it through rho Q_z l."""
    l, mu, mu1, mu2 = 0.8, 3.0, 0.2, 0.07
    M = element.mass_matrix(np.array([l]), np.array([mu]), np.array([mu1]), np.array([mu2]))[0]
    v, w = np.array([0.3, -1.2, 0.5]), np.array([0.7, 0.1, -0.4])
    translation = np.concatenate([v, 0 * v, 0 * v, v, 0 * v, 0 * v])
    chord_rate = np.concatenate([0 * w, 0 * w, w, 0 * w, 0 * w, w])
    assert translation @ M @ translation == pytest.approx(mu * l * v @ v, rel=1e-13)
    assert translation @ M @ chord_rate == pytest.approx(mu1 * l * v @ w, rel=1e-13)
    assert chord_rate @ M @ chord_rate == pytest.approx(mu2 * l * w @ w, rel=1e-13)


def test_gravity_force_is_weight_and_its_moment():
    l, mu, mu1 = 0.5, 2.0, 0.1
    g = np.array([0.0, 0.0, -9.81])
    F = element.distributed_force(np.array([l]), np.array([mu]), np.array([mu1]), g)[0]
    translation = np.tile(np.concatenate([np.ones(3), np.zeros(6)]), 2)
    # virtual work of a unit translation in each direction: the weight
    assert F.reshape(6, 3)[[0, 3]].sum(axis=0) @ np.array([0, 0, 1]) == pytest.approx(mu * l * g[2])
    assert translation @ F == pytest.approx(mu * l * g.sum())


def rigid_transform(e, rotation, shift):
    v = e.reshape(-1, 6, 3) @ rotation.T
    v[:, [0, 3]] += shift
    return v.reshape(-1, 18)


def assert_rigid_motion_free_and_objective(law, table, scale):
    """An element law (`element` or `shear_element`: elastic_energy, elastic_force of (e, l, table)) gives no force
    on a straight element moved rigidly (below 1e-9 of `scale`, N), and on a deformed one the same energy and the
    force rotated with it."""
    l = np.array([0.4])
    R = Rotation.from_rotvec([0.4, -1.1, 2.0]).as_matrix()
    moved = rigid_transform(straight(0.4)[None], R, np.array([1.0, -2.0, 0.5]))
    assert np.max(np.abs(law.elastic_force(moved, l, table))) < 1e-9 * scale
    deformed = straight(0.4)[None] + 0.02 * RNG.standard_normal((1, 18))
    moved = rigid_transform(deformed, R, np.array([0.3, 0.2, 0.1]))
    energy = law.elastic_energy(deformed, l, table)
    assert law.elastic_energy(moved, l, table) == pytest.approx(energy, rel=1e-12)
    rotated_force = (law.elastic_force(deformed, l, table).reshape(6, 3) @ R.T).ravel()
    np.testing.assert_allclose(law.elastic_force(moved, l, table)[0], rotated_force,
                               atol=1e-9 * np.abs(rotated_force).max())


def test_rigid_motion_gives_zero_elastic_force_and_objectivity():
    stiffness = np.array([[2e5, 3.0, 40.0, 1.5]])
    assert_rigid_motion_free_and_objective(element, stiffness, stiffness.max())


def test_force_is_gradient_of_energy_and_jacobian_is_its_derivative():
    stiffness = np.array([[1e3, 2.0, 3.0, 4.0], [5e2, 1.0, 7.0, 0.5]])
    l = np.array([0.3, 0.5])
    e = np.stack([straight(0.3), straight(0.5)]) + 0.05 * RNG.standard_normal((2, 18))
    force = element.elastic_force(e, l, stiffness)
    jac = element.elastic_jacobian(e, l, stiffness)
    h = 1e-6
    for k in range(18):
        ep, em = e.copy(), e.copy()
        ep[:, k] += h
        em[:, k] -= h
        dU = (element.elastic_energy(ep, l, stiffness) - element.elastic_energy(em, l, stiffness)) / (2 * h)
        np.testing.assert_allclose(-force[:, k], dU, rtol=1e-6, atol=1e-6 * np.abs(force).max())
        dF = (element.elastic_force(ep, l, stiffness) - element.elastic_force(em, l, stiffness)) / (2 * h)
        np.testing.assert_allclose(-jac[:, :, k], dF, rtol=1e-5, atol=1e-5 * np.abs(jac).max())


@pytest.mark.parametrize("section", ["constant", "varying"])
@pytest.mark.parametrize("term", ["axial", "flap", "chordwise", "torsion"])
def test_analytic_tangent_equals_the_complex_step_derivative_of_the_force(term, section):
    """Each energy term alone (its stiffness column only), on bent, twisted, stretched elements, its stiffness per
    element or varying along the span: the analytic second derivative against the complex-step derivative of the
    force, exact to round-off (no cancellation), so the two agree to 1e-12 and a wrong block of any term shows."""
    column = ["axial", "flap", "chordwise", "torsion"].index(term)
    stiffness = np.zeros((3, 4))
    stiffness[:, column] = [1e6, 2.0, 50.0, 3.0][column] * np.array([1.0, 0.2, 7.0])
    if section == "varying":
        stiffness = varying(stiffness, RNG)
    l = np.array([0.3, 0.5, 0.02])
    e = np.stack([straight(x) for x in l]) + 0.05 * RNG.standard_normal((3, 18))
    h = 1e-30
    perturbed = np.repeat(e[None].astype(complex), 18, axis=0)               # copy k moves e_k by i h
    perturbed[np.arange(18), :, np.arange(18)] += 1j * h
    force = element.elastic_force(perturbed.reshape(-1, 18), np.tile(l, 18),
                                  np.tile(stiffness, (18,) + (1,) * (stiffness.ndim - 1)))
    complex_step = -np.moveaxis(force.imag.reshape(18, 3, 18), 0, 2) / h
    jac = element.elastic_jacobian(e, l, stiffness)
    assert np.abs(complex_step).max() > 0
    np.testing.assert_allclose(jac, complex_step, rtol=0, atol=1e-12 * np.abs(complex_step).max())
    np.testing.assert_allclose(jac, np.swapaxes(jac, 1, 2), rtol=0, atol=1e-12 * np.abs(jac).max())


def arc_element(length, curvature, plane):
    """Nodes of a circular arc of `curvature` starting along x: bending toward z (flap) or y (chord)."""
    phi = curvature * length
    bend = np.array([0, 0, 1.0]) if plane == "flap" else np.array([0, 1.0, 0])
    x_axis = np.array([1.0, 0, 0])
    rB = (np.sin(phi) * x_axis + (1 - np.cos(phi)) * bend) / curvature
    xB = np.cos(phi) * x_axis + np.sin(phi) * bend
    yA = np.array([0, 1.0, 0])
    yB = yA if plane == "flap" else np.cos(phi) * yA - np.sin(phi) * x_axis
    return np.concatenate([np.zeros(3), x_axis, yA, rB, xB, yB])[None]


@pytest.mark.parametrize("plane, column", [("flap", 1), ("chord", 2)])
def test_pure_bending_gives_beam_theory_energy(plane, column):
    """A circular arc of curvature kappa stores EI kappa^2 l / 2 (Euler-Bernoulli)."""
    l, kappa = 0.2, 0.05
    stiffness = np.array([[1e6, 3.0, 5.0, 2.0]])
    U = element.elastic_energy(arc_element(l, kappa, plane), np.array([l]), stiffness)[0]
    assert U == pytest.approx(0.5 * stiffness[0, column] * kappa**2 * l, rel=1e-4)


@pytest.mark.parametrize("stretch", [1.0, 1.3])
def test_flap_curvature_of_a_circular_arc_is_its_curvature(stretch):
    """r(s) = stretch x (sin(kappa s), 0, 1 - cos(kappa s)) / kappa with the chord along y: a circle of
    radius stretch / kappa bending toward +n = r' x r_y / |r' x r_y|, so kappa_y = kappa / stretch at
    every s (a stretch of the line lowers its geometric curvature)."""
    kappa, s = 3.0, np.linspace(0.0, 0.4, 5)
    r1 = stretch * np.stack([np.cos(kappa * s), 0 * s, np.sin(kappa * s)], axis=-1)
    r2 = stretch * kappa * np.stack([-np.sin(kappa * s), 0 * s, np.cos(kappa * s)], axis=-1)
    ry = np.broadcast_to([0.0, 1.0, 0.0], r1.shape)
    values = element.flap_curvature(np.stack([r1, r2, ry], axis=-2))
    assert values == pytest.approx(np.full(5, kappa / stretch), rel=1e-12)
    # the formula of the docstring with cross and dot products, on random rows
    d = RNG.standard_normal((6, 3, 3))
    normal = np.cross(d[:, 0], d[:, 2])
    expected = np.sum(d[:, 1] * normal, axis=1) / (np.linalg.norm(normal, axis=1) * np.sum(d[:, 0] ** 2, axis=1))
    assert element.flap_curvature(d) == pytest.approx(expected, rel=1e-10)


def test_flap_curvature_keeps_the_stack_shape_and_the_det_form_to_round_off():
    """flap_curvature, on floats point by point, returns the shape of the stack it is given, and equals the
    determinant form -det[r', r'', r_y] / (|r' x r_y| |r'|^2) within the round-off of its products and of the
    Gram form of |r' x r_y| (whose cancellation grows as |r'|^2 |r_y|^2 / |r' x r_y|^2): 8 eps of that
    conditioning, on 20000 random points (2 eps at most is reached on 2e5)."""
    d = np.random.default_rng(3).standard_normal((20000, 3, 3))
    values = element.flap_curvature(d)
    assert element.flap_curvature(d.reshape(4, 5000, 3, 3)).shape == (4, 5000)
    assert element.flap_curvature(np.zeros((0, 3, 3))).shape == (0,)
    r1, r2, ry = d[:, 0], d[:, 1], d[:, 2]
    across, r1r1, ryry = np.linalg.norm(np.cross(r1, ry), axis=-1), np.sum(r1 * r1, axis=-1), np.sum(ry * ry, axis=-1)
    reference = -np.linalg.det(d) / (across * r1r1)
    conditioning = (np.linalg.norm(r2, axis=-1) * np.sqrt(r1r1 * ryry) / (across * r1r1)
                    + np.abs(reference) * r1r1 * ryry / across ** 2)
    assert np.all(np.abs(values - reference) <= 8 * np.finfo(float).eps * conditioning)


def test_pure_torsion_gives_beam_theory_energy():
    """A uniform twist rate kappa_x stores GJ kappa_x^2 l / 2."""
    l, twist = 0.2, 1e-3
    e = straight(l)
    e[15:18] = [0, np.cos(twist), np.sin(twist)]   # r_y^B rotated about x by the twist angle
    stiffness = np.array([[1e6, 3.0, 5.0, 2.0]])
    U = element.elastic_energy(e[None], np.array([l]), stiffness)[0]
    assert U == pytest.approx(0.5 * 2.0 * (twist / l) ** 2 * l, rel=1e-6)


def test_uniform_stretch_gives_axial_energy():
    l, strain = 0.3, 1e-3
    e = straight(l)
    e[3:6] *= 1 + strain
    e[9:12] *= 1 + strain
    e[12:15] *= 1 + strain
    stiffness = np.array([[2e5, 3.0, 5.0, 2.0]])
    U = element.elastic_energy(e[None], np.array([l]), stiffness)[0]
    assert U == pytest.approx(0.5 * 2e5 * strain**2 * l, rel=1e-6)


def test_the_slot_basis_has_the_zero_pattern_the_c_kernels_skip():
    """element_kernels.c loops over the slots [d, r_x^A, r_y^A, r_x^B, r_y^B] each field is made of: r' and r''
    from d, r_x^A, r_x^B (Hermite functions in x), r_y from r_y^A, r_y^B (linear in x), every other entry of
    element._slot_basis exactly zero, for any lengths; and each slot does enter its fields (r_y is the linear
    interpolation (1 - xi) r_y^A + xi r_y^B)."""
    curve, chord = [0, 1, 3], [2, 4]
    g = len(element.GAUSS_W)
    length = 10.0 ** np.random.default_rng(17).uniform(-3.0, 1.0, 11)
    basis = element._slot_basis(length)
    assert basis.shape == (11, 3 * g, 5)
    assert np.all(basis[:, :2 * g, chord] == 0.0)
    assert np.all(basis[:, 2 * g:, curve] == 0.0)
    assert np.all(np.abs(basis[:, :g, curve]).max(axis=1) > 0.0)
    assert np.all(np.abs(basis[:, g:2 * g, curve]).max(axis=1) > 0.0)
    np.testing.assert_allclose(basis[:, 2 * g:, chord], np.broadcast_to(
        np.stack([1.0 - element.GAUSS_XI, element.GAUSS_XI], axis=-1), (11, g, 2)), rtol=1e-15, atol=1e-15)


@pytest.mark.parametrize("points", [element.CONSTANT_POINTS, element.VARYING_POINTS])
def test_the_energy_reads_the_strain_measures_of_the_gradients_bit_for_bit(points):
    """elastic_energy takes its measures from element._energy_measures, which leaves out the cross products
    only the gradients need: flap r''.n, chordwise r''.r_y, the axial strains and tau equal those of
    element._measures (the gradients' path) exactly, on elements bent, stretched and twisted at random."""
    rng = np.random.default_rng(23)
    for n in (1, 2, 7):
        length = rng.uniform(0.05, 2.0, n)
        e = np.stack([straight(l) for l in length]) + 0.3 * rng.standard_normal((n, 18))
        full = element._measures(e, length, points)
        flap, chordwise, axial, tau = element._energy_measures(e, length, points)
        for name, value in (("flap", flap), ("chordwise", chordwise), ("axial", axial), ("tau", tau)):
            np.testing.assert_array_equal(value, full[name], err_msg=name)


def varying(stiffness, rng):
    """The stiffness table (n, 4) made to vary along each element: (n, VARYING_POINTS, 4), each column scaled by
    independent random factors in [0.5, 2] at the Gauss points."""
    g = element.VARYING_POINTS
    return stiffness[:, None, :] * rng.uniform(0.5, 2.0, (len(stiffness), g, 4))


def random_elements(seed, section):
    """Seven random elements, every term of the energy active (e (7, 18), length (7,) m, stiffness (7, 4)), their
    stiffness per element ("constant") or varying along the span ("varying")."""
    rng = np.random.default_rng(seed)
    e = rng.standard_normal((7, 18))
    length, stiffness = rng.uniform(0.05, 0.5, 7), rng.uniform(1.0, 1e3, (7, 4))
    return e, length, varying(stiffness, rng) if section == "varying" else stiffness


@pytest.mark.parametrize("section", ["constant", "varying"])
def test_the_c_elastic_force_equals_the_numpy_reference(monkeypatch, section):
    """element_kernels.c against element.elastic_force's numpy form on random elements (every term active:
    stretch, both bendings, torsion), with a stiffness per element and one that varies along the span (given at
    the Gauss points): equal to 1e-12 of the largest component."""
    e, length, stiffness = random_elements(11, section)
    forces = {}
    for kind in ("numpy", "compiled"):
        monkeypatch.setenv("WINGSIM_KERNELS", kind)
        forces[kind] = element.elastic_force(e, length, stiffness)
    assert np.abs(forces["compiled"] - forces["numpy"]).max() <= 1e-12 * np.abs(forces["numpy"]).max()


@pytest.mark.parametrize("section", ["constant", "varying"])
def test_the_c_elastic_energy_equals_the_numpy_reference(monkeypatch, section):
    """element_kernels.c's elastic_energy against element.elastic_energy's numpy form on random elements (stretch,
    both bendings and torsion all active), a stiffness per element and one varying along the span: equal to 1e-12
    of each element's energy; and the straight element, unstrained, holds none but the round-off of its strains
    (EA l (8 eps)^2 at most: a stretch of a few eps)."""
    e, length, stiffness = random_elements(13, section)
    energies = {}
    for kind in ("numpy", "compiled"):
        monkeypatch.setenv("WINGSIM_KERNELS", kind)
        energies[kind] = element.elastic_energy(e, length, stiffness)
        unstrained = element.elastic_energy(straight(0.3)[None], np.array([0.3]), stiffness[:1])[0]
        assert 0.0 <= unstrained <= stiffness.max() * 0.3 * (8 * np.finfo(float).eps) ** 2
    np.testing.assert_allclose(energies["compiled"], energies["numpy"], rtol=1e-12, atol=0)


@pytest.mark.parametrize("section", ["constant", "varying"])
def test_the_gathered_c_force_equals_the_numpy_assembly(monkeypatch, section):
    """add_elastic_force (one C call: gathered from E, added into F) on a chain of elements sharing nodes, against
    F + the numpy forces summed by np.bincount (its $WINGSIM_KERNELS=numpy reference): equal to 1e-12 of the
    largest component; the scratch space's earlier contents do not matter."""
    rng = np.random.default_rng(23)
    length = rng.uniform(0.05, 0.5, 6)
    stiffness = rng.uniform(0.5, 2.0, (6, 4)) * np.array([1e6, 2.0, 50.0, 3.0])
    if section == "varying":
        stiffness = varying(stiffness, rng)
    dofs = np.ascontiguousarray((9 * np.arange(6)[:, None] + np.arange(18)).astype(np.int64))   # node k: 9k..9k+8
    E = np.concatenate([straight(x)[:9] for x in length] + [straight(length[-1])[9:]]) + 0.1 * rng.standard_normal(63)
    base = rng.standard_normal(63)
    reference = base + np.bincount(dofs.ravel(), element.elastic_force(E[dofs], length, stiffness).ravel(), 63)
    forces = {}
    for kind in ("numpy", "compiled"):
        monkeypatch.setenv("WINGSIM_KERNELS", kind)
        forces[kind] = element.add_elastic_force(E, dofs, length, stiffness, base.copy(), np.full(36 * 6, np.nan))
    for kind in forces:
        assert np.abs(forces[kind] - reference).max() <= 1e-12 * np.abs(reference).max()


@pytest.mark.parametrize("section", ["constant", "varying"])
@pytest.mark.parametrize("term", ["all", "axial", "flap", "chordwise", "torsion"])
def test_the_c_elastic_jacobian_equals_the_numpy_reference(monkeypatch, term, section):
    """element_kernels.c's tangent against element.elastic_jacobian's numpy form on random stretched, bent and
    twisted elements of different lengths and stiffnesses (per element, or varying along the span): every term
    together, then each alone (so that a wrong block of a small term cannot hide under the axial one), equal to
    1e-12 of the largest entry."""
    rng = np.random.default_rng(13)
    length = rng.uniform(0.02, 0.5, 7)
    e = np.stack([straight(x) for x in length]) + 0.1 * rng.standard_normal((7, 18))
    stiffness = rng.uniform(0.5, 2.0, (7, 4)) * np.array([1e6, 2.0, 50.0, 3.0])
    if section == "varying":
        stiffness = varying(stiffness, rng)
    if term != "all":
        stiffness[..., ["axial", "flap", "chordwise", "torsion"].index(term) != np.arange(4)] = 0.0
    tangents = {}
    for kind in ("numpy", "compiled"):
        monkeypatch.setenv("WINGSIM_KERNELS", kind)
        tangents[kind] = element.elastic_jacobian(e, length, stiffness)
    assert np.abs(tangents["numpy"]).max() > 0
    assert np.abs(tangents["compiled"] - tangents["numpy"]).max() <= 1e-12 * np.abs(tangents["numpy"]).max()


def test_the_c_kernels_take_any_real_arrays_and_follow_a_stiffness_changed_in_place(monkeypatch):
    """The C kernels get their own contiguous copies: a read-only, Fortran-ordered e gives the numpy reference's
    force and tangent; their constant arguments are cached by value, so a stiffness array changed in place between
    two calls is seen by the second (equal to 1e-12 of the largest entry, as above)."""
    rng = np.random.default_rng(19)
    length = rng.uniform(0.05, 0.5, 5)
    e = np.asfortranarray(np.stack([straight(x) for x in length]) + 0.1 * rng.standard_normal((5, 18)))
    e.flags.writeable = False
    stiffness = rng.uniform(0.5, 2.0, (5, 4)) * np.array([1e6, 2.0, 50.0, 3.0])
    for scale in (1.0, 3.0):
        stiffness *= scale                      # in place: the same array object in both calls
        results = {}
        for kind in ("numpy", "compiled"):
            monkeypatch.setenv("WINGSIM_KERNELS", kind)
            results[kind] = [f(e, length, stiffness) for f in (element.elastic_force, element.elastic_jacobian)]
        for compiled, reference in zip(results["compiled"], results["numpy"]):
            assert np.abs(compiled - reference).max() <= 1e-12 * np.abs(reference).max()


def test_the_c_kernels_refuse_arguments_they_cannot_read(monkeypatch):
    """What C cannot check is refused before the call: e of another shape than (n, 18) for the n lengths, or a
    stiffness that is not (n, 4); the kernels themselves return -1 for a Gauss point count beyond their scratch
    arrays (MAX_GAUSS = 8), writing nothing."""
    monkeypatch.setenv("WINGSIM_KERNELS", "compiled")
    length, stiffness = np.full(3, 0.2), np.ones((3, 4))
    e = np.stack([straight(0.2)] * 3)
    with pytest.raises(ValueError, match=r"e \(3, 17\)"):
        element.elastic_force(e[:, :17], length, stiffness)
    with pytest.raises(ValueError, match=r"e \(2, 18\)"):
        element.elastic_jacobian(e[:2], length, stiffness)
    with pytest.raises(ValueError, match=r"stiffness \(3, 3\)"):
        element.elastic_force(e, length, stiffness[:, :3])
    kernels, out = element.c_kernels(), np.full((3, 18, 18), 7.0)
    table, address, _ = element._table(length, stiffness)
    for g in (0, 9):                            # the table holds 5 points: the kernel must not read it at all
        assert kernels.elastic_force(3, g, address, e.ctypes.data, out.ctypes.data) == -1
        assert kernels.elastic_jacobian(3, g, address, e.ctypes.data, out.ctypes.data) == -1
    assert np.all(out == 7.0)


def test_properties_given_at_the_gauss_points_with_constant_values_are_the_constant_section():
    """The same section given per element and at the VARYING_POINTS Gauss points, a finer rule of the same exact
    integrals: the mass matrix and body force equal to 1e-13, and the bending and torsion energy of a deformed
    element to 1e-12 (its integrands are polynomials of degree 8; the axial term is left out, its arc length
    |r'| being the one non-polynomial integrand, which no rule integrates exactly)."""
    g = element.VARYING_POINTS
    l, mu, mu1, mu2, rotary = np.array([0.37]), np.array([2.1]), np.array([0.13]), np.array([0.045]), np.array([1e-3])
    spread = [np.full((1, g), v[0]) for v in (mu, mu1, mu2, rotary)]
    np.testing.assert_allclose(element.mass_matrix(l, *spread), element.mass_matrix(l, mu, mu1, mu2, rotary),
                               rtol=1e-13, atol=1e-15)
    gravity = np.array([0.0, 0.0, -9.81])
    np.testing.assert_allclose(element.distributed_force(l, spread[0], spread[1], gravity),
                               element.distributed_force(l, mu, mu1, gravity), rtol=1e-13, atol=1e-15)
    stiffness = np.array([[0.0, 2.0, 50.0, 3.0]])       # no axial term: every other integrand is a polynomial
    e = straight(0.37)[None] + 0.05 * RNG.standard_normal((1, 18))
    per_point = np.repeat(stiffness[:, None, :], g, axis=1)
    assert element.elastic_energy(e, l, per_point) == pytest.approx(element.elastic_energy(e, l, stiffness),
                                                                     rel=1e-12)
