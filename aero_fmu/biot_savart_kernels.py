"""Compiled Biot-Savart kernels (numba): the segment velocity of biot_savart.py (Otsuka et al. 2019, Eq. 19, with
the Scully core), pair by pair without (P, S) temporaries. Loaded by fmu_common.compiled.load, never imported
directly (its cache must live in a stable folder); biot_savart.py's numpy kernel is the reference.

Each pair follows biot_savart._kernel operation for operation: r1 = p - a, r0 = b - a (or the unit direction d of
a semi-infinite segment, with |r0|^2 taken as 1), c = r0 x r1, k = r0 . (r1 / |r1| - r2 / |r2|) (or
1 + d . r1 / |r1|), divided by 4 pi (|c|^2 + delta^2 |r0|^2), a division by a zero norm giving 0 (a point at a
segment's end, a zero-length segment).

Layout (why it is fast). The innermost loop of every kernel runs over independent pairs reading contiguous
one-dimensional arrays from index 0 (the points of a block, or the segments in the structure-of-arrays of
`_segments`), so that LLVM vectorizes it (SIMD over pairs: square roots and divisions several at a time) with
IEEE arithmetic unchanged: no fast-math, no reassociation, each pair's operations and each point's sum over
segments in the same order as one pair at a time. error_model="numpy" keeps numba's Python division check (a
branch per division) out of those loops; no division here can be by zero (the divisors are at least TINY).
"""
import math

import numpy as np
from numba import njit

FOUR_PI = 4.0 * math.pi
TINY = np.finfo(np.float64).tiny
POINT_BLOCK = 256
"""Points per block in `velocity_sum`: their coordinates and sums (6 x 2 kB) stay in the L1 cache while every
segment passes over them."""


@njit(cache=True, inline="always", error_model="numpy")
def _pair(r1x, r1y, r1z, r0x, r0y, r0z, l2, core2, semi_infinite):
    """(c_x, c_y, c_z, k) of one pair, v = k c per unit circulation: r1 = p - a, r0 = b - a (or d), l2 = |r0|^2
    (1 for a semi-infinite segment), core2 = delta^2."""
    cx = r0y * r1z - r0z * r1y
    cy = r0z * r1x - r0x * r1z
    cz = r0x * r1y - r0y * r1x
    n1 = math.sqrt(r1x * r1x + r1y * r1y + r1z * r1z)
    k = r0x * r1x + r0y * r1y + r0z * r1z
    if semi_infinite:
        k = k / max(n1, TINY) + 1.0
    else:
        d2 = k - l2                                   # r0 . r2, exactly 0 when r2 = 0 (biot_savart._kernel)
        k = k / max(n1, TINY)
        r2x, r2y, r2z = r1x - r0x, r1y - r0y, r1z - r0z
        n2 = math.sqrt(r2x * r2x + r2y * r2y + r2z * r2z)
        k -= d2 / max(n2, TINY)
    den = (cx * cx + cy * cy + cz * cz + core2 * l2) * FOUR_PI
    k /= max(den, TINY)
    return cx, cy, cz, k


@njit(cache=True, error_model="numpy")
def _segments(starts, ends, semi_infinite):
    """Structure-of-arrays of the segments, (7, S): a_x, a_y, a_z, r0_x, r0_y, r0_z (b - a, or the direction d
    of a semi-infinite segment) and |r0|^2 (1 when semi-infinite)."""
    n_segments = starts.shape[0]
    out = np.empty((7, n_segments))
    for s in range(n_segments):
        for i in range(3):
            out[i, s] = starts[s, i]
            out[3 + i, s] = ends[s, i] if semi_infinite else ends[s, i] - starts[s, i]
        out[6, s] = 1.0 if semi_infinite else out[3, s] * out[3, s] + out[4, s] * out[4, s] + out[5, s] * out[5, s]
    return out


@njit(cache=True, error_model="numpy")
def normal_wash(points, normals, starts, ends, core, semi_infinite):
    """n_p . v_ps per unit circulation (m/s per m^2/s), (P, S): points, normals (P, 3), starts, ends (S, 3)."""
    n_points, n_segments = points.shape[0], starts.shape[0]
    seg = _segments(starts, ends, semi_infinite)
    ax, ay, az, r0x, r0y, r0z, l2 = seg[0], seg[1], seg[2], seg[3], seg[4], seg[5], seg[6]
    out = np.empty((n_points, n_segments))
    core2 = core * core
    for p in range(n_points):
        px, py, pz = points[p, 0], points[p, 1], points[p, 2]
        nx, ny, nz = normals[p, 0], normals[p, 1], normals[p, 2]
        row = out[p]
        for s in range(n_segments):
            cx, cy, cz, k = _pair(px - ax[s], py - ay[s], pz - az[s], r0x[s], r0y[s], r0z[s], l2[s], core2,
                                  semi_infinite)
            row[s] = (cx * nx + ny * cy + nz * cz) * k
    return out


@njit(cache=True, error_model="numpy")
def components(points, starts, ends, core, semi_infinite):
    """v_ps per unit circulation, (3, P, S): the x, y, z components of every pair (m/s per m^2/s)."""
    n_points, n_segments = points.shape[0], starts.shape[0]
    seg = _segments(starts, ends, semi_infinite)
    ax, ay, az, r0x, r0y, r0z, l2 = seg[0], seg[1], seg[2], seg[3], seg[4], seg[5], seg[6]
    out = np.empty((3, n_points, n_segments))
    core2 = core * core
    for p in range(n_points):
        px, py, pz = points[p, 0], points[p, 1], points[p, 2]
        ox, oy, oz = out[0, p], out[1, p], out[2, p]
        for s in range(n_segments):
            cx, cy, cz, k = _pair(px - ax[s], py - ay[s], pz - az[s], r0x[s], r0y[s], r0z[s], l2[s], core2,
                                  semi_infinite)
            ox[s] = cx * k
            oy[s] = cy * k
            oz[s] = cz * k
    return out


@njit(cache=True, error_model="numpy")
def velocity_sum(points, starts, ends, gamma, core, semi_infinite):
    """sum_s gamma_s v_ps (m/s), (P, 3): the velocity of segments of known circulations gamma (S,) m^2/s.
    Blocks of POINT_BLOCK points; each segment is added to every point of a block in turn, so a point's sum runs
    over the segments in order."""
    n_points, n_segments = points.shape[0], starts.shape[0]
    xyz = np.ascontiguousarray(points.T)                           # (3, P)
    sums = np.zeros((3, n_points))
    core2 = core * core
    for lo in range(0, n_points, POINT_BLOCK):
        hi = min(lo + POINT_BLOCK, n_points)
        px, py, pz = xyz[0, lo:hi], xyz[1, lo:hi], xyz[2, lo:hi]
        vx, vy, vz = sums[0, lo:hi], sums[1, lo:hi], sums[2, lo:hi]
        for s in range(n_segments):
            g = gamma[s]
            if g == 0.0:
                continue
            ax, ay, az = starts[s, 0], starts[s, 1], starts[s, 2]
            if semi_infinite:
                r0x, r0y, r0z, l2 = ends[s, 0], ends[s, 1], ends[s, 2], 1.0
            else:
                r0x, r0y, r0z = ends[s, 0] - ax, ends[s, 1] - ay, ends[s, 2] - az
                l2 = r0x * r0x + r0y * r0y + r0z * r0z
            for i in range(hi - lo):
                cx, cy, cz, k = _pair(px[i] - ax, py[i] - ay, pz[i] - az, r0x, r0y, r0z, l2, core2, semi_infinite)
                k *= g
                vx[i] += cx * k
                vy[i] += cy * k
                vz[i] += cz * k
    return np.ascontiguousarray(sums.T)
