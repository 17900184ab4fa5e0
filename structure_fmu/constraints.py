"""Internal and joint constraint equations on the exchanged coordinates E (Otsuka et al. 2019, Eqs. 6 and 17;
Otsuka et al. 2022, Sec. 3).

The internal constraints are quadratic in E, Phi_i = 1/2 E^T H_i E + h_i . E + c_i:
  unit length   (|v|^2 - 1) / 2 = 0        (Otsuka et al. 2019, Eq. 6 row 1 for r_y; Eq. 17 rows 1-2)
  orthogonality a . b = 0                  (Otsuka et al. 2019, Eq. 6 row 2; Eq. 17 row 3)
so their Jacobian G = dPhi/dE is linear in E and the acceleration term dE^T H_i dE is cheap. The linear rows
(`LinearRow`: sum_k a_k X_k . n = c) have a constant Jacobian: a pin about the section normal (a gradient in the
plane), a slider on a fixed plane or line whose node has no free point left (pins.py), a closed loop's shared
point. The joints' axis products
(`AxisProduct`: universal and revolute joints whose axis is not a shared chord) are quartic in E at most, the
sliding rows between two bodies (`joint_rows.SlidingRow`) cubic. The linear rows of Eq. (17) and the shared joint
points are eliminated by the coordinate map E = T q + P p (topology.py); the integrators need the Jacobian on the
free coordinates q, G_q = G T (Otsuka et al. 2019, Eq. 4's Phi_q).
"""
from dataclasses import dataclass

import numpy as np

from fmu_common.vectors import cross, skew

from .coordinate_map import CoordinateMap
from .joint_rows import GatheredRows, SlidingRows, frame_vector


@dataclass(frozen=True)
class LinearRow:
    """A linear row Phi = sum_k a_k X_{s_k} . n - c = 0 (m) on the 3-vector slots s_k of E (X = E.reshape(-1, 3)).

    A fixed plane through c n (|n| = 1) of slot s is LinearRow((s,), (1.0,), n, c); a pin closing a loop between
    slots s_a, s_b is three rows LinearRow((s_a, s_b), (1.0, -1.0), e_k, 0.0), k = x, y, z.

    slots: slots (`StructureTopology.slots`), ints. coefficients: a_k, dimensionless, one per slot. normal: n,
    (3,), global components. offset: c, m for a position slot (dimensionless for a gradient slot).
    """

    slots: tuple[int, ...]
    coefficients: tuple[float, ...]
    normal: np.ndarray
    offset: float

    def __post_init__(self):
        if not self.slots or len(self.slots) != len(self.coefficients):
            raise ValueError(f"a LinearRow needs one coefficient per slot, at least one slot: slots {self.slots}, "
                             f"coefficients {self.coefficients}")
        if np.shape(self.normal) != (3,):
            raise ValueError(f"a LinearRow's normal is a 3-vector, not of shape {np.shape(self.normal)}")


@dataclass(frozen=True)
class AxisProduct:
    """A joint row Phi = v_A(a) . v_B(b) = 0 between the parent's tip node A and the child's root node B.

    At a node with gradients r_x, r_y, the body-fixed direction of frame components c = (span, chord, normal) is
    v(c) = c_x r_x + c_y r_y + c_z (r_x x r_y), bilinear in E, so Phi is at most quartic. With the ground
    (`parent` None) v_A(a) = a, global components. A universal joint has one row (a = parent_axis,
    b = child_axis, Otsuka et al. 2022, Eq. 18's last row); a revolute joint about an axis a that is not a shared
    chord has two, b = p_1, p_2 perpendicular to the axis in the child's frame.

    On a rigid body |r_x| = 1 and v is the body's frame. In the flexible fidelity |r_x| = 1 + eps_x (axial
    strain) while |r_y| = 1 and r_x . r_y = 0, so v(c) = (1 + eps_x)(c_x x + c_z z) + c_y y in the unit frame
    (x, y, z): an axis that mixes the chord with the span or the normal is turned by O(eps_x); it is exact
    when the axis lies along one frame direction or in the span-normal plane.

    parent, child: slot (`StructureTopology.slots`) of r_x at node A (None: the ground) and at node B; the
    slot of r_y is the next one. parent_axis, child_axis: a and b, (3,), dimensionless.
    """

    parent: int | None
    parent_axis: np.ndarray
    child: int
    child_axis: np.ndarray


class AxisProducts(GatheredRows):
    """Vectorized evaluation of the `AxisProduct` rows on E, with their Jacobian on q for E = T q + P p.

    Each row gathers the four 3-vectors [r_x^A, r_y^A, r_x^B, r_y^B] (twelve E entries: r_x and r_y of a node
    are contiguous), so that every row has the same form u . w with u = v_A(a) and w = v_B(b); a row with the
    ground has u = a: zero coefficients on the gathered r_x^A, r_y^A (the child's, as placeholders: their
    derivatives vanish) and the constant a.

    Args:
        rows: the AxisProduct rows (m of them).
        T: (n, n_q) the map of q onto E (`StructureTopology.maps`).
        n: the length of E.
    """

    def __init__(self, rows, T, n):
        node = lambda slot: list(range(3 * slot, 3 * slot + 6))                        # noqa: E731
        super().__init__([node(r.child if r.parent is None else r.parent) + node(r.child) for r in rows], T, n)
        self._a = np.array([np.zeros(3) if r.parent is None else r.parent_axis for r in rows]).reshape(-1, 3)
        self._ground = np.array([r.parent_axis if r.parent is None else np.zeros(3) for r in rows]).reshape(-1, 3)
        self._b = np.array([r.child_axis for r in rows]).reshape(-1, 3)
        # coefficients of the gradient's four blocks: [a_x, a_y, b_x, b_y] on w, w, u, u and [a_z, a_z, b_z, b_z]
        self._linear = np.concatenate([self._a[:, :2], self._b[:, :2]], axis=1)[:, :, None]
        self._normal = np.repeat(np.stack([self._a[:, 2], self._b[:, 2]], axis=1), 2, axis=1)[:, :, None]

    def _vectors(self, X):
        """u = v_A(a) (+ a with the ground) and w = v_B(b), each (m, 3), of the gathered X (m, 4, 3)."""
        return (frame_vector(self._a, X[:, 0], X[:, 1]) + self._ground, frame_vector(self._b, X[:, 2], X[:, 3]))

    def residual(self, E):
        """Phi, one value per row.

        Args:
            E: (n,) exchanged coordinates, global frame.

        Returns:
            (m,) dimensionless.
        """
        u, w = self._vectors(self._gather(E))
        return np.einsum("mi,mi->m", u, w)

    def gradient(self, E):
        """dPhi/dE on each row's twelve entries [r_x^A, r_y^A, r_x^B, r_y^B].

        d(u . w) = w . du + u . dw with d(r_x x r_y) . c = dr_x . (r_y x c) + dr_y . (c x r_x).

        Args:
            E: (n,) exchanged coordinates, global frame.

        Returns:
            (m, 12).
        """
        X = self._gather(E)
        u, w = self._vectors(X)
        uw = np.stack([w, w, u, u], axis=1)
        turned = cross(np.stack([X[:, 1], w, X[:, 3], u], axis=1), np.stack([w, X[:, 0], u, X[:, 2]], axis=1))
        return (self._linear * uw + self._normal * turned).reshape(-1, 12)

    def velocity_quadratic(self, dE, E):
        """The part of d2Phi/dt2 quadratic in dE, at E.

        2 u'.w' + 2 a_z (r_x^A' x r_y^A') . w + 2 b_z (r_x^B' x r_y^B') . u.

        Args:
            dE: (n,) rates of the exchanged coordinates, per s.
            E: (n,) exchanged coordinates, global frame.

        Returns:
            (m,) 1/s^2.
        """
        X = self._gather(E)
        u, w = self._vectors(X)
        V = self._gather(dE)
        a, b = self._a, self._b
        # the normals' rates r_x' x r_y + r_x x r_y' at A and B, and the products r_x' x r_y' at A and B
        products = cross(np.concatenate([V[:, 0::2], X[:, 0::2], V[:, 0::2]], axis=1),
                         np.concatenate([X[:, 1::2], V[:, 1::2], V[:, 1::2]], axis=1))
        rates = products[:, 0:2] + products[:, 2:4]
        du = a[:, :1] * V[:, 0] + a[:, 1:2] * V[:, 1] + a[:, 2:] * rates[:, 0]
        dw = b[:, :1] * V[:, 2] + b[:, 1:2] * V[:, 3] + b[:, 2:] * rates[:, 1]
        return 2.0 * (np.einsum("mi,mi->m", du, dw) + a[:, 2] * np.einsum("mi,mi->m", products[:, 4], w)
                      + b[:, 2] * np.einsum("mi,mi->m", products[:, 5], u))

    def hessian(self, E):
        """d2Phi/dE2 on each row's twelve entries, exact, at E.

        Args:
            E: (n,) exchanged coordinates, global frame.

        Returns:
            (m, 12, 12).
        """
        X = self._gather(E)
        xa, ya, xb, yb = X[:, 0], X[:, 1], X[:, 2], X[:, 3]
        u, w = self._vectors(X)
        a, b = self._a, self._b
        eye = np.eye(3)
        # du/d[r_x^A, r_y^A] (m, 3, 6): d(x x y) = -[y]_x dx + [x]_x dy
        du = np.concatenate([a[:, 0, None, None] * eye - a[:, 2, None, None] * skew(ya),
                             a[:, 1, None, None] * eye + a[:, 2, None, None] * skew(xa)], axis=2)
        dw = np.concatenate([b[:, 0, None, None] * eye - b[:, 2, None, None] * skew(yb),
                             b[:, 1, None, None] * eye + b[:, 2, None, None] * skew(xb)], axis=2)
        H = np.zeros((self.count, 12, 12))
        H[:, :6, 6:] = np.swapaxes(du, 1, 2) @ dw
        # d2 [(x x y) . c] / dx dy = [c]_x^T = -[c]_x
        H[:, 0:3, 3:6] = -a[:, 2, None, None] * skew(w)
        H[:, 6:9, 9:12] = -b[:, 2, None, None] * skew(u)
        return H + np.swapaxes(H, 1, 2)


class Constraints:
    """Vectorized evaluation of the nonlinear constraints of a StructureTopology whose free coordinates q map to E.

    E = T q + P p.

    The unit-length and orthogonality rows are both products c (X_a . X_b) + c0 of two slots of
    X = E.reshape(-1, 3) (unit: a = b, c = 1/2, c0 = -1/2; orthogonality: c = 1, c0 = 0); the `LinearRow`s
    (`topology.linear_rows`) are L E - c with a constant (m, n) matrix L; the joints' `AxisProduct` rows
    (`AxisProducts`) and the `SlidingRow`s between bodies (`SlidingRows`) come last. Rows are ordered unit,
    orthogonality, linear, axis, sliding (`blocks`: their slices). Every evaluation gathers E through flat index
    arrays or matrices built once (these run several times per time step on small arrays).

    The axis and sliding rows are nonlinear beyond quadratic: their velocity term and Hessian depend on E as well
    as on dE and the multipliers: `velocity_quadratic` and `hessian_sum` take E.

    Args:
        topology: the StructureTopology.
        T: (n, n_q) the map of q onto E (`StructureTopology.maps`).
    """

    def __init__(self, topology, T):
        self.unit = np.array(topology.unit_slots, dtype=int)
        self.ortho = np.array(topology.orthogonal_slots, dtype=int).reshape(-1, 2)
        self.n = topology.n_coordinates
        T = np.asarray(T, dtype=float)
        self._linear_matrix = _linear_matrix(topology.linear_rows, self.n)
        self._linear_offset = np.array([row.offset for row in topology.linear_rows], dtype=float)
        self._linear_jacobian = self._linear_matrix @ T
        self._linear_zeros = np.zeros(len(self._linear_offset))
        self.axes = AxisProducts(topology.axis_products, T, self.n)
        self.sliding = SlidingRows(topology.sliding_rows, T, self.n)
        nu, no = len(self.unit), len(self.ortho)
        sizes = {"unit": nu, "orthogonal": no, "linear": len(self._linear_offset), "axis": self.axes.count,
                 "sliding": self.sliding.count}
        ends = np.cumsum(list(sizes.values()))
        # {kind: slice of its rows}, kinds in row order
        self.blocks = {name: slice(end - size, end) for (name, size), end in zip(sizes.items(), ends)}
        self.count = int(ends[-1])
        a, b = np.concatenate([self.unit, self.ortho[:, 0]]), np.concatenate([self.unit, self.ortho[:, 1]])
        components = np.arange(3)
        flat = lambda slots: (3 * slots[:, None] + components).ravel()          # E indices of the slots
        self._ia, self._ib = flat(a), flat(b)
        self._coefficient = np.repeat([0.5, 1.0], [nu, no])
        self._velocity_coefficient = 2.0 * self._coefficient
        self._constant = np.repeat([-0.5, 0.0], [nu, no])
        self._n_free = T.shape[1]
        self._pair = np.concatenate([self._ia.reshape(-1, 3), self._ib.reshape(-1, 3)], axis=1).ravel()
        self._swapped = np.concatenate([self._ib.reshape(-1, 3), self._ia.reshape(-1, 3)], axis=1).ravel()
        # G_q row of a product: c (X_b^T T_a + X_a^T T_b), T_s the three rows of T of slot s: each gathered pair
        # value [X_a, X_b][k] times T's entries in row [T_b; T_a][k] (coordinate_map), summed by one bincount
        source, columns, weights = CoordinateMap(T).row_entries(self._swapped)
        row = source // 6
        self._jacobian_entries = (source, row * self._n_free + columns, self._coefficient[row] * weights)
        # H_i entries: (slot row, slot column, constraint) pairs, each on the three components
        rows, cols, which = (np.concatenate(v) for v in zip((a, b, np.arange(nu + no)),
                                                             (self.ortho[:, 1], self.ortho[:, 0], nu + np.arange(no))))
        self._hessian_entries = ((3 * rows[:, None] + components) * self.n + 3 * cols[:, None] + components).ravel()
        self._hessian_multiplier = np.repeat(which, 3)
        # sums of 3 and 6 entries as products with ones (np.dot: a third of the cost of sum(axis=1) on few rows)
        self._ones3, self._ones6 = np.ones(3), np.ones(6)
        self._products_only = self.count == nu + no     # no linear, axis or sliding rows: skip `_parts`

    def _parts(self, products, linear, axes, sliding):
        """The rows of each kind concatenated in row order; the callables are evaluated only for kinds with rows."""
        parts = [products]
        for kind, part in (("linear", linear), ("axis", axes), ("sliding", sliding)):
            if self.blocks[kind].stop > self.blocks[kind].start:
                parts.append(part())
        return np.concatenate(parts) if len(parts) > 1 else products

    def residual(self, E):
        """Phi(E).

        Args:
            E: (n,) exchanged coordinates, global frame.

        Returns:
            (count,) in each row's unit.
        """
        products = np.dot((E[self._ia] * E[self._ib]).reshape(-1, 3), self._ones3) * self._coefficient + self._constant
        if self._products_only:
            return products
        return self._parts(products, lambda: self._linear_matrix @ E - self._linear_offset,
                           lambda: self.axes.residual(E), lambda: self.sliding.residual(E))

    def jacobian(self, E):
        """G_q = dPhi/dq = (dPhi/dE) T at E, dense.

        Args:
            E: (n,) exchanged coordinates, global frame.

        Returns:
            (count, n_q).
        """
        source, target, weight = self._jacobian_entries
        size = len(self._coefficient) * self._n_free
        products = np.bincount(target, E[self._pair][source] * weight, size).reshape(-1, self._n_free)
        if self._products_only:
            return products
        return self._parts(products, lambda: self._linear_jacobian, lambda: self.axes.jacobian(E),
                           lambda: self.sliding.jacobian(E))

    def rate(self, E, dE):
        """dPhi/dt = (dPhi/dE) dE at E.

        Args:
            E: (n,) exchanged coordinates, global frame.
            dE: (n,) a rate of the exchanged coordinates, per s.

        Returns:
            (count,) per s.
        """
        pairs = np.dot((E[self._pair] * dE[self._swapped]).reshape(-1, 6), self._ones6) * self._coefficient
        if self._products_only:
            return pairs
        return self._parts(pairs, lambda: self._linear_matrix @ dE, lambda: self.axes.rate(E, dE),
                           lambda: self.sliding.rate(E, dE))

    def velocity_quadratic(self, dE, E):
        """The term of d2Phi/dt2 that is not G d2E/dt2, quadratic in dE.

        dE^T H_i dE for the quadratic rows, 0 for the linear rows; the axis and sliding rows' terms also depend on E.

        Args:
            dE: (n,) rates of the exchanged coordinates, per s.
            E: (n,) exchanged coordinates, global frame.

        Returns:
            (count,) per s^2.
        """
        products = self._velocity_coefficient * np.dot((dE[self._ia] * dE[self._ib]).reshape(-1, 3), self._ones3)
        if self._products_only:
            return products
        return self._parts(products, lambda: self._linear_zeros, lambda: self.axes.velocity_quadratic(dE, E),
                           lambda: self.sliding.velocity_quadratic(dE, E))

    def hessian_sum(self, multipliers, E):
        """sum_i lambda_i d2Phi_i/dE2: the constraint part of the tangent stiffness at E.

        Exact; the linear rows add nothing.

        Args:
            multipliers: (count,) lambda.
            E: (n,) exchanged coordinates, global frame.

        Returns:
            (n, n) dense.
        """
        multipliers = np.asarray(multipliers)
        values = multipliers[self._hessian_multiplier]
        out = np.bincount(self._hessian_entries, values, self.n * self.n).reshape(self.n, self.n)
        out = out.astype(float, copy=False)   # without quadratic rows (shear-deformable) bincount gives integers
        beyond = self.nonquadratic_hessian_sum(multipliers, E)
        return out if beyond is None else out + beyond

    def product_rows(self):
        """The tables of the unit and orthogonality rows Phi_i = c_i X_a . X_b + c0_i, as `residual` and `jacobian`
        use them (the compiled step, step_kernel.py): ia (k, 3), ib (k, 3) the E indices of X_a and X_b,
        c (k,), c0 (k,), pair (6 k,) the E indices of each row's gathered [X_a, X_b], and G_q's entries (source into
        pair, target row * n_q + column, weight)."""
        return (self._ia.reshape(-1, 3), self._ib.reshape(-1, 3), self._coefficient, self._constant, self._pair,
                self._jacobian_entries)

    def linear_rows(self):
        """The `LinearRow`s as `residual` and `jacobian` use them: (L (k, n), c (k,), L T (k, n_q)), Phi = L E - c."""
        return self._linear_matrix, self._linear_offset, self._linear_jacobian

    @property
    def quadratic_hessian(self):
        """(positions (k,) flat indices i n + j into (n, n), rows (k,)): the unit and orthogonality rows' part of
        `hessian_sum` holds lambda[rows] at positions, summed where positions repeat (constant H_i)."""
        return self._hessian_entries, self._hessian_multiplier

    def nonquadratic_hessian_sum(self, multipliers, E):
        """The axis and sliding rows' part of `hessian_sum`, (n, n) dense; None without such rows.

        Args:
            multipliers: (count,) lambda.
            E: (n,) exchanged coordinates, global frame.
        """
        out = None
        if self.axes.count:
            out = self.axes.hessian_sum(multipliers[self.blocks["axis"]], E)
        if self.sliding.count:
            sliding = self.sliding.hessian_sum(multipliers[self.blocks["sliding"]], E)
            out = sliding if out is None else out + sliding
        return out


def _linear_matrix(rows, n):
    """L (m, n) of the `LinearRow`s on E (n,): row i has a_k n on the three entries of each slot s_k (summed where
    slots repeat)."""
    L = np.zeros((len(rows), n))
    for i, row in enumerate(rows):
        if not all(0 <= slot < n // 3 for slot in row.slots):
            raise ValueError(f"LinearRow slots {row.slots} outside the {n // 3} slots of E")
        for slot, coefficient in zip(row.slots, row.coefficients):
            L[i, 3 * slot:3 * slot + 3] += coefficient * np.asarray(row.normal, dtype=float)
    return L
