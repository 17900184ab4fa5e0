"""Velocity induced by straight vortex segments (Otsuka et al. 2019, Eq. 19), vectorized over points x segments.

A segment runs from a to b and carries circulation Gamma (m^2/s); at a point p, with r1 = p - a,
r2 = p - b, r0 = b - a (Otsuka et al. 2019, Eq. 19; Katz & Plotkin, Low-Speed Aerodynamics, straight vortex segment):

    v = Gamma / (4 pi) * (r1 x r2) / |r1 x r2|^2 * r0 . (r1 / |r1| - r2 / |r2|)          (m/s)

A semi-infinite segment starts at a and runs to infinity along the unit vector d (the limit b -> a + s d,
s -> inf, of the same formula):

    v = Gamma / (4 pi) * (d x r1) / |d x r1|^2 * (1 + d . r1 / |r1|)

Vortex core (the cutoff). Eq. (19) is singular on the segment's line: |r1 x r2| = h |r0| with h the
distance of p from the line. We use the Scully (Kaufmann) core, replacing h^2 by h^2 + delta^2:

    |r1 x r2|^2  ->  |r1 x r2|^2 + delta^2 |r0|^2          (finite segment)
    |d x r1|^2   ->  |d x r1|^2 + delta^2                  (semi-infinite segment)

so the swirl profile becomes h / (h^2 + delta^2) (maximum 1 / (2 delta) at h = delta) and the velocity
is a smooth function of p. Why this rule:
  * a point on a segment, at its ends, or on its extension gets a finite velocity, and it is zero there,
    the principal value of a straight filament on itself (no NaN, no inf; r1 / |r1| is evaluated as 0
    when r1 = 0, and a zero-length segment induces nothing). These cases occur: Kutta-Joukowski forces
    are evaluated at segment midpoints, the collinear spanwise segments of a lattice row lie on each
    other's extensions, and free-wake corners sit on their own segments;
  * away from the line the kernel is exact to a relative O((delta / h)^2). The lattice sets delta to
    1e-3 of its smallest reference panel dimension (`lattice.CORE_FRACTION`); a collocation point is at
    least a quarter panel from every bound segment, so the bound influence changes by at most
    (4e-3)^2 = 1.6e-5 relative: the core regularizes, it does not model viscosity. A free wake that
    rolls up may later need a physical core (a larger delta, or one growing with wake age).

Array layout and speed. Unless $WINGSIM_KERNELS = numpy, `influence` runs the C kernels of biot_savart.c
(fmu_common.c_library: compiled once per machine, and into every aero FMU by its build; loaded in about a
millisecond): the same arithmetic pair by pair without temporaries, vectorized over pairs (SIMD; 5e8-7e8
point-segment pairs per second for influence matrices, 1e9 for known circulations, one thread), known
circulations summed without the (P, S) matrix, equal to the numpy kernel bit for bit in the influence matrices
and to 1e-15 in the sums. The numpy kernel is the reference: it works on one contiguous (P, S) array per
component, in place, and reduces over segments block by block (BLOCK_PAIRS pairs), so memory stays at a few MB
whatever P x S is (25-35 million pairs per second, against about 8 million for the plain (P, S, 3) expression
of `segment_velocity`, kept for tests and small cases). biot_savart.c also holds the treecode's walk
(`tree_velocity`, the far field of the free wake's convection: treecode.py).
"""
import ctypes
from pathlib import Path

import numpy as np
import scipy.sparse

from fmu_common import c_library

FOUR_PI = 4.0 * np.pi
_TINY = np.finfo(float).tiny
BLOCK_PAIRS = 1 << 16   # point-segment pairs per block in `influence` (0.5 MB per temporary, cache-friendly)
C_SOURCE = Path(__file__).with_name("biot_savart.c")    # the compiled kernels (fmu_common.c_library)
_ARRAY = ctypes.c_void_p    # a C-contiguous float64 array, passed as its data address


def _kernel(points, starts, ends, core, semi_infinite):
    """Parts of Otsuka et al. 2019, Eq. (19) with the Scully core per unit circulation: (c_x, c_y, c_z, k), each (P, S),
    with v = k c. c = r1 x r2 (= r0 x r1) or d x r1; k the scalar factor. In-place arithmetic on
    component arrays (about 1.5 times faster than the plain expression)."""
    p = np.asarray(points, dtype=float).T[:, :, None]          # (3, P, 1)
    a = np.asarray(starts, dtype=float).T[:, None, :]          # (3, 1, S)
    r0 = np.asarray(ends, dtype=float).T[:, None, :]           # unit direction d when semi-infinite
    if not semi_infinite:
        r0 = r0 - a                                            # b - a
    r1x, r1y, r1z = p[0] - a[0], p[1] - a[1], p[2] - a[2]      # (P, S) each
    cx = r0[1] * r1z
    cx -= r0[2] * r1y
    cy = r0[2] * r1x
    cy -= r0[0] * r1z
    cz = r0[0] * r1y
    cz -= r0[1] * r1x
    n1 = _norm(r1x, r1y, r1z)
    k = _dot(r0, r1x, r1y, r1z)                                # r0 . r1
    if semi_infinite:
        _safe_divide(k, n1)
        k += 1.0                                               # 1 + d . r1 / |r1|
        l2 = 1.0
    else:
        l2 = r0[0] * r0[0] + r0[1] * r0[1] + r0[2] * r0[2]     # |r0|^2, (1, S)
        # r0 . r2 = r0 . r1 - |r0|^2 (r2 = r1 - r0); exactly 0 when r2 = 0 (p at b: then r1 = r0, and
        # both sums are the same products added in the same order)
        d2 = k - l2
        _safe_divide(k, n1)                                    # r0 . r1 / |r1| (0 when r1 = 0)
        r1x -= r0[0]                                           # r2 = r1 - r0, reusing r1's arrays
        r1y -= r0[1]
        r1z -= r0[2]
        k -= _safe_divide(d2, _norm(r1x, r1y, r1z))            # r0 . (r1 / |r1| - r2 / |r2|)
    den = cx * cx
    den += cy * cy
    den += cz * cz
    den += (core * core) * l2                                  # Scully core: h^2 -> h^2 + delta^2
    den *= FOUR_PI
    np.maximum(den, _TINY, out=den)                            # zero-length segment: 0 / tiny = 0
    k /= den
    return cx, cy, cz, k


def _norm(x, y, z):
    """sqrt(x^2 + y^2 + z^2) of component arrays, in a new array (in-place arithmetic)."""
    out = x * x
    out += y * y
    out += z * z
    return np.sqrt(out, out=out)


def _dot(v, x, y, z):
    """v . (x, y, z) for a vector v given by components broadcasting against the arrays."""
    out = v[0] * x
    out += v[1] * y
    out += v[2] * z
    return out


def _safe_divide(x, y):
    """x /= y in place where y > 0, x = 0 where y = 0 (a point at a segment's end). The norms y are 0 or
    far above the smallest normal float, and x is exactly 0 where y is 0 (r0 . r1 with r1 = 0, and
    r0 . r1 - |r0|^2 with r1 = r0: see `_kernel`), so dividing by max(y, tiny) is exact."""
    x /= np.maximum(y, _TINY, out=y)
    return x


def segment_velocity(points, starts, ends, core=0.0, semi_infinite=False):
    """Velocity induced at each point by each segment of unit circulation (1 m^2/s).

    Otsuka et al. 2019, Eq. 19

    Args:
        points: (P, 3) m, global frame.
        starts: (S, 3) m, global frame.
        ends: (S, 3) m, or unit directions when `semi_infinite`.
        core: Scully core radius delta (m), see the module docstring.
        semi_infinite: whether the segments run from `starts` to infinity along `ends`.

    Returns:
        (P, S, 3) m/s.
    """
    cx, cy, cz, k = _kernel(points, starts, ends, core, semi_infinite)
    return np.stack([cx * k, cy * k, cz * k], axis=-1)


def influence(points, starts, ends, weights, core=0.0, semi_infinite=False, normals=None):
    """Velocity at points of segments whose circulations are linear in K unknowns.

    Computed in blocks of points; no Python loop over points or segments inside a block.

    Otsuka et al. 2019, Eq. 22

    Args:
        points: (P, 3) m, global frame.
        starts: (S, 3) m, global frame.
        ends: (S, 3) m, or unit directions when `semi_infinite`.
        weights: (S, K) (dense or scipy.sparse): segment circulation = weights @ unknowns, so for vortex rings it is
            the +-1 incidence of segments in rings, and for known circulations a column (S, 1).
        core: Scully core radius delta, m.
        semi_infinite: whether the segments run from `starts` to infinity along `ends`.
        normals: (P, 3) unit normals, or None.

    Returns:
        without normals (P, 3, K): v_p = result[p] @ unknowns (m/s); with normals the normal wash (P, K): n_p . v_p
        per unit unknown, the rows of an influence matrix.
    """
    points = np.asarray(points, dtype=float)
    n_points, n_segments = len(points), len(starts)
    n_unknowns = weights.shape[1]
    shape = (n_points, n_unknowns) if normals is not None else (n_points, 3, n_unknowns)
    out = np.zeros(shape)
    if n_points == 0 or n_segments == 0:
        return out
    wt = weights.T   # (K, S): reduce as (K, S) @ (S, block) so sparse weights stay on the left
    block = max(1, BLOCK_PAIRS // n_segments)
    kernels = c_kernels()
    if kernels is not None:
        return _compiled_influence(kernels, out, points, starts, ends, weights, core, semi_infinite, normals, block)
    for lo in range(0, n_points, block):
        hi = min(lo + block, n_points)
        cx, cy, cz, k = _kernel(points[lo:hi], starts, ends, core, semi_infinite)   # (B, S) each
        if normals is not None:
            n = np.asarray(normals[lo:hi], dtype=float)
            cx *= n[:, 0:1]
            cx += n[:, 1:2] * cy
            cx += n[:, 2:3] * cz
            cx *= k                                                # n . v
            out[lo:hi] = np.asarray(wt @ cx.T).T
        else:
            components = np.concatenate([cx, cy, cz]) * np.concatenate([k, k, k])    # (3 B, S): one product
            out[lo:hi] = np.asarray(wt @ components.T).T.reshape(3, hi - lo, n_unknowns).transpose(1, 0, 2)
    return out


def c_kernels():
    """The C library of biot_savart.c (fmu_common.c_library), its functions typed; None when $WINGSIM_KERNELS
    selects the numpy kernels."""
    n, real, flag = ctypes.c_long, ctypes.c_double, ctypes.c_int
    return c_library.kernels(C_SOURCE, {
        "normal_wash": (ctypes.c_int, [n, _ARRAY, _ARRAY, n, _ARRAY, _ARRAY, real, flag, _ARRAY]),
        "components": (ctypes.c_int, [n, _ARRAY, n, _ARRAY, _ARRAY, real, flag, _ARRAY]),
        "velocity_sum": (ctypes.c_int, [n, _ARRAY, n, _ARRAY, _ARRAY, _ARRAY, real, flag, _ARRAY]),
        "tree_velocity": (ctypes.c_int, [n, _ARRAY, _ARRAY, _ARRAY, n, _ARRAY, _ARRAY, real, real, _ARRAY, _ARRAY])})


def _compiled_influence(kernels, out, points, starts, ends, weights, core, semi_infinite, normals, block):
    """`influence` by the C kernels (biot_savart.c) into `out`: the same blocks and products, the pairs computed
    one at a time; known circulations (one dense column) summed without the (P, S) matrix."""
    contiguous = lambda a: np.ascontiguousarray(a, dtype=float)                                  # noqa: E731
    # the arrays whose addresses the C calls get are held in variables until the calls return
    points, starts, ends = contiguous(points), contiguous(starts), contiguous(ends)
    n_segments, core, semi_infinite = len(starts), float(core), int(bool(semi_infinite))
    segments = (n_segments, starts.ctypes.data, ends.ctypes.data)
    wt = weights.T
    if normals is None and weights.shape[1] == 1 and not scipy.sparse.issparse(weights):
        sums, gamma = np.empty((len(points), 3)), contiguous(weights)
        _check(kernels.velocity_sum(len(points), points.ctypes.data, *segments, gamma.ctypes.data, core,
                                    semi_infinite, sums.ctypes.data))
        out[:, :, 0] = sums
        return out
    normals = None if normals is None else contiguous(normals)
    for lo in range(0, len(points), block):
        hi = min(lo + block, len(points))
        at = points[lo:hi].ctypes.data
        if normals is not None:
            wash = np.empty((hi - lo, n_segments))
            _check(kernels.normal_wash(hi - lo, at, normals[lo:hi].ctypes.data, *segments, core, semi_infinite,
                                       wash.ctypes.data))
            out[lo:hi] = np.asarray(wt @ wash.T).T
        else:
            parts = np.empty((3 * (hi - lo), n_segments))
            _check(kernels.components(hi - lo, at, *segments, core, semi_infinite, parts.ctypes.data))
            out[lo:hi] = np.asarray(wt @ parts.T).T.reshape(3, hi - lo, out.shape[2]).transpose(1, 0, 2)
    return out


def _check(status):
    """MemoryError for a C kernel's status -1 (its segment table could not be allocated)."""
    if status != 0:
        raise MemoryError("the Biot-Savart C kernel could not allocate its segment table")


def induced_velocity(points, starts, ends, gamma, core=0.0, semi_infinite=False):
    """Velocity at points induced by segments of known circulations.

    Args:
        points: (P, 3) m, global frame.
        starts: (S, 3) m, global frame.
        ends: (S, 3) m, or unit directions when `semi_infinite`.
        gamma: (S,) circulations, m^2/s.
        core: Scully core radius delta, m.
        semi_infinite: whether the segments run from `starts` to infinity along `ends`.

    Returns:
        (P, 3) m/s, global frame.
    """
    gamma = np.asarray(gamma, dtype=float).reshape(-1, 1)
    return influence(points, starts, ends, gamma, core, semi_infinite)[:, :, 0]
