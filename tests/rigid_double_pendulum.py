"""A rigid spatial double pendulum: the independent reference of Otsuka et al. 2022, Secs. 4.1-4.3 (not a test module).

Two uniform bars A and B, each of length L = 1.8 m and a square steel section of side a (Table 3's second
moments fit a = 2 cm; density 7800 kg/m^3). Bar A hangs from a ball joint at the origin and lies along +X;
bar B starts along +Z from A's tip P = (L, 0, 0). Body frames at t = 0: A's (x, y, z) = (X, Y, Z), B's
(x, y, z) = (Z, Y, -X); each bar lies along its own x axis. Gravity 9.8 m/s^2 along -Y; released from rest.
The joint between A's tip P and B's root Q is one of
  - "ball": P = Q;
  - "universal": P = Q and y_A . z_B = 0 (the cross of the joint is A's y axis and B's z axis);
  - "revolute": P = Q and z_B = -x_A (B turns relative to A about A's x axis only), imposed as
    x_A . x_B = 0 and x_A . y_B = 0 from the anti-parallel start.

Formulation (independent of wingsim's beam models): Newton-Euler equations of two rigid bodies in maximal
coordinates, centre of mass c (world, m), unit quaternion q (body to world), velocity v (world, m/s) and
angular velocity w (body frame, rad/s):
    m dv/dt = m g + constraint forces,   J dw/dt + w x J w = constraint torques,   dq/dt = q (x) (0, w) / 2,
with the joints as Lagrange multipliers solved at acceleration level, G a = -dG/dt v, stabilized by
Baumgarte's terms -2 xi omega dPhi/dt - omega^2 Phi, and the quaternion norm pulled back to 1. Integrated by
scipy's DOP853 at rtol 1e-10, atol 1e-12. Bar inertia about its centre, in its own frame: axial m a^2 / 6,
transverse m L^2 / 12 + m a^2 / 12 (a box of L x a x a).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.integrate import solve_ivp

LENGTH = 1.8            # m, each bar
SIDE = 0.02             # m, square section side
DENSITY = 7800.0        # kg/m^3
GRAVITY = np.array([0.0, -9.8, 0.0])  # m/s^2
JOINTS = ("ball", "universal", "revolute")
RTOL, ATOL = 1e-10, 1e-12
# Baumgarte stabilization of the joint drift: a critically damped pull-back at BAUMGARTE rad/s.
BAUMGARTE = 10.0

_EX, _EY, _EZ = np.eye(3)
_ROOT = np.array([-LENGTH / 2, 0.0, 0.0])   # a bar's root from its centre, body frame
_END = np.array([LENGTH / 2, 0.0, 0.0])     # a bar's free end from its centre, body frame
# The axis products held at zero, (A's axis, B's axis) in the body frames. The revolute's z_B = -x_A is imposed
# as x_A . x_B = 0 and x_A . y_B = 0: their constraint torques x_A x (.) never act about x_A, so A's spin about
# its own axis stays free even while the products drift (the pair y_A . z_B, z_A . z_B would torque A's tiny
# axial inertia in proportion to that drift: a stiff, spurious coupling).
_AXIS_PAIRS = {"ball": [], "universal": [(_EY, _EZ)], "revolute": [(_EX, _EX), (_EX, _EY)]}


@dataclass(frozen=True)
class Bars:
    """Mass (kg) and principal inertia about the centre (kg m^2, body frame: axial x, transverse y, z)."""
    mass: float
    inertia: np.ndarray

    @classmethod
    def of_side(cls, side: float) -> Bars:
        if not side > 0:
            raise ValueError(f"side must be a positive length in m, got {side!r}")
        m = DENSITY * side**2 * LENGTH
        transverse = m * LENGTH**2 / 12 + m * side**2 / 12
        return cls(m, np.array([m * side**2 / 6, transverse, transverse]))


@dataclass(frozen=True)
class Motion:
    """Samples of a run at `times` (s): B's free end (m, world), energies (J), the angular momentum about the
    fixed pivot (kg m^2/s, world; its Y component is conserved: gravity along -Y and the pivot exert no torque
    about Y), the joint residuals |P - Q| (m), y_A . z_B, z_A . z_B, |z_B + x_A|, and y_A . x_B (free in every
    variant: the product Otsuka et al. 2022, Sec. 4.2 shows reaching 1 for the universal joint)."""
    times: np.ndarray
    tip: np.ndarray
    kinetic: np.ndarray
    potential: np.ndarray
    angular_momentum: np.ndarray
    point_mismatch: np.ndarray
    ya_zb: np.ndarray
    za_zb: np.ndarray
    revolute_axis: np.ndarray
    ya_xb: np.ndarray

    @property
    def energy(self) -> np.ndarray:
        return self.kinetic + self.potential


def rotation(q: np.ndarray) -> np.ndarray:
    """Rotation matrix (body to world) of the quaternion q = (w, x, y, z), normalized first."""
    w, x, y, z = q / np.sqrt(q @ q)
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


def _skew(s: np.ndarray) -> np.ndarray:
    return np.array([[0.0, -s[2], s[1]], [s[2], 0.0, -s[0]], [-s[1], s[0], 0.0]])


def _quaternion_rate(q: np.ndarray, w: np.ndarray) -> np.ndarray:
    """dq/dt = q (x) (0, w) / 2 for the body-frame rate w, plus a pull of |q| back to 1."""
    s, v = q[0], q[1:]
    rate = 0.5 * np.concatenate(([-v @ w], s * w + np.cross(v, w)))
    return rate + BAUMGARTE * (1.0 - q @ q) * q


def initial_state() -> np.ndarray:
    """[c_A, q_A, c_B, q_B, v_A, w_A, v_B, w_B] at rest in the starting pose (B's frame: Y turned by -90 deg)."""
    half = np.sqrt(0.5)
    return np.concatenate(([LENGTH / 2, 0, 0], [1, 0, 0, 0], [LENGTH, 0, LENGTH / 2], [half, 0, -half, 0],
                           np.zeros(12)))


def _unpack(y: np.ndarray):
    return y[0:3], y[3:7], y[7:10], y[10:14], y[14:17], y[17:20], y[20:23], y[23:26]


def _point_rows(RA, RB, wA, wB):
    """The shared point c_A + R_A s_P = c_B + R_B s_Q: Jacobian on (v_A, w_A, v_B, w_B) and -d(G)/dt v."""
    G = np.hstack([np.eye(3), -RA @ _skew(_END), -np.eye(3), RB @ _skew(_ROOT)])
    gamma = -RA @ np.cross(wA, np.cross(wA, _END)) + RB @ np.cross(wB, np.cross(wB, _ROOT))
    return G, gamma


def _dot_row(RA, RB, wA, wB, a, b):
    """The product (R_A a) . (R_B b) = 0: its Jacobian row and -d(G)/dt v (body-fixed unit vectors a, b)."""
    u, w = RA @ a, RB @ b
    OA, OB = RA @ wA, RB @ wB
    n = np.cross(u, w)
    row = np.concatenate((np.zeros(3), n @ RA, np.zeros(3), -n @ RB))
    gamma = -(np.cross(np.cross(OA, u), w) + np.cross(u, np.cross(OB, w))) @ (OA - OB)
    return row, gamma


def _constraints(y: np.ndarray, joint: str):
    """Residuals Phi, Jacobian G (on the 12 velocities) and gamma = -dG/dt v of every constraint."""
    cA, qA, cB, qB, vA, wA, vB, wB = _unpack(y)
    RA, RB = rotation(qA), rotation(qB)
    point_rows, point_gamma = _point_rows(RA, RB, wA, wB)
    phi = [cA + RA @ _ROOT, cA + RA @ _END - cB - RB @ _ROOT]
    rows = [np.hstack([np.eye(3), -RA @ _skew(_ROOT), np.zeros((3, 6))]), point_rows]
    gammas = [-RA @ np.cross(wA, np.cross(wA, _ROOT)), point_gamma]
    for a, b in _AXIS_PAIRS[joint]:
        row, gamma = _dot_row(RA, RB, wA, wB, a, b)
        phi.append([(RA @ a) @ (RB @ b)])
        rows.append(row[None, :])
        gammas.append([gamma])
    return np.concatenate(phi), np.vstack(rows), np.concatenate(gammas)


def _rhs(bars: Bars, joint: str):
    m, J = bars.mass, bars.inertia
    inverse_mass = np.concatenate((np.full(3, 1 / m), 1 / J, np.full(3, 1 / m), 1 / J))

    def rhs(t, y):
        cA, qA, cB, qB, vA, wA, vB, wB = _unpack(y)
        v = y[14:26]
        f = np.concatenate((m * GRAVITY, -np.cross(wA, J * wA), m * GRAVITY, -np.cross(wB, J * wB)))
        phi, G, gamma = _constraints(y, joint)
        target = gamma - 2 * BAUMGARTE * (G @ v) - BAUMGARTE**2 * phi
        # M a + G^T lambda = f, G a = target, with M diagonal: the multipliers from the Schur complement.
        GM = G * inverse_mass
        lam = np.linalg.solve(GM @ G.T, GM @ f - target)
        a = inverse_mass * (f - G.T @ lam)
        return np.concatenate((vA, _quaternion_rate(qA, wA), vB, _quaternion_rate(qB, wB), a))
    return rhs


def _check(joint: str, times) -> np.ndarray:
    if joint not in JOINTS:
        raise ValueError(f"joint must be one of {', '.join(JOINTS)}, got {joint!r}")
    times = np.asarray(times, dtype=float)
    if times.ndim != 1 or times.size == 0 or times[0] < 0 or np.any(np.diff(times) < 0):
        raise ValueError("times must be a non-empty, non-decreasing 1-D array of non-negative seconds")
    return times


def simulate(joint: str, times, side: float = SIDE) -> Motion:
    """Run the pendulum with the joint `joint` ("ball", "universal" or "revolute") from rest at t = 0 and
    sample it at `times` (s, non-decreasing, >= 0); `side` (m) is the square section's side."""
    times = _check(joint, times)
    bars = Bars.of_side(side)
    stop = times[-1]
    if stop > 0:
        sol = solve_ivp(_rhs(bars, joint), (0.0, stop), initial_state(), method="DOP853", t_eval=times,
                        rtol=RTOL, atol=ATOL)
        if not sol.success:
            raise RuntimeError(f"the reference pendulum's integration failed: {sol.message}")
        states = sol.y.T
    else:
        states = np.tile(initial_state(), (times.size, 1))
    return _measure(bars, times, states)


def _measure(bars: Bars, times: np.ndarray, states: np.ndarray) -> Motion:
    m, J = bars.mass, bars.inertia
    out = {k: [] for k in ("tip", "kinetic", "potential", "angular_momentum", "point_mismatch", "ya_zb",
                           "za_zb", "revolute_axis", "ya_xb")}
    for y in states:
        cA, qA, cB, qB, vA, wA, vB, wB = _unpack(y)
        RA, RB = rotation(qA), rotation(qB)
        out["tip"].append(cB + RB @ _END)
        out["kinetic"].append(0.5 * m * (vA @ vA + vB @ vB) + 0.5 * (wA @ (J * wA) + wB @ (J * wB)))
        out["potential"].append(-m * GRAVITY @ (cA + cB))
        momentum = m * (np.cross(cA, vA) + np.cross(cB, vB)) + RA @ (J * wA) + RB @ (J * wB)
        out["angular_momentum"].append(momentum)
        out["point_mismatch"].append(np.linalg.norm(cA + RA @ _END - cB - RB @ _ROOT))
        out["ya_zb"].append(RA[:, 1] @ RB[:, 2])
        out["za_zb"].append(RA[:, 2] @ RB[:, 2])
        out["revolute_axis"].append(np.linalg.norm(RB[:, 2] + RA[:, 0]))
        out["ya_xb"].append(RA[:, 1] @ RB[:, 0])
    return Motion(times, **{k: np.array(v) for k, v in out.items()})


def tip_track(joint: str, times, side: float = SIDE) -> np.ndarray:
    """B's free end (m, world), shape (len(times), 3), for the joint `joint` at `times` (s)."""
    return simulate(joint, times, side).tip
