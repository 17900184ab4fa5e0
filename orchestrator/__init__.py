"""Master side of wingsim: scenes, FMU build, the co-simulation run loop, results, plots and the CLI.

Modules (one concept each):

- ``scene``       load a TOML scene, fill defaults, validate
- ``overrides``   ``--set KEY=VALUE`` on a raw scene
- ``build``       build the FMUs a scene needs, and tell whether built ones are up to date
- ``native_binary`` the FMU's Linux binary: a C shim (``fmi_shim.c``) that starts the build's Python
                  in a host without one and forwards every FMI call to pythonfmu's binary, or, in a
                  standalone FMU, to the unit's worker process (``worker_client.c``, ``fmi_worker.c``)
- ``standalone``  standalone FMUs: the unit, its Python runtime and its worker, for machines without Python
- ``runtime``     the Python runtime a standalone FMU carries (what the unit imports, traced by
                  ``import_trace.py``, and the libraries that needs)
- ``units``       structure/aero units behind one interface, over a port:
- ``fmu_port``    the FMU through fmpy
- ``direct_port`` the same slave class in-process
- ``master``      step the units from 0 to ``time.stop`` and record what the scene asks for
- ``timeseries``  the recorded samples (time, probe positions, fold angles, monitors)
- ``results``     ``timeseries.csv`` and ``summary.json`` (README, Outputs)
- ``plots``       PNG plots of a run
- ``system``      the built FMUs as one coupled system (components, connections, public variables)
- ``ssp``         that system as an SSP 1.0 package (``wingsim export``)
- ``container``   that system as one FMU, ``wing.fmu`` (our container binary, ``container.c``)
- ``progress``    the progress line on stderr
- ``metrics``     figures of merit of runs (CL error, peak bending, tip deflection, ...) for tests and studies
- ``stability``   stability estimates: time-step limits, the added-mass limit of explicit coupling, divergence
- ``study``       many runs in worker processes, recorded and resumable (the studies in benchmarks/)
- ``cli``         the ``wingsim`` command line
"""
