"""Does a point set move rigidly? (Kabsch fit), so that influence matrices can be reused.

An influence coefficient n_p . v_q(r_p) (Otsuka et al. 2019, Eqs. 19, 22) depends only on the relative positions of
points and segments and on the normals, so it does not change when the whole lattice translates and
rotates. The aero solvers keep their matrices (and the LU) of a reference geometry and reuse them while
the current geometry is that reference moved rigidly: a heaving or pitching rigid wing factorizes once.
"""
import numpy as np


def rigid_fit(reference, current):
    """The rigid motion x -> R x + t that best maps `reference` onto `current` in the least-squares sense.

    Kabsch: SVD of the 3 x 3 covariance, with the reflection removed.

    Args:
        reference: (n, 3) points, m, global frame.
        current: (n, 3) points, m, global frame.

    Returns:
        (R (3, 3), t (3,) m, residual = max_i |R reference_i + t - current_i| m).
    """
    reference = np.asarray(reference, dtype=float)
    current = np.asarray(current, dtype=float)
    c0, c1 = reference.mean(axis=0), current.mean(axis=0)
    a, b = reference - c0, current - c1
    u, _, vt = np.linalg.svd(a.T @ b)
    d = np.sign(np.linalg.det(vt.T @ u.T)) or 1.0
    R = vt.T @ np.diag([1.0, 1.0, d]) @ u.T
    t = c1 - R @ c0
    residual = float(np.max(np.abs(a @ R.T - b))) if len(a) else 0.0
    return R, t, residual


def distances_from_first(points):
    """|p_i - p_0| (n,) m: what any rigid motion of the points keeps (`may_be_rigid`).

    Args:
        points: (n, 3) m, global frame.
    """
    offsets = points - points[0]
    return np.sqrt(np.einsum("ij,ij->i", offsets, offsets))


def may_be_rigid(reference_distances, distances, tolerance):
    """False when no rigid motion can map the reference points onto the current ones within `tolerance`.

    A distance from the first point changed by more than 2 tolerance. A cheap necessary test for geometries that
    deform, where `rigid_fit` would fail anyway.

    Args:
        reference_distances: (n,) `distances_from_first` of the reference points, m.
        distances: (n,) those of the current points, m.
        tolerance: m.
    """
    return bool(np.abs(distances - reference_distances).max() <= 2 * tolerance)
