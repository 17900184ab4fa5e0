"""Camber lines of thin sections: the NACA 4-digit mean line and its thin-airfoil zero-lift angle.

A NACA 4-digit section "naca" m p tt (e.g. "naca2412": maximum camber m = 2% of the chord at p = 40% of the
chord from the leading edge, thickness 12%) has the mean line (Abbott and von Doenhoff 1959, Ch. 6), in
chord fractions f from the leading edge and heights z / c,

    z = m / p^2 (2 p f - f^2)                        for f < p
    z = m / (1 - p)^2 ((1 - 2 p) + 2 p f - f^2)      for f >= p

Thin-airfoil theory (Anderson 2017, Ch. 4) gives its zero-lift angle

    alpha_L0 = -(1 / pi) int_0^pi dz/df (cos(theta) - 1) d theta,   f = (1 - cos(theta)) / 2,

integrated here by Gauss-Legendre quadrature on each polynomial piece (exact to rounding). The thickness does
not enter: the lifting surfaces are mean surfaces.
"""
import re
from dataclasses import dataclass

import numpy as np

NACA_PATTERN = re.compile(r"naca(\d)(\d)(\d\d)", re.IGNORECASE)


@dataclass(frozen=True)
class CamberLine:
    """A NACA 4-digit mean line: maximum camber m (fraction of the chord) at p (fraction from the leading edge)."""

    m: float
    p: float

    def height(self, f):
        """z / c at chord fractions f (f beyond 1 continues the aft polynomial).

        Args:
            f: chord fractions from the leading edge, any shape.
        """
        f = np.asarray(f, dtype=float)
        if self.m == 0.0:
            return np.zeros_like(f)
        m, p = self.m, self.p
        fore = m / p ** 2 * (2 * p * f - f * f) if p > 0 else np.zeros_like(f)
        aft = m / (1 - p) ** 2 * ((1 - 2 * p) + 2 * p * f - f * f)
        return np.where(f < p, fore, aft)

    def slope(self, f):
        """dz/df (dimensionless) at chord fractions f.

        Args:
            f: chord fractions from the leading edge, any shape.
        """
        f = np.asarray(f, dtype=float)
        if self.m == 0.0:
            return np.zeros_like(f)
        m, p = self.m, self.p
        fore = 2 * m / p ** 2 * (p - f) if p > 0 else np.zeros_like(f)
        aft = 2 * m / (1 - p) ** 2 * (p - f)
        return np.where(f < p, fore, aft)

    def zero_lift_angle(self) -> float:
        """alpha_L0 (rad) of thin-airfoil theory (module docstring); negative for a positive camber."""
        if self.m == 0.0:
            return 0.0
        xi, w = np.polynomial.legendre.leggauss(24)
        split = np.arccos(1.0 - 2.0 * self.p)            # theta at f = p: the slope's kink
        total = 0.0
        for a, b in ((0.0, split), (split, np.pi)):
            theta = 0.5 * (b - a) * xi + 0.5 * (b + a)
            f = 0.5 * (1.0 - np.cos(theta))
            total += 0.5 * (b - a) * float(np.sum(w * self.slope(f) * (np.cos(theta) - 1.0)))
        return -total / np.pi


FLAT = CamberLine(0.0, 0.0)
"""The flat plate: no camber."""


def naca_camber(code: str) -> CamberLine:
    """The mean line of a NACA 4-digit designation such as "naca2412" (case-insensitive).

    Raises ValueError for any other string, and for a camber without its position (m > 0, p = 0).

    Args:
        code: "naca" and four digits.
    """
    match = NACA_PATTERN.fullmatch(code.strip()) if isinstance(code, str) else None
    if match is None:
        raise ValueError("a NACA 4-digit designation such as 'naca2412' or 'naca0012'")
    m, p = int(match.group(1)) / 100.0, int(match.group(2)) / 10.0
    if m > 0 and p == 0:
        raise ValueError("a NACA 4-digit designation whose second digit (the position of the maximum camber, "
                         "tenths of the chord) is not 0 when the first (the camber) is not")
    return CamberLine(m, p) if m > 0 else FLAT
