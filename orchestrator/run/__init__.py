"""Run stage: the units stepped together from 0 to ``time.stop``.

- ``port``          what the master and the ports agree on: the unit kinds, errors, log entries, ``Port``
- ``units``         a unit behind one interface (``Unit``), over a port:
- ``fmu_port``      the FMU through fmpy
- ``direct_port``   the same slave class in-process
- ``layout``        the variables an FMU declares, checked against its unit's code
- ``coupling``      the coupling schemes (Gauss-Seidel, Jacobi, implicit with rollback)
- ``acceleration``  interface acceleration of the implicit scheme
- ``master``        the run loop: step the units and record what the scene asks for
- ``recording``     each sample gathered from the units' output vectors into the series' next row
- ``timeseries``    the recorded samples (time, probe positions, fold angles, monitors)
- ``progress``      the progress line on stderr, with the time left and a note for a long run
- ``estimate``      the size of a run's timeseries.csv, announced before a run that writes a large one
- ``allocator``     glibc's allocator thresholds for the processes wingsim owns
"""
