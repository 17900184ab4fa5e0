"""The fixed columns of ``timeseries.csv`` (README, Outputs), declared where the scene is checked: a scene's
own names (probes, strain gauges, joints) must not take them. ``orchestrator.run.timeseries`` records them.
The units' columns are the outputs their interface tables mark as monitors (``structure_fmu.interface``,
``aero_fmu.interface``)."""

from aero_fmu.interface import AERO
from structure_fmu.interface import STRUCTURE

MONITOR_COLUMNS = tuple(row.key for row in STRUCTURE.outputs if row.monitor)
"""The structure unit's scalar monitor columns (energy, J; kinetic energy, J; constraint residual, -; external
work, J), in ``timeseries.csv`` order, after the fold angles."""

AERO_COLUMNS = tuple(row.key for row in AERO.outputs if row.monitor)
"""The aero unit's columns (lift coefficient, -; lift, N), only for scenes with an aero unit."""



def hinge_moment_column(hinge: str) -> str:
    """The column of the aero unit's moment about a hinge's axis (N m; output ``hinge_moment_<hinge>``), one per
    revolute joint of an aero scene, before AERO_COLUMNS."""
    return f"hinge_moment_{hinge}"


COUPLING_COLUMNS = ("coupling_iterations", "coupling_residual")
"""The implicit coupling's columns (iterations of the communication step, -; its final relative interface
residual, -), last, only for implicitly coupled aero scenes."""
