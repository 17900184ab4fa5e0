"""Run a scene, or sweep it over a grid of values, from a script or a notebook: what ``wingsim run`` and
``wingsim sweep`` do, with the results returned as ``wingsim.Result`` objects.

``run`` loads the scene, builds its FMUs when ``backend="fmu"`` needs them (into ``fmus/<scene>/`` of the working
folder, as ``wingsim run`` does), runs it (``orchestrator.run.master.run_scene``), writes its outputs
(``summary.json``, ``timeseries.csv``; with ``out`` the plots, animation and VTK files asked for, and ``run.json``
last, as ``wingsim run`` does) and reads them back. Without ``out`` the outputs go to a temporary folder that is
removed once they are read.
"""

from __future__ import annotations

import csv
import shutil
import sys
import tempfile
from contextlib import contextmanager
from pathlib import Path
from typing import Any, Iterator, Mapping, Sequence

import numpy as np

from fmu_common.errors import SceneError
from wingsim.result import Result
from wingsim.scene import Scene, load_scene, override_text

BACKENDS = ("direct", "fmu")
"""direct: the units' slaves in this process; fmu: the built FMUs through fmpy."""


def _check_backend(backend: str) -> None:
    if backend not in BACKENDS:
        raise SceneError("backend", backend, " or ".join(BACKENDS))


@contextmanager
def _output_folder(out: str | Path | None, option: str, wanted: Sequence[str] = (), hold: bool = True
                   ) -> Iterator[Path]:
    """``out`` checked and, with ``hold``, held (``orchestrator.files.folder_lock``; a sweep holds its folder
    itself), or a temporary folder removed afterwards; SceneError naming the first of ``wanted`` (outputs asked
    for) without ``out``, where they would be lost."""
    from orchestrator.files import folder_lock, process_record
    from orchestrator.output.results import check_out_dir

    if out is None:
        if wanted:
            raise SceneError(wanted[0], True, "an output folder to write it into: give out=FOLDER")
        folder = Path(tempfile.mkdtemp(prefix="wingsim-"))
        try:
            yield folder
        finally:
            shutil.rmtree(folder, ignore_errors=True)
        return
    folder = check_out_dir(Path(out), option)
    if not hold:
        yield folder
        return
    with folder_lock(folder, process_record()):
        yield folder


def _fmu_folder(scene: Scene) -> tuple[Path, Any]:
    """Build the scene's FMUs when they are missing or stale, as ``wingsim run`` does: (their folder, None), or
    (the folder, a failed RunResult saying why) when the build fails."""
    from orchestrator.cli import _build_if_needed, fmu_dir

    file_scene = scene.resolved
    if scene.overrides:
        try:
            file_scene = load_scene(scene.path).resolved
        except SceneError:
            file_scene = None     # the file alone is not a scene: the overrides complete it
    folder = fmu_dir(scene.resolved, file_scene)
    return folder, _build_if_needed(scene.resolved, folder)


def run(scene: Scene | str | Path, overrides: Mapping[str, Any] | None = None, backend: str = "direct",
        out: str | Path | None = None, plots: bool = False, animate: bool = False, vtk: bool = False) -> Result:
    """Run a scene and return its Result; a failed run (diverged, error, or FMUs that could not be built) returns its
    Result too, with its status and message.

    Args:
        scene: a Scene, a scene file or the name of a shipped scene.
        overrides: {dotted key: value} applied after the scene's own (``--set``), e.g. ``{"flow.speed": 10}``.
        backend: "direct" (the units in this process, no build) or "fmu" (the FMUs, built when needed into
            ``fmus/<scene>/`` of the working folder, through fmpy).
        out: the folder to write the outputs into (as ``wingsim run --out``); None: a temporary folder,
            removed once the Result is read.
        plots: write the PNG plots into ``out``.
        animate: write the deployment's animation (``animation.gif``) into ``out``.
        vtk: write the geometry history for ParaView (``vtk/``) into ``out``.

    Returns:
        The Result, read back from the files written. SceneError naming the key (nothing run) for a bad scene,
        override, backend, or an output asked for without ``out``.
    """
    from orchestrator.files import process_record
    from orchestrator.output.results import write_results
    from orchestrator.output.run_record import finish_record, start_record
    from orchestrator.run.master import run_scene

    _check_backend(backend)
    scene = load_scene(scene, overrides)
    wanted = [name for name, asked in (("plots", plots), ("animate", animate), ("vtk", vtk)) if asked]
    with _output_folder(out, "out", wanted) as folder:
        record = start_record(folder, process_record(), scene.overrides, scene_file=str(scene.path), backend=backend)
        fmu_folder, result = _fmu_folder(scene) if backend == "fmu" else (None, None)
        if result is None:        # else the build failed: its Result says why, as wingsim run writes it
            result = run_scene(scene.resolved, backend=backend, fmu_dir=fmu_folder)
        written = write_results(result, folder)
        if plots:
            from orchestrator.output.plots import write_plots

            written += write_plots(result, folder)
        if animate or vtk:       # one replay of the aero unit for both
            from orchestrator.output.animation import ANIMATION_FRAMES, write_animation
            from orchestrator.output.geometry_history import shared_histories
            from orchestrator.output.vtk import VTK_FRAMES, write_vtk

            history = shared_histories(result, [ANIMATION_FRAMES] * bool(animate) + [VTK_FRAMES] * bool(vtk))
            if animate:
                written += [p for p in [write_animation(result, folder, history=history(ANIMATION_FRAMES))]
                            if p is not None]
            if vtk:
                written += write_vtk(result, folder, history=history(VTK_FRAMES))
        finish_record(folder, record, written)    # last: the folder is complete, as wingsim run leaves it
        return Result.load(folder, keep_folder=out is not None)


class SweepResult:
    """A sweep: one row of key figures per run (sweep.csv) and each run's Result, in grid order.

    Attributes:
        grid: {dotted key: [values]} as given.
        rows: sweep.csv's rows, dicts with numbers as float and empty cells as None.
        results: each run's Result (None for a run whose outputs were not written).
        folder: the sweep's folder, or None when it was a temporary folder since removed.

    Args:
        grid: {dotted key: [values]}.
        rows: sweep.csv's rows.
        results: each run's Result.
        folder: the sweep's folder, or None.
    """

    def __init__(self, grid: dict, rows: list[dict], results: list[Result | None], folder: Path | None):
        self.grid, self.rows, self.results, self.folder = grid, rows, results, folder

    def column(self, name: str) -> np.ndarray:
        """A column of sweep.csv as floats (NaN for an empty cell), shape (runs,).

        Args:
            name: the column, e.g. ``"deployment_time_s"`` or a grid key ``"flow.speed"``.
        """
        if not self.rows or name not in self.rows[0]:
            columns = ", ".join(self.rows[0]) if self.rows else "none"
            raise KeyError(f"no column {name!r} in the sweep; its columns are {columns}")
        return np.array([np.nan if row[name] is None else float(row[name]) for row in self.rows])

    def to_pandas(self):
        """sweep.csv as a pandas DataFrame; ImportError saying how to install pandas when it is missing."""
        try:
            import pandas
        except ImportError:
            raise ImportError("SweepResult.to_pandas needs pandas, which wingsim does not install: pip install "
                              "pandas; sweep.rows and sweep.column(name) hold the same figures") from None
        return pandas.DataFrame(self.rows)

    def __repr__(self) -> str:
        statuses = [row.get("status") for row in self.rows]
        return f"<SweepResult of {len(self.rows)} runs over {', '.join(self.grid)}: {statuses.count('ok')} ok>"


def _cell(text: str) -> Any:
    if text == "":
        return None
    try:
        return float(text)
    except ValueError:
        return text


def sweep(scene: Scene | str | Path, grid: Mapping[str, Sequence[Any]], overrides: Mapping[str, Any] | None = None,
          backend: str = "direct", jobs: int | None = None, out: str | Path | None = None,
          plots: bool = False) -> SweepResult:
    """Run the scene for every combination of the grid's values (``wingsim sweep``), in worker processes.

    Args:
        scene: a Scene, a scene file or the name of a shipped scene.
        grid: {dotted key: [values]}, e.g. ``{"flow.speed": [0, 10, 20]}``; the last key varies fastest.
        overrides: {dotted key: value} applied to every run before the grid's values.
        backend: "direct" or "fmu" (as ``run``).
        jobs: worker processes (default: the number of CPUs).
        out: the sweep's folder (sweep.csv, sweep.png, runs/); None: a temporary folder, removed once read.
        plots: write each run's PNG plots (needs ``out``).

    Returns:
        The SweepResult. SceneError naming the key (nothing run) for a bad scene, grid value or override.
    """
    from orchestrator.sweep import SWEEP_CSV, plan_sweep, run_sweep

    _check_backend(backend)
    if jobs is not None and jobs < 1:
        raise SceneError("jobs", jobs, "a number of worker processes >= 1")
    scene = load_scene(scene, overrides)
    if not grid:
        raise SceneError("grid", grid, "at least one key with its values, e.g. {'flow.speed': [0, 10, 20]}")
    items = [f"{key}=" + ",".join(override_text(key, v).partition("=")[2] for v in values)
             for key, values in grid.items()]
    runs = plan_sweep(scene.path, items, scene.overrides)      # every combination checked before any runs
    with _output_folder(out, "out", ["plots"] if plots else [], hold=False) as folder:   # run_sweep holds it
        run_sweep(runs, folder, backend=backend, jobs=jobs, plots=plots, stream=sys.stderr)
        with (folder / SWEEP_CSV).open(newline="") as handle:
            rows = [{k: _cell(v) for k, v in row.items()} for row in csv.DictReader(handle)]
        results = []
        for row in rows:
            run_dir = folder / str(row["run_dir"])
            try:
                results.append(Result.load(run_dir, keep_folder=out is not None))
            except (OSError, ValueError):
                results.append(None)
        return SweepResult({k: list(v) for k, v in grid.items()}, rows, results,
                           folder if out is not None else None)
