"""Prescribed motions: a heaving and pitching rigid wing (for the aero unit) and the spin-up law."""
import numpy as np
import pytest

from fmu_common.errors import SceneError
from fmu_common.specs import StructureUnitSpec
from fmu_common.scene_schema import resolve_scene
from structure_fmu.motion import SpinUp
from structure_fmu.solver import StructureSolver

OMEGA = 2.5


def heaving_scene(**motion):
    return resolve_scene({"time": {"stop": 1.0}, "structure": {
        "fidelity": "prescribed", "motion": motion,
        "bodies": [{"name": "wing", "length": 4.0, "span_axis": [0, 1, 0], "chord_axis": [1, 0, 0],
                    "section": {"chord": 1.0, "thickness": 0.01, "density": 100.0,
                                "youngs_modulus": 1e9, "torsional_rigidity": 1.0}}]}}, "heaving")


def test_heave_law_moves_every_point_rigidly():
    """Z = A sin(omega t) along the section normal (Otsuka et al. 2019, Sec. VI.D), velocities consistent with
    positions."""
    solver = StructureSolver(StructureUnitSpec.from_scene(heaving_scene(heave_amplitude=0.1, frequency=OMEGA)))
    assert solver.state.q.size == 0          # no structural solver: a scene models only what it needs
    e0 = solver.e.copy()
    normal = np.cross([0, 1, 0], [1, 0, 0])
    for t in (0.1, 0.37, 1.0):
        solver.advance(t)
        shift = 0.1 * np.sin(OMEGA * t) * normal
        expected = e0.reshape(-1, 3, 3).copy()
        expected[:, 0] += shift
        np.testing.assert_allclose(solver.e, expected.ravel(), atol=1e-14)
        rate = np.zeros_like(expected)
        rate[:, 0] = 0.1 * OMEGA * np.cos(OMEGA * t) * normal
        np.testing.assert_allclose(solver.de, rate.ravel(), atol=1e-14)


def test_pitch_law_rotates_about_the_pitch_axis():
    scene = heaving_scene(pitch_amplitude_deg=5.0, frequency=OMEGA, pitch_axis_position=0.25)
    solver = StructureSolver(StructureUnitSpec.from_scene(scene))
    top = solver.topology
    solver.advance(0.6)
    pitch = np.radians(5.0) * np.sin(OMEGA * 0.6)
    # the quarter-chord line stays put; the trailing edge moves by 0.75 c along the rotated chord
    quarter = top.point_position(solver.e, "wing", 2.0, 0.25)
    trailing = top.point_position(solver.e, "wing", 2.0, 1.0)
    np.testing.assert_allclose(quarter, [-0.25, 2.0, 0.0], atol=1e-14)   # reference line at mid-chord
    # nose up: the leading edge moves toward the section normal n = span x chord, the trailing edge away
    chord, normal = np.array([1.0, 0, 0]), np.cross([0, 1, 0], [1, 0, 0])
    np.testing.assert_allclose(trailing - quarter, 0.75 * (np.cos(pitch) * chord - np.sin(pitch) * normal), atol=1e-14)


def test_prescribed_fidelity_needs_a_motion():
    scene = heaving_scene()
    del scene["structure"]["motion"]
    with pytest.raises(SceneError, match="structure.motion"):
        StructureSolver(StructureUnitSpec.from_scene(scene))


def test_spin_up_law_is_000_eq27_and_continuous():
    law = SpinUp([0, 1, 0], [0, 0, 0], omega=4.0, ramp_time=15.0)
    Ts, ws = 15.0, 4.0
    for t in (0.0, 3.0, 7.5, 14.999999, 15.0, 20.0):
        theta, rate, accel = law.angle(t)
        if t < Ts:
            expected = ws / Ts * (t**2 / 2 + (Ts / (2 * np.pi)) ** 2 * (np.cos(2 * np.pi * t / Ts) - 1))
        else:
            expected = ws * (t - Ts / 2)
        assert theta == pytest.approx(expected, abs=1e-9)
        h = 1e-6
        assert rate == pytest.approx((law.angle(t + h)[0] - law.angle(t - h)[0]) / (2 * h), rel=1e-6, abs=1e-6)
