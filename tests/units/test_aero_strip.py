"""Quasi-steady strip theory (aero.model = "strip", aero_fmu/strip.py) against closed forms.

Per strip: relative flow V_rel = U - r' at 3/4 chord, force pi rho c |V_perp| (V_rel . n) per unit span
along the section normal n at 1/4 chord (1/2 rho V^2 c 2 pi alpha_eff for small alpha_eff), Q by Otsuka et al. 2019
Eq. (12). The wing is the prescribed flat body of tests/flat_wing.py (span y, chord x,
n = -z), the stream V along +x.
"""
import numpy as np
import pytest

from aero_fmu.solver import AeroSolver
from fmu_common.specs import AeroUnitSpec, StructureUnitSpec
from aero_fmu.vlm import SteadyVLM
from fmu_common.errors import SceneError
from fmu_common.scene_schema import resolve_scene
from structure_fmu.solver import StructureSolver

SECTION = {"chord": 0.8, "thickness": 0.01, "density": 100.0, "youngs_modulus": 1e9, "torsional_rigidity": 1.0}
RHO, V = 1.2, 12.0


def scene(motion, span=3.0, N=6, speed=V, correction="none"):
    """A one-body wing; strip theory in 2D (span_correction "none") unless told."""
    body = {"name": "wing", "length": span, "span_axis": [0, 1, 0], "chord_axis": [1, 0, 0], "section": SECTION}
    return resolve_scene({"time": {"stop": 1.0},
                          "structure": {"fidelity": "prescribed", "bodies": [body], "motion": motion},
                          "aero": {"model": "strip", "chordwise_panels": 3, "spanwise_panels": N,
                                   "span_correction": correction},
                          "flow": {"speed": speed, "density": RHO}}, "strip")


def history(motion, times, **options):
    """(CL, lift, drag, aero) at the given times, the strip model fed by the prescribed structure."""
    resolved = scene(motion, **options)
    structure = StructureSolver(StructureUnitSpec.from_scene(resolved))
    aero = AeroSolver(AeroUnitSpec.from_scene(resolved))
    out = []
    for t in times:
        structure.advance(t)
        aero.advance(t, structure.e, structure.de)
        o = aero.outputs()
        out.append((o["CL"], o["lift"], o["drag"]))
    return np.array(out).T, aero


@pytest.mark.parametrize("alpha_deg", [-7.0, 2.0, 15.0])
def test_pitched_wing_in_steady_flow(alpha_deg):
    """A plate pitched by alpha: every strip has V_rel . n = V sin(alpha), |V_perp| = V, so the normal force
    is pi rho c V^2 sin(alpha) per unit span and C_L = 2 pi sin(alpha) cos(alpha), drag = normal force x
    sin(alpha) (no leading-edge suction), exactly; independent of the strip count and the aspect ratio.
    The forces act at the quarter chord: their moment about the quarter-chord line vanishes."""
    a = np.radians(alpha_deg)
    (CL, lift, drag), aero = history({"alpha_deg": alpha_deg, "pitch_axis_position": 0.25}, [0.1])
    assert CL[0] == pytest.approx(2 * np.pi * np.sin(a) * np.cos(a), rel=1e-12)
    normal_force = np.pi * RHO * 0.8 * V**2 * np.sin(a) * 3.0
    assert lift[0] == pytest.approx(normal_force * np.cos(a), rel=1e-12)
    assert drag[0] == pytest.approx(normal_force * np.sin(a), rel=1e-12)
    (CL_long, _, _), _ = history({"alpha_deg": alpha_deg, "pitch_axis_position": 0.25}, [0.1], span=300.0, N=2)
    assert CL_long[0] == pytest.approx(CL[0], rel=1e-12)
    points, forces = aero.panel_forces()
    quarter = np.array([-0.2, 0.0, 0.0])                  # the pitch axis: quarter chord, reference at mid-chord
    arm = points - quarter
    assert np.allclose(arm[:, [0, 2]], 0.0, atol=1e-12)   # the pitch leaves the quarter-chord line in place
    moment_about_span = np.cross(arm, forces)[:, 1].sum()
    assert abs(moment_about_span) < 1e-12 * np.abs(forces).sum()


def test_plunge_is_quasi_steady_without_lag():
    """h = h0 sin(omega t) along n: V_rel = V e_x - h' n, so C_L(t) = -2 pi (h'/V) sqrt(1 + (h'/V)^2) at
    every instant (no wake, no apparent mass: the response has no lag and no memory)."""
    h0, omega = 0.3, 9.0
    times = np.linspace(0.01, 1.0, 23)
    (CL, _, drag), _ = history({"heave_amplitude": h0, "frequency": omega}, times)
    rate = h0 * omega * np.cos(omega * times) / V
    np.testing.assert_allclose(CL, -2 * np.pi * rate * np.sqrt(1 + rate**2), rtol=1e-12, atol=1e-15)
    assert np.all(np.abs(drag) < 1e-12)                   # the force stays along n, which stays normal to U


@pytest.mark.parametrize("pivot", [0.0, 0.25, 0.5])
def test_pitch_rate_enters_through_the_three_quarter_chord_point(pivot):
    """Small pitch oscillation theta = A sin(omega t) about the chord fraction `pivot` (A = 0.3 deg, reduced
    frequency omega c / 2V = 0.3): quasi-steady thin-airfoil theory gives
    C_L = 2 pi [theta + (3/4 - pivot) c theta' / V] (Theodorsen's circulatory part with C = 1), to
    O(theta^2) ~ 1e-4 relative."""
    A, omega = np.radians(0.3), 0.3 * 2 * V / 0.8
    times = np.linspace(0.02, 0.4, 17)
    (CL, _, _), _ = history({"pitch_amplitude_deg": 0.3, "frequency": omega, "pitch_axis_position": pivot}, times)
    theta, rate = A * np.sin(omega * times), A * omega * np.cos(omega * times)
    expected = 2 * np.pi * (theta + (0.75 - pivot) * 0.8 * rate / V)
    np.testing.assert_allclose(CL, expected, rtol=0, atol=2e-3 * np.abs(expected).max())


def test_agrees_with_the_vortex_lattice_on_a_very_slender_wing():
    """Independent cross-check: on an AR-1000 wing at 3 deg, strip theory and the steady VLM (M = 4,
    N = 100, flat horseshoes) give the same C_L within 1% (the VLM's finite-span loss is ~0.3%)."""
    alpha = 3.0
    (CL, _, _), _ = history({"alpha_deg": alpha, "pitch_axis_position": 0.25}, [0.1], span=800.0, N=20)
    resolved = scene({"alpha_deg": alpha, "pitch_axis_position": 0.25}, span=800.0)
    structure = StructureSolver(StructureUnitSpec.from_scene(resolved))
    vlm = SteadyVLM(structure.topology, 4, 100).solve(structure.e, np.array([V, 0, 0]), RHO)
    assert CL[0] == pytest.approx(vlm.CL, rel=0.01)


def test_still_air():
    """Zero flow speed: a wing at rest has no force and C_L = 0; a wing heaving in still air feels a normal
    force pi rho c h'^2 L opposing its motion (alpha_eff = 90 deg), never NaN (no division anywhere)."""
    with np.errstate(all="raise"):
        (CL, lift, _), aero = history({"alpha_deg": 4.0}, [0.1, 0.2], speed=0.0)
        assert np.all(CL == 0.0) and np.all(lift == 0.0) and np.all(aero.Q == 0.0)
        h0, omega, t = 0.2, 5.0, 0.13
        (CL, lift, _), aero = history({"heave_amplitude": h0, "frequency": omega}, [t], speed=0.0)
    rate = h0 * omega * np.cos(omega * t)                 # along n, the lift axis in still air
    assert CL[0] == 0.0
    assert lift[0] == pytest.approx(-np.pi * RHO * 0.8 * rate * abs(rate) * 3.0, rel=1e-12)


@pytest.mark.parametrize("aspect", [4.0, 8.0])
def test_helmbold_span_correction(aspect):
    """aero.span_correction = "helmbold" (the default) scales the 2D lift slope by Helmbold's
    A / (2 + sqrt(A^2 + 4)) (0.617 at A = 4, 0.781 at A = 8, by hand); the 3D strip C_L then lies within 8%
    above the steady vortex lattice's for the same rectangular wing (the VLM's lift slopes 3.61 and 4.58,
    docs/aero.md), where the 2D strip theory is 60% and 35% above."""
    alpha, chord = 3.0, SECTION["chord"]
    motion = {"alpha_deg": alpha, "pitch_axis_position": 0.25}
    (CL, _, _), aero = history(motion, [0.1], span=aspect * chord, N=20, correction="helmbold")
    factor = {4.0: 4 / (2 + np.sqrt(20)), 8.0: 8 / (2 + np.sqrt(68))}[aspect]
    a = np.radians(alpha)
    assert CL[0] == pytest.approx(2 * np.pi * factor * np.sin(a) * np.cos(a), rel=1e-9)
    structure = StructureSolver(StructureUnitSpec.from_scene(scene(motion, span=aspect * chord)))
    vlm = SteadyVLM(structure.topology, 4, 32).solve(structure.e, np.array([V, 0, 0]), RHO)
    assert 1.0 < CL[0] / vlm.CL < 1.08


def test_unknown_span_correction_is_refused():
    with pytest.raises(SceneError) as err:
        scene({"alpha_deg": 2.0}, correction="prandtl")        # refused when the scene is resolved
    assert err.value.key == "aero.span_correction" and "'helmbold', 'none'" in str(err.value)
