"""Revolute hinge with its axis along the chord: fold angle, spring actuator and latch (Otsuka et al. 2019,
Sec. II.C; Otsuka et al. 2022, Sec. 5).

The fold angle theta is the angle from the parent's tip gradient a = r_x (parent) to the child's root
gradient b = r_x (child), positive about the shared chord vector n = r_y:
theta = atan2((a x b) . n, a . b). It is independent of |a| and |b| (axial strain), in (-pi, pi].
"""
import functools
import math

import numpy as np


def _sine_cosine(a0, a1, a2, b0, b1, b2, n0, n1, n2):
    """(a x b, s = (a x b) . n, c = a . b) of three 3-vectors given as floats (plain float arithmetic: on
    single 3-vectors it is several times faster than numpy calls)."""
    axb = (a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0)
    return axb, axb[0] * n0 + axb[1] * n1 + axb[2] * n2, a0 * b0 + a1 * b1 + a2 * b2


def fold_angle(x):
    """theta (rad) for x = [a, b, n] (9,), the stacked 3-vectors."""
    _, s, c = _sine_cosine(*x.tolist())
    return math.atan2(s, c)


def fold_angle_gradient(x):
    """(theta, d theta/dx (9,)) for x = [a, b, n] (9,), the stacked 3-vectors."""
    a0, a1, a2, b0, b1, b2, n0, n1, n2 = values = x.tolist()
    axb, s, c = _sine_cosine(*values)
    w = 1.0 / (s * s + c * c)
    cw, sw = c * w, s * w                   # d atan2(s, c) = (c ds - s dc) / (s^2 + c^2)
    ds = (b1 * n2 - b2 * n1, b2 * n0 - b0 * n2, b0 * n1 - b1 * n0,          # d s / d a = b x n
          n1 * a2 - n2 * a1, n2 * a0 - n0 * a2, n0 * a1 - n1 * a0)          # d s / d b = n x a
    dc = (b0, b1, b2, a0, a1, a2)
    grad = np.array([cw * x - sw * y for x, y in zip(ds, dc)] + [cw * x for x in axb])   # d s / d n = a x b
    return math.atan2(s, c), grad


def actuator_torque(hinge, theta, dtheta, latched):
    """Spring actuator torque K theta + C dtheta/dt + T_const (N m), acting to decrease theta.

    Once latched (Otsuka et al. 2022, Sec. 5) the spring stiffness is K times latch_factor about the stop angle.
    """
    if latched:
        spring = hinge.latch_factor * hinge.stiffness * (theta - hinge.stop_angle)
        stiffness = hinge.latch_factor * hinge.stiffness
    else:
        spring, stiffness = hinge.stiffness * theta, hinge.stiffness
    return spring + hinge.damping * dtheta + hinge.torque, stiffness


def actuator_terms(hinges, E, dE, latched):
    """Per hinge, what the generalized actuator force on E is made of (Otsuka et al. 2019, Sec. II.C, virtual work
    -torque * delta theta: the force is -torque * grad on the coordinates idx):

    (idx (9,) into E, torque N m, its stiffness d torque / d theta N m/rad, its damping
    d torque / d theta' N m s/rad, grad = d theta / dE[idx] (9,))."""
    for h in hinges:
        idx = hinge_coordinates(h)
        theta, grad = fold_angle_gradient(E[idx])
        torque, stiffness = actuator_torque(h, theta, float(grad @ dE[idx]), latched.get(h.name, False))
        yield idx, torque, stiffness, h.damping, grad


@functools.cache
def _coordinates_of(parent_slot, child_slot, axis_slot):
    return np.concatenate([np.arange(3 * s, 3 * s + 3) for s in (parent_slot, child_slot, axis_slot)])


def hinge_coordinates(hinge):
    """Indices (9,) into E of the parent's r_x, the child's r_x and the axis r_y of a hinge."""
    return _coordinates_of(hinge.parent_slot, hinge.child_slot, hinge.axis_slot)
