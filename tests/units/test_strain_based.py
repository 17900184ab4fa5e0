"""The strain-based fidelity (Otsuka et al. 2022, Secs. 2-3): its kinematics against closed forms and finite
differences, its stiffness against beam theory, its joints' constraints and its energy balance."""
import numpy as np
import pytest

from fmu_common.errors import SceneError, SolverDiverged
from fmu_common.specs import StrainGaugeSpec, StructureUnitSpec
from fmu_common.wing_spec import StructureSpec
from orchestrator.scene.load import load_scene
from repository import SCENES
from structure_fmu import strain_kinematics as sk
from structure_fmu.modes import natural_frequencies
from structure_fmu.sensors import Sensors
from structure_fmu.solver import StructureSolver
from structure_fmu.strain_model import StrainBasedModel
from structure_fmu.topology import StructureTopology

PENDULUM = SCENES / "double_pendulum.toml"
REVOLUTE = ["structure.joints.PQ.type=revolute", "structure.joints.PQ.axis=[1,0,0]"]
UNIVERSAL = ["structure.joints.PQ.type=universal"]


def model_of(path, *overrides):
    scene = load_scene(path, list(overrides))
    return StrainBasedModel(StructureTopology.from_spec(StructureSpec.from_scene(scene)), scene["structure"]["gravity"])


def test_an_element_of_constant_curvature_is_an_arc():
    """With kappa_y alone the reference line is a circular arc of radius 1/kappa_y, stretched by 1 + eps_x:
    r = (1 + eps) (sin(k s) / k, 0, -(1 - cos(k s)) / k) from r_x = X, r_z = Z (Eq. 6: r_x' = -kappa_y r_z)."""
    eps, kappa, length = 0.01, 0.7, 1.3
    Phi, _ = sk.transfer(np.array([[eps, 0.0, kappa, 0.0]]), np.array([length]))
    H = Phi[0] @ np.vstack([np.zeros(3), np.eye(3)])
    ks = kappa * length
    assert H[0] == pytest.approx((1 + eps) * np.array([np.sin(ks), 0.0, -(1 - np.cos(ks))]) / kappa, abs=1e-14)
    assert H[1] == pytest.approx([np.cos(ks), 0.0, -np.sin(ks)], abs=1e-14)
    assert H[2] == pytest.approx([0.0, 1.0, 0.0], abs=1e-14)


def test_transfer_derivatives_match_finite_differences():
    rng = np.random.default_rng(0)
    strains, rates, lengths = 0.3 * rng.standard_normal((3, 4)), rng.standard_normal((3, 4)), np.array([0.5, 1, 2])
    Phi, dPhi = sk.transfer(strains, lengths)
    h = 1e-6
    for p in range(4):
        step = np.zeros(4)
        step[p] = h
        fd = (sk.transfer(strains + step, lengths)[0] - sk.transfer(strains - step, lengths)[0]) / (2 * h)
        assert np.abs(fd - dPhi[:, p]).max() < 1e-8
    h = 1e-4
    second = (sk.transfer(strains + h * rates, lengths)[0] - 2 * Phi + sk.transfer(strains - h * rates, lengths)[0])
    assert np.abs(second / h**2 - sk.transfer_second(strains, rates, lengths)).max() < 1e-6


@pytest.mark.parametrize("scale", [0.0, 1e-12, 1e-7, 1e-3, 0.1, 1.0, 3.0])
def test_the_closed_form_transfer_is_the_block_exponential(scale):
    """The Rodrigues-type closed form of Phi, dPhi/dxi and d2Phi/dt2 against scipy's expm of the block matrices,
    to 1e-13 relative, from zero strain (and zero curvature with stretch) to rotations beyond pi (the expm route)."""
    rng = np.random.default_rng(7)
    strains, rates = scale * rng.standard_normal((40, 4)), rng.standard_normal((40, 4))
    lengths = rng.uniform(0.01, 1.5, 40)
    strains[:4, 1:] = 0.0
    strains[4, 1:] = [sk.THETA_MAX * (1 - 1e-12) / lengths[4], 0.0, 0.0]      # just below the switch
    strains[5, 1:] = [0.0, sk.THETA_MAX * (1 + 1e-12) / lengths[5], 0.0]      # just above it
    Phi, dPhi = sk.transfer(strains, lengths)
    Phi_ref, dPhi_ref = sk.transfer_expm(strains, lengths)
    second, second_ref = sk.transfer_second(strains, rates, lengths), sk.transfer_second_expm(strains, rates, lengths)
    for value, reference in ((Phi, Phi_ref), (dPhi, dPhi_ref), (second, second_ref)):
        assert np.abs(value - reference).max() <= 1e-13 * max(1.0, np.abs(reference).max())
    if scale < 1:
        assert not sk._large(strains[6:], lengths[6:]).any()      # the closed form did the work


def test_the_rotation_series_are_rodrigues_coefficients():
    theta = np.array([0.3, 0.5, 2.0, np.pi])      # where the closed forms lose few digits
    f = sk.rotation_series(theta**2)
    assert f[:, 0, 0] == pytest.approx(np.sin(theta) / theta, rel=1e-14)
    assert f[:, 1, 0] == pytest.approx((1 - np.cos(theta)) / theta**2, rel=1e-12)
    assert f[:, 2, 0] == pytest.approx((theta - np.sin(theta)) / theta**3, rel=1e-9)
    h = 1e-5                                                  # derivatives in s by central differences
    for j in (1, 2):
        fd = (sk.rotation_series(theta**2 + h)[:, :, j - 1] - sk.rotation_series(theta**2 - h)[:, :, j - 1]) / (2 * h)
        assert np.abs(fd - f[:, :, j]).max() < 1e-9


def test_the_revolute_joint_matrix_is_eq_15_for_the_chord_axis():
    theta = 0.4
    c, dc, _, _ = sk.joint_terms("revolute", np.array([theta]), np.zeros(1), np.array([0.0, 1.0, 0.0]),
                                 np.eye(3))
    co, si = np.cos(theta), np.sin(theta)
    assert c == pytest.approx(np.array([[co, 0, -si], [0, 1, 0], [si, 0, co]]), abs=1e-15)
    assert dc[0] == pytest.approx(np.array([[-si, 0, -co], [0, 0, 0], [co, 0, -si]]), abs=1e-15)


def test_euler_parameters_round_trip_and_their_gradient():
    rng = np.random.default_rng(1)
    for _ in range(5):
        z = rng.standard_normal(4)
        z /= np.linalg.norm(z)
        z = z if z[0] >= 0 else -z
        assert sk.quaternion_of(sk.quaternion_matrix(z)) == pytest.approx(z, abs=1e-12)
        h = 1e-6
        fd = np.array([sk.quaternion_matrix(z + h * e) - sk.quaternion_matrix(z - h * e) for e in np.eye(4)]) / (2 * h)
        assert np.abs(fd - sk.quaternion_gradient(z)).max() < 1e-9


@pytest.mark.parametrize("overrides", [[], UNIVERSAL, REVOLUTE], ids=["ball", "universal", "revolute"])
def test_velocity_map_and_convective_term_match_finite_differences(overrides):
    """B = dE/dq and dB/dt q' (the q''-free part of d2E/dt2) of the double pendulum at a random state."""
    model = model_of(PENDULUM, *overrides)
    rng = np.random.default_rng(2)
    q = model.initial_coordinates() + 0.05 * rng.standard_normal(model.n_q)
    dq = rng.standard_normal(model.n_q)
    E = lambda x: model.coordinates(x, dq, 0.0)[0]
    h = 1e-6
    fd = np.array([(E(q + h * e) - E(q - h * e)) / (2 * h) for e in np.eye(model.n_q)]).T
    B = model.velocity_map(q, 0.0)
    assert np.abs(fd - B).max() < 1e-8 * np.abs(B).max()
    _, dE, a = model._motion(q, dq, 0.0)
    assert dE == pytest.approx(B @ dq, abs=1e-14)
    h = 1e-4
    second = (E(q + h * dq) - 2 * E(q) + E(q - h * dq)) / h**2
    assert np.abs(second - a).max() < 1e-5 * np.abs(a).max()


@pytest.mark.parametrize("path, overrides", [(PENDULUM, []), (PENDULUM, UNIVERSAL), (PENDULUM, REVOLUTE),
                                             (SCENES / "spin_up.toml", ["structure.fidelity=strain-based"])],
                         ids=["ball", "universal", "revolute", "driven"])
def test_the_rates_sweep_without_b_matches_the_configuration(path, overrides):
    """coordinates() at a state whose B was never computed (one sweep of H and dH/dt) gives the E and dE/dt of
    the full recursion (_motion: B q' + dH/dt)."""
    model = model_of(path, *overrides)
    rng = np.random.default_rng(4)
    q = model.initial_coordinates() + 0.05 * rng.standard_normal(model.n_q)
    dq = rng.standard_normal(model.n_q)
    t = 0.013
    E, dE, _ = model.coordinates(q, dq, t)
    E_full, dE_full, _ = model._motion(q, dq, t)
    assert np.abs(E - E_full).max() < 1e-14 * np.abs(E_full).max()
    assert np.abs(dE - dE_full).max() < 1e-13 * np.abs(dE_full).max()


def test_the_c_kinematics_equal_the_numpy_reference(monkeypatch):
    """strain_kernels.c against the numpy forms of strain_kinematics.transfers and kinematics: two bodies of
    5 and 3 elements with random strains and rates, the first hanging from a moving ground point by one joint
    parameter, the second from the first's tip by four (random c, dc/deta, c', c''); every array equal to 1e-12 of
    its largest entry, and no node depending on a later strain."""
    rng = np.random.default_rng(12)
    n_el = (5, 3)
    n_q = 1 + 4 * n_el[0] + 4 + 4 * n_el[1]
    columns = (1 + 4 * np.arange(n_el[0]), 1 + 4 * n_el[0] + 4 + 4 * np.arange(n_el[1]))
    strains = 0.4 * rng.standard_normal((sum(n_el), 4))
    rates = rng.standard_normal((sum(n_el), 4))
    lengths = rng.uniform(0.05, 0.5, sum(n_el))
    dq = rng.standard_normal(n_q)
    roots = (sk.RootTerms(rng.standard_normal((3, 3)), rng.standard_normal((1, 3, 3)),
                          *rng.standard_normal((2, 3, 3)), 0, rng.standard_normal((3, 4, 3))),
             sk.RootTerms(rng.standard_normal((3, 3)), rng.standard_normal((4, 3, 3)), *rng.standard_normal((2, 3, 3)),
                          1 + 4 * n_el[0], np.zeros((3, 4, 3))))
    out = {}
    for kind in ("numpy", "compiled"):
        monkeypatch.setenv("WINGSIM_KERNELS", kind)
        transfers = sk.transfers(strains, rates, lengths)
        bodies = (sk.BodyLine(0, 0, -1, columns[0]), sk.BodyLine(n_el[0] + 1, n_el[0], n_el[0], columns[1]))
        out[kind] = transfers + sk.kinematics(bodies, roots, transfers, dq, sum(n_el) + 2)
    for compiled, reference in zip(out["compiled"], out["numpy"]):
        assert np.abs(compiled - reference).max() <= 1e-12 * np.abs(reference).max()
    dH = out["numpy"][5]
    assert not dH[:n_el[0] + 1, ..., 1 + 4 * n_el[0]:].any()     # the first body depends on none of the second's
    assert not dH[n_el[0] + 1, ..., 1 + 4 * n_el[0] + 4:].any()  # the second's root on none of its strains


def test_linear_stiffness_gives_the_piecewise_constant_curvature_cantilever():
    """K q = B^T Q at rest: each element takes the curvature at its midpoint (the energy minimum of constant
    curvatures under M(x) = F (L - x)), so a tip force F deflects the tip by F/EI sum_i l (L - x_i)^2 with x_i the
    element midpoints (the midpoint rule of F L^3 / (3 EI))."""
    n, force = 5, 10.0
    model = model_of(SCENES / "cantilever_static.toml", "structure.fidelity=strain-based",
                     f"structure.elements_per_body={n}")
    q0 = model.initial_coordinates()
    Q = np.zeros(model.top.n_coordinates)
    Q[9 * model.top.n_nodes - 9 + 2] = force              # tip node, r_z
    q = np.linalg.solve(np.diag(model.stiffness_diagonal), model.velocity_map(q0, 0.0).T @ Q)
    deflection = (model.velocity_map(q0, 0.0) @ q)[9 * model.top.n_nodes - 9 + 2]
    L, EI = 2.0, 1e5
    l = L / n
    midpoints = l * (np.arange(n) + 0.5)
    assert deflection == pytest.approx(force / EI * np.sum(l * (L - midpoints) ** 2), rel=1e-12)


@pytest.mark.parametrize("n", [5, 40])
def test_strain_gauges_read_the_elements_own_curvature(n):
    """Under a tip force F the elements take the curvature of their midpoints, F (L - x_i) / EI (see the test
    above), and a gauge reading the model's curvature reads d times its element's: exactly the midpoint value.
    The cubic reading of the same state has the same sign (both positive toward the section normal), and both are
    within d F (l / 2) / EI of Euler-Bernoulli's d F (L - s) / EI at the gauge's own span s (l the element length:
    the distance from the span to its element's midpoint)."""
    force, L, EI, d = 10.0, 2.0, 1e5, 0.01
    model = model_of(SCENES / "cantilever_static.toml", "structure.fidelity=strain-based",
                     f"structure.elements_per_body={n}")
    q0 = model.initial_coordinates()
    Q = np.zeros(model.top.n_coordinates)
    Q[9 * model.top.n_nodes - 9 + 2] = force              # tip node, r_z
    q = q0 + np.linalg.solve(np.diag(model.stiffness_diagonal), model.velocity_map(q0, 0.0).T @ Q)
    spans = (0.11, 1.31)
    gauges = [StrainGaugeSpec(f"g{k}", f"g{k}", "beam", s, d, curvature) for k, s in enumerate(spans)
              for curvature in ("model", "cubic")]
    sensors = Sensors((), tuple(gauges), model.top)
    E = model.coordinates(q, np.zeros_like(q), 0.0)[0]
    strains = sensors.strains(E, model.element_curvatures(q)).reshape(len(spans), 2)
    l = L / n
    midpoints = l * (np.floor(np.array(spans) / l) + 0.5)
    assert strains[:, 0] == pytest.approx(d * force * (L - midpoints) / EI, rel=1e-9)
    assert np.all(strains[:, 1] > 0)
    # both within the discretization's bound d F (l / 2) / EI of Euler-Bernoulli at the gauge's own span
    beam_theory = d * force * (L - np.array(spans)) / EI
    assert np.all(np.abs(strains - beam_theory[:, None]) <= d * force * (l / 2) / EI)


@pytest.mark.parametrize("overrides", [[], UNIVERSAL, REVOLUTE], ids=["ball", "universal", "revolute"])
def test_double_pendulum_conserves_energy_and_keeps_its_joints(overrides):
    """The first 0.05 s of Otsuka et al. 2022, Secs. 4.1-4.3 (RK4, 1e-4 s): energy conserved to 1e-6 of the
    kinetic energy reached; the shared point exact; the joint parameters' constraints held by projection."""
    solver = StructureSolver(StructureUnitSpec.from_scene(load_scene(PENDULUM, ["time.stop=0.05", *overrides])))
    start = solver.monitors()["energy"]
    solver.advance(0.05)
    monitors = solver.monitors()
    assert abs(monitors["energy"] - start) < 1e-6 * monitors["kinetic_energy"]
    assert monitors["constraint_residual"] < 1e-12
    X = solver.e.reshape(-1, 3, 3)
    assert np.abs(X[2, 0] - X[3, 0]).max() < 1e-12          # A's tip and B's root: one point


@pytest.mark.parametrize("path", sorted(SCENES.glob("*.toml")), ids=lambda p: p.stem)
def test_every_shipped_scene_takes_the_strain_based_fidelity(path):
    """Every joint of the shipped scenes is supported: each runs a communication step strain-based with its
    energy and constraints in order (a scissor chain's scene refuses the fidelity, naming it). A rigid scene's
    RK4 step may exceed the flexible bar's stability limit: the run then stops as diverged, saying when and what
    to change, and runs with generalized-alpha. A prescribed-motion scene refuses any other fidelity, naming its
    motion key."""
    raw = load_scene(path)
    if raw["structure"]["fidelity"] == "prescribed":
        with pytest.raises(SceneError, match="prescribed"):
            StructureSolver(StructureUnitSpec.from_scene(load_scene(path, ["structure.fidelity=strain-based"])))
        return
    if raw["structure"]["scissors"]:          # pins at mid-length and closed loops: rigid or flexible only
        with pytest.raises(SceneError) as refused:
            load_scene(path, ["structure.fidelity=strain-based"])
        assert refused.value.key == "structure.fidelity"
        return
    step = raw["coupling"]["step"]
    solver = StructureSolver(StructureUnitSpec.from_scene(load_scene(path, ["structure.fidelity=strain-based"])))
    try:
        solver.advance(step)
    except SolverDiverged as diverged:
        assert raw["structure"]["integrator"] == "rk4" and "generalized-alpha" in str(diverged)
        solver = StructureSolver(StructureUnitSpec.from_scene(load_scene(path, ["structure.fidelity=strain-based",
                                                   "structure.integrator=generalized-alpha"])))
        solver.advance(step)
    monitors = solver.monitors()
    assert np.isfinite(monitors["energy"]) and monitors["constraint_residual"] < 1e-10


def test_a_body_without_a_root_joint_is_refused_naming_it():
    scene = load_scene(PENDULUM)
    scene["structure"]["joints"] = scene["structure"]["joints"][1:]          # body A loses its ball joint
    with pytest.raises(SceneError, match=r"structure\.bodies\.A.*strain-based fidelity supports"):
        StructureSolver(StructureUnitSpec.from_scene(scene))


def test_a_driven_root_moves_the_body_with_its_law():
    """spin_up (Otsuka et al. 2019, Eq. 27) strain-based, mid-ramp: along q(tau) = q + tau q', t + tau, the rates
    and accelerations the model gives (B q' + dE/dt, and dB/dt q' plus the root's acceleration) are the finite
    differences of E."""
    model = model_of(SCENES / "spin_up.toml", "structure.fidelity=strain-based")
    rng = np.random.default_rng(3)
    q = model.initial_coordinates() + 0.01 * rng.standard_normal(model.n_q)
    dq = rng.standard_normal(model.n_q)
    t = 0.6 * model.roots["beam"].motion.ramp_time
    E = lambda tau: model.coordinates(q + tau * dq, dq, t + tau)[0]
    _, dE, a = model._motion(q, dq, t)
    h = 1e-5
    assert np.abs((E(h) - E(-h)) / (2 * h) - dE).max() < 1e-7 * np.abs(dE).max()
    h = 1e-4
    assert np.abs((E(h) - 2 * E(0.0) + E(-h)) / h**2 - a).max() < 1e-5 * np.abs(a).max()


def test_first_bending_frequency_converges_to_euler_bernoulli():
    """The cantilever of cantilever_static (EI 1e5 N m^2, rho A 10 kg/m, L 2 m) linearized at rest
    (structure_fmu.modes): omega_1 -> 1.87510^2 sqrt(EI / (rho A L^4)) = 87.900 rad/s, the error falling four
    times per doubling of the elements (constant curvature per element) and below 1e-3 at 16."""
    exact = 1.8751040687 ** 2 * np.sqrt(1e5 / (10.0 * 2.0 ** 4))
    errors = []
    for n in (4, 8, 16):
        solver = StructureSolver(StructureUnitSpec.from_scene(load_scene(SCENES / "cantilever_static.toml", [
            "structure.fidelity=strain-based", f"structure.elements_per_body={n}"])))
        errors.append(natural_frequencies(solver, 1)[0] / exact - 1)
    assert all(3.5 < a / b < 4.5 for a, b in zip(errors, errors[1:]))
    assert 0 < errors[-1] < 1e-3
