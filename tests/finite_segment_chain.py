"""A planar finite-segment model of Otsuka et al. 2022's two-body system (Sec. 4.4, Table 4), the independent
reference for the RMS of its free end's Z (Eq. 24) (not a test module).

The system: two bodies A and B, each L = 10 m long, bending stiffness EI = 1e4 N m^2, mass per length
rho A = 1 kg/m, rotary inertia per length rho I = 0.1 kg m; A clamped at the origin along +X, B hinged to A's
tip about Y (no spring, no damping), initially along +X too; gravity 9.8 m/s^2 along -Z; released from rest.
The motion stays in the X-Z plane; the beams are inextensible and shear-rigid (Euler-Bernoulli with rotary
inertia), as Table 4 gives no axial or shear stiffness.

Model: each body is N rigid segments of length l = L / N. A segment of length l has mass rho A l and rotary
inertia about its centre rho A l^3 / 12 + rho I l. Coordinates are the absolute segment angles theta_k, the
segment direction being e_k = (cos theta_k, sin theta_k) in (X, Z). Neighbouring segments of a body are
pinned end to end with rotational springs of stiffness EI / l (the relative angle at a joint is the curvature
integrated over the length l between the two segment centres). A's first segment is pinned to the clamp with
a spring of 2 EI / l: its angle is the chord slope at s = l / 2, so the clamp spring spans half a segment.
With these springs the linear static tip deflection of a cantilever under a uniform load q is q l / (2 EI)
times the trapezoidal rule of int_0^L (L - s)^3 ds, which converges to q L^4 / (8 EI) as 1/N^2 (a clamp
spring of EI / l adds q L^3 l / (4 EI): first order). The hinge between A and B has no spring.

Equations of motion (Lagrange, minimal coordinates): with the constant matrix
    mu_ij = sum_k m_k a_ki a_kj,  a_ki = l_i (i < k), l_k / 2 (i = k), 0 (i > k),
the mass matrix is M_ij = mu_ij cos(theta_i - theta_j) + delta_ij J_i and
    sum_j M_ij theta_j'' + sum_j mu_ij sin(theta_i - theta_j) theta_j'^2 + g w_i cos(theta_i) + (K theta)_i = 0,
w_i = sum_k m_k a_ki, K the spring chain's stiffness matrix (`lagrange_accelerations`). The integration
solves the same equations in O(N) as the Newton-Euler equations of the segments with the pin forces as
unknowns, a banded linear system (`accelerations`; the two agree to round-off, tests/units). The state is
(theta, theta'); scipy's DOP853 at rtol 1e-9, atol 1e-11. The springs' highest frequencies, about
(2 / l) sqrt(EI / rho I) (1.5e3 rad/s at N = 25), set the step, so the cost grows as N^2.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.integrate import solve_ivp
from scipy.linalg.lapack import dgbsv
from threadpoolctl import threadpool_limits

LENGTH = 10.0       # m, each body
EI = 1e4            # N m^2
RHO_A = 1.0         # kg/m
RHO_I = 0.1         # kg m
GRAVITY = 9.8       # m/s^2, along -Z
RTOL, ATOL = 1e-9, 1e-11
SAMPLES = np.linspace(0.0, 5.0, 501)   # s, Otsuka et al. 2022, Eq. 24: 0 to 5 s every 0.01 s
REFINEMENT = (25, 50, 100, 200)        # segments per body of the extrapolation


@dataclass(frozen=True)
class Chain:
    """`bodies` bodies of n segments each: segment lengths l (m), masses m (kg), rotary inertias J about the
    centres (kg m^2), the stiffness k_j (N m/rad) of the spring between segment j - 1 and j (k_0: to the
    clamp; 0 across the hinge), and the constant matrices mu (kg m^2), K (N m/rad) and weights w (kg m)."""
    n: int
    bodies: int
    l: np.ndarray
    m: np.ndarray
    J: np.ndarray
    k: np.ndarray
    mu: np.ndarray
    K: np.ndarray
    w: np.ndarray

    @property
    def size(self) -> int:
        return self.l.size


def chain(n_segments: int, bodies: int = 2, rho_i: float = RHO_I, clamp_factor: float = 2.0) -> Chain:
    """The model with `n_segments` segments per body and `bodies` bodies (2: Table 4's system; 1: body A alone,
    a cantilever), section rotary inertia `rho_i` (kg m) and a clamp spring of clamp_factor EI / l (2: the
    consistent value, see the module's docstring)."""
    if isinstance(n_segments, bool) or int(n_segments) != n_segments or n_segments < 1:
        raise ValueError(f"n_segments must be a positive integer, got {n_segments!r}")
    if bodies not in (1, 2):
        raise ValueError(f"bodies must be 1 (A alone) or 2 (A and B), got {bodies!r}")
    if not rho_i >= 0 or not clamp_factor > 0:
        raise ValueError(f"rho_i must be >= 0 and clamp_factor > 0, got {rho_i!r} and {clamp_factor!r}")
    n_segments = int(n_segments)
    size = bodies * n_segments
    l = np.full(size, LENGTH / n_segments)
    m = RHO_A * l
    J = m * l**2 / 12 + rho_i * l
    k = EI / l
    k[0] *= clamp_factor
    k[n_segments::n_segments] = 0.0           # the hinge at A's tip
    # a[k, i]: the lever of segment i's angle in segment k's centre.
    a = np.tril(np.broadcast_to(l, (size, size)), -1) + np.diag(l / 2)
    K = np.diag(k + np.append(k[1:], 0.0)) - np.diag(k[1:], 1) - np.diag(k[1:], -1)
    return Chain(n_segments, bodies, l, m, J, k, a.T @ (m[:, None] * a), K, a.T @ m)


def mass_matrix(c: Chain, theta: np.ndarray) -> np.ndarray:
    """M(theta) (kg m^2)."""
    return c.mu * np.cos(theta[:, None] - theta[None, :]) + np.diag(c.J)


def energy(c: Chain, theta: np.ndarray, omega: np.ndarray) -> float:
    """Kinetic + gravity + spring energy (J), with zero gravity potential at Z = 0."""
    z = np.cumsum(c.l * np.sin(theta)) - c.l / 2 * np.sin(theta)     # segment centres' Z
    return 0.5 * omega @ mass_matrix(c, theta) @ omega + GRAVITY * c.m @ z + 0.5 * theta @ c.K @ theta


def free_end(c: Chain, theta: np.ndarray) -> np.ndarray:
    """(X, Z) of the chain's free end (m) for angles theta of shape (size,) or (size, samples)."""
    return np.array([c.l @ np.cos(theta), c.l @ np.sin(theta)])


def lagrange_accelerations(c: Chain, theta: np.ndarray, omega: np.ndarray) -> np.ndarray:
    """theta'' (rad/s^2) from the assembled mass matrix: M theta'' = -centrifugal - gravity - springs."""
    w2 = omega**2
    centrifugal = c.mu * np.sin(theta[:, None] - theta[None, :]) @ w2
    return np.linalg.solve(mass_matrix(c, theta), -centrifugal - GRAVITY * c.w * np.cos(theta) - c.K @ theta)


def _spring_moments(c: Chain, theta: np.ndarray) -> np.ndarray:
    """-K theta (N m) in O(N)."""
    moment = c.k * np.diff(theta, prepend=0.0)
    return np.append(moment[1:], 0.0) - moment


class _BandedDynamics:
    """The segments' Newton-Euler equations with the pin forces as unknowns, per segment k [F_k (2), alpha_k]:
    F_k the force of segment k - 1 (the clamp for k = 0) on k at k's start, alpha_k = theta_k''. With the
    centre's acceleration a_k = (F_k - F_(k+1)) / m_k + g substituted, the rows per segment are the pin k's
    acceleration constraint (2), a_k - h_k e_k' alpha_k - a_(k-1) - h_(k-1) e_(k-1)' alpha_(k-1) =
    -h_k e_k w_k^2 - h_(k-1) e_(k-1) w_(k-1)^2, and J_k alpha_k + h_k e_k x (F_k + F_(k+1)) = spring moments,
    with h_k = l_k / 2, e' = (-sin, cos), e x F = e_X F_Z - e_Z F_X. Bandwidth 3 below and above the diagonal."""

    BAND = 3

    def __init__(self, c: Chain):
        self.c, n = c, c.size
        base = 3 * np.arange(n)
        inner, first = base[1:], base[:-1]   # segments with a predecessor, segments with a successor
        entries = [  # (rows, columns): the order of `_values`
            (base, base), (base + 1, base + 1), (first, first + 3), (first + 1, first + 4),
            (inner, inner - 3), (inner + 1, inner - 2), (base, base + 2), (base + 1, base + 2),
            (inner, inner - 1), (inner + 1, inner - 1),
            (base + 2, base + 2), (base + 2, base), (base + 2, base + 1), (first + 2, first + 3),
            (first + 2, first + 4)]
        rows = np.concatenate([r for r, _ in entries])
        cols = np.concatenate([col for _, col in entries])
        # LAPACK's gbsv storage: A[i, j] in row 2 BAND + i - j of column j (BAND rows left for the fill-in)
        self.flat = (2 * self.BAND + rows - cols) * (3 * n) + cols
        self.base = base
        diagonal = 1 / c.m + np.append(0.0, 1 / c.m[:-1])
        self.fixed = np.concatenate((diagonal, diagonal, -1 / c.m[:-1], -1 / c.m[:-1], -1 / c.m[:-1],
                                     -1 / c.m[:-1]))

    def accelerations(self, theta: np.ndarray, omega: np.ndarray) -> np.ndarray:
        c, n, base = self.c, self.c.size, self.base
        cos, sin = np.cos(theta), np.sin(theta)
        hs, hc = c.l / 2 * sin, c.l / 2 * cos
        ab = np.zeros((3 * self.BAND + 1) * 3 * n)
        ab[self.flat] = np.concatenate((self.fixed, hs, -hc, hs[:-1], -hc[:-1], c.J, -hs, hc, -hs[:-1], hc[:-1]))
        hw2 = c.l / 2 * omega**2
        rhs = np.empty(3 * n)
        rhs[base] = -hw2 * cos - np.append(0.0, (hw2 * cos)[:-1])
        rhs[base + 1] = -hw2 * sin - np.append(0.0, (hw2 * sin)[:-1]) + GRAVITY   # the clamp side's -g moved over
        rhs[base[1:] + 1] -= GRAVITY                                                # g cancels between segments
        rhs[base + 2] = _spring_moments(c, theta)
        _, _, x, info = dgbsv(self.BAND, self.BAND, ab.reshape(3 * self.BAND + 1, 3 * n), rhs)
        if info != 0:
            raise np.linalg.LinAlgError(f"the chain's Newton-Euler system is singular (LAPACK gbsv info {info})")
        return x[base + 2]


def accelerations(c: Chain, theta: np.ndarray, omega: np.ndarray) -> np.ndarray:
    """theta'' (rad/s^2) by the banded Newton-Euler system (equal to `lagrange_accelerations`)."""
    return _BandedDynamics(c).accelerations(theta, omega)


def simulate(c: Chain, times) -> np.ndarray:
    """Angles and rates (rad, rad/s), shape (2 size, len(times)), of the chain released from rest, straight
    along +X, sampled at `times` (s, increasing, >= 0)."""
    times = np.asarray(times, dtype=float)
    if times.ndim != 1 or times.size == 0 or times[0] < 0 or np.any(np.diff(times) <= 0):
        raise ValueError("times must be a non-empty, increasing 1-D array of non-negative seconds")
    y0 = np.zeros(2 * c.size)
    if times[-1] == 0:
        return y0[:, None]
    dynamics, n = _BandedDynamics(c), c.size

    def rhs(t, y):
        return np.concatenate((y[n:], dynamics.accelerations(y[:n], y[n:])))

    # one BLAS thread: the kernels are small, and a threaded pool on shared cores is far slower
    with threadpool_limits(limits=1, user_api="blas"):
        sol = solve_ivp(rhs, (0.0, times[-1]), y0, method="DOP853", t_eval=times, rtol=RTOL, atol=ATOL)
    if not sol.success:
        raise RuntimeError(f"the finite-segment chain's integration failed: {sol.message}")
    return sol.y


_RMS: dict[int, float] = {}


def free_end_z(n_segments: int, times) -> np.ndarray:
    """Z (m) of B's free end at `times` (s) with `n_segments` segments per body."""
    c = chain(n_segments)
    return free_end(c, simulate(c, times)[:c.size])[1]


def rms_free_end_z(n_segments: int) -> float:
    """sqrt(mean(Z^2)) (m) of B's free end over t = 0, 0.01, ..., 5 s (Otsuka et al. 2022, Eq. 24), computed
    once per process for each `n_segments`."""
    if n_segments not in _RMS:
        _RMS[n_segments] = float(np.sqrt(np.mean(free_end_z(n_segments, SAMPLES) ** 2)))
    return _RMS[n_segments]


@dataclass(frozen=True)
class Extrapolation:
    """The RMS (m) extrapolated to N -> infinity, its error estimate (m), the observed order p of the error
    C / N^p, and the raw values (m) per N (see `richardson`)."""
    value: float
    error: float
    order: float
    segments: tuple
    rms: tuple


def richardson(segments, values) -> tuple[float, float, float]:
    """(limit, observed order, error estimate) of values at N = segments, each twice the previous. The finest
    three give the order p = log2(d1 / d2) of the differences d1, d2 and the limit v3 + d2 / (2^p - 1). The
    error estimate is the change from the limit of the previous three (four or more values), else the
    distance of the finest value from the limit."""
    segments, values = np.asarray(segments, dtype=float), np.asarray(values, dtype=float)
    if segments.size < 3 or np.any(np.abs(segments[1:] / segments[:-1] - 2) > 1e-12):
        raise ValueError(f"need three or more segment counts, each twice the previous, got {segments.tolist()}")

    def triple(v):
        d1, d2 = v[1] - v[0], v[2] - v[1]
        if not d1 / d2 > 1:
            raise ValueError(f"the values {v.tolist()} do not converge monotonically: no order to observe")
        return v[2] + d2 / (d1 / d2 - 1), np.log2(d1 / d2)

    limit, order = triple(values[-3:])
    error = abs(limit - triple(values[-4:-1])[0]) if values.size >= 4 else abs(limit - values[-1])
    return float(limit), float(order), float(error)


def extrapolated_rms(segments=REFINEMENT) -> Extrapolation:
    """Richardson extrapolation of `rms_free_end_z` over `segments` (each twice the previous)."""
    rms = tuple(rms_free_end_z(n) for n in segments)
    value, order, error = richardson(segments, rms)
    return Extrapolation(value, error, order, tuple(segments), rms)
