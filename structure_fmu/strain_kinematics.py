"""Kinematics of the strain-based beam: nodal vectors from constant element strains and joint parameters
(Otsuka et al. 2022, Secs. 2-3), with their derivatives.

A node carries h = [r, r_x, r_y, r_z] (Otsuka et al. 2022, Eq. 4), here the (4, 3) matrix H whose rows are
those vectors (global frame; r in m, the gradients unit and orthogonal). Along an element of length ds with
constant strains xi = [eps_x, kappa_x, kappa_y, kappa_z] (1, 1/m, 1/m, 1/m; Eq. 12), dH/ds = K(xi) H
(Eqs. 5-6, first block row read as r' = (1 + eps_x) r_x), so the element's end node is H_{i+1} = exp(ds K) H_i
(Eq. 7): `transfer`. A joint maps the parent's tip node to the child's root node by H_root = C(eta) H_tip
with C = blockdiag(1, c(eta)) (Eq. 8): `joint_matrix`.

Derivatives come from exponentials of block-triangular matrices (the Frechet derivative of exp): with
X = ds K and a direction Y, exp([[X, Y], [0, X]]) holds d exp(X + tY)/dt at t = 0 in its upper right block,
and exp([[X, Y, 0], [0, X, Y], [0, 0, X]]) holds half the second derivative in its corner. Exact to
round-off, and free of the singularity of closed forms at zero curvature.
"""
import numpy as np
from scipy.linalg import expm

from fmu_common.vectors import rotation_about, skew

STRAINS = 4
"""Strain coordinates per element: eps_x, kappa_x, kappa_y, kappa_z."""


def _generators():
    """(K0, A (4, 4, 4)): K(xi) = K0 + sum_p xi_p A_p (Otsuka et al. 2022, Eq. 6 with r' = (1 + eps_x) r_x)."""
    K0 = np.zeros((4, 4))
    K0[0, 1] = 1.0
    A = np.zeros((STRAINS, 4, 4))
    A[0, 0, 1] = 1.0                                  # eps_x: r' = (1 + eps_x) r_x
    A[1, 2, 3], A[1, 3, 2] = 1.0, -1.0                # kappa_x: r_y' = kappa_x r_z, r_z' = -kappa_x r_y
    A[2, 1, 3], A[2, 3, 1] = -1.0, 1.0                # kappa_y: r_x' = -kappa_y r_z, r_z' = kappa_y r_x
    A[3, 1, 2], A[3, 2, 1] = 1.0, -1.0                # kappa_z: r_x' = kappa_z r_y, r_y' = -kappa_z r_x
    return K0, A


K0, GENERATORS = _generators()


def transfer(strains, lengths):
    """Element transfer matrices and their derivatives along the strains.

    H_end = Phi H_start.

    Otsuka et al. 2022, Eq. 7

    Args:
        strains: (n, 4) the elements' strains xi.
        lengths: (n,) m.

    Returns:
        (Phi (n, 4, 4), dPhi (n, 4, 4, 4)), dPhi[:, p] = d Phi / d xi_p.
    """
    n = len(strains)
    X = lengths[:, None, None] * (K0 + np.einsum("np,pij->nij", strains, GENERATORS))
    big = np.zeros((n, 4 * (STRAINS + 1), 4 * (STRAINS + 1)))
    for k in range(STRAINS + 1):
        big[:, 4 * k:4 * k + 4, 4 * k:4 * k + 4] = X
    for p in range(STRAINS):
        big[:, :4, 4 * (p + 1):4 * (p + 2)] = lengths[:, None, None] * GENERATORS[p]
    with np.errstate(over="ignore", invalid="ignore"):   # a diverging state: the solver's check reports it
        top = expm(big)[:, :4]
    Phi = top[:, :, :4]
    dPhi = top[:, :, 4:].reshape(n, 4, STRAINS, 4).transpose(0, 2, 1, 3)
    return Phi, dPhi


def transfer_second(strains, rates, lengths):
    """d2 Phi/dt2 at zero strain acceleration: the second derivative of exp(ds K(xi)) along the strain rates.

    Args:
        strains: (n, 4) the elements' strains xi.
        rates: (n, 4) their rates, per s.
        lengths: (n,) m.

    Returns:
        (n, 4, 4).
    """
    n = len(strains)
    X = lengths[:, None, None] * (K0 + np.einsum("np,pij->nij", strains, GENERATORS))
    Y = lengths[:, None, None] * np.einsum("np,pij->nij", rates, GENERATORS)
    big = np.zeros((n, 12, 12))
    for k in range(3):
        big[:, 4 * k:4 * k + 4, 4 * k:4 * k + 4] = X
    big[:, :4, 4:8] = big[:, 4:8, 8:12] = Y
    with np.errstate(over="ignore", invalid="ignore"):
        return 2.0 * expm(big)[:, :4, 8:12]


# --- joint parameters (Otsuka et al. 2022, Sec. 3) ------------------------------------------------------------
#
# c(eta) (3, 3) maps the parent's tip gradients to the child's root gradients, rows: [r_x; r_y; r_z]_child =
# c [r_x; r_y; r_z]_parent. With frames F = [r_x r_y r_z] (columns) that is F_child = F_parent c^T.

PARAMETERS = {"revolute": 1, "ball": 4, "universal": 9, "fixed": 0}
"""Joint parameters per joint kind (Otsuka et al. 2022, Table 2, N_J): theta; Euler parameters; direction cosines."""


def quaternion_matrix(z):
    """R(zeta): a rotation for a unit zeta, |zeta|^2 times one otherwise.

    Otsuka et al. 2022, Eq. 21

    Homogeneous quadratic, so its second derivative along w is 2 R(w).

    Args:
        z: (4,) Euler parameters zeta.

    Returns:
        (3, 3).
    """
    z0, z1, z2, z3 = z
    return np.array([[z0 * z0 + z1 * z1 - z2 * z2 - z3 * z3, 2 * (z1 * z2 - z0 * z3), 2 * (z1 * z3 + z0 * z2)],
                     [2 * (z1 * z2 + z0 * z3), z0 * z0 - z1 * z1 + z2 * z2 - z3 * z3, 2 * (z2 * z3 - z0 * z1)],
                     [2 * (z1 * z3 - z0 * z2), 2 * (z2 * z3 + z0 * z1), z0 * z0 - z1 * z1 - z2 * z2 + z3 * z3]])


def quaternion_of(rotation):
    """Unit Euler parameters of a rotation matrix, zeta_0 >= 0 (Shepperd's method).

    Args:
        rotation: (3, 3) rotation matrix.

    Returns:
        (4,) zeta.
    """
    R = np.asarray(rotation, dtype=float)
    trace = np.trace(R)
    candidates = [trace, R[0, 0], R[1, 1], R[2, 2]]
    k = int(np.argmax(candidates))
    if k == 0:
        z0 = 0.5 * np.sqrt(1 + trace)
        z = [z0, (R[2, 1] - R[1, 2]) / (4 * z0), (R[0, 2] - R[2, 0]) / (4 * z0), (R[1, 0] - R[0, 1]) / (4 * z0)]
    else:
        i, j, m = k - 1, k % 3, (k + 1) % 3
        zi = 0.5 * np.sqrt(1 + 2 * R[i, i] - trace)
        z = np.zeros(4)
        z[1 + i] = zi
        z[0] = (R[m, j] - R[j, m]) / (4 * zi)
        z[1 + j] = (R[j, i] + R[i, j]) / (4 * zi)
        z[1 + m] = (R[m, i] + R[i, m]) / (4 * zi)
    z = np.asarray(z, dtype=float)
    return z if z[0] >= 0 else -z


def joint_gradients(kind, eta, axis, orientation):
    """c(eta) and d c / d eta_k of a joint.

    revolute (Otsuka et al. 2022, Eq. 15 for the chord axis): F_child = F_parent R(axis, theta) orientation,
    c = orientation^T R^T; ball (Eqs. 19-21): F_child = F_parent R(zeta), c = R(zeta)^T; universal (Eqs. 16-17):
    c = mu, the nine direction cosines row by row; fixed: c = orientation^T.

    Args:
        kind: the joint's kind: "revolute", "ball", "universal"; any other is fixed.
        eta: (n_eta,) the joint parameters.
        axis: (3,) unit revolute axis, parent frame.
        orientation: (3, 3) the child's frame relative to the parent's at eta's origin.

    Returns:
        (c (3, 3), dc (n_eta, 3, 3)).
    """
    if kind == "revolute":
        R = rotation_about(axis, eta[0])
        dR = skew(axis) @ R
        return orientation.T @ R.T, (orientation.T @ dR.T)[None]
    if kind == "ball":
        return quaternion_matrix(eta).T, quaternion_gradient(eta).transpose(0, 2, 1)
    if kind == "universal":
        return eta.reshape(3, 3).copy(), np.eye(9).reshape(9, 3, 3)
    return orientation.T.copy(), np.zeros((0, 3, 3))


def quaternion_gradient(z):
    """d R(zeta) / d zeta_k of Otsuka et al. 2022, Eq. 21, linear in zeta.

    Args:
        z: (4,) Euler parameters zeta.

    Returns:
        (4, 3, 3).
    """
    z0, z1, z2, z3 = z
    return 2.0 * np.array([[[z0, -z3, z2], [z3, z0, -z1], [-z2, z1, z0]],
                           [[z1, z2, z3], [z2, -z1, -z0], [z3, z0, -z1]],
                           [[-z2, z1, z0], [z1, z2, z3], [-z0, z3, -z2]],
                           [[-z3, -z0, z1], [z0, -z3, z2], [z1, z2, z3]]])


def joint_second(kind, eta, rate, axis, orientation):
    """d2 c/dt2 at zero parameter acceleration.

    Args:
        kind: the joint's kind: "revolute", "ball", "universal"; any other is fixed.
        eta: (n_eta,) the joint parameters.
        rate: (n_eta,) their rates, per s.
        axis: (3,) unit revolute axis, parent frame.
        orientation: (3, 3) the child's frame relative to the parent's at eta's origin.

    Returns:
        (3, 3) per s^2.
    """
    if kind == "revolute":
        R = rotation_about(axis, eta[0])
        k = skew(axis)
        return orientation.T @ (k @ k @ R).T * rate[0] ** 2
    if kind == "ball":
        return 2.0 * quaternion_matrix(rate).T
    return np.zeros((3, 3))


def initial_parameters(kind, angle, orientation):
    """eta at t = 0 for a joint whose child starts at `angle` and `orientation`.

    Args:
        kind: the joint's kind: "revolute", "ball", "universal"; any other is fixed.
        angle: the revolute's initial angle, rad.
        orientation: (3, 3) the child's initial frame relative to the parent's.

    Returns:
        (n_eta,).
    """
    if kind == "revolute":
        return np.array([angle])
    if kind == "ball":
        return quaternion_of(orientation)
    if kind == "universal":
        return orientation.T.ravel().copy()
    return np.zeros(0)
