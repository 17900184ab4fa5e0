"""Kernels on 3-vectors both units use: the unit vector of a direction, the cross product on stacks of vectors,
the cross-product matrix, a rotation about an axis (Rodrigues)."""
import numpy as np

_IDENTITY = np.eye(3)
_IDENTITY.flags.writeable = False


def unit(vector) -> np.ndarray:
    """The unit vector v / |v| of a direction given with any finite, non-zero length.

    v is first divided by its largest |component|, so that |v| neither overflows (components near 1e308) nor
    underflows (near 1e-308): the direction is the one written, whatever its scale. Every direction a scene
    gives (axes, lines, normals, the flow) is normalized here.

    Args:
        vector: (3,) finite, not all zero.

    Returns:
        (3,) of length 1 (to round-off).

    Raises:
        ValueError: a vector that is not finite, or zero.
    """
    v = np.asarray(vector, dtype=float)
    largest = float(np.max(np.abs(v))) if v.size else 0.0
    if not (np.isfinite(largest) and largest > 0):
        raise ValueError(f"no direction: {v.tolist()} is zero or not finite")
    v = v / largest
    return v / np.linalg.norm(v)


def cross(a, b):
    """Cross product on the last axis; complex-safe and much faster than np.cross on small arrays.

    Args:
        a: (..., 3).
        b: (..., 3).
    """
    same = a.shape == b.shape and a.dtype == b.dtype
    out = np.empty_like(a) if same else np.empty(np.broadcast(a, b).shape, dtype=np.result_type(a, b))
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    out[..., 0] = a1 * b2 - a2 * b1
    out[..., 1] = a2 * b0 - a0 * b2
    out[..., 2] = a0 * b1 - a1 * b0
    return out


def skew(v):
    """[v]_x of vectors v: [v]_x u = v x u.

    Args:
        v: (..., 3).

    Returns:
        (..., 3, 3).
    """
    v = np.asarray(v, dtype=float)
    out = np.zeros(v.shape[:-1] + (3, 3))
    out[..., 0, 1], out[..., 0, 2], out[..., 1, 2] = -v[..., 2], v[..., 1], -v[..., 0]
    out[..., 1, 0], out[..., 2, 0], out[..., 2, 1] = v[..., 2], -v[..., 1], v[..., 0]
    return out


def rotation_about(axis, angle):
    """Rotation matrix for `angle` about the unit vector `axis` (Rodrigues).

    Args:
        axis: (3,) unit vector.
        angle: rad.

    Returns:
        (3, 3).
    """
    k = skew(axis)
    return rodrigues(k, k @ k, np.sin(angle), np.cos(angle))


def rodrigues(k, k2, sine, cosine):
    """R = I + sin(theta) K + (1 - cos(theta)) K^2 of a unit axis.

    Args:
        k: (3, 3) K = [axis]x.
        k2: (3, 3) K^2.
        sine: sin(theta).
        cosine: cos(theta).

    Returns:
        (3, 3).
    """
    return _IDENTITY + sine * k + (1 - cosine) * k2


def perpendiculars(axis):
    """(p_1, p_2): unit vectors with (p_1, p_2, axis) a right-handed orthonormal triad.

    p_1 from the frame direction least along the axis (for the chord: p_1 = span, p_2 = -normal).

    Args:
        axis: (3,) unit vector.
    """
    axis = np.asarray(axis, dtype=float)
    k = int(np.argmin(np.abs(axis)))
    p1 = np.eye(3)[k] - axis[k] * axis
    p1 /= np.linalg.norm(p1)
    return p1, np.cross(axis, p1)
