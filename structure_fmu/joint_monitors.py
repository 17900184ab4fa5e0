"""Per-joint constraint monitors on the exchanged coordinates E (any structural fidelity: every structure unit
exchanges the same E, per node r, r_x, r_y; Otsuka et al. 2019, Eq. 3).

For each ball, universal or revolute joint with a parent body (`fmu_common.topology.JointLine`), between the
parent's tip node A and the child's root node B, in the unit frames F = [x, y, z] of the two nodes
(x = r_x / |r_x|, y = r_y, z = r_x x r_y / |r_x|):
  <name>_point_mismatch  |r^A - r^B| (m), every joint: zero for a shared point;
  <name>_axis_product    (F_A a) . (F_B b) (-), a universal joint with a = parent_axis, b = child_axis: zero while
                         the cross holds (Otsuka et al. 2022, Sec. 4.2 plots (r_y^P)^T r_z^Q);
  <name>_axis_error      |F_A a - F_B O^T a| (-), a revolute joint with axis a (parent frame) and the child's
                         orientation O: zero while both bodies keep the axis (Otsuka et al. 2022, Sec. 4.3 plots
                         |r_x^P + r_z^Q|, the same for its anti-parallel axes).
Joints with the ground are left out (their point and chord are prescribed, or held by the constraint rows).
"""
import functools
import math

import numpy as np

# plain float arithmetic on 3-tuples, shared with the fold angles: a few joints, read at every communication step
from .joints import dot, frame_direction, unit_frame


@functools.cache
def monitor_names(name: str, kind: str) -> tuple[str, ...]:
    """The monitors of a joint with a parent body (made once per joint: `joint_monitors` names them at every read).

    Args:
        name: the joint's name.
        kind: its type, 'ball', 'universal' or 'revolute'.
    """
    axis = {"universal": ["_axis_product"], "revolute": ["_axis_error"]}.get(kind, [])
    return tuple(f"{name}{suffix}" for suffix in ["_point_mismatch", *axis])


def joint_monitors(joint_lines, bodies, e) -> dict[str, float]:
    """{monitor name: value} (module docstring) of the joints.

    Args:
        joint_lines: the joints (Topology.joint_lines).
        bodies: the bodies they join (Topology.bodies: name -> Body with its global node indices).
        e: (9 n_nodes,) exchanged coordinates, m and 1, global frame.
    """
    e = np.asarray(e, dtype=float)
    out = {}
    for line in joint_lines:
        if line.parent is None:
            continue
        a, b = 9 * bodies[line.parent].nodes[-1], 9 * bodies[line.child].nodes[0]
        tip, root = e[a:a + 9].tolist(), e[b:b + 9].tolist()           # r, r_x, r_y of each node
        values = [math.dist(tip[:3], root[:3])]
        if line.kind in ("universal", "revolute"):
            (xa, _, za), (xb, _, zb) = unit_frame(tip[3:6], tip[6:]), unit_frame(root[3:6], root[6:])
            axis = line.axis.tolist()
            parent = frame_direction(axis, xa, tip[6:], za)                # F_A a
            if line.kind == "universal":
                values.append(dot(parent, frame_direction(line.child_axis.tolist(), xb, root[6:], zb)))
            else:
                turned = frame_direction(axis, *line.orientation.tolist())     # O^T a
                values.append(math.dist(parent, frame_direction(turned, xb, root[6:], zb)))
        out.update(zip(monitor_names(line.name, line.kind), values))
    return out
