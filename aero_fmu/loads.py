"""Resultants of the panel forces: generalized force (Otsuka et al. 2019, Eq. 12), lift, drag, moments, coefficients.

Axes: drag along the free-stream unit direction d; lift along `vlm.lift_axis` (the area-weighted wing
normal without its component along d); side force along d x lift axis. Moments about the global origin,
of the panel forces at their application points. Coefficients use q = rho V^2 / 2 and the reference area
S (sum of body length x chord); they are 0 when q = 0 (still air or zero density), never NaN.
"""
from dataclasses import dataclass

import numpy as np

from .vlm import lift_axis


@dataclass
class Loads:
    """forces (n_panels, 3) N at points (n_panels, 3) m; Q (n_coordinates,) N / N.m; outputs (dict of floats)."""
    forces: np.ndarray
    points: np.ndarray
    Q: np.ndarray
    outputs: dict

    def copy(self):
        """A copy that shares no array or dict with these loads."""
        return Loads(self.forces.copy(), self.points.copy(), self.Q.copy(), dict(self.outputs))


OUTPUT_NAMES = ("CL", "lift", "wake_panels", "drag", "side_force", "CD", "moment_x", "moment_y", "moment_z")


def resultants(lattice, geometry, forces, direction, speed, density, wake_panels) -> Loads:
    """The Loads of panel forces acting at geometry.application.

    Q = sum_panels S(x_a, y_a)^T a.

    Otsuka et al. 2019, Eq. 12

    Args:
        lattice: the aero lattice (aero_fmu.lattice.Lattice).
        geometry: its Geometry at the current coordinates.
        forces: (n_panels, 3) panel forces, N, global frame.
        direction: (3,) unit free-stream direction, global frame.
        speed: free-stream speed, m/s.
        density: air density, kg/m^3.
        wake_panels: number of shed wake panels (an output).
    """
    points = geometry.application
    # sum_p x_p x f_p from the 3 x 3 moment sum_p x_p f_p^T: one product instead of a cross per panel
    outputs = resultant_outputs(lattice, forces.sum(axis=0), points.T @ forces, lift_axis(geometry, direction),
                                direction, speed, density, wake_panels)
    return Loads(forces, points, lattice.generalized_force(forces), outputs)


def resultant_outputs(lattice, total, first, lift_dir, direction, speed, density, wake_panels) -> dict:
    """The outputs of `resultants` (OUTPUT_NAMES) from the sums of the panel forces.

    Args:
        lattice: the aero lattice (aero_fmu.lattice.Lattice).
        total: (3,) sum_p f_p, N, global frame.
        first: (3, 3) sum_p x_p f_p^T, N m, global frame.
        lift_dir: (3,) the unit lift axis (vlm.lift_axis), global frame.
        direction: (3,) unit free-stream direction, global frame.
        speed: free-stream speed, m/s.
        density: air density, kg/m^3.
        wake_panels: number of wake panels (an output).
    """
    # on Python floats: the numpy calls on (3,) arrays would cost more than the arithmetic
    (f0, f1, f2), (l0, l1, l2), (d0, d1, d2) = (np.asarray(v, dtype=float).tolist()
                                                for v in (total, lift_dir, direction))
    first = np.asarray(first, dtype=float).tolist()
    moment = (first[1][2] - first[2][1], first[2][0] - first[0][2], first[0][1] - first[1][0])
    lift, drag = f0 * l0 + f1 * l1 + f2 * l2, f0 * d0 + f1 * d1 + f2 * d2
    side = f0 * (d1 * l2 - d2 * l1) + f1 * (d2 * l0 - d0 * l2) + f2 * (d0 * l1 - d1 * l0)    # total . (d x lift)
    q_area = 0.5 * density * speed * speed * lattice.reference_area
    coefficient = (lambda force: force / q_area) if q_area > 0 else (lambda force: 0.0)
    return {"CL": coefficient(lift), "lift": lift, "wake_panels": int(wake_panels), "drag": drag,
            "side_force": side, "CD": coefficient(drag),
            "moment_x": moment[0], "moment_y": moment[1], "moment_z": moment[2]}


def zero_loads(lattice, n_coordinates) -> Loads:
    """Loads before the first step: no force.

    Args:
        lattice: the aero lattice (aero_fmu.lattice.Lattice).
        n_coordinates: n, the length of Q.
    """
    outputs = {name: 0 if name == "wake_panels" else 0.0 for name in OUTPUT_NAMES}
    return Loads(np.zeros((lattice.n_panels, 3)), np.zeros((lattice.n_panels, 3)), np.zeros(n_coordinates), outputs)
