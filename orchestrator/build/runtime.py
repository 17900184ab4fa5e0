"""The Python runtime a standalone FMU carries: the build interpreter's shared libpython, the part of its
standard library and of its site-packages that the unit imports, and every shared library those need
beyond the system's C libraries.

`collect(resources, stage)` decides the files and `write(files, folder)` writes them, laid out as the worker
(`fmi_worker.c`) searches them:

    lib/libpython3.X.so.1.0       and every non-system library a bundled binary needs (libffi, ...)
    lib/python3.X/...             the standard library modules, compiled (*.pyc), and lib-dynload/
    site-packages/...             numpy, scipy, threadpoolctl, ..., compiled, their extension modules and
                                  their wheels' own libraries (numpy.libs/, scipy.libs/)

Which modules: those the unit loads when it runs, and those the standard library modules named anywhere in
its own sources load (`import_trace.py`, run on the FMU's own resources in a subprocess of the build
interpreter: experiment, initialization, steps, state saved and restored, refusals), plus, for a
third-party package, every module of each folder one of them comes from (a package's lazy imports stay
within its folders). The
runtime never holds a test suite, a header or a compiler. Python files are compiled to sourceless *.pyc
(unchecked hashes: unpacking sets new modification times), and the interpreter's binaries are stripped of
symbols they do not export (`strip --strip-unneeded` where it is installed; never the wheels' libraries,
which their build patched and strip would break), so that the FMU stays small.

System libraries (`SYSTEM_LIBRARIES`, as the manylinux policy allows a wheel to expect: glibc's,
libgcc_s, libstdc++) are the only ones the runtime takes from the target machine; `glibc_needed` tells
which glibc version its binaries need at least.
"""
from __future__ import annotations

import json
import py_compile
import re
import shutil
import struct
import subprocess
import sys
import sysconfig
from dataclasses import dataclass
from pathlib import Path

from orchestrator.build.native_binary import shared_libpython

SYSTEM_LIBRARIES = frozenset({
    "libc.so.6", "libm.so.6", "libdl.so.2", "librt.so.1", "libpthread.so.0", "libutil.so.1", "libresolv.so.2",
    "libnsl.so.1", "libgcc_s.so.1", "libstdc++.so.6", "ld-linux-x86-64.so.2"})
"""Libraries the target machine provides (glibc and the compiler's runtime): never bundled."""

LIBRARY_FOLDERS = ("/lib/x86_64-linux-gnu", "/usr/lib/x86_64-linux-gnu", "/lib64", "/usr/lib64", "/lib",
                   "/usr/lib", "/usr/local/lib")
"""Where a library a bundled binary needs is looked for on the build machine (after the interpreter's LIBDIR)."""

TRACE_STEPS = 5
"""Communication steps the import trace takes: enough for every lazy import of a step (factorizations,
wake shedding) to happen."""

UNWANTED = re.compile(r"(^|/)(tests?|testing|_examples?|include|__pycache__)(/|$)|\.(pyi|pxd|pyx|h|c|cpp|f|txt|md)$")
"""Paths inside a third-party package that the runtime never needs."""

_OWN_PACKAGES = ("fmu_common", "structure_fmu", "aero_fmu", "pythonfmu")   # carried in the FMU's resources
_SKIPPED = re.compile(r"^(__main__|site|sitecustomize|usercustomize|_distutils_hack|__editable__.*)$")


class RuntimeUnavailable(RuntimeError):
    """The runtime cannot be assembled; the message says what is missing."""


@dataclass(frozen=True)
class Runtime:
    """The files of a runtime: destination (relative to the runtime folder, POSIX) -> source file. A
    destination ending in .pyc has a .py source to compile. `traced`: the destinations of the modules the units
    loaded (the rest came with them: their folders' other modules, libraries)."""

    files: dict[str, Path]
    traced: frozenset[str] = frozenset()

    def size(self) -> int:
        return sum(f.stat().st_size for f in self.files.values())


def version_folder() -> str:
    """'python3.X' of the build interpreter: the standard library's folder name."""
    return f"python{sys.version_info.major}.{sys.version_info.minor}"


def collect(resources: list[Path]) -> Runtime:
    """The runtime of the units whose FMU resources (slave script, packages, scene) are the folders
    `resources`: what any of them needs (the units of a scene carry one runtime, so that they can share a
    worker process)."""
    roots = _roots()
    modules = {}
    for folder in resources:
        modules.update(_traced_modules(folder))
    libpython = Path(shared_libpython())
    files: dict[str, Path] = {f"lib/{libpython.name}": libpython}
    traced = set()
    for name, source in modules.items():
        if _SKIPPED.match(name) or name.split(".")[0] in _OWN_PACKAGES:
            continue
        placed = _place(Path(source), roots)
        if placed is None:
            continue
        dest, root, kind = placed
        if kind == "site-packages" and "/" in dest.removeprefix("site-packages/"):   # in a package's folder
            for sibling in _package_folder(Path(source)):
                sib = _place(sibling, roots)
                if sib is not None:
                    files.setdefault(_compiled_name(sib[0]), sibling)
        files.setdefault(_compiled_name(dest), Path(source))
        traced.add(_compiled_name(dest))
    _add_libraries(files)
    _add_licenses(files, roots)
    return Runtime(files, frozenset(traced))


def write(runtime: Runtime, folder: Path, strip: bool = True) -> None:
    """Write the runtime into `folder` (created): Python files compiled to sourceless .pyc, binaries copied
    (stripped of unexported symbols when `strip` and the `strip` tool is there)."""
    strip_tool = shutil.which("strip") if strip else None
    for dest, source in sorted(runtime.files.items()):
        target = folder / dest
        target.parent.mkdir(parents=True, exist_ok=True)
        if dest.endswith(".pyc"):
            py_compile.compile(str(source), cfile=str(target), dfile=dest[:-1], doraise=True,
                               invalidation_mode=py_compile.PycInvalidationMode.UNCHECKED_HASH)
            continue
        shutil.copyfile(source, target)
        if _is_elf(target):
            target.chmod(0o755)
            # the interpreter's own binaries only: strip breaks the libraries that wheels patched (patchelf)
            if strip_tool and dest.startswith("lib/"):
                subprocess.run([strip_tool, "--strip-unneeded", str(target)], capture_output=True)


def glibc_needed(folder: Path) -> str:
    """The highest GLIBC_x.y symbol version any binary under `folder` needs: the oldest glibc it runs on."""
    versions = set()
    for path in folder.rglob("*"):
        if path.is_file() and _is_elf(path):
            versions.update(re.findall(rb"GLIBC_([0-9]+\.[0-9]+(?:\.[0-9]+)?)\x00", path.read_bytes()))
    if not versions:
        return "any"
    return max((v.decode() for v in versions), key=lambda v: tuple(int(p) for p in v.split(".")))


# ---- which modules ----------------------------------------------------------------------------------------

def _roots() -> list[tuple[Path, str]]:
    """(folder, kind) of the module locations of the build environment, the longest first: the standard
    library ("stdlib": lib/python3.X/...) and the environment's site-packages ("site-packages")."""
    paths = sysconfig.get_paths()
    roots = {Path(paths["stdlib"]).resolve(): "stdlib", Path(paths["platstdlib"]).resolve(): "stdlib"}
    for key in ("purelib", "platlib"):
        roots.setdefault(Path(paths[key]).resolve(), "site-packages")
    return sorted(roots.items(), key=lambda item: -len(str(item[0])))


def _place(source: Path, roots) -> tuple[str, Path, str] | None:
    """(destination in the runtime, root, kind) of a module file, or None if it is in neither root."""
    resolved = source.resolve()
    for root, kind in roots:
        try:
            relative = resolved.relative_to(root)
        except ValueError:
            continue
        if kind == "stdlib" and relative.parts[:1] == ("site-packages",):
            continue                    # a base interpreter's site-packages are not its standard library
        prefix = f"lib/{version_folder()}" if kind == "stdlib" else "site-packages"
        return f"{prefix}/{relative.as_posix()}", root, kind
    return None


def _compiled_name(dest: str) -> str:
    return dest[:-3] + ".pyc" if dest.endswith(".py") else dest


def _add_licenses(files: dict[str, Path], roots) -> None:
    """Add under licenses/ the license of everything the runtime redistributes: Python's, each distribution's
    of site-packages (their files in the .dist-info folder: numpy's and scipy's also cover the libraries their
    wheels bundle) and, for a library taken from the system, its Debian copyright file where there is one."""
    stdlib = Path(sysconfig.get_paths()["stdlib"])
    if (stdlib / "LICENSE.txt").is_file():
        files["licenses/python/LICENSE.txt"] = stdlib / "LICENSE.txt"
    for root, kind in roots:
        if kind == "site-packages":
            files.update(distribution_licenses(root, files))
    for dest, source in list(files.items()):
        if dest.startswith("lib/") and "/" not in dest[4:] and source != Path(shared_libpython()):
            copyright_file = _debian_copyright(source)
            if copyright_file is not None:
                files[f"licenses/{Path(dest).name}/copyright"] = copyright_file


def distribution_licenses(site_packages: Path, files: dict[str, Path]) -> dict[str, Path]:
    """{licenses/<distribution>/...: file} of every distribution in `site_packages` whose modules `files` (a
    runtime's, destinations under site-packages/) carries: the license files of its .dist-info folder."""
    carried = {dest.split("/")[1].split(".")[0].lower() for dest in files if dest.startswith("site-packages/")}
    out = {}
    for info in sorted(site_packages.glob("*.dist-info")):
        name = info.name.split("-")[0].lower()
        if name.replace("-", "_") not in carried:
            continue
        for license_file in sorted(p for p in info.rglob("*") if p.is_file()
                                   and re.match(r"(LICEN[CS]E|COPYING|NOTICE|AUTHORS)", p.name, re.I)):
            out[f"licenses/{name}/{license_file.relative_to(info).as_posix()}"] = license_file
    return out


def _debian_copyright(library: Path) -> Path | None:
    """/usr/share/doc/<package>/copyright of the Debian package that installed `library`, if dpkg knows it."""
    if shutil.which("dpkg-query") is None:
        return None
    for candidate in {str(library), str(library).replace("/usr/lib/", "/lib/")}:
        found = subprocess.run(["dpkg-query", "-S", candidate], capture_output=True, text=True)
        if found.returncode == 0:
            package = found.stdout.split(":")[0].strip()
            copyright_file = Path("/usr/share/doc") / package / "copyright"
            return copyright_file if copyright_file.is_file() else None
    return None


def _package_folder(source: Path) -> list[Path]:
    """The modules and extension modules beside `source` (its package folder, not its subfolders)."""
    return [f for f in sorted(source.parent.iterdir())
            if f.is_file() and (f.suffix == ".py" or f.name.endswith(".so")) and not UNWANTED.search(f.as_posix())]


def _traced_modules(resources: Path) -> dict[str, str]:
    """{module: file} the unit loads when it runs (import_trace.py in a subprocess of this interpreter), with only
    the site-packages of its requirements importable (`required_packages`)."""
    trace = Path(__file__).with_name("import_trace.py")
    proc = subprocess.run([sys.executable, "-I", str(trace), str(resources), str(TRACE_STEPS),
                           ",".join(required_packages(resources))], capture_output=True, text=True)
    if proc.returncode != 0:
        raise RuntimeUnavailable(f"running the unit to find what it imports failed:\n{proc.stderr.strip()[-3000:]}")
    return json.loads(proc.stdout.strip().splitlines()[-1])


def required_packages(resources: Path) -> list[str]:
    """The top-level packages of the distributions a unit requires (its resources' requirements.txt, pythonfmu,
    and what they require in turn, as installed here): all the unit may import from site-packages when it is
    traced. A package of another distribution that happens to be installed (charset_normalizer, which numpy.f2py
    imports when it finds it) is then absent, as on a machine with the requirements alone, and the runtime does not
    depend on it."""
    import importlib.metadata as metadata
    import re

    canonical = lambda name: re.sub(r"[-_.]+", "-", name).lower()
    pending = [line.split("==")[0] for line in (resources / "requirements.txt").read_text().split()] + ["pythonfmu"]
    seen: set[str] = set()
    while pending:
        name = canonical(pending.pop())
        if name in seen:
            continue
        seen.add(name)
        try:
            requires = metadata.requires(name) or []
        except metadata.PackageNotFoundError:
            continue
        pending += [re.match(r"[A-Za-z0-9_.-]+", r).group(0) for r in requires if "extra ==" not in r]
    return sorted(top for top, dists in metadata.packages_distributions().items()
                  if any(canonical(d) in seen for d in dists))


# ---- which libraries --------------------------------------------------------------------------------------

def _add_libraries(files: dict[str, Path]) -> None:
    """Add to `files` every library a bundled binary needs that is not a system library: one its RPATH names
    (a wheel's own, numpy.libs/...) where the RPATH finds it, laid out as in site-packages so that the RPATH
    finds it again; any other under lib/, where the worker's RPATH finds it. RuntimeUnavailable if one is not
    on this machine."""
    roots = _roots()
    bundled = {Path(dest).name for dest in files}
    pending = [(source, []) for source in files.values() if _is_elf(source)]
    while pending:
        source, inherited = pending.pop()
        needed, own = _dynamic(source)
        search = own + inherited            # a library found through an RPATH finds its own needs there too
        for name in needed:
            if name in SYSTEM_LIBRARIES:
                continue
            found = next((Path(folder) / name for folder in search if (Path(folder) / name).is_file()), None)
            placed = _place(found, roots) if found is not None else None
            if placed is None and name in bundled:
                continue
            if found is None:
                found = _find_library(name)
            if found is None:
                raise RuntimeUnavailable(f"the library {name} that {source.name} needs was not found on this "
                                         f"machine (looked in {', '.join(_library_folders())})")
            dest = placed[0] if placed is not None else f"lib/{name}"
            if dest not in files:
                files[dest] = found
                bundled.add(name)
                pending.append((found, search))


def _library_folders() -> list[str]:
    return [sysconfig.get_config_var("LIBDIR") or "", *LIBRARY_FOLDERS]


def _find_library(name: str) -> Path | None:
    for folder in _library_folders():
        candidate = Path(folder) / name
        if folder and candidate.is_file():
            return candidate.resolve()
    return None


def _is_elf(path: Path) -> bool:
    with open(path, "rb") as f:
        return f.read(4) == b"\x7fELF"


def _dynamic(path: Path) -> tuple[list[str], list[str]]:
    """(DT_NEEDED, DT_RPATH and DT_RUNPATH folders with $ORIGIN resolved) of an ELF64 little-endian file: the
    libraries it names to the dynamic loader and where it tells the loader to look first."""
    data = path.read_bytes()
    if data[:4] != b"\x7fELF" or data[4] != 2 or data[5] != 1:
        return [], []
    shoff, = struct.unpack_from("<Q", data, 0x28)
    shentsize, shnum = struct.unpack_from("<HH", data, 0x3A)
    sections = [struct.unpack_from("<IIQQQQIIQQ", data, shoff + k * shentsize) for k in range(shnum)]
    needed, search = [], []
    for _, kind, _, _, offset, size, link, _, _, entsize in sections:
        if kind != 6:                               # SHT_DYNAMIC
            continue
        strtab = sections[link][4]
        for k in range(0, size, entsize or 16):
            tag, value = struct.unpack_from("<qQ", data, offset + k)
            if tag == 0:
                break
            if tag in (1, 15, 29):                  # DT_NEEDED, DT_RPATH, DT_RUNPATH
                text = data[strtab + value:data.index(b"\x00", strtab + value)].decode()
                if tag == 1:
                    needed.append(text)
                else:
                    origin = str(path.resolve().parent)
                    search += [p.replace("$ORIGIN", origin).replace("${ORIGIN}", origin) for p in text.split(":")]
    return needed, search
