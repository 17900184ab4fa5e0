"""Wall time of a whole `wingsim run`, as a user waits for it: the first run on a machine (empty kernel cache, no
FMUs: the build and the one-time compilation of the C kernels included) and the later runs (FMUs built, kernels
cached), each a fresh process from interpreter start to the plots written.

    python benchmarks/first_run.py [--scene deploy_rigid] [--repeat 3] [--standalone]

--standalone times `wingsim run SCENE --standalone` (its first run builds the standalone FMUs).

Per repetition: a new empty folder as working folder and kernel cache ($WINGSIM_CACHE_DIR), one first run, then
two later runs in the same folder. Prints each time and the medians (docs/performance.md).
"""
import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time

from report import ROOT, table


def timed_run(scene, folder, flags=()):
    """Seconds of one `python -m orchestrator run SCENE [FLAGS]` in `folder`, its kernel cache there too."""
    env = {**os.environ, "WINGSIM_CACHE_DIR": os.path.join(folder, "cache"), "OPENBLAS_NUM_THREADS": "1",
           "PYTHONPATH": str(ROOT)}
    start = time.perf_counter()
    run = subprocess.run([sys.executable, "-m", "orchestrator", "run", str(ROOT / "scenes" / f"{scene}.toml"),
                          "--out", "out", *flags], cwd=folder, env=env, capture_output=True, text=True)
    seconds = time.perf_counter() - start
    if run.returncode != 0:
        sys.exit(f"{scene}: the run failed:\n{run.stderr}")
    return seconds


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scene", default="deploy_rigid")
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--standalone", action="store_true", help="time `wingsim run SCENE --standalone`")
    args = parser.parse_args()
    flags = ["--standalone"] if args.standalone else []
    first, later = [], []
    for k in range(args.repeat):
        with tempfile.TemporaryDirectory(prefix="wingsim_first_run_") as folder:
            first.append(timed_run(args.scene, folder, flags))
            later += [timed_run(args.scene, folder, flags) for _ in range(2)]
        print(f"  {k + 1}/{args.repeat}: first {first[-1]:.2f} s, later {later[-2]:.2f} s, {later[-1]:.2f} s")
    print(table(["scene", "first run after install (s, median)", "later runs (s, median)", "runs"],
                [[args.scene + (", standalone FMUs" if args.standalone else ""), f"{statistics.median(first):.2f}",
                  f"{statistics.median(later):.2f}",
                  f"{len(first)} + {len(later)}"]]))


if __name__ == "__main__":
    main()
