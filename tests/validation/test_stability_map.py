"""Pinned points of the stability map (docs/studies/stability.md, benchmarks/stability.py), each computed here with its
own runs of scenes/stability_wing.toml (the clamped PVC wing body under a sudden tip load P, linear static tip
deflection delta_s = P L^3 / (3 EI)):

- RK4 is stable just below its analytic limit 2 sqrt(2) / omega_max and reported "diverged" just above it, at
  both ends of the stiffness range (E = 1e6 and 1e12 Pa);
- generalized-alpha is stable a hundred times beyond that limit, and its Newton failure far beyond is reported
  "diverged";
- in air 30 times denser than normal Gauss-Seidel coupling is reported "diverged" (added-mass instability),
  while implicit coupling stays bounded.

Stable, as in the doc: status "ok", kinetic energy <= P delta_s, tip displacement <= 4 delta_s (twice what an
undamped linear structure can reach under the sudden load: P delta_s / 2 and 2 delta_s)."""
import math
import re

import numpy as np
import pytest

from orchestrator.studies import stability
from orchestrator.run.master import run_scene
from orchestrator.scene.load import load_scene
from repository import SCENES

SCENE = SCENES / "stability_wing.toml"
AIR = 1.2      # kg/m^3


def stiffness(E):
    """Overrides giving the wing Young's modulus E (Pa), GJ scaled with it (fixed Poisson ratio)."""
    return stability.stiffness_overrides(load_scene(SCENE), "wing", E)


def frequencies(overrides):
    """(omega_1, omega_max) rad/s of the wing linearized at rest."""
    return stability.frequency_range(load_scene(SCENE, overrides))


def run(overrides):
    """(result, bounded): the run, and whether KE <= P delta_s and |tip displacement| <= 4 delta_s throughout."""
    scene = load_scene(SCENE, overrides)
    result = run_scene(scene, backend="direct")
    P, delta = stability.tip_load_scale(scene, "wing")
    return result, stability.sudden_load_response(result.series, "tip", P, delta)["bounded"]


@pytest.mark.parametrize("E", [1e6, 1e12])
def test_rk4_is_stable_below_its_analytic_limit_and_reported_diverged_above(E):
    _, omega_max = frequencies(stiffness(E))
    limit = 2 * math.sqrt(2) / omega_max          # RK4 on the imaginary axis: |R(i y)| <= 1 for y <= 2 sqrt(2)
    common = [*stiffness(E), "structure.integrator=rk4", f"time.stop={300 * limit!r}", f"coupling.step={30 * limit!r}"]
    below, bounded = run(common + [f"structure.step={0.95 * limit!r}"])
    assert below.status == "ok" and bounded, below.message
    above, _ = run(common + [f"structure.step={1.1 * limit!r}"])
    assert above.status == "diverged", above.message
    assert above.simulated_time_s < 300 * limit and "structure.step" in above.message   # the hint


def test_generalized_alpha_is_stable_far_beyond_the_explicit_limit_and_reports_its_newton_failure():
    omega_1, omega_max = frequencies([])
    period, limit = 2 * math.pi / omega_1, 2 * math.sqrt(2) / omega_max
    step = 100 * limit
    result, bounded = run(["structure.rho_inf=0.8", f"structure.step={step!r}", f"coupling.step={step!r}",
                           f"time.stop={period!r}"])
    assert result.status == "ok" and bounded, result.message
    assert result.series.time[-1] == pytest.approx(period)
    # an eighth of the first period per step: the Newton iteration fails, and says so (after the start-up's
    # shorter steps, structure_fmu.integrators.start_up: six steps here, so the run lasts three periods)
    far, _ = run(["structure.rho_inf=0.8", f"structure.step={period / 8!r}", f"coupling.step={period / 8!r}",
                  f"time.stop={3 * period!r}"])
    assert far.status == "diverged" and "Newton" in far.message, far.message


def test_gauss_seidel_is_reported_diverged_in_dense_air_where_implicit_coupling_stays_bounded():
    factor = 30.0
    section = load_scene(SCENE)["structure"]["bodies"][0]["section"]
    m_s = section["density"] * section["chord"] * section["thickness"]            # kg/m
    m_a = (3 + 1 / 2) * AIR * factor * math.pi * section["chord"] ** 2 / 4         # uvlm-flat's, M = 2, kg/m
    assert m_a / m_s > 1.0   # beyond the added-mass limit of explicit coupling (0.5 to 1.4, docs/studies/stability.md)
    common = ["aero.model=uvlm-flat", "flow.speed=0", f"flow.density={AIR * factor!r}", "coupling.step=1e-3",
              "structure.step=2.5e-4", "time.stop=0.05"]
    explicit, _ = run(common + ["coupling.algorithm=gauss-seidel"])
    assert explicit.status == "diverged" and explicit.simulated_time_s < 0.05, explicit.message
    # the message points at the exchange: the lift's swing grew between the two windows before the failure
    swings = re.search(r"lift swung over (\S+) N in the last (\d+) communication steps "
                       r"against (\S+) N in the \2 before", explicit.message)
    assert swings and float(swings.group(1)) > float(swings.group(3)), explicit.message
    assert 'try coupling.algorithm = "implicit"' in explicit.message
    implicit, bounded = run(common + ["coupling.algorithm=implicit"])
    assert implicit.status == "ok" and bounded, implicit.message
    assert np.all(implicit.series.column("coupling_residual")[1:] < 1e-6)


def test_a_run_that_fails_in_its_first_step_gets_no_coupling_hint():
    """The flexible aluminium wing under RK4 at 1 ms (far beyond its explicit limit) blows up in the first
    step, under the aero force of its initial state alone: no exchange happened, so the message names the
    structure's own remedy and not the coupling's."""
    scene = load_scene(SCENES / "deploy_rigid.toml", ["structure.fidelity=flexible", "time.stop=0.01"])
    result = run_scene(scene, backend="direct")
    assert result.status == "diverged" and result.simulated_time_s == 0.0, result.message
    assert "structure.integrator" in result.message and "coupling" not in result.message


def test_every_stiffness_of_a_varying_section_scales_with_youngs_modulus():
    """GJ and its tip value scale by E / E_scene, so the wing's frequencies scale by sqrt(E / E_scene) (a material of
    fixed Poisson ratio and density: every stiffness times the factor, the mass unchanged)."""
    tapered = ["structure.bodies.wing.section.torsional_rigidity_tip=0.05"]
    scene = load_scene(SCENE, tapered)
    E = scene["structure"]["bodies"][0]["section"]["youngs_modulus"]
    scaled = stability.stiffness_overrides(scene, "wing", 4.0 * E)
    section = load_scene(SCENE, tapered + scaled)["structure"]["bodies"][0]["section"]
    assert section["torsional_rigidity_tip"] == pytest.approx(4.0 * 0.05, rel=1e-15)
    assert section["torsional_rigidity"] == pytest.approx(4.0 * scene["structure"]["bodies"][0]["section"]
                                                          ["torsional_rigidity"], rel=1e-15)
    (low, high), (low4, high4) = stability.frequency_range(scene), stability.frequency_range(load_scene(
        SCENE, tapered + scaled))
    assert low4 / low == pytest.approx(2.0, rel=1e-9) and high4 / high == pytest.approx(2.0, rel=1e-9)
