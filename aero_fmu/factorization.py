"""The influence matrices of the bound rings (and flat horseshoes) and their LU, reused while the
lattice moves rigidly.

For the circulations Gamma (n_panels,) of the bound rings, the velocity they induce at the collocation
points is v_p = T_p Gamma with T (n_panels, 3, n_panels) from Otsuka et al. 2019, Eq. (19). The solvers need three
contractions of it, each invariant under a rigid motion of the lattice (and of the flat wake with it):

    A   = n . T      normal wash, the matrix of the no-penetration condition (Otsuka et al. 2019, Eq. 22)
    A_x = w_s . T    and  A_y = w_c . T, w_s, w_c the panels' Geometry.span_weight, chord_weight: the products
                     of Eq. (23) as aero_fmu.vlm.pressure_jump_forces writes them (m^2/s per m^2/s)

`BoundSystem` builds them (one kernel pass) and the LU of A at a reference geometry, and reuses them
while the current geometry is the reference moved rigidly (`rigid.rigid_fit`, tolerance
RIGID_TOLERANCE times the smallest panel dimension); with a flat wake the free-stream direction must
also have moved with the lattice. A singular A (a degenerate panel) raises numpy.linalg.LinAlgError.
"""
import numpy as np
import scipy.sparse
from scipy.linalg.lapack import dgetrf

from .biot_savart import influence
from .rigid import distances_from_first, may_be_rigid, rigid_fit
from .vlm import horseshoe_weights, leg_ends

RIGID_TOLERANCE = 1e-9   # x smallest reference panel dimension: a geometry within it reuses the matrices
DENSE_WEIGHTS = 100_000  # segment x panel entries up to which the stacked weights are kept dense


class BoundSystem:
    """Bound rings of a lattice, optionally with flat horseshoe wakes along the free stream.

    Otsuka et al. 2019, Sec. V. `builds` counts the factorizations.

    Args:
        lattice: the aero lattice (aero_fmu.lattice.Lattice).
        rings: its RingSegments (aero_fmu.vlm).
        flat_wake: whether horseshoe legs trail from the trailing edge.
        wake_length: their length, chords (inf: semi-infinite legs).
    """

    def __init__(self, lattice, rings, flat_wake=False, wake_length=np.inf):
        self.lattice, self.rings = lattice, rings
        self.flat_wake, self.wake_length = bool(flat_wake), float(wake_length)
        self.tolerance = RIGID_TOLERANCE * float(min(lattice.panel_span.min(), lattice.panel_chord.min()))
        self.builds = 0
        self._reference = None    # (geometry, corner distances from the first, direction, (A_x, A_y, lu))
        self._reference_frame = None   # `frame` of the reference geometry, built at the first rigid check
        # The finite segments as start/end indices into the nodes (the corners, then the far ends of finite
        # horseshoe legs) and their stacked weights, so that a build is two gathers and one kernel pass.
        # With the flat wake the segments are those of `vlm.horseshoe_wake` except its bound segments, which
        # are left out with the rings' trailing segments: they coincide and carry opposite circulations, so
        # their influences cancel exactly.
        kept = ~rings.trailing if self.flat_wake else np.ones(len(rings.start), dtype=bool)
        starts, ends, weights = [rings.start[kept]], [rings.end[kept]], [rings.incidence[kept]]
        self._semi_infinite_legs = None
        if self.flat_wake:
            legs, span, _ = horseshoe_weights(lattice)
            trailing = lattice.trailing_corners                                  # (B, N + 1)
            if np.isinf(self.wake_length):
                self._semi_infinite_legs = (trailing.ravel(), legs)
            else:
                far = lattice.n_corners + np.arange(trailing.size).reshape(trailing.shape)
                starts += [trailing.ravel(), far[:, :-1].ravel()]
                ends += [far.ravel(), far[:, 1:].ravel()]
                weights += [legs, span]
        self._start, self._end = np.concatenate(starts), np.concatenate(ends)
        stacked = scipy.sparse.vstack(weights, format="csr")
        # small lattices (Otsuka et al. 2019's M = 2, N = 7: 90 x 28) reduce faster dense, large ones stay sparse
        self._weights = stacked.toarray() if stacked.shape[0] * stacked.shape[1] <= DENSE_WEIGHTS else stacked

    def segments(self):
        """The vortex segments of a build, for a kernel that builds the same matrices (aero_fmu.flat_wake_step).

        Returns:
            (start, end, weights, legs): start, end (S,) node indices of the finite segments (the corners, then the
            far ends of finite horseshoe legs, `vlm.leg_ends` order); weights (S, n_panels), dense or sparse, the
            segment circulations per unit Gamma; legs, None or (start (L,) corner indices, weights (L, n_panels)) of
            semi-infinite legs along the free stream.
        """
        return self._start, self._end, self._weights, self._semi_infinite_legs

    def matrices(self, geometry, direction):
        """The influence matrices and the factorization at `geometry`.

        Args:
            geometry: the lattice's Geometry.
            direction: (3,) unit free-stream direction (used by a flat wake), global frame.

        Returns:
            (A_x, A_y, lu).
        """
        distances = distances_from_first(geometry.corners)
        if self._reference is not None and may_be_rigid(self._reference[1], distances, self.tolerance):
            ref_geometry, _, ref_direction, result = self._reference
            if self._reference_frame is None:
                self._reference_frame = frame(ref_geometry)
            R, _, residual = rigid_fit(self._reference_frame, frame(geometry))
            same_wake = not self.flat_wake or np.abs(R @ ref_direction - direction).max() <= 1e-12
            if residual <= self.tolerance and same_wake:
                return result
        result = self._build(geometry, direction)
        self._reference = (geometry, distances, np.array(direction, dtype=float), result)
        self._reference_frame = None
        self.builds += 1
        return result

    def _build(self, geometry, direction):
        if not geometry.area.min() > 0:       # also false for a NaN area
            flat = np.flatnonzero(~(geometry.area > 0))
            raise np.linalg.LinAlgError(f"singular influence matrix: panel {int(flat[0])} (of {flat.size}) has zero "
                                        "area (degenerate wing geometry)")
        core, corners = self.lattice.core_radius, geometry.corners
        nodes = corners
        if self.flat_wake and self._semi_infinite_legs is None:      # the legs' far ends, along the free stream
            far = leg_ends(self.lattice, corners[self.lattice.trailing_corners], direction, self.wake_length)
            nodes = np.concatenate([corners, far.reshape(-1, 3)])
        T = influence(geometry.collocation, nodes[self._start], nodes[self._end], self._weights, core)   # (P, 3, n)
        if self._semi_infinite_legs is not None:
            legs_start, legs = self._semi_infinite_legs
            T += influence(geometry.collocation, corners[legs_start], np.broadcast_to(direction, (len(legs_start), 3)),
                           legs, core, True)
        # A = n . T, A_x = span_weight . T, A_y = chord_weight . T in one batched product over the collocation
        # points (aero_fmu.vlm.pressure_jump_forces)
        directions = np.concatenate([geometry.normal, geometry.span_weight, geometry.chord_weight],
                                    axis=1).reshape(-1, 3, 3)
        products = directions @ T                                                               # (P, 3, n)
        A, A_x, A_y = products[:, 0], products[:, 1], products[:, 2]
        lu, pivot_rows, _ = dgetrf(A)         # LAPACK directly: a zero pivot is reported below, with the reason
        pivots = np.abs(lu.diagonal())
        if not pivots.min() > 1e-13 * pivots.max():       # also false for NaN or inf pivots
            raise np.linalg.LinAlgError("singular influence matrix: a panel has zero area or two collocation "
                                        "points coincide (degenerate wing geometry)")
        return A_x, A_y, (lu, pivot_rows)


def frame(geometry):
    """Points that move rigidly iff the lattice does: corners, collocation points, and the collocation
    points shifted by the tangents r_x, r_y (so a stretch or shear of the tangents counts).

    Args:
        geometry: anything with the Geometry's corners (n_corners, 3), collocation, r_x, r_y (n_panels, 3).

    Returns:
        (n_corners + 3 n_panels, 3) m, global frame.
    """
    c = geometry.collocation
    return np.concatenate([geometry.corners, c, c + geometry.r_x, c + geometry.r_y])
