"""The planform of a body: the map from (span x, chord fraction f) to the body's material plane and the normal
offset of its mean surface.

The body's reference line (the beam axis) is the material line y = 0, x = 0..L from the root; y is measured along
r_y toward the trailing edge (Otsuka et al. 2019, Eq. 2). Chord lines stay along r_y (x constant). In the
material plane, before twist and camber, the point at chord fraction f of the chord at span x is

    d(x, f) = y_LE(x) + f c(x),   c(x) = c_r + (c_t - c_r) x / L,   y_LE(x) = -a c_r + x tan(Lambda)

with the chord c_r at the root and c_t at the tip, a the reference line's chord fraction at the root and Lambda
the leading-edge sweep (positive toward the trailing edge); without a given sweep, tan(Lambda) = -a (c_t - c_r)
/ L keeps the reference line at the fraction a of every chord. The section at x is turned by the twist
theta(x) = theta_r + (theta_t - theta_r) x / L (nose up positive: the leading edge moves along the section
normal n = r_x x r_y) about the reference line, and the camber line z(f) (fmu_common.airfoil) lies along the
section's turned normal, so that the mean-surface point is

    y = d cos(theta) + c z(f) sin(theta),   h = -d sin(theta) + c z(f) cos(theta),
    r = S(x, y) e + h n,

S the element's shape functions (Otsuka et al. 2019, Eq. 20). A flat, untwisted planform has h = 0: r = S e.
"""
from dataclasses import dataclass

import numpy as np

from .airfoil import FLAT, CamberLine


@dataclass(frozen=True)
class Planform:
    """Length L (m), root and tip chords (m), reference line at chord fraction `axis_position` a of the root
    chord, the leading edge's y at the tip `leading_edge_tip` (m), twist at root and tip (rad), camber line."""

    length: float
    chord_root: float
    chord_tip: float
    axis_position: float
    leading_edge_tip: float
    twist_root: float = 0.0
    twist_tip: float = 0.0
    camber: CamberLine = FLAT

    @classmethod
    def of(cls, length, chord_root, chord_tip, axis_position, sweep_deg=None, twist_root_deg=0.0, twist_deg=0.0,
           camber=FLAT) -> "Planform":
        """The planform of a body's keys (module docstring).

        Args:
            length: L, m.
            chord_root: c_r, m.
            chord_tip: c_t, m.
            axis_position: a, fraction of the root chord from the leading edge.
            sweep_deg: the leading-edge sweep Lambda, deg; None: the reference line at a of every chord.
            twist_root_deg: theta_r, deg.
            twist_deg: theta_t - theta_r, deg.
            camber: the camber line.
        """
        if sweep_deg is None:
            tip = -axis_position * chord_tip
        else:
            tip = -axis_position * chord_root + length * np.tan(np.radians(sweep_deg))
        return cls(float(length), float(chord_root), float(chord_tip), float(axis_position), float(tip),
                   float(np.radians(twist_root_deg)), float(np.radians(twist_root_deg + twist_deg)), camber)

    @property
    def flat(self) -> bool:
        """True when the mean surface is the material plane (no twist, no camber): h = 0."""
        return self.twist_root == 0.0 and self.twist_tip == 0.0 and self.camber.m == 0.0

    @property
    def area(self) -> float:
        """The planform area L (c_r + c_t) / 2, m^2."""
        return 0.5 * self.length * (self.chord_root + self.chord_tip)

    def chord(self, x):
        """c(x), m, at span x.

        Args:
            x: span from the root, m, any shape.
        """
        return self.chord_root + (self.chord_tip - self.chord_root) * np.asarray(x, dtype=float) / self.length

    def leading_edge(self, x):
        """y_LE(x), m: the leading edge's offset from the reference line along r_y.

        Args:
            x: span from the root, m, any shape.
        """
        lead = -self.axis_position * self.chord_root
        return lead + (self.leading_edge_tip - lead) * np.asarray(x, dtype=float) / self.length

    def twist(self, x):
        """theta(x), rad.

        Args:
            x: span from the root, m, any shape.
        """
        return self.twist_root + (self.twist_tip - self.twist_root) * np.asarray(x, dtype=float) / self.length

    def chord_offset(self, x, f):
        """y (m) of the point at chord fraction f of the flat planform at span x: d(x, f).

        Args:
            x: span from the root, m.
            f: chord fraction from the leading edge; broadcast against x.
        """
        return self.leading_edge(x) + np.asarray(f, dtype=float) * self.chord(x)

    def surface(self, x, f):
        """(y, h, y_x, h_x, y_f, h_f): the mean-surface point at span x and chord fraction f as material y (m)
        and normal offset h (m), and their derivatives along x (-) and f (m); arrays broadcast from x and f.

        Args:
            x: span from the root, m.
            f: chord fraction from the leading edge; broadcast against x.
        """
        x, f = np.broadcast_arrays(np.asarray(x, dtype=float), np.asarray(f, dtype=float))
        c, dc = self.chord(x), (self.chord_tip - self.chord_root) / self.length
        d = self.chord_offset(x, f)
        d_x = (self.leading_edge_tip + self.axis_position * self.chord_root) / self.length + f * dc
        z, z_f = c * self.camber.height(f), c * self.camber.slope(f)
        z_x = dc * self.camber.height(f)
        theta, theta_x = self.twist(x), (self.twist_tip - self.twist_root) / self.length
        cos, sin = np.cos(theta), np.sin(theta)
        y, h = d * cos + z * sin, -d * sin + z * cos
        y_x = d_x * cos + z_x * sin + theta_x * h
        h_x = -d_x * sin + z_x * cos - theta_x * y
        return y, h, y_x, h_x, c * cos + z_f * sin, -c * sin + z_f * cos
