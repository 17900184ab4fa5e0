"""Prescribed rigid motions: clamps, driven hinges (Otsuka et al. 2019, Eq. 27), heave/pitch laws.

A law gives, at time t, the rotation R about a pivot and a translation h, with their rates:
x(t) = pivot + R(t) (x0 - pivot) + h(t) for a material point, g(t) = R(t) g0 for a gradient vector.
Angular velocity omega and acceleration alpha are in the global frame (rad/s, rad/s^2).
"""
import math
from dataclasses import dataclass

import numpy as np

from fmu_common.vectors import rodrigues, skew


@dataclass(frozen=True)
class Kinematics:
    """A law's rotation R and translation h at one time, with their rates, global frame."""

    rotation: np.ndarray          # R (3, 3)
    omega: np.ndarray             # rad/s
    alpha: np.ndarray             # rad/s^2
    translation: np.ndarray       # h, m
    velocity: np.ndarray          # dh/dt, m/s
    acceleration: np.ndarray      # d2h/dt2, m/s^2
    spin: np.ndarray              # [omega]x (3, 3), 1/s: dR/dt = spin R
    turn: np.ndarray              # [alpha]x + [omega]x^2 (3, 3), 1/s^2: d2R/dt2 = turn R


class Fixed:
    """A clamp: no motion."""

    pivot = np.zeros(3)

    def kinematics(self, t):
        """The identity rotation and zero translation, at rest.

        Args:
            t: time, s.
        """
        z, zz = np.zeros(3), np.zeros((3, 3))
        return Kinematics(np.eye(3), z, z, z, z, z, zz, zz)


class _AxisRotation:
    """Rotation by theta(t) about a fixed unit axis (fmu_common.vectors.rodrigues), with K = [axis]x and K^2 built
    once (these run once per time step)."""

    def __init__(self, axis):
        self.axis = np.asarray(axis, float)
        self._K = skew(self.axis)
        self._K2 = self._K @ self._K

    def kinematics(self, theta, dtheta, ddtheta, translation, velocity, acceleration):
        """Kinematics for the angle theta (rad) and its rates (rad/s, rad/s^2), and the translation h (m) and its
        rates."""
        K, K2 = self._K, self._K2
        rotation = rodrigues(K, K2, math.sin(theta), math.cos(theta))
        return Kinematics(rotation, dtheta * self.axis, ddtheta * self.axis, translation, velocity, acceleration,
                          dtheta * K, ddtheta * K + (dtheta * dtheta) * K2)


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
        self._still = np.zeros(3)

    def angle(self, t):
        """theta, dtheta/dt, d2theta/dt2 (rad, rad/s, rad/s^2).

        Args:
            t: time, s.
        """
        ws, Ts = self.omega, self.ramp_time
        if t < Ts:
            c = 2 * np.pi / Ts
            return (ws / Ts * (t**2 / 2 + (np.cos(c * t) - 1) / c**2),
                    ws / Ts * (t - np.sin(c * t) / c),
                    ws / Ts * (1 - np.cos(c * t)))
        return ws * (t - Ts / 2), ws, 0.0

    def kinematics(self, t):
        """The rotation by `angle(t)` about the axis.

        Args:
            t: time, s.
        """
        z = self._still
        return self._rotation.kinematics(*self.angle(t), z, z, z)


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
        self._rotation = _AxisRotation(self.pitch_axis)

    def kinematics(self, t):
        """The heave and pitch at time t.

        Args:
            t: time, s.
        """
        w = self.frequency
        s, c = np.sin(w * t), np.cos(w * t)
        sp, cp = np.sin(w * t + self.phase), np.cos(w * t + self.phase)
        a = self.pitch_amplitude
        theta, dtheta, ddtheta = a * sp, a * w * cp, -a * w * w * sp
        h = self.heave_amplitude * self.heave_axis
        return self._rotation.kinematics(theta, dtheta, ddtheta, s * h, w * c * h, -w * w * s * h)
