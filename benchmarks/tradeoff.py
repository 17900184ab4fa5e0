"""Trade study of the flexible deployment: error against cost of every structure, aero and coupling choice,
with the Pareto front, and the convergence findings of Otsuka et al. 2019 (Sec. VII.A) with our numbers.

    python benchmarks/tradeoff.py [--quick] [--jobs 2] [--resume] [--no-plots] [--speeds 10 20] [--stop 0.3]
                                  [--cost wall|cpu]

scenes/deploy_flexible.toml as shipped is the base; one factor at a time is changed (FACTORS, levels from
the least to the most accurate), plus the most accurate run (every factor at its last level). Errors
(orchestrator.studies.metrics) are against the most accurate run of the same speed, and within each factor against
its own most accurate level; the report (templates/tradeoff.md) defines them. --cost cpu draws the Pareto
fronts against CPU time instead of wall time. --quick: time.stop 0.05 s, 10 m/s, QUICK_FACTORS. Speeds or
a stop other than the defaults write to results/studies/tradeoff/.
"""
import math
import time
from dataclasses import dataclass, fields, replace

import numpy as np
from report import RECORDS, Report, fmt, ratio, status

from orchestrator.studies import metrics
from orchestrator.scene.load import load_scene

REPORT = Report("tradeoff", __doc__)
SCENE = REPORT.root / "scenes" / "deploy_flexible.toml"
RIGID_SCENE = REPORT.root / "scenes" / "deploy_rigid.toml"   # where the rigid fidelity's integrator and step come from
SPEEDS = (10.0, 20.0)          # m/s
STOP = 0.3                     # s, time.stop: the wing latches at about 0.17 s (10 m/s) and 0.20 s (20 m/s)
QUICK_STOP = 0.05              # s
CL_WINDOW = 0.2                # s, Otsuka et al. 2019, Sec. VII.A: the CL error over the history 0-0.2 s
LIMIT = 1.0                    # %, the convergence criterion of Otsuka et al. 2019
ERROR_FLOOR = 1e-4             # %, errors below it are drawn at it on the log axes of the convergence figure
FLAT_VS_FREE_PAPER = 95.0      # %, Otsuka et al. 2019, Sec. VII.A: the flat wake's time 95% shorter than the free's
PAPER_CHOICE = {"L_w": 5, "M": 2, "N": 7}   # Otsuka et al. 2019, Sec. VII.A, for the deployment
FACTORS = {                    # levels from the least to the most accurate
    "structure": ("rigid", 3, "strain-based 7", 7, "strain-based 15", 15),
    "h": (5e-4, 2e-4, 1e-4),   # generalized-alpha step of the flexible structure (the report says why)
    "aero": ("none", "strip", "uvlm-flat", "uvlm-prescribed", "uvlm-free"),
    "M": (1, 2, 3, 4),
    "N": tuple(range(1, 11)),
    "L_w": tuple(range(1, 11)),
    "step": (5e-3, 2e-3, 1e-3, 5e-4),
    "algorithm": ("jacobi", "gauss-seidel", "implicit"),
}
LEVEL_STEP = {15: 1e-4}        # s, structure levels that need a smaller step h than the base's: with 15 elements per
                               # body and h = 2e-4 s generalized-alpha's Newton diverges at the first coupled step
STRAIN = "strain-based "       # a structure level "strain-based <n>": the strain-based fidelity, n elements per body
QUICK_FACTORS = {              # the paper's choices L_w = 5, M = 2, N = 7 below the finest level, as in FACTORS
    "structure": ("rigid", "strain-based 7", 7), "h": (2e-4, 1e-4), "aero": ("none", "strip", "uvlm-flat"),
    "M": (1, 2, 3), "N": (3, 7, 10), "L_w": (2, 5, 10), "step": (2e-3, 1e-3), "algorithm": ("gauss-seidel", "implicit"),
}
COSTS = {"wall": ("wall_s", "run wall time"), "cpu": ("cpu_s", "run CPU time")}   # --cost: row key, axis label
FACTOR_NAMES = {"structure": "structure fidelity", "h": "structure step h", "aero": "aero model",
                "M": "chordwise panels M", "N": "spanwise panels N", "L_w": "wake length L_w (chords)",
                "step": "coupling step", "algorithm": "coupling algorithm"}
METRICS = {"deploy": "deployment time", "bend": "peak bending", "cl": "CL (Otsuka et al. 2019, Eq. 28)"}
FIGURES = {"deploy": "deployment", "bend": "bending", "cl": "cl"}
COLORS = dict(zip(FACTORS, ("tab:red", "tab:pink", "tab:blue", "tab:green", "tab:olive", "tab:purple",
                            "tab:orange", "tab:brown")))


@dataclass(frozen=True)
class Setting:
    """One point of the design space: structure "rigid", elements per body (ANCF) or "strain-based <n>", the
    deformable structure's step h
    (s), aero.model, M x N panels per body, L_w (chords), coupling step (s), coupling algorithm."""
    structure: object
    h: float
    aero: str
    M: int
    N: int
    L_w: float
    step: float
    algorithm: str

    def overrides(self):
        """The scene overrides (--set) of this setting."""
        out = [f"aero.model={self.aero}", f"aero.chordwise_panels={self.M}", f"aero.spanwise_panels={self.N}",
               f"aero.wake_length={self.L_w!r}", f"coupling.step={self.step!r}", f"coupling.algorithm={self.algorithm}"]
        if self.structure == "rigid":
            integrator, step = rigid_integrator()
            return out + ["structure.fidelity=rigid", f"structure.integrator={integrator}", f"structure.step={step!r}"]
        fidelity, elements = structure_level(self.structure)
        return out + [f"structure.fidelity={fidelity}", f"structure.elements_per_body={elements}",
                      f"structure.step={self.h!r}"]

    def text(self):
        """The setting in words."""
        fidelity, elements = structure_level(self.structure)
        structure = ("rigid" if self.structure == "rigid" else
                     f"{fidelity}, {elements} elements per body, h = {1e3 * self.h:g} ms")
        return (f"{structure}, {self.aero} M = {self.M}, N = {self.N} per body, L_w = {self.L_w:g} chords, "
                f"{self.algorithm} coupling every {1e3 * self.step:g} ms")


@dataclass(frozen=True)
class Job:
    """One run: `setting` at flow.speed = `speed` (m/s) until time.stop = `stop` (s)."""
    setting: Setting
    speed: float
    stop: float


def structure_level(level):
    """(structure.fidelity, elements per body) of a structure level: "rigid", n (ANCF) or "strain-based <n>"."""
    if level == "rigid":
        return "rigid", 1
    if isinstance(level, str):
        return "strain-based", int(level.removeprefix(STRAIN))
    return "flexible", level


def rigid_integrator():
    """(structure.integrator, structure.step in s) of scenes/deploy_rigid.toml, used for the rigid level."""
    structure = load_scene(RIGID_SCENE)["structure"]
    return structure["integrator"], structure["step"]


def base_setting():
    """The Setting of scenes/deploy_flexible.toml as shipped."""
    scene = load_scene(SCENE)
    structure, aero, coupling = scene["structure"], scene["aero"], scene["coupling"]
    fidelity = "rigid" if structure["fidelity"] == "rigid" else structure["elements_per_body"]
    return Setting(fidelity, structure["step"], aero["model"], aero["chordwise_panels"], aero["spanwise_panels"],
                   aero["wake_length"], coupling["step"], coupling["algorithm"])


def level_text(factor, level):
    """A level as the tables write it, e.g. "rigid", "15 elements/body", "M = 3", "step 0.5 ms"."""
    if factor == "structure":
        fidelity, elements = structure_level(level)
        return {"rigid": "rigid", "flexible": f"{elements} elements/body"}.get(fidelity,
                                                                              f"{elements} strain-based elements/body")
    if factor in ("M", "N", "L_w"):
        return f"{factor} = {level:g}"
    if factor in ("step", "h"):
        return f"step {1e3 * level:g} ms" if factor == "step" else f"h = {1e3 * level:g} ms"
    return str(level)


def with_level(base, name, level):
    """`base` with one factor at `level` (a structure level in LEVEL_STEP also takes its step h)."""
    setting = replace(base, **{name: level})
    if name == "structure" and level in LEVEL_STEP:
        setting = replace(setting, h=min(base.h, LEVEL_STEP[level]))
    return setting


def changed(setting, base):
    return [f.name for f in fields(Setting) if getattr(setting, f.name) != getattr(base, f.name)]


def label(setting, base, best):
    """"base", "most accurate", or the levels in which `setting` differs from `base`."""
    if setting in (base, best):
        return "base" if setting == base else "most accurate"
    return ", ".join(level_text(f, getattr(setting, f)) for f in changed(setting, base))


def factor_of(setting, base):
    """The factor in which `setting` differs from `base` ("base", or "all" for several); a structure level with
    its LEVEL_STEP counts as the structure factor."""
    names = changed(setting, base)
    if names == ["structure", "h"] and setting == with_level(base, "structure", setting.structure):
        return "structure"
    return names[0] if len(names) == 1 else ("base" if not names else "all")


def cost(job):
    """Rough relative cost of a run, to start the longest first: structure work (elements) plus aero work per
    coupling step (wake and panels), times the implicit coupling's iterations (about 5)."""
    s = job.setting
    fidelity, elements = structure_level(s.structure)
    structure = 0.2 if fidelity == "rigid" else elements / 7 * 1e-4 / s.h * (3 if fidelity == "strain-based" else 1)
    wake = {"uvlm-prescribed": 1.0, "uvlm-free": 5.0 * s.L_w / 5}.get(s.aero, 0.1)
    aero = wake * s.M * s.N / 14 * (1e-3 / s.step) ** (2 if s.aero == "uvlm-free" else 1)
    return (structure + aero) * (5 if s.algorithm == "implicit" else 1)


def warm_up():
    """Import the units in a worker before its first run, so that no run's wall or CPU time includes them."""
    import fmu_common.topology  # noqa: F401
    import orchestrator.run.units  # noqa: F401


def work(job):
    """A run's deployment time (s), peak bending (mm), its (time (s), CL) history and its CPU time (s)."""
    from orchestrator.run.master import run_scene
    from orchestrator.output.results import summarize

    cpu = time.process_time()
    result = run_scene(load_scene(SCENE, [f"time.stop={job.stop!r}", f"flow.speed={job.speed!r}",
                                          *job.setting.overrides()]), backend="direct")
    series = result.series
    return {"status": result.status, "message": result.message, "wall_s": result.wall_time_s,
            "simulated_s": result.simulated_time_s, "deploy_s": summarize(result)["deployment_time_s"],
            "bend_mm": 1e3 * metrics.peak_displacement(series, "bending_100mm", "y") if len(series) else None,
            "cl": (series.time, series.CL if series.has_aero else np.zeros(len(series))),   # no aero: no lift
            "cpu_s": time.process_time() - cpu}


# ---- errors, fronts, convergence ---------------------------------------------------------------------------
def errors(row, ref):
    """{metric: error (%)} of a run against a reference run; None where either did not finish."""
    if row["status"] != "ok" or ref is None or ref["status"] != "ok":
        return dict.fromkeys(METRICS)
    (t, cl), (t_ref, cl_ref) = row["cl"], ref["cl"]
    return {"deploy": metrics.relative_error_pct(row["deploy_s"], ref["deploy_s"]),
            "bend": metrics.relative_error_pct(row["bend_mm"], ref["bend_mm"]),
            "cl": metrics.cl_error_pct(t, cl, t_ref, cl_ref, until=CL_WINDOW)}


def analyse(jobs, res, base, best, key):
    """Per job: errors against the most accurate run of its speed ("err"), wall and CPU time / base ("ratio",
    "cpu_ratio"); per (speed, metric): the Pareto front [Job] in error against cost `key` (wall_s | cpu_s)."""
    out, fronts = {}, {}
    for speed in sorted({j.speed for j in jobs}):
        here = [j for j in jobs if j.speed == speed]
        ref = res.get(next((j for j in here if j.setting == best), None))
        base_row = res[next(j for j in here if j.setting == base)]
        for j in here:
            ran = res[j]["wall_s"] is not None and base_row["wall_s"] is not None    # no ratio of a raised run
            out[j] = {"err": errors(res[j], ref), "ratio": ratio(res[j]["wall_s"], base_row["wall_s"]),
                      "cpu_ratio": ratio(res[j]["cpu_s"], base_row["cpu_s"]) if ran else None}
        for m in METRICS:
            fronts[(speed, m)] = metrics.pareto_front((res[j][key], out[j]["err"][m], j) for j in here
                                                      if out[j]["err"][m] is not None and res[j][key] is not None)
    return out, fronts


def convergence(jobs, res, factors, base, key):
    """{(factor, speed): [(level, errors against the factor's most accurate level (%), cost / base)]}: the
    paper's convergence tests, one factor varied from the base."""
    out = {}
    for speed in sorted({j.speed for j in jobs}):
        runs = {j.setting: res[j] for j in jobs if j.speed == speed}
        for name, levels in factors.items():
            ref = runs.get(with_level(base, name, levels[-1]))
            out[(name, speed)] = [(level, errors(runs[with_level(base, name, level)], ref),
                                   ratio(runs[with_level(base, name, level)][key], runs[base][key]))
                                  for level in levels[:-1]]
    return out


def within_from(rows, metric, finest):
    """The least accurate level from which on every level's error of `metric` is below LIMIT % (`finest` if the
    next coarser one is not; a failed run counts as not within), or None when no level has an error."""
    if all(e[metric] is None for _, e, _ in rows):
        return None
    found = metrics.converged_from([level for level, _, _ in rows],
                                   [math.inf if e[metric] is None else e[metric] for _, e, _ in rows], LIMIT)
    return finest if found is None else found


def saving(cheap, costly):
    """(wall, CPU) time saving of run `cheap` over run `costly`, % (100 (1 - cheap / costly)), or None."""
    if cheap is None or costly is None or cheap["status"] != "ok" or costly["status"] != "ok":
        return None
    return 100 * (1 - cheap["wall_s"] / costly["wall_s"]), 100 * (1 - cheap["cpu_s"] / costly["cpu_s"])


# ---- figures ------------------------------------------------------------------------------------------------
def plot_fronts(jobs, res, ana, fronts, names, base, cost_key):
    """tradeoff_<metric>.png, one panel per speed: error (%) against cost (s), log-log, every run a labelled
    point coloured by its factor (filled on the Pareto front), the front a step line; an error of 0 (the most
    accurate run) drawn as a triangle at a third of the smallest other error."""
    key, xlabel = COSTS[cost_key]
    speeds = sorted({j.speed for j in jobs})
    for metric, name in FIGURES.items():
        fig, axes = REPORT.figure(1, len(speeds), 7.5 * len(speeds), 6.5)
        for ax, speed in zip(axes[0], speeds):
            front = fronts[(speed, metric)]
            here = [j for j in jobs if j.speed == speed and ana[j]["err"][metric] is not None and res[j][key]]
            floor = min((ana[j]["err"][metric] for j in here if ana[j]["err"][metric] > 0), default=1.0) / 3
            y = {j: max(ana[j]["err"][metric], floor) for j in here}
            for j in here:
                color = COLORS.get(factor_of(j.setting, base), "k")
                ax.plot(res[j][key], y[j], "o" if y[j] > floor else "v", ms=4, color=color,
                        mfc=color if j in front else "none")
                ax.annotate(names[j.setting], (res[j][key], y[j]), fontsize=5, color=color, xytext=(3, 2),
                            textcoords="offset points")
            if front:
                ax.step([res[j][key] for j in front], [y[j] for j in front], where="post", color="k", lw=0.8,
                        label="Pareto front")
            for factor, color in COLORS.items():
                ax.plot([], [], "o", ms=4, color=color, label=FACTOR_NAMES[factor])
            ax.set(xscale="log", yscale="log", xlabel=f"{xlabel} (s)", ylabel=f"{METRICS[metric]} error (%)",
                   title=f"{speed:g} m/s")
            ax.axhline(LIMIT, color="0.5", lw=0.6, ls="--")
            ax.legend(fontsize=6, loc="lower left")       # cheap and accurate: the corner no run reaches
        fig.suptitle(f"deploy_flexible: {METRICS[metric]} error against the most accurate run\n(filled: on the "
                     "Pareto front; triangle: error 0, drawn below the others; dashed: 1%)", fontsize=8)
        REPORT.save(fig, f"tradeoff_{name}")


def plot_convergence(conv, factors):
    """tradeoff_convergence.png: per factor, the errors (%) of its levels against its most accurate level;
    colour by metric, line style by speed."""
    cols = math.ceil(len(factors) / 2)
    fig, axes = REPORT.figure(2, cols, 3.3 * cols, 6.4)
    colors = {"deploy": "tab:blue", "bend": "tab:orange", "cl": "tab:green"}
    lines = dict(zip(sorted({speed for _, speed in conv}), ("o-", "s--", "^:", "d-.")))
    for ax, name in zip(axes.flat, factors):
        for (factor, speed), rows in conv.items():
            for m, color in colors.items():
                if factor == name:
                    ax.plot(range(len(rows)), [np.nan if e[m] is None else max(e[m], ERROR_FLOOR) for _, e, _ in rows],
                            lines.get(speed, "o-"), color=color, ms=3, lw=0.8, label=f"{METRICS[m]}, {speed:g} m/s")
        ticks = [level_text(name, v).replace(" elements/body", " el.") for v in factors[name][:-1]]
        ax.set_xticks(range(len(ticks)), ticks, fontsize=6, rotation=30)
        ax.set_yscale("log")
        ax.axhline(LIMIT, color="k", lw=0.6, ls="--")
        ax.set_title(f"{FACTOR_NAMES[name]}: against {level_text(name, factors[name][-1])}", fontsize=7)
        ax.set_ylabel("error (%)", fontsize=7)
    for ax in list(axes.flat)[len(factors):]:
        ax.set_visible(False)
    axes.flat[0].legend(fontsize=5)
    fig.suptitle("deploy_flexible: each factor against its own most accurate level, the others at base "
                 "(dashed: 1%)", fontsize=8)
    REPORT.save(fig, "tradeoff_convergence")


def main(argv=None):
    args = REPORT.arguments(argv, **{
        "--speeds": {"type": float, "nargs": "+", "help": "flow speeds, m/s (default 10 20; --quick: 10)"},
        "--stop": {"type": float, "help": f"time.stop, s (default {STOP:g}; --quick: {QUICK_STOP:g})"},
        "--cost": {"choices": COSTS, "default": "wall", "help": "the cost of the Pareto fronts: wall or CPU time"}})
    factors = QUICK_FACTORS if args.quick else FACTORS
    speeds = tuple(args.speeds or ((10.0,) if args.quick else SPEEDS))
    stop = args.stop or (QUICK_STOP if args.quick else STOP)
    if not args.quick and (speeds, stop) != (SPEEDS, STOP):
        REPORT.out = RECORDS / "tradeoff"
    base, best = base_setting(), replace(base_setting(), **{n: levels[-1] for n, levels in factors.items()})
    settings = [base] + [with_level(base, n, level) for n, levels in factors.items() for level in levels] + [best]
    jobs = [Job(s, v, stop) for v in speeds for s in dict.fromkeys(settings)]
    names = {j.setting: label(j.setting, base, best) for j in jobs}
    describe = lambda j, r: f"{r['status']}, deployment {fmt(r['deploy_s'], '.4f')} s, run {r['wall_s']:.1f} s"
    res = REPORT.run(jobs, work, cost=cost, initializer=warm_up, describe=describe)
    res = {j: r if "error" not in r else {"status": "error", "message": r["error"], "wall_s": None, "cpu_s": None,
                                          "deploy_s": None, "bend_mm": None, "cl": None} for j, r in res.items()}
    key = COSTS[args.cost][0]
    ana, fronts = analyse(jobs, res, base, best, key)
    conv = convergence(jobs, res, factors, base, key)
    if not args.no_plots:
        plot_fronts(jobs, res, ana, fronts, names, base, args.cost)
        plot_convergence(conv, factors)
    integrator, rigid_step = rigid_integrator()
    REPORT.render(runs=len(jobs), jobs=jobs, res=res, ana=ana, fronts=fronts, conv=conv, names=names, factors=factors,
                  base=base, best=best, stop=stop, window=min(CL_WINDOW, stop), cost_key=key, speeds=sorted(speeds),
                  cost_name=COSTS[args.cost][1].removeprefix("run "), rigid_integrator=integrator,
                  rigid_step=rigid_step, structure=load_scene(SCENE)["structure"],
                  finest_step=1e3 * min(factors["step"]),
                  METRICS=METRICS, FIGURES=FIGURES, FACTOR_NAMES=FACTOR_NAMES, LIMIT=LIMIT, PAPER_CHOICE=PAPER_CHOICE,
                  FLAT_VS_FREE_PAPER=FLAT_VS_FREE_PAPER, level_text=level_text, factor_of=factor_of,
                  within_from=within_from, saving=saving, errors=errors, with_level=with_level, replace=replace,
                  status=status)
    failed = [f"{names[j.setting]} at {j.speed:g} m/s" for j in jobs if res[j]["status"] != "ok"]
    return REPORT.finish(failed, len(jobs))


if __name__ == "__main__":
    raise SystemExit(main())
