"""Internal constraint equations on the exchanged coordinates E (Otsuka et al. 2019, Eqs. 6 and 17).

All remaining constraints are quadratic in E, Phi_i = 1/2 E^T H_i E + h_i . E + c_i:
  unit length   (|v|^2 - 1) / 2 = 0        (Otsuka et al. 2019, Eq. 6 row 1 for r_y; Eq. 17 rows 1-2)
  orthogonality a . b = 0                  (Otsuka et al. 2019, Eq. 6 row 2; Eq. 17 row 3)
  fixed plane   v . n = 0                  (a pin about the section normal)
so the constraint Jacobian G = dPhi/dE is linear in E and the acceleration term dE^T H_i dE is cheap.
The linear rows of Eq. (17) are eliminated by the coordinate map E = T q + P p (topology.py); the
integrators need the Jacobian on the free coordinates q, G_q = G T (Otsuka et al. 2019, Eq. 4's Phi_q).
"""
import numpy as np


class Constraints:
    """Vectorized evaluation of the nonlinear constraints of a StructureTopology whose free coordinates q map
    to E = T q + P p (`T`, (n, n_q), `StructureTopology.maps`).

    The unit-length and orthogonality rows are both products c (X_a . X_b) + c0 of two slots of
    X = E.reshape(-1, 3) (unit: a = b, c = 1/2, c0 = -1/2; orthogonality: c = 1, c0 = 0), the fixed-plane
    rows are X_s . n; rows are ordered unit, orthogonality, plane. Every evaluation gathers E through
    flat index arrays built once (these run several times per time step on small arrays)."""

    def __init__(self, topology, T):
        self.unit = np.array(topology.unit_slots, dtype=int)
        self.ortho = np.array(topology.orthogonal_slots, dtype=int).reshape(-1, 2)
        self.plane = np.array([s for s, _ in topology.fixed_directions], dtype=int)
        self.plane_normal = np.array([n for _, n in topology.fixed_directions]).reshape(-1, 3)
        self.count = len(self.unit) + len(self.ortho) + len(self.plane)
        self.n = topology.n_coordinates
        nu, no = len(self.unit), len(self.ortho)
        a, b = np.concatenate([self.unit, self.ortho[:, 0]]), np.concatenate([self.unit, self.ortho[:, 1]])
        components = np.arange(3)
        flat = lambda slots: (3 * slots[:, None] + components).ravel()          # E indices of the slots
        self._ia, self._ib, self._ip = flat(a), flat(b), flat(self.plane)
        self._coefficient = np.repeat([0.5, 1.0], [nu, no])
        self._velocity_coefficient = 2.0 * self._coefficient
        self._constant = np.repeat([-0.5, 0.0], [nu, no])
        self._plane_normal = self.plane_normal.ravel()
        self._plane_zeros = np.zeros(len(self.plane))
        # G_q row of a product: c (X_b^T T_a + X_a^T T_b), T_s the three rows of T of slot s. With the pair
        # [X_a, X_b] gathered as one 6-vector it is one small product with the stacked c [T_b; T_a] (6, n_q).
        T = np.asarray(T, dtype=float)
        self._n_free = T.shape[1]
        self._pair = np.concatenate([self._ia.reshape(-1, 3), self._ib.reshape(-1, 3)], axis=1).ravel()
        slot_rows = lambda flat_index: T[flat_index].reshape(len(flat_index) // 3, 3, self._n_free)
        self._pair_rows = self._coefficient[:, None, None] * np.concatenate([slot_rows(self._ib), slot_rows(self._ia)],
                                                                            axis=1)
        self._swapped = np.concatenate([self._ib.reshape(-1, 3), self._ia.reshape(-1, 3)], axis=1).ravel()
        self._plane_jacobian = np.einsum("sk,skj->sj", self.plane_normal, slot_rows(self._ip))
        # H_i entries: (slot row, slot column, constraint) pairs, each on the three components
        rows, cols, which = (np.concatenate(v) for v in zip((a, b, np.arange(nu + no)),
                                                             (self.ortho[:, 1], self.ortho[:, 0], nu + np.arange(no))))
        self._hessian_entries = ((3 * rows[:, None] + components) * self.n + 3 * cols[:, None] + components).ravel()
        self._hessian_multiplier = np.repeat(which, 3)

    def residual(self, E):
        """Phi(E), shape (count,)."""
        products = (E[self._ia] * E[self._ib]).reshape(-1, 3).sum(axis=1) * self._coefficient + self._constant
        if not len(self.plane):
            return products
        return np.concatenate([products, (E[self._ip] * self._plane_normal).reshape(-1, 3).sum(axis=1)])

    def jacobian(self, E):
        """G_q = dPhi/dq = (dPhi/dE) T at E, dense (count, n_q)."""
        pairs = E[self._pair].reshape(-1, 1, 6) @ self._pair_rows
        products = pairs.reshape(len(self._pair_rows), self._n_free)
        return np.concatenate([products, self._plane_jacobian]) if len(self.plane) else products

    def rate(self, E, dE):
        """dPhi/dt = (dPhi/dE) dE at E for a rate dE (n,) on the exchanged coordinates, shape (count,)."""
        pairs = (E[self._pair] * dE[self._swapped]).reshape(-1, 6).sum(axis=1) * self._coefficient
        if not len(self.plane):
            return pairs
        return np.concatenate([pairs, (dE[self._ip] * self._plane_normal).reshape(-1, 3).sum(axis=1)])

    def velocity_quadratic(self, dE):
        """dE^T H_i dE for each constraint: the term of d2Phi/dt2 that is not G d2E/dt2."""
        products = self._velocity_coefficient * (dE[self._ia] * dE[self._ib]).reshape(-1, 3).sum(axis=1)
        return np.concatenate([products, self._plane_zeros]) if len(self.plane) else products

    def hessian_sum(self, multipliers):
        """sum_i lambda_i H_i, dense (n, n): the constraint part of the tangent stiffness (on E)."""
        values = np.asarray(multipliers)[self._hessian_multiplier]
        return np.bincount(self._hessian_entries, values, self.n * self.n).reshape(self.n, self.n)
