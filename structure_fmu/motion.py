"""Prescribed rigid motions: clamps, driven hinges (Otsuka et al. 2019, Eq. 27), heave/pitch laws.

A law gives, at time t, the rotation R about a pivot and a translation h, with their rates:
x(t) = pivot + R(t) (x0 - pivot) + h(t) for a material point, g(t) = R(t) g0 for a gradient vector.
Angular velocity omega and acceleration alpha are in the global frame (rad/s, rad/s^2).
"""
import math
from typing import NamedTuple

import numpy as np

from fmu_common.vectors import skew


class Kinematics(NamedTuple):
    """A law's rotation R and translation h at one time, with their rates, global frame.

    Each call of a law's kinematics(t) gives new arrays (views of one array of that call).
    """

    rotation: np.ndarray          # R (3, 3)
    omega: np.ndarray             # rad/s
    alpha: np.ndarray             # rad/s^2
    translation: np.ndarray       # h, m
    velocity: np.ndarray          # dh/dt, m/s
    acceleration: np.ndarray      # d2h/dt2, m/s^2
    spin: np.ndarray              # [omega]x (3, 3), 1/s: dR/dt = spin R
    turn: np.ndarray              # [alpha]x + [omega]x^2 (3, 3), 1/s^2: d2R/dt2 = turn R


def _kinematics(rows):
    """The Kinematics whose fields are views of `rows` (14, 3): R, omega, alpha, h, h', h'', spin, turn."""
    return Kinematics(rows[0:3], rows[3], rows[4], rows[5], rows[6], rows[7], rows[8:11], rows[11:14])


class Fixed:
    """A clamp: no motion."""

    pivot = np.zeros(3)
    _rest = np.vstack([np.eye(3), np.zeros((11, 3))])

    def kinematics(self, t):
        """The identity rotation and zero translation, at rest.

        Args:
            t: time, s.
        """
        return _kinematics(self._rest.copy())


class _AxisRotation:
    """Rotation by theta(t) about a fixed unit axis a and translation s(t) d along a fixed vector d.

    With K = [a]x, every field of Kinematics is linear in c = (1, sin theta, 1 - cos theta, theta', theta'',
    theta'^2, s, s', s''): R = I + sin theta K + (1 - cos theta) K^2 (Rodrigues, fmu_common.vectors.rodrigues),
    omega = theta' a, alpha = theta'' a, h = s d, spin = theta' K, turn = theta'' K + theta'^2 K^2. They are the
    one product c B, with the basis B built once (a law runs at every structure step).

    Args:
        axis: (3,) unit vector a, global frame.
        shift: (3,) d, m, global frame; None: no translation.
    """

    def __init__(self, axis, shift=None):
        a = np.asarray(axis, float)
        d = np.zeros(3) if shift is None else np.asarray(shift, float)
        K = skew(a)
        K2 = K @ K
        basis = np.zeros((9, 14, 3))           # [term of c, row of the fields (_kinematics), component]
        basis[0, 0:3] = np.eye(3)
        basis[1, 0:3], basis[2, 0:3] = K, K2
        basis[3, 3], basis[3, 8:11] = a, K
        basis[4, 4], basis[4, 11:14] = a, K
        basis[5, 11:14] = K2
        basis[6, 5], basis[7, 6], basis[8, 7] = d, d, d
        self._basis = basis.reshape(9, 42)

    def kinematics(self, theta, dtheta, ddtheta, s=0.0, ds=0.0, dds=0.0):
        """Kinematics for the angle theta (rad) and its rates (rad/s, rad/s^2), and the translation's factor s (-)
        and its rates (1/s, 1/s^2)."""
        c = np.array((1.0, math.sin(theta), 1.0 - math.cos(theta), dtheta, ddtheta, dtheta * dtheta, s, ds, dds))
        return _kinematics(np.dot(c, self._basis).reshape(14, 3))


class SpinUp:
    """Rotation about `axis` through `pivot` by the spin-up law.

    Otsuka et al. 2019, Eq. 27

    theta = omega_s / T_s [t^2/2 + (T_s / 2 pi)^2 (cos(2 pi t / T_s) - 1)] for t < T_s,
    theta = omega_s (t - T_s / 2) afterwards.

    Args:
        axis: (3,) unit rotation axis, global frame.
        pivot: (3,) point on the axis, m, global frame.
        omega: omega_s, the final rate, rad/s.
        ramp_time: T_s, s.
    """

    def __init__(self, axis, pivot, omega, ramp_time):
        self.axis, self.pivot = np.asarray(axis, float), np.asarray(pivot, float)
        self.omega, self.ramp_time = float(omega), float(ramp_time)
        self._rotation = _AxisRotation(self.axis)

    def angle(self, t):
        """theta, dtheta/dt, d2theta/dt2 (rad, rad/s, rad/s^2).

        Args:
            t: time, s.
        """
        ws, Ts = self.omega, self.ramp_time
        if t < Ts:
            c = 2 * math.pi / Ts
            cosine = math.cos(c * t)
            return (ws / Ts * (t**2 / 2 + (cosine - 1) / c**2),
                    ws / Ts * (t - math.sin(c * t) / c),
                    ws / Ts * (1 - cosine))
        return ws * (t - Ts / 2), ws, 0.0

    def kinematics(self, t):
        """The rotation by `angle(t)` about the axis.

        Args:
            t: time, s.
        """
        return self._rotation.kinematics(*self.angle(t))


class HeavePitch:
    """Sinusoidal heave along `heave_axis` and pitch about `pitch_axis` through `pivot`.

    h(t) = heave_amplitude sin(frequency t) (m); pitch(t) = pitch_amplitude sin(frequency t + phase) (rad).
    A constant pitch (sudden start at an angle of attack) is pitch_amplitude with frequency 0 and phase pi/2.

    Args:
        heave_axis: (3,) unit heave direction, global frame.
        pitch_axis: (3,) unit pitch axis, global frame.
        pivot: (3,) point on the pitch axis, m, global frame.
        heave_amplitude: m.
        pitch_amplitude: rad.
        frequency: rad/s.
        phase: of the pitch ahead of the heave, rad.
    """

    def __init__(self, heave_axis, pitch_axis, pivot, heave_amplitude, pitch_amplitude, frequency, phase):
        self.heave_axis = np.asarray(heave_axis, float)
        self.pitch_axis = np.asarray(pitch_axis, float)
        self.pivot = np.asarray(pivot, float)
        self.heave_amplitude, self.pitch_amplitude = float(heave_amplitude), float(pitch_amplitude)
        self.frequency, self.phase = float(frequency), float(phase)
        self._rotation = _AxisRotation(self.pitch_axis, self.heave_amplitude * self.heave_axis)

    def kinematics(self, t):
        """The heave and pitch at time t.

        Args:
            t: time, s.
        """
        w = self.frequency
        s, c = math.sin(w * t), math.cos(w * t)
        sp, cp = math.sin(w * t + self.phase), math.cos(w * t + self.phase)
        a = self.pitch_amplitude
        theta, dtheta, ddtheta = a * sp, a * w * cp, -a * w * w * sp
        return self._rotation.kinematics(theta, dtheta, ddtheta, s, w * c, -w * w * s)
