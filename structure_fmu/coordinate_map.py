"""The coordinate map E = T q + P p(t) (Otsuka et al. 2019, Eq. 5) by T's nonzero entries: gathers and scatters.

T (n, n_q) is constant and nearly a selection (structure_fmu.topology): a slot of E is one free vector (kron I_3,
coefficient 1), a free scalar times its direction (a slider), or prescribed (a zero row of T); a slot shared by two
nodes repeats a column. `CoordinateMap` keeps only T's nonzero entries (row, column, weight) and applies

    E = T q (+ offset),   T^T F,   T^T X T,

the last for an X (n, n) given by its entries at known flat positions (the element blocks, the constraint Hessian's
entries, a hinge's or a damped body's block): `assembly(positions)` expands each position i n + j into the reduced
entries (c_a, c_b) of every pair of T's entries a in row i, b in row j, with weight T[i, c_a] T[j, c_b], once; the
tangent is then one np.bincount into the (n_q, n_q) matrix, the dense (n, n) matrix never formed.

Below DENSE_ENTRIES entries of T, E = T q and T^T F stay dense products: a numpy gather costs about as many
instructions as a matrix-vector product of 20000 entries (its call overhead), so a small T (rigid bodies, a
spin-up beam) is applied faster as it is; above, the gathers' cost stays flat while the product's grows with
n n_q. The tangent and the constraint Jacobian are assembled through the entries at every size.

Exact: T q with one entry per row is the same product as the dense one bit for bit; sums over repeated columns
(T^T F, T^T X T) are taken in another order than the dense products', equal to round-off.
"""
from dataclasses import dataclass

import numpy as np

DENSE_ENTRIES = 16384
"""T with at most this many entries (n n_q) is applied to vectors as a dense product (module docstring); measured
with valgrind: T q by gathers costs 6e3 more instructions than the product at 90 x 81 and 144 x 129, T^T F by a
gather 3e3 more at 90 x 81 and 1e4 fewer at 144 x 129; at 300 x 270 the gathers save 2e4 and 6e4."""


@dataclass(frozen=True)
class Assembly:
    """Where entries of an (n, n) matrix X go in T^T X T (n_q, n_q): the reduced matrix is
    bincount(target, values[source] * weight, n_q^2) for X's values at the positions the assembly was made for."""

    source: np.ndarray      # (k,) int: index into the values at the given positions
    target: np.ndarray      # (k,) int: flat index into the (n_q, n_q) matrix
    weight: np.ndarray      # (k,) T[i, c_a] T[j, c_b]

    @staticmethod
    def joined(parts, sizes):
        """One Assembly for the values of `parts` concatenated in order.

        Args:
            parts: the Assemblies, each of its own values.
            sizes: the number of values of each part.
        """
        offsets = np.concatenate([[0], np.cumsum(sizes)[:-1]]).astype(np.intp)
        return Assembly(np.concatenate([p.source + o for p, o in zip(parts, offsets)]).astype(np.intp),
                        np.concatenate([p.target for p in parts]).astype(np.intp),
                        np.concatenate([p.weight for p in parts]))


class CoordinateMap:
    """T (n, n_q) by its nonzero entries, applied by gathers and scatters (module docstring).

    Args:
        T: (n, n_q) the constant coordinate map dE/dq.
    """

    def __init__(self, T):
        T = np.asarray(T, dtype=float)
        self.n, self.n_q = T.shape
        rows, cols = np.nonzero(T)                      # row-major: grouped by row
        self._rows, self._cols, self._weights = rows, cols, T[rows, cols]
        self._count = np.bincount(rows, minlength=self.n)           # entries per row of T
        self._start = np.concatenate([[0], np.cumsum(self._count)[:-1]]).astype(np.intp)
        # one entry per row: T q is a gather (bit for bit the dense product); coefficient 1 and each column once
        # (no shared slot, no slider): T^T F is a gather too
        self._selection = bool(self._count.max(initial=0) <= 1)
        self._unit = self._selection and bool(np.all(self._weights == 1.0))
        self._one_to_one = self._unit and len(np.unique(cols)) == len(cols) == self.n_q
        self._dense = None          # (T's rows' block, its Assembly), made when `congruence` is first called
        self._small = T if T.size <= DENSE_ENTRIES else None    # applied as a dense product (DENSE_ENTRIES)

    def apply(self, q, offset=None):
        """T q + offset, (n,).

        Args:
            q: (n_q,) generalized coordinates (or their rates, accelerations).
            offset: (n,) added (P p), or None.
        """
        if self._small is not None:
            return np.dot(self._small, q) if offset is None else np.dot(self._small, q) + offset
        if not self._selection:
            values = np.bincount(self._rows, self._weights * q[self._cols], self.n)
            return values if offset is None else values + offset
        E = np.zeros(self.n) if offset is None else offset.copy()
        E[self._rows] += q[self._cols] if self._unit else self._weights * q[self._cols]
        return E

    def transpose_apply(self, F):
        """T^T F, (n_q,).

        Args:
            F: (n,) a generalized force on E.
        """
        if self._small is not None:
            return np.dot(self._small.T, F)
        if self._one_to_one:
            out = np.empty(self.n_q)
            out[self._cols] = F[self._rows]
            return out
        return np.bincount(self._cols, self._weights * F[self._rows], self.n_q)

    def csr(self):
        """T by rows: (start (n + 1,), columns (k,), weights (k,)), row i's entries at start[i]:start[i + 1]."""
        return np.concatenate([self._start, [len(self._cols)]]).astype(np.intp), self._cols, self._weights

    def row_entries(self, rows):
        """T's entries in the given rows of E, in the order of `rows`: (source (k,) the position in `rows`,
        column (k,), weight (k,)).

        Args:
            rows: int array of indices into E (read flat).
        """
        rows = np.asarray(rows, dtype=np.intp).ravel()
        counts = self._count[rows]
        source = np.repeat(np.arange(len(rows)), counts)
        within = np.arange(counts.sum()) - np.repeat(np.cumsum(counts) - counts, counts)
        entry = self._start[rows][source] + within
        return source, self._cols[entry], self._weights[entry]

    def assembly(self, positions):
        """The Assembly of the values of an (n, n) matrix at `positions` (flat indices i n + j, any shape, read
        flat) into T^T X T.

        Args:
            positions: int array of flat indices into (n, n).
        """
        positions = np.asarray(positions, dtype=np.intp).ravel()
        i, j = np.divmod(positions, self.n)
        ci, cj = self._count[i], self._count[j]
        index = np.arange(len(positions))
        sources, targets, weights = [], [], []
        for a in range(self._count.max(initial=0)):
            for b in range(self._count.max(initial=0)):
                kept = (a < ci) & (b < cj)
                ea, eb = self._start[i[kept]] + a, self._start[j[kept]] + b
                sources.append(index[kept])
                targets.append(self._cols[ea] * self.n_q + self._cols[eb])
                weights.append(self._weights[ea] * self._weights[eb])
        if not sources:
            return Assembly(np.zeros(0, np.intp), np.zeros(0, np.intp), np.zeros(0))
        return Assembly(*(np.concatenate(v) for v in (sources, targets, weights)))

    def reduce(self, assembly, values):
        """T^T X T (n_q, n_q) for X's values at the assembly's positions.

        Args:
            assembly: the Assembly.
            values: the values, read flat, in the order of the positions.
        """
        flat = np.bincount(assembly.target, values.ravel()[assembly.source] * assembly.weight, self.n_q * self.n_q)
        return flat.reshape(self.n_q, self.n_q)

    def congruence(self, X):
        """T^T X T (n_q, n_q) for a dense X (n, n): the constraint Hessians of axis and sliding rows.

        Args:
            X: (n, n).
        """
        if self._dense is None:
            rows = np.unique(self._rows)            # the rows of E that T reaches
            self._dense = (np.ix_(rows, rows), self.assembly(rows[:, None] * self.n + rows[None, :]))
        block, entries = self._dense
        return self.reduce(entries, X[block])
