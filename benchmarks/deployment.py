"""Coupled wind-tunnel deployment of the folding wing: deployment time, bending, strain and tip deflection
against flow speed and aero model (000 Sec. VII, 003 Sec. 5).

    python benchmarks/deployment.py [--quick] [--jobs 2] [--parts 1 2 3] [--no-plots]

Parts (every run is `orchestrator.master.run_scene(scene, backend="direct")`, Gauss-Seidel coupling, exactly
what `wingsim run SCENE --backend direct --set ...` runs; runs go to `--jobs` processes, one BLAS thread each):
  1. scenes/deploy_rigid.toml, time.stop = 0.35 s, uvlm-flat at flow.speed = 0, 5, ..., 30 m/s, plus still
     air without aero (aero.model = none): deployment time (000 Fig. 11a);
  2. scenes/deploy_flexible.toml, time.stop = 0.3 s, uvlm-flat at 0, 10, 20, 30 m/s plus still air without
     aero: deployment time against 003's 0.120 / 0.166 / 0.198 s at 0 / 10 / 20 m/s, peak bending (000
     Fig. 15), peak strain (003 Fig. 12), tip deflection at 0.2 s (003 Sec. 5: 18% of the span); when the
     scene's structure.damping_model is not "deformation", also 0, 10, 20 m/s and still air with it;
  3. deploy_flexible at 10 m/s with aero.model = strip, uvlm-flat, uvlm-prescribed, uvlm-free and none.
--quick: rigid at 0, 15, 30 m/s, flexible at 0, 10, 20 m/s, part 3 uvlm-flat and strip only; tables only.

Definitions (the doc states them too):
  deployment time   summary deployment_time_s (s): the fold angle reaches its stop, 0 deg (the structure
                    unit's latch time, found within its internal step);
  peak bending      max over the run of |y displacement| of probe bending_100mm, mm (global y is the
                    out-of-plane direction of the deployed wing);
  peak strain       summary strain_gauges.strain_20mm.peak, microstrain;
  tip deflection    sqrt(tip_x^2 + tip_y^2), the tip probe's distance from the undeformed span line (the
                    global z axis), as % of the 0.3 m span: at t = 0.2 s, and its maximum after the latch.

A full run of all three parts writes docs/deployment.md (the tables, the command, the wall time) and, unless
--no-plots, docs/img/deployment_*.png; --quick or a subset of --parts only prints the tables.
"""
import argparse
import math
import os
import sys
import time
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):   # one BLAS thread per process
    os.environ.setdefault(_var, "1")

from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from orchestrator.master import run_scene  # noqa: E402
from orchestrator.results import summarize  # noqa: E402
from orchestrator.scene import load_scene  # noqa: E402

IMG = ROOT / "docs" / "img"
DOC = ROOT / "docs" / "deployment.md"
SPAN = 0.3                                    # m, deployed span (two 0.15 m bodies)
TIP_TIME = 0.2                                # s, 003 Sec. 5: tip deflection 18% (0.056 m) at 0.2 s
PAPER_003 = {0.0: 0.120, 10.0: 0.166, 20.0: 0.198}    # s, 003 Fig. 10: fold angle 0 at V = 0, 10, 20 m/s
STOP = {"deploy_rigid": 0.35, "deploy_flexible": 0.3}  # s, time.stop of each part
MODELS = ("strip", "uvlm-flat", "uvlm-prescribed", "uvlm-free", "none")
LINESTYLE = {"strip": "-", "uvlm-flat": "-", "uvlm-prescribed": "-.", "uvlm-free": ":"}   # the UVLMs overlap
COST = {"none": 1, "strip": 1, "uvlm-flat": 1.2, "uvlm-prescribed": 1.5, "uvlm-free": 4}   # relative, rough


@dataclass(frozen=True)
class Job:
    """One run: `scene` (file stem) with aero.model = `model` at flow.speed = `speed` (m/s; 0 for none) and
    structure.damping_model = `damping` ("": the scene's)."""
    scene: str
    model: str
    speed: float
    damping: str = ""

    @property
    def overrides(self):
        out = [f"time.stop={STOP[self.scene]}", f"aero.model={self.model}", f"flow.speed={self.speed:g}"]
        return out + ([f"structure.damping_model={self.damping}"] if self.damping else [])

    @property
    def label(self):
        flow = "still air, no aero" if self.model == "none" else f"{self.model} {self.speed:g} m/s"
        return f"{self.scene} {flow}" + (f", {self.damping} damping" if self.damping else "")


def still(scene, damping=""):
    """The still-air run without aerodynamics of `scene`."""
    return Job(scene, "none", 0.0, damping)


def scene_damping(scene):
    """structure.damping_model of `scene` as the scene file resolves it."""
    return load_scene(ROOT / "scenes" / f"{scene}.toml")["structure"].get("damping_model", "deformation")


def plan(quick=False):
    """{part: [Job, ...]} in table order."""
    rigid = (0, 15, 30) if quick else range(0, 31, 5)
    flexible = (0, 10, 20) if quick else (0, 10, 20, 30)
    models = ("strip", "uvlm-flat") if quick else MODELS
    other = "" if quick or scene_damping("deploy_flexible") == "deformation" else "deformation"
    variant = [Job("deploy_flexible", "uvlm-flat", v, other) for v in PAPER_003] + [still("deploy_flexible", other)]
    return {
        1: [Job("deploy_rigid", "uvlm-flat", float(v)) for v in rigid] + [still("deploy_rigid")],
        2: [Job("deploy_flexible", "uvlm-flat", float(v)) for v in flexible] + [still("deploy_flexible")]
           + (variant if other else []),
        3: [still("deploy_flexible") if m == "none" else Job("deploy_flexible", m, 10.0) for m in models],
    }


def estimated_cost(job):
    """Rough relative cost of a run, to start the longest first."""
    return (10 if job.scene == "deploy_flexible" else 1) * COST[job.model]


def tip_deflection(t, tip_x, tip_y, latch_time):
    """(at TIP_TIME, max after `latch_time`) of sqrt(tip_x^2 + tip_y^2), m; NaN where it does not apply."""
    r = np.hypot(tip_x, tip_y)
    at = float(np.interp(TIP_TIME, t, r)) if len(t) and t[-1] >= TIP_TIME else math.nan
    after = r[t >= latch_time] if latch_time is not None else r[:0]
    return at, float(after.max()) if after.size else math.nan


def metrics(result):
    """The numbers a table row needs (s, mm, microstrain, % of span) and the curves a figure needs."""
    series, summary = result.series, summarize(result)
    t, y = series.time, series.column("bending_100mm_y")
    bend = summary["probes"]["bending_100mm"]
    low, high = bend["min_displacement"][1], bend["max_displacement"][1]
    at, most = tip_deflection(t, series.column("tip_x"), series.column("tip_y"), summary["deployment_time_s"])
    strain = summary["strain_gauges"]["strain_20mm"]
    return {
        "status": result.status, "message": result.message, "wall_s": result.wall_time_s,
        "simulated_s": result.simulated_time_s, "deploy_s": summary["deployment_time_s"],
        "bend_mm": 1e3 * max(abs(low), abs(high)) if low is not None else None,
        "bend_min_mm": 1e3 * low if low is not None else None,
        "strain_ue": 1e6 * strain["peak"] if strain["peak"] is not None else None,
        "tip_pct": 100 * at / SPAN, "tip_m": at, "tip_max_pct": 100 * most / SPAN,
        "curves": {"t": t, "fold": series.column("fold_angle_fold"), "bend_mm": 1e3 * (y - y[:1]),
                   "strain_ue": 1e6 * series.column("strain_20mm")},
    }


def run_one(job):
    """metrics() of one run plus its CPU time `cpu_s` (s, this process: load, run, summary); a run that
    raises becomes an "error" row with the exception as its message."""
    cpu = time.process_time()
    try:
        row = metrics(run_scene(load_scene(ROOT / "scenes" / f"{job.scene}.toml", job.overrides), backend="direct"))
    except Exception as err:                      # noqa: BLE001 - reported as a row, never dropped
        row = {"status": "error", "message": f"{type(err).__name__}: {err}", "wall_s": None, "curves": None}
    return {**row, "cpu_s": time.process_time() - cpu}


def run_all(jobs, workers):
    """{Job: metrics} of all `jobs`, longest first, one progress line per finished run."""
    results, start = {}, time.perf_counter()
    with ProcessPoolExecutor(max_workers=max(1, workers)) as pool:
        futures = {pool.submit(run_one, job): job for job in sorted(jobs, key=estimated_cost, reverse=True)}
        for k, future in enumerate(as_completed(futures), 1):
            job, row = futures[future], future.result()
            results[job] = row
            print(f"[{k}/{len(jobs)} {time.perf_counter() - start:6.1f} s] {job.label}: {row['status']}, "
                  f"deployment {fmt(row.get('deploy_s'), '.4f')} s, run {fmt(row['wall_s'], '.1f')} s", flush=True)
    return results


def fmt(value, spec):
    """`value` formatted with `spec`, or "-" for None / NaN."""
    return "-" if value is None or (isinstance(value, float) and math.isnan(value)) else format(value, spec)


def pct(value, ref):
    """100 (value - ref) / ref, or None."""
    return None if value is None or ref is None else 100.0 * (value - ref) / ref


def ratio(value, ref):
    """value / ref, or None."""
    return None if value is None or not ref else value / ref


def status(row):
    """"ok", or the status, the time reached and the message of a failed run."""
    if row["status"] == "ok":
        return "ok"
    reached = f" at t = {row['simulated_s']:.4g} s" if row.get("simulated_s") is not None else ""
    return f"{row['status']}{reached}: {row['message']}".replace("|", "/").replace("\n", " ")


def tip_cell(row):
    """Tip deflection at TIP_TIME (% span), marked when the wing has not latched yet (a fold, not a bend)."""
    latched = row.get("deploy_s") is not None and row["deploy_s"] <= TIP_TIME
    text = fmt(row.get("tip_pct"), ".1f")
    return text if latched or text == "-" else f"{text} (not latched)"


def air(job):
    """The flow column of a row: the speed (m/s) or still air."""
    return "none (still air)" if job.model == "none" else f"{job.speed:g}"


def table(header, rows):
    """Markdown table lines."""
    return ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)] + ["| " + " | ".join(r) + " |" for r in rows]


def table_rigid(jobs, res):
    """Part 1 rows: deployment time (s) and run wall time (s) per flow speed."""
    rows = [[air(j), fmt(res[j].get("deploy_s"), ".4f"), fmt(res[j]["wall_s"], ".1f"), status(res[j])] for j in jobs]
    return table(["flow speed (m/s)", "deployment time (s)", "run (s)", "status"], rows)


def table_flexible(jobs, res):
    """Part 2 rows: deployment time (s) against 003, bending (mm), strain (microstrain), tip (% span)."""
    rows, default = [], scene_damping("deploy_flexible")
    for j in jobs:
        r, ref = res[j], PAPER_003.get(j.speed)
        rows.append([air(j), j.damping or default, fmt(r.get("deploy_s"), ".4f"), fmt(ref, ".3f"),
                     fmt(pct(r.get("deploy_s"), ref), "+.1f"), fmt(r.get("bend_mm"), ".1f"),
                     fmt(r.get("bend_min_mm"), ".1f"), fmt(r.get("strain_ue"), ".0f"), tip_cell(r),
                     fmt(r.get("tip_max_pct"), ".1f"), fmt(r["wall_s"], ".1f"), status(r)])
    return table(["flow speed (m/s)", "damping_model", "deployment time (s)", "003 (s)", "difference (%)",
                  "peak bending (mm)", "min bending y (mm)", "peak strain (microstrain)", "tip at 0.2 s (% span)",
                  "max tip after latch (% span)", "run (s)", "status"], rows)


def table_fidelity(jobs, res):
    """Part 3 rows per aero model, deployment time against uvlm-free (%), run time against uvlm-flat."""
    ref = next((res[j].get("deploy_s") for j in jobs if j.model == "uvlm-free"), None)
    flat = next((res[j] for j in jobs if j.model == "uvlm-flat"), {})
    rows = []
    for j in jobs:
        r = res[j]
        rows.append([j.model, fmt(r.get("deploy_s"), ".4f"), fmt(pct(r.get("deploy_s"), ref), "+.2f"),
                     fmt(r.get("bend_mm"), ".1f"), fmt(r.get("strain_ue"), ".0f"), tip_cell(r),
                     fmt(r["wall_s"], ".1f"), fmt(ratio(r["wall_s"], flat.get("wall_s")), ".2f"),
                     fmt(r["cpu_s"], ".1f"), fmt(ratio(r["cpu_s"], flat.get("cpu_s")), ".2f"), status(r)])
    return table(["aero.model", "deployment time (s)", "vs uvlm-free (%)", "peak bending (mm)",
                  "peak strain (microstrain)", "tip at 0.2 s (% span)", "run (s)", "run / uvlm-flat", "CPU (s)",
                  "CPU / uvlm-flat", "status"], rows)


TABLES = {1: ("Rigid deployment (deploy_rigid, 0.35 s)", table_rigid),
          2: ("Flexible deployment (deploy_flexible, 0.3 s)", table_flexible),
          3: ("Aero fidelity (deploy_flexible, 10 m/s, 0.3 s)", table_fidelity)}


def figure(rows, cols, height):
    """A Figure (Agg) of rows x cols axes, 4.2 in wide per column and `height` in tall."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(4.2 * cols, height))
    FigureCanvasAgg(fig)
    return fig, fig.subplots(rows, cols, squeeze=False)


def save(fig, name):
    """Write docs/img/deployment_<name>.png."""
    path = IMG / f"deployment_{name}.png"
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    print(f"wrote {path.relative_to(ROOT)} ({path.stat().st_size // 1024} KB)")


def plot_rigid(jobs, res):
    """deployment_rigid.png: deployment time (s) vs flow speed (m/s); fold angle (deg) vs time (s)."""
    fig, ((a, b),) = figure(1, 2, 3.4)
    aero = [j for j in jobs if j.model != "none" and res[j].get("deploy_s") is not None]
    a.plot([j.speed for j in aero], [res[j]["deploy_s"] for j in aero], "o-", label="uvlm-flat")
    for j in jobs:
        if j.model == "none" and res[j].get("deploy_s") is not None:
            a.axhline(res[j]["deploy_s"], color="k", ls="--", lw=0.8, label="still air, no aero")
        if res[j]["curves"] is not None:
            c = res[j]["curves"]
            b.plot(c["t"], c["fold"], **curve_style(j, "speed"))
    a.set(xlabel="flow speed (m/s)", ylabel="deployment time (s)", title="deploy_rigid (000 Fig. 11a)")
    b.set(xlabel="time (s)", ylabel="fold angle (deg)", title="deploy_rigid, uvlm-flat")
    for ax in (a, b):
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=7)
    save(fig, "rigid")


def curve_style(job, by):
    """Matplotlib keywords of a run's curve, labelled by "speed" or by "model"."""
    if job.model == "none":
        return {"color": "k", "ls": "--", "lw": 1.0, "label": "still air, no aero"}
    if by == "speed":
        return {"lw": 1.0, "label": f"{job.speed:g} m/s"}
    return {"lw": 1.0, "ls": LINESTYLE[job.model], "label": job.model}


def plot_histories(jobs, res, by, name, title):
    """Three stacked panels vs time (s): fold angle (deg), bending_100mm y (mm), strain_20mm (microstrain)."""
    fig, axes = figure(3, 1, 7.5)
    fig.set_figwidth(6.5)
    keys = (("fold", "fold angle (deg)"), ("bend_mm", "bending_100mm y (mm)"),
            ("strain_ue", "strain_20mm (microstrain)"))
    for ax, (key, ylabel) in zip(axes[:, 0], keys):
        for j in jobs:
            if res[j]["curves"] is not None:
                ax.plot(res[j]["curves"]["t"], res[j]["curves"][key], **curve_style(j, by))
        ax.set_ylabel(ylabel, fontsize=8)
        ax.grid(True, alpha=0.3)
    axes[0, 0].set_title(title, fontsize=9)
    axes[0, 0].legend(fontsize=7)
    axes[-1, 0].set_xlabel("time (s)")
    save(fig, name)


def plot_peaks(jobs, res):
    """deployment_flexible_peaks.png: peak bending (mm) and peak strain (microstrain) vs flow speed (m/s)."""
    fig, ((a, b),) = figure(1, 2, 3.2)
    default = scene_damping("deploy_flexible")
    panels = ((a, "bend_mm", "peak |bending_100mm y| (mm)"), (b, "strain_ue", "peak strain_20mm (microstrain)"))
    for ax, key, ylabel in panels:
        for damping, ls in (("", "-"), ("deformation", ":")):
            aero = [j for j in jobs if j.damping == damping and j.model != "none" and res[j]["status"] == "ok"]
            if aero:
                ax.plot([j.speed for j in aero], [res[j][key] for j in aero], "o", ls=ls,
                        label=f"uvlm-flat, {damping or default}")
            for j in jobs:
                if j.damping == damping and j.model == "none" and res[j].get(key) is not None:
                    ax.axhline(res[j][key], color="k", ls="--" if ls == "-" else ":", lw=0.8,
                               label=f"still air, no aero, {damping or default}")
        ax.set(xlabel="flow speed (m/s)", ylabel=ylabel)
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=7)
    a.set_title("000 Fig. 15", fontsize=9)
    b.set_title("003 Fig. 12", fontsize=9)
    save(fig, "flexible_peaks")


def plot_all(parts, res):
    """The figures of the parts that ran."""
    IMG.mkdir(parents=True, exist_ok=True)
    if 1 in parts:
        plot_rigid(parts[1], res)
    if 2 in parts:
        plot_histories([j for j in parts[2] if not j.damping], res, "speed", "flexible",
                       f"deploy_flexible, uvlm-flat, damping_model = {scene_damping('deploy_flexible')}")
        plot_peaks(parts[2], res)
    if 3 in parts:
        plot_histories(parts[3], res, "model", "fidelity", "deploy_flexible at 10 m/s, by aero.model")


def rises(jobs, res):
    """Sentence: does the deployment time (s) rise with every speed step of the aero runs `jobs`?"""
    times = [(j.speed, res[j].get("deploy_s")) for j in jobs if j.model != "none"]
    if len(times) < 2 or any(t is None for _, t in times):
        return "Not every run latched, so the trend is not stated."
    steps = np.diff([t for _, t in times])
    falls = int((steps <= 0).sum())
    verdict = "rises at every step" if not falls else f"does not rise at every step ({falls} of {steps.size} do not)"
    return (f"The deployment time {verdict}: {times[0][1]:.4f} s at {times[0][0]:g} m/s, {times[-1][1]:.4f} s at "
            f"{times[-1][0]:g} m/s ({pct(times[-1][1], times[0][1]):+.1f}%).")


def paper_facts(jobs, res):
    """Sentences comparing part 2 with 003's tip deflection and 000's measured bending."""
    out = []
    at10 = next((res[j] for j in jobs if j.model != "none" and j.speed == 10.0), None)
    if at10 is not None:
        after = None if at10.get("deploy_s") is None else 1e3 * (TIP_TIME - at10["deploy_s"])
        out.append(f"Tip deflection at 0.2 s, 10 m/s: {fmt(at10.get('tip_m'), '.4f')} m = "
                   f"{fmt(at10.get('tip_pct'), '.1f')}% of the span, {fmt(after, '.0f')} ms after the latch (003 "
                   f"Sec. 5: 0.056 m = 18%, {1e3 * (TIP_TIME - PAPER_003[10.0]):.0f} ms after its latch).")
    calm = next((res[j] for j in jobs if j.model == "none"), None)
    if calm is not None:
        out.append(f"Still air without aero: bending_100mm y down to {fmt(calm.get('bend_min_mm'), '.1f')} mm "
                   f"(000 Sec. VII.B: -28 mm measured).")
    return out


def air_effect(jobs, res):
    """Sentence: uvlm-flat at 0 m/s against still air without aero (deployment time, %)."""
    flat = next((res[j].get("deploy_s") for j in jobs if j.model != "none" and j.speed == 0.0), None)
    calm = next((res[j].get("deploy_s") for j in jobs if j.model == "none"), None)
    return (f"At 0 m/s the air forces of the wing's own motion (uvlm-flat) delay the latch by "
            f"{fmt(pct(flat, calm), '+.1f')}% against no aero.")


def damping_facts(jobs, res):
    """Sentence on the deformation-damping rows of part 2: deployment time against 003 (%), tip at 0.2 s."""
    rows = {j.speed: res[j] for j in jobs if j.damping and j.model != "none"}
    if not rows:
        return []
    diffs = ", ".join(f"{fmt(pct(rows[v].get('deploy_s'), ref), '+.1f')}%" for v, ref in PAPER_003.items() if v in rows)
    at10 = rows.get(10.0, {})
    after = None if at10.get("deploy_s") is None else 1e3 * (TIP_TIME - at10["deploy_s"])
    return [f"With damping of deformation only the deployment time differs from 003's by {diffs} at "
            f"{', '.join(f'{v:g}' for v in PAPER_003 if v in rows)} m/s; tip deflection at 0.2 s, 10 m/s: "
            f"{fmt(at10.get('tip_pct'), '.1f')}% of the span, {fmt(after, '.0f')} ms after the latch."]


def damping_note():
    """The damping bullet of the doc, from deploy_flexible's structure.damping_model and alpha (1/s)."""
    scene = load_scene(ROOT / "scenes" / "deploy_flexible.toml")
    alpha = scene["structure"]["bodies"][0].get("damping", 0.0)
    if scene_damping("deploy_flexible") == "deformation":
        return (f"- damping (alpha = {alpha:g} 1/s on deploy_flexible) acts on deformation only, not on the rigid\n"
                "  swing of the outer body (`structure.damping_model = \"deformation\"`, 000 Sec. IV;\n"
                "  docs/structure.md); the rigid fidelity has none;")
    return (f"- damping: deploy_flexible sets `structure.damping_model = \"mass-proportional\"`, F = -alpha M de\n"
            f"  with alpha = {alpha:g} 1/s on every coordinate, which also damps the outer body's swing\n"
            "  (000 Sec. II.C and 003 Sec. 5 as written; docs/structure.md). The rows marked `deformation` rerun\n"
            "  part 2 with damping of deformation only (the default, 000 Sec. IV). The rigid fidelity has no damping;")


def fidelity_facts(jobs, res):
    """Sentences on part 3: spread of the UVLM wakes (%), the structure's share of the run time (s)."""
    uvlm = [res[j].get("deploy_s") for j in jobs if j.model.startswith("uvlm")]
    calm = next((res[j]["cpu_s"] for j in jobs if j.model == "none"), None)
    out = []
    if len(uvlm) > 1 and None not in uvlm:
        out.append(f"The {len(uvlm)} UVLM wakes latch within {100 * (max(uvlm) - min(uvlm)) / min(uvlm):.2f}% "
                   "of each other.")
    if calm is not None:
        out.append(f"The structure alone (none) takes {calm:.1f} s of CPU time.")
        cheaper = [j.model for j in jobs if j.model != "none" and res[j]["status"] == "ok" and res[j]["cpu_s"] < calm]
        if cheaper:
            out.append(f"{', '.join(cheaper)} took less CPU time than the run without aero, so differences of "
                       "that size are run-to-run spread, not aero cost.")
    return out


DEFINITIONS = """\
## Cases and definitions

Scenes: `scenes/deploy_rigid.toml` (aluminium, rigid fidelity, RK4 h = 5e-4 s) and
`scenes/deploy_flexible.toml` (PVC, 7 ANCF elements per body, generalized-alpha h = 1e-4 s), both with the
uvlm-flat aero unit (M = 2, N = 7 per body, L_w = 5 chords), Gauss-Seidel coupling every 1 ms, gravity
-9.8 m/s^2 along the span, fold angle from 170 deg to the latch at 0 deg. Speed and model are scene
overrides (`flow.speed=...`, `aero.model=...`); `aero.model=none` is still air without aerodynamics, while
uvlm-flat at 0 m/s still has the air forces of the wing's own motion. Each run is
`orchestrator.master.run_scene(scene, backend="direct")`, what `wingsim run SCENE --backend direct --set ...` runs.

- **deployment time**: `deployment_time_s` of the summary, the time the fold angle reaches 0 deg (s), as the
  structure unit finds it within its own internal step;
- **peak bending**: max over the run of |y displacement| of probe `bending_100mm` (mid-chord, 0.1 m from the
  root; global y is the out-of-plane direction of the deployed wing), mm (000 Fig. 15); "min bending y" is
  the signed minimum;
- **peak strain**: `strain_gauges.strain_20mm.peak`, the largest |h/2 x bending curvature| at 0.02 m from the
  root, microstrain (003 Fig. 12);
- **tip deflection**: sqrt(tip_x^2 + tip_y^2), the distance of the tip probe (on the reference line) from
  the undeformed span line, the global z axis, as % of the 0.3 m span: at t = 0.2 s (003 Sec. 5: 18%,
  0.056 m at 10 m/s) and its maximum after the latch; "(not latched)": the wing latches after 0.2 s, so
  the number is mostly the fold, not a deflection;
- **run (s)**: `RunResult.wall_time_s`, two runs at a time on a 2-core machine shared with other work, so
  wall times vary by tens of % between repeats; **CPU (s)**: the worker's process time for the run (scene
  load, run, summary).

Decisions documented elsewhere that these numbers depend on:

{damping}
- actuator stiffness K = 0.026 N m/rad (000 Table 2), not 003 Table 5's 0.26 (../shared/papers/README.md);
- strip theory scales 2 pi by Helmbold's finite-span lift slope A / (2 + sqrt(A^2 + 4)) by default
  (`aero.span_correction = "helmbold"`; A = 6 here, factor 0.72; aero_fmu/strip.py).
"""


def document(parts, res, command, wall, workers):
    """The text of docs/deployment.md."""
    n = len({j for jobs in parts.values() for j in jobs})
    lines = ["# Wind-tunnel deployment, coupled structure and aero", "",
             f"Made by `{command}`: {n} runs in {wall:.0f} s wall time on {workers} processes, "
             f"{time.strftime('%Y-%m-%d')}. Sources: 000 Sec. VII (Figs. 11a, 15), 003 Sec. 5 (Figs. 10, 12).", "",
             DEFINITIONS.format(damping=damping_note())]
    main2 = [j for j in parts[2] if not j.damping]
    notes = {1: [rises(parts[1], res), air_effect(parts[1], res)],
             2: [rises(main2, res), air_effect(main2, res), *paper_facts(main2, res), *damping_facts(parts[2], res)],
             3: fidelity_facts(parts[3], res)}
    figures = {1: ["rigid"], 2: ["flexible", "flexible_peaks"], 3: ["fidelity"]}
    for part, jobs in parts.items():
        title, make = TABLES[part]
        lines += [f"## {part}. {title}", "", *make(jobs, res), "", *notes[part], ""]
        lines += [line for f in figures[part] for line in (f"![deployment_{f}](img/deployment_{f}.png)", "")]
    return "\n".join(lines)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="fewer speeds and models, tables only (a smoke test)")
    parser.add_argument("--jobs", type=int, default=2, help="worker processes (default 2)")
    parser.add_argument("--parts", type=int, nargs="+", choices=(1, 2, 3), default=[1, 2, 3])
    parser.add_argument("--no-plots", action="store_true", help="no figures")
    args = parser.parse_args(argv)

    parts = {p: jobs for p, jobs in plan(args.quick).items() if p in args.parts}
    jobs = list(dict.fromkeys(j for part in parts.values() for j in part))
    start = time.perf_counter()
    res = run_all(jobs, args.jobs)
    wall = time.perf_counter() - start
    for part, part_jobs in parts.items():
        title, make = TABLES[part]
        print(f"\n{part}. {title}\n" + "\n".join(make(part_jobs, res)))
    print(f"\n{len(jobs)} runs in {wall:.0f} s wall time on {args.jobs} processes")
    full = not args.quick and len(parts) == 3
    if not args.no_plots and not args.quick:
        plot_all(parts, res)
    if full:
        command = " ".join(["python benchmarks/deployment.py", *(argv if argv is not None else sys.argv[1:])])
        DOC.write_text(document(parts, res, command, wall, args.jobs))
        print(f"wrote {DOC.relative_to(ROOT)}")
    failed = [j.label for j in jobs if res[j]["status"] != "ok"]
    if failed:
        print(f"{len(failed)} runs failed: {', '.join(failed)}")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
