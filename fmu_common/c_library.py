"""C kernels: a C source file compiled into a shared library with the system C compiler, once per machine, and
loaded with ctypes (a process loads it in about a millisecond).

`load(source)` returns the library of `source` (e.g. aero_fmu/biot_savart.c), loaded once per process. The
library's file name carries a digest of the source, the compiler flags and the platform
(`<stem>-<digest>.so`; `<stem>-<digest>.dll` on Windows, where a standalone FMU's worker runs them), and it is
looked for, in this order:

1. beside the source: an FMU's build puts its C kernels' libraries into the FMU (`library_file`), so an FMU
   never compiles at instantiation, whatever folder it unpacks into;
2. in the per-user cache folder of the compiled kernels (`fmu_common.compiled.cache_folder`), where `load`
   compiles it the first time (about 0.5 s, written atomically, never rewritten): in-process runs, tests and the
   FMU builds. `start_compiling` begins that compilation in the background, for a caller with other work.
   Where that folder cannot be written, the library is compiled in every process (a warning says so).

A changed source or other flags get a new file name. Compiling needs the system C compiler ($CC, else cc),
which the FMU build needs anyway; without one, or when the compilation fails, `load` raises
CLibraryUnavailable naming $WINGSIM_KERNELS=numpy, the numpy kernels that need no compiler. The Windows
libraries of a standalone FMU's win64 binaries are compiled on Linux with a cross compiler (`cross_compiled`).
"""
from __future__ import annotations

import atexit
import ctypes
import hashlib
import os
import shlex
import shutil
import subprocess
import sysconfig
import tempfile
import warnings
from pathlib import Path

from .compiled import CACHE_VARIABLE, KERNELS_VARIABLE, cache_folder, selected

FLAGS = ("-O3", "-shared", "-fPIC", "-ffp-contract=off", "-fno-math-errno", "-Wall")
"""IEEE arithmetic as numpy does it (-ffp-contract=off: no fused multiply-add; no fast-math); -fno-math-errno
lets the square roots vectorize (they set no errno then, and their results are the same)."""
PLATFORM_FLAGS = {"win-amd64": ("-static-libgcc",)}
"""Flags added for a platform: on Windows the library then imports Windows's own DLLs only (no libgcc DLL)."""

_loaded: dict[str, ctypes.CDLL] = {}
_compiling: dict[Path, "_Compilation"] = {}     # started by `start_compiling`, by resolved source path


class CLibraryUnavailable(RuntimeError):
    """A C kernel library could not be compiled or loaded; the message says why and names the alternative."""


def c_compiler() -> list[str]:
    """The system C compiler as a command: $CC split like a shell word list, else `cc`; CLibraryUnavailable when
    it is not on PATH."""
    cc = shlex.split(os.environ.get("CC", "") or "cc")
    if not cc or shutil.which(cc[0]) is None:
        raise CLibraryUnavailable(f"no C compiler: {cc[0] if cc else 'cc'} (from $CC, else cc) was not found")
    return cc


def library_name(source: Path, platform: str | None = None) -> str:
    """File name of the library of `source`: `<stem>-<digest of source, flags and platform>.so`, `.dll` on Windows.

    Args:
        source: the C file.
        platform: sysconfig.get_platform()'s name of the target, "win-amd64" for 64-bit Windows; None: this
            interpreter's.
    """
    platform = platform or sysconfig.get_platform()
    h = hashlib.sha256(Path(source).read_bytes())
    h.update(" ".join(_flags(platform)).encode() + platform.encode())
    suffix = ".dll" if platform.startswith("win") else ".so"
    return f"{Path(source).stem}-{h.hexdigest()[:16]}{suffix}"


def _flags(platform: str) -> tuple[str, ...]:
    return FLAGS + PLATFORM_FLAGS.get(platform, ())


def cross_compiled(source: str | Path, compiler: list[str], platform: str) -> Path:
    """The library of the C file `source` for `platform`, compiled with a cross compiler into the cache folder once.

    CLibraryUnavailable when the compilation fails, OSError if the cache folder cannot be written.

    Args:
        source: the C file.
        compiler: the cross compiler's command line.
        platform: sysconfig.get_platform()'s name of the target.
    """
    source = Path(source).resolve()
    target = cache_folder() / library_name(source, platform)
    if target.is_file():
        return target
    return _Compilation(source, cache_folder(), compiler, platform).wait()


def load(source: str | Path) -> ctypes.CDLL:
    """The library of the C file `source`, loaded once per process (module docstring).

    CLibraryUnavailable if it can be neither found nor compiled.

    Args:
        source: the C file.
    """
    library = _loaded.get(source)          # by the path as given (a module constant): no file system call
    if library is None:
        library = _loaded[source] = _load(Path(source))
    return library


def kernels(source: str | Path, signatures: dict) -> ctypes.CDLL | None:
    """The library of the C kernels `source` (`load`) with the functions of `signatures` typed, once per process;
    None when $WINGSIM_KERNELS selects the numpy kernels (fmu_common.compiled.selected).

    Args:
        source: the C file.
        signatures: {function name: (its ctypes restype, its ctypes argtypes list)}.

    Returns:
        the library, or None.
    """
    if selected() == "numpy":
        return None
    library = load(source)
    if not hasattr(library, "typed"):
        for name, (restype, argtypes) in signatures.items():
            function = getattr(library, name)
            function.restype, function.argtypes = restype, argtypes
        library.typed = True
    return library


def _load(source: Path) -> ctypes.CDLL:
    try:
        return _open(library_file(source))
    except OSError as err:
        warnings.warn(f"C kernels: cannot write the cache folder {cache_folder()} ({err}); {source.name} is "
                      f"compiled in every process (set {CACHE_VARIABLE} to a writable folder)", stacklevel=3)
    folder = tempfile.mkdtemp(prefix="wingsim_c_")
    try:
        return _open(compile_into(source, folder))
    finally:                # a loaded library stays mapped once its file is gone
        shutil.rmtree(folder, ignore_errors=True)


def library_file(source: str | Path) -> Path:
    """The library of the C file `source`: beside it, else in the cache folder, where it is compiled if absent.

    Or where the compilation `start_compiling` began is awaited. CLibraryUnavailable if it cannot be compiled;
    OSError if the cache folder cannot be written.

    Args:
        source: the C file.
    """
    source = Path(source).resolve()
    found = _found(source)
    if found is not None:
        return found
    pending = _compiling.pop(source, None)
    return (pending or _Compilation(source, cache_folder())).wait()


def start_compiling(source: str | Path) -> None:
    """Begin compiling the C file `source` into the cache folder in the background, unless its library is found.

    So the compiler runs while the caller does other work (the FMU build); the next `library_file` or `load` of it
    waits for it and reports its errors.

    Args:
        source: the C file.
    """
    source = Path(source).resolve()
    if source in _compiling or _found(source) is not None:
        return
    try:
        _compiling[source] = _Compilation(source, cache_folder())
    except (CLibraryUnavailable, OSError):
        return              # not started: `library_file` tries again and raises the same error, where it is needed


@atexit.register
def _abandon_compilations() -> None:
    """At exit, stop the compilations nobody waited for (the command ended first) and remove their partial files."""
    for pending in _compiling.values():
        pending.process.kill()
        pending.process.wait()
        pending.partial.unlink(missing_ok=True)
    _compiling.clear()


def compile_into(source: str | Path, folder: str | Path) -> Path:
    """Compile the C file `source` into `folder`/`library_name(source)` (atomically) and return that path.

    CLibraryUnavailable without a compiler or when the compilation fails.

    Args:
        source: the C file.
        folder: where the library is written.
    """
    return _Compilation(Path(source), Path(folder)).wait()


def _found(source: Path) -> Path | None:
    """The library of `source` beside it or in the cache folder, if it is there."""
    name = library_name(source)
    if (source.parent / name).is_file():
        return source.parent / name
    # only then the cache folder: an FMU's worker on Windows has no home folder in its environment
    cached = cache_folder() / name
    return cached if cached.is_file() else None


class _Compilation:
    """The compiler running on `source`, writing `folder`/`library_name(source, platform)` (renamed into place when
    done): this machine's compiler and platform unless `compiler` and `platform` are given."""

    def __init__(self, source: Path, folder: Path, compiler: list[str] | None = None, platform: str | None = None):
        platform = platform or sysconfig.get_platform()
        self.source, self.target = source, folder / library_name(source, platform)
        try:
            compiler = compiler or c_compiler()
        except CLibraryUnavailable as missing:
            raise CLibraryUnavailable(f"the C kernel {source.name} needs compiling: {missing}; install one, or set "
                                      f"{KERNELS_VARIABLE}=numpy for the numpy kernels") from None
        folder.mkdir(parents=True, exist_ok=True)
        self.partial = self.target.with_name(f".{self.target.name}.{os.getpid()}.tmp")
        self.command = compiler + list(_flags(platform)) + ["-o", str(self.partial), str(source), "-lm"]
        try:
            self.process = subprocess.Popen(self.command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        except OSError as err:
            raise CLibraryUnavailable(f"compiling the C kernel {source.name} failed to start ({err}); "
                                      f"{KERNELS_VARIABLE}=numpy runs the numpy kernels") from None

    def wait(self) -> Path:
        """The library's path once the compiler has finished; CLibraryUnavailable if it failed."""
        _, errors = self.process.communicate()
        if self.process.returncode != 0:
            self.partial.unlink(missing_ok=True)
            raise CLibraryUnavailable(f"compiling the C kernel {self.source.name} failed ({shlex.join(self.command)}):"
                                      f"\n{errors.strip()}\n{KERNELS_VARIABLE}=numpy runs the numpy kernels")
        os.replace(self.partial, self.target)
        return self.target


def _open(path: Path) -> ctypes.CDLL:
    try:
        return ctypes.CDLL(str(path))
    except OSError as err:
        raise CLibraryUnavailable(f"cannot load the C kernel {path} ({err}); delete it to have it compiled "
                                  f"again, or set {KERNELS_VARIABLE}=numpy") from None
