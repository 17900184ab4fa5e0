"""Trade study of the flexible deployment: error against wall time of every structure, aero and coupling
choice, with the Pareto front, and 000's convergence findings (Sec. VII.A) restated with our numbers.

    python benchmarks/tradeoff.py [--quick] [--jobs 2] [--speeds 10 20] [--stop 0.3] [--cost wall|cpu]
                                  [--no-plots]

What runs: scenes/deploy_flexible.toml as shipped (the "base": flexible, 7 elements per body, generalized-
alpha structure.step h, uvlm-flat M = 2, N = 7 per body, L_w = 5 chords, Gauss-Seidel coupling every 1 ms) at
flow.speed = 10 and 20 m/s, time.stop = 0.3 s, each run `orchestrator.master.run_scene(scene,
backend="direct")` (what `wingsim run scenes/deploy_flexible.toml --backend direct --set ...` runs), in
`--jobs` processes with one BLAS thread each. One factor at a time is changed from the base (levels from
the least to the most accurate; FACTORS):

  structure   rigid (structure.fidelity = rigid with scenes/deploy_rigid.toml's integrator and step, RK4:
              the rigid fidelity has no damping and needs no small step), flexible 3, 7, 15 elements per body
  h           the flexible structure's generalized-alpha step structure.step: 0.5, 0.2, 0.1 ms. Not a factor
              of the issue: added so that the most accurate run keeps h = 1e-4 s, the step of the structure's
              validation (docs/structure.md), whatever step the scene ships with (the solver speed-up work is
              moving it to 2e-4 s), and so that the scene's step is measured like the other choices
  aero        none, strip, uvlm-flat, uvlm-prescribed, uvlm-free (aero.model)
  M, N        chordwise panels 1-4, spanwise panels 1-10 per body
  L_w         wake length 1-10 chords
  step        coupling step 5, 2, 1, 0.5 ms (also the aero time step: one aero step per coupling step)
  algorithm   jacobi, gauss-seidel, implicit (Aitken, tolerance 1e-6, the scene defaults)

plus the most accurate run: every factor at its most accurate level (15 elements, h = 0.1 ms, uvlm-free,
M = 4, N = 10, L_w = 10, implicit coupling every 0.5 ms). Per speed, every run's errors are against the most
accurate run (%):

  deployment time   |t_d - t_d,ref| / t_d,ref, t_d = summary deployment_time_s (the structure unit's latch
                    time, found within its internal step);
  bending           |D - D_ref| / D_ref, D = max over the run of |y displacement| of probe bending_100mm
                    (benchmarks/deployment.py's peak bending, 000 Fig. 15);
  CL                RMS(CL - CL_ref) / max|CL_ref| over 0 < t <= 0.2 s (000 Eqs. 28-30, 0-0.2 s as 000;
                    benchmarks/convergence.cl_error); aero.model = none has no lift: CL = 0.

and each factor's levels are also compared with that factor's most accurate level, the others at base
(000's convergence tests, where its "L_w = 5, M = 2, N = 7 each within 1%" is checked). Cost is the run's
wall_time_s (from unit start-up to the end of the run), also as a ratio to the base run of the same speed,
and the worker's CPU time. The Pareto front (per speed and metric) is the set of runs no other run beats in
both wall time and error.

--quick: time.stop = 0.05 s (unless --stop), 10 m/s (unless --speeds), two or three levels per factor
(QUICK_FACTORS; its most accurate run is the finest of those): a smoke test of the whole pipeline, writing
the doc and figures into results/tradeoff_quick/. A full run (default speeds and stop) writes
docs/tradeoff.md and, unless --no-plots, docs/img/tradeoff_{deployment,bending,cl,convergence}.png; other
--speeds or --stop write them into results/tradeoff/. The raw numbers of every run go to
results/tradeoff[_quick]/runs.json (not committed). --cost cpu draws the fronts against CPU time instead of
wall time (on a loaded machine the wall time of a run can be several times its CPU time).
"""
import argparse
import json
import math
import os
import sys
import time
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import asdict, dataclass, fields, replace

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):   # one BLAS thread per process
    os.environ.setdefault(_var, "1")

from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from benchmarks.convergence import PAPER_CHOICE, below, cl_error  # noqa: E402
from benchmarks.deployment import fmt, metrics, status, table  # noqa: E402
from orchestrator.master import run_scene  # noqa: E402
from orchestrator.scene import load_scene  # noqa: E402

SCENE = ROOT / "scenes" / "deploy_flexible.toml"
RIGID_SCENE = ROOT / "scenes" / "deploy_rigid.toml"     # where the rigid fidelity's integrator and step come from
DOCS = ROOT / "docs"
SPEEDS = (10.0, 20.0)          # m/s
STOP = 0.3                     # s, time.stop: the wing latches at about 0.17 s (10 m/s) and 0.20 s (20 m/s)
QUICK_STOP = 0.05              # s
CL_WINDOW = 0.2                # s, 000 Sec. VII.A: the CL error over the history 0-0.2 s
LIMIT = 1.0                    # %, 000's convergence criterion
ERROR_FLOOR = 1e-4             # %, errors below it are drawn at it on the log axes of the convergence figure
FLAT_VS_FREE_000 = 95.0        # %, 000 Sec. VII.A: the flat wake's calculation time 95% shorter than the free's

FACTORS = {                    # levels from the least to the most accurate
    "structure": ("rigid", 3, 7, 15),
    "h": (5e-4, 2e-4, 1e-4),   # generalized-alpha step of the flexible structure (not in the issue: docstring)
    "aero": ("none", "strip", "uvlm-flat", "uvlm-prescribed", "uvlm-free"),
    "M": (1, 2, 3, 4),
    "N": tuple(range(1, 11)),
    "L_w": tuple(range(1, 11)),
    "step": (5e-3, 2e-3, 1e-3, 5e-4),
    "algorithm": ("jacobi", "gauss-seidel", "implicit"),
}
LEVEL_STEP = {15: 1e-4}        # s, structure levels that need a smaller step h than the base's: with 15 elements per
                               # body and h = 2e-4 s generalized-alpha's Newton diverges at the first coupled step
QUICK_FACTORS = {              # 000's choices L_w = 5, M = 2, N = 7 below the finest level, as in FACTORS
    "structure": ("rigid", 7), "h": (2e-4, 1e-4), "aero": ("none", "strip", "uvlm-flat"), "M": (1, 2, 3),
    "N": (3, 7, 10), "L_w": (2, 5, 10), "step": (2e-3, 1e-3), "algorithm": ("gauss-seidel", "implicit"),
}
COSTS = {"wall": ("wall_s", "run wall time"), "cpu": ("cpu_s", "run CPU time")}   # --cost: row key, axis label
FACTOR_NAMES = {"structure": "structure fidelity", "h": "structure step h", "aero": "aero model",
                "M": "chordwise panels M", "N": "spanwise panels N", "L_w": "wake length L_w (chords)",
                "step": "coupling step", "algorithm": "coupling algorithm"}
METRICS = {"deploy": "deployment time", "bend": "peak bending", "cl": "CL (000 Eq. 28)"}
FIGURES = {"deploy": "deployment", "bend": "bending", "cl": "cl"}
COLORS = dict(zip(FACTORS, ("tab:red", "tab:pink", "tab:blue", "tab:green", "tab:olive", "tab:purple",
                            "tab:orange", "tab:brown")))


@dataclass(frozen=True)
class Setting:
    """One point of the design space: structure "rigid" or elements per body, the flexible structure's step h
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
               f"aero.wake_length={self.L_w!r}", f"coupling.step={self.step!r}",
               f"coupling.algorithm={self.algorithm}"]
        if self.structure == "rigid":
            integrator, step = rigid_integrator()
            return out + ["structure.fidelity=rigid", f"structure.integrator={integrator}", f"structure.step={step!r}"]
        return out + ["structure.fidelity=flexible", f"structure.elements_per_body={self.structure}",
                      f"structure.step={self.h!r}"]


@dataclass(frozen=True)
class Job:
    """One run: `setting` at flow.speed = `speed` (m/s) until time.stop = `stop` (s)."""
    setting: Setting
    speed: float
    stop: float

    @property
    def overrides(self):
        return [f"time.stop={self.stop!r}", f"flow.speed={self.speed!r}", *self.setting.overrides()]


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


def finest(factors):
    """The most accurate Setting: every factor at its last level."""
    return Setting(**{name: levels[-1] for name, levels in factors.items()})


def level_text(factor, level):
    """A level as the table writes it, e.g. "rigid", "15 elements/body", "M = 3", "step 0.5 ms"."""
    if factor == "structure":
        return "rigid" if level == "rigid" else f"{level} elements/body"
    if factor in ("M", "N", "L_w"):
        return f"{factor} = {level:g}"
    if factor == "step":
        return f"step {1e3 * level:g} ms"
    if factor == "h":
        return f"h = {1e3 * level:g} ms"
    return str(level)


def label(setting, base, best):
    """"base", "most accurate", or the levels in which `setting` differs from `base`."""
    if setting == base:
        return "base"
    if setting == best:
        return "most accurate"
    changed = [f.name for f in fields(Setting) if getattr(setting, f.name) != getattr(base, f.name)]
    return ", ".join(level_text(f, getattr(setting, f)) for f in changed)


def factor_of(setting, base):
    """The factor in which `setting` differs from `base` ("base" for the base, "all" for several); a structure
    level with its LEVEL_STEP counts as the structure factor."""
    changed = [f.name for f in fields(Setting) if getattr(setting, f.name) != getattr(base, f.name)]
    if changed == ["structure", "h"] and setting == with_level(base, "structure", setting.structure):
        return "structure"
    return changed[0] if len(changed) == 1 else ("base" if not changed else "all")


def with_level(base, name, level):
    """`base` with one factor at `level` (a structure level in LEVEL_STEP also takes its step h)."""
    setting = replace(base, **{name: level})
    if name == "structure" and level in LEVEL_STEP:
        setting = replace(setting, h=min(base.h, LEVEL_STEP[level]))
    return setting


def plan(factors, base, speeds, stop):
    """[Job]: per speed the base, every factor's levels (one factor changed at a time) and the most accurate
    run, each distinct setting once, in table order."""
    settings = [base] + [with_level(base, name, level) for name, levels in factors.items() for level in levels]
    settings.append(finest(factors))
    return [Job(s, v, stop) for v in speeds for s in dict.fromkeys(settings)]


def estimated_cost(job):
    """Rough relative cost of a run, to start the longest first: structure work (elements) plus aero work per
    coupling step (wake and panels), times the implicit coupling's iterations (about 5)."""
    s = job.setting
    structure = 0.2 if s.structure == "rigid" else s.structure / 7 * 1e-4 / s.h
    wake = {"uvlm-prescribed": 1.0, "uvlm-free": 5.0 * s.L_w / 5}.get(s.aero, 0.1)
    aero = wake * s.M * s.N / 14 * (1e-3 / s.step) ** (2 if s.aero == "uvlm-free" else 1)
    return (structure + aero) * (5 if s.algorithm == "implicit" else 1)


# ---- running -------------------------------------------------------------------------------------------
def run_one(job):
    """benchmarks.deployment.metrics of one run (without its curves), its (time (s), CL) history and the CPU
    time `cpu_s` (s) of this process for it. A run that raises becomes an "error" row with the exception as
    its message; a failed run whose numbers cannot be read keeps its status and message."""
    cpu = time.process_time()
    try:
        result = run_scene(load_scene(SCENE, job.overrides), backend="direct")
    except Exception as err:                      # noqa: BLE001 - reported as a row, never dropped
        return {"status": "error", "message": f"{type(err).__name__}: {err}", "wall_s": None, "cl": None,
                "cpu_s": time.process_time() - cpu}
    try:
        row = {**metrics(result), "curves": None}
    except Exception as err:                      # noqa: BLE001 - e.g. no sample recorded
        row = {"status": result.status if result.status != "ok" else "error", "wall_s": result.wall_time_s,
               "message": result.message or f"{type(err).__name__}: {err}", "simulated_s": result.simulated_time_s}
    series = result.series
    cl = series.CL if series.has_aero else np.zeros(len(series))           # no aero: no lift
    return {**row, "cl": (series.time.copy(), np.array(cl, dtype=float)), "cpu_s": time.process_time() - cpu}


def warm_up():
    """Import the units and the structure's topology in a worker before its first run, so that no run's wall or
    CPU time includes them (run_scene imports them lazily)."""
    import orchestrator.units  # noqa: F401
    import structure_fmu.topology  # noqa: F401


def run_all(jobs, workers, names):
    """{Job: row} of all `jobs`, longest first, one progress line per finished run."""
    results, start = {}, time.perf_counter()
    with ProcessPoolExecutor(max_workers=max(1, workers), initializer=warm_up) as pool:
        futures = {pool.submit(run_one, job): job for job in sorted(jobs, key=estimated_cost, reverse=True)}
        for k, future in enumerate(as_completed(futures), 1):
            job, row = futures[future], future.result()
            results[job] = row
            print(f"[run {k} of {len(jobs)}, {time.perf_counter() - start:7.1f} s] {names[job.setting]} at "
                  f"{job.speed:g} m/s: {row['status']}, deployment {fmt(row.get('deploy_s'), '.4f')} s, "
                  f"run {fmt(row['wall_s'], '.1f')} s", flush=True)
    return results


# ---- errors and fronts ----------------------------------------------------------------------------------
def relative_error(value, ref):
    """|value - ref| / |ref| x 100 (%), or None."""
    return None if value is None or ref is None or ref == 0 else 100.0 * abs(value - ref) / abs(ref)


def cl_rms_error(run, ref, window=CL_WINDOW):
    """000 Eqs. (28)-(30) over 0 < t <= window (s): RMS(CL - CL_ref) / max|CL_ref| x 100 (%), with
    benchmarks.convergence.cl_error (CL_ref interpolated at the run's times); None without both histories."""
    if run is None or ref is None:
        return None
    (t, cl), (t_ref, cl_ref) = run, ref
    keep, keep_ref = t <= window + 1e-9, t_ref <= window + 1e-9
    if not (t_ref[keep_ref] > 0).any() or not np.abs(cl_ref[keep_ref]).max() > 0:
        return None
    return cl_error(t[keep], cl[keep], t_ref[keep_ref], cl_ref[keep_ref])


def errors(row, ref):
    """{metric: error (%)} of a run against a reference run; None where either did not finish."""
    if row["status"] != "ok" or ref is None or ref["status"] != "ok":
        return dict.fromkeys(METRICS)
    return {"deploy": relative_error(row.get("deploy_s"), ref.get("deploy_s")),
            "bend": relative_error(row.get("bend_mm"), ref.get("bend_mm")),
            "cl": cl_rms_error(row.get("cl"), ref.get("cl"))}


def pareto(points):
    """The keys of the non-dominated (cost, error, key) points: no other point is as cheap and as accurate
    with one of the two strictly better."""
    front, best = [], math.inf
    for cost, error, key in sorted(points, key=lambda p: (p[0], p[1])):
        if error < best:
            front.append(key)
            best = error
    return front


def analyse(jobs, res, base, best, cost):
    """Per job: errors against the most accurate run of its speed ("err"), wall and CPU time / base ("ratio",
    "cpu_ratio"); per (speed, metric): the Pareto front [Job] in error against `cost` ("wall_s" | "cpu_s")."""
    out, fronts = {}, {}
    for speed in sorted({j.speed for j in jobs}):
        here = [j for j in jobs if j.speed == speed]
        ref = res.get(next((j for j in here if j.setting == best), None))
        base_row = res[next(j for j in here if j.setting == base)]
        for j in here:
            ran = res[j]["wall_s"] is not None and base_row["wall_s"] is not None    # no ratio of a raised run
            out[j] = {"err": errors(res[j], ref), "ratio": ratio(res[j]["wall_s"], base_row["wall_s"]),
                      "cpu_ratio": ratio(res[j]["cpu_s"], base_row["cpu_s"]) if ran else None}
        for metric in METRICS:
            points = [(res[j][cost], out[j]["err"][metric], j) for j in here
                      if out[j]["err"][metric] is not None and res[j][cost] is not None]
            fronts[(speed, metric)] = pareto(points)
    return out, fronts


def convergence(jobs, res, factors, base, cost):
    """{(factor, speed): [(level, errors against the factor's most accurate level (%), cost / base)]}: 000's
    convergence tests, one factor varied from the base; `cost` is "wall_s" or "cpu_s"."""
    out = {}
    for speed in sorted({j.speed for j in jobs}):
        runs = {j.setting: res[j] for j in jobs if j.speed == speed}
        for name, levels in factors.items():
            ref = runs.get(with_level(base, name, levels[-1]))
            rows = []
            for level in levels[:-1]:
                row = runs[with_level(base, name, level)]
                rows.append((level, errors(row, ref), ratio(row[cost], runs[base][cost])))
            out[(name, speed)] = rows
    return out


def ratio(value, ref):
    """value / ref, or None."""
    return None if value is None or not ref else value / ref


def within_from(rows, metric, finest_level, limit=LIMIT):
    """The least accurate level from which on every level's error of `metric` against `finest_level` is below
    `limit` % (`finest_level` itself if the next coarser one is not; a level without an error, i.e. a failed
    run, counts as not within), or None when no level has an error (e.g. the finest level's run failed)."""
    if all(e[metric] is None for _, e, _ in rows):
        return None
    levels = [level for level, _, _ in rows]
    errs = [math.inf if e[metric] is None else e[metric] for _, e, _ in rows]
    found = below(levels, errs, limit)
    return finest_level if found is None else found


# ---- tables ---------------------------------------------------------------------------------------------
def pct(value):
    """An error (%) as a table cell."""
    return fmt(value, ".3g")


def pct_text(value):
    """An error (%) in a sentence: "0.123%", or "not computed"."""
    return "not computed" if value is None else f"{value:.3g}%"


def main_table(jobs, res, ana, fronts, names, base):
    """One row per run: speed, factor, variant, deployment time, bending, errors, wall, ratio, CPU, Pareto."""
    rows = []
    for j in jobs:
        r, a = res[j], ana[j]
        on = [METRICS[m].split(" (")[0] for m in METRICS if j in fronts[(j.speed, m)]]
        rows.append([f"{j.speed:g}", FACTOR_NAMES.get(factor_of(j.setting, base), factor_of(j.setting, base)),
                     names[j.setting],
                     fmt(r.get("deploy_s"), ".4f"), fmt(r.get("bend_mm"), ".2f"),
                     *(pct(a["err"][m]) for m in METRICS), fmt(r["wall_s"], ".1f"), fmt(a["ratio"], ".2f"),
                     fmt(r["cpu_s"], ".1f"), fmt(a["cpu_ratio"], ".2f"), ", ".join(on) or "-", status(r)])
    return table(["speed (m/s)", "factor", "variant", "deployment time (s)", "peak bending (mm)",
                  "deployment time error (%)", "bending error (%)", "CL error (%)", "run (s)", "run / base",
                  "CPU (s)", "CPU / base", "Pareto front of", "status"], rows)


def convergence_table(conv, name, factors, cost):
    """Rows per level and speed: errors against the factor's most accurate level (%), cost / base."""
    rows = [[level_text(name, level), f"{speed:g}", *(pct(e[m]) for m in METRICS), fmt(r, ".2f")]
            for (factor, speed), levels in conv.items() if factor == name for level, e, r in levels]
    return table([f"{FACTOR_NAMES[name]} (against {level_text(name, factors[name][-1])})", "speed (m/s)",
                  *(f"{METRICS[m]} error (%)" for m in METRICS), "run / base" if cost == "wall_s" else "CPU / base"],
                 rows)


def convergence_sentence(conv, name, factors):
    """Per speed: from which level on each metric stays below LIMIT % of the factor's finest level."""
    out = []
    for (factor, speed), rows in conv.items():
        if factor != name:
            continue
        parts = []
        for m in METRICS:
            level = within_from(rows, m, factors[name][-1])
            parts.append(f"{METRICS[m]} " + ("not computed" if level is None else level_text(name, level)))
        out.append(f"At {speed:g} m/s, the coarsest level from which on every level is within {LIMIT:g}% of "
                   f"{level_text(name, factors[name][-1])}: " + ", ".join(parts) + ".")
    return out


# ---- 000's findings --------------------------------------------------------------------------------------
def run_at(jobs, res, setting, speed):
    """The row of `setting` at `speed`, or None if it was not run."""
    job = next((j for j in jobs if j.setting == setting and j.speed == speed), None)
    return None if job is None else res[job]


def panel_findings(conv, factors):
    """000's L_w = 5, M = 2, N = 7 against our convergence errors (CL, %), per speed."""
    out = []
    for name, choice in PAPER_CHOICE.items():
        if name not in factors or choice not in factors[name][:-1]:
            continue
        for (factor, speed), rows in conv.items():
            if factor != name:
                continue
            e = next(e for level, e, _ in rows if level == choice)
            if e["cl"] is None:
                out.append(f"- {name} = {choice} at {speed:g} m/s: not computed (a run failed).")
                continue
            finest_level = factors[name][-1]
            verdict = f"within {LIMIT:g}%: confirmed" if e["cl"] < LIMIT else f"not within {LIMIT:g}%"
            first = within_from(rows, "cl", finest_level)
            reach = (f"no coarser level is within {LIMIT:g}%" if first == finest_level else
                     f"every level from {level_text(name, first)} on is within {LIMIT:g}%")
            out.append(f"- {name} = {choice} at {speed:g} m/s: CL error {e['cl']:.3g}% against "
                       f"{level_text(name, finest_level)} ({verdict}; {reach}); deployment time "
                       f"{pct_text(e['deploy'])}, bending {pct_text(e['bend'])}.")
    return out


def saving(cheap, costly):
    """(wall, CPU) time saving of run `cheap` over run `costly`, % (100 (1 - cheap / costly)), or None when
    either is missing or failed."""
    if cheap is None or costly is None or cheap["status"] != "ok" or costly["status"] != "ok":
        return None
    return 100 * (1 - cheap["wall_s"] / costly["wall_s"]), 100 * (1 - cheap["cpu_s"] / costly["cpu_s"])


def error_text(e, which=tuple(METRICS)):
    """"deployment time x%, peak bending y%, CL z%" of an errors dict, for the metrics `which`."""
    return ", ".join(f"{METRICS[m].split(' (')[0]} {pct_text(e[m])}" for m in which)


def wake_findings(jobs, res, ana, base, speeds):
    """The flat wake's saving over the free wake (wall and CPU time, %) and its errors, per speed (000 Sec.
    VII.A: 95% shorter)."""
    out, free = [], replace(base, aero="uvlm-free")
    for speed in speeds:
        flat_row, free_row = run_at(jobs, res, base, speed), run_at(jobs, res, free, speed)
        cut = saving(flat_row, free_row)
        if cut is None or base.aero != "uvlm-flat":
            continue
        job = {s: next(j for j in jobs if j.setting == s and j.speed == speed) for s in (base, free)}
        out.append(f"- {speed:g} m/s, flat against free wake: uvlm-flat ran {flat_row['wall_s']:.1f} s, uvlm-free "
                   f"{free_row['wall_s']:.1f} s: {cut[0]:.0f}% shorter (CPU time {cut[1]:.0f}% shorter; 000: "
                   f"{FLAT_VS_FREE_000:g}% shorter). The flat wake against the free wake: "
                   f"{error_text(errors(flat_row, free_row))}. Against the most accurate run, flat: "
                   f"{error_text(ana[job[base]]['err'])}; free: {error_text(ana[job[free]]['err'])}.")
    return out


def rigid_findings(jobs, res, ana, base, factors, speeds):
    """The rigid model's saving over each flexible level (wall and CPU time, %) and its errors, per speed."""
    out, rigid = [], replace(base, structure="rigid")
    flexible = [with_level(base, "structure", n) for n in factors["structure"] if n != "rigid"]
    for speed in speeds:
        rigid_row = run_at(jobs, res, rigid, speed)
        rows = [(s, run_at(jobs, res, s, speed)) for s in flexible]
        cuts = [(s, row, saving(rigid_row, row)) for s, row in rows if saving(rigid_row, row) is not None]
        if not cuts:
            continue
        job = next(j for j in jobs if j.setting == rigid and j.speed == speed)
        against = "; ".join(f"{cut[0]:.0f}% shorter than {s.structure} elements/body ({row['wall_s']:.1f} s, CPU "
                            f"{cut[1]:.0f}% shorter)" for s, row, cut in cuts)
        own = errors(rigid_row, run_at(jobs, res, base, speed))
        out.append(f"- {speed:g} m/s, rigid against flexible: rigid ran {rigid_row['wall_s']:.1f} s, {against}. "
                   f"The rigid model against the most accurate run: {error_text(ana[job]['err'])}; against the "
                   f"base ({base.structure} elements/body): {error_text(own, ('deploy', 'cl'))}.")
    return out


def base_findings(jobs, ana, fronts, base, speeds, names):
    """The base run's errors against the most accurate one and the Pareto fronts, per speed."""
    out = []
    for speed in speeds:
        job = next((j for j in jobs if j.setting == base and j.speed == speed), None)
        if job is None:
            continue
        e = ana[job]["err"]
        out.append(f"- {speed:g} m/s: the base run's errors against the most accurate run: deployment time "
                   f"{pct_text(e['deploy'])}, bending {pct_text(e['bend'])}, CL {pct_text(e['cl'])}.")
        for m in METRICS:
            members = ", ".join(names[j.setting] for j in fronts[(speed, m)]) or "none"
            out.append(f"  Pareto front of the {METRICS[m]} error (cheapest first): {members}.")
    return out


# ---- figures ----------------------------------------------------------------------------------------------
def figure(rows, cols, width, height):
    """A Figure (Agg) of rows x cols axes."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(width, height))
    FigureCanvasAgg(fig)
    return fig, fig.subplots(rows, cols, squeeze=False)


def save(fig, img, name):
    """Write img/tradeoff_<name>.png."""
    path = img / f"tradeoff_{name}.png"
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    print(f"wrote {path.relative_to(ROOT)} ({path.stat().st_size // 1024} KB)")


def plot_front(ax, jobs, res, ana, fronts, metric, speed, names, base, cost):
    """One panel: error (%) vs cost (s), log-log, every run a labelled point coloured by its factor (filled when
    on the Pareto front), the front a step line; an error of 0 (the most accurate run) is drawn as a triangle
    at a third of the smallest other error."""
    key, xlabel = COSTS[cost]
    front = fronts[(speed, metric)]
    here = [j for j in jobs if j.speed == speed and ana[j]["err"][metric] is not None and res[j][key]]
    positive = [ana[j]["err"][metric] for j in here if ana[j]["err"][metric] > 0]
    floor = min(positive, default=1.0) / 3
    for j in here:
        color = COLORS.get(factor_of(j.setting, base), "k")
        x, y = res[j][key], max(ana[j]["err"][metric], floor)
        ax.plot(x, y, "o" if y > floor else "v", ms=4, color=color, mfc=color if j in front else "none")
        ax.annotate(names[j.setting], (x, y), fontsize=5, color=color, xytext=(3, 2), textcoords="offset points")
    if front:
        xs = [res[j][key] for j in front]
        ys = [max(ana[j]["err"][metric], floor) for j in front]
        ax.step(xs, ys, where="post", color="k", lw=0.8, label="Pareto front")
    for factor, color in COLORS.items():
        ax.plot([], [], "o", ms=4, color=color, label=FACTOR_NAMES[factor])
    ax.set(xscale="log", yscale="log", xlabel=f"{xlabel} (s)", ylabel=f"{METRICS[metric]} error (%)",
           title=f"{speed:g} m/s")
    ax.axhline(LIMIT, color="0.5", lw=0.6, ls="--")
    ax.grid(True, which="both", alpha=0.25)
    ax.legend(fontsize=6, loc="lower left")       # cheap and accurate: the corner no run reaches


def plot_fronts(jobs, res, ana, fronts, names, base, cost, img):
    """tradeoff_<metric>.png: one panel per speed."""
    speeds = sorted({j.speed for j in jobs})
    for metric, name in FIGURES.items():
        fig, axes = figure(1, len(speeds), 7.5 * len(speeds), 6.5)
        for ax, speed in zip(axes[0], speeds):
            plot_front(ax, jobs, res, ana, fronts, metric, speed, names, base, cost)
        fig.suptitle(f"deploy_flexible: {METRICS[metric]} error against the most accurate run\n(filled: on the "
                     "Pareto front; triangle: error 0, drawn below the others; dashed: 1%)", fontsize=8)
        save(fig, img, name)


def plot_convergence(conv, factors, img):
    """tradeoff_convergence.png: per factor, the errors (%) of its levels against its most accurate level;
    colour by metric, line style by speed."""
    names = list(factors)
    cols = math.ceil(len(names) / 2)
    fig, axes = figure(2, cols, 3.3 * cols, 6.4)
    colors = {"deploy": "tab:blue", "bend": "tab:orange", "cl": "tab:green"}
    speeds = sorted({speed for _, speed in conv})
    lines = dict(zip(speeds, ("o-", "s--", "^:", "d-.")))
    for ax, name in zip(axes.flat, names):
        for (factor, speed), rows in conv.items():
            if factor != name:
                continue
            for m, color in colors.items():
                ys = [np.nan if e[m] is None else max(e[m], ERROR_FLOOR) for _, e, _ in rows]
                ax.plot(range(len(rows)), ys, lines.get(speed, "o-"), color=color, ms=3, lw=0.8,
                        label=f"{METRICS[m]}, {speed:g} m/s")
        ticks = [level_text(name, v).replace(" elements/body", " el.") for v in factors[name][:-1]]
        ax.set_xticks(range(len(ticks)), ticks, fontsize=6, rotation=30)
        ax.set_yscale("log")
        ax.axhline(LIMIT, color="k", lw=0.6, ls="--")
        ax.set_title(f"{FACTOR_NAMES[name]}: against {level_text(name, factors[name][-1])}", fontsize=7)
        ax.set_ylabel("error (%)", fontsize=7)
        ax.grid(True, which="both", alpha=0.25)
    for ax in list(axes.flat)[len(names):]:
        ax.set_visible(False)
    axes.flat[0].legend(fontsize=5)
    fig.suptitle("deploy_flexible: each factor against its own most accurate level, the others at base "
                 "(dashed: 1%)", fontsize=8)
    save(fig, img, "convergence")


# ---- the document ----------------------------------------------------------------------------------------
DEFINITIONS = """\
## Cases and definitions

Scene `scenes/deploy_flexible.toml` as shipped is the **base**: {base_text}. From it one factor at a time
is changed (levels from the least to the most accurate):

{levels}

The structure step h (`structure.step` of the flexible structure) is not a factor of the issue: it is one here
so that the most accurate run keeps h = 1e-4 s, the step of the structure's validation (docs/structure.md),
whatever step the scene ships with, and so that the scene's step is measured like the other choices. A level
that diverges is kept in the tables with its status.

The rigid level is `structure.fidelity = rigid` with deploy_rigid's `structure.integrator = {rigid_integrator}`
and `structure.step = {rigid_step:g}` s: one element per body (000 Eq. 17), no elastic modes to resolve, and
no damping (the rigid fidelity has none, docs/structure.md), so its difference from the flexible runs is the
structure's flexibility and its damping together. The coupling step is also the aero time step (one aero step
per coupling step, docs/scenes.md). The **most accurate** run has every factor at its most accurate level:
{best_text}. Every run is `orchestrator.master.run_scene(scene, backend="direct")` with flow.speed and
time.stop = {stop:g} s set, what `wingsim run scenes/deploy_flexible.toml --backend direct --set ...` runs.

Errors (%) of a run against the most accurate run of the same speed:

- **deployment time**: |t_d - t_d,ref| / t_d,ref, t_d = `deployment_time_s` of the summary: the time the fold
  angle reached 0 deg, as the structure unit finds it within its own internal step (output
  `latch_time_fold`), so a long coupling step does not coarsen the measure itself;
- **bending**: |D - D_ref| / D_ref, D = max over the run of |y displacement| of probe `bending_100mm`
  (mid-chord, 0.1 m from the root; the peak bending of docs/deployment.md, 000 Fig. 15); a rigid run has
  D = 0, error 100%;
- **CL**: RMS(CL - CL_ref) / max|CL_ref| over the communication points 0 < t <= {window:g} s (000 Eqs. 28-30,
  over 0-0.2 s as 000; `benchmarks/convergence.cl_error`, CL_ref interpolated at the run's times, exact:
  every coupling step's grid is a subset of the {finest_step:g} ms grid); `aero.model = none` has no lift,
  CL = 0, error RMS(CL_ref) / max|CL_ref|.

The **convergence** tables compare each factor's levels with that factor's own most accurate level, the others
at base, as 000 Sec. VII.A does (its tests used the rigid wing at 15 m/s with the free wake and M = N = 1
where not varied; `benchmarks/convergence.py` repeats those, docs/img/convergence_deploy_rigid.png).

Cost: **run (s)** is the run's `wall_time_s` (unit start-up to the end of the run); **run / base** divides it
by the base run's at the same speed; **CPU (s)** is the worker's process time for the run (scene load, run,
numbers; every worker imports the units before its first run), **CPU / base** likewise. {jobs} runs at a time
on a {cores}-core machine shared with other work: runs slow each other down, wall times vary by tens of %
between repeats, and ratios within one study are more telling than absolute times. The **Pareto front** of a
metric (per speed) is the set of runs that no other run beats in both {cost_name} and error; the most accurate
run (error 0) is on every front.
"""


def setting_text(s):
    """A Setting in words."""
    flexible = f"flexible, {s.structure} elements per body, h = {1e3 * s.h:g} ms"
    structure = "rigid" if s.structure == "rigid" else flexible
    return (f"{structure}, {s.aero} M = {s.M}, N = {s.N} per body, L_w = {s.L_w:g} chords, {s.algorithm} "
            f"coupling every {1e3 * s.step:g} ms")


def definitions(factors, base, best, stop, workers, cost):
    """The definitions section."""
    integrator, step = rigid_integrator()
    levels = "\n".join(f"- {FACTOR_NAMES[n]}: " + ", ".join(level_text(n, v) for v in lv) for n, lv in factors.items())
    structure = load_scene(SCENE)["structure"]
    base_text = (f"{setting_text(base)}; structure integrator {structure['integrator']}, damping_model = "
                 f"{structure.get('damping_model')}")
    return DEFINITIONS.format(base_text=base_text, levels=levels, rigid_integrator=integrator, rigid_step=step,
                              best_text=setting_text(best), stop=stop, window=min(CL_WINDOW, stop), jobs=workers,
                              cores=os.cpu_count(), finest_step=1e3 * min(factors["step"]),
                              cost_name=COSTS[cost][1].removeprefix("run "))


def document(jobs, res, ana, fronts, conv, names, factors, base, best, header, workers, cost, plots=True):
    """The text of tradeoff.md; `header` its first line (command, runs, wall time); figure links if `plots`."""
    speeds = sorted({j.speed for j in jobs})
    failed = [f"{names[j.setting]} at {j.speed:g} m/s" for j in jobs if res[j]["status"] != "ok"]
    lines = ["# Trade study: accuracy against cost of the flexible deployment", "", header, "",
             definitions(factors, base, best, jobs[0].stop, workers, cost),
             "## Runs against the most accurate run", "",
             *main_table(jobs, res, ana, fronts, names, base), ""]
    if failed:
        lines += [f"Runs that did not finish ({len(failed)}): {', '.join(failed)}; their errors are not computed "
                  "and they are on no front.", ""]
    lines += [f"![tradeoff_{f}](img/tradeoff_{f}.png)" + "\n" for f in FIGURES.values() if plots]
    lines += ["## 000's findings with our numbers", "", "Convergence (000 Sec. VII.A: the CL error below 1% "
              "from L_w = 5 against the whole wake, from M = 2 against M = 10, from N = 7 against N = 10):", "",
              *panel_findings(conv, factors), "", "Savings:", "",
              *wake_findings(jobs, res, ana, base, speeds), *rigid_findings(jobs, res, ana, base, factors, speeds), "",
              "The base scene's choice:", "",
              *base_findings(jobs, ana, fronts, base, speeds, names), "",
              "## Convergence of each factor (the others at base)", "",
              *(["![tradeoff_convergence](img/tradeoff_convergence.png)", ""] if plots else [])]
    for name in factors:
        lines += [f"### {FACTOR_NAMES[name]}", "", *convergence_table(conv, name, factors, COSTS[cost][0]), "",
                  *convergence_sentence(conv, name, factors), ""]
    return "\n".join(lines)


def header(command, n, wall, workers):
    """The doc's first line: the command, the runs, their wall time (s), the processes, the date."""
    return (f"Made by `{command}`: {n} runs in {wall:.0f} s wall time on {workers} processes, "
            f"{time.strftime('%Y-%m-%d')}. Sources: 000 Sec. VII.A (Eqs. 28-30, Fig. 12), 000 Sec. IV (rigid "
            "model), 003 Sec. 5.")


def dump(jobs, res, ana, names, path):
    """runs.json: every run's setting, speed, numbers and errors (the CL history left out)."""
    rows = [{"variant": names[j.setting], "speed": j.speed, "stop": j.stop, "setting": asdict(j.setting),
             **{k: v for k, v in res[j].items() if k not in ("cl", "curves")}, **ana[j]} for j in jobs]
    path.write_text(json.dumps(rows, indent=1, default=float))
    print(f"wrote {path.relative_to(ROOT)}")


def output_dir(quick, speeds, stop):
    """docs/ for the full study, results/tradeoff_quick/ or results/tradeoff/ otherwise."""
    if quick:
        return ROOT / "results" / "tradeoff_quick"
    return DOCS if tuple(speeds) == SPEEDS and stop == STOP else ROOT / "results" / "tradeoff"


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="few short runs at 10 m/s (a smoke test)")
    parser.add_argument("--jobs", type=int, default=2, help="worker processes (default 2)")
    parser.add_argument("--speeds", type=float, nargs="+", help="flow speeds, m/s (default 10 20; --quick: 10)")
    parser.add_argument("--stop", type=float, help=f"time.stop, s (default {STOP:g}; --quick: {QUICK_STOP:g})")
    parser.add_argument("--cost", choices=COSTS, default="wall",
                        help="the cost of the Pareto fronts: each run's wall time (default) or its CPU time")
    parser.add_argument("--no-plots", action="store_true", help="no figures")
    args = parser.parse_args(argv)

    factors = QUICK_FACTORS if args.quick else FACTORS
    speeds = tuple(args.speeds or ((10.0,) if args.quick else SPEEDS))
    stop = args.stop or (QUICK_STOP if args.quick else STOP)
    base, best = base_setting(), finest(factors)
    jobs = plan(factors, base, speeds, stop)
    names = {j.setting: label(j.setting, base, best) for j in jobs}
    start = time.perf_counter()
    res = run_all(jobs, args.jobs, names)
    wall = time.perf_counter() - start

    cost = COSTS[args.cost][0]
    ana, fronts = analyse(jobs, res, base, best, cost)
    conv = convergence(jobs, res, factors, base, cost)
    print("\n" + "\n".join(main_table(jobs, res, ana, fronts, names, base)))
    print(f"\n{len(jobs)} runs in {wall:.0f} s wall time on {args.jobs} processes")
    out = output_dir(args.quick, speeds, stop)
    raw = ROOT / "results" / ("tradeoff_quick" if args.quick else "tradeoff")
    raw.mkdir(parents=True, exist_ok=True)
    dump(jobs, res, ana, names, raw / "runs.json")
    if not args.no_plots:
        img = out / "img"
        img.mkdir(parents=True, exist_ok=True)
        plot_fronts(jobs, res, ana, fronts, names, base, args.cost, img)
        plot_convergence(conv, factors, img)
    command = " ".join(["python benchmarks/tradeoff.py", *(argv if argv is not None else sys.argv[1:])])
    doc = out / "tradeoff.md"
    doc.write_text(document(jobs, res, ana, fronts, conv, names, factors, base, best,
                            header(command, len(jobs), wall, args.jobs), args.jobs, args.cost, not args.no_plots))
    print(f"wrote {doc.relative_to(ROOT)}")
    failed = [j for j in jobs if res[j]["status"] != "ok"]
    if failed:
        print(f"{len(failed)} runs failed: {', '.join(f'{names[j.setting]} at {j.speed:g} m/s' for j in failed)}")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
