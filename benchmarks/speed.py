"""Speed of the coupled deployment runs through both kinds of FMU and in-process: the table of docs/performance.md.

    python benchmarks/speed.py [--scenes deploy_rigid deploy_flexible] [--stop 0.3] [--repeat N] [--set KEY=VALUE ...]

Per scene as shipped: build the ordinary and the standalone FMUs (not timed), ten untimed warm-up steps through
each kind of run, then:
- the run through the ordinary FMUs (`backend="fmu"`, what `wingsim run SCENE` runs) and in-process
  (`backend="direct"`), one BLAS thread, taking turns one communication step each on one CPU (`Lockstep`), so
  that a slow phase of a shared machine falls on both alike;
- the run through the standalone FMUs (`wingsim run SCENE --standalone`: the units in a worker process beside
  the host) and in-process, taking turns of ten steps on every CPU the process may use, as a user runs them:
  the worker and its host each need a CPU, and a worker that waits for its host spins on its own for a while
  (orchestrator/build/worker_channel.h), which a single CPU would take from the other run.
Stepping: the communication steps after the first (whose turn also loads the units). Real-time factor:
stepping wall time through the ordinary FMUs / simulated time (TARGET); overhead, for each kind of FMU: wall
time / its in-process run's - 1, of the stepping (FMU_OVERHEAD_TARGET, STANDALONE_OVERHEAD_TARGET) and of the
whole run. --repeat N runs each scene N times and adds per scene the ranges over the runs, the runs within
the targets, the real-time factor of the fastest turn of each step summed over the steps (a floor that drops
the machine's slow phases) and the standalone overhead of those floors, and the median of each figure
(docs/performance.md's table, from --repeat 5). CPU time: the CPU time of the thread of each run over its
stepping (the ordinary FMUs and in-process, whose every call runs in that thread), which other tenants of a
busy machine do not inflate as they do the wall time: the real-time factor and the FMU overhead in CPU time.
--set overrides scene keys as `wingsim run --set` does (e.g. `record.probes=position record.monitors=constraints`,
to read fewer outputs: the units compute only those read).
"""
import argparse
import os
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np
from report import ROOT, process_setup, table

from orchestrator.build.fmus import build_fmus
from orchestrator.run.master import run_scene
from orchestrator.scene.load import load_scene

TARGET = {"deploy_rigid": 0.1, "deploy_flexible": 1.0}   # real-time factor through the FMUs (docs/performance.md)
FMU_OVERHEAD_TARGET = 0.10
STANDALONE_OVERHEAD_TARGET = {"deploy_rigid": 0.10, "deploy_flexible": 0.03}
# A standalone run's turn: ten steps, so that the worker's wake-up after the other run's turn (a worker sleeps
# after 2 ms without a call) falls on one step in ten, as a longer pause of the host would in a user's run.
STANDALONE_STEPS_PER_TURN = 10


class Lockstep:
    """Runs of one scene, one per backend ("fmu" and "standalone" through the FMUs in `fmu_dirs[backend]`,
    "direct" in-process), each in its own thread, taking turns (`run_scene`'s progress hook hands the turn over):
    the first step, which loads the units, then `steps_per_turn` communication steps at a time; only the thread
    holding the turn works, the others wait on a condition. With `one_cpu` every thread runs on one CPU (where
    the platform lets a process choose: Linux). Per backend: `turns`, the wall time (s) of each step (the first
    from the run's start, loading the units included); `cpu`, the CPU time (s) of its thread over the steps
    after the first; `tail`, from the last step to the end of `run_scene` (terminating the units); `result`,
    the RunResult."""

    def __init__(self, scene, fmu_dirs, backends, one_cpu, steps_per_turn=1):
        self.scene, self.fmu_dirs, self.backends, self.one_cpu = scene, fmu_dirs, backends, one_cpu
        self.steps_per_turn = steps_per_turn
        self.turn, self.done, self.condition = backends[0], set(), threading.Condition()
        self.turns, self.tail, self.result = {b: [] for b in backends}, {}, {}
        self.cpu = {b: 0.0 for b in backends}

    def run(self):
        """Every run to its end."""
        allowed = os.sched_getaffinity(0) if self.one_cpu and hasattr(os, "sched_setaffinity") else None
        if allowed:
            os.sched_setaffinity(0, {max(allowed)})     # the threads started below inherit the mask
        try:
            threads = [threading.Thread(target=self._run, args=(b,), daemon=True) for b in self.backends]
            for thread in threads:
                thread.start()
            for thread in threads:
                thread.join()
        finally:
            if allowed:
                os.sched_setaffinity(0, allowed)
        return self

    def _run(self, backend):
        with self.condition:
            self.condition.wait_for(lambda: self.turn == backend)
        clock = Turns(self, backend)
        try:
            self.result[backend] = run_scene(self.scene, backend="direct" if backend == "direct" else "fmu",
                                             progress=clock, fmu_dir=self.fmu_dirs.get(backend))
            self.tail[backend] = time.perf_counter() - clock.resumed
        finally:                                # also if the run raised: the other run must not wait for it
            with self.condition:
                self.done.add(backend)
                self.turn = next((b for b in self.backends if b not in self.done), None)
                self.condition.notify_all()

    def hand_over(self, backend):
        """After a step of `backend`: give the turn to the next unfinished run and wait for it to come back."""
        with self.condition:
            others = [b for b in self.backends if b != backend and b not in self.done]
            if others:
                self.turn = others[0]
                self.condition.notify_all()
                self.condition.wait_for(lambda: self.turn == backend)


class Turns:
    """`run_scene`'s progress hook for one run of a `Lockstep`: times the run's turns and hands over."""

    def __init__(self, lockstep, backend):
        self.lockstep, self.backend, self.resumed = lockstep, backend, time.perf_counter()
        self.resumed_cpu = time.thread_time()

    def update(self, t):
        turns = self.lockstep.turns[self.backend]
        turns.append(time.perf_counter() - self.resumed)
        if len(turns) > 1:                                               # the first turn loads the units
            self.lockstep.cpu[self.backend] += time.thread_time() - self.resumed_cpu
        if (len(turns) - 1) % self.lockstep.steps_per_turn == 0:
            self.lockstep.hand_over(self.backend)
        self.resumed, self.resumed_cpu = time.perf_counter(), time.thread_time()

    def finish(self, t, status):
        pass


def warm_up(scene, fmu_dirs):
    """Ten communication steps of every kind of run, not timed: the first steps of a process pay one-off
    costs (lazy imports, first calls into LAPACK and the FMU libraries) that are not the per-step cost."""
    short = {**scene, "time": {**scene["time"], "stop": 10 * scene["coupling"]["step"]}}
    for backend in ("fmu", "standalone", "direct"):
        result = run_scene(short, backend="direct" if backend == "direct" else "fmu", fmu_dir=fmu_dirs.get(backend))
        if result.status != "ok":
            raise RuntimeError(f"{scene['name']} ({backend}, warm-up): {result.status}: {result.message}")


def timed(scene, fmu_dirs, backends, one_cpu, steps_per_turn=1):
    """{backend: (stepping s, whole run s, turns, stepping CPU s)} of one `Lockstep` run of each backend
    (stepping: the steps after the first; turns: their times, s, one per step); raises unless every run ends
    ok."""
    lockstep = Lockstep(scene, fmu_dirs, backends, one_cpu, steps_per_turn).run()
    out = {}
    for backend in backends:
        result = lockstep.result.get(backend)
        if result is None:
            raise RuntimeError(f"{scene['name']} ({backend}): the run raised (its traceback is printed above)")
        if result.status != "ok":
            raise RuntimeError(f"{scene['name']} ({backend}): {result.status}: {result.message}")
        turns = lockstep.turns[backend]
        out[backend] = (sum(turns[1:]), sum(turns) + lockstep.tail[backend], turns[1:], lockstep.cpu[backend])
    return out


def figures(row):
    """(simulated s, stepping s through the ordinary FMUs, real-time factor, stepping s direct, overhead of the
    stepping and of the whole run through the ordinary FMUs, the same two through the standalone FMUs, real-time
    factor and overhead of the stepping through the ordinary FMUs in CPU time) of a result row (scene, simulated,
    stepping and whole run through the ordinary FMUs and direct in lockstep, stepping and whole run through the
    standalone FMUs and direct in lockstep, CPU time of the stepping through the ordinary FMUs and direct)."""
    (_, simulated, step_fmu, whole_fmu, step_direct, whole_direct, step_sa, whole_sa, step_alone, whole_alone,
     cpu_fmu, cpu_direct) = row
    return (simulated, step_fmu, step_fmu / simulated, step_direct, step_fmu / step_direct - 1,
            whole_fmu / whole_direct - 1, step_sa / step_alone - 1, whole_sa / whole_alone - 1,
            cpu_fmu / simulated, cpu_fmu / cpu_direct - 1)


def target(name):
    return "-" if TARGET.get(name) is None else f"<= {TARGET[name]:g}"


def within(name, figure) -> bool:
    """Whether a run's figures meet the scene's targets."""
    _, _, factor, _, overhead, _, standalone, _, _, _ = figure
    return (factor <= TARGET.get(name, np.inf) and overhead <= FMU_OVERHEAD_TARGET
            and standalone <= STANDALONE_OVERHEAD_TARGET.get(name, np.inf))


def print_tables(rows, step_times, repeat):
    """Every run's figures, and with `repeat` > 1 the spread and the median per scene (`step_times`: per scene,
    per kind of run, the wall times of the steps of each run); True when every run met its targets."""
    met, lines = True, []
    for row in rows:
        figure = figures(row)
        (simulated, step_fmu, factor, step_direct, overhead, whole, standalone, whole_sa, cpu_factor,
         cpu_overhead) = figure
        met &= within(row[0], figure)
        lines.append([row[0], f"{simulated:g}", f"{step_fmu:.3f}", f"{factor:.2f}", target(row[0]),
                      f"{step_direct:.3f}", f"{100 * overhead:+.1f}%", f"{100 * standalone:+.1f}%",
                      f"{100 * whole:+.1f}%", f"{100 * whole_sa:+.1f}%", f"{cpu_factor:.2f}",
                      f"{100 * cpu_overhead:+.1f}%"])
    print("\n" + table(["scene", "simulated, steps 2.. (s)", "stepping, FMUs (s)", "real-time factor, FMUs",
                        "target", "stepping, direct (s)", "overhead, FMUs", "overhead, standalone FMUs",
                        "whole run, FMUs", "whole run, standalone", "real-time factor, FMUs, CPU time",
                        "overhead, FMUs, CPU time"], lines))
    if repeat > 1:
        spread, median = [], []
        for name, steps in step_times.items():
            runs = np.array([figures(row) for row in rows if row[0] == name])
            factors, overheads, standalone = runs[:, 2], runs[:, 4], runs[:, 6]
            ok = "-" if name not in TARGET else sum(within(name, figure) for figure in runs)
            fastest = {kind: np.min(times, axis=0).sum() for kind, times in steps.items()}
            spread.append([name, len(runs), f"{factors.min():.2f}-{factors.max():.2f}", target(name), ok,
                           f"{fastest['fmu'] / runs[0, 0]:.2f}",
                           f"{100 * overheads.min():+.1f}..{100 * overheads.max():+.1f}%",
                           f"{100 * standalone.min():+.1f}..{100 * standalone.max():+.1f}%",
                           f"{100 * (fastest['standalone'] / fastest['direct beside standalone'] - 1):+.1f}%"])
            (simulated, step_fmu, factor, step_direct, overhead, whole, sa, whole_sa, cpu_factor,
             cpu_overhead) = np.median(runs, axis=0)
            median.append([name, f"{simulated:.3g}", f"{step_fmu:.3g}", f"{factor:.2g}", target(name),
                           f"{step_direct:.3g}", f"{100 * overhead:+.1f}%", f"{100 * sa:+.1f}%",
                           f"<= {100 * STANDALONE_OVERHEAD_TARGET.get(name, np.inf):g}%",
                           f"{100 * whole:+.1f}%", f"{100 * whole_sa:+.1f}%", f"{cpu_factor:.2g}",
                           f"{100 * cpu_overhead:+.1f}%"])
        print("\n" + table(["scene", "runs", "real-time factor, FMUs (min-max)", "target", "runs within targets",
                            "fastest turn of each step, FMUs (real-time factor)", "overhead, FMUs (min-max)",
                            "overhead, standalone FMUs (min-max)",
                            "overhead, standalone FMUs, fastest turn of each step"], spread))
        print("\nMedian over the runs of each scene:\n\n" + table(
            ["scene", "simulated time (s)", "stepping through the FMUs (s)", "real-time factor", "target",
             "stepping, direct (s)", "overhead, FMUs", "overhead, standalone FMUs", "target",
             "whole run overhead, FMUs", "whole run overhead, standalone", "real-time factor, CPU time",
             "overhead, FMUs, CPU time"], median))
    return met


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", nargs="+", default=list(TARGET), help="scene file stems (default: both)")
    parser.add_argument("--stop", type=float, default=None, help="time.stop, s (default: the scene's)")
    parser.add_argument("--repeat", type=int, default=1, metavar="N",
                        help="timed runs of each scene, one after the other (default 1)")
    parser.add_argument("--set", nargs="+", default=[], metavar="KEY=VALUE", dest="overrides",
                        help="scene keys to override, as wingsim run --set (e.g. record.probes=position)")
    args = parser.parse_args(argv)
    process_setup()                                     # one BLAS thread, the allocator as wingsim runs it
    if args.repeat < 1:
        parser.error(f"--repeat must be at least 1, got {args.repeat}")
    rows, step_times = [], {}
    with tempfile.TemporaryDirectory() as tmp:
        for name in args.scenes:
            scene = load_scene(ROOT / "scenes" / f"{name}.toml",
                               ([f"time.stop={args.stop}"] if args.stop else []) + args.overrides)
            stop, step = scene["time"]["stop"], scene["coupling"]["step"]
            if stop < 2 * step:
                parser.error(f"{name}: time.stop = {stop:g} s is less than two communication steps ({step:g} s): "
                             "the first step's turn holds the loading")
            fmu_dirs = {"fmu": Path(tmp) / name, "standalone": Path(tmp) / f"{name}-standalone"}
            build_fmus(scene, fmu_dirs["fmu"])
            build_fmus(scene, fmu_dirs["standalone"], standalone=True)
            print(f"{name}: {stop:g} s simulated ...", flush=True)
            warm_up(scene, fmu_dirs)
            for _ in range(args.repeat):
                times = timed(scene, fmu_dirs, ("fmu", "direct"), one_cpu=True)
                alone = timed(scene, fmu_dirs, ("standalone", "direct"), one_cpu=False,
                              steps_per_turn=STANDALONE_STEPS_PER_TURN)
                rows.append((name, stop - step, *times["fmu"][:2], *times["direct"][:2],
                             *alone["standalone"][:2], *alone["direct"][:2], times["fmu"][3], times["direct"][3]))
                for kind, steps in (("fmu", times["fmu"][2]), ("standalone", alone["standalone"][2]),
                                    ("direct beside standalone", alone["direct"][2])):
                    step_times.setdefault(name, {}).setdefault(kind, []).append(steps)
    if rows:
        met = print_tables(rows, step_times, args.repeat)
        print(f"\nall targets met: {'yes' if met else 'no'} (real-time factors as above; overhead of the stepping "
              f"through the ordinary FMUs <= {100 * FMU_OVERHEAD_TARGET:.0f}%, through the standalone FMUs as above"
              f"{', in every run' if args.repeat > 1 else ''})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
