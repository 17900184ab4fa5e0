"""Shape functions of the 18-DoF ANCF beam element (Otsuka et al. 2019, Eq. 2), with no element physics.

Element coordinates (Otsuka et al. 2019, Eq. 3): e = [r^A, r_x^A, r_y^A, r^B, r_x^B, r_y^B], metres for r,
dimensionless for the gradients. The position of a material point is r(x, y) = S(x, y) e with x along the
span (0..l, m) and y along the chord from the reference line toward the trailing edge (m): cubic Hermite
along the span for r and r_x, r_y linear along the span, r(x, y) = r(x, 0) + y r_y(x), and
S(x, y) = kron(s, I_3). The structure unit integrates its element matrices with them; the aero unit maps
panel points and forces to the exchanged coordinates with the same rows (Eq. 12).
"""
import numpy as np


def hermite(xi, length):
    """Span shape functions and their x-derivatives at xi = x / l.

    Args:
        xi: x / l, dimensionless, any shape.
        length: l, m, broadcast against xi.

    Returns:
        (N, dN, ddN, L): N, dN = dN/dx, ddN = d2N/dx2 of shape (..., 4) for (r^A, r_x^A, r^B, r_x^B) and L of shape
        (..., 2) for (r_y^A, r_y^B).
    """
    xi, length = np.broadcast_arrays(np.asarray(xi, dtype=float), np.asarray(length, dtype=float))
    l, x2, x3 = length, xi**2, xi**3
    N = np.stack([1 - 3 * x2 + 2 * x3, l * (xi - 2 * x2 + x3), 3 * x2 - 2 * x3, l * (x3 - x2)], axis=-1)
    dN = np.stack([(6 * x2 - 6 * xi) / l, 1 - 4 * xi + 3 * x2, (6 * xi - 6 * x2) / l, 3 * x2 - 2 * xi], axis=-1)
    ddN = np.stack([(12 * xi - 6) / l**2, (6 * xi - 4) / l, (6 - 12 * xi) / l**2, (6 * xi - 2) / l], axis=-1)
    L = np.stack([1 - xi, xi], axis=-1)
    return N, dN, ddN, L


def shape_row(x, y, length):
    """Scalar shape row s(x, y); S(x, y) = kron(s, I_3).

    Otsuka et al. 2019, Eq. 2

    Ordering follows e: [r^A, r_x^A, r_y^A, r^B, r_x^B, r_y^B].

    Args:
        x: position along the element, m.
        y: position along the chord, m.
        length: l, the element length, m.

    Returns:
        (..., 6).
    """
    N, _, _, L = hermite(np.asarray(x) / length, length)
    y = np.asarray(y, dtype=float)[..., None]
    return np.concatenate([N[..., :2], y * L[..., :1], N[..., 2:], y * L[..., 1:]], axis=-1)
