"""Damping of deformation: mass-proportional, zero for rigid-body motion (Otsuka et al. 2019, Sec. II.C, corrected).

Otsuka et al. 2019 prints F_damping = -alpha M (the velocity is missing) and states in Sec. IV that the damping
is zero for a rigid body: it acts on deformation only. We take the deformation velocity of a body as its velocity
relative to the rigid motion of its root node's frame, v_def = (I - P) de, where P de is the velocity
field of a rigid body moving with the root node (translation of r, angular velocity of the frame
r_x/|r_x|, r_y, their cross product). The force F = -alpha (I - P)^T M (I - P) de is dissipative
(power -alpha |v_def|_M^2), zero for a rigid motion, and equals -alpha M de on a clamped body.
"""
import numpy as np

from fmu_common.vectors import cross, skew


def frame_angular_velocity_map(root):
    """W with omega = W d(root)/dt for the root node coordinates [r, r_x, r_y].

    omega = 1/2 sum_i e_i x de_i over the frame e_1 = r_x/|r_x|, e_2 = r_y, e_3 = e_1 x e_2.

    Args:
        root: (9,) the root node's [r, r_x, r_y], m and 1, global frame.

    Returns:
        (3, 9).
    """
    x, y = root[3:6], root[6:9]
    nx = np.linalg.norm(x)
    e1, e2 = x / nx, y
    e3 = np.cross(e1, e2)
    de1 = (np.eye(3) - np.outer(e1, e1)) / nx             # d e1 / d r_x
    de3_dx = -skew(e2) @ de1                             # d(e1 x e2)/d r_x = -[e2]x de1
    de3_dy = skew(e1)
    W = np.zeros((3, 9))
    W[:, 3:6] = 0.5 * (skew(e1) @ de1 + skew(e3) @ de3_dx)
    W[:, 6:9] = 0.5 * (skew(e2) + skew(e3) @ de3_dy)
    return W


def rigid_velocity_projector(E_body):
    """P mapping a body's coordinate rates to those of the rigid motion of its root frame.

    Args:
        E_body: (9m,) the body's coordinates (m nodes), global frame.

    Returns:
        (9m, 9m).
    """
    nodes = E_body.reshape(-1, 3, 3)
    m = len(nodes)
    W = frame_angular_velocity_map(E_body[:9])
    P = np.zeros((m, 3, 3, 9))
    arms = _arms(nodes)
    P[:, :, :, :] = -np.einsum("mkij,jc->mkic", skew(arms), W)                      # omega x arm
    P[:, 0, :, 0:3] += np.eye(3)                                                     # + dr_root/dt
    out = np.zeros((9 * m, 9 * m))
    out[:, :9] = P.reshape(9 * m, 9)
    return out


def _arms(nodes):
    """Per node the vectors a rigid rotation acts on: r - r_root, r_x, r_y, shape (m, 3, 3)."""
    return np.stack([nodes[:, 0] - nodes[0, 0], nodes[:, 1], nodes[:, 2]], axis=1)


def deformation_damping_matrix(E_body, mass_body, alpha):
    """D = alpha (I - P)^T M (I - P) for one body; the damping force is -D de (used for the tangent).

    Args:
        E_body: (9m,) the body's coordinates (m nodes), global frame.
        mass_body: (9m, 9m) its mass matrix, SI.
        alpha: damping coefficient, 1/s.

    Returns:
        (9m, 9m), the units of alpha M.
    """
    A = np.eye(len(E_body)) - rigid_velocity_projector(E_body)
    return alpha * A.T @ mass_body @ A


def deformation_damping_force(E_body, dE_body, mass_body, alpha):
    """-D de computed matrix-free in O(n): v = (I - P) de, y = M v, F = -alpha (y - P^T y).

    P^T y is non-zero only on the root coordinates: the sum of y over the r slots (translation) plus
    W^T sum_j a_j x y_j (rotation), since y . (omega x a) = omega . (a x y).

    Args:
        E_body: (9m,) the body's coordinates (m nodes), global frame.
        dE_body: (9m,) their rates, per s.
        mass_body: (9m, 9m) its mass matrix, SI.
        alpha: damping coefficient, 1/s.

    Returns:
        (9m,) N and N m, global frame.
    """
    nodes, rates = E_body.reshape(-1, 3, 3), dE_body.reshape(-1, 3, 3)
    W = frame_angular_velocity_map(E_body[:9])
    arms = _arms(nodes)
    rigid = cross(W @ dE_body[:9], arms)
    rigid[:, 0] += rates[0, 0]
    y = mass_body @ (rates - rigid).ravel()
    Y = y.reshape(-1, 3, 3)
    back = W.T @ cross(arms, Y).sum(axis=(0, 1))
    back[:3] += Y[:, 0].sum(axis=0)
    y[:9] -= back
    return -alpha * y
