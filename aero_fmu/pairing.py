"""The pairing check: the e an aero unit first receives must come from a structure of its own scene geometry.

The SSP/container export compares `topology_hash`, but a system tool that does not compare it could pair an aero
unit built for one wing with a structure unit of another (another span, node layout folded into the same n,
root position or fold angle). Both units then run and the aero unit computes forces on a lattice that is not
the structure's wing. `PairingCheck` refuses such an e at the aero unit's first step with an `InputError`
naming both geometries; AeroSolver calls it on every advance from a model state that has not started (the first
advance after construction, or after restoring a state saved before it: an implicit coupling that repeats its
first step checks each iterate, a correct one passing each time).

Rule. For every node i, with r_i the position slots of the received e (`coordinate_description`: r of node i
is e[9 i .. 9 i + 2]), r0_i this unit's own initial position (`Topology.initial_coordinates`) and v_i the
received rate of r_i:

    d_i = |r_i - r0_i|  <=  tol_i = GEOMETRIC_TOLERANCE * L + a_i + MOTION_SAFETY * h * |v_i|

- L is the reference length of the lattice, the sum of its body lengths (the span of a straight wing, the
  deployed span of a folding one). A structure unit of the same scene builds its nodes with the same
  `fmu_common.topology.Topology` code from the same numbers, so at t = 0 its positions equal ours to
  round-off (measured on the shipped scenes: at most 4e-15 m, two_body_003; the strain-based fidelity,
  which rebuilds E from strains, 4e-17 m on deploy_flexible). GEOMETRIC_TOLERANCE = 1e-3 L is about ten
  orders above that, and below what another wing differs by: another span, root, node layout or fold angle
  moves some node by a fraction of L (measured 31 to 6700 times the tolerance, docs/aero_api.md). A span
  that differs by less than 0.1% passes: aerodynamically the same wing.
- h is the time from the unit's state to the step's end (t_end - time). The first e is the structure's at
  t0 (Jacobi: the exchange at t0) or at t0 + h (Gauss-Seidel and implicit: the structure steps first), and
  a correct structure may already move then (deploying, heaving, spinning up). Its node moved by
  |integral over the step of v dt| <= h max |v| over the step. Only the rate at the end, v_i, is known;
  max |v| <= 2 |v_i| holds for any motion that starts from rest with a speed that grows over the step,
  for a constant speed, and for a speed that falls by at most half over the step (a sinusoid resolved with
  6 or more steps per period: cos(omega h) >= 1/2). MOTION_SAFETY = 2.
- a_i: a prescribed motion (structure.fidelity = prescribed, structure.motion) poses the wing at t = 0 by
  its pitch theta_0 = alpha_deg, or pitch_amplitude sin(phase), about the span axis through the pivot at
  pitch_axis_position of the chord (default: the reference line, a_i = 0); a node on the reference line is
  then |p - a| c from the pitch axis and moves by 2 |sin(theta_0 / 2)| |p - a| c (the heave starts at 0).
  a_i is that chord of the arc: a bound, not a replica of the structure's motion law.

The check reads positions only: the slopes r_x, r_y turn with the prescribed pitch at t = 0 and with any
motion, and the chord length and the reference line's chord position (axis_position) are not in e at all;
`topology_hash` covers those. A received e of another length is refused before this check
(`fmu_common.errors.checked_input`).
"""
from __future__ import annotations

import math

import numpy as np

from fmu_common.errors import InputError
from fmu_common.interface import coordinate_description

GEOMETRIC_TOLERANCE = 1e-3
"""Allowed distance of a node from this unit's initial position, as a fraction of the lattice's reference length
(the sum of its body lengths); module docstring."""
MOTION_SAFETY = 2.0
"""Factor on |received node rate| x step: how far a correct structure's node may have moved by the first
exchange (module docstring)."""


def prescribed_pose_allowance(topology, structure) -> np.ndarray:
    """How far a prescribed motion may move each node at t = 0, m, (n_nodes,) (module docstring, a_i).

    Args:
        topology: the aero unit's topology (fmu_common.topology.Topology).
        structure: the scene's structure table (fmu_common.wing_spec.StructureSpec).

    Returns:
        (n_nodes,) m: 2 |sin(theta_0 / 2)| |p - a| c of each node's body (c its larger end chord); zeros without
        a prescribed motion.
    """
    allowance = np.zeros(topology.n_nodes)
    motion = structure.motion
    if motion is None or not structure.fidelity.moved_by_law:
        return allowance
    if motion.alpha_deg != 0.0:
        theta = math.radians(motion.alpha_deg)
    else:
        theta = math.radians(motion.pitch_amplitude_deg) * math.sin(math.radians(motion.phase_deg))
    for body in topology.bodies.values():
        pivot = body.axis_position if motion.pitch_axis_position is None else motion.pitch_axis_position
        chord = max(body.planform.chord_root, body.planform.chord_tip)
        allowance[body.nodes] = 2.0 * abs(math.sin(theta / 2.0)) * abs(pivot - body.axis_position) * chord
    return allowance


class PairingCheck:
    """This aero unit's own node positions and tolerances, and the check of a received e, de against them.

    Args:
        topology: the aero unit's topology (fmu_common.topology.Topology).
        structure: the scene's structure table (fmu_common.wing_spec.StructureSpec), for a prescribed pose.
        description: this unit in words for the message, e.g. "scene 'heaving_wing', uvlm-prescribed lattice
            of 1 body, 5 nodes, 20 panels".
    """

    def __init__(self, topology, structure, description: str):
        self.topology = topology
        self.description = description
        self.initial = topology.initial_coordinates().reshape(-1, 9)[:, :3]      # (n_nodes, 3) r0, m
        self.reference_length = float(sum(b.length for b in topology.bodies.values()))
        self.allowance = prescribed_pose_allowance(topology, structure)

    def tolerances(self, de: np.ndarray, step: float) -> np.ndarray:
        """tol_i of each node (module docstring).

        Args:
            de: (n,) received rates, m/s on r slots.
            step: h, s: time from the unit's state to the end of the step the inputs are for.

        Returns:
            (n_nodes,) m.
        """
        speed = np.linalg.norm(np.asarray(de, dtype=float).reshape(-1, 9)[:, :3], axis=1)
        return GEOMETRIC_TOLERANCE * self.reference_length + self.allowance + MOTION_SAFETY * max(step, 0.0) * speed

    def ratios(self, e: np.ndarray, de: np.ndarray, step: float) -> np.ndarray:
        """d_i / tol_i of each node: above 1 refuses the pairing.

        Args:
            e: (n,) received coordinates, m and 1, global frame.
            de: (n,) received rates, per s.
            step: h, s (`tolerances`).

        Returns:
            (n_nodes,) -.
        """
        distance = np.linalg.norm(np.asarray(e, dtype=float).reshape(-1, 9)[:, :3] - self.initial, axis=1)
        return distance / self.tolerances(de, step)

    def check(self, e: np.ndarray, de: np.ndarray, step: float, time: float) -> float:
        """Refuse an e whose node positions are not this unit's (InputError naming both); else the largest ratio.

        Args:
            e: (n,) received coordinates, m and 1, global frame (of the right length: `checked_input`).
            de: (n,) received rates, per s.
            step: h, s (`tolerances`).
            time: the unit's time, s, for the message.

        Returns:
            max_i d_i / tol_i, at most 1.
        """
        ratios = self.ratios(e, de, step)
        worst = int(np.argmax(ratios))
        if ratios[worst] <= 1.0:
            return float(ratios[worst])
        received = np.asarray(e, dtype=float).reshape(-1, 9)[worst, :3]
        own = self.initial[worst]
        tolerance = float(self.tolerances(de, step)[worst])
        distance = float(np.linalg.norm(received - own))
        node, _, _ = coordinate_description(self.topology, 9 * worst)
        off = int((ratios > 1.0).sum())
        raise InputError(
            f"the structure's coordinates e for the first step (t = {time:.6g} s to {time + step:.6g} s) do not fit "
            f"this aero unit's lattice: node {node} "
            f"(e[{9 * worst + 1}]..e[{9 * worst + 3}], r) is at {_point(received)} m, this unit's own node "
            f"is at {_point(own)} m, {distance:.4g} m apart, tolerance {tolerance:.3g} m "
            f"({off} of {len(ratios)} nodes off). This aero unit: {self.description}, reference length "
            f"{self.reference_length:.6g} m (sum of body lengths), topology_hash {self.topology.topology_hash}. "
            "The structure unit connected to it was built for another wing geometry: connect the structure unit "
            "built from the same scene geometry (the same topology_hash)")


def _point(r) -> str:
    return "(" + ", ".join(f"{float(v):.6g}" for v in r) + ")"
