"""Kernels on 3-vectors both units use: the cross product on stacks of vectors, a rotation about an axis."""
import numpy as np


def cross(a, b):
    """Cross product on the last axis; complex-safe and much faster than np.cross on small arrays."""
    same = a.shape == b.shape and a.dtype == b.dtype
    out = np.empty_like(a) if same else np.empty(np.broadcast(a, b).shape, dtype=np.result_type(a, b))
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    out[..., 0] = a1 * b2 - a2 * b1
    out[..., 1] = a2 * b0 - a0 * b2
    out[..., 2] = a0 * b1 - a1 * b0
    return out


def rotation_about(axis, angle):
    """Rotation matrix for `angle` (rad) about the unit vector `axis` (Rodrigues)."""
    a = np.asarray(axis, dtype=float)
    k = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    return np.eye(3) + np.sin(angle) * k + (1 - np.cos(angle)) * (k @ k)
