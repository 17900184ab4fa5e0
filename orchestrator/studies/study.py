"""Studies: many independent tasks (runs of scenes, searches over a step) in worker processes, recorded
as they finish so that a study can be resumed and its report rendered again without running anything.

A task is a hashable, picklable value (a frozen dataclass) whose ``repr`` names it; ``work(task)`` runs
in a worker and returns a JSON-able dict. ``Study.run`` appends one JSON line per finished task,
``{"task": repr(task), "result": {...}, "wall_s": s, "finished": Unix time}``, to the study's file (e.g.
results/studies/stability.jsonl), and returns every result as read back from JSON, so a fresh result and
a resumed one are the same values.
A task that raises becomes ``{"error": "<type>: <message>"}``: reported, never dropped.

``wingsim sweep`` (``orchestrator.sweep``) is the command-line tool for a grid of ``--set`` values; a
study is for what a grid cannot express: one factor at a time, bracketing searches, a run observed by a
hook.
"""

from __future__ import annotations

import json
import multiprocessing
import sys
import time
from collections.abc import Callable, Hashable, Iterable
from concurrent.futures import ProcessPoolExecutor, as_completed
from pathlib import Path
from typing import Any, TextIO


def _worker_start(initializer: Callable[[], None] | None) -> None:
    from fmu_common.threads import limit_blas_threads

    limit_blas_threads()                 # workers share the cores: one BLAS thread each
    from orchestrator.run import allocator
    allocator.tune()
    if initializer is not None:
        initializer()


def _work(work: Callable[[Any], dict], task: Any) -> tuple[str, float]:
    """(the result as JSON text, wall time s) of work(task); an exception becomes {"error": ...}."""
    start = time.perf_counter()
    try:
        result = work(task)
    except Exception as err:                      # noqa: BLE001 - recorded in the result, never dropped
        result = {"error": f"{type(err).__name__}: {err}"}
    return json.dumps(result, default=_plain), time.perf_counter() - start


def _plain(value: Any) -> Any:
    """numpy arrays and scalars as lists and Python numbers, for JSON."""
    if hasattr(value, "tolist"):
        return value.tolist()
    raise TypeError(f"{type(value).__name__} is not JSON serializable")


class Study:
    """The record of a study: ``path`` (a JSON-lines file) and the results read from it so far.

    ``resume=False`` starts afresh (the file is emptied); ``resume=True`` keeps the finished tasks, which
    ``run`` then does not run again."""

    def __init__(self, path: Path, resume: bool = False, stream: TextIO | None = None):
        self.path, self.stream = Path(path), stream if stream is not None else sys.stderr
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self.results: dict[str, dict] = {}
        self._spans: list[tuple[float, float]] = []    # (start, end) of each recorded task, Unix time, s
        if resume and self.path.exists():
            for line in self.path.read_text().splitlines():
                if line.strip():
                    record = json.loads(line)
                    self.results[record["task"]] = record["result"]
                    if "finished" in record:
                        self._spans.append((record["finished"] - record["wall_s"], record["finished"]))
        else:
            self.path.write_text("")

    def run(self, tasks: Iterable[Hashable], work: Callable[[Any], dict], jobs: int = 2,
            cost: Callable[[Any], float] | None = None, describe: Callable[[Any, dict], str] | None = None,
            initializer: Callable[[], None] | None = None) -> dict:
        """{task: result} of ``tasks``: the recorded ones read back, the others run by ``work`` in ``jobs``
        worker processes (spawned, one BLAS thread each, ``initializer()`` first), the most costly first
        (``cost(task)``, any unit), with one progress line per finished task (``describe(task, result)``)."""
        tasks = list(dict.fromkeys(tasks))
        todo = [t for t in tasks if repr(t) not in self.results]
        if cost is not None:
            todo.sort(key=cost, reverse=True)
        if todo:
            self._run(todo, work, jobs, describe, initializer)
        return {task: self.results[repr(task)] for task in tasks}

    @property
    def wall_time(self) -> float | None:
        """Wall time (s) from the start of the first recorded task to the end of the last, also when the
        record was resumed; None for a record without times."""
        if not self._spans:
            return None
        return max(end for _, end in self._spans) - min(start for start, _ in self._spans)

    def _run(self, todo, work, jobs, describe, initializer) -> None:
        start = time.perf_counter()
        context = multiprocessing.get_context("spawn")
        with ProcessPoolExecutor(max_workers=max(1, min(jobs, len(todo))), mp_context=context,
                                 initializer=_worker_start, initargs=(initializer,)) as pool, \
                self.path.open("a") as record:
            futures = {pool.submit(_work, work, task): task for task in todo}
            for k, future in enumerate(as_completed(futures), 1):
                task = futures[future]
                text, wall = future.result()
                finished = time.time()
                self._spans.append((finished - wall, finished))
                result = self.results[repr(task)] = json.loads(text)
                record.write(json.dumps({"task": repr(task), "result": result, "wall_s": wall,
                                         "finished": finished}) + "\n")
                record.flush()
                outcome = result["error"] if "error" in result else describe(task, result) if describe else "done"
                print(f"[{k}/{len(todo)} {time.perf_counter() - start:7.1f} s] {getattr(task, 'label', task)}: "
                      f"{outcome} ({wall:.1f} s)", file=self.stream, flush=True)
