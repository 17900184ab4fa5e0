"""Coupled wind-tunnel deployment of the folding wing: deployment time, bending, strain and tip deflection
against flow speed and aero model (Otsuka et al. 2019, Sec. VII; Otsuka et al. 2022, Sec. 5).

    python benchmarks/deployment.py [--quick] [--jobs 2] [--resume] [--no-plots]

Every run is `run_scene(scene, backend="direct")`, what `wingsim run SCENE --backend direct --set ...` runs:
  1. deploy_rigid, 0.35 s, uvlm-flat at 0, 5, ..., 30 m/s and still air without aero (aero.model = none);
  2. deploy_flexible, 0.3 s, uvlm-flat at 0, 10, 20, 30 m/s and still air; when the scene's
     structure.damping_model is not "deformation", also 0, 10, 20 m/s and still air with it;
  3. deploy_flexible at 10 m/s with every aero.model;
  4. deploy_wind_tunnel_2019 (Otsuka et al. 2019, Table 2, PVC), 0.4 s, uvlm-flat at 0, 5, ..., 30 m/s and still air.
--quick: rigid at 0, 15, 30 m/s, flexible at 0, 10, 20 m/s, part 3 with strip and uvlm-flat, part 4 at 0, 10, 20 m/s.
The figures of merit are orchestrator.studies.metrics'; the report (templates/deployment.md) defines them.
"""
import time
from dataclasses import dataclass

import numpy as np
from report import Report, fmt, ratio, status

from orchestrator.studies import metrics
from orchestrator.scene.load import load_scene

REPORT = Report("deployment", __doc__)
SPAN = 0.3                                            # m, deployed span (two 0.15 m bodies)
TIP_TIME = 0.2                                        # s, Otsuka et al. 2022, Sec. 5: tip deflection at 0.2 s
PAPER_2022 = {0.0: 0.120, 10.0: 0.166, 20.0: 0.198}   # s, Otsuka et al. 2022, Fig. 10: latch at 0, 10, 20 m/s
# mm, Otsuka et al. 2019, Sec. VII.B: the minimum of bending_100mm y in Fig. 14, after the bodies align; the text names
# no speed, the bending falls with speed (Fig. 15), so it is the 0 m/s history's
PAPER_2019_MIN = {0.0: -28.0}
STOP = {"deploy_rigid": 0.35, "deploy_flexible": 0.3, "deploy_wind_tunnel_2019": 0.4}  # s, time.stop of each scene
MODELS = ("strip", "uvlm-flat", "uvlm-prescribed", "uvlm-free", "none")
COST = {"none": 1, "strip": 1, "uvlm-flat": 1.2, "uvlm-prescribed": 1.5, "uvlm-free": 4}   # relative, rough


@dataclass(frozen=True)
class Job:
    """One run: `scene` (file stem) with aero.model = `model` at flow.speed = `speed` (m/s; 0 for none) and
    structure.damping_model = `damping` ("": the scene's). Its repr keys its record."""
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


def load(name, overrides=()):
    """The resolved scene scenes/<name>.toml with `overrides`."""
    return load_scene(REPORT.root / "scenes" / f"{name}.toml", list(overrides))


def plan(quick):
    """{part: [Job, ...]} in table order."""
    still = lambda scene, damping="": Job(scene, "none", 0.0, damping)
    damping = load("deploy_flexible")["structure"]["damping_model"]
    other = "" if quick or damping == "deformation" else "deformation"
    variant = [Job("deploy_flexible", "uvlm-flat", v, other) for v in PAPER_2022] + [still("deploy_flexible", other)]
    return {1: [Job("deploy_rigid", "uvlm-flat", float(v)) for v in ((0, 15, 30) if quick else range(0, 31, 5))]
               + [still("deploy_rigid")],
            2: [Job("deploy_flexible", "uvlm-flat", float(v)) for v in ((0, 10, 20) if quick else (0, 10, 20, 30))]
               + [still("deploy_flexible")] + (variant if other else []),
            3: [still("deploy_flexible") if m == "none" else Job("deploy_flexible", m, 10.0)
                for m in (("strip", "uvlm-flat") if quick else MODELS)],
            4: [Job("deploy_wind_tunnel_2019", "uvlm-flat", float(v))
                for v in ((0, 10, 20) if quick else range(0, 31, 5))] + [still("deploy_wind_tunnel_2019")]}


def work(job):
    """The figures of one run (s, mm, microstrain, % of span), its CPU time (s) and the curves of the figures."""
    from orchestrator.run.master import run_scene
    from orchestrator.output.results import summarize

    cpu = time.process_time()
    scene = load(job.scene, job.overrides)
    result = run_scene(scene, backend="direct")
    series, summary = result.series, summarize(result)
    low, high = metrics.displacement_range(series, "bending_100mm", "y")
    t, tip_x, tip_y = series.time, series.column("tip_x"), series.column("tip_y")
    strain = summary["strain_gauges"]["strain_20mm"]["peak"]
    y = series.column("bending_100mm_y")
    deploy = summary["deployment_time_s"]
    return {"status": result.status, "message": result.message, "wall_s": result.wall_time_s,
            "simulated_s": result.simulated_time_s, "deploy_s": deploy,
            "bend_mm": 1e3 * max(abs(low), abs(high)), "bend_min_mm": 1e3 * low,
            "bend_min_t": float(t[np.nanargmin(y - y[:1])]),
            "bend_deploy_mm": None if deploy is None else
            1e3 * metrics.peak_displacement(series, "bending_100mm", "y", until=deploy),
            "strain_ue": None if strain is None else 1e6 * strain,
            "torque_scale": torque_scale(scene, series, deploy),
            "tip_m": metrics.tip_deflection(t, tip_x, tip_y, TIP_TIME),
            "tip_max_pct": 100 * metrics.largest_after(t, np.hypot(tip_x, tip_y), summary["deployment_time_s"]) / SPAN,
            "curves": {"t": t, "fold": series.column("fold_angle_fold"), "bend_mm": 1e3 * (y - y[:1]),
                       "strain_ue": 1e6 * series.column("strain_20mm")},
            "cpu_s": time.process_time() - cpu}


def torque_scale(scene, series, deploy):
    """F = T_const / T_aero of the hinge `fold` during the deployment (up to the latch; Otsuka et al. 2019,
    Sec. VII.A, Fig. 11b; metrics.deployment_torque_scale), or None: no aero unit, or not latched."""
    if deploy is None or "hinge_moment_fold" not in series.hinge_moment_names:
        return None
    fold = next(j for j in scene["structure"]["joints"] if j.get("name") == "fold")
    value = metrics.deployment_torque_scale(series.time, series.column("hinge_moment_fold"), fold["torque"], deploy)
    return None if np.isnan(value) else value


def pct(value, ref):
    """100 (value - ref) / ref, or None."""
    return None if value is None or ref is None else 100.0 * (value - ref) / ref


def rises(rows):
    """The trend of the deployment time (s) over the aero runs `rows` (speed order): first and last row, the
    speed steps and how many of them do not raise it; None unless every run latched."""
    aero = [r for r in rows if r["model"] != "none"]
    if len(aero) < 2 or any(r["deploy_s"] is None for r in aero):
        return None
    steps = np.diff([r["deploy_s"] for r in aero])
    return {"first": aero[0], "last": aero[-1], "steps": steps.size, "falls": int((steps <= 0).sum())}


def falls(rows, key):
    """The trend of `key` over the aero runs `rows` (speed order): first and last row, the speed steps and how
    many of them do not lower it; None unless every run has the number."""
    aero = [r for r in rows if r["model"] != "none"]
    if len(aero) < 2 or any(r[key] is None for r in aero):
        return None
    steps = np.diff([r[key] for r in aero])
    return {"first": aero[0], "last": aero[-1], "steps": steps.size, "rises": int((steps >= 0).sum())}


def after_latch(r):
    """ms from the latch to TIP_TIME, or None."""
    return None if r["deploy_s"] is None else 1e3 * (TIP_TIME - r["deploy_s"])


def row(job, result):
    """A run's numbers for the template: the job's fields, the run's figures, status text, % of span."""
    out = {**vars(job), "label": job.label, "status_text": status(result), "ok": result.get("status") == "ok"}
    out.update({k: result.get(k) for k in ("deploy_s", "bend_mm", "bend_min_mm", "bend_min_t", "bend_deploy_mm",
                                           "strain_ue", "torque_scale", "tip_m", "tip_max_pct", "wall_s", "cpu_s",
                                           "curves")})
    out["tip_pct"] = None if out["tip_m"] is None else 100 * out["tip_m"] / SPAN
    out["latched"] = out["deploy_s"] is not None and out["deploy_s"] <= TIP_TIME
    out["uvlm"] = job.model.startswith("uvlm")
    out["air"] = "none (still air)" if job.model == "none" else f"{job.speed:g}"
    return out


def style(r, by):
    """Matplotlib keywords of a run's curve, labelled by "speed" or by "model"."""
    if r["model"] == "none":
        return {"color": "k", "ls": "--", "lw": 1.0, "label": "still air, no aero"}
    if by == "speed":
        return {"lw": 1.0, "label": f"{r['speed']:g} m/s"}
    return {"lw": 1.0, "ls": {"uvlm-prescribed": "-.", "uvlm-free": ":"}.get(r["model"], "-"), "label": r["model"]}


def plot(parts, default):
    """deployment_rigid, _flexible, _flexible_peaks, _fidelity, _wind_tunnel_2019 and _wind_tunnel_2019_peaks.png."""
    fig, ((a, b),) = REPORT.figure(1, 2, 8.4, 3.4)
    aero = [r for r in parts[1] if r["model"] != "none" and r["deploy_s"] is not None]
    a.plot([r["speed"] for r in aero], [r["deploy_s"] for r in aero], "o-", label="uvlm-flat")
    for r in parts[1]:
        if r["model"] == "none" and r["deploy_s"] is not None:
            a.axhline(r["deploy_s"], color="k", ls="--", lw=0.8, label="still air, no aero")
        if r["curves"] is not None:
            b.plot(r["curves"]["t"], r["curves"]["fold"], **style(r, "speed"))
    a.set(xlabel="flow speed (m/s)", ylabel="deployment time (s)", title="deploy_rigid (Otsuka et al. 2019, Fig. 11a)")
    b.set(xlabel="time (s)", ylabel="fold angle (deg)", title="deploy_rigid, uvlm-flat")
    REPORT.save(fig, "deployment_rigid", legend=7)
    fig, ((ax,),) = REPORT.figure(1, 1, 4.6, 3.2)    # Otsuka et al. 2019, Fig. 11b
    for part, scene, marker in ((1, "deploy_rigid", "o-"), (4, "deploy_wind_tunnel_2019", "s:")):
        scaled = [r for r in parts[part] if r["torque_scale"] is not None]
        ax.plot([r["speed"] for r in scaled], [r["torque_scale"] for r in scaled], marker, label=scene)
    ax.set(xlabel="flow speed (m/s)", ylabel="F = T_const / T_aero", yscale="log")
    ax.set_title("deployment torque scale (Otsuka et al. 2019, Fig. 11b)", fontsize=9)
    REPORT.save(fig, "deployment_torque_scale", legend=7)
    histories([r for r in parts[2] if not r["damping"]], "speed", "deployment_flexible",
              f"deploy_flexible, uvlm-flat, damping_model = {default}")
    histories(parts[3], "model", "deployment_fidelity", "deploy_flexible at 10 m/s, by aero.model")
    fig, axes = REPORT.figure(1, 2, 8.4, 3.2)        # peak bending and strain against flow speed, per damping
    for ax, key, ylabel in zip(axes[0], ("bend_mm", "strain_ue"),
                               ("peak |bending_100mm y| (mm)", "peak strain_20mm (microstrain)")):
        for damping, ls in (("", "-"), ("deformation", ":")):
            aero = [r for r in parts[2] if r["damping"] == damping and r["model"] != "none" and r["ok"]]
            if aero:
                ax.plot([r["speed"] for r in aero], [r[key] for r in aero], "o", ls=ls,
                        label=f"uvlm-flat, {damping or default}")
            for r in parts[2]:
                if r["damping"] == damping and r["model"] == "none" and r[key] is not None:
                    ax.axhline(r[key], color="k", ls="--" if ls == "-" else ":", lw=0.8,
                               label=f"still air, no aero, {damping or default}")
        ax.set(xlabel="flow speed (m/s)", ylabel=ylabel)
    axes[0, 0].set_title("Otsuka et al. 2019, Fig. 15", fontsize=9)
    axes[0, 1].set_title("Otsuka et al. 2022, Fig. 12", fontsize=9)
    REPORT.save(fig, "deployment_flexible_peaks", legend=7)
    histories([r for r in parts[4] if r["model"] == "none" or r["speed"] in (0.0, 10.0, 20.0)], "speed",
              "deployment_wind_tunnel_2019", "deploy_wind_tunnel_2019 (Otsuka et al. 2019, Table 2, PVC), uvlm-flat")
    fig, ((ax,),) = REPORT.figure(1, 1, 4.6, 3.2)    # Otsuka et al. 2019, Fig. 15: bending up to the latch and in all
    aero = [r for r in parts[4] if r["model"] != "none" and r["ok"]]
    for key, marker, label in (("bend_deploy_mm", "o-", "during the deployment (Fig. 15's D)"),
                               ("bend_mm", "s:", "whole run")):
        ax.plot([r["speed"] for r in aero], [r[key] for r in aero], marker, label=label)
    ax.set(xlabel="flow speed (m/s)", ylabel="max |bending_100mm y| (mm)")
    ax.set_title("deploy_wind_tunnel_2019 (Otsuka et al. 2019, Fig. 15)", fontsize=9)
    REPORT.save(fig, "deployment_wind_tunnel_2019_peaks", legend=7)


def histories(rows, by, name, title):
    """Three stacked panels against time (s): fold angle (deg), bending_100mm y (mm), strain_20mm (microstrain)."""
    fig, axes = REPORT.figure(3, 1, 6.5, 7.5)
    for ax, (key, ylabel) in zip(axes[:, 0], (("fold", "fold angle (deg)"), ("bend_mm", "bending_100mm y (mm)"),
                                              ("strain_ue", "strain_20mm (microstrain)"))):
        for r in rows:
            if r["curves"] is not None:
                ax.plot(r["curves"]["t"], r["curves"][key], **style(r, by))
        ax.set_ylabel(ylabel, fontsize=8)
    axes[0, 0].set_title(title, fontsize=9)
    axes[0, 0].legend(fontsize=7)
    axes[-1, 0].set_xlabel("time (s)")
    REPORT.save(fig, name)


def main(argv=None):
    args = REPORT.arguments(argv)
    parts = plan(args.quick)
    res = REPORT.run([j for jobs in parts.values() for j in jobs], work,
                     cost=lambda j: (1 if j.scene == "deploy_rigid" else 10 * STOP[j.scene] / 0.3) * COST[j.model],
                     describe=lambda j, r: f"{r['status']}, deployment {fmt(r['deploy_s'], '.4f')} s")
    rows = {part: [row(j, res[j]) for j in jobs] for part, jobs in parts.items()}
    structure = load("deploy_flexible")["structure"]
    if not args.no_plots:
        plot(rows, structure["damping_model"])
    scenes = {name: load(name) for name in STOP}
    REPORT.render(parts=rows, runs=len(res), paper=PAPER_2022, tip_time=TIP_TIME, default=structure["damping_model"],
                  pct=pct, ratio=ratio, rises=rises, after_latch=after_latch, alpha=structure["bodies"][0]["damping"],
                  paper_2019=PAPER_2019_MIN, scenes=scenes, stop=STOP, falls=falls)
    return REPORT.finish([r["label"] for rs in rows.values() for r in rs if not r["ok"]], len(res))


if __name__ == "__main__":
    raise SystemExit(main())
