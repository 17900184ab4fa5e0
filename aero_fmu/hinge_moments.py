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

from dataclasses import dataclass

import numpy as np

from fmu_common.vectors import cross


@dataclass(frozen=True)
class HingeLine:
    """What the hinge moment of one revolute joint needs: its `name`; `parent_node`, the global node index of the
    parent's tip node (None: the ground); `child_node`, that of the child's root node; `axis` (3,), the unit axis
    in the parent's tip frame (span, chord, normal components), global components with the ground; `panels`
    (k,), the lattice indices of the panels of the outboard bodies."""

    name: str
    parent_node: int | None
    child_node: int
    axis: np.ndarray
    panels: np.ndarray


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
                               axis / np.linalg.norm(axis), np.flatnonzero(np.isin(lattice.body, outboard))))
    return lines


def hinge_axis(e, line: HingeLine) -> tuple[np.ndarray, np.ndarray]:
    """The hinge's point and unit axis in the current configuration (module docstring).

    Args:
        e: (9 n_nodes,) exchanged coordinates (per node r, r_x, r_y), m and 1, global frame.
        line: the HingeLine.

    Returns:
        (x_h (3,) m, a (3,) unit), global frame.
    """
    e = np.asarray(e, dtype=float)
    if line.parent_node is None:
        k = 9 * line.child_node
        return e[k:k + 3].copy(), line.axis.copy()
    k = 9 * line.parent_node
    r, r_x, r_y = e[k:k + 3], e[k + 3:k + 6], e[k + 6:k + 9]
    x = r_x / np.linalg.norm(r_x)
    axis = line.axis[0] * x + line.axis[1] * r_y + line.axis[2] * cross(x, r_y)
    return r.copy(), axis / np.linalg.norm(axis)


def hinge_moment(points, forces, point, axis) -> float:
    """a . sum_p (x_p - x_h) x F_p: the moment of forces about an axis.

    Args:
        points: (P, 3) where the forces act, x_p, m, global frame.
        forces: (P, 3) the forces F_p, N, global frame.
        point: (3,) a point x_h on the axis, m, global frame.
        axis: (3,) the axis direction a, unit, global frame.

    Returns:
        the moment about the axis, N m, positive right-handed about `axis`.
    """
    points, forces = np.asarray(points, dtype=float).reshape(-1, 3), np.asarray(forces, dtype=float).reshape(-1, 3)
    moment = cross(points - np.asarray(point, dtype=float), forces).sum(axis=0)
    return float(moment @ np.asarray(axis, dtype=float))


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
