"""Compiled kernels: which kernels a process runs (compiled or the numpy reference) and where their machine code
is cached, so that the compilation is paid once per machine, not per run nor per FMU instantiation. The compiled
kernels are numba modules (the structure's element kernels, loaded here) and C files (the aero unit's Biot-Savart
kernels, fmu_common.c_library, whose libraries share the cache folder).

A numba kernel module (e.g. structure_fmu/element_kernels.py) is plain Python whose functions numba compiles
(`numba.njit(cache=True)`); `load(path)` imports it. numba keys its on-disk cache by the module's file path and
modification time, and an FMU unpacks into a fresh temporary folder at every instantiation: imported from there,
the kernels would be compiled again by every run. `load` therefore imports a copy of the module kept in a
per-user folder named by the hash of its source and of the numba and Python versions
(`<cache>/<module>-<hash>/<module>.py`, written once and never rewritten), so every process, FMU or not, on
the machine shares one compiled copy; a changed source or a new numba gets a new folder.

The cache folder is $WINGSIM_CACHE_DIR, else $XDG_CACHE_HOME/wingsim, else ~/.cache/wingsim. Where it cannot be
written, the kernels are compiled in the process (a warning says so once) and run compiled all the same.

$WINGSIM_KERNELS selects the kernels: `compiled` (the default) or `numpy`, the pure-numpy reference that every
kernel keeps beside it (tests check both agree to 1e-12 relative). `compiled` without numba installed is an
error naming the variable; `numpy` never imports numba and runs without a C compiler (an FMU build still puts
the C kernels into the FMU, for the hosts that select them).
"""
from __future__ import annotations

import hashlib
import importlib.util
import os
import sys
import warnings
from pathlib import Path

KERNELS_VARIABLE = "WINGSIM_KERNELS"
CACHE_VARIABLE = "WINGSIM_CACHE_DIR"
CHOICES = ("compiled", "numpy")

_loaded: dict[str, object] = {}


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


def load(path: str | Path):
    """The compiled kernel module at `path` (imported once per process from its cached copy), or None when the
    numpy kernels are selected."""
    if selected() == "numpy":
        return None
    module = _loaded.get(path)      # by the path as given (a module constant): no file system call per kernel call
    if module is None:
        module = _loaded[path] = _load(Path(path))
    return module


def _load(path: Path):
    """Import the kernel module at `path` from its cached copy (module docstring)."""
    try:
        import numba
    except ImportError as missing:
        raise ImportError(f"the compiled kernels need numba ({missing}); install it, or set "
                          f"{KERNELS_VARIABLE}=numpy for the numpy kernels") from None
    source = path.read_bytes()
    digest = hashlib.sha256(source + numba.__version__.encode() + sys.version.encode()).hexdigest()[:16]
    return _import(_stable_copy(path, source, digest) or path, f"_wingsim_kernels_{path.stem}_{digest}")


def _stable_copy(path: Path, source: bytes, digest: str) -> Path | None:
    """The copy of the module in the cache folder, written once (atomically); None if it cannot be written."""
    target = cache_folder() / f"{path.stem}-{digest}" / path.name
    if target.exists():
        return target
    try:
        target.parent.mkdir(parents=True, exist_ok=True)
        partial = target.with_suffix(f".{os.getpid()}.tmp")
        partial.write_bytes(source)
        os.replace(partial, target)
        return target
    except OSError as err:
        warnings.warn(f"compiled kernels: cannot write the cache folder {target.parent} ({err}); they are compiled "
                      f"in every process (set {CACHE_VARIABLE} to a writable folder)", stacklevel=3)
        return None


def _import(path: Path, name: str):
    """Import the file `path` as the module `name`, registered in sys.modules (numba re-imports a cached kernel's
    module by name)."""
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    spec.loader.exec_module(module)
    return module
