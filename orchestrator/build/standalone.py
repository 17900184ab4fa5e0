"""Standalone FMUs: units that carry their whole runtime and run it in a worker process of their own.

`make_standalone(fmus)` rewrites the FMUs of a scene built by `orchestrator.build.fmus` so that they need no Python on
the target machine and nothing from the host's (one runtime for all, so that a host runs them in one worker):

    binaries/linux64/<id>.so            the shim compiled with `worker` (native_binary.compile_shim): in the
                                        host process, it starts the worker at fmi2Instantiate and forwards
                                        every call to it (worker_client.c); nothing of Python enters the host
    binaries/linux64/<id>_worker        the worker (fmi_worker.c): starts the runtime's Python isolated and
                                        serves the calls with pythonfmu's binary, as an ordinary FMU does
    binaries/linux64/<id>_pythonfmu.so  pythonfmu's binary, unchanged
    binaries/linux64/runtime/           the Python runtime (`orchestrator.build.runtime`)
    resources/                          as built, the Python sources compiled beside them (__pycache__,
                                        unchecked hashes), so that a worker starts without compiling
    resources/standalone.json           what the target needs and what the runtime holds: the oldest glibc
                                        its binaries run on, the Python and package versions (`describe`)

With `win64`, the FMUs also carry binaries/win64/ (`orchestrator.build.win64`: the same design for 64-bit Windows,
compiled here with mingw-w64, with a Windows runtime of the same packages); else linux64 only. The archive is
deflated at zlib's default level (the highest saves under 1% of the size and takes twice as long). Building
one needs a C compiler and a Python with a shared libpython and its headers (`unavailable_reason`), and for
win64 what `win64.unavailable_reason` names.
"""
from __future__ import annotations

import hashlib
import importlib.metadata
import importlib.util
import json
import os
import py_compile
import shutil
import sys
import tempfile
import zipfile
from pathlib import Path

from orchestrator.build import native_binary, runtime, win64 as windows
from orchestrator.files import write_file

PLATFORM = "linux64"
DESCRIPTION = "standalone.json"


def unavailable_reason() -> str | None:
    """What this machine lacks to build standalone FMUs (a C compiler, a shared libpython, the Python or FMI
    headers), or None."""
    return native_binary.unavailable_reason()


def make_standalone(fmus: list[Path], win64: bool = False) -> None:
    """Rewrite `fmus` (a scene's FMUs, built by orchestrator.build.fmus) as standalone FMUs with one runtime, each
    written whole or not at all: units of the same runtime and code share a worker process in a host
    (worker_channel.h). `win64`: with the win64 binaries and runtime too (module docstring).

    Raises native_binary.ShimUnavailable, runtime.RuntimeUnavailable or win64.Win64Unavailable when something it
    needs is missing, RuntimeError when a compilation fails.
    """
    fmus = [Path(fmu) for fmu in fmus]
    with tempfile.TemporaryDirectory(prefix="wingsim_standalone_") as tmp:
        folders = [Path(tmp) / f"{k}" for k in range(len(fmus))]
        for fmu, folder in zip(fmus, folders):
            _unpack(fmu, folder)
        held = runtime.collect([folder / "resources" for folder in folders])
        worker = Path(tmp) / "worker"                # one program serves every unit: compiled once
        native_binary.compile_worker(worker, Path(native_binary.shared_libpython()))
        if win64:
            kit = windows.kit()
            windows_files = windows.runtime_files(held, kit)
            windows_worker = Path(tmp) / "worker.exe"
            windows.compile_worker(windows_worker, kit)
        key = None
        for folder in folders:
            guid, identifier = native_binary._identity((folder / "modelDescription.xml").read_bytes())
            binaries = folder / "binaries"
            for platform in binaries.iterdir():
                if platform.name != PLATFORM:
                    shutil.rmtree(platform)
            linux = binaries / PLATFORM
            inner = linux / native_binary.inner_name(identifier)
            if not inner.exists():                   # built without the ordinary shim: pythonfmu's binary
                os.replace(linux / f"{identifier}.so", inner)
            runtime.write(held, linux / "runtime")
            _compile_sources(folder / "resources")
            key, packages = key or _runtime_key(linux / "runtime"), _packages(folder / "resources")
            native_binary.compile_shim(linux / f"{identifier}.so", guid, identifier, worker=(key, packages))
            shutil.copy2(worker, linux / native_binary.worker_name(identifier))
            description = _description(held, linux)
            if win64:
                windows.add_binaries(folder, guid, identifier, key, packages, windows_worker, windows_files)
                description["win64"] = {"windows": "10 or later, x64", "python": kit.python_version()}
            (folder / "resources" / DESCRIPTION).write_text(json.dumps(description, indent=1))
        for fmu, folder in zip(fmus, folders):
            write_file(fmu, lambda partial, folder=folder: _pack(folder, partial))


def describe(fmu: Path) -> str:
    """One line on a standalone FMU for its builder: its size, packed and unpacked, and what it needs."""
    with zipfile.ZipFile(fmu) as z:
        unpacked = sum(info.file_size for info in z.infolist())
        held = json.loads(z.read(f"resources/{DESCRIPTION}"))
    windows = (f" and on 64-bit Windows {held['win64']['windows'].split(',')[0]} (Python {held['win64']['python']})"
               if "win64" in held else "")
    return (f"{fmu}: standalone, {Path(fmu).stat().st_size / 1e6:.1f} MB ({unpacked / 1e6:.0f} MB unpacked), "
            f"Python {held['python']}; runs on x86-64 Linux with glibc >= {held['glibc']}{windows}")


def _description(held: runtime.Runtime, linux: Path) -> dict:
    """resources/standalone.json: the oldest glibc the binaries run on, the interpreter and the packages."""
    packages, distributions = {}, importlib.metadata.packages_distributions()
    for dest in held.files:
        parts = dest.split("/")
        if parts[0] == "site-packages":
            for dist in distributions.get(parts[1].split(".")[0], []):
                packages[dist] = importlib.metadata.version(dist)
    return {"glibc": runtime.glibc_needed(linux), "python": ".".join(map(str, sys.version_info[:3])),
            "packages": dict(sorted(packages.items()))}


def _runtime_key(folder: Path) -> str:
    """16 hex digits naming the runtime in `folder` and the native binaries' sources: FMUs with the same key
    can share a worker process (worker_channel.h)."""
    h = hashlib.sha256(native_binary.source_digest().encode())
    for path in sorted(p for p in folder.rglob("*") if p.is_file()):
        h.update(path.relative_to(folder).as_posix().encode() + b"\0" + hashlib.sha256(path.read_bytes()).digest())
    return h.hexdigest()[:16]


def _packages(resources: Path) -> str:
    """"name=digest;..." of the Python code in `resources` (each package folder and module): a worker serves
    FMUs whose code of a same name is the same (worker_channel.h)."""
    entries = []
    for item in sorted(resources.iterdir()):
        if item.is_dir() and (item / "__init__.py").is_file():
            files = sorted(p for p in item.rglob("*") if p.is_file() and "__pycache__" not in p.parts)
        elif item.suffix == ".py":
            files = [item]
        else:
            continue
        h = hashlib.sha256()
        for path in files:
            h.update(path.relative_to(resources).as_posix().encode() + b"\0" + path.read_bytes() + b"\0")
        entries.append(f"{item.name.removesuffix('.py')}={h.hexdigest()[:16]}")
    return ";".join(entries)


def _unpack(fmu: Path, folder: Path) -> None:
    """Extract `fmu` into `folder`, keeping the file modes the archive records."""
    with zipfile.ZipFile(fmu) as archive:
        for info in archive.infolist():
            target = folder / info.filename
            archive.extract(info, folder)
            mode = info.external_attr >> 16
            if mode and not info.is_dir():
                target.chmod(mode & 0o777)


def _compile_sources(resources: Path) -> None:
    """Compile every Python file under `resources` into its __pycache__ (unchecked hash: unpacking gives the
    sources new modification times, which a checked .pyc would take as changes)."""
    for source in sorted(resources.rglob("*.py")):
        py_compile.compile(str(source), cfile=importlib.util.cache_from_source(str(source)), doraise=True,
                           invalidation_mode=py_compile.PycInvalidationMode.UNCHECKED_HASH)


def _pack(folder: Path, archive: Path) -> None:
    """Zip `folder` into `archive`, deflated, executables marked so (0755)."""
    with zipfile.ZipFile(archive, "w", zipfile.ZIP_DEFLATED) as z:
        for path in sorted(folder.rglob("*")):
            if path.is_dir():
                continue
            info = zipfile.ZipInfo(path.relative_to(folder).as_posix(), date_time=(2020, 1, 1, 0, 0, 0))
            info.compress_type = zipfile.ZIP_DEFLATED
            info.external_attr = (0o755 if os.access(path, os.X_OK) else 0o644) << 16
            with open(path, "rb") as f:
                z.writestr(info, f.read())
