"""Output stage: what a run leaves in its output folder.

- ``results``         ``timeseries.csv`` and ``summary.json`` (README, Outputs), also for a failed run
- ``structure_counts`` summary.json's ``structure_counts``: the structure's coordinates and constraint rows
- ``plots``           PNG plots of a run
- ``run_record``      ``run.json``: which run wrote the folder, and whether it finished writing it
- ``mechanism_view``  the mechanism at several instants (``mechanism.png``)
- ``wake_view``       the wing and its wake in 3D (``wake_3d.png``), by replaying the aero unit
- ``planform_view``   the planform and vortex lattice of each body as designed (``planform.png``)
"""
