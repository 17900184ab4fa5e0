"""C kernels: a C source file compiled into a shared library with the system C compiler, once per machine, and
loaded with ctypes (a process loads it in about a millisecond).

`load(source)` returns the library of `source` (e.g. aero_fmu/biot_savart.c), loaded once per process. The
library's file name carries a digest of the source, the compiler flags and the platform
(`<stem>-<digest>.so`; `<stem>-<digest>.dll` on Windows, where a standalone FMU's worker runs them), and it is
looked for, in this order:

1. beside the source: an FMU's build puts its C kernels' libraries into the FMU (`carry`), so an FMU never
   compiles at instantiation, whatever folder it unpacks into;
2. in the per-user cache folder of the compiled kernels (`fmu_common.compiled.cache_folder`), where `load`
   compiles it the first time (about 0.5 s, never rewritten): in-process runs, tests and the FMU builds.
   `start_compiling` begins that compilation in the background, for a caller with other work.

Every library is verified before it is loaded or carried: beside it, `<library>.sha256` records the SHA-256 of
its exact bytes, written when it was compiled (`record_file`). A library whose bytes do not match its record
(truncated, altered, or without one) is reported by a warning naming the file, deleted and compiled again, so a
damaged file is never mapped into the process. A compilation runs in a private temporary folder and its library
is then copied into the cache folder (record first, each renamed into place); where that folder cannot be
written (read-only, full), a warning says so and the library is loaded from the temporary folder: compiled in
every process. A compilation that has not finished within `fmu_common.compiled.compile_seconds` is stopped.

A changed source or other flags get a new file name. Compiling needs the system C compiler ($CC, else cc),
which the FMU build needs anyway. Without one, when the compilation fails or is stopped, `load` raises
CLibraryUnavailable, and `kernels` (what the units call) warns once per process and returns None: the numpy
kernels run ($WINGSIM_KERNELS=numpy selects them without the warning). The Windows libraries of a standalone
FMU's win64 binaries are compiled on Linux with a cross compiler (`carry` with its command).
"""
from __future__ import annotations

import atexit
import ctypes
import hashlib
import os
import shlex
import shutil
import signal
import subprocess
import sysconfig
import tempfile
import time
import warnings
from pathlib import Path

from .compiled import (CACHE_VARIABLE, COMPILE_SECONDS_VARIABLE, KERNELS_VARIABLE, cache_folder, compile_seconds,
                       selected)

FLAGS = ("-O3", "-shared", "-fPIC", "-ffp-contract=off", "-fno-math-errno", "-Wall")
"""IEEE arithmetic as numpy does it (-ffp-contract=off: no fused multiply-add; no fast-math); -fno-math-errno
lets the square roots vectorize (they set no errno then, and their results are the same)."""
PLATFORM_FLAGS = {"win-amd64": ("-static-libgcc",)}
"""Flags added for a platform: on Windows the library then imports Windows's own DLLs only (no libgcc DLL)."""
RECORD_SUFFIX = ".sha256"
"""The record of a library's digest is the file `<library><RECORD_SUFFIX>` beside it (`record_file`)."""

_loaded: dict[str, ctypes.CDLL] = {}
_unavailable: set[str] = set()                  # sources whose kernels `kernels` gave up on in this process
_compiling: dict[tuple[Path, str], "_Compilation"] = {}     # by (resolved source, platform): `start_compiling`
_private: list["_Compilation"] = []             # compilations whose library is loaded from their own folder


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
    # RECORD_SUFFIX too: libraries compiled before their digests were recorded have other names, never looked at
    h.update(" ".join(_flags(platform)).encode() + platform.encode() + RECORD_SUFFIX.encode())
    suffix = ".dll" if platform.startswith("win") else ".so"
    return f"{Path(source).stem}-{h.hexdigest()[:16]}{suffix}"


def _flags(platform: str) -> tuple[str, ...]:
    return FLAGS + PLATFORM_FLAGS.get(platform, ())


def record_file(library: Path) -> Path:
    """The file recording the SHA-256 of `library`'s bytes (hex), beside it.

    Args:
        library: a library file's path.
    """
    return library.with_name(library.name + RECORD_SUFFIX)


def _digest(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def mismatch(library: Path) -> str | None:
    """Why the bytes of `library` are not those recorded when it was compiled (`record_file`), or None.

    Args:
        library: a library file that exists.
    """
    try:        # bytes, not text: a standalone FMU's runtime carries no codecs beyond UTF-8
        recorded = record_file(library).read_bytes().strip().decode(errors="replace")
    except OSError as err:
        return f"its digest record {record_file(library).name} cannot be read ({err})"
    try:
        actual, size = _digest(library), library.stat().st_size
    except OSError as err:
        return f"it cannot be read ({err})"
    if actual != recorded:
        return (f"its {size} bytes have SHA-256 {actual[:16]}..., not the {recorded[:16]}... recorded when it was "
                "compiled (truncated or altered)")
    return None


def carry(source: str | Path, folder: str | Path, platform: str | None = None,
          compiler: list[str] | None = None) -> Path:
    """Put the library of the C file `source` and its digest record into `folder` (an FMU being built), checked
    there before it is packed; returns the copy. CLibraryUnavailable when it cannot be compiled or the copy is not
    the library recorded (naming the file); OSError when `folder` cannot be written.

    Args:
        source: the C file.
        folder: where the library goes (beside the source's copy, where `load` looks first).
        platform: the target's platform name (`library_name`); None: this interpreter's.
        compiler: the compiler's command line (a cross compiler for another platform); None: `c_compiler`.
    """
    library = library_file(source, platform, compiler)
    copy = Path(folder) / library.name
    shutil.copyfile(record_file(library), record_file(copy))
    shutil.copyfile(library, copy)
    problem = mismatch(copy)
    if problem is not None:
        copy.unlink(missing_ok=True)
        raise CLibraryUnavailable(f"the C kernel library {copy} copied from {library} is not the library compiled: "
                                  f"{problem}")
    return copy


def load(source: str | Path) -> ctypes.CDLL:
    """The library of the C file `source`, loaded once per process (module docstring).

    CLibraryUnavailable if it can be neither found nor compiled.

    Args:
        source: the C file.
    """
    library = _loaded.get(source)          # by the path as given (a module constant): no file system call
    if library is None:
        library = _loaded[source] = _open(library_file(source))
    return library


def kernels(source: str | Path, signatures: dict) -> ctypes.CDLL | None:
    """The library of the C kernels `source` (`load`) with the functions of `signatures` typed, once per process;
    None when $WINGSIM_KERNELS selects the numpy kernels (fmu_common.compiled.selected), or when the library can
    be neither found nor compiled: then the numpy kernels run, and the first time in a process a warning says why.

    Args:
        source: the C file.
        signatures: {function name: (its ctypes restype, its ctypes argtypes list)}.

    Returns:
        the library, or None.
    """
    if selected() == "numpy" or source in _unavailable:
        return None
    try:
        library = load(source)
    except CLibraryUnavailable as missing:
        if not _unavailable:
            warnings.warn(f"C kernels unavailable, the numpy kernels run instead (the same numbers to 1e-12, "
                          f"slower): {missing}", stacklevel=3)
        _unavailable.add(source)
        return None
    if not hasattr(library, "typed"):
        for name, (restype, argtypes) in signatures.items():
            function = getattr(library, name)
            function.restype, function.argtypes = restype, argtypes
        library.typed = True
    return library


def address(array) -> int:
    """The address of the data of a writable, C-contiguous, non-empty numpy array: array.ctypes.data at a fraction
    of its cost (the kernels are called thousands of times per simulated second).

    Args:
        array: the numpy array.
    """
    return ctypes.addressof(ctypes.c_char.from_buffer(array))


def library_file(source: str | Path, platform: str | None = None, compiler: list[str] | None = None) -> Path:
    """The verified library of the C file `source`: beside it, else in the cache folder, where it is compiled if
    absent or damaged (module docstring); where the cache folder cannot be written, the library compiled for this
    process (with a warning). CLibraryUnavailable if it cannot be compiled.

    Or where the compilation `start_compiling` began is awaited.

    Args:
        source: the C file.
        platform: the target's platform name (`library_name`); None: this interpreter's.
        compiler: the compiler's command line; None: this machine's (`c_compiler`).
    """
    source = Path(source).resolve()
    platform = platform or sysconfig.get_platform()
    found = _found(source, platform)
    if found is not None:
        return found
    compilation = _compiling.pop((source, platform), None) or _Compilation(source, compiler, platform)
    built = compilation.wait()
    try:
        target = _install(built, cache_folder())
    except OSError as err:
        warnings.warn(f"C kernels: cannot write the cache folder {cache_folder()} ({err}); {source.name} is "
                      f"compiled in every process (set {CACHE_VARIABLE} to a writable folder)", stacklevel=2)
        _private.append(compilation)        # removed at exit: a loaded library stays mapped once its file is gone
        return built
    compilation.discard()
    return target


def start_compiling(source: str | Path) -> None:
    """Begin compiling the C file `source` into the cache folder in the background, unless its library is found.

    So the compiler runs while the caller does other work (the FMU build); the next `library_file` or `load` of it
    waits for it and reports its errors.

    Args:
        source: the C file.
    """
    key = (Path(source).resolve(), sysconfig.get_platform())
    if key in _compiling or _found(*key) is not None:
        return
    try:
        _compiling[key] = _Compilation(key[0], platform=key[1])
    except CLibraryUnavailable:
        return              # not started: `library_file` tries again and raises the same error, where it is needed


@atexit.register
def _abandon_compilations() -> None:
    """At exit, stop the compilations nobody waited for (the command ended first) and remove every temporary
    folder of a compilation."""
    for compilation in [*_compiling.values(), *_private]:
        compilation.discard()
    _compiling.clear()
    _private.clear()


def compile_into(source: str | Path, folder: str | Path) -> Path:
    """Compile the C file `source` into `folder`/`library_name(source)` with its digest record (each renamed into
    place) and return that path.

    CLibraryUnavailable without a compiler or when the compilation fails; OSError if `folder` cannot be written.

    Args:
        source: the C file.
        folder: where the library is written.
    """
    compilation = _Compilation(Path(source))
    try:
        return _install(compilation.wait(), Path(folder))
    finally:
        compilation.discard()


def _found(source: Path, platform: str) -> Path | None:
    """The verified library of `source` beside it (this interpreter's platform only) or in the cache folder, if
    it is there; a library that fails its check is reported and deleted."""
    name = library_name(source, platform)
    # the cache folder only then: an FMU's worker on Windows has no home folder in its environment
    places = [source.parent, None] if platform == sysconfig.get_platform() else [None]
    for folder in places:
        library = (folder or cache_folder()) / name
        if not library.is_file():
            continue
        problem = mismatch(library)
        if problem is None:
            return library
        _discard(library, problem, source)
    return None


def _discard(library: Path, problem: str, source: Path) -> None:
    """Report a library that failed its check and delete it (and its record), so that it is compiled again."""
    try:
        library.unlink(missing_ok=True)
        record_file(library).unlink(missing_ok=True)
        done = "deleted"
    except OSError as err:
        done = f"not deleted ({err}), not loaded"
    warnings.warn(f"C kernels: {library} is not the library compiled from {source.name}: {problem}; {done}, "
                  f"{source.name} is compiled again", stacklevel=4)


def _install(built: Path, folder: Path) -> Path:
    """Copy the compiled library `built` and its record into `folder`, each to a temporary name renamed into
    place (the record first: a library in place always has one); returns the library's new path. OSError if
    `folder` cannot be written."""
    folder.mkdir(parents=True, exist_ok=True)
    target = folder / built.name
    for file, destination in ((record_file(built), record_file(target)), (built, target)):
        partial = destination.with_name(f".{destination.name}.{os.getpid()}.tmp")
        try:
            shutil.copyfile(file, partial)
            os.replace(partial, destination)
        finally:
            partial.unlink(missing_ok=True)
    return target


class _Compilation:
    """The compiler running on `source` in a private temporary folder, writing `library_name(source, platform)`
    there: this machine's compiler and platform unless `compiler` and `platform` are given. Stopped when it has
    not finished within `compile_seconds` of its start."""

    def __init__(self, source: Path, compiler: list[str] | None = None, platform: str | None = None):
        platform = platform or sysconfig.get_platform()
        self.source = source
        try:
            compiler = compiler or c_compiler()
        except CLibraryUnavailable as missing:
            raise CLibraryUnavailable(f"the C kernel {source.name} needs compiling: {missing}; install one, or set "
                                      f"{KERNELS_VARIABLE}=numpy for the numpy kernels") from None
        self.limit = compile_seconds()
        try:
            self.folder = Path(tempfile.mkdtemp(prefix="wingsim_c_"))
        except OSError as err:
            raise CLibraryUnavailable(f"compiling the C kernel {source.name}: no temporary folder ({err}); "
                                      f"{KERNELS_VARIABLE}=numpy runs the numpy kernels") from None
        self.built = self.folder / library_name(source, platform)
        self.command = compiler + list(_flags(platform)) + ["-o", str(self.built), str(source), "-lm"]
        self.started = time.monotonic()
        try:            # its own process group: stopping it stops whatever the compiler command started
            self.process = subprocess.Popen(self.command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                                            start_new_session=True)
        except OSError as err:
            shutil.rmtree(self.folder, ignore_errors=True)
            raise CLibraryUnavailable(f"compiling the C kernel {source.name} failed to start ({err}); "
                                      f"{KERNELS_VARIABLE}=numpy runs the numpy kernels") from None

    def wait(self) -> Path:
        """The library's path, with its digest record beside it, once the compiler has finished; CLibraryUnavailable
        if it failed or was stopped at the time limit."""
        try:
            _, errors = self.process.communicate(timeout=max(0.0, self.started + self.limit - time.monotonic()))
        except subprocess.TimeoutExpired:
            self.discard()
            raise CLibraryUnavailable(f"compiling the C kernel {self.source.name} did not finish within "
                                      f"{self.limit:g} s and was stopped ({shlex.join(self.command)}); "
                                      f"{COMPILE_SECONDS_VARIABLE} sets the limit, {KERNELS_VARIABLE}=numpy runs "
                                      "the numpy kernels") from None
        if self.process.returncode != 0 or not self.built.is_file():
            self.discard()
            raise CLibraryUnavailable(f"compiling the C kernel {self.source.name} failed ({shlex.join(self.command)}):"
                                      f"\n{errors.strip()}\n{KERNELS_VARIABLE}=numpy runs the numpy kernels")
        try:
            record_file(self.built).write_bytes(_digest(self.built).encode() + b"\n")
        except OSError as err:
            self.discard()
            raise CLibraryUnavailable(f"compiling the C kernel {self.source.name}: its digest record cannot be "
                                      f"written ({err}); {KERNELS_VARIABLE}=numpy runs the numpy kernels") from None
        return self.built

    def discard(self) -> None:
        """Stop the compiler if it runs and remove the temporary folder."""
        # SIGTERM first: the compiler driver then removes its own temporary files
        for stop in (signal.SIGTERM, getattr(signal, "SIGKILL", signal.SIGTERM)):    # Windows has no SIGKILL
            if self.process.poll() is not None:
                break
            try:
                if hasattr(os, "killpg"):
                    os.killpg(self.process.pid, stop)
                else:
                    self.process.kill()
            except OSError:
                pass                # it ended meanwhile
            try:
                self.process.communicate(timeout=5)
            except subprocess.TimeoutExpired:
                continue
        shutil.rmtree(self.folder, ignore_errors=True)


def _open(path: Path) -> ctypes.CDLL:
    try:
        return ctypes.CDLL(str(path))
    except OSError as err:
        raise CLibraryUnavailable(f"cannot load the C kernel {path} ({err}); delete it to have it compiled "
                                  f"again, or set {KERNELS_VARIABLE}=numpy") from None
