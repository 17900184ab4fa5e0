"""Aerodynamic FMI unit (UVLM with flat, prescribed or free wake; strip theory).

Built so far (issue 3, first step): the kernels of a steady vortex-lattice method on the structure's
shape functions (000 Sec. V):

  lattice.py      vortex-ring lattice of each body as fixed shape-function matrices (000 Eqs. 12, 20, 21, 24)
  biot_savart.py  velocity of straight vortex segments with a Scully core (000 Eq. 19)
  vlm.py          influence matrix, flat horseshoe wake, circulations (Eq. 22), panel forces (Eqs. 23, 25)

Not implemented yet: the unsteady solver and its wakes, strip theory, the FMI slave. Scenes must use
``aero.model = "none"`` until then, and the scene loader rejects any other aero model with a clear message.

Like structure_fmu, we ask for one BLAS thread (effective only if numpy is not imported yet): on the
shared 2-core machines threaded OpenBLAS was many times slower for the small matrices we factorize.
"""
import os

for _variable in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_variable, "1")
