"""The influence matrices of the bound rings (and flat horseshoes) and their LU, reused while the
lattice moves rigidly.

For the circulations Gamma (n_panels,) of the bound rings, the velocity they induce at the collocation
points is v_p = T_p Gamma with T (n_panels, 3, n_panels) from 000 Eq. (19). The solvers need three
contractions of it, each invariant under a rigid motion of the lattice (and of the flat wake with it):

    A   = n . T      normal wash, the matrix of the no-penetration condition (000 Eq. 22)
    A_x = r_x . T    and  A_y = r_y . T: the products V . r_x, V . r_y of Eq. (23) (m/s per m^2/s)

`BoundSystem` builds them (one kernel pass) and the LU of A at a reference geometry, and reuses them
while the current geometry is the reference moved rigidly (`rigid.rigid_fit`, tolerance
RIGID_TOLERANCE times the smallest panel dimension); with a flat wake the free-stream direction must
also have moved with the lattice. A singular A (a degenerate panel) raises numpy.linalg.LinAlgError.
"""
import warnings

import numpy as np
import scipy.linalg
import scipy.sparse

from .biot_savart import influence
from .rigid import may_be_rigid, rigid_fit
from .vlm import Segments, bound_segments, horseshoe_wake, horseshoe_weights

RIGID_TOLERANCE = 1e-9   # x smallest reference panel dimension: a geometry within it reuses the matrices
DENSE_WEIGHTS = 100_000  # segment x panel entries up to which the stacked weights are kept dense


class BoundSystem:
    """Bound rings of a lattice, optionally with flat horseshoe wakes along the free stream (000 Sec. V)
    of `wake_length` chords (inf: semi-infinite legs). `builds` counts the factorizations."""

    def __init__(self, lattice, rings, flat_wake=False, wake_length=np.inf):
        self.lattice, self.rings = lattice, rings
        self.flat_wake, self.wake_length = bool(flat_wake), float(wake_length)
        self.tolerance = RIGID_TOLERANCE * float(min(lattice.panel_span.min(), lattice.panel_chord.min()))
        self.builds = 0
        self._horseshoe = horseshoe_weights(lattice) if self.flat_wake else None
        self._inner_incidence = rings.incidence[~rings.trailing] if self.flat_wake else None
        self._reference = None    # (frame points, direction, (A_x, A_y, lu))
        # the finite segments' weights stacked once in `segments` order, so a build is one kernel pass
        self._finite_weights = None

    def matrices(self, geometry, direction):
        """(A_x, A_y, lu) at `geometry` with the free-stream unit `direction` (3,) (used by a flat wake)."""
        frame = _frame(geometry)
        n = len(geometry.corners)       # the corners alone suffice for the quick test
        if self._reference is not None and may_be_rigid(self._reference[0][:n], frame[:n], self.tolerance):
            ref_frame, ref_direction, result = self._reference
            R, _, residual = rigid_fit(ref_frame, frame)
            same_wake = not self.flat_wake or np.max(np.abs(R @ ref_direction - direction)) <= 1e-12
            if residual <= self.tolerance and same_wake:
                return result
        result = self._build(geometry, direction)
        self._reference = (frame, np.array(direction, dtype=float), result)
        self.builds += 1
        return result

    def segments(self, geometry, direction):
        """The vortex systems whose circulations are linear in Gamma: the bound rings and, with the flat
        wake, the horseshoes' legs (and closing segments). The horseshoes' bound segments and the rings'
        trailing segments are both left out: they coincide and carry opposite circulations
        (`vlm.horseshoe_wake`), so their influences cancel exactly."""
        if not self.flat_wake:
            return [bound_segments(self.rings, geometry.corners)]
        rings, kept = self.rings, ~self.rings.trailing
        inner = Segments(geometry.corners[rings.start[kept]], geometry.corners[rings.end[kept]],
                         self._inner_incidence)
        wake = horseshoe_wake(self.lattice, geometry.corners, direction, self.wake_length, self._horseshoe)
        return [inner] + wake[1:]

    def _build(self, geometry, direction):
        flat = np.flatnonzero(~(geometry.area > 0))
        if flat.size:
            raise np.linalg.LinAlgError(f"singular influence matrix: panel {int(flat[0])} (of {flat.size}) has zero "
                                        "area (degenerate wing geometry)")
        core = self.lattice.core_radius
        systems = self.segments(geometry, direction)
        finite = [s for s in systems if not s.semi_infinite]
        if self._finite_weights is None:
            weights = scipy.sparse.vstack([s.weights for s in finite], format="csr")
            # small lattices (000's M = 2, N = 7: 118 x 28) reduce faster dense, large ones stay sparse
            self._finite_weights = weights.toarray() if weights.shape[0] * weights.shape[1] <= DENSE_WEIGHTS else weights
        T = influence(geometry.collocation, np.concatenate([s.starts for s in finite]),
                      np.concatenate([s.ends for s in finite]), self._finite_weights, core)     # (P, 3, n)
        for s in systems:
            if s.semi_infinite:
                T += influence(geometry.collocation, s.starts, s.ends, s.weights, core, True)
        A, A_x, A_y = np.einsum("dpc,pck->dpk", np.stack([geometry.normal, geometry.r_x, geometry.r_y]), T)
        with warnings.catch_warnings():                 # a zero pivot is reported below, with the reason
            warnings.simplefilter("ignore", scipy.linalg.LinAlgWarning)
            lu = scipy.linalg.lu_factor(A, check_finite=False)
        pivots = np.abs(np.diag(lu[0]))
        if not np.all(np.isfinite(pivots)) or pivots.min() <= 1e-13 * max(pivots.max(), 1e-300):
            raise np.linalg.LinAlgError("singular influence matrix: a panel has zero area or two collocation "
                                        "points coincide (degenerate wing geometry)")
        return A_x, A_y, lu


def _frame(geometry):
    """Points that move rigidly iff the lattice does: corners, collocation points, and the collocation
    points shifted by the tangents r_x, r_y (so a stretch or shear of the tangents counts)."""
    c = geometry.collocation
    return np.concatenate([geometry.corners, c, c + geometry.r_x, c + geometry.r_y])
