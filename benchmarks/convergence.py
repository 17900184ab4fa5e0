"""Convergence of the lift coefficient with the wake length L_w, the chordwise panels M and the spanwise
panels N: the curves of 000 Sec. VII.A (Eqs. 28-30, Fig. 12).

    python benchmarks/convergence.py [--quick] [--jobs 2] [--scenes heaving_wing deploy_rigid] [--no-plots]

Error of a run against its reference (000 Eqs. 28-30):

    error = RMS(CL - CL_ref) / max|CL_ref| x 100 %

over the communication points after t = 0 (CL = 0 at t = 0 in every run); CL_ref is read at the run's
times by linear interpolation, exact here because every run's time grid is a subset of its reference's.

Every run is `orchestrator.master.run_scene(scene, backend="direct")`: the structure unit (prescribed or
rigid) and the aero unit in-process, Gauss-Seidel coupling, exactly what
`wingsim run SCENE --backend direct --set ...` runs. Runs go to `--jobs` processes, one BLAS thread each.

heaving_wing (000 Sec. VI.D; uvlm-prescribed; the scene's M = 10, N = 5, L_w = 25, step 0.1 s = c/(M V),
37.7 s = three periods at k = 0.25), one parameter varied at a time:
  (a) L_w = 1 ... 30 chords against the whole wake (no truncation: 37.7 chords at the end; aero.wake_length
      = inf is set on the resolved scene, which the aero solver accepts and the scene checker does not);
  (b) M = 1 ... 20 against M = 20, at the scene's fixed step of 0.1 s (what `--set aero.chordwise_panels=M`
      runs) and with the step c/(M V) (each shed wake row one panel long, the scene's rule);
  (c) N = 1 ... 20 against N = 40.
deploy_rigid at 15 m/s (000's own case, Fig. 12: uvlm-free, 0-0.2 s, 1 ms steps, per body):
  (a) L_w with M = N = 1 against the whole wake; (b) M with N = 1, L_w = 5 against M = 10;
  (c) N with M = 1, L_w = 5 against N = 10.

Writes docs/img/convergence_<scene>.png (one panel per parameter; 000's choices L_w = 5, M = 2, N = 7 dotted).
"""
import argparse
import os
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from pathlib import Path

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):   # one BLAS thread per process
    os.environ.setdefault(_var, "1")

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from orchestrator.master import run_scene  # noqa: E402
from orchestrator.scene import load_scene  # noqa: E402

IMG = ROOT / "docs" / "img"
PAPER_CHOICE = {"L_w": 5, "M": 2, "N": 7}          # 000 Sec. VII.A, for the deployment
T = 4 * np.pi                                      # s, the heaving wing's period (omega = 0.5 rad/s)
LABELS = {"L_w": "wake length L_w (chords)", "M": "chordwise panels M", "N": "spanwise panels N"}


@dataclass(frozen=True)
class Study:
    """One convergence curve: `values` of `parameter` (the reference `reference` included), each run with
    `base` + `overrides(value)` scene overrides."""
    scene: str
    parameter: str          # "L_w" | "M" | "N"
    label: str
    base: tuple
    values: tuple
    reference: object       # a value, or "all" (no wake truncation)
    step_per_panel: bool = False   # coupling.step = c / (M V) (heaving wing: 1 / M s)
    late: float | None = None      # also the error over t > late (s): without the start transient

    def overrides(self, value):
        out = list(self.base)
        if self.parameter == "L_w":
            out.append(f"aero.wake_length={'inf' if value == 'all' else value}")   # inf: no truncation
        elif self.parameter == "M":
            out.append(f"aero.chordwise_panels={value}")
            if self.step_per_panel:
                out.append(f"coupling.step={1.0 / value!r}")
        else:
            out.append(f"aero.spanwise_panels={value}")
        return out

    def runs(self):
        return [(self, v) for v in (*self.values, self.reference)]


def studies(quick=False):
    heave = []
    dep = ["aero.model=uvlm-free", "flow.speed=15", "time.stop=0.2"]
    if quick:
        heave.append(Study("heaving_wing", "L_w", "L_w (M = 10, N = 5)", ("time.stop=12.6",), (1, 3, 5, 10), "all"))
        heave.append(Study("heaving_wing", "M", "M, step 1/M s (N = 5, L_w = 25)", ("time.stop=12.6",),
                           (1, 2, 5), 10, step_per_panel=True))
        heave.append(Study("heaving_wing", "N", "N (M = 10, L_w = 25)", ("time.stop=12.6",), (1, 2, 5), 10))
        deploy = [Study("deploy_rigid", "L_w", "L_w (M = N = 1)", (*dep, "aero.chordwise_panels=1",
                        "aero.spanwise_panels=1", "time.stop=0.1"), (1, 5), "all")]
        return heave + deploy
    heave = [
        Study("heaving_wing", "L_w", "L_w (M = 10, N = 5)", (), (1, 2, 3, 5, 7, 10, 15, 20, 25, 30), "all",
              late=T),
        Study("heaving_wing", "M", "M, fixed step 0.1 s (N = 5, L_w = 25)", (), (1, 2, 3, 4, 5, 7, 10, 15), 20,
              late=T),
        Study("heaving_wing", "M", "M, step c/(MV) (N = 5, L_w = 25)", (), (1, 2, 4, 5, 10), 20,
              step_per_panel=True, late=T),
        Study("heaving_wing", "N", "N (M = 10, L_w = 25)", (), (1, 2, 3, 5, 7, 10, 20), 40, late=T),
    ]
    deploy = [
        Study("deploy_rigid", "L_w", "L_w (M = N = 1)", (*dep, "aero.chordwise_panels=1", "aero.spanwise_panels=1"),
              (1, 2, 3, 5, 7, 10), "all"),
        Study("deploy_rigid", "M", "M (N = 1, L_w = 5)", (*dep, "aero.spanwise_panels=1", "aero.wake_length=5"),
              (1, 2, 3, 4, 5, 7), 10),
        Study("deploy_rigid", "N", "N (M = 1, L_w = 5)", (*dep, "aero.chordwise_panels=1", "aero.wake_length=5"),
              (1, 2, 3, 5, 7), 10),
    ]
    return heave + deploy


def job_scene(job):
    study, value = job
    return load_scene(ROOT / "scenes" / f"{study.scene}.toml", study.overrides(value))


def estimated_cost(job):
    """Rough cost of a run (steps x bound panels x wake panels), to start the longest runs first."""
    scene = job_scene(job)
    aero, step = scene["aero"], scene["coupling"]["step"]
    steps = scene["time"]["stop"] / step
    rows = min(steps, aero["wake_length"] / max(scene["flow"]["speed"] * step, 1e-12))
    return steps * aero["chordwise_panels"] * aero["spanwise_panels"] ** 2 * (rows + aero["chordwise_panels"])


def run_one(job):
    """(time (s,), CL (s,), wall s) of one run."""
    study, value = job
    scene = job_scene(job)
    start = time.perf_counter()
    result = run_scene(scene, backend="direct")
    if result.status != "ok":
        raise RuntimeError(f"{study.scene} {study.overrides(value)}: {result.status}: {result.message}")
    return result.series.time.copy(), result.series.CL.copy(), time.perf_counter() - start


def cl_error(t, cl, t_ref, cl_ref, after_time=0.0):
    """000 Eqs. (28)-(30): RMS(CL - CL_ref) / max|CL_ref| x 100 %, over the samples after t = after_time
    (0: the whole run; max|CL_ref| always over the whole run)."""
    after = t > after_time
    ref = np.interp(t[after], t_ref, cl_ref)
    return 100.0 * float(np.sqrt(np.mean((cl[after] - ref) ** 2))) / float(np.abs(cl_ref[t_ref > 0]).max())


def below(values, errors, limit=1.0):
    """The smallest value from which on every error is below `limit` %, or None."""
    ok = None
    for v, e in zip(reversed(values), reversed(errors)):
        if e >= limit:
            break
        ok = v
    return ok


def plot(scene, curves, path):
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    from matplotlib.ticker import NullFormatter

    parameters = [p for p in ("L_w", "M", "N") if any(c[0].parameter == p for c in curves)]
    fig = Figure(figsize=(3.4 * len(parameters), 3.0))
    axes = fig.subplots(1, len(parameters), squeeze=False)[0]
    for ax, parameter in zip(axes, parameters):
        for study, values, errors, late in (c for c in curves if c[0].parameter == parameter):
            ref = "all wake" if study.reference == "all" else f"{parameter} = {study.reference}"
            line, = ax.semilogy(values, np.maximum(errors, 1e-4), "o-", ms=3, label=f"{study.label}\nref. {ref}")
            if late is not None:
                ax.semilogy(values, np.maximum(late, 1e-4), "o--", ms=3, mfc="none", color=line.get_color(),
                            label=f"  same, t > {study.late:.3g} s")
        ax.axhline(1.0, color="k", lw=0.6, ls="--")
        ax.axvline(PAPER_CHOICE[parameter], color="0.5", lw=0.8, ls=":")
        ax.set_xlabel(LABELS[parameter], fontsize=8)
        ax.set_ylabel("CL error (%)", fontsize=8)
        ax.tick_params(labelsize=7)
        ax.yaxis.set_minor_formatter(NullFormatter())
        ax.grid(True, which="both", alpha=0.25)
        ax.legend(fontsize=6)
    fig.suptitle(f"{scene}: CL error RMS(CL - CL_ref) / max|CL_ref| (000 Eqs. 28-30); "
                 "black dashed: 1 %, dotted: 000's choice", fontsize=8)
    FigureCanvasAgg(fig)
    fig.tight_layout()
    fig.savefig(path, dpi=90)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="a few short runs, no plots (a smoke test)")
    parser.add_argument("--jobs", type=int, default=2, help="worker processes (default 2)")
    parser.add_argument("--scenes", nargs="+", default=["heaving_wing", "deploy_rigid"])
    parser.add_argument("--no-plots", action="store_true", help="print the tables only")
    args = parser.parse_args(argv)

    chosen = [s for s in studies(args.quick) if s.scene in args.scenes]
    jobs = sorted(dict.fromkeys(job for s in chosen for job in s.runs()), key=estimated_cost, reverse=True)
    start = time.perf_counter()
    with ProcessPoolExecutor(max_workers=max(1, args.jobs)) as pool:
        results = dict(zip(jobs, pool.map(run_one, jobs)))
    wall = time.perf_counter() - start

    curves = {}
    for study in chosen:
        t_ref, cl_ref, ref_wall = results[(study, study.reference)]
        errors = [cl_error(*results[(study, v)][:2], t_ref, cl_ref) for v in study.values]
        late = None if study.late is None else [cl_error(*results[(study, v)][:2], t_ref, cl_ref, study.late)
                                                for v in study.values]
        curves.setdefault(study.scene, []).append((study, list(study.values), errors, late))
        ref = "all wake (no truncation)" if study.reference == "all" else f"{study.parameter} = {study.reference}"
        print(f"\n{study.scene}: {study.label}, reference {ref} ({ref_wall:.1f} s, max|CL_ref| = "
              f"{np.abs(cl_ref).max():.4f}); error < 1 % from {study.parameter} = {below(study.values, errors)}")
        print(f"| {study.parameter} | " + " | ".join(str(v) for v in study.values) + " |")
        print("|---|" + "---|" * len(study.values))
        print("| error (%) | " + " | ".join(f"{e:.3g}" for e in errors) + " |")
        if late is not None:
            print(f"| after t = {study.late:.3g} s (%) | " + " | ".join(f"{e:.3g}" for e in late) + " |")
        print("| run (s) | " + " | ".join(f"{results[(study, v)][2]:.1f}" for v in study.values) + " |")
    print(f"\n{len(jobs)} runs in {wall:.0f} s wall time on {args.jobs} processes")
    if not args.no_plots and not args.quick:
        IMG.mkdir(parents=True, exist_ok=True)
        for scene, scene_curves in curves.items():
            path = IMG / f"convergence_{scene}.png"
            plot(scene, scene_curves, path)
            print(f"wrote {path.relative_to(ROOT)} ({path.stat().st_size // 1024} KB)")


if __name__ == "__main__":
    main()
