"""The aero unit's FMI interface, declared once (fmu_common.interface): the rows its slave registers and publishes,
the master reads and docs/fmu.md shows. Every value comes from `AeroSolver` (docs/aero_api.md): Q, and the
scalars of `AeroSolver.outputs()` (aero_fmu/loads.py: axes, moments about the global origin, coefficients on
q = rho V^2 / 2 and the reference area S_ref, 0 when q = 0), and per hinge `AeroSolver.hinge_moments()`
(aero_fmu/hinge_moments.py).
"""
from __future__ import annotations

from fmu_common.interface import INPUT, OUTPUT, Block, Interface, Items, Output, Parameters, Reading

HINGES = Items("<hinge>", "H", "the revolute joints (hinges), in the structure's order",
               lambda solver: solver.topology.hinge_names)
"""The hinges, as the structure unit lays them out (structure_fmu.interface.HINGES: the same names and order)."""


def _loads(solver) -> dict:
    return solver.outputs()


def _hinge_moments(solver) -> dict:
    return solver.hinge_moments()


def _hinge_moments_of(reading: Reading, hinges) -> list[float]:
    """The aerodynamic moment (N m) about each hinge's axis."""
    moments = reading.once(_hinge_moments)
    return [moments[h] for h in hinges]


def _load(name: str, unit: str, description: str, doc: str = "", monitor: bool = False) -> Output:
    """The output `name` of AeroSolver.outputs()."""
    return Output(name, unit, description, lambda reading, _: reading.once(_loads)[name], doc=doc, monitor=monitor)


AERO = Interface(
    unit="aero unit",
    blocks=(
        Block("e", INPUT, "coordinate", "node", "the structure's nodal coordinates",
              start=lambda solver: solver.topology.initial_coordinates(),
              start_doc="the scene's initial coordinates"),
        Block("de", INPUT, "rate", "rate of node", "their rates (the wing's own velocity in the no-penetration "
              "condition)"),
        Block("Q", OUTPUT, "force", "generalized aerodynamic force on node", "generalized aerodynamic force, "
              "Q = sum over panels S^T a (Otsuka et al. 2019, Eq. 12)", value=lambda reading, _: reading.solver.Q),
    ),
    outputs=(
        _load("CL", "1", "lift coefficient: lift / (1/2 rho V^2 S_ref), 0 at zero dynamic pressure", monitor=True),
        _load("lift", "N", "aerodynamic force along the lift axis (normal to the free stream)", monitor=True),
        _load("wake_panels", "1", "number of wake panels (a count, as Real)"),
        _load("drag", "N", "aerodynamic force along the free stream"),
        _load("side_force", "N", "aerodynamic side force",
              doc="aerodynamic force across the free stream and the lift axis"),
        _load("CD", "1", "drag coefficient", doc="drag / (1/2 rho V^2 S_ref), 0 at zero dynamic pressure"),
        _load("moment_x", "N.m", "aerodynamic moment about global x", doc="aerodynamic moment about the global "
              "x axis through the origin"),
        _load("moment_y", "N.m", "aerodynamic moment about global y", doc="the same about y"),
        _load("moment_z", "N.m", "aerodynamic moment about global z", doc="the same about z"),
        Output("hinge_moment_<hinge>", "N.m", "aerodynamic moment about the axis of hinge <hinge> (positive as the "
               "fold angle grows)", _hinge_moments_of, HINGES, key="hinge_moments",
               doc="aerodynamic moment about each revolute joint's axis, a . sum (x_p - x_h) x F_p over the panels "
                   "of the bodies outboard of it, axis a and point x_h in the current configuration (turning with "
                   "the parent body); positive right-handed about the axis as declared, the sense in which the fold "
                   "angle grows, against the actuator torque T (which acts to decrease it): T_const / "
                   "hinge_moment is the deployment torque scale of Otsuka et al. 2019, Sec. VII.A "
                   "(aero_fmu/hinge_moments.py); 0 at zero dynamic pressure"),
    ),
    parameters=Parameters("the tunable keys of the scene's `flow` table (`AeroSolver.tunable_parameters`), each "
                          "with the unit and description of its scene key: set before initialization, no rebuild"),
    partner="structure unit",
)
"""The aero unit's variables in value-reference order (docs/fmu.md, "Aero FMU")."""
