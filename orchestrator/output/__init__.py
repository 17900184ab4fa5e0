"""Output stage: what a run leaves in its output folder.

- ``results``          ``timeseries.csv`` and ``summary.json`` (README, Outputs), also for a failed run
- ``column_units``     the unit of each ``timeseries.csv`` column, written in its header (``tip_z [m]``)
- ``structure_counts`` summary.json's ``structure_counts``: the structure's coordinates and constraint rows
- ``plots``            PNG plots of a run
- ``run_record``       ``run.json``: which run wrote the folder, and whether it finished writing it
- ``run_folders``      the folder of each ``--set`` variant, and the run folders ``wingsim results`` lists
- ``mechanism_view``   the mechanism at several instants (``mechanism.png``)
- ``wake_view``        the wing and its wake in 3D (``wake_3d.png``), by replaying the aero unit
- ``planform_view``    the planform and vortex lattice of each body as designed (``planform.png``)
- ``geometry_history`` the structure and the lattice at chosen instants, for the animation and the VTK files
- ``animation``        ``animation.gif`` (``wingsim run --animate``): the run's geometry moving, with the wake
- ``vtk``              the geometry history for ParaView (``wingsim run --vtk``): ``vtk/*.vtu`` and ``*.pvd``
- ``sweep_plot``       ``sweep.png``: a sweep's key figures against each grid key
"""
