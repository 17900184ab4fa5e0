"""Aerodynamic moment about each revolute joint's (hinge's) axis, from the panel forces and the current coordinates.

For a revolute joint with axis a (unit, current configuration) through the point x_h:

    M_hinge = a . sum_p (x_p - x_h) x F_p

over the panels p of the bodies outboard of the hinge: its child body and every body attached further out through
revolute, ball or universal joints (`fmu_common.topology.JointLine`, parent -> child; pins and sliders are not
followed). F_p is the panel's aerodynamic force, N, acting at its force point x_p (`Geometry.application`, the
middle of the panel's bound segment, aero_fmu/lattice.py), the same forces and points as Q (Otsuka et al. 2019,
Eq. 12).

The axis and the point are those the structure unit uses (structure_fmu/joints.py, structure_fmu/joint_monitors.py),
taken from the exchanged coordinates e, so that the axis turns with the parent body as the wing deploys:
x_h = r of the parent's tip node (which the child's root node shares while the joint holds), and
a = F_A a_0 / |F_A a_0|, with a_0 the joint's axis in the parent's tip frame (span, chord, normal components) and
F_A = [x, r_y, x x r_y], x = r_x / |r_x|, the unit frame of the parent's tip node. With the ground as parent,
a = a_0 (global components) and x_h = r of the child's root node (held at the joint).

Sign: positive about the joint axis as declared, the right-hand sense in which the fold angle theta grows
(structure_fmu.joints). Where the outboard bodies turn rigidly about the hinge, M_hinge is the generalized
aerodynamic force on theta: Q . dE/dtheta = M_hinge. The actuator torque T = K theta + C theta' + T_const acts
to decrease theta (its moment about +a is -T), so T_const > 0 opens a fold that deploys toward smaller theta and
the aerodynamic torque opposing it is M_hinge > 0: the deployment torque scale of Otsuka et al. 2019,
Sec. VII.A, Fig. 11b, F = T_const / T_aero, is T_const / M_hinge (positive when the air opposes the actuator).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np



@dataclass(frozen=True)
class HingeLine:
    """What the hinge moment of one revolute joint needs: its `name`; `parent_node`, the global node index of the
    parent's tip node (None: the ground); `child_node`, that of the child's root node; `axis` (3,), the unit axis
    in the parent's tip frame (span, chord, normal components), global components with the ground; `panels`,
    the lattice indices of the panels of the outboard bodies: (k,) indices, or the slice of them when they are
    consecutive (`panel_selection`; a view of the panel arrays instead of a copy, the same rows)."""

    name: str
    parent_node: int | None
    child_node: int
    axis: np.ndarray
    panels: np.ndarray | slice


def panel_selection(indices) -> np.ndarray | slice:
    """The rows `indices` (k,) of a panel array as a slice when they are consecutive and ascending, else the
    indices: indexing by the slice reads the same rows, in the same order, without copying them.

    Args:
        indices: (k,) lattice panel indices.
    """
    indices = np.asarray(indices, dtype=np.intp)
    if indices.size and np.array_equal(indices, np.arange(indices[0], indices[0] + indices.size)):
        return slice(int(indices[0]), int(indices[0]) + indices.size)
    return indices


def outboard_bodies(joint_lines, child: str) -> list[str]:
    """The body `child` and every body attached further out through parent-child joints.

    Args:
        joint_lines: the topology's joints (fmu_common.topology.JointLine), parent -> child.
        child: the child body of the hinge.

    Returns:
        body names, `child` first.
    """
    found, queue = [child], [child]
    while queue:
        parent = queue.pop()
        for line in joint_lines:
            if line.parent == parent and line.child not in found:
                found.append(line.child)
                queue.append(line.child)
    return found


def hinge_lines(topology, lattice) -> list[HingeLine]:
    """The HingeLine of every revolute joint, in the topology's hinge order (`Topology.hinge_names`).

    Args:
        topology: the aero unit's topology (fmu_common.topology.Topology).
        lattice: its lattice (aero_fmu.lattice.Lattice), whose `body` gives each panel's body index in
            `lattice.body_names`.
    """
    lines = []
    for line in topology.joint_lines:
        if line.kind != "revolute":
            continue
        outboard = [lattice.body_names.index(b) for b in outboard_bodies(topology.joint_lines, line.child)]
        parent_node = None if line.parent is None else topology.bodies[line.parent].nodes[-1]
        axis = np.asarray(line.axis, dtype=float)
        lines.append(HingeLine(line.name, parent_node, topology.bodies[line.child].nodes[0],
                               axis / np.linalg.norm(axis),
                               panel_selection(np.flatnonzero(np.isin(lattice.body, outboard)))))
    return lines


def hinge_axis(e, line: HingeLine) -> tuple[tuple[float, ...], tuple[float, ...]]:
    """The hinge's point and unit axis in the current configuration (module docstring).

    On Python floats: three components each, where numpy's per-call cost would be most of the time.

    Args:
        e: (9 n_nodes,) exchanged coordinates (per node r, r_x, r_y), m and 1, global frame.
        line: the HingeLine.

    Returns:
        (x_h (3,) m, a (3,) unit), global frame.
    """
    if line.parent_node is None:
        k = 9 * line.child_node
        return tuple(e[k:k + 3].tolist()), tuple(line.axis.tolist())
    k = 9 * line.parent_node
    r, r_x, r_y = e[k:k + 3].tolist(), e[k + 3:k + 6].tolist(), e[k + 6:k + 9].tolist()
    x = _unit(r_x)
    z = (x[1] * r_y[2] - x[2] * r_y[1], x[2] * r_y[0] - x[0] * r_y[2], x[0] * r_y[1] - x[1] * r_y[0])  # x cross r_y
    a0, a1, a2 = line.axis.tolist()
    return tuple(r), _unit([a0 * x[i] + a1 * r_y[i] + a2 * z[i] for i in range(3)])


def _unit(v) -> tuple[float, float, float]:
    """v / |v| of three floats."""
    norm = math.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
    return v[0] / norm, v[1] / norm, v[2] / norm


def hinge_moment(points, forces, point, axis) -> float:
    """a . sum_p (x_p - x_h) x F_p: the moment of forces about an axis.

    From the 3 x 3 moments G = sum_p (x_p - x_h) F_p^T (one matrix product over the panels): the summed cross
    product's components are G_12 - G_21, G_20 - G_02, G_01 - G_10, so that the cost on the panels is two numpy
    calls whatever their number.

    Args:
        points: (P, 3) where the forces act, x_p, m, global frame (an array).
        forces: (P, 3) the forces F_p, N, global frame (an array).
        point: (3,) a point x_h on the axis, m, global frame.
        axis: (3,) the axis direction a, unit, global frame.

    Returns:
        the moment about the axis, N m, positive right-handed about `axis`.
    """
    G = np.dot((points - np.asarray(point, dtype=float)).T, forces).tolist()
    a0, a1, a2 = axis
    return float(a0 * (G[1][2] - G[2][1]) + a1 * (G[2][0] - G[0][2]) + a2 * (G[0][1] - G[1][0]))


def hinge_moments(lines, e, points, forces) -> dict[str, float]:
    """{hinge name: M_hinge, N m} of every hinge (module docstring).

    Args:
        lines: the HingeLines (`hinge_lines`).
        e: (9 n_nodes,) the exchanged coordinates the forces were computed at, m and 1, global frame.
        points: (n_panels, 3) the panels' force points, m, global frame.
        forces: (n_panels, 3) the panels' aerodynamic forces, N, global frame.
    """
    out = {}
    for line in lines:
        point, axis = hinge_axis(e, line)
        out[line.name] = hinge_moment(points[line.panels], forces[line.panels], point, axis)
    return out
