"""Convergence of the lift coefficient with the wake length L_w, the chordwise panels M and the spanwise
panels N: the curves of Otsuka et al. 2019, Sec. VII.A (Eqs. 28-30, Fig. 12).

    python benchmarks/convergence.py [--quick] [--jobs 2] [--resume] [--no-plots] [--scenes heaving_wing deploy_rigid]

One parameter varied at a time; the error of a run against its reference is orchestrator.studies.metrics.cl_error_pct
over the communication points after t = 0 (every run's time grid is a subset of its reference's).
heaving_wing (Otsuka et al. 2019, Sec. VI.D; the scene's M = 10, N = 5, L_w = 25, step 0.1 s = c/(M V),
three periods): L_w = 1 ... 30 against the whole wake (aero.wake_length = inf); M = 1 ... 20 against M = 20
at the fixed step and with the step c/(M V); N = 1 ... 20 against N = 40. deploy_rigid at 15 m/s (the
paper's case, Fig. 12: uvlm-free, 0-0.2 s): L_w (M = N = 1) against the whole wake, M (N = 1, L_w = 5)
against M = 10, N (M = 1, L_w = 5) against N = 10. Prints a table per curve and writes
docs/img/convergence_<scene>.png (the paper's choices L_w = 5, M = 2, N = 7 dotted).
"""
from dataclasses import dataclass

import numpy as np
from report import Report, table

from orchestrator.studies.metrics import cl_error_pct, converged_from

REPORT = Report("convergence", __doc__, Report.root / "docs")
PAPER_CHOICE = {"L_w": 5, "M": 2, "N": 7}          # Otsuka et al. 2019, Sec. VII.A, for the deployment
T = 4 * np.pi                                      # s, the heaving wing's period (omega = 0.5 rad/s)
LABELS = {"L_w": "wake length L_w (chords)", "M": "chordwise panels M", "N": "spanwise panels N"}


@dataclass(frozen=True)
class Curve:
    """One convergence curve: `values` of `parameter` against the reference value `reference` ("all": no wake
    truncation), each run with the `base` overrides and the parameter's."""
    scene: str
    parameter: str                 # "L_w" | "M" | "N"
    label: str
    base: tuple
    values: tuple
    reference: object
    step_per_panel: bool = False   # coupling.step = c / (M V) (heaving wing: 1 / M s)
    late: float | None = None      # also the error over t > late (s): without the start transient

    def run(self, value):
        """The Run of one value of the curve."""
        if self.parameter == "L_w":
            return Run(self.scene, self.base, whole_wake=True) if value == "all" else \
                Run(self.scene, (*self.base, f"aero.wake_length={value}"))
        if self.parameter == "N":
            return Run(self.scene, (*self.base, f"aero.spanwise_panels={value}"))
        step = (f"coupling.step={1.0 / value!r}",) if self.step_per_panel else ()
        return Run(self.scene, (*self.base, f"aero.chordwise_panels={value}", *step))


@dataclass(frozen=True)
class Run:
    """One run: the scene (file stem) with `overrides`, and aero.wake_length = inf if `whole_wake`. Its repr
    keys its record."""
    scene: str
    overrides: tuple
    whole_wake: bool = False

    @property
    def label(self):
        return f"{self.scene} {' '.join(self.overrides)}"

    def load(self):
        from orchestrator.scene.load import load_scene

        whole = ["aero.wake_length=inf"] if self.whole_wake else []
        return load_scene(REPORT.root / "scenes" / f"{self.scene}.toml", [*self.overrides, *whole])


def curves(quick=False):
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


def cost(run):
    """Rough cost of a run (steps x bound panels x wake panels), to start the longest runs first."""
    scene = run.load()
    aero, step = scene["aero"], scene["coupling"]["step"]
    steps = scene["time"]["stop"] / step
    rows = min(steps, aero["wake_length"] / max(scene["flow"]["speed"] * step, 1e-12))
    return steps * aero["chordwise_panels"] * aero["spanwise_panels"] ** 2 * (rows + aero["chordwise_panels"])


def work(run):
    """The run's times (s), CL and wall time (s); an error unless the run ended ok."""
    from orchestrator.run.master import run_scene

    result = run_scene(run.load(), backend="direct")
    if result.status != "ok":
        raise RuntimeError(f"{result.status}: {result.message}")
    return {"t": result.series.time, "CL": result.series.CL, "wall_s": result.wall_time_s}


def plot(scene, done):
    """docs/img/convergence_<scene>.png: one panel per parameter, CL error (%) against its values."""
    from matplotlib.ticker import NullFormatter

    parameters = [p for p in ("L_w", "M", "N") if any(c.parameter == p for c, _, _ in done)]
    fig, (axes,) = REPORT.figure(1, len(parameters), 3.4 * len(parameters), 3.0)
    for ax, parameter in zip(axes, parameters):
        for curve, errors, late in (d for d in done if d[0].parameter == parameter):
            ref = "all wake" if curve.reference == "all" else f"{parameter} = {curve.reference}"
            line, = ax.semilogy(curve.values, np.maximum(errors, 1e-4), "o-", ms=3, label=f"{curve.label}\nref. {ref}")
            if late is not None:
                ax.semilogy(curve.values, np.maximum(late, 1e-4), "o--", ms=3, mfc="none", color=line.get_color(),
                            label=f"  same, t > {curve.late:.3g} s")
        ax.axhline(1.0, color="k", lw=0.6, ls="--")
        ax.axvline(PAPER_CHOICE[parameter], color="0.5", lw=0.8, ls=":")
        ax.set_xlabel(LABELS[parameter], fontsize=8)
        ax.set_ylabel("CL error (%)", fontsize=8)
        ax.tick_params(labelsize=7)
        ax.yaxis.set_minor_formatter(NullFormatter())
    fig.suptitle(f"{scene}: CL error RMS(CL - CL_ref) / max|CL_ref| (Otsuka et al. 2019, Eqs. 28-30); "
                 "black dashed: 1 %, dotted: the paper's choice", fontsize=8)
    REPORT.save(fig, f"convergence_{scene}", dpi=90, legend=6)


def main(argv=None):
    args = REPORT.arguments(argv, **{"--scenes": {"nargs": "+", "default": ["heaving_wing", "deploy_rigid"]}})
    chosen = [c for c in curves(args.quick) if c.scene in args.scenes]
    res = REPORT.run([c.run(v) for c in chosen for v in (*c.values, c.reference)], work, cost=cost,
                     describe=lambda run, r: f"max|CL| {np.abs(r['CL']).max():.4f}")
    done = {}
    for c in chosen:
        ref, runs = res[c.run(c.reference)], [res[c.run(v)] for v in c.values]
        if "error" in ref or any("error" in r for r in runs):
            print(f"\n{c.scene}: {c.label}: not computed, a run failed")
            continue
        errors = [cl_error_pct(r["t"], r["CL"], ref["t"], ref["CL"]) for r in runs]
        late = None if c.late is None else [cl_error_pct(r["t"], r["CL"], ref["t"], ref["CL"], after=c.late)
                                            for r in runs]
        done.setdefault(c.scene, []).append((c, errors, late))
        name = "all wake (no truncation)" if c.reference == "all" else f"{c.parameter} = {c.reference}"
        print(f"\n{c.scene}: {c.label}, reference {name} ({ref['wall_s']:.1f} s, max|CL_ref| = "
              f"{np.abs(ref['CL']).max():.4f}); error < 1 % from {c.parameter} = {converged_from(c.values, errors)}")
        rows = [["error (%)", *(f"{e:.3g}" for e in errors)]]
        rows += [] if late is None else [[f"after t = {c.late:.3g} s (%)", *(f"{e:.3g}" for e in late)]]
        print(table([c.parameter, *map(str, c.values)], rows + [["run (s)", *(f"{r['wall_s']:.1f}" for r in runs)]]))
    if not args.no_plots and not args.quick:
        for scene, scene_curves in done.items():
            plot(scene, scene_curves)


if __name__ == "__main__":
    main()
