"""Compiled kernels: which kernels a process runs (compiled or the numpy reference) and where the compiled ones are
cached. The compiled kernels are C files beside the Python code that calls them (the structure's element force and
tangent, structure_fmu/element_kernels.c; the strain-based sweeps along a body, structure_fmu/strain_kernels.c; the
aero unit's Biot-Savart sums, aero_fmu/biot_savart.c), compiled once per machine by fmu_common.c_library into the
cache folder, or into an FMU by its build.

The cache folder is $WINGSIM_CACHE_DIR, else $XDG_CACHE_HOME/wingsim, else ~/.cache/wingsim.

$WINGSIM_KERNELS selects the kernels: `compiled` (the default) or `numpy`, the pure-numpy reference that every
kernel keeps beside it (tests check both agree to 1e-12 relative). `numpy` runs without a C compiler (an FMU
build still puts the C kernels into the FMU, for the hosts that select them).
"""
from __future__ import annotations

import os
from pathlib import Path

KERNELS_VARIABLE = "WINGSIM_KERNELS"
CACHE_VARIABLE = "WINGSIM_CACHE_DIR"
CHOICES = ("compiled", "numpy")


def selected() -> str:
    """The kernels $WINGSIM_KERNELS selects: "compiled" (default) or "numpy"; ValueError naming it otherwise."""
    value = os.environ.get(KERNELS_VARIABLE, "compiled").strip().lower() or "compiled"
    if value not in CHOICES:
        raise ValueError(f"{KERNELS_VARIABLE}={value!r}: one of {', '.join(CHOICES)}")
    return value


def cache_folder() -> Path:
    """The per-user folder of the compiled kernels (module docstring)."""
    if os.environ.get(CACHE_VARIABLE):
        return Path(os.environ[CACHE_VARIABLE])
    base = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    return Path(base) / "wingsim"
