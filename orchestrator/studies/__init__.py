"""The study toolkit of the tests and of benchmarks/; the product (``wingsim``) does not import it.

- ``metrics``    figures of merit of runs (CL error, peak bending, tip deflection, ...)
- ``stability``  stability estimates: time-step limits, the added-mass limit of explicit coupling, divergence
- ``study``      many runs in worker processes, recorded and resumable
"""
