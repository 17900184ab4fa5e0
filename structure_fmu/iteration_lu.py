"""The LU factorization of generalized-alpha's iteration matrix, banded where its sparsity allows.

The matrix of each Newton step (Peng et al. 2019, Fig. 3, in the index-3 form of Arnold & Bruls 2007) is

    A = [[S, b' G^T], [b' G, 0]],   S = beta' M_q + gamma' C_t + K_t (n_q, n_q),  G = Phi_q (m, n_q),

with b' = beta' scaling the constraint rows. A beam's elements couple only neighbouring nodes and its internal
constraints (Otsuka et al. 2019, Eq. 6) only the coordinates of one node, so A is sparse with a narrow band
once its unknowns are ordered along the beam. `IterationLU` takes the pattern of A (the model's
`iteration_pattern`: every entry that can be nonzero) and chooses, once, the order of the unknowns whose band
costs the least work (`band_order`), and:

* banded: the unknowns reordered, the band gathered from S and G into LAPACK's band storage (dgbtrf/dgbtrs,
  partial pivoting within the band: exact, like the dense LU), when the band's work is well below the dense
  LU's (BANDED_WORK_FRACTION). dgbtrf blocks only bands wider than 64 (LAPACK's ilaenv); a beam's band, set by
  a node's coupling whatever the number of elements (19-30), runs its unblocked rank-one updates (dgbtf2);
* dense: dgetrf/dgetrs on the whole matrix otherwise (or when the model gives no pattern).

Both are exact LU factorizations of the same matrix: the choice changes the time a factorization takes
(a 15-element beam: 175 unknowns, 0.12 ms dense, 0.03 ms banded), not the Newton iterates beyond round-off.
"""
from dataclasses import dataclass

import numpy as np
import scipy.sparse
from scipy.linalg.lapack import dgbtrf, dgbtrs, dgetrf, dgetrs
from scipy.sparse.csgraph import reverse_cuthill_mckee

BANDED_WORK_FRACTION = 0.4
"""Banded storage is used when n kl (kl + ku + 1), its LU's work, is below this fraction of the dense LU's n^3 / 3
(LAPACK's dense LU runs faster per operation: at 99 unknowns and kl = ku = 22 the banded LU takes 0.4 of the
dense one's time for 0.3 of its operations)."""


@dataclass(frozen=True)
class Factorization:
    """One factorized iteration matrix; `solve(b)` returns A^-1 b for b (n_q + m,). Never modified after it is
    made, so that a saved solver state may hold it by reference."""

    lu: np.ndarray
    pivots: np.ndarray
    order: np.ndarray | None      # banded: the unknowns' order (None: dense)
    lower: int
    upper: int

    def solve(self, b):
        """A^-1 b; ValueError if LAPACK's solve fails.

        Args:
            b: (n_q + m,) right-hand side.

        Returns:
            (n_q + m,) the solution.
        """
        if self.order is None:
            x, info = dgetrs(self.lu, self.pivots, b)
        else:
            x, info = dgbtrs(self.lu, self.lower, self.upper, b[self.order], self.pivots)
            x = _scatter(x, self.order)
        if info != 0:
            raise ValueError(f"LAPACK solve failed (info {info})")
        return x


def _scatter(values, order):
    out = np.empty_like(values)
    out[order] = values
    return out


def band_order(pattern, n_q):
    """The order of A's unknowns with the least banded LU work n kl (kl + ku + 1) of two: reverse Cuthill-McKee on
    the pattern, and the coordinates in their own order with each constraint row after the last coordinate it
    holds (a beam's coordinates run node by node: deploy_flexible's 158 unknowns have a band of 23 so, 30 by
    reverse Cuthill-McKee; a scissor array's joints couple distant nodes, where reverse Cuthill-McKee wins).

    Args:
        pattern: (n_q + m, n_q + m) bool, True wherever A can be nonzero, the diagonal included.
        n_q: number of generalized coordinates (the first n_q unknowns; the constraint rows follow).

    Returns:
        (order (n_q + m,) int, kl, ku): the unknowns' order and the band's lower and upper widths in it.
    """
    size = len(pattern)
    rows_last = [np.flatnonzero(pattern[i, :n_q]) for i in range(n_q, size)]
    key = np.concatenate([np.arange(n_q, dtype=float),
                          [(r.max() if r.size else n_q) + 0.5 for r in rows_last]])
    best = None
    for order in (reverse_cuthill_mckee(scipy.sparse.csr_array(pattern), symmetric_mode=False),
                  np.argsort(key, kind="stable")):
        order = np.asarray(order, dtype=np.intp)
        rows, cols = np.nonzero(pattern[np.ix_(order, order)])
        lower, upper = int(np.max(rows - cols)), int(np.max(cols - rows))
        if best is None or lower * (lower + upper + 1) < best[1] * (best[1] + best[2] + 1):
            best = (order, lower, upper)
    return best


class IterationLU:
    """Factorizes A (module docstring) for a model with n_q coordinates and m constraint rows."""

    def __init__(self, n_q, m, pattern=None):
        """How the iteration matrix A of n_q coordinates and m constraint rows is factorized.

        Args:
            n_q: number of generalized coordinates.
            m: number of constraint rows.
            pattern: (n_q + m, n_q + m) bool, True wherever A can be nonzero (None: use the dense LU).
        """
        self.n_q, self.m = n_q, m
        size = n_q + m
        self.banded = False
        if pattern is None or size < 2:
            return
        pattern = np.asarray(pattern, dtype=bool) | np.eye(size, dtype=bool)
        order, lower, upper = band_order(pattern, n_q)
        if size * max(lower, 1) * (lower + upper + 1) > BANDED_WORK_FRACTION * size ** 3 / 3:
            return
        self.banded, self.order, self.lower, self.upper = True, order, lower, upper
        # band storage (LAPACK dgbtrf, Fortran order): row kl + ku + i - j, column j of the reordered A holds
        # A[order[i], order[j]]; the first kl rows are the LU's fill-in space
        band_rows = 2 * lower + upper + 1
        self._band_shape = (band_rows, size)
        position = np.empty(size, dtype=np.intp)
        position[order] = np.arange(size)
        i, j = np.nonzero(pattern)                      # original indices of the entries that can be nonzero
        band_flat = position[j] * band_rows + lower + upper + position[i] - position[j]
        in_s = (i < n_q) & (j < n_q)
        in_g = (i >= n_q) & (j < n_q)                   # b' G (the (m, m) block is zero)
        in_gt = (j >= n_q) & (i < n_q)                  # b' G^T
        self._s = (band_flat[in_s], i[in_s] * n_q + j[in_s])
        self._g = (band_flat[in_g], (i[in_g] - n_q) * n_q + j[in_g])
        self._gt = (band_flat[in_gt], (j[in_gt] - n_q) * n_q + i[in_gt])

    def storage(self):
        """Where `factor` puts S and b' G in LAPACK's storage (Fortran order, flat), for a caller that fills it
        itself (the compiled step, step_kernel.py): (rows of the storage, then (target, source) of the
        S entries (source flat into (n_q, n_q)), of b' G's and of b' G^T's (source flat into (m, n_q))). Band storage
        ((2 kl + ku + 1) rows) when `banded`, else the dense (n_q + m) rows."""
        if self.banded:
            return self._band_shape[0], self._s, self._g, self._gt
        n, size = self.n_q, self.n_q + self.m
        i, j = np.divmod(np.arange(n * n), n)
        r, c = np.divmod(np.arange(self.m * n), n)
        return size, (j * size + i, i * n + j), (c * size + n + r, r * n + c), ((n + r) * size + c, r * n + c)

    def factor(self, S, G, row_scale):
        """The LU of A; numpy.linalg.LinAlgError if A is singular.

        Args:
            S: (n_q, n_q) the iteration matrix without the constraint rows.
            G: (m, n_q) the constraint Jacobian, or None without constraints.
            row_scale: b', the factor on the constraint rows.

        Returns:
            the Factorization.
        """
        if self.banded:
            band = np.zeros(self._band_shape, order="F")
            band_view = band.reshape(-1, order="F")          # a view: the band is Fortran-contiguous
            target, source = self._s
            band_view[target] = S.ravel()[source]
            if self.m:
                g = row_scale * G.ravel()
                band_view[self._g[0]] = g[self._g[1]]
                band_view[self._gt[0]] = g[self._gt[1]]
            lu, pivots, info = dgbtrf(band, self.lower, self.upper, overwrite_ab=True)
            if info != 0:
                raise np.linalg.LinAlgError(f"singular iteration matrix (banded LU, LAPACK info {info})")
            return Factorization(lu, pivots, self.order, self.lower, self.upper)
        n = self.n_q
        A = np.zeros((n + self.m, n + self.m))
        A[:n, :n] = S
        if self.m:
            A[:n, n:] = row_scale * G.T
            A[n:, :n] = row_scale * G
        lu, pivots, info = dgetrf(A, overwrite_a=True)
        if info != 0:
            raise np.linalg.LinAlgError(f"singular iteration matrix (LAPACK info {info})")
        return Factorization(lu, pivots, None, 0, 0)
