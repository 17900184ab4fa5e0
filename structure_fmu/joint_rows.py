"""Joint rows on four gathered 3-vectors of E (`GatheredRows`: the axis products of constraints.py and the sliding
rows here), and the sliding rows: a point of one body kept on a line or plane fixed in another body.

The row is Phi = (X_p - X_q) . v_Q(c) - offset on the exchanged coordinates E, X = E.reshape(-1, 3): X_p the
position r of the sliding point's node P, X_q the position r of a node Q of the carrying body, and
v_Q(c) = c_x r_x + c_y r_y + c_z (r_x x r_y) at node Q the body-fixed direction of frame components
c = (span, chord, normal), as in `constraints.AxisProduct`. Phi is cubic in E: its Jacobian depends on E, and so do
its velocity term and Hessian. A slider on a line or plane fixed in space is linear instead: a coordinate
(pins.py), or `constraints.LinearRow` where its node has no free point left.
"""
from dataclasses import dataclass

import numpy as np

from fmu_common.vectors import cross, skew


@dataclass(frozen=True)
class SlidingRow:
    """A row Phi = (X_p - X_q) . v_Q(c) - offset = 0 (m): node P's point on a line or plane fixed in the body of
    node Q.

    A plane fixed in the body gives one row, c its normal; a line gives two, c_1, c_2 perpendicular to it (both
    in Q's frame components). On a rigid body v_Q(c) is the body's frame applied to c; in the flexible fidelity
    its span part is stretched by 1 + eps_x at Q (see `constraints.AxisProduct`).

    point: slot (`StructureTopology.slots`) of r at node P. origin: slot of r at node Q. frame: slot of r_x at
    node Q; the slot of r_y is the next one. components: c, (3,), dimensionless. offset: the row's value of
    (X_p - X_q) . v_Q(c) where it holds (at the start), m for a unit c on a rigid body.
    """

    point: int
    origin: int
    frame: int
    components: np.ndarray
    offset: float


def frame_vector(c, x, y):
    """v(c) = c_x x + c_y y + c_z (x x y), one per row.

    Args:
        c: (m, 3) components, 1.
        x: (m, 3) r_x, 1, global frame.
        y: (m, 3) r_y, 1, global frame.

    Returns:
        (m, 3) global frame.
    """
    return c[:, :1] * x + c[:, 1:2] * y + c[:, 2:] * cross(x, y)


class GatheredRows:
    """Rows that each read four 3-vector slots of E (n,), twelve entries, with E = T q + P p.

    A subclass gives residual(E), gradient(E) (m, 12), velocity_quadratic(dE, E) and hessian(E) (m, 12, 12) on the
    gathered entries; the Jacobian on q, the rate and the Hessian sum on E follow here. Entries that coincide in E
    (two rows' or one row's) are summed where the derivatives are scattered on E or mapped by T.

    Args:
        index: (m, 12) the E entries each row reads.
        T: (n, n_q) the map of q onto E.
        n: the length of E.
    """

    def __init__(self, index, T, n):
        self._index = np.asarray(index, dtype=int).reshape(-1, 12)
        self.count, self.n = len(self._index), n
        self._T = np.asarray(T, dtype=float)[self._index]                              # (m, 12, n_q)
        self._hessian_entries = (self._index[:, :, None] * n + self._index[:, None, :]).ravel()

    def _gather(self, E):
        """The four gathered 3-vectors of each row, (m, 4, 3)."""
        return E[self._index].reshape(-1, 4, 3)

    def jacobian(self, E):
        """G_q = dPhi/dq.

        Args:
            E: (n,) exchanged coordinates, global frame.

        Returns:
            (m, n_q).
        """
        return np.einsum("mk,mkj->mj", self.gradient(E), self._T)

    def rate(self, E, dE):
        """dPhi/dt for the rate dE.

        Args:
            E: (n,) exchanged coordinates, global frame.
            dE: (n,) their rates, per s.

        Returns:
            (m,) per s.
        """
        return np.einsum("mk,mk->m", self.gradient(E), dE[self._index])

    def hessian_sum(self, multipliers, E):
        """sum_i lambda_i d2Phi_i/dE2, dense.

        Args:
            multipliers: (m,) the rows' multipliers lambda.
            E: (n,) exchanged coordinates, global frame.

        Returns:
            (n, n).
        """
        values = (np.asarray(multipliers)[:, None, None] * self.hessian(E)).ravel()
        return np.bincount(self._hessian_entries, values, self.n * self.n).reshape(self.n, self.n)


class SlidingRows(GatheredRows):
    """Vectorized evaluation of `SlidingRow`s.

    Each row gathers [X_p, X_q, r_x^Q, r_y^Q]; with d = X_p - X_q and v = v_Q(c), Phi = d . v - offset (m).

    Args:
        rows: the SlidingRows (m of them).
        T: (n, n_q) the map of q onto E.
        n: the length of E.
    """

    def __init__(self, rows, T, n):
        slot = lambda s: list(range(3 * s, 3 * s + 3))                                 # noqa: E731
        super().__init__([slot(r.point) + slot(r.origin) + slot(r.frame) + slot(r.frame + 1) for r in rows], T, n)
        self._c = np.array([r.components for r in rows], dtype=float).reshape(-1, 3)
        self._offset = np.array([r.offset for r in rows], dtype=float)

    def residual(self, E):
        """Phi, one value per row, m.

        Args:
            E: (n,) exchanged coordinates, global frame.

        Returns:
            (m,) m.
        """
        X = self._gather(E)
        return np.einsum("mi,mi->m", X[:, 0] - X[:, 1], frame_vector(self._c, X[:, 2], X[:, 3])) - self._offset

    def gradient(self, E):
        """dPhi/dE on each row's twelve entries [X_p, X_q, r_x^Q, r_y^Q].

        v, -v, c_x d + c_z (r_y x d), c_y d + c_z (d x r_x), from (r_x x r_y) . d = r_x . (r_y x d) = r_y . (d x r_x).

        Args:
            E: (n,) exchanged coordinates, global frame.

        Returns:
            (m, 12).
        """
        X = self._gather(E)
        c = self._c
        d = X[:, 0] - X[:, 1]
        v = frame_vector(c, X[:, 2], X[:, 3])
        turned = cross(np.stack([X[:, 3], d], axis=1), np.stack([d, X[:, 2]], axis=1))
        return np.concatenate([v, -v, c[:, :1] * d + c[:, 2:] * turned[:, 0], c[:, 1:2] * d + c[:, 2:] * turned[:, 1]],
                              axis=1)

    def velocity_quadratic(self, dE, E):
        """The part of d2Phi/dt2 that is not (dPhi/dE) E'', at E.

        2 d' . v' + 2 c_z d . (r_x' x r_y'), with v' = c_x r_x' + c_y r_y' + c_z (r_x' x r_y + r_x x r_y').

        Args:
            dE: (n,) rates of the exchanged coordinates, per s.
            E: (n,) exchanged coordinates, global frame.

        Returns:
            (m,) m/s^2.
        """
        X, V = self._gather(E), self._gather(dE)
        c = self._c
        products = cross(np.stack([V[:, 2], X[:, 2], V[:, 2]], axis=1), np.stack([X[:, 3], V[:, 3], V[:, 3]], axis=1))
        dv = c[:, :1] * V[:, 2] + c[:, 1:2] * V[:, 3] + c[:, 2:] * (products[:, 0] + products[:, 1])
        return 2.0 * (np.einsum("mi,mi->m", V[:, 0] - V[:, 1], dv)
                      + c[:, 2] * np.einsum("mi,mi->m", X[:, 0] - X[:, 1], products[:, 2]))

    def hessian(self, E):
        """d2Phi/dE2 on each row's twelve entries, exact, at E.

        The nonzero blocks: dv/dr_x = c_x I - c_z [r_y]_x and dv/dr_y = c_y I + c_z [r_x]_x on X_p (minus on X_q), and
        d2 [d . (r_x x r_y)] / dr_x dr_y = -c_z [d]_x.

        Args:
            E: (n,) exchanged coordinates, global frame.

        Returns:
            (m, 12, 12) 1/m.
        """
        X = self._gather(E)
        c = self._c
        eye = np.eye(3)
        dv_dx = c[:, 0, None, None] * eye - c[:, 2, None, None] * skew(X[:, 3])
        dv_dy = c[:, 1, None, None] * eye + c[:, 2, None, None] * skew(X[:, 2])
        dv = np.concatenate([dv_dx, dv_dy], axis=2)                                      # (m, 3, 6)
        H = np.zeros((self.count, 12, 12))
        H[:, 0:3, 6:12] = dv
        H[:, 3:6, 6:12] = -dv
        H[:, 6:9, 9:12] = -c[:, 2, None, None] * skew(X[:, 0] - X[:, 1])
        return H + np.swapaxes(H, 1, 2)
