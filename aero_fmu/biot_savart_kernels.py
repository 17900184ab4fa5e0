"""Compiled Biot-Savart kernels (numba): the segment velocity of biot_savart.py (Otsuka et al. 2019, Eq. 19, with
the Scully core), one point-segment pair at a time, no temporaries. Loaded by fmu_common.compiled.load, never
imported directly (its cache must live in a stable folder); biot_savart.py's numpy kernel is the reference.

Each pair follows biot_savart._kernel operation for operation: r1 = p - a, r0 = b - a (or the unit direction d of
a semi-infinite segment), c = r0 x r1, k = r0 . (r1 / |r1| - r2 / |r2|) (or 1 + d . r1 / |r1|), divided by
4 pi (|c|^2 + delta^2 |r0|^2), a division by a zero norm giving 0 (a point at a segment's end).
"""
import math

import numpy as np
from numba import njit

FOUR_PI = 4.0 * math.pi
TINY = np.finfo(np.float64).tiny


@njit(cache=True, inline="always")
def _pair(px, py, pz, ax, ay, az, bx, by, bz, core2, semi_infinite):
    """(c_x, c_y, c_z, k) of one point-segment pair: v = k c per unit circulation."""
    r1x, r1y, r1z = px - ax, py - ay, pz - az
    if semi_infinite:
        r0x, r0y, r0z = bx, by, bz
    else:
        r0x, r0y, r0z = bx - ax, by - ay, bz - az
    cx = r0y * r1z - r0z * r1y
    cy = r0z * r1x - r0x * r1z
    cz = r0x * r1y - r0y * r1x
    n1 = math.sqrt(r1x * r1x + r1y * r1y + r1z * r1z)
    k = r0x * r1x + r0y * r1y + r0z * r1z
    if semi_infinite:
        k = k / max(n1, TINY) + 1.0
        l2 = 1.0
    else:
        l2 = r0x * r0x + r0y * r0y + r0z * r0z
        d2 = k - l2
        k = k / max(n1, TINY)
        r2x, r2y, r2z = r1x - r0x, r1y - r0y, r1z - r0z
        n2 = math.sqrt(r2x * r2x + r2y * r2y + r2z * r2z)
        k -= d2 / max(n2, TINY)
    den = (cx * cx + cy * cy + cz * cz + core2 * l2) * FOUR_PI
    k /= max(den, TINY)
    return cx, cy, cz, k


@njit(cache=True)
def normal_wash(points, normals, starts, ends, core, semi_infinite):
    """n_p . v_ps per unit circulation (m/s per m^2/s), (P, S): points, normals (P, 3), starts, ends (S, 3)."""
    n_points, n_segments = points.shape[0], starts.shape[0]
    out = np.empty((n_points, n_segments))
    core2 = core * core
    for p in range(n_points):
        px, py, pz = points[p, 0], points[p, 1], points[p, 2]
        nx, ny, nz = normals[p, 0], normals[p, 1], normals[p, 2]
        for s in range(n_segments):
            cx, cy, cz, k = _pair(px, py, pz, starts[s, 0], starts[s, 1], starts[s, 2], ends[s, 0], ends[s, 1],
                                  ends[s, 2], core2, semi_infinite)
            out[p, s] = (cx * nx + ny * cy + nz * cz) * k
    return out


@njit(cache=True)
def components(points, starts, ends, core, semi_infinite):
    """v_ps per unit circulation, (3, P, S): the x, y, z components of every pair (m/s per m^2/s)."""
    n_points, n_segments = points.shape[0], starts.shape[0]
    out = np.empty((3, n_points, n_segments))
    core2 = core * core
    for p in range(n_points):
        px, py, pz = points[p, 0], points[p, 1], points[p, 2]
        for s in range(n_segments):
            cx, cy, cz, k = _pair(px, py, pz, starts[s, 0], starts[s, 1], starts[s, 2], ends[s, 0], ends[s, 1],
                                  ends[s, 2], core2, semi_infinite)
            out[0, p, s] = cx * k
            out[1, p, s] = cy * k
            out[2, p, s] = cz * k
    return out


@njit(cache=True)
def velocity_sum(points, starts, ends, gamma, core, semi_infinite):
    """sum_s gamma_s v_ps (m/s), (P, 3): the velocity of segments of known circulations gamma (S,) m^2/s."""
    n_points, n_segments = points.shape[0], starts.shape[0]
    out = np.zeros((n_points, 3))
    core2 = core * core
    for p in range(n_points):
        px, py, pz = points[p, 0], points[p, 1], points[p, 2]
        vx = vy = vz = 0.0
        for s in range(n_segments):
            if gamma[s] == 0.0:
                continue
            cx, cy, cz, k = _pair(px, py, pz, starts[s, 0], starts[s, 1], starts[s, 2], ends[s, 0], ends[s, 1],
                                  ends[s, 2], core2, semi_infinite)
            k *= gamma[s]
            vx += cx * k
            vy += cy * k
            vz += cz * k
        out[p, 0], out[p, 1], out[p, 2] = vx, vy, vz
    return out
