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
    """Vectorized evaluation of the nonlinear constraints of a Topology."""

    def __init__(self, topology):
        self.unit = np.array(topology.unit_slots, dtype=int)
        self.ortho = np.array(topology.orthogonal_slots, dtype=int).reshape(-1, 2)
        self.plane = np.array([s for s, _ in topology.fixed_directions], dtype=int)
        self.plane_normal = np.array([n for _, n in topology.fixed_directions]).reshape(-1, 3)
        self.count = len(self.unit) + len(self.ortho) + len(self.plane)
        self.n = topology.n_coordinates

    @staticmethod
    def _vec(E, slots):
        return E.reshape(-1, 3)[slots]

    def residual(self, E):
        """Phi(E), shape (count,)."""
        u, a, b = self._vec(E, self.unit), self._vec(E, self.ortho[:, 0]), self._vec(E, self.ortho[:, 1])
        p = self._vec(E, self.plane)
        return np.concatenate([0.5 * (np.sum(u * u, 1) - 1.0), np.sum(a * b, 1), np.sum(p * self.plane_normal, 1)])

    def jacobian(self, E):
        """G = dPhi/dE, dense (count, n)."""
        G = np.zeros((self.count, self.n // 3, 3))
        rows = np.arange(self.count)
        nu, no = len(self.unit), len(self.ortho)
        G[rows[:nu], self.unit] = self._vec(E, self.unit)
        G[rows[nu:nu + no], self.ortho[:, 0]] += self._vec(E, self.ortho[:, 1])
        G[rows[nu:nu + no], self.ortho[:, 1]] += self._vec(E, self.ortho[:, 0])
        G[rows[nu + no:], self.plane] = self.plane_normal
        return G.reshape(self.count, self.n)

    def velocity_quadratic(self, dE):
        """dE^T H_i dE for each constraint: the term of d2Phi/dt2 that is not G d2E/dt2."""
        u, a, b = self._vec(dE, self.unit), self._vec(dE, self.ortho[:, 0]), self._vec(dE, self.ortho[:, 1])
        return np.concatenate([np.sum(u * u, 1), 2.0 * np.sum(a * b, 1), np.zeros(len(self.plane))])

    def hessian_sum(self, multipliers):
        """sum_i lambda_i H_i, dense (n, n): the constraint part of the tangent stiffness."""
        H = np.zeros((self.n // 3, self.n // 3))
        nu, no = len(self.unit), len(self.ortho)
        np.add.at(H, (self.unit, self.unit), multipliers[:nu])
        np.add.at(H, (self.ortho[:, 0], self.ortho[:, 1]), multipliers[nu:nu + no])
        np.add.at(H, (self.ortho[:, 1], self.ortho[:, 0]), multipliers[nu:nu + no])
        return np.kron(H, np.eye(3))
