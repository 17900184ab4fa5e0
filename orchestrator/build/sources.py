"""What a unit's FMU is made of: its slave script, the packages it embeds and the third-party distributions
they import, and the digest of those sources that a built FMU carries (`build_info.json`)."""
from __future__ import annotations

import hashlib
import importlib
import importlib.metadata
import importlib.util
import sys
from pathlib import Path

UNITS = {
    "structure": ("structure.fmu", "structure_fmu.structure_slave", ("fmu_common", "structure_fmu")),
    "aero": ("aero.fmu", "aero_fmu.aero_slave", ("fmu_common", "aero_fmu")),
}


class BuildError(RuntimeError):
    """An FMU could not be built; the message names the unit, the scene and the cause."""


def slave_script(kind: str) -> Path:
    fmu_name, module_name, _ = UNITS[kind]
    try:
        module = importlib.import_module(module_name)
    except ImportError as exc:
        raise BuildError(f"cannot import {module_name} to build {fmu_name}: {exc}") from exc
    return Path(module.__file__)


def _package_dir(package: str) -> Path:
    spec = importlib.util.find_spec(package)
    if spec is None or not spec.submodule_search_locations:
        raise BuildError(f"package {package} to embed in the FMU was not found on sys.path")
    return Path(list(spec.submodule_search_locations)[0])


def sources(kind: str) -> list[tuple[str, Path]]:
    """(archive name, file) of the slave script and every *.py and *.c (C kernels) of the embedded packages,
    sorted."""
    script = slave_script(kind)
    files = [(script.name, script)]
    for package in UNITS[kind][2]:
        root = _package_dir(package)
        for f in sorted([*root.rglob("*.py"), *root.rglob("*.c")]):
            if "__pycache__" in f.parts or f == script:
                continue
            files.append((f"{package}/{f.relative_to(root).as_posix()}", f))
    return files


def requirements(kind: str) -> str:
    """requirements.txt of a unit: the distributions of every third-party module its sources import, pinned to
    the versions installed here (the FMU carries its own packages and pythonfmu in its resources)."""
    from orchestrator.build.import_trace import imported_modules

    own = {package for package in UNITS[kind][2]} | {"pythonfmu"}
    distributions = importlib.metadata.packages_distributions()
    lines = set()
    for name in imported_modules(str(f) for _, f in sources(kind) if f.suffix == ".py"):
        top = name.split(".")[0]
        if top in own or top in sys.stdlib_module_names:
            continue
        for dist in distributions.get(top, []):
            lines.add(f"{dist}=={importlib.metadata.version(dist)}")
    return "".join(f"{line}\n" for line in sorted(lines))


def source_digest(kind: str) -> str:
    """The `sources_sha256` an FMU of `kind` built now from the installed sources carries: SHA-256 of the
    slave script and the embedded packages' *.py and *.c files, names and contents."""
    h = hashlib.sha256()
    for name, f in sources(kind):
        h.update(name.encode() + b"\0" + f.read_bytes() + b"\0")
    return h.hexdigest()
