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
from fmu_common.vectors import rodrigues, skew

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


def _closed(strains, rates, lengths):
    """(Phi, dPhi, Phi', Phi'') by the closed form for elements with theta <= THETA_MAX: the C kernel
    element_transfers of strain_kernels.c, unless $WINGSIM_KERNELS = numpy (then _transfer_closed and
    _transfer_second_closed, its reference; tests/units/test_strain_based.py checks both agree to 1e-12).
    Phi' and Phi'' are None without rates."""
    library = _c_kernels()
    if library is None or not len(strains):
        Phi, dPhi = _transfer_closed(strains, lengths)
        if rates is None:
            return Phi, dPhi, None, None
        return Phi, dPhi, np.einsum("np,npij->nij", rates, dPhi), _transfer_second_closed(strains, rates, lengths)
    n = len(strains)
    strains = np.ascontiguousarray(strains, dtype=float)
    lengths = np.ascontiguousarray(lengths, dtype=float)
    Phi, dPhi = np.empty((n, 4, 4)), np.empty((n, STRAINS, 4, 4))
    if rates is None:
        library.element_transfers(n, _SERIES.ctypes.data, SERIES_TERMS, strains.ctypes.data, None,
                                  lengths.ctypes.data, Phi.ctypes.data, dPhi.ctypes.data, None, None)
        return Phi, dPhi, None, None
    rates = np.ascontiguousarray(rates, dtype=float)
    Phi_d, Phi_dd = np.empty((n, 4, 4)), np.empty((n, 4, 4))
    library.element_transfers(n, _SERIES.ctypes.data, SERIES_TERMS, strains.ctypes.data, rates.ctypes.data,
                              lengths.ctypes.data, Phi.ctypes.data, dPhi.ctypes.data, Phi_d.ctypes.data,
                              Phi_dd.ctypes.data)
    return Phi, dPhi, Phi_d, Phi_dd


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
        return _closed(strains, None, lengths)[:2]
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
        return _closed(strains, rates, lengths)[3]
    out = np.zeros((len(strains), 4, 4))
    small = ~large
    out[small] = _transfer_second_closed(strains[small], rates[small], lengths[small])
    out[large] = transfer_second_expm(strains[large], rates[large], lengths[large])
    return out


def transfers(strains, rates, lengths):
    """Phi, dPhi (`transfer`), Phi' = sum_p rate_p dPhi/dxi_p and Phi'' (`transfer_second`) of the elements in one
    pass of the closed form (the block exponential beyond THETA_MAX).

    Args:
        strains: (n, 4) the elements' strains xi.
        rates: (n, 4) their rates, per s.
        lengths: (n,) m.

    Returns:
        (Phi (n, 4, 4), dPhi (n, 4, 4, 4), Phi' (n, 4, 4) per s, Phi'' (n, 4, 4) per s^2).
    """
    strains, rates, lengths = (np.asarray(x, dtype=float) for x in (strains, rates, lengths))
    if not _large(strains, lengths).any():
        return _closed(strains, rates, lengths)
    Phi, dPhi = transfer(strains, lengths)
    return Phi, dPhi, np.einsum("np,npij->nij", rates, dPhi), transfer_second(strains, rates, lengths)


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


def kinematics(bodies, roots, transfers, dq, n_nodes):
    """The nodal vectors of every body, parents first: each body's root node from what it hangs from (Otsuka et al.
    2022, Eq. 8: H_root = C(eta) H_parent, C = blockdiag(1, c)), then along its elements H_{k+1} = Phi_k H_k
    (Eq. 7) with dH_{k+1}/dq = Phi_k dH_k/dq + sum_p dPhi_k/dxi_p H_k e_{c_k + p}^T and dH_{k+1}/dt = Phi_k dH_k/dt at
    fixed q; the rates dH/dt = dH/dq q' + dH/dt; the accelerations at q'' = 0, d2H_{k+1}/dt2 = Phi''_k H_k +
    2 Phi'_k dH_k/dt + Phi_k d2H_k/dt2. Runs the C kernel body_kinematics of strain_kernels.c once per body unless
    $WINGSIM_KERNELS = numpy (the numpy form `_body_kinematics` is its reference; tests/units/test_strain_based.py
    checks both agree to 1e-12).

    Args:
        bodies: the BodyLine of each body, parents first.
        roots: the RootTerms of each body's root joint at this state, in the same order.
        transfers: (Phi, dPhi, Phi', Phi'') of every element (`transfers`).
        dq: (n_q,) the rates q', per s.
        n_nodes: the number of nodes.

    Returns:
        (H, dH/dq, dH/dt at fixed q, dH/dt, d2H/dt2 at q'' = 0): (n_nodes, 4, 3) each but dH/dq (n_nodes, 4, 3,
        n_q); m, 1 and per s, per s^2.
    """
    dq = np.ascontiguousarray(dq, dtype=float)
    n_q = len(dq)
    H, Ht, Hd, Hdd = (np.zeros((n_nodes, 4, 3)) for _ in range(4))
    dH = np.zeros((n_nodes, 4, 3, n_q))
    library = _c_kernels()
    if library is None:
        for body, root in zip(bodies, roots):
            _body_kinematics(body, root, transfers, dq, H, dH, Ht, Hd, Hdd)
        return H, dH, Ht, Hd, Hdd
    shared = [x.ctypes.data for x in (*transfers, dq, H, dH, Ht, Hd, Hdd)]
    for body, root in zip(bodies, roots):
        library.body_kinematics(body.n_el, n_q, body.first, body.first_element, body.parent, body.columns_address,
                                root.ground.ctypes.data, root.c.ctypes.data, len(root.dc), root.offset,
                                root.dc.ctypes.data, root.c_dot.ctypes.data, root.c_ddot.ctypes.data, *shared)
    return H, dH, Ht, Hd, Hdd


class BodyLine:
    """A body as the sweep sees it: its root node `first` (its nodes first..first + n_el), its first element
    (its elements first_element..first_element + n_el - 1), the node its root hangs from (the parent's tip; -1:
    the ground) and the column of each element's first strain in q (n_el,), increasing by 4.

    Args:
        first: the root node.
        first_element: the first element.
        parent: the parent's tip node, or -1.
        columns: (n_el,) int.
    """

    def __init__(self, first, first_element, parent, columns):
        self.first, self.first_element, self.parent = first, first_element, parent
        self.columns = np.ascontiguousarray(columns, dtype=np.int64)
        self.n_el = len(self.columns)
        self.columns_address = self.columns.ctypes.data


def _body_kinematics(body, root, transfers, dq, H, dH, Ht, Hd, Hdd):
    """`kinematics` of one body in numpy, written into the arrays: the reference of the C kernel."""
    first, first_element, parent, columns = body.first, body.first_element, body.parent, body.columns
    n_el, n_q = body.n_el, len(dq)
    Phi, dPhi, Phi_d, Phi_dd = transfers
    if parent >= 0:
        Hp, dHp, Htp, Hpd, Hpdd = H[parent], dH[parent], Ht[parent], Hd[parent], Hdd[parent]
    else:
        (Hp, Htp, Hpdd), dHp = root.ground, np.zeros((4, 3, n_q))
        Hpd = Htp
    c = root.c
    H[first] = np.vstack([Hp[0], c @ Hp[1:]])
    dH[first] = np.concatenate([dHp[:1], np.einsum("ij,jkq->ikq", c, dHp[1:])])
    for k, dc_k in enumerate(root.dc):
        dH[first, 1:, :, root.offset + k] += dc_k @ Hp[1:]
    Ht[first] = np.vstack([Htp[0], c @ Htp[1:]])
    Hdd[first] = np.vstack([Hpdd[0], root.c_ddot @ Hp[1:] + 2.0 * root.c_dot @ Hpd[1:] + c @ Hpdd[1:]])
    for k in range(n_el):
        a, e, width = first + k, first_element + k, columns[k]
        H[a + 1] = Phi[e] @ H[a]
        dH[a + 1, ..., :width] = np.einsum("ij,jkq->ikq", Phi[e], dH[a, ..., :width])
        dH[a + 1, ..., width:width + STRAINS] = np.einsum("pij,jk->ikp", dPhi[e], H[a])
        Ht[a + 1] = Phi[e] @ Ht[a]
    nodes = slice(first, first + n_el + 1)
    Hd[nodes] = dH[nodes] @ dq + Ht[nodes]
    for k in range(n_el):
        a, e = first + k, first_element + k
        Hdd[a + 1] = Phi_dd[e] @ H[a] + 2.0 * Phi_d[e] @ Hd[a] + Phi[e] @ Hdd[a]


class RootTerms:
    """What `kinematics` needs of a root joint at a state (Otsuka et al. 2022, Eq. 8).

    Args:
        c: (3, 3) the joint matrix c(eta).
        dc: (n_eta, 3, 3) dc/deta.
        c_dot: (3, 3) dc/dt, per s.
        c_ddot: (3, 3) d2c/dt2 at zero parameter acceleration, per s^2.
        offset: the column of eta's first parameter in q.
        ground: (3, 4, 3) H, dH/dt, d2H/dt2 of the ground point the root hangs from (read when it hangs from no
            parent).
    """

    def __init__(self, c, dc, c_dot, c_ddot, offset, ground):
        as_c = lambda x: np.ascontiguousarray(x, dtype=float)
        self.c, self.dc, self.c_dot, self.c_ddot = as_c(c), as_c(dc), as_c(c_dot), as_c(c_ddot)
        self.offset, self.ground = offset, as_c(ground)


_N, _ARRAY = ctypes.c_long, ctypes.c_void_p   # a count; a C-contiguous array, passed as its data address
SIGNATURES = {"body_kinematics": (_N, [_N] * 5 + [_ARRAY] * 3 + [_N] * 2 + [_ARRAY] * 13),
              "element_transfers": (_N, [_N, _ARRAY, _N] + [_ARRAY] * 7)}
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


def joint_terms(kind, eta, rate, axis, orientation):
    """c(eta), d c / d eta_k, dc/dt and d2 c/dt2 (at zero parameter acceleration) of a joint.

    revolute (Otsuka et al. 2022, Eq. 15 for the chord axis): F_child = F_parent R(axis, theta) orientation,
    c = orientation^T R^T; ball (Eqs. 19-21): F_child = F_parent R(zeta), c = R(zeta)^T; universal (Eqs. 16-17):
    c = mu, the nine direction cosines row by row; fixed: c = orientation^T.

    Args:
        kind: the joint's kind: "revolute", "ball", "universal"; any other is fixed.
        eta: (n_eta,) the joint parameters.
        rate: (n_eta,) their rates, per s.
        axis: (3,) unit revolute axis, parent frame.
        orientation: (3, 3) the child's frame relative to the parent's at eta's origin.

    Returns:
        (c (3, 3), dc (n_eta, 3, 3), c' (3, 3) per s, c'' (3, 3) per s^2).
    """
    if kind == "revolute":
        k = skew(axis)
        R = rodrigues(k, k @ k, np.sin(eta[0]), np.cos(eta[0]))
        dR = k @ R
        dc = orientation.T @ dR.T
        return orientation.T @ R.T, dc[None], dc * rate[0], orientation.T @ (k @ dR).T * rate[0] ** 2
    if kind == "ball":
        dc = quaternion_gradient(eta).transpose(0, 2, 1)
        return quaternion_matrix(eta).T, dc, np.einsum("k,kij->ij", rate, dc), 2.0 * quaternion_matrix(rate).T
    if kind == "universal":
        return eta.reshape(3, 3).copy(), np.eye(9).reshape(9, 3, 3), rate.reshape(3, 3).copy(), np.zeros((3, 3))
    return orientation.T.copy(), np.zeros((0, 3, 3)), np.zeros((3, 3)), np.zeros((3, 3))


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
