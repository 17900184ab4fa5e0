"""Structure unit speed: wall time per simulated second for the deployment scenes, RK4 against
generalized-alpha, and what the FMI boundary costs (FMU backend against direct), all in one run.

    python benchmarks/structure.py [--quick]

The machines are shared and noisy: compare the ratios printed by one run, not absolute times across runs.
RK4 on the flexible wing runs at 0.9 times its stability limit 2 sqrt(2) / omega_max (omega_max from the
linear modes) over a short interval, since the full deployment would take hours.
"""
import argparse
import sys
import tempfile
from pathlib import Path

from report import ROOT, limit_blas_threads

from orchestrator.build import build_fmus
from orchestrator.master import run_scene
from orchestrator.scene import load_scene
from orchestrator.stability import frequency_range, rk4_step_limit

SCENES = ROOT / "scenes"


def measure(name, overrides, backend, fmu_root):
    scene = load_scene(SCENES / f"{name}.toml", overrides)
    fmu_dir = None
    if backend == "fmu":
        fmu_dir = fmu_root / f"{name}-{abs(hash(tuple(overrides)))}"
        build_fmus(scene, fmu_dir)
    result = run_scene(scene, backend=backend, fmu_dir=fmu_dir)
    if result.status != "ok":
        raise SystemExit(f"{name} {overrides} {backend}: {result.status}: {result.message}")
    return result.wall_time_s / result.simulated_time_s


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="shorter simulated intervals")
    quick = parser.parse_args().quick
    limit_blas_threads()
    flexible_stop = 0.05 if quick else 0.3
    limit = rk4_step_limit(frequency_range(load_scene(SCENES / "deploy_flexible.toml"))[1])
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        fmu_root = Path(tmp)
        cases = [
            ("deploy_rigid", "rk4, h = 1e-4 s", ["structure.integrator=rk4", "structure.step=1e-4"]),
            ("deploy_rigid", "generalized-alpha, h = 1e-4 s", ["structure.integrator=generalized-alpha",
                                                               "structure.step=1e-4"]),
            ("deploy_flexible", "generalized-alpha, h = 1e-4 s", [f"time.stop={flexible_stop}"]),
            ("deploy_flexible", f"rk4, h = {0.9 * limit:.2e} s (0.9 x limit)",
             ["structure.integrator=rk4", f"structure.step={float(0.9 * limit)!r}",
              f"time.stop={float(400 * limit)!r}", f"coupling.step={float(40 * limit)!r}"]),
        ]
        for name, label, overrides in cases:
            direct = measure(name, overrides, "direct", fmu_root)
            fmu = measure(name, overrides, "fmu", fmu_root)
            rows.append((name, label, direct, fmu))
            print(f"  {name:16s} {label:40s} direct {direct:9.2f}  fmu {fmu:9.2f}", file=sys.stderr, flush=True)
    print("| scene | integrator | wall s / simulated s, direct | through the FMU | FMU / direct |")
    print("|---|---|---|---|---|")
    for name, label, direct, fmu in rows:
        print(f"| {name} | {label} | {direct:.2f} | {fmu:.2f} | {fmu / direct:.3f} |")
    ga = {n: d for n, l, d, f in rows if l.startswith("generalized")}
    rk = {n: d for n, l, d, f in rows if l.startswith("rk4")}
    print(f"\nRK4 / generalized-alpha cost per simulated second: deploy_rigid {rk['deploy_rigid'] / ga['deploy_rigid']:.2f}, "
          f"deploy_flexible {rk['deploy_flexible'] / ga['deploy_flexible']:.1f}")
    print(f"flexible / rigid (generalized-alpha): {ga['deploy_flexible'] / ga['deploy_rigid']:.1f}")
    print(f"RK4 stability limit of deploy_flexible (7 elements/body): {limit:.3e} s")


if __name__ == "__main__":
    main()
