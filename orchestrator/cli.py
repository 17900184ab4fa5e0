"""The ``wingsim`` command line (docs/architecture.md); ``python -m orchestrator`` is the same.

- ``wingsim build SCENE [--out DIR] [--set KEY=VALUE ...] [--unit structure|aero] [--standalone [--win64]]``:
  build the scene's FMUs, or only the one unit, into DIR (default: the folder ``run`` uses, ``fmu_dir``;
  ``--standalone``: FMUs that carry their Python runtime; ``--win64``: with binaries and a runtime for 64-bit
  Windows too).
- ``wingsim run SCENE [--out DIR] [--set KEY=VALUE ...] [--backend fmu|direct] [--standalone] [--animate] [--vtk]``:
  build if needed, run, write ``summary.json``, ``timeseries.csv`` and PNG plots into DIR (default
  ``results/<scene>/``, and ``results/<scene>/<overrides>/`` for a ``--set`` variant:
  ``orchestrator.output.run_folders``); notes first for implausible flow values and a large timeseries.csv (the run
  goes ahead); ``--animate``: ``animation.gif`` too, ``--vtk``: the geometry history for ParaView in ``DIR/vtk/``
  (``orchestrator.output.animation``, ``orchestrator.output.vtk``).
- ``wingsim validate [FMU ...]``: fmpy's model-description check and a short simulation of each FMU; compliance
  and the physics of the simulation reported apart.
- ``wingsim scenes``: the shipped scenes with their headlines; ``wingsim init NAME [--from SCENE]``: copy one to
  ``./NAME.toml`` (``orchestrator.scene.shipped``). SCENE everywhere is a file or a shipped scene's name.
- ``wingsim results [SCENE]``: the run folders under ``results/`` with status, key figures and overrides;
  ``wingsim clean [SCENE] [--fmus] [--results] [--export] [--dry-run]``: remove them (``orchestrator.clean``).
- ``wingsim --version``.
- ``wingsim export SCENE [--out DIR] [--set KEY=VALUE ...] [--aero FMU] [--standalone [--win64]]``: build the
  FMUs if needed (into the folder ``run`` uses), write the coupled system as ``DIR/<scene>.ssp`` (SSP 1.0) and as
  one FMU, ``DIR/wing.fmu``; ``--aero``: with that aero unit FMU (built for the same structure, e.g. by
  ``build --set aero.model=strip --unit aero``) in place of the scene's own, whose structure FMU is used as it
  is. Default DIR ``export/<scene>/`` for the scene as its file writes it, ``export/<scene>-<variant>/`` for a
  variant (``export_dir``), so that no variant overwrites another's files; ``-standalone`` appended with
  ``--standalone``.
- ``wingsim sweep SCENE --grid KEY=V1,V2,... [--grid ...] [--set KEY=VALUE ...] [--out DIR]
  [--backend direct|fmu] [--jobs N] [--scheduler ADDRESS] [--plots]``: every combination of the grid
  values, one run folder each under ``DIR/runs/`` and one row per run in ``DIR/sweep.csv`` (default
  ``results/<scene>/sweep/``); local processes, or a Dask cluster with ``--scheduler`` (docs/sweep.md).

``run`` and ``export`` build and open the FMUs in ``fmus/<scene>/`` when no ``--set`` is given (the folder
``build`` fills by default) and in ``fmus/<scene>-<first 12 hex digits of the resolved scene's SHA-256>/``
with ``--set``, so that variants of one scene never overwrite each other's FMUs (``fmu_dir``); standalone FMUs
in the same folders with ``-standalone`` appended.

``--out`` is checked before anything runs (``results.check_out_dir``): a file, a path below a file or a
folder that cannot be written is refused with exit 2; so is the folder of ``run`` or ``sweep`` while another
run or sweep writes it (``orchestrator.files.folder_lock``, ``FolderBusy`` naming that run). ``build`` waits for
a build of the same folder (``orchestrator.build.fmus.build_lock``).

Exit codes: 0 run ok (or build done); 1 run diverged or failed (its summary is still written), a results
file could not be written (the message names it), or an unexpected error; 2 bad scene or bad arguments
(nothing runs); 130 interrupted by Ctrl-C (SIGINT), 143 terminated by SIGTERM: both are handled alike,
the results so far are written with status "interrupted" (128 + the signal number, as a shell reports a process
killed by it).
Errors are one line, ``error: ...``; set ``WINGSIM_DEBUG=1`` to see tracebacks.
"""

from __future__ import annotations

import argparse
import logging
import os
import signal
import sys
import time
from pathlib import Path
from typing import Sequence

from fmu_common.errors import SceneError
from fmu_common.threads import limit_blas_threads
from orchestrator.run import allocator
DEBUG_ENV = "WINGSIM_DEBUG"
FMU_ROOT = Path("fmus")
RESULTS_ROOT = Path("results")
EXPORT_ROOT = Path("export")
INIT_SOURCE = "deploy_rigid"
"""The shipped scene ``wingsim init`` copies without ``--from``."""
DIGEST_CHARS = 12
"""Hex digits of the resolved scene's digest in the FMU folder of a ``--set`` variant."""
HANDLED_SIGNALS = (signal.SIGINT, signal.SIGTERM)
STANDALONE_HELP = ("FMUs that carry their Python runtime and run it in a worker process of their own: they need "
                   "no Python on the machine that runs them (docs/fmu.md)")
SCENE_HELP = "scene file (.toml), or the name of a shipped scene (wingsim scenes lists them)"
SET_HELP = "override a dotted scene key, e.g. --set flow.speed=20 (repeatable)"
WIN64_HELP = ("with --standalone: binaries and a Python runtime for 64-bit Windows too (cross-compiled with mingw-w64; "
              "the first such build downloads the Windows packages; docs/fmu.md)")


def _debug() -> bool:
    return os.environ.get(DEBUG_ENV, "") not in ("", "0")


class Interrupted(KeyboardInterrupt):
    """SIGINT or SIGTERM, raised where the main thread stands so that both unwind like Ctrl-C."""

    def __init__(self, signum: int):
        self.signum = signum
        super().__init__(signal.Signals(signum).name)


_received: list[int] = []   # the handled signals received during this command, in order


def _interrupt(signum: int, frame) -> None:
    _received.append(signum)
    raise Interrupted(signum)


def interrupt_exit_code() -> int | None:
    """128 + the number of the first signal received (130 for SIGINT, 143 for SIGTERM), or None."""
    return 128 + _received[0] if _received else None


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="wingsim", description="FMI co-simulation of deployable wings (structure and aero units).",
        epilog=f"Set {DEBUG_ENV}=1 to see tracebacks of unexpected errors.")
    parser.add_argument("--version", action="version", version=f"%(prog)s {_version()}")
    commands = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    build = commands.add_parser("build", help="build the FMUs a scene needs",
                                description="Build the FMUs a scene needs.")
    build.add_argument("scene", type=Path, metavar="SCENE", help=SCENE_HELP)
    build.add_argument("--out", type=Path, metavar="DIR",
                       help="output folder (default: the folder `run` uses: fmus/<scene name>/ for the scene as its "
                            "file writes it, fmus/<scene name>-<digest>/ for a --set variant; -standalone appended "
                            "with --standalone)")
    build.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                       help=SET_HELP)
    build.add_argument("--unit", choices=("structure", "aero"), action="append", dest="units", metavar="UNIT",
                       help="build only this unit's FMU: structure or aero (repeatable; default: every unit the "
                            "scene needs)")
    build.add_argument("--standalone", action="store_true", help=STANDALONE_HELP)
    build.add_argument("--win64", action="store_true", help=WIN64_HELP)
    build.set_defaults(func=cmd_build)

    run = commands.add_parser("run", help="build if needed, run a scene, write results and plots",
                              description="Build the FMUs if needed, run the scene and write "
                                          "timeseries.csv, summary.json and PNG plots.")
    run.add_argument("scene", type=Path, metavar="SCENE", help=SCENE_HELP)
    run.add_argument("--out", type=Path, metavar="DIR",
                     help="output folder (default: results/<scene name>/ for the scene as its file writes it, "
                          "results/<scene name>/<overrides>/ with --set, e.g. results/deploy_rigid/flow.speed=8/)")
    run.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                     help=SET_HELP)
    run.add_argument("--backend", choices=("fmu", "direct"), default="fmu",
                     help="fmu: the built FMUs through fmpy (default); direct: the same slaves in-process")
    run.add_argument("--standalone", action="store_true", help=STANDALONE_HELP + " (with --backend fmu)")
    run.add_argument("--animate", action="store_true",
                     help="also write animation.gif: the deployment from the recorded geometry, with the wake")
    run.add_argument("--vtk", action="store_true",
                     help="also write the geometry history for ParaView: vtk/structure.pvd (and vtk/lattice.pvd for "
                          "an aero scene), one .vtu per frame")
    run.set_defaults(func=cmd_run)

    validate = commands.add_parser("validate", help="check built FMUs: model description and a short simulation",
                                   description="Check built FMUs as another FMI tool would: fmpy's model "
                                               "description validation and a short simulation of each.")
    validate.add_argument("fmus", type=Path, nargs="*", metavar="FMU", help="FMU files (default: fmus/**/*.fmu)")
    validate.set_defaults(func=cmd_validate)

    export = commands.add_parser("export", help="write the coupled system as an SSP package and as one FMU",
                                 description="Build the scene's FMUs if needed and write the coupled system as "
                                             "DIR/<scene>.ssp (System Structure and Parameterization 1.0: both "
                                             "FMUs, every connection, the parameters, the default experiment) "
                                             "and as DIR/wing.fmu (one FMU with the units coupled inside).")
    export.add_argument("scene", type=Path, metavar="SCENE", help=SCENE_HELP)
    export.add_argument("--out", type=Path, metavar="DIR", help="output folder (default: export/<scene name>/)")
    export.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                        help=SET_HELP)
    export.add_argument("--aero", type=Path, metavar="FMU",
                        help="couple this aero unit FMU (built for the same structure, e.g. by wingsim build SCENE "
                             "--set aero.model=strip --unit aero) instead of the scene's own; the structure FMU is "
                             "the scene's, built only if needed")
    export.add_argument("--standalone", action="store_true", help=STANDALONE_HELP)
    export.add_argument("--win64", action="store_true", help=WIN64_HELP)
    export.set_defaults(func=cmd_export)

    sweep = commands.add_parser("sweep", help="run every combination of --grid values, one row per run in sweep.csv",
                                description="Run the scene for every combination of the --grid values "
                                            "(after the --set overrides); write DIR/runs/<run>/ and DIR/sweep.csv. "
                                            "Rerunning the same command resumes: finished runs are skipped.")
    sweep.add_argument("scene", type=Path, metavar="SCENE", help=SCENE_HELP)
    sweep.add_argument("--grid", dest="grid", action="append", default=[], metavar="KEY=V1,V2,...",
                       help="a dotted scene key and its values, e.g. --grid flow.speed=0,10,20 (repeatable; "
                            "required)")
    sweep.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                       help="override a dotted scene key in every run (repeatable)")
    sweep.add_argument("--out", type=Path, metavar="DIR", help="output folder (default: results/<scene name>/sweep/)")
    sweep.add_argument("--backend", choices=("fmu", "direct"), default="direct",
                       help="direct: the slaves in-process in each worker (default for sweeps); fmu: build "
                            "each run's FMUs into DIR/fmus/<run>/ first, then run them through fmpy")
    sweep.add_argument("--jobs", type=int, default=None, metavar="N",
                       help="local worker processes (default: the number of CPUs)")
    sweep.add_argument("--scheduler", metavar="ADDRESS",
                       help="run on a Dask distributed cluster, e.g. tcp://127.0.0.1:8786, instead of locally")
    sweep.add_argument("--plots", action="store_true", help="write PNG plots into each run folder (off by default)")
    sweep.set_defaults(func=cmd_sweep)

    scenes = commands.add_parser("scenes", help="list the shipped scenes", description="List the scenes shipped "
                                 "with wingsim, each with the first line of its header; run one by name "
                                 "(wingsim run NAME) or copy it to edit (wingsim init).")
    scenes.set_defaults(func=cmd_scenes)

    init = commands.add_parser("init", help="copy a shipped scene into this folder to edit it",
                               description="Copy a scene (a shipped one by name, or a file) to ./NAME.toml with its "
                                           "name set to NAME; an existing file is never overwritten.")
    init.add_argument("name", metavar="NAME", help="name of the new scene (and of its file NAME.toml)")
    init.add_argument("--from", dest="source", default=INIT_SOURCE, metavar="SCENE",
                      help=f"the scene to copy (default: {INIT_SOURCE})")
    init.set_defaults(func=cmd_init)

    results = commands.add_parser("results", help="list the runs under results/ with their overrides and figures",
                                  description="List the run folders under results/ (of one scene, or all): "
                                              "status, key figures from summary.json, --set overrides from "
                                              "run.json.")
    results.add_argument("scene", nargs="?", metavar="SCENE", help="only this scene's runs (a name or a file)")
    results.set_defaults(func=cmd_results)

    clean = commands.add_parser("clean", help="remove built FMUs, results or exports",
                                description="Remove what wingsim wrote into fmus/, results/ or export/ of the "
                                            "current folder (of one scene, or all); folders a running wingsim "
                                            "process holds are kept. Nothing outside those folders is touched.")
    clean.add_argument("scene", nargs="?", metavar="SCENE", help="only this scene's folders (a name or a file)")
    clean.add_argument("--fmus", action="store_true", help="remove built FMUs (fmus/)")
    clean.add_argument("--results", action="store_true", help="remove results (results/)")
    clean.add_argument("--export", action="store_true", help="remove exported packages (export/)")
    clean.add_argument("--dry-run", action="store_true", help="list what would be removed, remove nothing")
    clean.set_defaults(func=cmd_clean)

    return parser


def _version() -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("wingsim")
    except PackageNotFoundError:   # run from a source tree that was never installed
        return "(not installed)"


def cmd_validate(args: argparse.Namespace) -> int:
    from orchestrator.export.validate import main as validate_main

    return validate_main(args.fmus)


def _start_compiling_kernels() -> None:
    """Begin the C kernels' one-time compilation (fmu_common.c_library) in the background, so that the compiler
    runs while Python imports and checks the rest (every FMU build needs them); nothing when they are compiled
    already or no compiler is found (the error comes where the kernels are used)."""
    import aero_fmu
    from fmu_common import c_library

    for source in Path(aero_fmu.__file__).parent.glob("*.c"):
        c_library.start_compiling(source)


def cmd_build(args: argparse.Namespace) -> int:
    _start_compiling_kernels()
    from orchestrator.build.fmus import build_fmus, build_lock, units_to_build
    from orchestrator.output.results import check_out_dir
    from orchestrator.scene.load import load_scene

    scene = load_scene(args.scene, args.overrides)
    _require_standalone(args.standalone, args.win64)
    units_to_build(scene, args.units)   # a unit the scene does not build: SceneError before anything is written
    out = check_out_dir(args.out or fmu_dir(scene, _file_scene(args, scene), args.standalone))
    with build_lock(out):   # a concurrent build of the same folder finishes first, this one waits
        built = build_fmus(scene, out, standalone=args.standalone, win64=args.win64, units=args.units)
    for path in built:
        if args.standalone:
            from orchestrator.build.standalone import describe

            print(describe(path))
        else:
            print(path)
    return 0


def _require_standalone(standalone: bool, win64: bool = False) -> None:
    """Refuse --standalone, before anything is written, where standalone FMUs cannot be built, and --win64 without
    --standalone or where its binaries cannot be built (the cross compiler missing, the downloads failing, which
    are fetched here the first time): exit 2 (orchestrator.build.fmus.refusal)."""
    from orchestrator.build.fmus import refusal

    refused = refusal(standalone, win64)
    if refused is not None:
        raise SceneError(refused[0], True, refused[1])


def _file_scene(args: argparse.Namespace, scene: dict) -> dict | None:
    """The scene as its file writes it (`scene` itself without ``--set``); None when the file alone is not a
    valid scene (a ``--set`` completes it)."""
    from orchestrator.scene.load import load_scene

    if not args.overrides:
        return scene
    try:
        return load_scene(args.scene)
    except SceneError:
        return None


def fmu_dir(scene: dict, file_scene: dict | None, standalone: bool = False) -> Path:
    """The folder `run` and `export` build a scene's FMUs into and run them from: ``fmus/<scene>/`` for the
    scene as its file writes it (`file_scene`, where `build` puts them; None: not a valid scene alone) and
    for every ``--set`` variant that changes tunable keys only (the master sets those as parameters of the
    same FMUs); for a variant that changes what the FMUs are built from, ``fmus/<scene>-<digest>/``, keyed
    by the first DIGEST_CHARS hex digits of its build digest (``orchestrator.build.fmus.build_digest``), so
    that concurrent runs of different variants never rebuild each other's FMUs; ``-standalone`` appended for
    standalone FMUs."""
    from orchestrator.build.fmus import build_digest

    name, digest = scene["name"], build_digest(scene)
    if file_scene is None or digest != build_digest(file_scene):
        name += f"-{digest[:DIGEST_CHARS]}"
    return FMU_ROOT / (f"{name}-standalone" if standalone else name)


def export_dir(scene: dict, overrides: list[str], aero: Path | None, standalone: bool) -> Path:
    """The folder `export` writes into by default: ``export/<scene>/`` for the scene as its file writes it with
    its own units, ``export/<scene>-<variant>/`` otherwise, the variant the first DIGEST_CHARS hex digits of the
    SHA-256 of the resolved scene and of the swapped aero FMU's bytes (so that two variants never share a folder,
    and exporting one variant again replaces its own files); ``-standalone`` appended for standalone FMUs."""
    import hashlib
    import json

    name = scene["name"]
    if overrides or aero is not None:
        digest = hashlib.sha256(json.dumps(scene, sort_keys=True).encode())
        if aero is not None:
            digest.update(aero.read_bytes())
        name += f"-{digest.hexdigest()[:DIGEST_CHARS]}"
    return EXPORT_ROOT / (f"{name}-standalone" if standalone else name)


def swapped_aero(path: Path | None, standalone: bool) -> Path | None:
    """The aero FMU given with ``export --aero``, checked before anything is built: a file that is an aero unit
    FMU built by wingsim, standalone when ``--standalone`` is given (the package would not run without Python
    otherwise). SceneError naming ``--aero`` (exit 2) if not; None without ``--aero``."""
    import json
    import zipfile

    from orchestrator.build.fmus import BUILD_INFO_RESOURCE, read_resource

    if path is None:
        return None
    try:
        info = json.loads(read_resource(path, BUILD_INFO_RESOURCE))
    except (OSError, KeyError, ValueError, zipfile.BadZipFile) as err:
        raise SceneError("--aero", str(path), f"an aero unit FMU built by wingsim ({type(err).__name__}: {err})") \
            from None
    if info.get("unit") != "aero":
        raise SceneError("--aero", str(path), f"an aero unit FMU: this is wingsim's {info.get('unit')} unit")
    if standalone and not info.get("standalone"):
        raise SceneError("--aero", str(path), "a standalone aero FMU with --standalone: build it with wingsim "
                                              "build SCENE --standalone --unit aero ...")
    return path


def _build_if_needed(scene: dict, fmu_dir: Path, standalone: bool = False, win64: bool = False,
                     units: list[str] | None = None):
    """None when the FMUs (every one the scene needs, or those of `units`) are ready, else a failed RunResult
    saying why the build failed.

    The FMUs are rebuilt when one is missing or was built from another scene (``--set`` included; but for
    its tunable keys) or other sources (``orchestrator.build.fmus.fmus_up_to_date`` compares digests embedded
    in the FMUs).
    """
    from orchestrator.build.fmus import build_fmus, build_lock, fmus_up_to_date
    from orchestrator.run.master import RunResult, new_series

    start = time.perf_counter()
    try:
        with build_lock(fmu_dir):   # a concurrent run of the same folder builds it, this one waits
            if fmus_up_to_date(scene, fmu_dir, standalone, win64, units):
                return None
            kind = "standalone FMUs" + (" with win64 binaries" if win64 else "") if standalone else "FMUs"
            print(f"building the {kind} of {scene['name']} into {fmu_dir} ...", file=sys.stderr)
            fmus = build_fmus(scene, fmu_dir, standalone=standalone, win64=win64, units=units)
    except SceneError:
        raise
    except Exception as err:
        logging.getLogger(__name__).debug("build failed", exc_info=True)
        message = f"building the FMUs into {fmu_dir} failed: {type(err).__name__}: {err}"
        return RunResult("error", message, time.perf_counter() - start, 0.0, scene, new_series(scene))
    print(f"built {', '.join(str(p) for p in fmus)}", file=sys.stderr)
    return None


def cmd_run(args: argparse.Namespace) -> int:
    _start_compiling_kernels()
    from orchestrator.files import folder_lock, process_record, remove_partials
    from orchestrator.output.results import check_out_dir
    from orchestrator.output.run_folders import run_folder
    from orchestrator.scene.load import load_scene

    scene = load_scene(args.scene, args.overrides)
    if args.standalone and args.backend != "fmu":
        raise SceneError("--standalone", True, "standalone FMUs run with --backend fmu only")
    _require_standalone(args.standalone)
    out = check_out_dir(args.out or run_folder(RESULTS_ROOT, scene["name"], args.overrides))
    _announce(scene)
    holder = process_record()
    with folder_lock(out, holder):   # another run writing there: refused (exit 2), naming it
        remove_partials(out)         # temporary files of a run killed while it wrote them
        return _run_into(args, scene, out, holder)


def _announce(scene: dict) -> None:
    """Notes before a run: values outside their plausible range (``orchestrator.scene.plausibility``) and a large
    timeseries.csv (``orchestrator.run.estimate``); the run goes ahead."""
    from orchestrator.run.estimate import output_note
    from orchestrator.scene.plausibility import plausibility_notes

    for note in [*plausibility_notes(scene), output_note(scene)]:
        if note:
            print(f"note: {note}", file=sys.stderr)


def _run_into(args: argparse.Namespace, scene: dict, out: Path, holder: dict) -> int:
    """`wingsim run` once `out` is held: run.json, the summary before the run, the run, the results and plots,
    run.json completed last."""
    from orchestrator.files import WriteError
    from orchestrator.output.plots import plot_workers, write_plots
    from orchestrator.output.results import deployment_time, latching_hinges, write_results, write_started
    from orchestrator.output.run_record import finish_record, start_record
    from orchestrator.run.master import RunResult, new_series, run_scene
    from orchestrator.run.progress import Progress

    start = time.perf_counter()
    try:   # from here on an interrupt still writes the results (run_scene handles its own)
        try:
            record = start_record(out, holder, args.overrides, scene_file=str(args.scene), backend=args.backend)
            write_started(scene, out)
        except WriteError as err:
            print(f"error: {err}; nothing was run", file=sys.stderr)
            return 1
        folder = fmu_dir(scene, _file_scene(args, scene), args.standalone)
        result = _build_if_needed(scene, folder, args.standalone) if args.backend == "fmu" else None
        if result is None:
            progress = Progress(scene["time"]["stop"], label=scene["name"], interrupted=lambda: bool(_received))
            result = run_scene(scene, backend=args.backend, fmu_dir=folder, progress=progress)
    except KeyboardInterrupt as err:
        result = RunResult("interrupted", f"interrupted ({err or 'SIGINT'}) before the first communication step",
                           time.perf_counter() - start, 0.0, scene, new_series(scene))
    result = _as_interrupted(result)
    try:
        written = write_results(result, out)   # summary.json first, then timeseries.csv
    except WriteError as err:
        print(f"{scene['name']}: {result.status}: {result.message}", file=sys.stderr)
        print(f"error: {err}", file=sys.stderr)
        return interrupt_exit_code() or 1
    plotted = True
    try:
        written += write_plots(result, out, plot_workers())
    except Exception as err:  # the data are written; a plotting problem must not hide them
        if _debug():
            raise
        print(f"warning: plots not written: {type(err).__name__}: {err}", file=sys.stderr)
        plotted = False
    requested, failure = _write_requested(args, result, out)   # asked for by name: a failure is an error
    written += requested
    if failure:
        print(f"{scene['name']}: {result.status}: {result.message}", file=sys.stderr)
        print(f"error: {failure}", file=sys.stderr)
        return interrupt_exit_code() or 1
    if plotted:
        try:
            finish_record(out, record, written)   # last: the folder is complete
        except WriteError as err:
            print(f"{scene['name']}: {result.status}: {result.message}", file=sys.stderr)
            print(f"error: {err}", file=sys.stderr)
            return interrupt_exit_code() or 1
    print(f"{scene['name']}: {result.status}: {result.message}")
    latching = latching_hinges(scene)
    if latching:   # the answer a deployment run is for
        deployed = deployment_time(result.latch_times, scene)
        waiting = ", ".join(h for h in latching if h not in result.latch_times)
        print(f"deployment time: {deployed:.6g} s" if deployed is not None else
              f"not deployed: {waiting} had not latched at t = {result.simulated_time_s:g} s")
    print(f"results in {out}")
    return interrupt_exit_code() or (0 if result.status == "ok" else 1)


def _as_interrupted(result):
    """`result` with status "interrupted" when a handled signal arrived during the run and ended it. An FMU
    receives the signal as an exception inside its Python code, which the FMI layer turns into fmi2Fatal: the
    failure is the interruption, not an error of the unit, and its message says so rather than repeat the FMU's."""
    import dataclasses

    if not _received or result.status in ("ok", "interrupted"):
        return result
    name = signal.Signals(_received[0]).name
    return dataclasses.replace(result, status="interrupted",
                               message=f"interrupted ({name}) after t = {result.simulated_time_s:g} s")


def _write_requested(args: argparse.Namespace, result, out: Path) -> tuple[list[Path], str]:
    """The outputs asked for with ``--animate`` and ``--vtk``: (paths written, "" or why one was not written)."""
    from orchestrator.output.animation import ANIMATION_FILE, ANIMATION_FRAMES, write_animation
    from orchestrator.output.geometry_history import shared_histories
    from orchestrator.output.vtk import VTK_FOLDER, VTK_FRAMES, write_vtk

    written: list[Path] = []
    history = shared_histories(result, [ANIMATION_FRAMES] * args.animate + [VTK_FRAMES] * args.vtk)
    asked = [(ANIMATION_FILE, lambda: [p for p in [write_animation(result, out, history=history(ANIMATION_FRAMES))]
                                       if p is not None])] if args.animate else []
    asked += [(f"{VTK_FOLDER}/", lambda: write_vtk(result, out, history=history(VTK_FRAMES)))] if args.vtk else []
    for what, write in asked:
        try:
            paths = write()
        except Exception as err:
            if _debug():
                raise
            return written, f"{what} not written: {type(err).__name__}: {err}"
        if not paths:
            return written, f"{what} not written: the run recorded no geometry"
        written += paths
    return written, ""


def cmd_export(args: argparse.Namespace) -> int:
    from orchestrator.export.container import CONTAINER_FILE, ContainerUnavailable, write_container
    from orchestrator.output.results import check_out_dir
    from orchestrator.scene.load import load_scene
    from orchestrator.export.ssp import write_ssp
    from orchestrator.export.system import coupled_system

    scene = load_scene(args.scene, args.overrides)
    _require_standalone(args.standalone, args.win64)
    aero = swapped_aero(args.aero, args.standalone)
    out = check_out_dir(args.out or export_dir(scene, args.overrides, aero, args.standalone))
    folder = fmu_dir(scene, _file_scene(args, scene), args.standalone)
    failed = _build_if_needed(scene, folder, args.standalone, args.win64, ["structure"] if aero else None)
    if failed is not None:
        print(f"error: {failed.message}", file=sys.stderr)
        return interrupt_exit_code() or 1
    system = coupled_system(scene, folder, aero=aero, variant=args.overrides)
    print(write_ssp(system, out / f"{scene['name']}.ssp"))
    try:
        print(write_container(system, out / CONTAINER_FILE))
    except ContainerUnavailable as missing:   # the package is written and usable; say why wing.fmu is not
        print(f"error: {out / CONTAINER_FILE} not written: {missing}", file=sys.stderr)
        return 1
    return 0


def cmd_sweep(args: argparse.Namespace) -> int:
    from orchestrator.output.results import check_out_dir
    from orchestrator.scene.plausibility import plausibility_notes
    from orchestrator.sweep import plan_sweep, run_sweep

    if args.scheduler:
        _require_extra("dask.distributed", "cluster", "--scheduler")
    if args.jobs is not None and args.jobs < 1:
        raise SceneError("--jobs", args.jobs, "a number of worker processes >= 1")
    if not args.grid:
        raise SceneError("--grid", None, "give at least one --grid KEY=V1,V2,..., e.g. --grid flow.speed=0,10,20")
    runs = plan_sweep(args.scene, args.grid, args.overrides)   # SceneError (exit 2) before anything runs
    out = check_out_dir(args.out or RESULTS_ROOT / runs[0].scene["name"] / "sweep")
    for note in dict.fromkeys(note for run in runs for note in plausibility_notes(run.scene)):
        print(f"note: {note}", file=sys.stderr)
    where = f"the Dask cluster at {args.scheduler}" if args.scheduler else "local processes"
    print(f"sweep: {len(runs)} runs of {args.scene} on {where}, results in {out}", file=sys.stderr)
    outcome = run_sweep(runs, out, backend=args.backend, jobs=args.jobs, scheduler=args.scheduler,
                        plots=args.plots)
    counts = ", ".join(f"{status} {n}" for status, n in sorted(outcome.statuses.items())) or "none run"
    print(f"sweep: {outcome.runs} runs, {outcome.ran} run now ({counts}), {outcome.skipped} already done")
    print(f"results in {outcome.table}")
    rows_ok = all(row["status"] == "ok" for row in _read_rows(outcome.table))
    return interrupt_exit_code() or (0 if rows_ok else 1)


def _require_extra(module: str, extra: str, option: str) -> None:
    """SceneError naming `option` (exit 2, before anything runs) when `module`, installed with the extra
    `extra`, is missing."""
    import importlib.util

    try:
        found = importlib.util.find_spec(module) is not None
    except ModuleNotFoundError:
        found = False
    if not found:
        raise SceneError(option, True, f"the optional dependency {module.split('.')[0]}: pip install "
                                       f"'wingsim[{extra}]'")


def cmd_scenes(args: argparse.Namespace) -> int:
    from orchestrator.scene.shipped import headline, shipped_scenes

    scenes = shipped_scenes()
    width = max(map(len, scenes), default=0)
    for name, path in scenes.items():
        print(f"{name:<{width}}  {headline(path)}")
    return 0


def cmd_init(args: argparse.Namespace) -> int:
    from orchestrator.scene.load import load_scene
    from orchestrator.scene.shipped import init_scene

    path = init_scene(args.name, args.source)
    load_scene(path)   # the copy is a valid scene under its new name
    print(f"{path} (from {args.source}): edit it, then wingsim run {path}")
    return 0


def cmd_results(args: argparse.Namespace) -> int:
    from orchestrator.output.run_folders import describe_runs, find_runs

    name = _scene_name(args.scene) if args.scene else None
    entries = find_runs(RESULTS_ROOT, name)
    if not entries:
        where = RESULTS_ROOT / name if name else RESULTS_ROOT
        print(f"no runs in {where}{os.sep} (wingsim run SCENE writes them)", file=sys.stderr)
        return 0
    for line in describe_runs(entries, RESULTS_ROOT):
        print(line)
    return 0


def _scene_name(scene: str) -> str:
    """The scene name of a SCENE argument: the ``name`` of the scene file (or shipped scene) it names, else the
    argument itself (the folder of a scene whose file is gone)."""
    from orchestrator.scene.load import read_scene_file
    from orchestrator.scene.shipped import locate

    path = locate(scene)
    if not path.is_file():
        return Path(scene).stem if str(scene).endswith(".toml") else str(scene)
    raw = read_scene_file(path)
    return raw.get("name") if isinstance(raw.get("name"), str) else path.stem


def cmd_clean(args: argparse.Namespace) -> int:
    from orchestrator.clean import clean

    roots = [root for root, chosen in ((FMU_ROOT, args.fmus), (RESULTS_ROOT, args.results),
                                       (EXPORT_ROOT, args.export)) if chosen]
    if not roots:
        raise SceneError("--fmus/--results/--export", "none given", "at least one, to choose what to remove")
    done = clean(roots, _scene_name(args.scene) if args.scene else None, dry_run=args.dry_run)
    verb = "would remove" if args.dry_run else "removed"
    for path in done.removed:
        print(f"{verb} {path}")
    for path in done.busy:
        print(f"kept {path}: a running wingsim process holds it", file=sys.stderr)
    if not done.removed and not done.busy:
        print(f"nothing to remove in {', '.join(str(r) for r in roots)}", file=sys.stderr)
    return 0


def _read_rows(path: Path) -> list[dict]:
    import csv

    with path.open(newline="") as handle:
        return list(csv.DictReader(handle))


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of ``wingsim``; returns the exit code."""
    argv = list(sys.argv[1:] if argv is None else argv)
    if _debug():
        logging.basicConfig(level=logging.DEBUG)
    args = build_parser().parse_args(argv)
    limit_blas_threads()
    allocator.tune()
    from orchestrator.files import WriteError

    _received.clear()
    previous = _handle_signals()
    try:
        return args.func(args)
    except SceneError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    except KeyboardInterrupt as err:
        print(f"error: interrupted ({err or 'SIGINT'})", file=sys.stderr)
        return interrupt_exit_code() or 128 + signal.SIGINT
    except WriteError as err:
        print(f"error: {err}", file=sys.stderr)
        return 1
    except Exception as err:
        if _debug():
            raise
        print(f"error: {type(err).__name__}: {err} (set {DEBUG_ENV}=1 to see the traceback)", file=sys.stderr)
        return 1
    finally:
        for signum, handler in previous.items():
            signal.signal(signum, handler)


def _handle_signals() -> dict:
    """Install ``_interrupt`` for SIGINT and SIGTERM (main thread only); returns the previous handlers."""
    import threading

    if threading.current_thread() is not threading.main_thread():
        return {}
    return {signum: signal.signal(signum, _interrupt) for signum in HANDLED_SIGNALS}
