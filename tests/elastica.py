"""The inextensible elastica of a cantilever under a dead transverse tip load, by shooting: the reference of the
large-deflection tests of the ANCF elements."""
import numpy as np
from scipy.integrate import solve_ivp
from scipy.optimize import brentq


def elastica_tip(k):
    """(dx, dz) / L of the tip of an inextensible cantilever under a dead transverse tip load, k = P L^2 / EI.

    Shooting on theta'' = -k cos(theta), theta(0) = 0, theta'(1) = 0 (no moment at the free end).
    """
    def rhs(s, y):
        return [y[1], -k * np.cos(y[0]), np.cos(y[0]), np.sin(y[0])]

    def end_moment(c):
        return solve_ivp(rhs, (0, 1), [0, c, 0, 0], rtol=1e-12, atol=1e-12).y[1, -1]
    slope = brentq(end_moment, 0.0, k)
    end = solve_ivp(rhs, (0, 1), [0, slope, 0, 0], rtol=1e-12, atol=1e-12).y[:, -1]
    return end[2] - 1.0, end[3]
