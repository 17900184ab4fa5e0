"""Aero unit cost per step: each model against the bound and wake panel counts, and the free/flat cost
ratio on the deployment mesh (Otsuka et al. 2019, Sec. VII.A, report the flat wake 95% cheaper).

    python benchmarks/aero.py [--quick]

Wall time per `AeroSolver.advance` (mean of the last steps, one BLAS thread):
  1. bound panels: an AR-8 wing, M x N from 2 x 7 to 8 x 64, wake 5 chords, dt = c/(MV); "rigid": a heaving
     wing (the influence matrix factorized once), "deforming": E changes every step (matrix and LU rebuilt);
  2. wake panels: M x N = 4 x 16, wake 2.5 to 20 chords, prescribed and free wakes;
  3. deploy_rigid at 15 m/s (M = 2, N = 7 per body, L_w = 5), the structure run by its own solver, only the
     aero step timed, over the first 0.1 s;
  4. Biot-Savart throughput (Otsuka et al. 2019, Eq. 19): segment-point pairs per second for an influence
     matrix (normal wash, ring weights) and for the induced velocity of known circulations.
The machines are shared and noisy: compare the ratios of one run, not absolute times across runs.
"""
import argparse
import time
import timeit

import numpy as np
from report import ROOT, process_setup

from aero_fmu.solver import AeroSolver
from fmu_common.specs import AeroUnitSpec, StructureUnitSpec
from fmu_common.choices import AERO_MODELS
from orchestrator.scene.load import load_scene, resolve_scene
from structure_fmu.solver import StructureSolver

MODELS = tuple(name for name, model in AERO_MODELS.items() if model.builds_unit)
SECTION = {"chord": 1.0, "thickness": 0.01, "density": 100.0, "youngs_modulus": 1e9, "torsional_rigidity": 1.0}


def wing(model, M, N, wake_length, fidelity="prescribed"):
    body = {"name": "wing", "length": 8.0, "span_axis": [0, 1, 0], "chord_axis": [1, 0, 0], "section": SECTION}
    structure = {"fidelity": fidelity, "bodies": [body], "joints": [{"type": "clamp", "body": "wing"}]}
    if fidelity == "prescribed":
        structure.update(motion={"heave_amplitude": 0.05, "frequency": 3.0}, joints=[])
    else:
        structure["elements_per_body"] = 4
    return resolve_scene({"time": {"stop": 1.0}, "coupling": {"step": 0.1}, "structure": structure,
                          "flow": {"speed": 10.0, "density": 1.2},
                          "aero": {"model": model, "chordwise_panels": M, "spanwise_panels": N,
                                   "wake_length": wake_length}}, "wing")


def per_step(aero, inputs, timed):
    """Mean wall time (s) of the last `timed` of the advance calls over inputs [(t, e, de), ...]."""
    for t, e, de in inputs[:-timed]:
        aero.advance(t, e, de)
    start = time.perf_counter()
    for t, e, de in inputs[-timed:]:
        aero.advance(t, e, de)
    return (time.perf_counter() - start) / timed


def wing_inputs(scene, M, steps, deforming):
    dt = 1.0 / (M * 10.0)
    if deforming:
        E0 = AeroSolver(AeroUnitSpec.from_scene(scene)).topology.initial_coordinates()
        wobble = 1e-3 * np.sin(np.arange(E0.size))
        return [(k * dt, E0 + k * wobble, np.zeros_like(E0)) for k in range(1, steps + 1)]
    structure, out = StructureSolver(StructureUnitSpec.from_scene(scene)), []
    for k in range(1, steps + 1):
        structure.advance(k * dt)
        out.append((k * dt, structure.e, structure.de))
    return out


def bound_scaling(meshes, timed):
    print("1. cost per step (ms) against bound panels; AR-8 wing, wake 5 chords (5 M rows)")
    print(f"{'M x N':>8} {'bound':>6} {'wake':>6} " + " ".join(f"{m + ' ' + k:>22}" for m in MODELS
                                                               for k in ("rigid", "deforming")))
    for M, N in meshes:
        row, wake_panels = [], 0
        for model in MODELS:
            for deforming in (False, True):
                scene = wing(model, M, N, 5.0, "flexible" if deforming else "prescribed")
                aero = AeroSolver(AeroUnitSpec.from_scene(scene))
                row.append(1e3 * per_step(aero, wing_inputs(scene, M, 5 * M + timed + 1, deforming), timed))
                wake_panels = max(wake_panels, aero.outputs()["wake_panels"])
        print(f"{M:>3} x {N:<3} {M * N:>6} {wake_panels:>6} " + " ".join(f"{v:>22.3f}" for v in row))


def wake_scaling(lengths, timed):
    M, N = 4, 16
    print(f"2. cost per step (ms) against wake panels; M x N = {M} x {N} (64 bound panels), heaving wing")
    print(f"{'L_w':>6} {'wake':>6} {'uvlm-prescribed':>16} {'uvlm-free':>10}")
    for length in lengths:
        row = []
        for model in ("uvlm-prescribed", "uvlm-free"):
            scene = wing(model, M, N, length)
            aero = AeroSolver(AeroUnitSpec.from_scene(scene))
            row.append(1e3 * per_step(aero, wing_inputs(scene, M, int(length * M) + timed + 1, False), timed))
        print(f"{length:>6.1f} {aero.outputs()['wake_panels']:>6} {row[0]:>16.3f} {row[1]:>10.3f}")


def deployment(duration):
    scene = load_scene(ROOT / "scenes" / "deploy_rigid.toml", ["flow.speed=15"])
    structure = StructureSolver(StructureUnitSpec.from_scene(scene))
    step = scene["coupling"]["step"]
    inputs = []
    for k in range(1, round(duration / step) + 1):
        structure.advance(k * step)
        inputs.append((k * step, structure.e, structure.de))
    fold = np.degrees(structure.topology.fold_angles(inputs[-1][1])["fold"])
    aero = scene["aero"]
    print(f"3. deployment mesh (Otsuka et al. 2019; deploy_rigid at 15 m/s, M = {aero['chordwise_panels']}, "
          f"N = {aero['spanwise_panels']} per body, L_w = {aero['wake_length']:g}, {len(inputs)} steps of {step:g} s, "
          f"fold angle {fold:.0f} deg at the end)")
    times = {}
    for model in MODELS:
        solver = AeroSolver(AeroUnitSpec.from_scene({**scene, "aero": {**aero, "model": model}}))
        start = time.perf_counter()
        for t, e, de in inputs:
            solver.advance(t, e, de)
        times[model] = (time.perf_counter() - start) / len(inputs)
        print(f"   {model:<16} {1e3 * times[model]:8.3f} ms per step, wake panels {solver.outputs()['wake_panels']}, "
              f"C_L at the end {solver.outputs()['CL']:+.3f}")
    print(f"   flat / free cost: {times['uvlm-flat'] / times['uvlm-free']:.3f} "
          f"(flat {100 * (1 - times['uvlm-flat'] / times['uvlm-free']):.0f}% cheaper; Otsuka et al. 2019 report 95%)")


def biot_savart_throughput(points=2000, segments=4000, repeats=3):
    """Pairs per second of aero_fmu.biot_savart on random geometry (the kernel is geometry-independent)."""
    from scipy import sparse

    from aero_fmu.biot_savart import induced_velocity, influence
    rng = np.random.default_rng(0)
    p, a = rng.standard_normal((points, 3)), rng.standard_normal((segments, 3))
    b = a + 0.1 * rng.standard_normal((segments, 3))
    normals = rng.standard_normal((points, 3))
    rings = sparse.random(segments, segments // 4, density=4 / segments, random_state=0, format="csr")
    gamma = rng.standard_normal(segments)
    print(f"4. Biot-Savart throughput, {points} points x {segments} segments")
    for label, call in (("influence matrix (normal wash)", lambda: influence(p, a, b, rings, 1e-3, normals=normals)),
                        ("induced velocity of known circulations", lambda: induced_velocity(p, a, b, gamma, 1e-3))):
        best = min(timeit.repeat(call, number=1, repeat=repeats))
        print(f"   {label:<40} {points * segments / best / 1e6:8.1f} million pairs per second")


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="smaller meshes, fewer steps")
    quick = parser.parse_args().quick
    process_setup()
    bound_scaling([(2, 7), (4, 16)] if quick else [(2, 7), (4, 16), (8, 32), (8, 64)], 3 if quick else 5)
    wake_scaling([2.5, 5.0] if quick else [2.5, 5.0, 10.0, 20.0], 3 if quick else 5)
    deployment(0.02 if quick else 0.1)
    biot_savart_throughput(500 if quick else 2000, 1000 if quick else 4000)


if __name__ == "__main__":
    main()
