"""Speed of the coupled deployment runs: wall time against simulated time, and the FMU backend's overhead.

    python benchmarks/speed.py [--scenes deploy_rigid deploy_flexible] [--stop 0.3] [--repeat N] [--profile]

For each scene as shipped it builds the FMUs (not timed), takes ten untimed warm-up steps through each
backend, then runs the scene through the FMUs (`backend="fmu"`, what `wingsim run SCENE` runs) and with the
same slaves in-process (`backend="direct"`), one BLAS thread. The two runs take turns, one communication
step each (`Lockstep`), on one CPU, so that a slow phase of a shared machine falls on both alike and their
ratio is the FMU backend's own cost. Each run's time is the sum of its own turns. Printed per run:

    real-time factor   stepping wall time / simulated time through the FMUs (1 = real time; targets:
                       deploy_rigid <= 1, deploy_flexible <= 20). The stepping is the communication
                       steps after the first (the first turn also loads the units: counted in the whole run).
    FMU overhead       stepping wall time fmu / direct - 1 (target <= 15%), and the same for the whole run
                       (loading, instantiating and terminating the units included).

--repeat N runs each scene N times in a row and adds, per scene, the range of the real-time factor, the
runs within its target, the range of the FMU overhead, and the real-time factor of the fastest of the N
turns of each communication step summed over the steps: a floor that drops the machine's slow phases, not
a measurement of one run; and last the median of each figure over the runs, the table of docs/performance.md
(made with `--repeat 3`).
--profile prints the 25 most expensive functions (cProfile, cumulative) of one direct run per scene.
"""
import argparse
import os
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np
from report import ROOT, limit_blas_threads

from orchestrator.build import build_fmus
from orchestrator.master import run_scene
from orchestrator.scene import load_scene

TARGET = {"deploy_rigid": 1.0, "deploy_flexible": 20.0}   # real-time factor through the FMUs
FMU_OVERHEAD_TARGET = 0.15
BACKENDS = ("fmu", "direct")


class Lockstep:
    """Runs of one scene, one per backend, each in its own thread, taking turns one communication step at a
    time (the `progress` hook of `run_scene` hands the turn over after every step). Only the thread holding
    the turn works; the others wait on a condition, holding no lock Python's threads compete for.

    Per backend: `turns`, the wall time (s) of each of its turns: the first from the run's start to its
    first step's end (loading the units included), then one communication step each (recording included);
    `tail`, from its last turn to the end of `run_scene` (terminating the units); `result`, the RunResult."""

    def __init__(self, scene, fmu_dir):
        self.scene, self.fmu_dir = scene, fmu_dir
        self._turn, self._done = BACKENDS[0], set()
        self._condition = threading.Condition()
        self.turns = {b: [] for b in BACKENDS}
        self.tail, self.result = {}, {}

    def run(self):
        """Both runs to their end, on one CPU (where the platform lets a process choose: Linux)."""
        pinned = hasattr(os, "sched_setaffinity")
        if pinned:
            allowed = os.sched_getaffinity(0)
            os.sched_setaffinity(0, {max(allowed)})     # the threads started below inherit the mask
        try:
            self._run_threads()
        finally:
            if pinned:
                os.sched_setaffinity(0, allowed)
        return self

    def _run_threads(self):
        threads = [threading.Thread(target=self._run, args=(b,), daemon=True) for b in BACKENDS]
        for thread in threads:
            thread.start()
        for thread in threads:
            thread.join()

    def _run(self, backend):
        self._wait(backend)
        clock = _TurnClock(self, backend)
        try:
            self.result[backend] = run_scene(self.scene, backend=backend, progress=clock,
                                             fmu_dir=self.fmu_dir if backend == "fmu" else None)
            self.tail[backend] = time.perf_counter() - clock.resumed
        finally:                                # also if the run raised: the other run must not wait for it
            with self._condition:
                self._done.add(backend)
                self._turn = next((b for b in BACKENDS if b not in self._done), None)
                self._condition.notify_all()

    def _wait(self, backend):
        with self._condition:
            self._condition.wait_for(lambda: self._turn == backend)

    def hand_over(self, backend):
        """After a step of `backend`: give the turn to the next unfinished run and wait for it to come back."""
        with self._condition:
            others = [b for b in BACKENDS if b != backend and b not in self._done]
            if not others:
                return
            self._turn = others[0]
            self._condition.notify_all()
            self._condition.wait_for(lambda: self._turn == backend)


class _TurnClock:
    """`run_scene`'s progress hook for one run of a `Lockstep`: times the run's turns and hands over."""

    def __init__(self, lockstep, backend):
        self.lockstep, self.backend = lockstep, backend
        self.resumed = time.perf_counter()

    def update(self, t):
        self.lockstep.turns[self.backend].append(time.perf_counter() - self.resumed)
        self.lockstep.hand_over(self.backend)
        self.resumed = time.perf_counter()

    def finish(self, t, status):
        pass


def warm_up(scene, fmu_dir):
    """Ten communication steps through both backends, not timed: the first steps of a process pay one-off
    costs (lazy imports, first calls into LAPACK and the FMU libraries) that are not the per-step cost."""
    short = {**scene, "time": {**scene["time"], "stop": 10 * scene["coupling"]["step"]}}
    for backend in BACKENDS:
        result = run_scene(short, backend=backend, fmu_dir=fmu_dir)
        if result.status != "ok":
            raise RuntimeError(f"{scene['name']} ({backend}, warm-up): {result.status}: {result.message}")


def timed(scene, fmu_dir):
    """{backend: (stepping s, whole run s, turns)} of one `Lockstep` run of each backend (stepping: the
    steps after the first; turns: their times, s, one per step); raises unless both runs end ok."""
    lockstep = Lockstep(scene, fmu_dir).run()
    out = {}
    for backend in BACKENDS:
        result = lockstep.result.get(backend)
        if result is None:
            raise RuntimeError(f"{scene['name']} ({backend}): the run raised (its traceback is printed above)")
        if result.status != "ok":
            raise RuntimeError(f"{scene['name']} ({backend}): {result.status}: {result.message}")
        turns = lockstep.turns[backend]
        out[backend] = (sum(turns[1:]), sum(turns) + lockstep.tail[backend], turns[1:])
    return out


def profile(scene, count=25):
    """Print the `count` most expensive functions of one direct run (cumulative time)."""
    import cProfile
    import pstats
    profiler = cProfile.Profile()
    profiler.runcall(run_scene, scene, backend="direct")
    pstats.Stats(profiler).sort_stats("cumulative").print_stats(count)


def ratios(row):
    """(real-time factor through the FMUs, FMU overhead of the stepping) of a result row."""
    _, simulated, step_fmu, _, step_direct, _ = row
    return step_fmu / simulated, step_fmu / step_direct - 1


def print_table(rows):
    """The markdown table of the rows; True when every row met its targets."""
    print("\n| scene | simulated, steps 2.. (s) | stepping, FMUs (s) | real-time factor, FMUs | target "
          "| stepping, direct (s) | FMU overhead, stepping | whole run, FMUs (s) | whole run, direct (s) "
          "| FMU overhead, whole run |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    met = True
    for row in rows:
        name, simulated, step_fmu, whole_fmu, step_direct, whole_direct = row
        factor, overhead = ratios(row)
        target = TARGET.get(name)
        met &= (target is None or factor <= target) and overhead <= FMU_OVERHEAD_TARGET
        print(f"| {name} | {simulated:g} | {step_fmu:.3f} | {factor:.2f} | {'-' if target is None else f'<= {target:g}'} "
              f"| {step_direct:.3f} | {100 * overhead:+.1f}% | {whole_fmu:.3f} | {whole_direct:.3f} "
              f"| {100 * (whole_fmu / whole_direct - 1):+.1f}% |")
    return met


def print_median(rows):
    """Per scene, the median over its runs of each figure (the table of docs/performance.md)."""
    print("\nMedian over the runs of each scene:\n\n| scene | simulated time (s) | stepping through the FMUs (s) "
          "| real-time factor | target | stepping, direct (s) | FMU overhead, stepping | FMU overhead, whole run |")
    print("|---|---|---|---|---|---|---|---|")
    for name in dict.fromkeys(row[0] for row in rows):
        figures = np.median([(simulated, step_fmu, step_fmu / simulated, step_direct, step_fmu / step_direct - 1,
                              whole_fmu / whole_direct - 1)
                             for scene, simulated, step_fmu, whole_fmu, step_direct, whole_direct in rows
                             if scene == name], axis=0)
        simulated, step_fmu, factor, step_direct, overhead, whole = figures
        target = TARGET.get(name)
        print(f"| {name} | {simulated:.3g} | {step_fmu:.3g} | {factor:.2g} | "
              f"{'-' if target is None else f'<= {target:g}'} | {step_direct:.3g} | {100 * overhead:+.1f}% | "
              f"{100 * whole:+.1f}% |")


def print_spread(rows, fmu_turns):
    """Per scene, over its runs: the range of the real-time factor, the runs within its target, the
    real-time factor of the fastest turn of each step (`fmu_turns`: {scene: [turn times (s) of each run]})
    and the range of the FMU overhead."""
    print("\n| scene | runs | real-time factor, FMUs (min-max) | target | runs within it "
          "| fastest turn of each step, FMUs (real-time factor) | FMU overhead, stepping (min-max) |")
    print("|---|---|---|---|---|---|---|")
    for name, turns in fmu_turns.items():
        simulated = next(row[1] for row in rows if row[0] == name)
        factors, overheads = zip(*(ratios(row) for row in rows if row[0] == name))
        target = TARGET.get(name)
        within = "-" if target is None else sum(f <= target for f in factors)
        fastest = np.min(turns, axis=0).sum() / simulated
        print(f"| {name} | {len(turns)} | {min(factors):.2f}-{max(factors):.2f} | "
              f"{'-' if target is None else f'<= {target:g}'} | {within} | {fastest:.2f} | "
              f"{100 * min(overheads):+.1f}..{100 * max(overheads):+.1f}% |")


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", nargs="+", default=list(TARGET), help="scene file stems (default: both)")
    parser.add_argument("--stop", type=float, default=None, help="time.stop, s (default: the scene's)")
    parser.add_argument("--repeat", type=int, default=1, metavar="N",
                        help="timed runs of each scene, one after the other (default 1)")
    parser.add_argument("--profile", action="store_true", help="print a cProfile of one direct run per scene")
    args = parser.parse_args(argv)
    limit_blas_threads()                                # one BLAS thread, as in CI runs
    if args.repeat < 1:
        parser.error(f"--repeat must be at least 1, got {args.repeat}")
    rows, fmu_turns = [], {}
    with tempfile.TemporaryDirectory() as tmp:
        for name in args.scenes:
            overrides = [f"time.stop={args.stop}"] if args.stop else []
            scene = load_scene(ROOT / "scenes" / f"{name}.toml", overrides=overrides)
            if args.profile:
                profile(scene)
                continue
            if scene["time"]["stop"] < 2 * scene["coupling"]["step"]:
                parser.error(f"{name}: time.stop = {scene['time']['stop']:g} s is less than two communication "
                             f"steps ({scene['coupling']['step']:g} s): the first step's turn holds the loading")
            fmu_dir = Path(tmp) / name
            build_fmus(scene, fmu_dir)
            print(f"{name}: {scene['time']['stop']:g} s simulated ...", flush=True)
            warm_up(scene, fmu_dir)
            for _ in range(args.repeat):
                times = timed(scene, fmu_dir)
                rows.append((name, scene["time"]["stop"] - scene["coupling"]["step"], *times["fmu"][:2],
                             *times["direct"][:2]))
                fmu_turns.setdefault(name, []).append(times["fmu"][2])
    if not rows:
        return 0
    met = print_table(rows)
    if args.repeat > 1:
        print_spread(rows, fmu_turns)
        print_median(rows)
    print(f"\nall targets met: {'yes' if met else 'no'} (real-time factors as above; FMU overhead of the stepping "
          f"<= {100 * FMU_OVERHEAD_TARGET:.0f}%{', in every run' if args.repeat > 1 else ''})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
