"""Speed of the coupled deployment runs: wall time against simulated time, and the FMU backend's overhead.

    python benchmarks/speed.py [--scenes deploy_rigid deploy_flexible] [--stop 0.3] [--profile]

For each scene (as shipped: uvlm-flat aero unit, Gauss-Seidel coupling at 1 ms) it builds the FMUs (not
timed), then runs the scene once through the FMUs (`backend="fmu"`, what `wingsim run SCENE` runs) and
once with the same slaves in-process (`backend="direct"`), one after the other in this process, one BLAS
thread, after ten untimed warm-up steps through each backend. From this one run of each it prints:

    real-time factor   stepping wall time / simulated time, through the FMUs (1 = real time; issue 5
                       targets: deploy_rigid <= 1, deploy_flexible <= 20). The stepping wall time
                       (summary `stepping_wall_time_s`) covers the communication steps: both units'
                       doStep, the exchange, the recording. Loading and instantiating the units comes
                       before it and is printed as `set-up`.
    FMU overhead       stepping wall time fmu / direct - 1 (target <= 15%), and the same for the whole run
                       (`wall_time_s`, set-up included).

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
    """(stepping wall time, whole wall time) in s of one run; raises unless the run ends ok."""
    result = run_scene(scene, backend=backend, fmu_dir=fmu_dir)
    if result.status != "ok":
        raise RuntimeError(f"{scene['name']} ({backend}): {result.status}: {result.message}")
    return result.stepping_wall_time_s, result.wall_time_s


def warm_up(scene, fmu_dir):
    """Ten communication steps through both backends, not timed: the first steps of a process pay one-off
    costs (lazy imports, first calls into LAPACK and the FMU libraries) that are not the per-step cost."""
    short = {**scene, "time": {**scene["time"], "stop": 10 * scene["coupling"]["step"]}}
    timed_run(short, "fmu", fmu_dir)
    timed_run(short, "direct")


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
            print(f"{name}: {scene['time']['stop']:g} s simulated ...", flush=True)
            warm_up(scene, fmu_dir)
            rows.append((name, scene["time"]["stop"], *timed_run(scene, "fmu", fmu_dir), *timed_run(scene, "direct")))
    if not rows:
        return 0
    print("\n| scene | simulated (s) | stepping, FMUs (s) | real-time factor, FMUs | target | set-up, FMUs (s) "
          "| stepping, direct (s) | FMU overhead, stepping | FMU overhead, whole run |")
    print("|---|---|---|---|---|---|---|---|---|")
    met = True
    for name, simulated, step_fmu, wall_fmu, step_direct, wall_direct in rows:
        factor, overhead = step_fmu / simulated, step_fmu / step_direct - 1
        target = TARGET.get(name)
        met &= (target is None or factor <= target) and overhead <= FMU_OVERHEAD_TARGET
        print(f"| {name} | {simulated:g} | {step_fmu:.3f} | {factor:.2f} | {'-' if target is None else f'<= {target:g}'} "
              f"| {wall_fmu - step_fmu:.3f} | {step_direct:.3f} | {100 * overhead:+.1f}% "
              f"| {100 * (wall_fmu / wall_direct - 1):+.1f}% |")
    print(f"\nall targets met: {'yes' if met else 'no'} (real-time factors as above; FMU overhead of the stepping "
          f"<= {100 * FMU_OVERHEAD_TARGET:.0f}%)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
