"""orchestrator.studies.stability against analytic cases: the generalized-alpha spectral radius, the added-mass limit
of explicit coupling of a free mass, the tip load's scale, the lattice's modal energies and lift slope, and the
torsional divergence pressure."""
import itertools
import math

import numpy as np
import pytest

from orchestrator.studies import stability
from orchestrator.scene.load import load_scene
from repository import SCENES

SCENE = SCENES / "stability_wing.toml"


@pytest.mark.parametrize("omega_h", [0.1, 1.0, 10.0, 100.0])
def test_generalized_alpha_with_rho_inf_1_neither_damps_nor_grows_an_undamped_mode(omega_h):
    """rho_inf = 1 is the trapezoidal rule: the amplification matrix of x'' = -omega^2 x has |z| = 1 at any step."""
    assert stability.coupled_mode_radius(0.0, 0, omega_h, substeps=1, rho_inf=1.0) == pytest.approx(1.0, abs=1e-12)


@pytest.mark.parametrize("rho_inf", [0.8, 0.5, 0.0])
def test_generalized_alpha_spectral_radius_tends_to_rho_inf_at_large_steps_and_to_1_at_small_ones(rho_inf):
    """Chung and Hulbert 1993: the spectral radius of an undamped mode is 1 for omega h -> 0 (second-order
    accurate, no dissipation of the resolved modes) and rho_inf for omega h -> infinity; in between it falls."""
    radius = [stability.coupled_mode_radius(0.0, 0, w, substeps=1, rho_inf=rho_inf)
              for w in (1e-3, 1e-1, 1.0, 1e2, 1e4, 1e6)]
    assert radius[0] == pytest.approx(1.0, abs=1e-9)
    assert all(a >= b for a, b in itertools.pairwise(radius)), radius
    assert abs(radius[-1] - rho_inf) < abs(radius[-2] - rho_inf) and abs(radius[-1] - rho_inf) < 1e-3


def test_free_mass_added_mass_limits_tend_to_those_of_the_plain_explicit_update():
    """With many structure steps per coupling step the held force is integrated exactly, v_(n+1) = v_n + h F_n,
    F_n = -mu (3 v_k - 4 v_(k-1) + v_(k-2)) / 2 (h = m = 1). Gauss-Seidel (k = n): besides the drift z = 1 the
    characteristic polynomial is z^2 + 3 mu z / 2 - mu / 2, with a root at z = -1 for mu = 1/2. Jacobi
    (k = n - 1): z^3 + 3 mu z / 2 - mu / 2, whose complex pair reaches |z| = 1 where mu^2 + 6 mu - 4 = 0,
    mu = sqrt(13) - 3. The blend of the old force fades like 1 / substeps."""
    for lag, limit in ((0, 0.5), (1, math.sqrt(13) - 3)):
        coarse, fine = (stability.critical_mass_ratio(lag, substeps=k) for k in (256, 1024))
        assert abs(fine - limit) < 1e-3 and abs(fine - limit) < abs(coarse - limit) / 3, (lag, coarse, fine)


def test_critical_mass_ratio_is_the_edge_of_the_spectral_radius():
    mu = stability.critical_mass_ratio(0, substeps=4)
    assert stability.coupled_mode_radius(0.99 * mu, 0, 0.0, 4) <= 1.0 + 1e-9
    assert stability.coupled_mode_radius(1.01 * mu, 0, 0.0, 4) > 1.0


def test_modal_growth_of_modes_without_added_mass_is_their_start():
    modes = {"omega": np.array([100.0, 2000.0]), "mu": np.zeros(2), "kinetic": np.array([0.3, 0.2])}
    assert stability.modal_growth(modes, 1.2, 0, 1e-3, 50) == (0.3, 0)


def test_tip_load_and_its_static_deflection():
    """P = 0.1 EI / L^2 with EI = E c t^3 / 12 of the plate; delta_s = P L^3 / (3 EI) = 0.1 L / 3."""
    scene = load_scene(SCENE)
    section = scene["structure"]["bodies"][0]["section"]
    EI = section["youngs_modulus"] * section["chord"] * section["thickness"] ** 3 / 12
    P, delta = stability.tip_load_scale(scene, "wing")
    assert P == pytest.approx(0.1 * EI / 0.15 ** 2, rel=1e-12)
    assert delta == pytest.approx(0.1 * 0.15 / 3, rel=1e-12)


@pytest.fixture(scope="module")
def lattice():
    scene = load_scene(SCENE, ["aero.model=uvlm-flat"])
    return scene, stability.lattice_added_mass(scene, "wing")


def test_modal_kinetic_energies_under_the_sudden_load_sum_to_half_the_static_work(lattice):
    """sum_i (phi_i . f)^2 / (2 omega_i^2) = f^T K^-1 f / 2 = P delta / 2 for a linear structure: the cubic
    elements reproduce the clamped beam's static tip deflection, so the sum is 1/2 in units of P delta_s."""
    _, (_, _, modes) = lattice
    assert modes["kinetic"].sum() == pytest.approx(0.5, abs=1e-6)


def test_lattice_added_mass_is_below_the_two_dimensional_value(lattice):
    """Tip relief: the finite wing's added-mass ratio over all shapes stays below uvlm-flat's 2D flat plate,
    (3 + 1/M) rho pi c^2 / 4 per unit span over m_s = rho_s c t (per kg/m^3 of air)."""
    scene, (mu_max, mu_1, modes) = lattice
    section = scene["structure"]["bodies"][0]["section"]
    two_d = (3 + 1 / scene["aero"]["chordwise_panels"]) * math.pi * section["chord"] ** 2 / 4 / (
        section["density"] * section["chord"] * section["thickness"])
    assert 0 < mu_1 <= mu_max < two_d
    assert np.all(modes["mu"] <= mu_max * (1 + 1e-9))     # each mode's Rayleigh quotient is below the largest


def test_lift_slope_of_the_lattice_is_near_the_finite_wing_estimate(lattice):
    """Helmbold 1942: a = 2 pi A / (2 + sqrt(A^2 + 4)) for aspect ratio A = 3 (3.36 /rad), an elliptic-wing
    estimate; a rectangular lattice differs by a few percent."""
    scene, _ = lattice
    A = 0.15 / 0.05
    assert stability.lift_slope(scene) == pytest.approx(2 * math.pi * A / (2 + math.sqrt(A * A + 4)), rel=0.05)


def test_divergence_pressure_and_speed_by_hand():
    """GJ = 0.18 N m^2, L = 0.15 m, c = 0.05 m, e = c / 4, a = 2 pi: q_D = 0.18 (pi / 0.3)^2 / (0.05 x 0.0125 x
    2 pi) = 5026.5 Pa; at 1.2 kg/m^3 V = sqrt(2 q_D / rho) = 91.53 m/s."""
    q = stability.divergence_pressure(0.18, 0.15, 0.05, 0.0125, 2 * math.pi)
    assert q == pytest.approx(5026.5, rel=1e-4)
    assert stability.divergence_speed(q, 1.2) == pytest.approx(91.53, rel=1e-4)


def test_rk4_step_limit():
    assert stability.rk4_step_limit(1000.0) == pytest.approx(2 * math.sqrt(2) / 1000.0)


@pytest.mark.parametrize("limit", [0.9, 0.3, 0.01, 1e-3])
def test_largest_stable_step_brackets_a_known_limit_on_the_grid(limit):
    """Stable iff h <= limit: the search returns the largest grid step at or below it, and the next one up."""
    calls = []

    def run(h):
        calls.append(h)
        return {"stable": h <= limit}

    found = stability.largest_stable_step(run, 1.0, fine=4, octaves=10)
    h = lambda k: 2.0 ** (-k / 4)
    assert h(found["stable"]) <= limit < h(found["unstable"]) and found["unstable"] == found["stable"] - 1
    # one probe per octave down to the first stable one, then log2(fine) = 2 to bisect that octave
    assert len(calls) == len(found["rows"]) <= math.ceil(math.log2(1 / limit)) + 1 + 2


def test_largest_stable_step_at_the_ends_of_the_grid():
    assert stability.largest_stable_step(lambda h: {"stable": True}, 1.0, 4, 10)["stable"] == 0
    none = stability.largest_stable_step(lambda h: {"stable": False}, 1.0, 4, 10)
    assert none["stable"] is None and none["unstable"] == 40 and len(none["rows"]) == 11
