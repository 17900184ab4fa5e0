"""Kinematics of the strain-based beam: nodal vectors from constant element strains and joint parameters
(Otsuka et al. 2022, Secs. 2-3), with their derivatives.

A node carries h = [r, r_x, r_y, r_z] (Otsuka et al. 2022, Eq. 4), here the (4, 3) matrix H whose rows are
those vectors (global frame; r in m, the gradients unit and orthogonal). Along an element of length ds with
constant strains xi = [eps_x, kappa_x, kappa_y, kappa_z] (1, 1/m, 1/m, 1/m; Eq. 12), dH/ds = K(xi) H
(Eqs. 5-6, first block row read as r' = (1 + eps_x) r_x), so the element's end node is H_{i+1} = exp(ds K) H_i
(Eq. 7): `transfer`. A joint maps the parent's tip node to the child's root node by H_root = C(eta) H_tip
with C = blockdiag(1, c(eta)) (Eq. 8): `joint_matrix`.

ds K = [[0, ds (1 + eps_x) e_1^T], [0, Omega]] with Omega = [w]_x, w = -ds kappa (3,), so the transfer matrix has
a closed form (Rodrigues): Phi = [[1, ds (1 + eps_x) e_1^T P], [0, R]] with R = exp(Omega) = I + a Omega + b Omega^2
and P = sum_k Omega^k / (k + 1)! = I + b Omega + c Omega^2, where a, b, c are the power series
f_k(s) = sum_n (-s)^n / (2n + k)! (k = 1, 2, 3) in s = |w|^2 = theta^2 (sin(theta)/theta, (1 - cos(theta))/theta^2,
(theta - sin(theta))/theta^3). Their derivatives along the strains differentiate these polynomials in Omega and the
series term by term: exact to round-off, with no singularity at zero curvature. An element turning by more than
pi (theta > pi) takes the general route instead: exponentials of block-triangular matrices (the Frechet derivative
of exp: exp([[X, Y], [0, X]]) holds d exp(X + tY)/dt at t = 0 in its upper right block, and
exp([[X, Y, 0], [0, X, Y], [0, 0, X]]) half the second derivative in its corner).
"""
import ctypes
import math
from pathlib import Path

import numpy as np
from scipy.linalg import expm

from fmu_common import c_library
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


SERIES_TERMS = 20
"""Terms of the series f_k and their derivatives: below 1e-18 relative at theta = pi."""

THETA_MAX = np.pi
"""Largest rotation of an element (rad) the series evaluate; beyond it the block-matrix exponential."""


def _series_coefficients():
    """(9, SERIES_TERMS) coefficients of s^n: rows f_k, f_k', f_k'' (d/ds) for k = 1, 2, 3."""
    n = np.arange(SERIES_TERMS + 2)
    rows = []
    for k in (1, 2, 3):
        c = np.array([(-1.0) ** m / math.factorial(2 * m + k) for m in n])
        rows += [c[:SERIES_TERMS], (n[1:] * c[1:])[:SERIES_TERMS], (n[2:] * (n[2:] - 1) * c[2:])[:SERIES_TERMS]]
    return np.array(rows)


_SERIES = _series_coefficients()


def rotation_series(s):
    """The scalar functions of the closed-form element exponential and their derivatives in s.

    f_k(s) = sum_n (-s)^n / (2n + k)!: f_1 = sin(theta)/theta, f_2 = (1 - cos(theta))/theta^2,
    f_3 = (theta - sin(theta))/theta^3 with s = theta^2 (Rodrigues' coefficients of exp and of its integral).

    Args:
        s: (n,) theta^2, rad^2, at most THETA_MAX^2.

    Returns:
        (n, 3, 3): [:, k - 1, j] the j-th derivative of f_k in s.
    """
    powers = np.asarray(s, dtype=float)[:, None] ** np.arange(SERIES_TERMS)
    return (powers @ _SERIES.T).reshape(-1, 3, 3)


def _rotation_terms(strains, lengths):
    """(w (n, 3), Omega (n, 3, 3), Omega^2, coefficients (n, 3, 3) of rotation_series) of the elements."""
    w = -lengths[:, None] * strains[:, 1:]
    s = np.einsum("ni,ni->n", w, w)
    Om = skew(w)
    return w, Om, Om @ Om, rotation_series(s)


def _transfer_closed(strains, lengths):
    """transfer() by the closed form (see the module), for elements with theta <= THETA_MAX."""
    n = len(strains)
    w, Om, Om2, f = _rotation_terms(strains, lengths)
    a, b, c = f[:, 0, 0, None, None], f[:, 1, 0, None, None], f[:, 2, 0, None, None]
    da, db, dc = f[:, 0, 1, None, None], f[:, 1, 1, None, None], f[:, 2, 1, None, None]
    eye = np.eye(3)
    R = eye + a * Om + b * Om2
    P = eye + b * Om + c * Om2
    stretch = lengths * (1.0 + strains[:, 0])
    Phi = np.zeros((n, 4, 4))
    Phi[:, 0, 0] = 1.0
    Phi[:, 0, 1:] = stretch[:, None] * P[:, 0]
    Phi[:, 1:, 1:] = R
    dPhi = np.zeros((n, STRAINS, 4, 4))
    dPhi[:, 0, 0, 1:] = lengths[:, None] * P[:, 0]
    # directions u = dw/dkappa_j = -ds e_j, U = [u]_x, sigma = ds(s)/dkappa_j = 2 w . u
    U = -lengths[:, None, None, None] * skew(np.eye(3))[None]                     # (n, 3, 3, 3)
    sigma = (-2.0 * lengths[:, None] * w)[:, :, None, None]                      # (n, 3, 1, 1)
    sym = U @ Om[:, None] + Om[:, None] @ U
    a_, b_, c_ = a[:, None], b[:, None], c[:, None]
    da_, db_, dc_ = da[:, None], db[:, None], dc[:, None]
    dR = da_ * sigma * Om[:, None] + a_ * U + db_ * sigma * Om2[:, None] + b_ * sym
    dP = db_ * sigma * Om[:, None] + b_ * U + dc_ * sigma * Om2[:, None] + c_ * sym
    dPhi[:, 1:, 0, 1:] = stretch[:, None, None] * dP[:, :, 0]
    dPhi[:, 1:, 1:, 1:] = dR
    return Phi, dPhi


def _transfer_second_closed(strains, rates, lengths):
    """transfer_second() by the closed form (see the module), for elements with theta <= THETA_MAX."""
    n = len(strains)
    w, Om, Om2, f = _rotation_terms(strains, lengths)
    a, b, c = (f[:, k, 0, None, None] for k in range(3))
    da, db, dc = (f[:, k, 1, None, None] for k in range(3))
    d2a, d2b, d2c = (f[:, k, 2, None, None] for k in range(3))
    u = -lengths[:, None] * rates[:, 1:]
    U = skew(u)
    sigma = 2.0 * np.einsum("ni,ni->n", w, u)[:, None, None]
    tau = 2.0 * np.einsum("ni,ni->n", u, u)[:, None, None]
    sym, UU = U @ Om + Om @ U, U @ U
    d2R = ((d2a * sigma**2 + da * tau) * Om + 2.0 * da * sigma * U + (d2b * sigma**2 + db * tau) * Om2
           + 2.0 * db * sigma * sym + 2.0 * b * UU)
    dP1 = db * sigma * Om + b * U + dc * sigma * Om2 + c * sym
    d2P = ((d2b * sigma**2 + db * tau) * Om + 2.0 * db * sigma * U + (d2c * sigma**2 + dc * tau) * Om2
           + 2.0 * dc * sigma * sym + 2.0 * c * UU)
    out = np.zeros((n, 4, 4))
    out[:, 0, 1:] = lengths[:, None] * (2.0 * rates[:, :1] * dP1[:, 0] + (1.0 + strains[:, :1]) * d2P[:, 0])
    out[:, 1:, 1:] = d2R
    return out


def _large(strains, lengths):
    """(n,) bool: elements turning by more than THETA_MAX (or not finite), left to the block exponential."""
    theta2 = np.einsum("ni,ni->n", strains[:, 1:], strains[:, 1:]) * lengths**2
    return ~(theta2 <= THETA_MAX**2)


def transfer(strains, lengths):
    """Element transfer matrices and their derivatives along the strains.

    H_end = Phi H_start, by the closed form of the module's docstring (the block exponential beyond THETA_MAX).

    Otsuka et al. 2022, Eq. 7

    Args:
        strains: (n, 4) the elements' strains xi.
        lengths: (n,) m.

    Returns:
        (Phi (n, 4, 4), dPhi (n, 4, 4, 4)), dPhi[:, p] = d Phi / d xi_p.
    """
    strains, lengths = np.asarray(strains, dtype=float), np.asarray(lengths, dtype=float)
    large = _large(strains, lengths)
    if not large.any():
        return _transfer_closed(strains, lengths)
    Phi, dPhi = np.zeros((len(strains), 4, 4)), np.zeros((len(strains), STRAINS, 4, 4))
    small = ~large
    Phi[small], dPhi[small] = _transfer_closed(strains[small], lengths[small])
    Phi[large], dPhi[large] = transfer_expm(strains[large], lengths[large])
    return Phi, dPhi


def transfer_second(strains, rates, lengths):
    """d2 Phi/dt2 at zero strain acceleration: the second derivative of exp(ds K(xi)) along the strain rates.

    By the closed form of the module's docstring (the block exponential beyond THETA_MAX).

    Args:
        strains: (n, 4) the elements' strains xi.
        rates: (n, 4) their rates, per s.
        lengths: (n,) m.

    Returns:
        (n, 4, 4).
    """
    strains, rates, lengths = (np.asarray(x, dtype=float) for x in (strains, rates, lengths))
    large = _large(strains, lengths)
    if not large.any():
        return _transfer_second_closed(strains, rates, lengths)
    out = np.zeros((len(strains), 4, 4))
    small = ~large
    out[small] = _transfer_second_closed(strains[small], rates[small], lengths[small])
    out[large] = transfer_second_expm(strains[large], rates[large], lengths[large])
    return out


def transfer_expm(strains, lengths):
    """transfer() by block-triangular matrix exponentials (scipy.linalg.expm): any strain, and the reference
    of the closed form.

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


def transfer_second_expm(strains, rates, lengths):
    """transfer_second() by a block-triangular matrix exponential (scipy.linalg.expm): any strain, and the
    reference of the closed form.

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

C_SOURCE = Path(__file__).with_name("strain_kernels.c")    # the compiled sweeps (fmu_common.c_library)


def body_sweep(Phi, dPhi, H0, dH0, Ht0, columns):
    """The nodes of one body from its root node: H_{k+1} = Phi_k H_k (Otsuka et al. 2022, Eq. 7) with the
    derivatives along q, dH_{k+1}/dq = Phi_k dH_k/dq + sum_p dPhi_k/dxi_p H_k e_{c_k + p}^T, and along t at fixed q,
    dH_{k+1}/dt = Phi_k dH_k/dt. Runs the C kernel of strain_kernels.c unless $WINGSIM_KERNELS = numpy (the
    numpy form below is its reference; tests/units/test_strain_based.py checks both agree to 1e-12).

    Args:
        Phi: (n_el, 4, 4) the body's transfer matrices in order from its root (`transfer`).
        dPhi: (n_el, 4, 4, 4) their derivatives along the element's strains [p, i, j] (`transfer`).
        H0: (4, 3) the root node's H (m and 1).
        dH0: (4, 3, n_q) its derivative along q, zero in the columns of the body's strains and beyond.
        Ht0: (4, 3) its derivative along t at fixed q, per s.
        columns: (n_el,) int, the column of each element's first strain in q, increasing by 4.

    Returns:
        (H (n_el + 1, 4, 3), dH/dq (n_el + 1, 4, 3, n_q), dH/dt (n_el + 1, 4, 3)), row 0 the root's.
    """
    n_el, n_q = len(Phi), dH0.shape[-1]
    H = np.zeros((n_el + 1, 4, 3))
    dH = np.zeros((n_el + 1, 4, 3, n_q))
    Ht = np.zeros((n_el + 1, 4, 3))
    H[0], dH[0], Ht[0] = H0, dH0, Ht0
    library = _c_kernels()
    if library is not None and n_el:
        Phi = np.ascontiguousarray(Phi, dtype=float)
        dPhi = np.ascontiguousarray(dPhi, dtype=float)
        columns = np.ascontiguousarray(columns, dtype=np.int64)
        library.body_sweep(n_el, n_q, columns.ctypes.data, Phi.ctypes.data, dPhi.ctypes.data, H.ctypes.data,
                           dH.ctypes.data, Ht.ctypes.data)
        return H, dH, Ht
    for k in range(n_el):
        H[k + 1] = Phi[k] @ H[k]
        width = columns[k]
        dH[k + 1, ..., :width] = np.einsum("ij,jkq->ikq", Phi[k], dH[k, ..., :width])
        dH[k + 1, ..., width:width + STRAINS] = np.einsum("pij,jk->ikp", dPhi[k], H[k])
        Ht[k + 1] = Phi[k] @ Ht[k]
    return H, dH, Ht


def body_accelerations(Phi, Phi_d, Phi_dd, H, Hd, Hdd0):
    """d2H/dt2 of one body's nodes from its root node's: d2H_{k+1}/dt2 = Phi''_k H_k + 2 Phi'_k dH_k/dt +
    Phi_k d2H_k/dt2 (the time derivatives of Otsuka et al. 2022, Eq. 7). Runs the C kernel of strain_kernels.c
    unless $WINGSIM_KERNELS = numpy (the numpy form below is its reference; equal to 1e-12).

    Args:
        Phi: (n_el, 4, 4) the body's transfer matrices in order from its root (`transfer`).
        Phi_d: (n_el, 4, 4) their rates, per s.
        Phi_dd: (n_el, 4, 4) their second time derivatives, per s^2 (`transfer_second`).
        H: (n_el + 1, 4, 3) the body's nodes, root first, m and 1.
        Hd: (n_el + 1, 4, 3) their rates, per s.
        Hdd0: (4, 3) the root node's d2H/dt2, per s^2.

    Returns:
        (n_el + 1, 4, 3) d2H/dt2, row 0 the root's.
    """
    n_el = len(Phi)
    Hdd = np.zeros((n_el + 1, 4, 3))
    Hdd[0] = Hdd0
    library = _c_kernels()
    if library is not None and n_el:
        arrays = [np.ascontiguousarray(x, dtype=float) for x in (Phi, Phi_d, Phi_dd, H, Hd)]
        library.body_accelerations(n_el, *(x.ctypes.data for x in arrays), Hdd.ctypes.data)
        return Hdd
    for k in range(n_el):
        Hdd[k + 1] = Phi_dd[k] @ H[k] + 2.0 * Phi_d[k] @ Hd[k] + Phi[k] @ Hdd[k]
    return Hdd


_N, _ARRAY = ctypes.c_long, ctypes.c_void_p   # a count; a C-contiguous array, passed as its data address
SIGNATURES = {"body_sweep": (_N, [_N, _N] + [_ARRAY] * 6), "body_accelerations": (_N, [_N] + [_ARRAY] * 6)}
"""The C functions of strain_kernels.c: {name: (restype, argtypes)} (fmu_common.c_library.kernels)."""


def _c_kernels():
    """The C library of strain_kernels.c, typed; None when $WINGSIM_KERNELS selects the numpy kernels."""
    return c_library.kernels(C_SOURCE, SIGNATURES)


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
