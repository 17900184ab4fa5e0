"""``wingsim sweep``: run every combination of ``--grid KEY=V1,V2,...`` values (docs/sweep.md).

Each combination is one run of the scene with the ``--set`` overrides followed by the grid overrides
(``load_scene(path, [*sets, *grid])`` then ``run_scene``). Every combination is loaded and checked
before anything runs, so a bad key or value exits 2 and runs nothing. The runs go to local worker
processes (``jobs``, default ``os.cpu_count()``) or, with ``scheduler``, to a Dask distributed
cluster. Workers only compute: they return the RunResult and this process writes every file, so
Dask workers need no shared file system (except with ``backend="fmu"``, whose FMUs are built here
before any run starts and opened by the workers from ``OUT/fmus/<digest>/``: one pair of FMUs for all the
runs that differ only in tunable keys, such as ``flow.speed``, which the master sets as parameters).

Layout of the output folder ``OUT``:

- ``OUT/runs/<index>_<key=value_...>/``: ``summary.json``, ``timeseries.csv`` (as ``wingsim run``), PNG plots
  with ``plots=True``, and ``run.json`` (``orchestrator.output.run_record``: the sweep that wrote the folder, the
  run's overrides, and under ``sweep`` its index, grid values, backend and whether it has plots; completed last,
  with the digest of every file, once the folder is whole);
- ``OUT/sweep.csv``: one row per run, appended as runs finish (a killed sweep keeps the finished
  rows) and rewritten complete, in grid order, at the end;
- ``OUT/sweep.png``: the key figures of sweep.csv against each grid key (``orchestrator.output.sweep_plot``),
  written after sweep.csv is complete.

The sweep holds ``OUT`` (``orchestrator.files.folder_lock``): a second sweep or run into it is refused, naming
this one. Every file but the appended ``sweep.csv`` (rewritten whole at the end) is written to a temporary name
in its folder and renamed (``orchestrator.files``).

Before any run starts, each run folder gets its ``run.json`` (not complete) and a summary with status "running"
(``results.write_started``). A run folder that cannot be written, a run that fails, and a run whose
results cannot be written each get their row (status "error", the message naming the file or the
cause) and the sweep goes on with the others.

Resume: a run whose folder is complete (its ``run.json`` written last, every file it lists unchanged since),
for the same overrides, backend and resolved scene, with a ``summary.json`` of status ok, diverged or error,
and with its plots when ``plots=True`` asks for them, is not run again; any other is run again (a run killed
while its results or plots were written included).

Local workers die with the sweep's process: they ignore SIGINT (the sweep's process stops them), and on
Linux each asks the kernel for SIGKILL when its parent dies (``prctl(PR_SET_PDEATHSIG)``), also when the
sweep's process is itself killed by SIGKILL. multiprocessing's resource tracker then exits by itself: it
stops when the last process holding its pipe (the sweep's process and its workers) is gone.
"""

from __future__ import annotations

import csv
import itertools
import json
import math
import multiprocessing
import os
import re
import signal
import sys
import time
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Iterable, Sequence, TextIO

from fmu_common.errors import SceneError
from fmu_common.threads import limit_blas_threads
from orchestrator.run import allocator
from orchestrator.run.progress import duration
from orchestrator.scene.overrides import INDEX_PATTERN

DONE_STATUSES = ("ok", "diverged", "error")
FIXED_COLUMNS = ("index",)
RESULT_COLUMNS = ("status", "deployment_time_s", "wall_time_s", "message", "run_dir")
SKIPPED_FIGURES = {"status", "message", "wall_time_s", "stepping_wall_time_s", "deployment_time_s", "scene"}
SWEEP_CSV = "sweep.csv"
GRID_HELP = "KEY=V1,V2,... with a dotted scene key and at least one value, e.g. --grid flow.speed=0,10,20"
AXES = ("x", "y", "z")


# --- the grid ---------------------------------------------------------------------------------------

def split_values(raw: str) -> list[str]:
    """``0,5,[0,0,-9.8]`` -> ``['0', '5', '[0,0,-9.8]']``: commas inside brackets or quotes do not split."""
    values, depth, quote, current = [], 0, "", []
    for ch in raw:
        if quote:
            quote = "" if ch == quote else quote
        elif ch in "\"'":
            quote = ch
        elif ch in "[{":
            depth += 1
        elif ch in "]}":
            depth -= 1
        elif ch == "," and depth == 0:
            values.append("".join(current).strip())
            current = []
            continue
        current.append(ch)
    values.append("".join(current).strip())
    return values


def parse_grid(items: Sequence[str]) -> list[tuple[str, list[str]]]:
    """``--grid`` arguments -> [(dotted key, [raw value, ...]), ...] in the order given; SceneError if bad."""
    grid: list[tuple[str, list[str]]] = []
    for item in items:
        key, sep, raw = item.partition("=")
        key = INDEX_PATTERN.sub(r".\1", key.strip())
        if not sep or not key or not all(part.strip() for part in key.split(".")):
            raise SceneError("--grid", item, GRID_HELP)
        values = split_values(raw)
        if not raw.strip() or not all(values):
            raise SceneError(key, raw, f"--grid: empty value in {item!r}; {GRID_HELP}")
        if key in (k for k, _ in grid):
            raise SceneError(key, raw, "--grid given twice for this key; give all its values in one --grid")
        grid.append((key, values))
    if not grid:
        raise SceneError("--grid", "", GRID_HELP)
    return grid


def _folder_part(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9._=+-]+", "-", text).strip("-")


@dataclass
class Run:
    """One combination of the grid."""

    index: int
    values: dict[str, str]          # grid key -> raw value text, in grid order
    overrides: list[str]            # --set items, then the grid items
    name: str                       # the run folder's name
    scene: dict = field(default_factory=dict)   # resolved scene (filled by plan_sweep)


def combinations(grid: list[tuple[str, list[str]]], sets: Sequence[str] = ()) -> list[Run]:
    """Every combination (cartesian product, last key varying fastest) as a Run."""
    keys = [key for key, _ in grid]
    products = list(itertools.product(*(values for _, values in grid)))
    width = max(3, len(str(len(products) - 1)))
    runs = []
    for index, combo in enumerate(products):
        values = dict(zip(keys, combo))
        label = "_".join(f"{key}={value}" for key, value in values.items())
        name = f"{index:0{width}d}_{_folder_part(label)}"[:150]
        runs.append(Run(index, values, [*sets, *(f"{k}={v}" for k, v in values.items())], name))
    return runs


def plan_sweep(scene_path: Path, grid_items: Sequence[str], sets: Sequence[str] = ()) -> list[Run]:
    """The runs of a sweep, each with its resolved scene; SceneError (nothing run) for any bad input."""
    from orchestrator.scene.load import load_scene

    runs = combinations(parse_grid(grid_items), sets)
    for run in runs:
        run.scene = load_scene(scene_path, run.overrides)
    return runs


# --- one run (in a worker) --------------------------------------------------------------------------

def run_one(scene: dict, backend: str, fmu_dir: str | None) -> Any:
    """Run one resolved scene; the worker-side task (returns the RunResult; never writes files)."""
    limit_blas_threads()   # one BLAS thread per worker
    allocator.tune()
    from orchestrator.run.master import run_scene

    return run_scene(scene, backend=backend, fmu_dir=Path(fmu_dir) if fmu_dir else None, progress=None)


def _failed(scene: dict, message: str, wall: float = 0.0) -> Any:
    from orchestrator.run.master import RunResult, new_series

    return RunResult("error", message, wall, 0.0, scene, new_series(scene))


PR_SET_PDEATHSIG = 1   # linux/prctl.h


def die_with_parent(parent_pid: int) -> None:
    """Initializer of each local worker: on Linux, be sent SIGKILL by the kernel when the parent dies,
    however it dies; exit at once if the parent is already gone (it died before the request took
    effect); then ignore SIGINT (a Ctrl-C reaches the whole process group: the sweep's process stops its
    workers itself)."""
    if sys.platform.startswith("linux"):
        import ctypes

        libc = ctypes.CDLL(None, use_errno=True)
        if libc.prctl(PR_SET_PDEATHSIG, int(signal.SIGKILL), 0, 0, 0) != 0:
            errno = ctypes.get_errno()
            raise OSError(errno, f"prctl(PR_SET_PDEATHSIG) failed: {os.strerror(errno)}")
    if os.getppid() != parent_pid:
        os._exit(1)
    signal.signal(signal.SIGINT, signal.SIG_IGN)


# --- resume -----------------------------------------------------------------------------------------

def _sweep_fields(run: Run, backend: str, plots: bool) -> dict:
    """What a run folder's run.json says of the sweep's run (beside its writer and overrides)."""
    return {"index": run.index, "grid": run.values, "backend": backend, "plots": plots}


def finished_summary(run: Run, run_dir: Path, backend: str, plots: bool = False) -> dict | None:
    """The run folder's summary if the folder is complete (``run_record.complete_record``: run.json written
    last, every file it lists unchanged) and holds a finished run of the same overrides, backend and scene,
    with its plots when `plots` asks for them."""
    from orchestrator.output.results import SUMMARY_FILE, TIMESERIES_FILE, json_safe
    from orchestrator.output.run_record import complete_record

    record = complete_record(run_dir)
    if record is None or not {SUMMARY_FILE, TIMESERIES_FILE} <= set(record["files"]):
        return None
    try:
        summary = json.loads((run_dir / SUMMARY_FILE).read_text())
    except (OSError, ValueError):
        return None
    sweep = record.get("sweep") or {}
    same = (record.get("overrides") == run.overrides and sweep.get("backend") == backend
            and (sweep.get("plots") or not plots) and summary.get("status") in DONE_STATUSES
            and summary.get("scene") == json.loads(json.dumps(json_safe(run.scene))))
    return summary if same else None


# --- sweep.csv --------------------------------------------------------------------------------------

def _flatten(value: Any, prefix: str, out: dict[str, Any]) -> None:
    if isinstance(value, dict):
        for key, item in value.items():
            _flatten(item, f"{prefix}.{key}" if prefix else str(key), out)
    elif isinstance(value, list):
        if len(value) == 3 and all(isinstance(v, (int, float)) or v is None for v in value):
            for axis, item in zip(AXES, value):
                out[f"{prefix}_{axis}"] = item
        elif all(isinstance(v, (int, float, str, bool)) or v is None for v in value):
            for i, item in enumerate(value):
                out[f"{prefix}.{i}"] = item
    else:
        out[prefix] = value


def summary_figures(summary: dict) -> dict[str, Any]:
    """The scalar figures of a summary.json, flattened with dotted names (``probes.tip.max_displacement_z``),
    plus ``probes.<probe>.max_abs_displacement`` (m, largest |component| of min/max displacement)."""
    out: dict[str, Any] = {}
    for key, value in summary.items():
        if key not in SKIPPED_FIGURES:
            _flatten(value, key, out)
    for probe, figures in (summary.get("probes") or {}).items():
        parts = [abs(v) for k in ("min_displacement", "max_displacement") for v in (figures.get(k) or [])
                 if isinstance(v, (int, float))]
        if parts:
            out[f"probes.{probe}.max_abs_displacement"] = max(parts)
    return out


def time_left(elapsed: float, finished: int, remaining: int) -> str:
    """``"; about 3.5 min left"``: the remaining runs at the rate of those this sweep finished so far (wall s per
    run, parallel jobs included), or "" before the first or after the last.

    Args:
        elapsed: wall time (s) since this sweep started running.
        finished: runs it finished since (not those found done).
        remaining: runs still to run.
    """
    if finished <= 0 or remaining <= 0:
        return ""
    return f"; about {duration(elapsed / finished * remaining)} left"


def sweep_row(run: Run, summary: dict, run_dir: Path, out: Path) -> dict[str, Any]:
    row: dict[str, Any] = {"index": run.index, **run.values}
    row.update(status=summary.get("status"), deployment_time_s=summary.get("deployment_time_s"),
               wall_time_s=summary.get("wall_time_s"), message=summary.get("message", ""),
               run_dir=str(run_dir.relative_to(out)))
    row.update(summary_figures(summary))
    return row


def _columns(grid_keys: Iterable[str], rows: Iterable[dict]) -> list[str]:
    columns = [*FIXED_COLUMNS, *grid_keys, *RESULT_COLUMNS]
    seen = set(columns)
    for row in rows:
        for key in row:
            if key not in seen:
                seen.add(key)
                columns.append(key)
    return columns


def _cell(value: Any) -> Any:
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return ""
    return value


class SweepTable:
    """sweep.csv, appended row by row (header from the first row) and rewritten complete by ``close``."""

    def __init__(self, path: Path, grid_keys: list[str]):
        self.path, self.grid_keys = path, grid_keys
        self.rows: dict[int, dict] = {}
        self._file: TextIO | None = None
        self._writer: csv.DictWriter | None = None

    def add(self, row: dict) -> None:
        """Keep the row and append it to the file; WriteError naming the file if that fails."""
        from orchestrator.files import WriteError

        self.rows[row["index"]] = row
        try:
            if self._writer is None:
                self._file = self.path.open("w", newline="")
                self._writer = csv.DictWriter(self._file, _columns(self.grid_keys, [row]), extrasaction="ignore")
                self._writer.writeheader()
            self._writer.writerow({k: _cell(v) for k, v in row.items()})
            self._file.flush()
        except OSError as err:
            raise WriteError(self.path, err) from err

    def close(self) -> None:
        """Rewrite the file with every row so far, sorted by index, with the union of all columns;
        WriteError naming the file if that fails (the file appended so far stays)."""
        from orchestrator.files import write_file

        if self._file is not None:
            try:
                self._file.close()
            except OSError:
                pass   # the rewrite below writes every row again
            self._file = self._writer = None
        rows = [self.rows[i] for i in sorted(self.rows)]

        def write(tmp: Path) -> None:
            with tmp.open("w", newline="") as handle:
                writer = csv.DictWriter(handle, _columns(self.grid_keys, rows))
                writer.writeheader()
                for row in rows:
                    writer.writerow({k: _cell(v) for k, v in row.items()})

        write_file(self.path, write)


# --- the sweep --------------------------------------------------------------------------------------

@dataclass
class SweepOutcome:
    runs: int
    ran: int
    skipped: int
    statuses: dict[str, int]   # status -> runs, of the rows of the runs run now
    table: Path


def fmu_folder(out: Path, scene: dict) -> Path:
    """Where a run's FMUs are: ``OUT/fmus/<digest>/``, the first 12 hex digits of the scene's build digest
    (``orchestrator.build.fmus.build_digest``), one folder for all the runs that differ in tunable keys only
    (the master sets those as parameters)."""
    from orchestrator.build.fmus import build_digest

    return out / "fmus" / build_digest(scene)[:12]


def _build_fmus(todo: list[Run], out: Path, stream: TextIO) -> dict[int, Any]:
    """Build (if needed) the FMUs of every run into its ``fmu_folder`` before any run starts, once per
    folder; failed builds as RunResults by run index."""
    from orchestrator.build.fmus import build_fmus, build_lock, fmus_up_to_date

    failed, built = {}, {}   # built: folder -> None, or the failure message
    for run in todo:
        fmu_dir = fmu_folder(out, run.scene)
        if fmu_dir not in built:
            start = time.perf_counter()
            built[fmu_dir] = None
            try:
                with build_lock(fmu_dir):
                    if not fmus_up_to_date(run.scene, fmu_dir):
                        print(f"building the FMUs of {run.name} into {fmu_dir} ...", file=stream)
                        build_fmus(run.scene, fmu_dir)
            except SceneError:
                raise
            except Exception as err:
                built[fmu_dir] = (f"building the FMUs into {fmu_dir} failed: {type(err).__name__}: {err}",
                                  time.perf_counter() - start)
        if built[fmu_dir] is not None:
            failed[run.index] = _failed(run.scene, *built[fmu_dir])
    return failed


def run_sweep(runs: list[Run], out: Path, backend: str = "direct", jobs: int | None = None,
              scheduler: str | None = None, plots: bool = False, stream: TextIO | None = None) -> SweepOutcome:
    """Run (or resume) the planned runs; writes the run folders and OUT/sweep.csv (``out`` must be a
    folder that can be written: ``results.check_out_dir``). A run folder that cannot be written, a failed
    run or results that cannot be written give the run's row status "error" and the sweep goes on."""
    from orchestrator.files import folder_lock, process_record

    out = Path(out)
    holder = process_record()
    with folder_lock(out, holder, stream=stream):   # another sweep or run writing there: refused, naming it
        return _sweep_into(runs, out, holder, backend, jobs, scheduler, plots,
                           stream if stream is not None else sys.stderr)


def _sweep_into(runs: list[Run], out: Path, holder: dict, backend: str, jobs: int | None, scheduler: str | None,
                plots: bool, stream: TextIO) -> SweepOutcome:
    """`run_sweep` once `out` is held by this process (`holder`, its record)."""
    from orchestrator.files import WriteError, remove_partials
    from orchestrator.output.results import TIMESERIES_FILE, summarize, write_results, write_started
    from orchestrator.output.run_record import finish_record, start_record

    grid_keys = list(runs[0].values) if runs else []
    table = SweepTable(out / SWEEP_CSV, grid_keys)
    by_index = {run.index: run for run in runs}
    total, done = len(runs), 0
    todo = []
    for run in runs:
        run_dir = out / "runs" / run.name
        summary = finished_summary(run, run_dir, backend, plots)
        if summary is None:
            todo.append(run)
        else:
            table.add(sweep_row(run, summary, run_dir, out))
            done += 1
    skipped = done
    if skipped:
        print(f"sweep: {skipped}/{total} runs already done in {out / 'runs'}, running the other {len(todo)}",
              file=stream)
    statuses: dict[str, int] = {}
    records: dict[int, dict] = {}   # run.json of each run folder prepared, by run index
    started = time.perf_counter()

    def record(run: Run, result: Any, status: str, message: str) -> None:
        nonlocal done
        run_dir = out / "runs" / run.name
        summary = {**summarize(result), "status": status, "message": message}
        table.add(sweep_row(run, summary, run_dir, out))
        done += 1
        statuses[status] = statuses.get(status, 0) + 1
        print(f"sweep: {done}/{total} runs done: {run.name}: {status} "
              f"({result.wall_time_s:.2f} s){': ' + message if message else ''}"
              f"{time_left(time.perf_counter() - started, done - skipped, total - done)}", file=stream)
        stream.flush()

    def finish(run: Run, result: Any) -> None:
        run_dir = out / "runs" / run.name
        status, message = result.status, result.message
        try:
            written = write_results(result, run_dir)   # summary.json, then timeseries.csv
        except WriteError as err:
            status, message = "error", f"{err} (the run itself: {result.status}: {result.message})"
        else:
            try:
                if plots:
                    from orchestrator.output.plots import write_plots

                    written += write_plots(result, run_dir)
                if run.index in records:
                    finish_record(run_dir, records[run.index], written)   # last: the folder is complete
            except Exception as err:   # the folder stays incomplete: a resume runs it again
                print(f"warning: {run.name}: {'plots' if plots else 'run.json'} not written: "
                      f"{type(err).__name__}: {err}", file=stream)
        record(run, result, status, message)

    def prepare(run: Run) -> bool:
        """Write the run folder's record and "running" summary; a row with the cause if that fails."""
        run_dir = out / "runs" / run.name
        path = run_dir
        try:
            run_dir.mkdir(parents=True, exist_ok=True)
            remove_partials(run_dir)       # temporary files of a sweep killed while it wrote them
            path = run_dir / TIMESERIES_FILE
            path.unlink(missing_ok=True)   # a stale one is never taken as this run's
            records[run.index] = start_record(run_dir, holder, run.overrides,
                                              sweep=_sweep_fields(run, backend, plots))
            write_started(run.scene, run_dir)
        except WriteError as err:
            record(run, _failed(run.scene, ""), "error", f"{err}; not run")
            return False
        except OSError as err:
            record(run, _failed(run.scene, ""), "error", f"cannot write {path}: {err.strerror or err}; not run")
            return False
        return True

    try:
        todo = [run for run in todo if prepare(run)]
        fmu_dirs: dict[int, str | None] = {run.index: None for run in todo}
        if backend == "fmu" and todo:
            for index, result in _build_fmus(todo, out, stream).items():
                todo.remove(by_index[index])
                finish(by_index[index], result)
            fmu_dirs = {run.index: str(fmu_folder(out, run.scene).resolve()) for run in todo}
        if todo and scheduler:
            _run_dask(todo, backend, fmu_dirs, scheduler, finish)
        elif todo:
            _run_local(todo, backend, fmu_dirs, jobs, finish)
    except KeyboardInterrupt as err:
        print(f"sweep: interrupted ({err or 'SIGINT'}) after {done}/{total} runs; sweep.csv holds the finished "
              "ones, rerun the same command to resume", file=stream)
        raise
    finally:
        table.close()
    _write_sweep_plot(runs, out, grid_keys, stream)
    return SweepOutcome(total, total - skipped, skipped, statuses, out / SWEEP_CSV)


def _write_sweep_plot(runs: list[Run], out: Path, grid_keys: list[str], stream: TextIO) -> None:
    """``sweep.png`` from the whole sweep.csv (``orchestrator.output.sweep_plot``); a failure only warns: the
    table is written."""
    from orchestrator.output.sweep_plot import SWEEP_PLOT, write_sweep_plot

    name = runs[0].scene.get("name", "sweep") if runs else "sweep"
    try:
        write_sweep_plot(out / SWEEP_CSV, grid_keys, f"{name}: key figures of the sweep over {', '.join(grid_keys)}")
    except Exception as err:
        (out / SWEEP_PLOT).unlink(missing_ok=True)   # no stale picture of an earlier sweep
        print(f"warning: {SWEEP_PLOT} not written: {type(err).__name__}: {err}", file=stream)


def _run_local(todo: list[Run], backend: str, fmu_dirs: dict, jobs: int | None, finish) -> None:
    workers = max(1, min(jobs or os.cpu_count() or 1, len(todo)))
    others = set(multiprocessing.active_children())   # children that are not this pool's workers
    # spawn: each worker imports numpy afresh (no fork of a process with threads)
    with ProcessPoolExecutor(max_workers=workers, mp_context=multiprocessing.get_context("spawn"),
                             initializer=die_with_parent, initargs=(os.getpid(),)) as pool:
        futures = {pool.submit(run_one, run.scene, backend, fmu_dirs[run.index]): run for run in todo}
        try:
            for future in as_completed(futures):
                run = futures[future]
                try:
                    result = future.result()
                except Exception as err:   # a worker that died or raised: the run failed, the sweep goes on
                    result = _failed(run.scene, f"worker failed: {type(err).__name__}: {err}")
                finish(run, result)
        except BaseException:
            # stop the workers now: shutdown alone would wait for the runs they are in
            for worker in set(multiprocessing.active_children()) - others:
                worker.kill()
            pool.shutdown(wait=False, cancel_futures=True)
            raise


def _run_dask(todo: list[Run], backend: str, fmu_dirs: dict, address: str, finish) -> None:
    from dask.distributed import Client, as_completed as dask_completed

    with Client(address, timeout="30s") as client:
        futures = {}
        for run in todo:
            future = client.submit(run_one, run.scene, backend, fmu_dirs[run.index], pure=False,
                                   key=f"wingsim-sweep-{run.name}-{time.time_ns()}")
            futures[future.key] = (future, run)
        try:
            for future in dask_completed([f for f, _ in futures.values()]):
                run = futures[future.key][1]
                try:
                    result = future.result()
                except Exception as err:
                    result = _failed(run.scene, f"dask task failed: {type(err).__name__}: {err}")
                finish(run, result)
        except BaseException:
            client.cancel([f for f, _ in futures.values()])
            raise
