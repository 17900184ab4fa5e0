"""Speed of the coupled deployment runs: wall time against simulated time, and the FMU backend's overhead.

    python benchmarks/speed.py [--scenes deploy_rigid deploy_flexible] [--stop 0.3] [--profile]

For each scene (as shipped: uvlm-flat aero unit, Gauss-Seidel coupling at 1 ms) it builds the FMUs (not
timed), then runs the scene once through the FMUs (`backend="fmu"`, what `wingsim run SCENE` runs) and
once with the same slaves in-process (`backend="direct"`), one after the other in this process, one BLAS
thread. The wall time is `RunResult.wall_time_s`: from the start of `run_scene` (loading and instantiating
the units included) to its end. It prints, from this one run of each:

    real-time factor   wall time / simulated time (1 = real time; issue 5 targets: deploy_rigid <= 1,
                       deploy_flexible <= 20, through the FMUs)
    FMU overhead       wall time fmu / wall time direct - 1 (target <= 15%)

The machine is shared and noisy: compare ratios from one run, not absolute times across runs.
--profile prints the 25 most expensive functions (cProfile, cumulative) of one direct run per scene.
"""
import argparse
import os
import sys
import tempfile

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):   # one BLAS thread, as in CI runs
    os.environ.setdefault(_var, "1")

from pathlib import Path  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from orchestrator.build import build_fmus  # noqa: E402
from orchestrator.master import run_scene  # noqa: E402
from orchestrator.scene import load_scene  # noqa: E402

TARGET = {"deploy_rigid": 1.0, "deploy_flexible": 20.0}   # real-time factor through the FMUs (issue 5)
FMU_OVERHEAD_TARGET = 0.15


def timed_run(scene, backend, fmu_dir=None):
    """Wall time (s) of one run; raises if the run does not end ok (a failed run times nothing)."""
    result = run_scene(scene, backend=backend, fmu_dir=fmu_dir)
    if result.status != "ok":
        raise RuntimeError(f"{scene['name']} ({backend}): {result.status}: {result.message}")
    return result.wall_time_s


def profile(scene, count=25):
    """Print the `count` most expensive functions of one direct run (cumulative time)."""
    import cProfile
    import pstats
    profiler = cProfile.Profile()
    profiler.runcall(run_scene, scene, backend="direct")
    pstats.Stats(profiler).sort_stats("cumulative").print_stats(count)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", nargs="+", default=list(TARGET), help="scene file stems (default: both)")
    parser.add_argument("--stop", type=float, default=None, help="time.stop, s (default: the scene's)")
    parser.add_argument("--profile", action="store_true", help="print a cProfile of one direct run per scene")
    args = parser.parse_args(argv)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for name in args.scenes:
            overrides = [f"time.stop={args.stop}"] if args.stop else []
            scene = load_scene(ROOT / "scenes" / f"{name}.toml", overrides=overrides)
            if args.profile:
                profile(scene)
                continue
            fmu_dir = Path(tmp) / name
            build_fmus(scene, fmu_dir)
            simulated = scene["time"]["stop"]
            print(f"{name}: {simulated:g} s simulated ...", flush=True)
            wall_fmu = timed_run(scene, "fmu", fmu_dir)
            wall_direct = timed_run(scene, "direct")
            rows.append((name, simulated, wall_fmu, wall_direct))
    if not rows:
        return 0
    print("\n| scene | simulated (s) | wall, FMUs (s) | real-time factor, FMUs | target | wall, direct (s) "
          "| FMU overhead |")
    print("|---|---|---|---|---|---|---|")
    ok = True
    for name, simulated, wall_fmu, wall_direct in rows:
        factor, overhead = wall_fmu / simulated, wall_fmu / wall_direct - 1
        target = TARGET.get(name)
        ok &= (target is None or factor <= target) and overhead <= FMU_OVERHEAD_TARGET
        print(f"| {name} | {simulated:g} | {wall_fmu:.2f} | {factor:.2f} | "
              f"{'-' if target is None else f'<= {target:g}'} | {wall_direct:.2f} | {100 * overhead:+.1f}% |")
    print(f"\nall targets met: {'yes' if ok else 'no'} (FMU overhead target <= {100 * FMU_OVERHEAD_TARGET:.0f}%)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
