"""Free wake: the treecode's far field (aero.wake_far_field = treecode) against the exact sum over every segment,
time and CL, on the AR-8 flat plate of benchmarks/peer_pterasoftware.py (5 deg, impulsive start, dt = c / (M V),
the whole wake kept).

    python benchmarks/free_wake.py [--panels 8 32] [--steps 100 200 400] [--openings 0.3 0.5] [--pairs 1]
                                   [--without-exact]

For each step count, the runs interleaved (exact, then each opening parameter, `--pairs` times): the aero
solver's stepping alone (`AeroSolver.advance` and the read of CL; the prescribed structure's coordinates are
computed before), its CPU time on one thread (WINGSIM_THREADS=1) and the wall time of the treecode on the
process's cores; CL at the last step and the largest difference of the CL history from the exact run's, relative
to the exact last CL. Then the growth of each CPU time with the step count (the slope of log time against log
steps between the last two step counts) and, where the largest step count is below 1000, the 1000-step times
extrapolated with that slope (printed as extrapolated). --without-exact runs the treecode alone (e.g. the
1000 steps that the exact sum would take half an hour for). The machines are shared and noisy: CPU-time ratios of one
run are the guide, wall times only for the threads' gain.
"""
import argparse
import math
import os
import statistics
import time

import numpy as np
from peer_pterasoftware import time_step, wingsim_scene
from report import process_setup

from aero_fmu.solver import AeroSolver
from fmu_common.specs import AeroUnitSpec, StructureUnitSpec
from structure_fmu.solver import StructureSolver

TARGET_STEPS = 1000


def inputs(M, N, steps):
    """The prescribed structure's (t, e, de) at each aero step."""
    scene, dt = wingsim_scene("uvlm-free", M, N, steps), time_step(M)
    structure, out = StructureSolver(StructureUnitSpec.from_scene(scene)), []
    for k in range(1, steps + 1):
        structure.advance(k * dt)
        out.append((k * dt, structure.e.copy(), structure.de.copy()))
    return scene, out


def run(scene, steps_inputs, far_field, opening, threads):
    """(CPU s, wall s, CL history) of one run of the aero solver with the given far field and thread count."""
    os.environ["WINGSIM_THREADS"] = str(threads)
    aero_table = dict(scene["aero"], wake_far_field=far_field, wake_opening=opening)
    aero = AeroSolver(AeroUnitSpec.from_scene(dict(scene, aero=aero_table)))
    history = []
    wall, cpu = time.perf_counter(), time.process_time()
    for t, e, de in steps_inputs:
        aero.advance(t, e, de)
        history.append(aero.outputs()["CL"])
    return time.process_time() - cpu, time.perf_counter() - wall, np.array(history)


def sheet(rows, span_rings=32):
    """(points, starts, ends, gamma) of a wavy wake sheet of rows x span_rings rings, 4 rows per chord, its
    circulation elliptic along the span and varying along the wake."""
    from aero_fmu import wake as wakes

    X, Y = np.meshgrid(np.arange(rows + 1) * 0.25, np.linspace(0.0, 8.0, span_rings + 1), indexing="ij")
    corners = np.stack([X, Y, 0.2 * np.sin(0.7 * X) * np.cos(0.4 * Y)], axis=-1)[None]
    along = np.sqrt(1.0 - np.linspace(-0.95, 0.95, span_rings) ** 2)
    gamma = along[None, None, :] * (1.0 + 0.3 * np.cos(0.3 * np.arange(rows)))[None, :, None]
    wake = wakes.ShedWake(corners, gamma)
    return (corners.reshape(-1, 3), *wakes.live_segments(wake))


def one_evaluation(rows, what, opening):
    """The convection velocity of `sheet(rows)` once, on one thread (`what`: setup, exact or treecode)."""
    from aero_fmu import wake as wakes
    from aero_fmu.biot_savart import c_kernels

    os.environ["WINGSIM_THREADS"] = "1"
    points, starts, ends, gamma = sheet(rows)
    c_kernels()                                                  # loaded in every variant, setup included
    if what != "setup":
        wakes.segment_sum(points, starts, ends, gamma, 0.025, None if what == "exact" else opening)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--panels", type=int, nargs=2, default=(8, 32), metavar=("M", "N"))
    parser.add_argument("--steps", type=int, nargs="+", default=(100, 200, 400))
    parser.add_argument("--openings", type=float, nargs="+", default=(0.3, 0.5))
    parser.add_argument("--pairs", type=int, default=1, help="interleaved repetitions per step count")
    parser.add_argument("--without-exact", action="store_true", help="the treecode runs only")
    parser.add_argument("--sheet", nargs=2, metavar=("ROWS", "WHAT"), help="one evaluation for callgrind")
    args = parser.parse_args()
    if args.sheet:
        one_evaluation(int(args.sheet[0]), args.sheet[1], args.openings[0])
        return
    process_setup()
    cores = os.environ.get("WINGSIM_THREADS") or str(len(os.sched_getaffinity(0)))
    M, N = args.panels
    print(f"AR-8 flat plate, {M} x {N} panels, free wake; CPU s on one thread (median of {args.pairs}), "
          f"wall s of the treecode on {cores} threads")
    print(f"{'steps':>6} {'run':>14} {'CPU s':>9} {'ratio':>7} {'wall s':>8} {'wall, threads':>13} "
          f"{'CL last':>11} {'max |dCL| / CL':>15}")
    growth = {}
    for steps in args.steps:
        scene, steps_inputs = inputs(M, N, steps)
        cases = [] if args.without_exact else [("exact", 0.5)]
        cases += [("treecode", theta) for theta in args.openings]
        samples = {case: [] for case in cases}
        threaded = {case: [] for case in cases if case[0] == "treecode"}
        for _ in range(args.pairs):
            for case in cases:
                samples[case].append(run(scene, steps_inputs, *case, threads=1))
                if case in threaded:
                    threaded[case].append(run(scene, steps_inputs, *case, threads=int(cores))[1])
        exact_cpu, exact_cl = math.nan, np.full(steps, np.nan)
        if not args.without_exact:
            exact_cpu, exact_cl = statistics.median(s[0] for s in samples[cases[0]]), samples[cases[0]][0][2]
        for case in cases:
            cpu = statistics.median(s[0] for s in samples[case])
            wall = statistics.median(s[1] for s in samples[case])
            cl = samples[case][0][2]
            name = "exact" if case[0] == "exact" else f"theta {case[1]:g}"
            walls = f"{statistics.median(threaded[case]):13.2f}" if case in threaded else f"{'':13}"
            print(f"{steps:6d} {name:>14} {cpu:9.2f} {cpu / exact_cpu:7.3f} {wall:8.2f} {walls} {cl[-1]:11.6f} "
                  f"{np.abs(cl - exact_cl).max() / abs(exact_cl[-1]):15.2e}")
            growth.setdefault(name, []).append((steps, cpu))
    if len(args.steps) < 2 or args.without_exact:
        return
    print(f"growth of the CPU time with the steps (slope of log-log between the last two step counts); "
          f"{TARGET_STEPS} steps EXTRAPOLATED with it where not measured:")
    exact = None
    for name, points in growth.items():
        (s0, t0), (s1, t1) = points[-2], points[-1]
        slope = math.log(t1 / t0) / math.log(s1 / s0)
        at_target = t1 * (TARGET_STEPS / s1) ** slope
        exact = exact or at_target
        label = "measured" if s1 == TARGET_STEPS else "extrapolated"
        print(f"  {name:>10}: steps^{slope:.2f}; {TARGET_STEPS} steps {at_target:8.1f} s CPU ({label}), "
              f"{exact / at_target:5.1f} x faster than exact")


if __name__ == "__main__":
    main()
