"""The flat-wake UVLM step (uvlm-flat) in one compiled call: the C kernel of flat_wake_step.c on buffers allocated
once per unit.

`FlatWakeStep.solve(E, dE, ...)` takes the exchanged coordinates and rates to the circulations Gamma, the panel forces
(Otsuka et al. 2019, Eqs. 22, 23, 25), the generalized force Q (Eq. 12) and the sums the resultants need, as the
numpy path of `uvlm.UVLM` does (lattice.Lattice.geometry, factorization.BoundSystem, vlm.pressure_jump_forces,
loads.resultants), which stays the reference ($WINGSIM_KERNELS=numpy; the tests compare both to 1e-12 relative).
The lattice's dense shape matrices become index gathers: each lattice point is one element's K <= 6 shape entries.

The influence matrices and their LU are reused while the lattice moves rigidly, by BoundSystem's rule: the kernel
tests the corners' distances from the first corner (`rigid.may_be_rigid`) and, when they may be rigid, returns so
that the Kabsch fit (`rigid.rigid_fit`) decides here; a folding or deforming wing takes one call per step.
"""
import ctypes
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import scipy.sparse
from scipy.linalg.lapack import dgetrf

from fmu_common import c_library

from .factorization import frame
from .rigid import rigid_fit

C_SOURCE = Path(__file__).with_name("flat_wake_step.c")    # the compiled step (fmu_common.c_library)
COMPILED_LU_PANELS = 64
"""Lattices of up to this many panels factorize in the kernel (unblocked LU: below LAPACK's call overhead there);
larger ones with LAPACK (scipy's dgetrf, blocked, in place on the kernel's buffer)."""
_LONG = np.dtype(ctypes.c_long)                            # C long: 64 bits on Linux, 32 on Windows
_SCALARS = 11      # U (3), direction (3), density, rate coefficients (3), rate order (0: none, 1, 2)

_FIELDS = [(name, ctypes.c_long) for name in ("n_slots", "n_rows", "K", "n_corners", "n_panels", "M", "N", "flat",
                                               "lapack_lu")]
_FIELDS += [(name, ctypes.c_void_p) for name in (
    "row_index", "row_value", "surface", "corner_offset", "colloc_offset", "panel_span")]
_FIELDS += [("n_segments", ctypes.c_long)] + [(name, ctypes.c_void_p) for name in (
    "seg_start", "seg_end", "seg_ptr", "seg_col", "seg_val")]
_FIELDS += [("n_legs", ctypes.c_long)] + [(name, ctypes.c_void_p) for name in ("leg_start", "leg_ptr", "leg_col",
                                                                                "leg_val")]
_FIELDS += [("n_far", ctypes.c_long), ("far_head", ctypes.c_void_p), ("far_length", ctypes.c_void_p),
            ("core", ctypes.c_double), ("tolerance", ctypes.c_double)]
_FIELDS += [(name, ctypes.c_void_p) for name in (
    "E", "dE", "scalars", "history", "points", "nodes", "normal", "span_weight", "chord_weight", "relative", "area",
    "A", "A_x", "A_y", "LU", "pivots", "distances", "reference_distances", "reference", "reference_direction",
    "has_reference", "gamma", "v_x", "v_y", "forces", "Q", "sums", "bad", "segment_table", "wash")]


class _Struct(ctypes.Structure):
    _fields_ = _FIELDS       # flat_wake_step.c's FlatWakeStep, field for field


def c_kernels():
    """The C library of flat_wake_step.c (fmu_common.c_library), typed; None when $WINGSIM_KERNELS selects the
    numpy path (or the library can be neither found nor compiled: then one warning says why)."""
    return c_library.kernels(C_SOURCE, {
        "flat_wake_step": (ctypes.c_int, [ctypes.POINTER(_Struct), ctypes.c_int])})


def _gather_rows(dense):
    """(index (rows, K) C long, value (rows, K)) of the non-zero entries of each row of `dense` (rows, n_slots), padded
    with index 0 and value 0: dense @ X = sum_k value[:, k, None] * X[index[:, k]]."""
    nonzero = dense != 0.0
    K = max(1, int(nonzero.sum(axis=1).max()))
    index, value = np.zeros((len(dense), K), dtype=_LONG), np.zeros((len(dense), K))
    for r, row in enumerate(dense):
        cols = np.flatnonzero(nonzero[r])
        index[r, :cols.size], value[r, :cols.size] = cols, row[cols]
    return index, value


def _csr(weights):
    """(ptr, col, val) of the weights (S, P) in CSR, C long indices."""
    m = scipy.sparse.csr_matrix(weights)
    m.sort_indices()
    return m.indptr.astype(_LONG), m.indices.astype(_LONG), m.data.astype(float)


class FlatWakeStep:
    """The buffers and the compiled step of one flat-wake UVLM. `builds` counts the factorizations.

    Args:
        lattice: the aero lattice (aero_fmu.lattice.Lattice).
        system: its factorization.BoundSystem with the flat wake (the segments, weights and tolerance of the
            reference path).
        kernels: the library of flat_wake_step.c (`c_kernels`).
    """

    def __init__(self, lattice, system, kernels):
        self._function = kernels.flat_wake_step
        self.lattice, self.tolerance = lattice, system.tolerance
        self.builds = 0
        nc, P, n_slots = lattice.n_corners, lattice.n_panels, lattice.n_slots
        keep = {}     # every array the struct points at, held for the object's life

        def hold(name, array, dtype=float):
            keep[name] = np.ascontiguousarray(array, dtype=dtype)
            return keep[name].ctypes.data

        rows, surface, corner_offset, collocation_offset = lattice.point_rows()
        seg_start, seg_end, weights, legs = system.segments()
        index, value = _gather_rows(rows)
        trailing = lattice.trailing_corners
        finite_legs = legs is None
        far_head = trailing.ravel() if finite_legs else np.zeros(0, dtype=int)
        far_length = (np.broadcast_to((system.wake_length * lattice.body_chords)[:, None], trailing.shape).ravel()
                      if finite_legs else np.zeros(0))
        seg_ptr, seg_col, seg_val = _csr(weights)
        leg_start, (leg_ptr, leg_col, leg_val) = ((legs[0], _csr(legs[1])) if legs is not None
                                                  else (np.zeros(0), (np.zeros(1), np.zeros(0), np.zeros(0))))
        n_rows = len(index)
        self.scalars = np.zeros(_SCALARS)
        self.history = np.zeros((2, P))
        self.E, self.dE = np.zeros(3 * n_slots), np.zeros(3 * n_slots)
        self.points = np.zeros((n_rows, 3))
        self.nodes = np.zeros((nc + far_head.size, 3))
        self.normal, self.span_weight, self.chord_weight, self.relative = (np.zeros((P, 3)) for _ in range(4))
        self.area, self.gamma, self.v_x, self.v_y = (np.zeros(P) for _ in range(4))
        self.A, self.A_x, self.A_y = (np.zeros((P, P)) for _ in range(3))
        self.LU = np.zeros((P, P), order="F")           # LAPACK's layout: dgetrf factorizes it in place
        self.lapack_lu = P > COMPILED_LU_PANELS
        self.pivots = np.zeros(P, dtype=_LONG)
        self.distances, self.reference_distances = np.zeros(nc), np.zeros(nc)
        self.reference, self.reference_direction = np.zeros((nc + 3 * P, 3)), np.zeros(3)
        self.has_reference, self.bad = np.zeros(1, dtype=_LONG), np.zeros(1, dtype=_LONG)
        self.forces, self.Q, self.sums = np.zeros((P, 3)), np.zeros(3 * n_slots), np.zeros(15)
        scratch = max(len(seg_start), len(leg_start), 1)
        self.segment_table, self.wash = np.zeros(6 * scratch), np.zeros(3 * scratch)
        buffers = {name: getattr(self, name).ctypes.data for name in (
            "E", "dE", "scalars", "history", "points", "nodes", "normal", "span_weight", "chord_weight", "relative",
            "area", "A", "A_x", "A_y", "LU", "pivots", "distances", "reference_distances", "reference",
            "reference_direction", "has_reference", "gamma", "v_x", "v_y", "forces", "Q", "sums", "bad",
            "segment_table", "wash")}
        self._struct = _Struct(
            n_slots=n_slots, n_rows=n_rows, K=index.shape[1], n_corners=nc, n_panels=P, M=lattice.M, N=lattice.N,
            flat=int(lattice.flat), lapack_lu=int(self.lapack_lu), row_index=hold("index", index, _LONG),
            row_value=hold("value", value),
            surface=hold("surface", surface), corner_offset=hold("corner_offset", corner_offset),
            colloc_offset=hold("colloc_offset", collocation_offset),
            panel_span=hold("panel_span", lattice.panel_span),
            n_segments=len(seg_start), seg_start=hold("seg_start", seg_start, _LONG),
            seg_end=hold("seg_end", seg_end, _LONG), seg_ptr=hold("seg_ptr", seg_ptr, _LONG),
            seg_col=hold("seg_col", seg_col, _LONG), seg_val=hold("seg_val", seg_val),
            n_legs=len(leg_start), leg_start=hold("leg_start", leg_start, _LONG),
            leg_ptr=hold("leg_ptr", leg_ptr, _LONG), leg_col=hold("leg_col", leg_col, _LONG),
            leg_val=hold("leg_val", leg_val), n_far=far_head.size, far_head=hold("far_head", far_head, _LONG),
            far_length=hold("far_length", far_length),
            core=lattice.core_radius, tolerance=self.tolerance, **buffers)
        self._keep = keep
        self._pointer = ctypes.pointer(self._struct)
        self._reference_frame = None

    # views of the gathered rows (Lattice numbering)
    @property
    def corners(self):
        """(n_corners, 3) m: the ring corners on the mean surface, global frame."""
        return self.nodes[:self.lattice.n_corners]

    @property
    def application(self):
        """(P, 3) m: the panel force points, global frame."""
        nc, P = self.lattice.n_corners, self.lattice.n_panels
        return self.points[nc + P:nc + 2 * P]

    def solve(self, E, dE, U, direction, density, rate):
        """One step into the buffers: gamma, forces, Q, sums (total force (3) N, first moment sum_p x_p f_p^T (3, 3)
        N m row-major, sum_p area_p n_p (3) m^2), and the geometry's views.

        Args:
            E: (n,) exchanged coordinates, m and 1, global frame.
            dE: (n,) their rates, per s.
            U: (3,) the free stream, m/s, global frame.
            direction: (3,) unit free-stream direction, global frame.
            density: kg/m^3.
            rate: None (dGamma/dt = 0), or (coefficients (3,), order 1 or 2, history (Gamma(t_{n-1}),
                Gamma(t_{n-2}))) for uvlm.circulation_rate's difference: order 1 (Gamma - G1) / c0, order 2
                Gamma c0 - G1 c1 + G2 c2.

        Raises:
            numpy.linalg.LinAlgError: a panel of zero area, or a singular influence matrix (BoundSystem's messages).
        """
        self.E[:], self.dE[:] = E, dE
        s = self.scalars
        s[0:3], s[3:6], s[6] = U, direction, density
        if rate is None:
            s[10] = 0.0
        else:
            s[7:10], s[10] = rate[0], rate[1]
            self.history[0], self.history[1] = rate[2]
        status = self._function(self._pointer, 0)
        if status == 2:
            status = self._function(self._pointer, 1 if self._reuses(direction) else 2)
        if status == 3:
            self._lapack_factorization()
            status = self._function(self._pointer, 3)
        if status == 1:
            self.builds += 1
            self._reference_frame = None
        elif status == -1:
            flat = np.flatnonzero(~(self.area > 0))
            raise np.linalg.LinAlgError(f"singular influence matrix: panel {int(self.bad[0])} (of {flat.size}) has "
                                        "zero area (degenerate wing geometry)")
        elif status == -2:
            raise np.linalg.LinAlgError("singular influence matrix: a panel has zero area or two collocation "
                                        "points coincide (degenerate wing geometry)")

    def _lapack_factorization(self):
        """LAPACK's LU of A (in LU, column-major) in place, its 0-based pivot rows into `pivots`."""
        lu, pivots, _ = dgetrf(self.LU, overwrite_a=1)       # a zero pivot is refused by the kernel, with the reason
        if not np.shares_memory(lu, self.LU):
            self.LU[...] = lu
        self.pivots[:] = pivots

    def _reuses(self, direction):
        """Whether the current geometry is the reference moved rigidly, with the wake's direction moved alike
        (factorization.BoundSystem.matrices)."""
        nc, P = self.lattice.n_corners, self.lattice.n_panels
        if self._reference_frame is None:
            ref = self.reference
            self._reference_frame = frame(SimpleNamespace(corners=ref[:nc], collocation=ref[nc:nc + P],
                                                          r_x=ref[nc + P:nc + 2 * P], r_y=ref[nc + 2 * P:]))
        p = self.points
        current = frame(SimpleNamespace(corners=self.corners, collocation=p[nc:nc + P], r_x=p[nc + 2 * P:nc + 3 * P],
                                        r_y=p[nc + 3 * P:nc + 4 * P]))
        R, _, residual = rigid_fit(self._reference_frame, current)
        return residual <= self.tolerance and np.abs(R @ self.reference_direction - direction).max() <= 1e-12

