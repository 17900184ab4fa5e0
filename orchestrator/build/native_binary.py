"""The FMU's native binary: a C shim (`fmi_shim.c`) in place of pythonfmu's Linux binary.

pythonfmu's `binaries/linux64/<id>.so` takes the Python C API from the host process, so only a Python
host can load it. `install_shim(fmu)` compiles `fmi_shim.c` with the system C compiler (`$CC`, else
`cc`) for the interpreter running the build, makes it `binaries/linux64/<id>.so` and keeps pythonfmu's
binary beside it as `<id>_pythonfmu.so`. The shim starts this interpreter's shared libpython, with this
environment's python as program name, in a host without Python; in a Python host it uses the host's
interpreter. Either way the FMU runs on the machine and in the Python environment it was built in.

The same source, compiled with `worker=` (`compile_shim`), is the binary of a standalone FMU
(`orchestrator.build.standalone`): it forwards to the unit's worker process (`fmi_worker.c`, `compile_worker`)
instead of pythonfmu's binary. `source_digest` covers every C file of both.
"""
from __future__ import annotations

import hashlib
import importlib.util
import shlex
import subprocess
import sys
import sysconfig
import tempfile
import xml.etree.ElementTree as ET
import zipfile
from pathlib import Path

from fmu_common import c_library
from orchestrator.files import write_file

SHIM_SOURCE = Path(__file__).with_name("fmi_shim.c")
WORKER_SOURCE = Path(__file__).with_name("fmi_worker.c")
NATIVE_SOURCES = (SHIM_SOURCE, WORKER_SOURCE, *(Path(__file__).with_name(name) for name in (
    "fmi2_table.h", "fmi2_uri.h", "native_platform.h", "worker_channel.h", "worker_client.c", "worker_client_win.c",
    "fmi_worker_win.c", "python_win.h")))
"""The C sources of the native binaries: the shim, the worker, and what they include (on Linux and Windows)."""
PLATFORM_DIR = "binaries/linux64"
INNER_SUFFIX = "_pythonfmu"
WORKER_SUFFIX = "_worker"


class ShimUnavailable(RuntimeError):
    """The shim cannot be built with this interpreter and compiler (no C compiler, no shared libpython,
    missing headers); the message says what is missing."""


def source_digest() -> str:
    """SHA-256 of the native binaries' sources: an FMU built with another shim or worker is out of date."""
    h = hashlib.sha256()
    for source in NATIVE_SOURCES:
        h.update(source.name.encode() + b"\0" + source.read_bytes() + b"\0")
    return h.hexdigest()


def inner_name(model_identifier: str) -> str:
    """File name of pythonfmu's binary inside the FMU once the shim replaces it."""
    return f"{model_identifier}{INNER_SUFFIX}.so"


def worker_name(model_identifier: str) -> str:
    """File name of a standalone FMU's worker executable, beside its binary."""
    return f"{model_identifier}{WORKER_SUFFIX}"


def install_shim(fmu: Path, libpython: str | None = None, python: str | None = None) -> None:
    """Replace pythonfmu's Linux binary in `fmu` (rewritten in place) by the shim.

    `libpython` and `python` default to this interpreter's shared library and `sys.executable`;
    tests override them to make an FMU whose build environment is gone.
    Raises ShimUnavailable when something the shim needs is missing, RuntimeError if the compiler fails.
    """
    fmu = Path(fmu)
    compiler = c_compiler()
    libpython = libpython or shared_libpython()
    python = python or sys.executable
    if not python:
        raise ShimUnavailable("this interpreter does not know its own executable (sys.executable is empty)")
    with zipfile.ZipFile(fmu) as z:
        guid, model_identifier = _identity(z.read("modelDescription.xml"))
        names = set(z.namelist())
        kept = f"{PLATFORM_DIR}/{inner_name(model_identifier)}"  # an FMU that has the shim already
        pythonfmu_binary = z.read(kept if kept in names else f"{PLATFORM_DIR}/{model_identifier}.so")
    with tempfile.TemporaryDirectory(prefix="wingsim_shim_") as tmp:
        shim = Path(tmp) / f"{model_identifier}.so"
        compile_shim(shim, guid, model_identifier, libpython=libpython, python=python, compiler=compiler)
        _replace_binary(fmu, model_identifier, shim.read_bytes(), pythonfmu_binary)


def compile_shim(out: Path, guid: str, model_identifier: str, libpython: str | None = None,
                 python: str | None = None, worker: tuple[str, str] | None = None,
                 compiler: list[str] | None = None) -> None:
    """Compile `fmi_shim.c` into `out` for the FMU (`guid`, `model_identifier`): an ordinary FMU's binary
    (this interpreter's `libpython` and `python` compiled in), or with `worker` = (runtime key, packages) a
    standalone FMU's, which forwards to a worker process and needs nothing of Python (worker_client.c:
    SHIM_WORKER_KEY, SHIM_PACKAGES). RuntimeError if the compiler fails."""
    defines = {"SHIM_GUID": guid, "SHIM_INNER": inner_name(model_identifier)}
    includes = ["-I", str(fmi_headers())]
    if worker:
        defines.update(SHIM_WORKER=worker_name(model_identifier), SHIM_WORKER_KEY=worker[0], SHIM_PACKAGES=worker[1])
    else:
        defines.update(SHIM_LIBPYTHON=libpython, SHIM_PYTHON=python)
        includes += ["-I", str(_python_headers())]
    command = (compiler or c_compiler()) + ["-shared", "-fPIC", "-O2", "-pthread", "-Wall", *includes]
    command += [f"-D{name}={_c_string(value)}" for name, value in defines.items()]
    run_compiler(command + ["-o", str(out), str(SHIM_SOURCE), "-ldl"])


def compile_worker(out: Path, libpython: Path) -> None:
    """Compile a standalone FMU's worker (`fmi_worker.c`) into `out`, linked against `libpython` (found at run
    time in `runtime/lib` beside the worker). RuntimeError if the compiler fails."""
    command = c_compiler() + ["-O2", "-pthread", "-Wall", "-I", str(fmi_headers()), "-I", str(_python_headers()),
                              "-o", str(out), str(WORKER_SOURCE), str(libpython), "-ldl",
                              "-Wl,--disable-new-dtags,-rpath,$ORIGIN/runtime/lib"]
    run_compiler(command)


def run_compiler(command: list[str]) -> None:
    """Run a compiler command; RuntimeError with its messages when it fails."""
    proc = subprocess.run(command, capture_output=True, text=True)
    if proc.returncode != 0:
        raise RuntimeError(f"compiling the FMU's native binary failed ({shlex.join(command)}):\n"
                           f"{proc.stderr.strip()}")


def unavailable_reason() -> str | None:
    """What is missing to build the shim with this interpreter, or None if nothing is."""
    try:
        c_compiler(), shared_libpython(), _python_headers(), fmi_headers()
    except ShimUnavailable as missing:
        return str(missing)
    return None


def c_compiler() -> list[str]:
    """The system C compiler as a command (fmu_common.c_library.c_compiler: $CC, else cc); raises
    ShimUnavailable when it is not on PATH (or the platform is not Linux)."""
    if not sys.platform.startswith("linux"):
        raise ShimUnavailable(f"the shim is built for Linux only, not {sys.platform}")
    try:
        return c_library.c_compiler()
    except c_library.CLibraryUnavailable as missing:
        raise ShimUnavailable(str(missing)) from None


def shared_libpython() -> str:
    """This interpreter's shared libpython (path); ShimUnavailable if it has none."""
    if not sysconfig.get_config_var("Py_ENABLE_SHARED"):
        raise ShimUnavailable(f"this Python ({sys.executable}) has no shared libpython "
                              "(it was built without --enable-shared)")
    name = sysconfig.get_config_var("INSTSONAME") or sysconfig.get_config_var("LDLIBRARY")
    path = Path(sysconfig.get_config_var("LIBDIR") or "") / (name or "")
    if not name or not path.is_file():
        raise ShimUnavailable(f"the shared libpython of this Python was not found (looked for {path})")
    return str(path)


def _python_headers() -> Path:
    include = Path(sysconfig.get_config_var("INCLUDEPY") or "")
    if not (include / "Python.h").is_file():
        raise ShimUnavailable(f"the Python headers are missing (no Python.h in {include}; a python3-dev "
                              "package provides them)")
    return include


def fmi_headers() -> Path:
    """The folder of the FMI 2.0 C headers fmpy ships (fmpy/c-code); raises ShimUnavailable without them."""
    spec = importlib.util.find_spec("fmpy")
    folders = list(spec.submodule_search_locations or []) if spec else []
    for folder in folders:
        if (Path(folder) / "c-code" / "fmi2Functions.h").is_file():
            return Path(folder) / "c-code"
    raise ShimUnavailable("the FMI 2.0 headers (fmpy/c-code/fmi2Functions.h) were not found")


def _identity(model_description: bytes) -> tuple[str, str]:
    """(GUID, Co-Simulation modelIdentifier) of a modelDescription.xml."""
    root = ET.fromstring(model_description)
    cs = root.find("CoSimulation")
    if cs is None or not root.get("guid") or not cs.get("modelIdentifier"):
        raise RuntimeError("modelDescription.xml has no guid or no CoSimulation modelIdentifier")
    return root.get("guid"), cs.get("modelIdentifier")


def _c_string(text: str) -> str:
    """`text` as a C string literal (UTF-8, every byte outside printable ASCII escaped in octal)."""
    out = []
    for byte in text.encode("utf-8"):
        ch = chr(byte)
        if ch in '"\\' or not 32 <= byte < 127:
            out.append(f"\\{byte:03o}")
        else:
            out.append(ch)
    return '"' + "".join(out) + '"'


def _replace_binary(fmu: Path, model_identifier: str, shim: bytes, pythonfmu_binary: bytes) -> None:
    """Rewrite `fmu` with `shim` as the Linux binary and pythonfmu's beside it, and no other platform's."""
    binary = f"{PLATFORM_DIR}/{model_identifier}.so"
    kept = f"{PLATFORM_DIR}/{inner_name(model_identifier)}"

    def rewrite(rewritten: Path) -> None:
        with zipfile.ZipFile(fmu) as old, zipfile.ZipFile(rewritten, "w", zipfile.ZIP_DEFLATED) as new:
            for info in old.infolist():
                if info.filename == kept or not _on_linux(info.filename):
                    continue
                if info.filename == binary:
                    new.writestr(_executable_entry(binary, info.date_time), shim)
                    new.writestr(_executable_entry(kept, info.date_time), pythonfmu_binary)
                else:
                    new.writestr(info, old.read(info))

    write_file(fmu, rewrite)


def keep_linux_only(fmu: Path) -> None:
    """Rewrite `fmu` without the binaries of other platforms than linux64 (pythonfmu's builder adds its win64
    binary, which nothing of ours is built or tested for)."""
    with zipfile.ZipFile(fmu) as old:
        if all(_on_linux(name) for name in old.namelist()):
            return

    def rewrite(rewritten: Path) -> None:
        with zipfile.ZipFile(fmu) as old, zipfile.ZipFile(rewritten, "w", zipfile.ZIP_DEFLATED) as new:
            for info in old.infolist():
                if _on_linux(info.filename):
                    new.writestr(info, old.read(info))

    write_file(fmu, rewrite)


def _on_linux(name: str) -> bool:
    """False for an archive entry in another platform's binaries folder."""
    parts = name.split("/")
    return not (parts[0] == "binaries" and len(parts) > 2 and parts[1] != PLATFORM_DIR.split("/")[1])


def _executable_entry(name: str, date_time: tuple) -> zipfile.ZipInfo:
    info = zipfile.ZipInfo(name, date_time=date_time)
    info.compress_type = zipfile.ZIP_DEFLATED
    info.external_attr = 0o755 << 16
    return info
