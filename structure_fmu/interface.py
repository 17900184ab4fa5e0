"""The structure unit's FMI interface, declared once (fmu_common.interface): the rows its slave registers and
publishes, the master reads and docs/fmu.md shows. Every value comes from `StructureSolver` (docs/solver_api.md);
this module does not import it, so that the master's scene stage reads the monitor names without loading the
solver.
"""
from __future__ import annotations

from fmu_common.interface import (CALCULATED, DISCRETE, INPUT, OUTPUT, Block, Interface, Items, Output, Parameters,
                                  Reading)

LATCH_PENDING = -1.0
"""Value (s) of latch_time_<hinge> until the hinge latches. Latch times are at or after the start time,
which wingsim's master sets to 0."""

HINGES = Items("<hinge>", "H", "the revolute joints (hinges), in the structure's order",
               lambda solver: solver.topology.hinge_names)
PROBES = Items("<probe>", "P", "the scene's probes, in its order", lambda solver: solver.sensors.probe_names)
GAUGES = Items("<gauge>", "G", "the scene's strain gauges, in its order", lambda solver: solver.sensors.gauge_names)
JOINT_MONITORS = Items("<joint monitor>", "J", "the constraint monitors of the joints with a parent body, in the "
                       "structure's order (structure_fmu.joint_monitors)",
                       lambda solver: solver.joint_monitor_names())


# ---- the solver's queries, each made once per solver state and only when a row reading it is read
# (fmu_common.interface.Reading, fmu_common.fmi_slave): the cheap ones apart from the costly (the potential energy,
# the probes' accelerations, a constrained solve), so that reading one does not compute the other -------------
def _latch_times_of(solver) -> dict:
    return dict(solver.state.latch_times)


def _fold_angles(solver) -> dict:
    return solver.fold_angles_deg()


def _joint_monitors(solver) -> dict:
    return solver.joint_monitors()


def _kinetic_energy(solver) -> float:
    return solver.kinetic_energy()


def _energy(reading: Reading, _) -> float:
    """Kinetic plus potential energy (J), the kinetic energy shared with its own output."""
    return reading.once(_kinetic_energy) + reading.solver.potential_energy()


def _flat(query):
    """A row's values from `query` (solver -> (items, k) array), flat item by item."""
    return lambda reading, _: reading.once(query).reshape(-1)


def _probe_positions(solver):
    return solver.probe_positions()


def _probe_velocities(solver):
    return solver.probe_velocities()


def _probe_accelerations(solver):
    return solver.probe_accelerations()


def _gauge_strains(solver):
    return solver.gauge_strains()


def _fold_angles_of(reading: Reading, hinges) -> list[float]:
    """Fold angle (deg) of each hinge."""
    angles = reading.once(_fold_angles)
    return [angles[h] for h in hinges]


def _joint_monitors_of(reading: Reading, names) -> list[float]:
    """Each joint monitor (m or 1, structure_fmu.joint_monitors)."""
    values = reading.once(_joint_monitors)
    return [values[name] for name in names]


def _latch_times(reading: Reading, hinges) -> list[float]:
    """FMI time (s) each hinge latched at, LATCH_PENDING until then: the solver's latch time plus the start time."""
    latched = reading.once(_latch_times_of)
    return [reading.start_time + latched[h] if h in latched else LATCH_PENDING for h in hinges]


def _sensor_descriptions(solver) -> dict[str, str]:
    return {name: text for name, _, text in solver.sensors.output_declarations()}


STRUCTURE = Interface(
    unit="structure unit",
    blocks=(
        Block("e", OUTPUT, "coordinate", "node", "ANCF nodal coordinates (per node r, r_x, r_y in the global "
              "frame, Otsuka et al. 2019, Eq. 3)", value=lambda reading, _: reading.solver.e),
        Block("de", OUTPUT, "rate", "rate of node", "their rates", value=lambda reading, _: reading.solver.de),
        Block("Q", INPUT, "force", "generalized force on node", "generalized external force, work-conjugate to e "
              "(Otsuka et al. 2019, Eq. 12)"),
    ),
    outputs=(
        Output("fold_angle_<hinge>", "deg", "fold angle of hinge <hinge> (child root r_x from parent tip r_x, about "
               "r_y)", _fold_angles_of, HINGES,
               key="fold_angles_deg", doc="fold angle of each revolute joint (a hinge)"),
        Output("energy", "J", "energy monitor of the structure solver", _energy, monitor=True,
               initial=CALCULATED,   # its potential energy of gravity and of the actuators' springs and torques
               doc="kinetic plus potential energy of the structure (springs, elastic energy, gravity)"),
        Output("kinetic_energy", "J", "kinetic energy of the structure (1/2 de^T M de)",
               lambda reading, _: reading.once(_kinetic_energy), monitor=True),
        Output("constraint_residual", "1", "constraint residual monitor (max norm)",
               lambda reading, _: reading.solver.constraint_residual(), monitor=True,
               doc="max |Phi| of the internal constraints"),
        Output("external_work", "J", "work of the point loads and Q since the start: energy minus it changes only "
               "by damping and driven motions", lambda reading, _: reading.solver.state.work, monitor=True,
               doc="work of the point loads and Q since the start (trapezoidal over the internal steps): energy "
                   "minus it changes only by damping and driven motions"),
        Output("latch_time_<hinge>", "s", f"time hinge <hinge> latched at its stop angle ({LATCH_PENDING:g} until "
               "then)", _latch_times, HINGES, DISCRETE, key="latch_times", pending=LATCH_PENDING,
               doc="time the hinge latched at its stop angle, found within the unit's own internal step; "
                   f"{LATCH_PENDING:g} until then (and for a hinge without a stop). The master's "
                   "`deployment_time_s` is read from it"),
        Output(("<probe>_x", "<probe>_y", "<probe>_z"), "m", "",
               _flat(_probe_positions), PROBES, key="probe_positions",
               describe=_sensor_descriptions,
               doc="global position of each probe's material point, r = S(x, y) e (Otsuka et al. 2019, Eq. 2)"),
        Output(("<probe>_vx", "<probe>_vy", "<probe>_vz"), "m/s", "",
               _flat(_probe_velocities), PROBES, key="probe_velocities",
               describe=_sensor_descriptions, doc="its global velocity, S(x, y) de"),
        Output(("<probe>_ax", "<probe>_ay", "<probe>_az"), "m/s2", "",
               _flat(_probe_accelerations), PROBES, key="probe_accelerations",
               describe=_sensor_descriptions, initial=CALCULATED,   # gravity, the actuators, at t = 0 too
               doc="its global acceleration, S(x, y) dde, under the Q of the last step"),
        Output("<gauge>", "1", "",
               _flat(_gauge_strains), GAUGES, key="strains",
               describe=_sensor_descriptions,
               doc="surface strain of each strain gauge: distance from the reference line x flap curvature"),
        Output("<joint monitor>", {"_point_mismatch": "m", "_axis_product": "1", "_axis_error": "1"},
               {"_point_mismatch": "distance between the parent's tip and the child's root",
                "_axis_product": "axis condition of the joint, 0 while it holds",
                "_axis_error": "axis condition of the joint, 0 while it holds"},
               _joint_monitors_of, JOINT_MONITORS,
               key="joints", doc="constraint monitors of each joint with a parent body (docs/structure.md): "
                                 "`<joint>_point_mismatch` of every one, `<joint>_axis_product` of a universal "
                                 "joint, `<joint>_axis_error` of a revolute one"),
    ),
    parameters=Parameters("the tunable keys of the scene's `structure` table (`StructureSolver.tunable_parameters`), "
                          "each with the unit and description of its scene key: set before initialization, "
                          "no rebuild"),
    partner="aero unit",
)
"""The structure unit's variables in value-reference order (docs/fmu.md, "Structure FMU")."""
