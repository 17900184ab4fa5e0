"""Build the FMUs a scene needs (pythonfmu), with the resolved scene embedded as `resources/scene.json`.

`build_fmus(scene, out_dir)` writes `out_dir/structure.fmu` and, when `aero.model != "none"`, `aero.fmu`.
Each FMU holds its slave script at the top of `resources/` (pythonfmu imports it from there, and puts
`resources/` first on `sys.path`; the two scripts have distinct names, `structure_slave.py` and
`aero_slave.py`, so that both FMUs run in one process), the Python packages it imports (`fmu_common/` and
`structure_fmu/`; `fmu_common/` and `aero_fmu/` for the aero unit, never the structure solver; copied as
their *.py files and C kernels, each *.c with its library beside it, compiled once per machine by
fmu_common.c_library, so that an FMU never compiles when it starts), `scene.json`, `build_info.json`
(digests used by `fmus_up_to_date`) and `requirements.txt` (the third-party distributions the sources import,
pinned to this environment's versions: `pythonfmu deploy` installs them, and the unit names every missing
one at once, fmu_common/dependencies.py).
FMUs are built with canGetAndSetFMUstate and canSerializeFMUstate, for rollback by implicit masters.
An ordinary FMU does not bundle Python, numpy or scipy: it runs in the Python environment it was built in.
Its Linux binary is a C shim (`native_binary`) that starts that environment's Python in a host without one
and forwards every FMI call to pythonfmu's binary. With `standalone=True` the FMU carries its whole runtime
and runs it in a worker process of its own (`orchestrator.build.standalone`): it needs no Python on the target.
Either kind carries binaries for linux64 only, but standalone FMUs built with `win64=True`, which carry win64
binaries and a Windows runtime too (`orchestrator.build.win64`).
"""
from __future__ import annotations

import hashlib
import importlib
import importlib.metadata
import importlib.util
import json
import shutil
import sys
import tempfile
import zipfile
from pathlib import Path

from fmu_common import c_library
from fmu_common.choices import aero_model
from fmu_common.dependencies import REQUIREMENTS
from fmu_common.errors import SceneError
from fmu_common.fmi_slave import SCENE_RESOURCE
from fmu_common.scene_schema import MASTER_TABLES, without_tunables
from orchestrator.build import native_binary, standalone as standalone_fmu, win64 as windows
from orchestrator.build.sources import UNITS, BuildError, requirements, slave_script, source_digest, sources
from orchestrator.files import folder_lock, process_record, write_file
from orchestrator.scene.load import check_physics

BUILD_INFO_RESOURCE = "build_info.json"

# kind -> (FMU file name, slave module, packages embedded in resources/)
def units_needed(scene: dict) -> list[str]:
    """Unit kinds the scene needs: always the structure, the aero unit when `aero.model` builds one (not "none",
    `fmu_common.choices.AeroModel.builds_unit`)."""
    return ["structure", "aero"] if aero_model(scene["aero"]["model"]).builds_unit else ["structure"]


def build_fmus(scene: dict, out_dir: Path, standalone: bool = False, win64: bool = False,
               units: list[str] | None = None) -> list[Path]:
    """Build every FMU the scene needs into `out_dir`, or only those of `units` (kinds, a subset of
    `units_needed`); returns their paths (structure first). `standalone`: FMUs that carry their runtime (module
    docstring); `win64` (with `standalone` only): with win64 binaries too.

    Raises SceneError (from the structure package) for a bad scene, BuildError if a build fails or, before
    anything is built, when standalone FMUs (or their win64 binaries) cannot be built here
    (`standalone_fmu.unavailable_reason`, `win64.unavailable_reason`).
    """
    refused = refusal(standalone, win64)
    if refused is not None:
        raise BuildError(refused[1])
    kinds = units_to_build(scene, units)
    for kind in kinds:  # the C kernels compile (once per machine) while the scene is checked and the units built
        for _, source in sources(kind):
            if source.suffix == ".c":
                c_library.start_compiling(source)
    for kind in kinds:  # fail before building anything
        _require(kind, scene)
    check_physics(scene)
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    built = [_build_unit(kind, scene, out_dir, standalone, win64) for kind in kinds]
    if standalone:
        try:
            standalone_fmu.make_standalone(built, win64)
        except Exception as exc:
            for fmu in built:            # never leave an FMU whose build_info says standalone but is not
                fmu.unlink(missing_ok=True)
            if isinstance(exc, SceneError):
                raise
            raise BuildError(f"building the standalone FMUs of scene {scene.get('name', '?')!r} into {out_dir} "
                             f"failed: {type(exc).__name__}: {exc}") from exc
    return built


BUILD_LOCK = ".build.lock"


def build_lock(out_dir: Path):
    """Hold the folder `out_dir` (created if missing) for one process while it checks and builds FMUs there
    (`orchestrator.files.folder_lock` on `out_dir/.build.lock`, waiting for a process that holds it, and saying
    whom it waits for): concurrent builds of one folder run one after the other, each FMU is renamed into place
    whole, and runs of variants that share one folder (they differ in tunable keys only) build it once, the
    others waiting and finding the FMUs up to date. Released when the block ends or the process dies."""
    return folder_lock(out_dir, process_record(), lock_file=BUILD_LOCK, wait=True)


def refusal(standalone: bool, win64: bool) -> tuple[str, str] | None:
    """Why FMUs of this kind cannot be built here, as (the option to blame, "--standalone" or "--win64", the
    reason), or None: win64 binaries without standalone FMUs, or what this machine lacks for either."""
    if win64 and not standalone:
        return "--win64", "win64 binaries are added to standalone FMUs only: give --standalone too"
    missing = standalone_fmu.unavailable_reason() if standalone else None
    if missing is not None:
        return "--standalone", f"standalone FMUs cannot be built here: {missing}"
    missing = windows.unavailable_reason() if win64 else None
    if missing is not None:
        return "--win64", f"win64 binaries cannot be built here: {missing}"
    return None


def fmus_up_to_date(scene: dict, out_dir: Path, standalone: bool = False, win64: bool = False,
                    units: list[str] | None = None) -> bool:
    """True if every FMU the scene needs (or each of `units`) exists in `out_dir`, of the kind asked for, built
    from this scene (but for its tunable keys, which the master sets as parameters: `build_digest`) and these
    sources (an FMU with win64 binaries serves where none are asked for)."""
    for kind in units_to_build(scene, units):
        fmu = Path(out_dir) / UNITS[kind][0]
        try:
            info = json.loads(read_resource(fmu, BUILD_INFO_RESOURCE))
            if info not in (_build_info(kind, scene, standalone, win64), _build_info(kind, scene, standalone, True)):
                return False
        except (OSError, KeyError, ValueError, zipfile.BadZipFile, BuildError):
            return False
    return True


def units_to_build(scene: dict, units: list[str] | None) -> list[str]:
    """`units` in build order (structure first), each one the scene needs; all it needs for None. SceneError
    naming ``--unit`` for a unit the scene does not build."""
    needed = units_needed(scene)
    if units is None:
        return needed
    for kind in units:
        if kind not in needed:
            raise SceneError("--unit", kind, f"a unit the scene builds ({', '.join(needed)}): aero.model = "
                                             f"{scene['aero']['model']!r} builds no {kind} unit")
    return [kind for kind in needed if kind in units]


def read_resource(fmu: Path, name: str) -> str:
    """Text of `resources/<name>` inside an FMU file."""
    with zipfile.ZipFile(fmu) as z:
        return z.read(f"resources/{name}").decode("utf-8")


def embedded_scene(fmu: Path) -> dict:
    """The resolved scene an FMU was built from."""
    return json.loads(read_resource(fmu, SCENE_RESOURCE))


def _require(kind: str, scene: dict) -> None:
    """BuildError unless the slave module of `kind` can be imported."""
    module_name = UNITS[kind][1]
    try:
        spec = importlib.util.find_spec(module_name)
    except ImportError:
        spec = None
    if spec is None:
        raise BuildError(f"the {kind} unit needs {module_name}, which is missing from this installation")
    slave_script(kind)


def build_digest(scene: dict) -> str:
    """SHA-256 (hex) of what the FMUs of a resolved scene are built from: the scene as canonical JSON with the
    values of its tunable keys blanked (`fmu_common.scene_schema.without_tunables`) and without the tables only
    the master reads (`MASTER_TABLES`: what it records), the `scene_sha256` its FMUs carry. Scenes that differ
    only in those keys have one digest and run on the same FMUs."""
    built_from = {key: value for key, value in without_tunables(scene).items() if key not in MASTER_TABLES}
    return hashlib.sha256(json.dumps(built_from, sort_keys=True).encode()).hexdigest()


def _build_info(kind: str, scene: dict, standalone: bool, win64: bool = False) -> dict:
    info = {"unit": kind, "sources_sha256": source_digest(kind), "scene_sha256": build_digest(scene),
            "native_binary_sha256": native_binary.source_digest(), "standalone": standalone}
    if win64:
        info["win64"] = True
    return info


def _build_unit(kind: str, scene: dict, out_dir: Path, standalone: bool, win64: bool = False) -> Path:
    fmu_name, module_name, packages = UNITS[kind]
    from pythonfmu import FmuBuilder

    script = slave_script(kind)
    dest = out_dir / fmu_name
    saved_path, saved_module = list(sys.path), sys.modules.get(script.stem)
    with tempfile.TemporaryDirectory(prefix=f"wingsim_build_{kind}_") as tmp:
        stage = Path(tmp) / "stage"
        stage.mkdir()
        (stage / SCENE_RESOURCE).write_text(json.dumps(scene, indent=1), encoding="utf-8")
        (stage / BUILD_INFO_RESOURCE).write_text(json.dumps(_build_info(kind, scene, standalone, win64)),
                                                 encoding="utf-8")
        (stage / REQUIREMENTS).write_text(requirements(kind), encoding="utf-8")
        project_files = [stage / SCENE_RESOURCE, stage / BUILD_INFO_RESOURCE, stage / REQUIREMENTS]
        for archive_name, f in sources(kind)[1:]:
            target = stage / archive_name
            target.parent.mkdir(parents=True, exist_ok=True)
            shutil.copyfile(f, target)
            if target.suffix == ".c":
                _c_kernel(f, target.parent, dest)
        project_files += [stage / p for p in packages]

        def build(partial: Path) -> None:   # into a temporary name beside `dest`, renamed when whole
            try:
                FmuBuilder.build_FMU(script, dest=partial, project_files=project_files,
                                     canGetAndSetFMUstate=True, canSerializeFMUstate=True)
                _native_binary(partial, dest)
            except SceneError:
                raise
            except Exception as exc:
                raise BuildError(f"building {dest} for scene {scene.get('name', '?')!r} failed: "
                                 f"{type(exc).__name__}: {exc}") from exc

        try:
            write_file(dest, build)
        finally:  # pythonfmu leaves the script folder on sys.path and the script in sys.modules
            sys.path[:] = saved_path
            if saved_module is None:
                sys.modules.pop(script.stem, None)
            else:
                sys.modules[script.stem] = saved_module
    return dest


def _native_binary(fmu: Path, dest: Path) -> None:
    """Give `fmu` the shim as its Linux binary; without a C compiler it keeps pythonfmu's, and says so. Either
    way no other platform's binary stays."""
    try:
        native_binary.install_shim(fmu)
    except native_binary.ShimUnavailable as missing:
        native_binary.keep_linux_only(fmu)
        print(f"warning: {dest}: {missing}. The FMU keeps pythonfmu's own binary: it runs only in Python "
              "hosts (wingsim run, fmpy, libcosimpy), not in C tools such as the FMI Compliance Checker, "
              "and a call the unit refuses returns fmi2OK with the reason logged at error status.",
              file=sys.stderr)


def _c_kernel(source: Path, folder: Path, dest: Path) -> None:
    """Put the library of the C kernel `source` (fmu_common.c_library: compiled once per machine) and its digest
    record into `folder` beside its copy, verified there (`c_library.carry`), so that the FMU loads it without
    compiling; without a C compiler the FMU compiles it at its first instantiation on a machine that has one, and
    says so."""
    try:
        c_library.carry(source, folder)
    except (c_library.CLibraryUnavailable, OSError) as missing:
        print(f"warning: {dest}: the C kernel {source.name} was not compiled into the FMU ({missing}). The FMU "
              "compiles it at its first instantiation where a C compiler is found, else runs with "
              "WINGSIM_KERNELS=numpy only.", file=sys.stderr)



