"""Build stage: the FMUs a scene needs, and whether built ones are up to date.

- ``fmus``           build the structure and aero FMUs of a scene (pythonfmu), and tell whether built ones are
                     up to date
- ``sources``        what a unit's FMU is made of: slave script, embedded packages, requirements, their digest
- ``native_binary``  the FMU's Linux binary: a C shim (``fmi_shim.c``) that starts the build's Python in a
                     host without one and forwards every FMI call to pythonfmu's binary, or, in a standalone
                     FMU, to the unit's worker process (``worker_client.c``, ``fmi_worker.c``)
- ``standalone``     standalone FMUs: the unit, its Python runtime and its worker, for machines without Python
- ``runtime``        the Python runtime a standalone FMU carries (what the unit imports and the libraries
                     that needs)
- ``import_trace``   what a unit imports when it runs: a script ``runtime`` runs while it builds
- ``win64``          the Windows binaries and runtime of a standalone FMU (``--win64``)
"""
