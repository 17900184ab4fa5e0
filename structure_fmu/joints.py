"""Revolute joints: fold angle, spring actuator and latch (Otsuka et al. 2019, Sec. II.C; Otsuka et al. 2022,
Secs. 3.1 and 5).

The fold angle theta of a revolute joint is the signed angle (right hand about the joint axis) of the child
relative to the parent, as in `fmu_common.topology.JointLine`: F_child = F_parent R(a, theta) O, with F the
[span, chord, normal] frames of the parent's tip node and of the child's root node, a the axis (parent
components) and O the child's orientation at theta = 0. It lies in (-pi, pi]. Two forms:

* chord axis (a along the chord of both frames, O = I: the folding wings' chordwise hinge, r_y shared): the
  angle from the parent's tip gradient p = r_x (parent) to the child's root gradient q = r_x (child) about the
  shared chord vector n = r_y, theta = atan2((p x q) . n, p . q), independent of |p| and |q| (axial strain);
* any other axis: with the unit frames F = [x, y, z] of the two nodes (x = r_x / |r_x|, y = r_y,
  z = x x r_y), a unit p perpendicular to a (parent components) and Q = F_child O^T p (the child's material
  line that lies along F_parent p at theta = 0): theta = atan2(Q . F_parent (a x p), Q . F_parent p), with
  F_parent = I for the ground. While the joint holds, Q = F_parent R(a, theta) p, so that this is theta for
  any p, and it does not depend on the stretch |r_x| of either node.
"""
import functools
import math

import numpy as np


def _sine_cosine(a0, a1, a2, b0, b1, b2, n0, n1, n2):
    """(a x b, s = (a x b) . n, c = a . b) of three 3-vectors given as floats (plain float arithmetic: on
    single 3-vectors it is several times faster than numpy calls)."""
    axb = (a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0)
    return axb, axb[0] * n0 + axb[1] * n1 + axb[2] * n2, a0 * b0 + a1 * b1 + a2 * b2


def _angle_weight(s, c):
    """1 / (s^2 + c^2), the weight of d atan2(s, c); NaN where s = c = 0 (a state whose vectors vanished, to
    underflow, has no fold angle): the integrator's finite check then reports a divergence, where a float
    division would raise ZeroDivisionError."""
    r2 = s * s + c * c
    return 1.0 / r2 if r2 > 0 else math.nan


def fold_angle(x):
    """theta (rad) of a chord-axis hinge.

    Args:
        x: (9,) [a, b, n], the stacked 3-vectors.
    """
    _, s, c = _sine_cosine(*x.tolist())
    return math.atan2(s, c)


def fold_angle_gradient(x):
    """theta and its gradient for a chord-axis hinge.

    Args:
        x: (9,) [a, b, n], the stacked 3-vectors.

    Returns:
        (theta rad, d theta/dx (9,)).
    """
    a0, a1, a2, b0, b1, b2, n0, n1, n2 = values = x.tolist()
    (p0, p1, p2), s, c = _sine_cosine(*values)
    w = _angle_weight(s, c)
    cw, sw = c * w, s * w                   # d atan2(s, c) = (c ds - s dc) / (s^2 + c^2)
    # d s / d a = b x n, d s / d b = n x a, d s / d n = a x b = p; d c / d a = b, d c / d b = a (written out:
    # this runs at every acceleration evaluation, and one list is the cheapest way to build the array)
    grad = np.array([cw * (b1 * n2 - b2 * n1) - sw * b0, cw * (b2 * n0 - b0 * n2) - sw * b1,
                     cw * (b0 * n1 - b1 * n0) - sw * b2, cw * (n1 * a2 - n2 * a1) - sw * a0,
                     cw * (n2 * a0 - n0 * a2) - sw * a1, cw * (n0 * a1 - n1 * a0) - sw * a2,
                     cw * p0, cw * p1, cw * p2])
    return math.atan2(s, c), grad


# Plain float arithmetic on 3-tuples below (also the joint monitors'): on single 3-vectors it is several times
# faster than numpy calls.
def dot(a, b):
    """a . b of two 3-vectors by their components (cheaper than numpy's on single vectors).

    Args:
        a: (3,) vector.
        b: (3,) vector.
    """
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def _cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def unit_frame(rx, ry):
    """The unit frame of a node from its gradients.

    Args:
        rx: (3,) r_x, 1, global frame.
        ry: (3,) r_y, 1, global frame.

    Returns:
        (x = r_x / |r_x| (3,), |r_x|, z = x x r_y (3,)), global frame.
    """
    length = math.sqrt(dot(rx, rx))
    x = (rx[0] / length, rx[1] / length, rx[2] / length)
    return x, length, _cross(x, ry)


def frame_direction(c, x, y, z):
    """c_x x + c_y y + c_z z.

    Args:
        c: (3,) components in the frame.
        x: (3,) first axis, global frame.
        y: (3,) second axis, global frame.
        z: (3,) third axis, global frame.

    Returns:
        (3,) global frame.
    """
    c0, c1, c2 = c
    return (c0 * x[0] + c1 * y[0] + c2 * z[0], c0 * x[1] + c1 * y[1] + c2 * z[1], c0 * x[2] + c1 * y[2] + c2 * z[2])


def _direction_gradient(x, length, ry, c, g):
    """d(g . v(c)) / d[r_x, r_y] (6 floats) of the unit-frame direction v(c) = c_x x + c_y r_y + c_z (x x r_y),
    x = r_x / |r_x|, for frame components c and a fixed vector g."""
    ry_g, g_x = _cross(ry, g), _cross(g, x)
    d_x = [c[0] * g[k] + c[2] * ry_g[k] for k in range(3)]
    along = dot(d_x, x)
    return [(d_x[k] - along * x[k]) / length for k in range(3)] + [c[1] * g[k] + c[2] * g_x[k] for k in range(3)]


def axis_angle_gradient(x, hinge):
    """theta and its gradient for a revolute joint about any axis (module docstring, second form).

    Args:
        x: (12,) [r_x^A, r_y^A, r_x^B, r_y^B] of the parent's tip node A and the child's root node B, or (6,)
            [r_x^B, r_y^B] with the ground; 1, global frame.
        hinge: the Hinge (structure_fmu.topology).

    Returns:
        (theta rad, d theta/dx, the shape of x).
    """
    values = x.tolist()
    ground = hinge.parent_slot is None
    rxb, ryb = values[-6:-3], values[-3:]
    xb, lb, zb = unit_frame(rxb, ryb)
    q, p = hinge.child_reference.tolist(), hinge.reference.tolist()
    binormal = _cross(hinge.axis.tolist(), p)                    # a x p
    Q = frame_direction(q, xb, ryb, zb)
    if ground:
        C, S = p, binormal
    else:
        rxa, rya = values[:3], values[3:6]
        xa, la, za = unit_frame(rxa, rya)
        C, S = frame_direction(p, xa, rya, za), frame_direction(binormal, xa, rya, za)
    s, c = dot(Q, S), dot(Q, C)
    ds, dc = _direction_gradient(xb, lb, ryb, q, S), _direction_gradient(xb, lb, ryb, q, C)
    if not ground:
        ds = _direction_gradient(xa, la, rya, binormal, Q) + ds
        dc = _direction_gradient(xa, la, rya, p, Q) + dc
    w = _angle_weight(s, c)
    return math.atan2(s, c), np.array([(c * a - s * b) * w for a, b in zip(ds, dc)])


def hinge_angle_gradient(hinge, E):
    """The fold angle of a hinge at E and its gradient.

    Args:
        hinge: the Hinge (structure_fmu.topology).
        E: (n,) exchanged coordinates, global frame.

    Returns:
        (theta rad, idx (k,) the distinct E indices theta depends on, d theta/dE[idx] (k,)).
    """
    if hinge.axis_slot is not None:
        idx = hinge_coordinates(hinge)
        theta, grad = fold_angle_gradient(E[idx])
        return theta, idx, grad
    full, idx, where = _axis_coordinates(hinge.parent_slot, hinge.child_slot)
    theta, grad = axis_angle_gradient(E[full], hinge)
    return theta, idx, np.bincount(where, grad, len(idx))


def hinge_angle(hinge, E):
    """theta (rad) of a hinge at E.

    Args:
        hinge: the Hinge (structure_fmu.topology).
        E: (n,) exchanged coordinates, global frame.
    """
    if hinge.axis_slot is not None:
        return fold_angle(E[hinge_coordinates(hinge)])
    return hinge_angle_gradient(hinge, E)[0]


def actuator_torque(hinge, theta, dtheta, latched):
    """Spring actuator torque K theta + C dtheta/dt + T_const (N m), acting to decrease theta.

    Once latched (Otsuka et al. 2022, Sec. 5) the spring stiffness is K times latch_factor about the stop angle.

    Args:
        hinge: the Hinge with its actuator parameters.
        theta: fold angle, rad.
        dtheta: its rate, rad/s.
        latched: {hinge: latched}.
    """
    stiffness, neutral = actuator_spring(hinge, latched)
    return stiffness * (theta - neutral) + hinge.damping * dtheta + hinge.torque, stiffness


def actuator_spring(hinge, latched):
    """The actuator spring's stiffness k (N m/rad) and neutral angle theta_0 (rad), torque k (theta - theta_0):
    (K, 0), latched (latch_factor K, stop angle) (Otsuka et al. 2022, Sec. 5).

    Args:
        hinge: the Hinge with its actuator parameters.
        latched: whether it has latched.
    """
    if latched:
        return hinge.latch_factor * hinge.stiffness, hinge.stop_angle
    return hinge.stiffness, 0.0


def actuator_energy(hinge, theta, latched):
    """The potential (J) of the actuator of `actuator_torque`.

    1/2 K theta^2 + T_const theta, latched 1/2 latch_factor K (theta - stop)^2 + T_const theta (the damping C stores
    none).

    Args:
        hinge: the Hinge with its actuator parameters.
        theta: fold angle, rad.
        latched: {hinge: latched}.
    """
    if latched:
        return 0.5 * hinge.latch_factor * hinge.stiffness * (theta - hinge.stop_angle) ** 2 + hinge.torque * theta
    return 0.5 * hinge.stiffness * theta**2 + hinge.torque * theta


def actuator_terms(hinges, E, dE, latched):
    """Per hinge, what the generalized actuator force on E is made of.

    Otsuka et al. 2019, Sec. II.C: virtual work -torque * delta theta, the force is -torque * grad on the
    coordinates idx.

    Args:
        hinges: the Hinges (structure_fmu.topology).
        E: (n,) exchanged coordinates, global frame.
        dE: (n,) their rates, per s.
        latched: {hinge: latched}.

    Returns:
        per hinge with an actuator, (idx (k,) distinct indices into E, torque N m, its stiffness d torque / d theta
        N m/rad, its damping d torque / d theta' N m s/rad, grad = d theta / dE[idx] (k,)).
    """
    for h in hinges:
        theta, idx, grad = hinge_angle_gradient(h, E)
        torque, stiffness = actuator_torque(h, theta, float(np.dot(grad, dE[idx])), latched.get(h.name, False))
        yield idx, torque, stiffness, h.damping, grad


@functools.cache
def _coordinates_of(parent_slot, child_slot, axis_slot):
    return np.concatenate([np.arange(3 * s, 3 * s + 3) for s in (parent_slot, child_slot, axis_slot)])


@functools.cache
def _axis_coordinates(parent_slot, child_slot):
    """(full, idx, where): the E indices of [r_x^A, r_y^A, r_x^B, r_y^B] (r_x^B, r_y^B with the ground), their
    distinct values idx, and full = idx[where] (a revolute may share r_y between the two nodes)."""
    slots = (child_slot,) if parent_slot is None else (parent_slot, child_slot)
    full = np.concatenate([np.arange(3 * s, 3 * s + 6) for s in slots])
    idx, where = np.unique(full, return_inverse=True)
    return full, idx, where


def hinge_coordinates(hinge):
    """Indices into E of the coordinates the hinge's fold angle depends on.

    The parent's r_x, the child's r_x and the axis r_y (9,) of a chord-axis hinge, the distinct ones of
    [r_x^A, r_y^A, r_x^B, r_y^B] otherwise.

    Args:
        hinge: the Hinge (structure_fmu.topology).
    """
    if hinge.axis_slot is not None:
        return _coordinates_of(hinge.parent_slot, hinge.child_slot, hinge.axis_slot)
    return _axis_coordinates(hinge.parent_slot, hinge.child_slot)[1]
