"""Master side of wingsim: the stages of a run, one sub-package each, and the command line on top.

A stage imports only the stages above it in this list (tests/cli/test_architecture.py checks that no
import runs in a circle and that the product never imports ``studies``):

- ``files``    what every stage writes: each file whole or not at all (a temporary name in its folder, renamed),
               each folder written by one process at a time (a lock naming its holder); no stage imported
- ``scene``    read a TOML scene, apply ``--set``, fill defaults, validate; docs/scenes.md from the schema
- ``build``    build the FMUs a scene needs (pythonfmu, the C shim), standalone FMUs and their runtime
- ``run``      the units behind one interface (FMU or in-process), the coupling schemes, the run loop, the
               recorded samples, sweeps
- ``output``   ``timeseries.csv``, ``summary.json`` and the PNG plots of a run
- ``export``   the built FMUs as one system: an SSP package, one container FMU, and ``wingsim validate``
- ``sweep``    ``wingsim sweep``: every combination of grid values, each a run with its outputs, resumable
- ``cli``      the ``wingsim`` command line (``python -m orchestrator``, ``__main__``)
- ``clean``    ``wingsim clean``: remove built FMUs, results, exports of the current folder

``scenes`` is not code: the shipped scene files (the repository's ``scenes/``, installed under this name).

``studies`` (figures of merit, stability estimates, many runs in worker processes) serves the tests and
the studies in benchmarks/; the product does not import it.
"""
