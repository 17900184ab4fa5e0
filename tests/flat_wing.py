"""The flat wing of the aero unit tests, and Theodorsen's theory of its heave (not a test module).

The wing is a prescribed-fidelity structure (tests/units/test_prescribed.py): one flat rectangular body, span
along y, chord along x (n = r_x x r_y = -z), heaving along n or held at a nose-up angle alpha, in a free
stream V along +x. For h = h0 sin(omega t) along the lift direction, k = omega c / (2V), the complex amplitude
of C_L is (h0/c) [2 pi k^2 - 4 pi i k C(k)] (apparent mass + circulatory, Bisplinghoff-Ashley-Halfman), with
Theodorsen's C(k) = H1(k) / (H1(k) + i H0(k)) from the Hankel functions of the second kind.
"""
import numpy as np
from scipy.special import hankel2

from fmu_common.scene_schema import resolve_scene

SECTION = {"chord": 1.0, "thickness": 0.01, "density": 100.0, "youngs_modulus": 1e9, "torsional_rigidity": 1.0}
RHO = 1.2


def theodorsen(k):
    """Theodorsen's function C(k) = F + iG."""
    return hankel2(1, k) / (hankel2(1, k) + 1j * hankel2(0, k))


def heave_theory(k, h0_over_c):
    """Complex amplitude of C_L for h = h0 sin(omega t) along the lift direction (Theodorsen)."""
    return h0_over_c * (2 * np.pi * k**2 - 4j * np.pi * k * theodorsen(k))


def wing_scene(model, motion, span=1000.0, M=10, N=5, wake_length=20.0, speed=1.0, chord=1.0):
    section = dict(SECTION, chord=chord)
    body = {"name": "wing", "length": span, "span_axis": [0, 1, 0], "chord_axis": [1, 0, 0], "section": section}
    return resolve_scene({"time": {"stop": 1.0},
                          "structure": {"fidelity": "prescribed", "bodies": [body], "motion": motion},
                          "aero": {"model": model, "chordwise_panels": M, "spanwise_panels": N,
                                   "wake_length": wake_length},
                          "flow": {"speed": speed, "density": RHO}}, "wing")


def fitted_amplitude(times, values, omega, t_from):
    """Complex amplitude z of values ~ Im(z e^{i omega t}) + offset over t >= t_from (least squares)."""
    m = times >= t_from - 1e-9
    X = np.stack([np.sin(omega * times[m]), np.cos(omega * times[m]), np.ones(m.sum())], axis=1)
    a, b, _ = np.linalg.lstsq(X, values[m], rcond=None)[0]
    return a + 1j * b


def assert_heave_matches(z, reference, amplitude_tol, phase_tol_deg):
    amplitude_error = abs(z) / abs(reference) - 1
    phase_error = np.degrees(np.angle(z / reference))
    assert abs(amplitude_error) < amplitude_tol, (abs(z), abs(reference), amplitude_error)
    assert abs(phase_error) < phase_tol_deg, (np.degrees(np.angle(z)), np.degrees(np.angle(reference)))
