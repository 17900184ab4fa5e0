"""Structure unit speed: wall time per simulated second of the deployments with RK4 and generalized-alpha,
in-process and through the FMU, timed as speed.py times them (lockstep, one CPU, after a warm-up).

    python benchmarks/structure.py [--quick]

RK4 on the flexible wing runs at 0.9 times its stability limit 2 sqrt(2) / omega_max (omega_max from the
linear modes) over 400 limits of time, since the full deployment would take hours. The machines are shared
and noisy: compare the ratios printed by one run, not absolute times across runs.
"""
import argparse
import tempfile
from pathlib import Path

from report import ROOT, process_setup, table
from speed import timed, warm_up

from orchestrator.build.fmus import build_fmus
from orchestrator.scene.load import load_scene
from orchestrator.studies.stability import frequency_range, rk4_step_limit


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="shorter simulated intervals")
    quick = parser.parse_args().quick
    process_setup()
    limit = rk4_step_limit(frequency_range(load_scene(ROOT / "scenes" / "deploy_flexible.toml"))[1])
    cases = [("deploy_rigid", "", ["structure.integrator=rk4", "structure.step=1e-4"]),
             ("deploy_rigid", "", ["structure.integrator=generalized-alpha", "structure.step=1e-4"]),
             ("deploy_flexible", "", [f"time.stop={0.05 if quick else 0.3}"]),
             ("deploy_flexible", " (0.9 x limit)", ["structure.integrator=rk4", f"structure.step={0.9 * limit!r}",
                                                   f"time.stop={400 * limit!r}", f"coupling.step={40 * limit!r}"])]
    rows, cost = [], {}
    with tempfile.TemporaryDirectory() as tmp:
        for k, (name, note, overrides) in enumerate(cases):
            scene, fmu_dir = load_scene(ROOT / "scenes" / f"{name}.toml", overrides), Path(tmp) / str(k)
            integrator, step = scene["structure"]["integrator"], scene["structure"]["step"]
            build_fmus(scene, fmu_dir)
            warm_up(scene, fmu_dir)
            times = timed(scene, fmu_dir)
            simulated = scene["time"]["stop"] - scene["coupling"]["step"]
            direct, fmu = (times[backend][0] / simulated for backend in ("direct", "fmu"))
            cost[name, integrator] = direct
            rows.append([name, f"{integrator}, h = {step:.3g} s{note}",
                         f"{direct:.2f}", f"{fmu:.2f}", f"{fmu / direct:.3f}"])
    print(table(["scene", "integrator", "wall s / simulated s, direct", "through the FMU", "FMU / direct"], rows))
    ga, rk4 = ({name: cost[name, integrator] for name in ("deploy_rigid", "deploy_flexible")}
               for integrator in ("generalized-alpha", "rk4"))
    print(f"\nRK4 / generalized-alpha cost per simulated second: deploy_rigid "
          f"{rk4['deploy_rigid'] / ga['deploy_rigid']:.2f}, "
          f"deploy_flexible {rk4['deploy_flexible'] / ga['deploy_flexible']:.1f}")
    print(f"flexible / rigid (generalized-alpha): {ga['deploy_flexible'] / ga['deploy_rigid']:.1f}")
    print(f"RK4 stability limit of deploy_flexible: {limit:.3e} s")


if __name__ == "__main__":
    main()
