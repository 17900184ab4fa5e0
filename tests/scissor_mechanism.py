"""A rigid planar linear array of scissor-like elements (SLEs) in one degree of freedom: the independent reference
of the deployment of Peng et al. 2019, Sec. 5 (not a test module).

The mechanism. A deployment direction d and a height direction h (unit, perpendicular; world frame) span the
plane of motion. n SLEs of uniform rigid bars, each of length L (m) and mass m (kg), all at the angle theta (rad)
to d; w = L cos(theta), H = L sin(theta). SLE i (i = 0..n-1) has
    bar "up_i":   from b_{i+1} = origin + i w d         to a_{i+2} = origin + (i+1) w d + H h,
    bar "down_i": from a_{i+1} = origin + i w d + H h   to b_{i+2} = origin + (i+1) w d,
pinned to each other at their common midpoint c_{i+1} = origin + (i + 1/2) w d + H/2 h (the points named as in
Peng et al. 2019, Sec. 5: upper ends a_1..a_{n+1}, lower ends b_1..b_{n+1}, mid pivots c_1..c_n). b_1 is pinned
to the ground at the origin and a_1 slides on the line through the origin along h. A force F >= 0 (N) pushes a_1
towards b_1 (along -h): theta falls and the array deploys along d. Gravity g (m/s^2, world) is optional; only its
components g_d = g . d and g_h = g . h do work.

Kinetic energy (Lagrange, the single coordinate theta). Both bars of SLE i have their centre at c_{i+1}, whose
velocity is L theta' (-(i + 1/2) sin(theta) d + cos(theta)/2 h); the up bar lies along (cos, sin), the down bar
along (cos, -sin), so each turns at the rate |theta'|. With each bar's energy
1/2 m |v_centre|^2 + 1/2 (m L^2 / 12) theta'^2 + 1/2 rho I L theta'^2 (rho I, kg m: an optional rotary inertia
of the section per length, `rotary`), and sum_{i<n} (i + 1/2)^2 = n (4 n^2 - 1) / 12:
    T = J(theta) theta'^2 / 2,   J = (2 n m L^2 / 3) (1 + (n^2 - 1) sin^2 theta) + 2 n rho I L      (kg m^2),
    dJ/dtheta = (2 n m L^2 / 3) (n^2 - 1) sin(2 theta).
(n = 1: the up bar turns about b_1, m L^2 / 3; the down bar, a ladder, about the corner (w, H), m L^2 / 3.)
Generalized force (virtual work; a_1 = origin + L sin(theta) h, sum_{i<n} (i + 1/2) = n^2 / 2):
    Q = -F L cos(theta) + n m L (g_h cos(theta) - n g_d sin(theta))                                     (N m).
Equation of motion, d/dt(J theta') - J' theta'^2 / 2 = Q:
    J theta'' + J'(theta) theta'^2 / 2 = Q(theta),
and, from rest at theta_0, its first integral J theta'^2 / 2 = W(theta) with the work done since the start
    W = F L (sin theta_0 - sin theta) + n m L (g_h (sin theta - sin theta_0) + n g_d (cos theta - cos theta_0)).
The slider travel of a_1 towards b_1 is L (sin theta_0 - sin theta).

Integration: scipy's DOP853 on (theta, theta') from rest, rtol = atol = 1e-12 by default. theta = 0 (all bars
along d: the array fully flat, a_k on b_k's line) and theta = pi/2 (all bars along h: fully folded) are singular
configurations of the mechanism; the integration stops there cleanly by a terminal event and the result says so.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.integrate import solve_ivp

RTOL, ATOL = 1e-12, 1e-12
STOPS = ("flat", "folded")      # theta = 0 and theta = pi/2


@dataclass(frozen=True)
class Mechanism:
    """The array's data, checked: n SLEs, bar length L (m), bar mass m (kg), force F on a_1 (N, >= 0), gravity
    (m/s^2, world), unit perpendicular d and h (world), rotary inertia rho I per bar (kg m, >= 0)."""
    n: int
    L: float
    m: float
    F: float
    gravity: np.ndarray
    d: np.ndarray
    h: np.ndarray
    rotary: float

    @classmethod
    def of(cls, n, L, m, F=0.0, gravity=(0.0, 0.0, 0.0), d=(1.0, 0.0, 0.0), h_ax=(0.0, 1.0, 0.0),
           rotary=0.0) -> Mechanism:
        if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
            raise ValueError(f"n (the number of SLEs) must be a positive integer, got {n!r}")
        for name, value in (("L", L), ("m", m)):
            if not np.isfinite(value) or not value > 0:
                raise ValueError(f"{name} must be positive and finite, got {value!r}")
        for name, value in (("F", F), ("rotary", rotary)):
            if not np.isfinite(value) or value < 0:
                raise ValueError(f"{name} must be non-negative and finite, got {value!r}")
        gravity = _vector("gravity", gravity)
        d, h = _directions(d, h_ax)
        return cls(int(n), float(L), float(m), float(F), gravity, d, h, float(rotary))

    @property
    def g_d(self) -> float:
        return float(self.gravity @ self.d)

    @property
    def g_h(self) -> float:
        return float(self.gravity @ self.h)


@dataclass(frozen=True)
class Deployment:
    """A run from rest: times t (s), theta (rad) and dtheta (rad/s) at them; `stop` is None, "flat" (theta reached
    0) or "folded" (theta reached pi/2), `stop_time` (s) the time of that event (None without one). After a stop
    the samples end at the last requested time before it."""
    t: np.ndarray
    theta: np.ndarray
    dtheta: np.ndarray
    stop: str | None
    stop_time: float | None


@dataclass(frozen=True)
class Energies:
    """Kinetic energy (J) and the work (J) done since theta_0 by F and by gravity; `balance` = kinetic - work."""
    kinetic: np.ndarray
    work_force: np.ndarray
    work_gravity: np.ndarray

    @property
    def balance(self) -> np.ndarray:
        return self.kinetic - self.work_force - self.work_gravity


def _vector(name, value) -> np.ndarray:
    v = np.asarray(value, dtype=float)
    if v.shape != (3,) or not np.all(np.isfinite(v)):
        raise ValueError(f"{name} must be a finite 3-vector, got {value!r}")
    return v


def _directions(d, h_ax):
    d, h = _vector("d", d), _vector("h_ax", h_ax)
    for name, v in (("d", d), ("h_ax", h)):
        if abs(np.linalg.norm(v) - 1.0) > 1e-12:
            raise ValueError(f"{name} must be a unit vector, got {v.tolist()} (norm {np.linalg.norm(v)!r})")
    if abs(d @ h) > 1e-12:
        raise ValueError(f"d and h_ax must be perpendicular, got d . h_ax = {d @ h!r}")
    return d, h


def _start_angle(theta0) -> float:
    if not 0.0 < theta0 < np.pi / 2:
        raise ValueError(f"theta0 must lie strictly between 0 and pi/2 rad, got {theta0!r}")
    return float(theta0)


def inertia(theta, n, L, m, rotary=0.0):
    """J(theta) (kg m^2) and dJ/dtheta (kg m^2/rad) of the array of n SLEs, bars of length L (m) and mass m (kg),
    rotary inertia rho I (kg m) per bar; theta (rad) a scalar or an array."""
    theta = np.asarray(theta, dtype=float)
    scale = 2.0 * n * m * L**2 / 3.0
    J = scale * (1.0 + (n**2 - 1) * np.sin(theta) ** 2) + 2.0 * n * rotary * L
    return J, scale * (n**2 - 1) * np.sin(2.0 * theta)


def generalized_force(theta, mech: Mechanism):
    """Q(theta) (N m): the virtual work of F on a_1 and of gravity on the bars per unit delta theta."""
    theta = np.asarray(theta, dtype=float)
    c, s = np.cos(theta), np.sin(theta)
    return -mech.F * mech.L * c + mech.n * mech.m * mech.L * (mech.g_h * c - mech.n * mech.g_d * s)


def angular_acceleration(theta, dtheta, mech: Mechanism):
    """theta'' (rad/s^2) = (Q - J' theta'^2 / 2) / J."""
    J, dJ = inertia(theta, mech.n, mech.L, mech.m, mech.rotary)
    return (generalized_force(theta, mech) - 0.5 * dJ * np.asarray(dtheta) ** 2) / J


def _integrate(theta0, t_end, mech: Mechanism, t_eval, rtol, atol, extra_events=()):
    def rhs(t, y):
        return [y[1], angular_acceleration(y[0], y[1], mech)]

    def flat(t, y):
        return y[0]

    def folded(t, y):
        return y[0] - np.pi / 2

    for event, direction in ((flat, -1.0), (folded, 1.0)):
        event.terminal, event.direction = True, direction
    return solve_ivp(rhs, (0.0, t_end), [theta0, 0.0], method="DOP853", t_eval=t_eval, rtol=rtol, atol=atol,
                     events=[flat, folded, *extra_events])


def simulate(theta0, t_end, n, L, m, F, gravity=(0.0, 0.0, 0.0), d=(1.0, 0.0, 0.0), h_ax=(0.0, 1.0, 0.0),
             rotary=0.0, t_eval=None, rtol=RTOL, atol=ATOL) -> Deployment:
    """Integrate J theta'' + J' theta'^2 / 2 = Q from rest at theta0 (rad, in (0, pi/2)) to t_end (s) by DOP853;
    the samples at t_eval (s, sorted, within [0, t_end]) or at the integrator's steps. Stops at theta = 0 or pi/2
    (see Deployment)."""
    theta0 = _start_angle(theta0)
    mech = Mechanism.of(n, L, m, F, gravity, d, h_ax, rotary)
    if not np.isfinite(t_end) or not t_end > 0:
        raise ValueError(f"t_end must be a positive time in s, got {t_end!r}")
    if t_eval is not None:
        t_eval = np.asarray(t_eval, dtype=float)
        if t_eval.ndim != 1 or t_eval.size == 0 or t_eval[0] < 0 or t_eval[-1] > t_end \
                or np.any(np.diff(t_eval) < 0):
            raise ValueError("t_eval must be a non-empty, non-decreasing 1-D array of times within [0, t_end] s")
    sol = _integrate(theta0, float(t_end), mech, t_eval, rtol, atol)
    if sol.status < 0:
        raise RuntimeError(f"the scissor reference's integration failed: {sol.message}")
    stop, stop_time = None, None
    for name, times in zip(STOPS, sol.t_events):
        if times.size:
            stop, stop_time = name, float(times[0])
    return Deployment(sol.t, sol.y[0], sol.y[1], stop, stop_time)


def time_to_angle(theta0, theta1, n, L, m, F, gravity=(0.0, 0.0, 0.0), d=(1.0, 0.0, 0.0), h_ax=(0.0, 1.0, 0.0),
                  rotary=0.0, t_max=60.0, rtol=RTOL, atol=ATOL) -> float:
    """The time (s) at which theta, from rest at theta0, first reaches theta1 (rad, in (0, pi/2)); a RuntimeError
    if it does not within t_max (s) or the mechanism reaches a singular configuration first."""
    theta0, theta1 = _start_angle(theta0), _start_angle(theta1)
    if theta1 == theta0:
        return 0.0
    mech = Mechanism.of(n, L, m, F, gravity, d, h_ax, rotary)

    def reached(t, y):
        return y[0] - theta1

    reached.terminal, reached.direction = True, (1.0 if theta1 > theta0 else -1.0)
    sol = _integrate(theta0, float(t_max), mech, None, rtol, atol, extra_events=(reached,))
    if sol.status < 0:
        raise RuntimeError(f"the scissor reference's integration failed: {sol.message}")
    if not sol.t_events[2].size:
        raise RuntimeError(f"theta did not reach {theta1!r} rad within {t_max!r} s (it ended at {sol.y[0, -1]!r})")
    return float(sol.t_events[2][0])


def points(theta, n, L, origin=(0.0, 0.0, 0.0), d=(1.0, 0.0, 0.0), h_ax=(0.0, 1.0, 0.0)) -> dict:
    """Positions (m, world), shape theta.shape + (3,), of the upper ends "a1".."a{n+1}", the lower ends
    "b1".."b{n+1}" and the mid pivots "c1".."cn" at the angle theta (rad)."""
    d, h = _directions(d, h_ax)
    origin = _vector("origin", origin)
    theta = np.asarray(theta, dtype=float)[..., None]
    w, H = L * np.cos(theta), L * np.sin(theta)
    out = {}
    for k in range(1, n + 2):
        out[f"a{k}"] = origin + (k - 1) * w * d + H * h
        out[f"b{k}"] = origin + (k - 1) * w * d
    for k in range(1, n + 1):
        out[f"c{k}"] = origin + (k - 0.5) * w * d + 0.5 * H * h
    return out


def slider_travel(theta, theta0, L):
    """How far (m) a_1 has moved towards b_1 since theta0: L (sin theta0 - sin theta)."""
    return L * (np.sin(theta0) - np.sin(np.asarray(theta, dtype=float)))


def energy(theta, dtheta, theta0, n, L, m, F, gravity=(0.0, 0.0, 0.0), d=(1.0, 0.0, 0.0), h_ax=(0.0, 1.0, 0.0),
           rotary=0.0) -> Energies:
    """Kinetic energy J theta'^2 / 2 and the work since theta0 (rad) of F, F L (sin theta0 - sin theta), and of
    gravity, n m L (g_h (sin theta - sin theta0) + n g_d (cos theta - cos theta0)) (all J)."""
    mech = Mechanism.of(n, L, m, F, gravity, d, h_ax, rotary)
    theta = np.asarray(theta, dtype=float)
    J, _ = inertia(theta, n, L, m, rotary)
    work_gravity = n * m * L * (mech.g_h * (np.sin(theta) - np.sin(theta0))
                                + n * mech.g_d * (np.cos(theta) - np.cos(theta0)))
    return Energies(0.5 * J * np.asarray(dtheta) ** 2, F * slider_travel(theta, theta0, L), work_gravity)
