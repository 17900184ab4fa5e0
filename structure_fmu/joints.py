"""Revolute hinge with its axis along the chord: fold angle, spring actuator and latch (000 Sec. II.C; 003 Sec. 5).

The fold angle theta is the angle from the parent's tip gradient a = r_x (parent) to the child's root
gradient b = r_x (child), positive about the shared chord vector n = r_y:
theta = atan2((a x b) . n, a . b). It is independent of |a| and |b| (axial strain), in (-pi, pi].
"""
import numpy as np

from .element import cross


def fold_angle(a, b, n):
    """theta (rad) for gradient vectors a, b and hinge axis n, each (..., 3)."""
    return np.arctan2(np.sum(cross(a, b) * n, axis=-1), np.sum(a * b, axis=-1))


def fold_angle_gradient(a, b, n):
    """(theta, d theta/da, d theta/db, d theta/dn) for single 3-vectors."""
    s, c = cross(a, b) @ n, a @ b
    q = s * s + c * c
    ds_da, ds_db, ds_dn = cross(b, n), cross(n, a), cross(a, b)
    return (np.arctan2(s, c), (c * ds_da - s * b) / q, (c * ds_db - s * a) / q, c * ds_dn / q)


def actuator_torque(hinge, theta, dtheta, latched):
    """Spring actuator torque K theta + C dtheta/dt + T_const (N m), acting to decrease theta.

    Once latched (003 Sec. 5) the spring stiffness is K times latch_factor about the stop angle.
    """
    if latched:
        spring = hinge.latch_factor * hinge.stiffness * (theta - hinge.stop_angle)
        stiffness = hinge.latch_factor * hinge.stiffness
    else:
        spring, stiffness = hinge.stiffness * theta, hinge.stiffness
    return spring + hinge.damping * dtheta + hinge.torque, stiffness


def actuator_forces(hinges, E, dE, latched, n_coordinates, with_tangent=False):
    """Generalized actuator force on E (000 Sec. II.C, virtual work -torque * delta theta).

    Returns (force (n,), angles {name: rad}, and if with_tangent the Gauss-Newton tangent stiffness and
    damping matrices (n, n): K grad theta grad theta^T and C grad theta grad theta^T).
    """
    force = np.zeros(n_coordinates)
    stiff = np.zeros((n_coordinates, n_coordinates)) if with_tangent else None
    damp = np.zeros((n_coordinates, n_coordinates)) if with_tangent else None
    angles = {}
    for h in hinges:
        idx = np.concatenate([np.arange(3 * s, 3 * s + 3) for s in (h.parent_slot, h.child_slot, h.axis_slot)])
        theta, ga, gb, gn = fold_angle_gradient(E[idx[:3]], E[idx[3:6]], E[idx[6:]])
        grad = np.concatenate([ga, gb, gn])
        dtheta = grad @ dE[idx]
        torque, k = actuator_torque(h, theta, dtheta, latched.get(h.name, False))
        force[idx] -= torque * grad
        angles[h.name] = theta
        if with_tangent:
            outer = np.outer(grad, grad)
            stiff[np.ix_(idx, idx)] += k * outer
            damp[np.ix_(idx, idx)] += h.damping * outer
    return force, angles, stiff, damp
