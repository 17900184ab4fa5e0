"""Convergence of the lift coefficient with the wake length L_w, the chordwise panels M and the spanwise
panels N: the curves of Otsuka et al. 2019, Sec. VII.A (Eqs. 28-30, Fig. 12).

    python benchmarks/convergence.py [--quick] [--jobs 2] [--resume] [--scenes heaving_wing deploy_rigid]
                                     [--no-plots]

The error of a run against its reference is orchestrator.metrics.cl_error_pct, RMS(CL - CL_ref) / max|CL_ref|
x 100 % over the communication points after t = 0 (CL_ref read at the run's times, exact here: every run's
time grid is a subset of its reference's). Every run is `orchestrator.master.run_scene(scene,
backend="direct")`, what `wingsim run SCENE --backend direct --set ...` runs, in `--jobs` worker processes.

heaving_wing (Otsuka et al. 2019, Sec. VI.D; uvlm-prescribed; the scene's M = 10, N = 5, L_w = 25, step
0.1 s = c/(M V), 37.7 s = three periods at k = 0.25), one parameter varied at a time:
  (a) L_w = 1 ... 30 chords against the whole wake (no truncation: aero.wake_length = inf is set on the
      resolved scene, which the aero solver accepts and the scene checker does not);
  (b) M = 1 ... 20 against M = 20, at the scene's fixed step of 0.1 s and with the step c/(M V);
  (c) N = 1 ... 20 against N = 40.
deploy_rigid at 15 m/s (the paper's own case, Fig. 12: uvlm-free, 0-0.2 s, 1 ms steps, per body):
  (a) L_w with M = N = 1 against the whole wake; (b) M with N = 1, L_w = 5 against M = 10;
  (c) N with M = 1, L_w = 5 against N = 10.
Prints a table per curve and writes docs/img/convergence_<scene>.png (the paper's choices L_w = 5, M = 2,
N = 7 dotted); every run's CL history goes to results/studies/convergence.jsonl.
"""
import math
from dataclasses import dataclass

import numpy as np
from report import RECORDS, ROOT, arguments, figure, save

from orchestrator.metrics import cl_error_pct, converged_from
from orchestrator.study import Study

PAPER_CHOICE = {"L_w": 5, "M": 2, "N": 7}          # Otsuka et al. 2019, Sec. VII.A, for the deployment
T = 4 * np.pi                                      # s, the heaving wing's period (omega = 0.5 rad/s)
LABELS = {"L_w": "wake length L_w (chords)", "M": "chordwise panels M", "N": "spanwise panels N"}


@dataclass(frozen=True)
class Curve:
    """One convergence curve: `values` of `parameter` and the reference value `reference` ("all": no wake
    truncation), each run with the `base` overrides and the parameter's."""
    scene: str
    parameter: str                 # "L_w" | "M" | "N"
    label: str
    base: tuple
    values: tuple
    reference: object
    step_per_panel: bool = False   # coupling.step = c / (M V) (heaving wing: 1 / M s)
    late: float | None = None      # also the error over t > late (s): without the start transient


@dataclass(frozen=True)
class Run:
    """One run of a curve: the scene (file stem) with `overrides`; `whole_wake` sets an untruncated wake."""
    scene: str
    overrides: tuple
    whole_wake: bool = False

    @property
    def label(self):
        return f"{self.scene} {' '.join(self.overrides)}"


def run_of(study, value):
    out = list(study.base)
    if study.parameter == "L_w":
        return Run(study.scene, tuple(out), whole_wake=True) if value == "all" else \
            Run(study.scene, (*out, f"aero.wake_length={value}"))
    if study.parameter == "M":
        out.append(f"aero.chordwise_panels={value}")
        out += [f"coupling.step={1.0 / value!r}"] if study.step_per_panel else []
    else:
        out.append(f"aero.spanwise_panels={value}")
    return Run(study.scene, tuple(out))


def studies(quick=False):
    dep = ("aero.model=uvlm-free", "flow.speed=15", "time.stop=0.2")
    if quick:
        short = ("time.stop=12.6",)
        return [Curve("heaving_wing", "L_w", "L_w (M = 10, N = 5)", short, (1, 3, 5, 10), "all"),
                Curve("heaving_wing", "M", "M, step 1/M s (N = 5, L_w = 25)", short, (1, 2, 5), 10, True),
                Curve("heaving_wing", "N", "N (M = 10, L_w = 25)", short, (1, 2, 5), 10),
                Curve("deploy_rigid", "L_w", "L_w (M = N = 1)", (*dep, "aero.chordwise_panels=1",
                       "aero.spanwise_panels=1", "time.stop=0.1"), (1, 5), "all")]
    return [Curve("heaving_wing", "L_w", "L_w (M = 10, N = 5)", (), (1, 2, 3, 5, 7, 10, 15, 20, 25, 30), "all", late=T),
            Curve("heaving_wing", "M", "M, fixed step 0.1 s (N = 5, L_w = 25)", (), (1, 2, 3, 4, 5, 7, 10, 15), 20,
                   late=T),
            Curve("heaving_wing", "M", "M, step c/(MV) (N = 5, L_w = 25)", (), (1, 2, 4, 5, 10), 20, True, late=T),
            Curve("heaving_wing", "N", "N (M = 10, L_w = 25)", (), (1, 2, 3, 5, 7, 10, 20), 40, late=T),
            Curve("deploy_rigid", "L_w", "L_w (M = N = 1)", (*dep, "aero.chordwise_panels=1", "aero.spanwise_panels=1"),
                   (1, 2, 3, 5, 7, 10), "all"),
            Curve("deploy_rigid", "M", "M (N = 1, L_w = 5)", (*dep, "aero.spanwise_panels=1", "aero.wake_length=5"),
                   (1, 2, 3, 4, 5, 7), 10),
            Curve("deploy_rigid", "N", "N (M = 1, L_w = 5)", (*dep, "aero.chordwise_panels=1", "aero.wake_length=5"),
                   (1, 2, 3, 5, 7), 10)]


def scene_of(run):
    from orchestrator.scene import load_scene

    scene = load_scene(ROOT / "scenes" / f"{run.scene}.toml", list(run.overrides))
    if run.whole_wake:
        scene["aero"]["wake_length"] = math.inf     # no truncation (the scene checker refuses inf)
    return scene


def cost(run):
    """Rough cost of a run (steps x bound panels x wake panels), to start the longest runs first."""
    scene = scene_of(run)
    aero, step = scene["aero"], scene["coupling"]["step"]
    steps = scene["time"]["stop"] / step
    rows = min(steps, aero["wake_length"] / max(scene["flow"]["speed"] * step, 1e-12))
    return steps * aero["chordwise_panels"] * aero["spanwise_panels"] ** 2 * (rows + aero["chordwise_panels"])


def work(run):
    """The run's times (s), CL and wall time (s); an error unless the run ended ok."""
    from orchestrator.master import run_scene

    result = run_scene(scene_of(run), backend="direct")
    if result.status != "ok":
        raise RuntimeError(f"{result.status}: {result.message}")
    return {"t": result.series.time, "CL": result.series.CL, "wall_s": result.wall_time_s}


def plot(scene, curves):
    """docs/img/convergence_<scene>.png: one panel per parameter, CL error (%) against its values."""
    from matplotlib.ticker import NullFormatter

    parameters = [p for p in ("L_w", "M", "N") if any(c[0].parameter == p for c in curves)]
    fig, (axes,) = figure(1, len(parameters), 3.4 * len(parameters), 3.0)
    for ax, parameter in zip(axes, parameters):
        for study, errors, late in (c for c in curves if c[0].parameter == parameter):
            ref = "all wake" if study.reference == "all" else f"{parameter} = {study.reference}"
            line, = ax.semilogy(study.values, np.maximum(errors, 1e-4), "o-", ms=3, label=f"{study.label}\nref. {ref}")
            if late is not None:
                ax.semilogy(study.values, np.maximum(late, 1e-4), "o--", ms=3, mfc="none", color=line.get_color(),
                            label=f"  same, t > {study.late:.3g} s")
        ax.axhline(1.0, color="k", lw=0.6, ls="--")
        ax.axvline(PAPER_CHOICE[parameter], color="0.5", lw=0.8, ls=":")
        ax.set_xlabel(LABELS[parameter], fontsize=8)
        ax.set_ylabel("CL error (%)", fontsize=8)
        ax.tick_params(labelsize=7)
        ax.yaxis.set_minor_formatter(NullFormatter())
        ax.grid(True, which="both", alpha=0.25)
        ax.legend(fontsize=6)
    fig.suptitle(f"{scene}: CL error RMS(CL - CL_ref) / max|CL_ref| (Otsuka et al. 2019, Eqs. 28-30); "
                 "black dashed: 1 %, dotted: the paper's choice", fontsize=8)
    save(fig, ROOT / "docs", f"convergence_{scene}", dpi=90)


def main(argv=None):
    args = arguments(__doc__, argv=argv, **{"--scenes": {"nargs": "+", "default": ["heaving_wing", "deploy_rigid"]}})
    chosen = [s for s in studies(args.quick) if s.scene in args.scenes]
    study = Study(RECORDS / f"convergence{'_quick' if args.quick else ''}.jsonl", resume=args.resume)
    res = study.run([run_of(s, v) for s in chosen for v in (*s.values, s.reference)], work, args.jobs, cost=cost,
                    describe=lambda run, r: f"max|CL| {np.abs(r['CL']).max():.4f}")
    curves = {}
    for s in chosen:
        ref, runs = res[run_of(s, s.reference)], [res[run_of(s, v)] for v in s.values]
        if "error" in ref or any("error" in r for r in runs):
            print(f"\n{s.scene}: {s.label}: not computed, a run failed")
            continue
        errors = [cl_error_pct(r["t"], r["CL"], ref["t"], ref["CL"]) for r in runs]
        late = None if s.late is None else [cl_error_pct(r["t"], r["CL"], ref["t"], ref["CL"], after=s.late) for r in runs]
        curves.setdefault(s.scene, []).append((s, errors, late))
        name = "all wake (no truncation)" if s.reference == "all" else f"{s.parameter} = {s.reference}"
        print(f"\n{s.scene}: {s.label}, reference {name} ({ref['wall_s']:.1f} s, max|CL_ref| = "
              f"{np.abs(ref['CL']).max():.4f}); error < 1 % from {s.parameter} = {converged_from(s.values, errors)}")
        print(f"| {s.parameter} | " + " | ".join(str(v) for v in s.values) + " |\n|---|" + "---|" * len(s.values))
        print("| error (%) | " + " | ".join(f"{e:.3g}" for e in errors) + " |")
        if late is not None:
            print(f"| after t = {s.late:.3g} s (%) | " + " | ".join(f"{e:.3g}" for e in late) + " |")
        print("| run (s) | " + " | ".join(f"{r['wall_s']:.1f}" for r in runs) + " |")
    if not args.no_plots and not args.quick:
        for scene, scene_curves in curves.items():
            plot(scene, scene_curves)


if __name__ == "__main__":
    main()
