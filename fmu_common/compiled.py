"""Compiled kernels: which kernels a process runs (compiled or the numpy reference) and where the compiled ones are
cached. The compiled kernels are C files beside the Python code that calls them (the structure's element force and
tangent, structure_fmu/element_kernels.c; the strain-based sweeps along a body, structure_fmu/strain_kernels.c; the
aero unit's Biot-Savart sums, aero_fmu/biot_savart.c; its flat-wake step, aero_fmu/flat_wake_step.c), compiled
once per machine by fmu_common.c_library into the cache folder, or into an FMU by its build.

The cache folder is $WINGSIM_CACHE_DIR, else $XDG_CACHE_HOME/wingsim, else ~/.cache/wingsim. A compilation is
stopped after $WINGSIM_COMPILE_SECONDS seconds (default `COMPILE_SECONDS`), so a compiler that never returns
cannot hang a run.

$WINGSIM_KERNELS selects the kernels: `compiled` (the default) or `numpy`, the pure-numpy reference that every
kernel keeps beside it (tests check both agree to 1e-12 relative). `numpy` runs without a C compiler (an FMU
build still puts the C kernels into the FMU, for the hosts that select them).

$WINGSIM_THREADS sets the threads of the threaded kernels (the free wake's treecode, aero_fmu/treecode.py): by
default the cores this process may run on (os.sched_getaffinity; os.cpu_count where that is not available).
"""
from __future__ import annotations

import os
from pathlib import Path

KERNELS_VARIABLE = "WINGSIM_KERNELS"
CACHE_VARIABLE = "WINGSIM_CACHE_DIR"
COMPILE_SECONDS_VARIABLE = "WINGSIM_COMPILE_SECONDS"
THREADS_VARIABLE = "WINGSIM_THREADS"
CHOICES = ("compiled", "numpy")
COMPILE_SECONDS = 60.0
"""Default time limit of one C kernel's compilation, s: each compiles in under a second; the margin is for a
loaded machine."""


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


def compile_seconds() -> float:
    """The time limit of one compilation, s: $WINGSIM_COMPILE_SECONDS, else `COMPILE_SECONDS`; ValueError naming
    the variable for a value that is not a number > 0."""
    text = os.environ.get(COMPILE_SECONDS_VARIABLE, "").strip()
    if not text:
        return COMPILE_SECONDS
    try:
        seconds = float(text)
    except ValueError:
        seconds = float("nan")
    if not 0 < seconds < float("inf"):
        raise ValueError(f"{COMPILE_SECONDS_VARIABLE}={text!r}: a time limit in seconds, a number > 0")
    return seconds


def kernel_threads() -> int:
    """Threads of the threaded kernels: $WINGSIM_THREADS, else the cores this process may run on (module
    docstring); ValueError naming the variable for a value that is not an integer >= 1."""
    text = os.environ.get(THREADS_VARIABLE, "").strip()
    if not text:
        cores = os.sched_getaffinity(0) if hasattr(os, "sched_getaffinity") else range(os.cpu_count() or 1)
        return max(1, len(cores))
    if not text.isdigit() or int(text) < 1:
        raise ValueError(f"{THREADS_VARIABLE}={text!r}: a number of threads, an integer >= 1")
    return int(text)
