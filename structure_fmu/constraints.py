"""Internal constraint equations on the exchanged coordinates E (000 Eqs. 6 and 17).

All remaining constraints are quadratic in E, Phi_i = 1/2 E^T H_i E + h_i . E + c_i:
  unit length   (|v|^2 - 1) / 2 = 0        (000 Eq. 6 row 1 for r_y; Eq. 17 rows 1-2)
  orthogonality a . b = 0                  (000 Eq. 6 row 2; Eq. 17 row 3)
  fixed plane   v . n = 0                  (a pin about the section normal)
so the constraint Jacobian G = dPhi/dE is linear in E and the acceleration term dE^T H_i dE is cheap.
The linear rows of Eq. (17) are eliminated by the coordinate map in topology.py.
"""
import numpy as np


class Constraints:
    """Vectorized evaluation of the nonlinear constraints of a Topology.

    The unit-length and orthogonality rows are both products c (X_a . X_b) + c0 of two slots of
    X = E.reshape(-1, 3) (unit: a = b, c = 1/2, c0 = -1/2; orthogonality: c = 1, c0 = 0), the fixed-plane
    rows are X_s . n; rows are ordered unit, orthogonality, plane."""

    def __init__(self, topology):
        self.unit = np.array(topology.unit_slots, dtype=int)
        self.ortho = np.array(topology.orthogonal_slots, dtype=int).reshape(-1, 2)
        self.plane = np.array([s for s, _ in topology.fixed_directions], dtype=int)
        self.plane_normal = np.array([n for _, n in topology.fixed_directions]).reshape(-1, 3)
        self.count = len(self.unit) + len(self.ortho) + len(self.plane)
        self.n = topology.n_coordinates
        nu, no = len(self.unit), len(self.ortho)
        self._a = np.concatenate([self.unit, self.ortho[:, 0]])
        self._b = np.concatenate([self.unit, self.ortho[:, 1]])
        self._coefficient = np.repeat([0.5, 1.0], [nu, no])[:, None]
        self._constant = np.repeat([-0.5, 0.0], [nu, no])
        self._products = np.arange(nu + no)
        # the plane rows of G are constant
        self._jacobian_template = np.zeros((self.count, self.n // 3, 3))
        self._jacobian_template[np.arange(nu + no, self.count), self.plane] = self.plane_normal
        # H_i entries: (slot row, slot column, constraint) pairs, each on the three components
        rows, cols, which = (np.concatenate(v) for v in zip((self._a, self._b, self._products),
                                                             (self.ortho[:, 1], self.ortho[:, 0], nu + np.arange(no))))
        c = np.arange(3)
        self._hessian_entries = ((3 * rows[:, None] + c) * self.n + 3 * cols[:, None] + c).ravel()
        self._hessian_multiplier = np.repeat(which, 3)

    def residual(self, E):
        """Phi(E), shape (count,)."""
        X = E.reshape(-1, 3)
        products = self._coefficient[:, 0] * np.einsum("ij,ij->i", X[self._a], X[self._b]) + self._constant
        return np.concatenate([products, np.einsum("ij,ij->i", X[self.plane], self.plane_normal)])

    def jacobian(self, E):
        """G = dPhi/dE, dense (count, n)."""
        X = E.reshape(-1, 3)
        G = self._jacobian_template.copy()
        G[self._products, self._a] += self._coefficient * X[self._b]
        G[self._products, self._b] += self._coefficient * X[self._a]
        return G.reshape(self.count, self.n)

    def velocity_quadratic(self, dE):
        """dE^T H_i dE for each constraint: the term of d2Phi/dt2 that is not G d2E/dt2."""
        V = dE.reshape(-1, 3)
        products = 2.0 * self._coefficient[:, 0] * np.einsum("ij,ij->i", V[self._a], V[self._b])
        return np.concatenate([products, np.zeros(len(self.plane))])

    def hessian_sum(self, multipliers):
        """sum_i lambda_i H_i, dense (n, n): the constraint part of the tangent stiffness."""
        values = np.asarray(multipliers)[self._hessian_multiplier]
        return np.bincount(self._hessian_entries, values, self.n * self.n).reshape(self.n, self.n)
