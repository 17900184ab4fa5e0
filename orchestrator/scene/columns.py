"""The fixed columns of ``timeseries.csv`` (README, Outputs), declared where the scene is checked: a scene's
own names (probes, strain gauges, joints) must not take them. ``orchestrator.run.timeseries`` records them."""

MONITOR_COLUMNS = ("energy", "kinetic_energy", "constraint_residual", "external_work")
"""The scalar monitor columns, in ``timeseries.csv`` order, after the fold angles."""

AERO_COLUMNS = ("CL", "lift")
"""The aero unit's columns (lift coefficient, -; lift, N), only for scenes with an aero unit."""

COUPLING_COLUMNS = ("coupling_iterations", "coupling_residual")
"""The implicit coupling's columns (iterations of the communication step, -; its final relative interface
residual, -), last, only for implicitly coupled aero scenes."""
