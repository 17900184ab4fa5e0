"""Structure unit: the 18-DoF ANCF multibody solver (000 Secs. II-IV) and its FMI 2.0 slave.

Our matrices are small (n < 1000). On a loaded 2-core machine threaded OpenBLAS made an LU of size 158
take 40-90 ms against 0.35 ms single-threaded, so we ask for one BLAS thread. This takes effect only if
numpy is not imported yet: hosts that import numpy first should set OPENBLAS_NUM_THREADS=1 themselves.
"""
import os

for _variable in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_variable, "1")
