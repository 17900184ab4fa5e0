"""Fine meshes: deploy_flexible's structure with 7, 15, 20 and 30 elements per body at the shipped step.

    python benchmarks/mesh.py [--quick] [--instructions]

Each mesh runs in still air (aero.model = none: the structure's cost and stiffness are what the mesh changes),
through the solver API, from the start to time.stop. Printed per mesh: the highest natural frequency omega_max at
rest and h omega_max, the start's largest acceleration max|q''_0| and generalized-alpha's start-up (d, k: the
first k steps taken as d shorter ones, structure_fmu.integrators.start_up), the most energy any millisecond adds (a
damped structure in still air may only lose energy), the latch time and the tip at 0.2 s against the same mesh
at a quarter of the step, Newton iterations and CPU seconds per simulated second. With --instructions, the
instructions per simulated second that valgrind's callgrind counts between t = 0.01 and 0.03 s (a process run
to each time, their difference: imports, start-up and compilation cancel). --quick: to 0.05 s, without the
reference runs and the tip.
"""
import argparse
import json
import re
import subprocess
import sys
import time

import numpy as np
from report import ROOT, process_setup, table

from fmu_common.specs import StructureUnitSpec
from orchestrator.scene.load import load_scene
from structure_fmu.integrators import start_up
from structure_fmu.modes import natural_frequencies
from structure_fmu.solver import StructureSolver

ELEMENTS = (7, 15, 20, 30)
TIP_TIME = 0.2          # s, the tip deflection Otsuka et al. 2022, Sec. 5 reports
WINDOW = (0.01, 0.03)   # s, the interval whose instructions are counted


def solver(elements, step=None):
    """A StructureSolver of deploy_flexible in still air with `elements` per body, at `step` (s; None: the
    scene's)."""
    overrides = [f"structure.elements_per_body={elements}", "aero.model=none"]
    if step is not None:
        overrides.append(f"structure.step={step!r}")
    return StructureSolver(StructureUnitSpec.from_scene(load_scene(ROOT / "scenes" / "deploy_flexible.toml",
                                                                   overrides)))


def run(elements, stop, step=None):
    """{latch time s, tip (3,) m at TIP_TIME, largest energy added by a communication-length interval J,
    Newton iterations, CPU s} of one run to `stop` (s), advanced in 1 ms intervals."""
    unit = solver(elements, step)
    energy, rise, tip, start = unit.monitors()["energy"], 0.0, None, time.process_time()
    for k in range(1, round(stop / 1e-3) + 1):
        unit.advance(k * 1e-3)
        now = unit.monitors()["energy"]
        rise, energy = max(rise, now - energy), now
        if k == round(TIP_TIME / 1e-3):
            tip = unit.probe_positions()[1]
    return {"latch": unit.monitors()["latch_times"].get("fold"), "tip": tip, "rise": rise,
            "iterations": unit.integrator.newton_iterations, "cpu": time.process_time() - start}


def stiffness(elements):
    """(omega_max rad/s, h s, max|q''_0|, start-up (d, k)) of a mesh at rest."""
    unit = solver(elements)
    omega = float(natural_frequencies(unit, count=None).max())
    unit.advance(0.0)               # initializes the state's accelerations
    acceleration = float(np.abs(unit.state.ddq).max())
    return omega, unit.step_size, acceleration, start_up(unit.step_size, acceleration, unit.integrator.rho_inf)


def instructions(elements):
    """Instructions per simulated second between WINDOW's times (callgrind, two processes)."""
    counts = []
    for stop in WINDOW:
        command = ["valgrind", "--tool=callgrind", "--callgrind-out-file=/dev/null", sys.executable, __file__,
                   "--one", json.dumps([elements, stop])]
        out = subprocess.run(command, capture_output=True, text=True, cwd=ROOT)
        found = re.search(r"Collected : (\d+)", out.stderr)
        if out.returncode or not found:
            raise RuntimeError(f"callgrind of {elements} elements to {stop} s: exit {out.returncode}: "
                               f"{out.stderr[-500:]}")
        counts.append(int(found.group(1)))
    return (counts[1] - counts[0]) / (WINDOW[1] - WINDOW[0])


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="to 0.05 s, no reference runs")
    parser.add_argument("--instructions", action="store_true", help="count instructions with callgrind")
    parser.add_argument("--one", help=argparse.SUPPRESS)
    args = parser.parse_args()
    process_setup()
    if args.one:                    # a worker of `instructions`
        elements, stop = json.loads(args.one)
        solver(elements).advance(stop)
        return
    stop = 0.05 if args.quick else 0.3
    rows, base = [], {}
    for elements in ELEMENTS:
        omega, h, acceleration, (d, k) = stiffness(elements)
        result = run(elements, stop)
        row = [elements, f"{omega:.3g}", f"{h * omega:.0f}", f"{acceleration:.2g}", f"{d}, {k}",
               f"{result['rise']:.2g}"]
        if not args.quick:
            reference = run(elements, stop, h / 4)
            row += [f"{result['latch']:.5f}", f"{reference['latch']:.5f}",
                    f"{1e3 * np.linalg.norm(result['tip'] - reference['tip']):.3f}"]
        cost = result["cpu"] / stop
        base.setdefault("cpu", cost)
        row += [result["iterations"], f"{cost:.1f}", f"{cost / base['cpu']:.2f}"]
        if args.instructions:
            count = instructions(elements)
            base.setdefault("instructions", count)
            row += [f"{count:.3g}", f"{count / base['instructions']:.2f}"]
        rows.append(row)
        print(f"{elements} elements per body done", file=sys.stderr)
    header = ["elements per body", "omega_max rad/s", "h omega_max", "max|q''_0| 1/s^2", "start-up d, k",
              "largest energy rise J"]
    if not args.quick:
        header += ["latch s", "latch at h/4 s", "tip at 0.2 s against h/4 mm"]
    header += ["Newton iterations", "CPU s / simulated s", "CPU / 7 elements"]
    if args.instructions:
        header += ["instructions / simulated s", "instructions / 7 elements"]
    print(table(header, rows))


if __name__ == "__main__":
    main()
