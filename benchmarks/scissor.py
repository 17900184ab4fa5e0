"""Scissor structures: the three-SLE array of Peng et al. 2019, Sec. 5 (flexible against rigid bars and an
independent one-degree-of-freedom model) and the scissor-deployed wing in the wind (deployment time against
flow speed).

    python benchmarks/scissor.py [--quick] [--jobs 2] [--resume] [--no-plots] [--repeats 3]

Every run is `run_scene(scene, backend="direct")`, what `wingsim run SCENE --backend direct --set ...` runs:
  1. scissor_array, 0-0.6 s, flexible (the scene) and rigid (structure.fidelity=rigid) at rho_inf = 0.8 (the
     scene), 1, 0.5 and 0; the slider travel of a_1 against the rigid mechanism's Lagrange equation
     (tests/scissor_mechanism.py, imported by putting tests/ on sys.path; its data read from the scene), the
     flexible minus rigid positions of the pivots a_2..a_4 and the flexible a_2 - a_3, a_3 - a_4 y differences
     (Peng et al. 2019, Figs. 7 and 8); the pivots' velocities and accelerations as the run records them
     (timeseries.csv columns array_<pivot>_vx .. _ay): flexible against rigid, the flexible a_2..a_4 against each
     other and a_1's y acceleration against rho_inf (their Figs. 5, 7c-f, 9 and 10);
     the element models at the scene's rho_inf: rigid bars, the element of Otsuka et al. 2019 (flexible) and the
     shear-deformable element of Peng et al. 2019 (structure.fidelity=shear-deformable): their coordinate and
     constraint row counts (summary.json's structure_counts), their motion against the rigid bars' and the
     shear-deformable against the flexible, and their cost: the median CPU time (time.process_time, in the
     worker) of --repeats interleaved repeats of the three (every model once, then again), run after the
     other tasks so that every worker has imported the units;
  2. scissor_wing, rigid: the latch time of its revolute joint "deploy" (the deployment time) with uvlm-flat
     at 0, 5, 10, 15, 20 m/s and in still air without aero (aero.model=none); scissor_wing_flexible (the
     flexible plates at the scene's defaults: generalized-alpha, rho_inf 0.8, one 0.5 ms step per Gauss-Seidel
     exchange) at 10 m/s (the scene's speed) and 20 m/s to the scene's stop, and at 0 m/s to STILL_AIR_STOP.
--quick: the array to 0.3 s at the scene's rho_inf only, one cost repeat, the wing rigid at 0 and 10 m/s and
without aero, the flexible wing at 10 m/s.
"""
import shutil
import sys
import tempfile
import time
from dataclasses import dataclass

import numpy as np
from report import ROOT, Report, fmt, medians, status

from orchestrator.output.structure_counts import structure_counts
from orchestrator.run.master import RunResult, StructureCoordinates, run_scene
from orchestrator.output.mechanism_view import instant_indices, write_mechanism_view
from orchestrator.scene.load import load_scene

REPORT = Report("scissor", __doc__)
RHOS = (1.0, 0.8, 0.5, 0.0)              # rho_inf of the array (Peng et al. 2019); the scene's is run first
SPEEDS = (0.0, 5.0, 10.0, 15.0, 20.0)    # m/s, the wing with uvlm-flat
PIVOTS = ("a2", "a3", "a4")
POINTS = ("a1", *PIVOTS)
FLEXIBLE_SPEEDS = (0.0, 10.0, 20.0)      # m/s, scissor_wing_flexible with uvlm-flat
STILL_AIR_STOP = 0.41                    # s: in still air scissor_wing_flexible latches at 0.3985 s and its tip
                                         # SLE whips shut 20 ms later, a collision the model has no contact for
                                         # (the scene's header); the run stops between the two
# Peng et al. 2019, Sec. 5 (their sizes, not given in the paper's text, and a deployment of about 1.5 s):
# Fig. 7, largest flexible minus rigid difference in x and in y; Fig. 8b, largest flexible a_2 - a_3 and
# a_3 - a_4 y differences, both at 1.5 s.
PAPER = {"dx": 0.01498, "dy": 0.02503, "a2_a3": 0.01863, "a3_a4": 0.02203, "at": 1.5,
         # Fig. 7c-f, largest amplitude of the flexible bars' vibration in velocity and acceleration; Figs. 9b and
         # 10b, largest difference in y velocity and y acceleration between the flexible pivots a_2..a_4
         "dv": 0.3889, "da": 18.60, "v_apart": 0.7749, "a_apart": 27.20}
RATES = ("v", "a")                       # the recorded velocity (m/s) and acceleration (m/s^2) columns
ELEMENTS = {"rigid": "rigid bars", "flexible": "Otsuka et al. 2019 (flexible)",
            "shear-deformable": "Peng et al. 2019 (shear-deformable)"}   # the array's element models


@dataclass(frozen=True)
class Run:
    """One run: `scene` (file stem), structure `fidelity`, `rho_inf` (None: the scene's), flow `speed` (m/s,
    None: the scene's), aero `model` ("": the scene's), `stop` (s); `repeat` > 0 numbers a repeat that only
    measures the CPU time."""
    scene: str
    fidelity: str
    rho_inf: float | None
    speed: float | None
    model: str
    stop: float
    repeat: int = 0

    def config(self):
        return (self.scene, self.fidelity, self.rho_inf, self.speed, self.model, self.stop)

    def overrides(self):
        out = [f"structure.fidelity={self.fidelity}", f"time.stop={self.stop!r}"]
        out += [] if self.rho_inf is None else [f"structure.rho_inf={self.rho_inf!r}"]
        out += [] if self.speed is None else [f"flow.speed={self.speed!r}"]
        out += [f"aero.model={self.model}"] if self.model else []
        return out

    @property
    def label(self):
        flow = ("" if self.scene == "scissor_array" else ", still air, no aero" if self.model == "none"
                else f", uvlm-flat {self.speed:g} m/s")
        rho = "" if self.rho_inf is None else f", rho_inf {self.rho_inf:g}"
        repeat = f", cost repeat {self.repeat}" if self.repeat else ""
        return f"{self.scene} {self.fidelity}{rho}{flow}{repeat}"


def load(run):
    return load_scene(ROOT / "scenes" / f"{run.scene}.toml", run.overrides())


def work(run):
    """The run's status, CPU time (s) and either the array's probe tracks and mechanism frames or the wing's
    deployment time (s)."""
    cpu = time.process_time()
    result = run_scene(load(run), backend="direct")
    cpu = time.process_time() - cpu
    out = {"status": result.status, "message": result.message, "cpu_s": cpu,
           "simulated_s": result.simulated_time_s}
    if run.repeat:
        return out
    if run.scene != "scissor_array":
        return out | {"deploy_s": result.latch_times.get("deploy")}
    series = result.series
    out["t"] = series.time
    out |= {f"{p}_{kind}{axis}": series.column(f"array_{p}_{kind}{axis}") for p in POINTS for kind in ("", *RATES)
            for axis in "xy"}
    record = result.structure_coordinates
    chosen = instant_indices(record.t)
    out["frames"] = {"t": [record.t[i] for i in chosen], "e": [record.e[i] for i in chosen]}
    return out


def lagrange_travel(t):
    """The slider travel (m) of a_1 at the times t (s) by the one-degree-of-freedom model of the rigid array,
    with the scene's data; that data (n, L m, m kg, F N, rho I kg m, theta0 deg) and the model's time (s) to a
    given travel (m)."""
    sys.path.insert(0, str(ROOT / "tests"))
    from scissor_mechanism import simulate, slider_travel, time_to_angle

    scene = load_scene(ROOT / "scenes" / "scissor_array.toml")
    chain, (load_,) = scene["structure"]["scissors"][0], scene["structure"]["loads"]
    section = chain["section"]
    L = chain["bar_length"]
    data = {"n": chain["count"], "L": L, "m": section["chord"] * section["thickness"] * section["density"] * L,
            "F": float(np.linalg.norm(load_["force"])), "rotary": section["rotary_inertia"],
            "theta0": chain["initial_angle_deg"]}
    theta0 = np.radians(data["theta0"])
    run = simulate(theta0, t[-1], data["n"], L, data["m"], data["F"], rotary=data["rotary"], t_eval=t)
    if run.stop is not None:
        raise RuntimeError(f"the Lagrange model reached its {run.stop} configuration at {run.stop_time} s")

    def time_to(travel):
        return time_to_angle(theta0, np.arcsin(np.sin(theta0) - travel / L), data["n"], L, data["m"], data["F"],
                             rotary=data["rotary"])

    return slider_travel(run.theta, theta0, L), data, time_to


def peak(values, t):
    """(max |values|, the time (s) of it)."""
    k = int(np.argmax(np.abs(values)))
    return float(abs(values[k])), float(t[k])


def array_rows(res, flexible, rigid, reference, time_to):
    """The table cells of one rho_inf: slider travel and pivot differences, with their arrays for the plots and
    the pivot maxima (m)."""
    f, r = res[flexible], res[rigid]
    if "t" not in f or "t" not in r or len(f["t"]) != len(r["t"]) or len(r["t"]) != len(reference):
        return None
    t = np.asarray(f["t"])
    travel = {k: np.asarray(x["a1_y"][0]) - np.asarray(x["a1_y"]) for k, x in (("flexible", f), ("rigid", r))}
    d = {f"{p}_{axis}": np.asarray(f[f"{p}_{axis}"]) - np.asarray(r[f"{p}_{axis}"]) for p in PIVOTS for axis in "xy"}
    steps = {"a2_a3": np.asarray(f["a2_y"]) - np.asarray(f["a3_y"]),
             "a3_a4": np.asarray(f["a3_y"]) - np.asarray(f["a4_y"])}
    rigid_error = peak(travel["rigid"] - reference, t)
    rho = fmt(flexible.rho_inf, "g")
    travel_row = [rho, fmt(reference[-1], ".5f"), fmt(travel["rigid"][-1], ".5f"), fmt(travel["flexible"][-1], ".5f"),
                  fmt(rigid_error[0], ".2e"), fmt(rigid_error[0] / reference[-1], ".1e"),
                  fmt(time_to(travel["flexible"][-1]), ".4f"),
                  fmt(r["cpu_s"], ".1f"), fmt(f["cpu_s"], ".1f")]
    pivot_cells, maxima, times = [], [], []
    for axis in "xy":
        value, at, pivot = max(peak(d[f"{p}_{axis}"], t) + (p,) for p in PIVOTS)
        pivot_cells.append(f"{value:.5f} ({pivot}, {at:.3f} s)")
        maxima.append(value)
        times.append(at)
    for key in steps:
        value, at = peak(steps[key], t)
        pivot_cells.append(f"{value:.5f} ({at:.3f} s)")
        maxima.append(value)
        times.append(at)
    a1_vibration = (np.asarray(f["a1_ay"]) - np.asarray(r["a1_ay"]))[1:]
    a1_rms = float(np.sqrt(np.mean(a1_vibration**2)))
    rates, rates_cells = pivot_rates(f, r, t)
    return {"travel_row": travel_row, "pivot_row": [rho, *pivot_cells],
            "rates_row": [rho, *rates_cells, fmt(a1_rms, ".1f")], "rates": rates | {"a1_rms": a1_rms}, "t": t,
            "travel": travel, "d": d, "steps": steps, "maxima": maxima,
            "at_end": all(at == t[-1] for at in times)}


def pivot_rates(f, r, t):
    """The pivots' velocities and accelerations of one rho_inf, from the flexible `f` and rigid `r` runs' records:
    {"dv", "da": the largest |flexible - rigid| velocity (m/s) and acceleration (m/s^2) component over a_2..a_4;
    "v_apart", "a_apart": the largest y velocity and y acceleration difference between two flexible pivots of
    a_2..a_4} (the keys of PAPER), and their table cells (which pivot, axis or pair, and when)."""
    values, cells = {}, []
    for key, kind, digits in (("dv", "v", ".4f"), ("da", "a", ".1f")):
        value, at, pivot, axis = max(peak(np.asarray(f[f"{p}_{kind}{axis}"]) - np.asarray(r[f"{p}_{kind}{axis}"]), t)
                                     + (p, axis) for p in PIVOTS for axis in "xy")
        values[key] = value
        cells.append(f"{value:{digits}} ({pivot} {axis}, {at:.3f} s)")
    for key, kind, digits in (("v_apart", "v", ".4f"), ("a_apart", "a", ".1f")):
        value, at, pair = max(peak(np.asarray(f[f"{p}_{kind}y"]) - np.asarray(f[f"{q}_{kind}y"]), t) + (f"{p} - {q}",)
                              for i, p in enumerate(PIVOTS) for q in PIVOTS[i + 1:])
        values[key] = value
        cells.append(f"{value:{digits}} ({pair}, {at:.3f} s)")
    return values, cells


def element_rows(res, runs, configs, costs, counts, reference, time_to):
    """The element models' table rows at the scene's rho_inf, from the runs {fidelity: Run} (their results
    `res`), the cost repeats' medians `costs` ({config: (median CPU s, [CPU s], row)}, `configs` {fidelity:
    config}) and `counts` ({fidelity: structure_counts}); the largest |shear-deformable - flexible| pivot
    position (m) and velocity (m/s), and the models' median CPU times {fidelity: s}."""
    rigid, flexible, shear = (runs[f] for f in ELEMENTS)
    pairs = {f: array_rows(res, runs[f], rigid, reference, time_to) for f in ("flexible", "shear-deformable")}
    cpu = {f: costs[configs[f]][0] for f in ELEMENTS}
    size_rows, motion_rows = [], []
    for f, name in ELEMENTS.items():
        c, spent = counts[f], costs[configs[f]]
        size_rows.append([name, c["exchanged_coordinates"], c["coordinates"], c["constraint_rows"],
                          c["coordinates"] - c["constraint_rows"], fmt(cpu[f], ".2f"),
                          ", ".join(f"{x:.2f}" for x in spent[1]) or "-",
                          fmt(None if cpu[f] is None or not cpu["flexible"] else cpu[f] / cpu["flexible"], ".2f")])
        row = pairs.get(f)
        travel = row["travel_row"][3] if row else fmt(
            float(res[rigid]["a1_y"][0] - res[rigid]["a1_y"][-1]) if "t" in res[rigid] else None, ".5f")
        motion_rows.append([name, travel, *(row["pivot_row"][1:] if row else ["-"] * 4),
                            *(row["rates_row"][1:2] if row else ["-"])])
    d = {}
    if "t" in res[flexible] and "t" in res[shear]:
        t = np.asarray(res[flexible]["t"])
        s, f = res[shear], res[flexible]
        for key, kind in (("position", ""), ("velocity", "v")):
            d[key] = max(peak(np.asarray(s[f"{p}_{kind}{axis}"]) - np.asarray(f[f"{p}_{kind}{axis}"]), t) + (p, axis)
                         for p in PIVOTS for axis in "xy")
    return size_rows, motion_rows, d, cpu


def shear_correction(section, length):
    """Timoshenko's shear deflection over the bending deflection of a bar of depth h (m, in the plane of its
    bending) and span `length` (m), loaded at its end: (E I / (k G A)) / (L^2 / 3) = (E / (4 k G)) (h / L)^2 for a
    rectangle, with k = 1 (the element's uniform shear strain) and G = E / (2 (1 + nu)); with the section's data
    (chord, thickness, youngs_modulus, poissons_ratio)."""
    h, nu = section["thickness"], section["poissons_ratio"]
    return 2 * (1 + nu) / 4 * (h / length) ** 2


def main():
    args = REPORT.arguments(**{"--repeats": {"type": int, "default": 3,
                                             "help": "interleaved repeats of the element models' runs for their "
                                                     "cost (default 3)"}})
    repeats = 1 if args.quick else args.repeats
    scene_rho = load_scene(ROOT / "scenes" / "scissor_array.toml")["structure"]["rho_inf"]
    rhos = (scene_rho, *(r for r in RHOS if r != scene_rho))
    array_stop, rhos = (0.3, rhos[:1]) if args.quick else (0.6, rhos)
    array = {rho: (Run("scissor_array", "flexible", rho, None, "", array_stop),
                   Run("scissor_array", "rigid", rho, None, "", array_stop)) for rho in rhos}
    elements = {"rigid": array[scene_rho][1], "flexible": array[scene_rho][0],
                "shear-deformable": Run("scissor_array", "shear-deformable", scene_rho, None, "", array_stop)}
    # interleaved: every model once, then again
    repeated = [Run("scissor_array", f, scene_rho, None, "", array_stop, k) for k in range(1, repeats + 1)
                for f in ELEMENTS]
    wing_scene = load_scene(ROOT / "scenes" / "scissor_wing.toml")
    wing_stop = wing_scene["time"]["stop"]
    wing = [Run("scissor_wing", "rigid", None, v, "", wing_stop) for v in ((0.0, 10.0) if args.quick else SPEEDS)]
    wing.append(Run("scissor_wing", "rigid", None, 0.0, "none", wing_stop))
    flexible_scene = load_scene(ROOT / "scenes" / "scissor_wing_flexible.toml")
    flexible_stop = flexible_scene["time"]["stop"]
    flexible_wing = [Run("scissor_wing_flexible", flexible_scene["structure"]["fidelity"], None, v, "",
                         flexible_stop if v > 0 else STILL_AIR_STOP)
                     for v in ((flexible_scene["flow"]["speed"],) if args.quick else FLEXIBLE_SPEEDS)]
    runs = ([r for pair in array.values() for r in pair] + [elements["shear-deformable"]] + wing + flexible_wing
            + repeated)
    # the most costly first, the cost repeats last (cost 0, a stable sort keeps them interleaved)
    res = REPORT.run(runs, work, cost=lambda r: 0 if r.repeat else 1 if r.fidelity == "rigid" else 10,
                     describe=lambda r, x: f"{x['status']}, CPU {x['cpu_s']:.1f} s"
                     + (f", deployment {fmt(x['deploy_s'], '.4f')} s" if "deploy_s" in x else ""))
    failed = [r.label for r in runs if "error" in res[r] or res[r]["status"] != "ok"]

    rigid = res[array[rhos[0]][1]]
    t = np.asarray(rigid["t"]) if "t" in rigid else np.array([0.0, array_stop])
    reference, data, time_to = lagrange_travel(t)
    table = {rho: row for rho in rhos if (row := array_rows(res, *array[rho], reference, time_to)) is not None}
    theta = np.arcsin(np.sin(np.radians(data["theta0"])) - reference[-1] / data["L"])   # rad, rigid, at the stop
    lengths = [data["n"] * data["L"] * np.cos(a) for a in (np.radians(data["theta0"]), theta)]   # m, b_1 to b_n+1
    spread = max(np.ptp([row["maxima"][k] for row in table.values()]) for k in range(4)) if table else None
    counts = {f: structure_counts(load(r)) for f, r in elements.items()}
    size_rows, motion_rows, shear_vs_flexible, element_cpu = element_rows(
        res, elements, {f: r.config() for f, r in elements.items()}, medians(repeated, res), counts, reference,
        time_to)
    section = load(elements["flexible"])["structure"]["scissors"][0]["section"]
    wing_section = wing_scene["structure"]["scissors"][0]["section"]
    wing_length = wing_scene["structure"]["scissors"][0]["bar_length"]
    shear = {"array": {"L": data["L"], "h": section["thickness"], "c": section["chord"],
                       "half": shear_correction(section, data["L"] / 2), "whole": shear_correction(section, data["L"]),
                       "E_G": 2 * (1 + section["poissons_ratio"])},
             "wing": {"L": wing_length, "h": wing_section["thickness"],
                      "half": shear_correction(wing_section, wing_length / 2)}}
    shipped = table.get(scene_rho)

    def wing_row(run):
        x = res[run]
        structure = f"{run.fidelity} ({run.scene})"
        flow = "still air, no aero" if run.model == "none" else f"{run.speed:g} m/s, uvlm-flat"
        return [structure, flow, fmt(x.get("deploy_s"), ".4f"), fmt(run.stop, "g"), fmt(x.get("cpu_s"), ".1f"),
                short_status(x)]

    if not args.no_plots:
        plot(table, reference, res, array[rhos[0]][0], wing, flexible_wing)
        if scene_rho in table:
            plot_rates(table, res, array, scene_rho)
        plot_elements(res, elements)
    REPORT.render(array_stop=array_stop, data=data, scene_rho=scene_rho, final_angle=np.degrees(theta),
                  lengths=lengths, spread=spread, rho_list=", ".join(f"{r:g}" for r in table), rho_count=len(table),
                  maxima=None if shipped is None else shipped["maxima"],
                  at_end=all(row["at_end"] for row in table.values()),
                  travel_rows=[row["travel_row"] for row in table.values()],
                  pivot_rows=[row["pivot_row"] for row in table.values()], paper=PAPER,
                  rates_rows=[row["rates_row"] for row in table.values()],
                  rates={rho: row["rates"] for rho, row in table.items()},
                  a1_rms_falls_with_rho=all(table[low]["rates"]["a1_rms"] <= table[high]["rates"]["a1_rms"]
                                            for low, high in zip(sorted(table), sorted(table)[1:])),
                  size_rows=size_rows, motion_rows=motion_rows, shear_vs_flexible=shear_vs_flexible,
                  element_cpu=element_cpu, counts=counts, repeats=repeats, shear=shear,
                  wing_rows=[wing_row(r) for r in wing + flexible_wing], wing_stop=wing_stop,
                  flexible_stop=flexible_stop, still_air_stop=STILL_AIR_STOP, flexible_scene=flexible_scene,
                  flexible_wing=[(r.speed, res[r]) for r in flexible_wing], rigid_wing={
                      r.speed if r.model != "none" else "none": res[r].get("deploy_s") for r in wing},
                  messages=[(r.label, status(res[r])) for r in runs if r.label in failed])
    return REPORT.finish(failed, len(runs))


def short_status(x):
    """"ok", "error", or the status and the time (s) it was reached: the message follows the table."""
    if "error" in x:
        return "error"
    return "ok" if x["status"] == "ok" else f"{x['status']} at t = {x['simulated_s']:.4g} s"


def plot_rates(table, res, array, rho):
    """img/scissor_pivot_rates.png (the pivots' velocities and accelerations at the scene's rho_inf `rho`:
    flexible against rigid, Peng et al. 2019, Figs. 7c-f, 9 and 10) and scissor_a1_acceleration.png (a_1's y
    acceleration, flexible, at every rho_inf run, and rigid: their Fig. 5)."""
    t = table[rho]["t"]
    f, r = (res[run] for run in array[rho])
    fig, axes = REPORT.figure(2, 2, 11, 8)
    for row, (kind, unit, name) in enumerate((("v", "m/s", "velocity"), ("a", "m/s^2", "acceleration"))):
        for ax, axis in zip(axes[row], "xy"):
            for k, p in enumerate(PIVOTS):
                ax.plot(t, f[f"{p}_{kind}{axis}"], f"C{k}-", linewidth=0.8, label=f"{p} flexible")
                ax.plot(t, r[f"{p}_{kind}{axis}"], f"C{k}--", linewidth=1.2, label=f"{p} rigid")
            ax.set(xlabel="t (s)", ylabel=f"{axis} {name} ({unit})", title=f"pivots, {axis} {name}, rho_inf = {rho:g}")
    REPORT.save(fig, "scissor_pivot_rates", legend=7)

    # every rho_inf, the least dissipative (the highest) drawn first, under the others; then those below 1 after
    # t = 0 (the initial acceleration, the same for all, dwarfs them)
    rhos = sorted(table, key=lambda rho_k: -rho_k)
    fig, axes = REPORT.figure(1, 2, 12, 4)
    for ax, shown, start in ((axes[0, 0], rhos, 0), (axes[0, 1], [x for x in rhos if x < 1], 1)):
        for rho_k in shown:
            ax.plot(t[start:], res[array[rho_k][0]]["a1_ay"][start:], f"C{rhos.index(rho_k)}-", linewidth=0.8,
                    label=f"flexible, rho_inf {rho_k:g}")
        ax.plot(t[start:], r["a1_ay"][start:], "k--", label=f"rigid, rho_inf {rho:g}")
        ax.set(xlabel="t (s)", ylabel="y acceleration of a_1 (m/s^2)",
               title="slider a_1" + ("" if start == 0 else ", after t = 0, rho_inf < 1"))
    REPORT.save(fig, "scissor_a1_acceleration", legend=8)


def plot_elements(res, runs):
    """img/scissor_elements.png: the pivots' y, flexible - rigid and shear-deformable - rigid, and the
    shear-deformable - flexible positions and velocities of the pivots, from the runs {fidelity: Run}."""
    r, f, s = (res[runs[k]] for k in ELEMENTS)
    if any("t" not in x for x in (r, f, s)):
        return
    t = np.asarray(r["t"])
    fig, axes = REPORT.figure(1, 3, 15, 4)
    ax = axes[0, 0]
    for k, p in enumerate(PIVOTS):
        ax.plot(t, np.asarray(f[f"{p}_y"]) - np.asarray(r[f"{p}_y"]), f"C{k}-", linewidth=2.5, alpha=0.4,
                label=f"{p} flexible")
        ax.plot(t, np.asarray(s[f"{p}_y"]) - np.asarray(r[f"{p}_y"]), f"C{k}--", label=f"{p} shear-deformable")
    ax.set(xlabel="t (s)", ylabel="model - rigid y (m)", title="pivots against the rigid bars")
    for ax, kind, unit, name in ((axes[0, 1], "", "m", "position"), (axes[0, 2], "v", "m/s", "velocity")):
        for k, p in enumerate(PIVOTS):
            for axis, style in (("x", "-"), ("y", ":")):
                ax.plot(t, np.asarray(s[f"{p}_{kind}{axis}"]) - np.asarray(f[f"{p}_{kind}{axis}"]), f"C{k}{style}",
                        linewidth=0.8, label=f"{p} {axis}")
        ax.set(xlabel="t (s)", ylabel=f"shear-deformable - flexible {name} ({unit})", title=f"pivots, {name}")
    REPORT.save(fig, "scissor_elements", legend=7)


def plot(table, reference, res, flexible, wing, flexible_wing):
    """img/scissor_slider_travel.png, scissor_pivot_differences.png, scissor_deployment_time.png and
    scissor_mechanism.png (the flexible array at the scene's rho_inf)."""
    shipped = table.get(flexible.rho_inf)
    if shipped is not None:
        t = shipped["t"]
        fig, axes = REPORT.figure(1, 2, 11, 4)
        ax = axes[0, 0]
        ax.plot(t, reference, "k-", linewidth=3, alpha=0.35, label="Lagrange model (rigid)")
        for name, style in (("rigid", "C0--"), ("flexible", "C1-")):
            ax.plot(t, shipped["travel"][name], style, label=f"{name} bars")
        ax.set(xlabel="t (s)", ylabel="slider travel of a_1 (m)", title=f"rho_inf = {flexible.rho_inf:g}")
        ax = axes[0, 1]
        for rho, row in table.items():
            ax.plot(t, row["travel"]["flexible"] - row["travel"]["rigid"], label=f"flexible - rigid, rho_inf {rho:g}")
        ax.plot(t, shipped["travel"]["rigid"] - reference, "k:",
                label=f"rigid - Lagrange, rho_inf {flexible.rho_inf:g}")
        ax.set(xlabel="t (s)", ylabel="difference in travel (m)", title="differences")
        REPORT.save(fig, "scissor_slider_travel", legend=8)

        fig, axes = REPORT.figure(2, 2, 11, 8)
        for ax, axis in zip(axes[0], "xy"):
            for p in PIVOTS:
                ax.plot(t, shipped["d"][f"{p}_{axis}"], label=p)
            ax.set(xlabel="t (s)", ylabel=f"flexible - rigid {axis} (m)",
                   title=f"pivots, {axis}, rho_inf = {flexible.rho_inf:g}")
        ax = axes[1, 0]
        for key, label in (("a2_a3", "a_2 - a_3"), ("a3_a4", "a_3 - a_4")):
            ax.plot(t, shipped["steps"][key], label=label)
        ax.set(xlabel="t (s)", ylabel="y difference (m)", title=f"flexible bars, rho_inf = {flexible.rho_inf:g}")
        ax = axes[1, 1]
        for rho, row in table.items():
            ax.plot(t, np.max(np.abs([row["d"][f"{p}_y"] for p in PIVOTS]), axis=0), label=f"rho_inf {rho:g}")
        ax.set(xlabel="t (s)", ylabel="max over a_2..a_4 of |flexible - rigid y| (m)", title="against rho_inf")
        REPORT.save(fig, "scissor_pivot_differences", legend=8)

    frames = res[flexible].get("frames")
    if frames:
        scene = load(flexible)
        record = StructureCoordinates(t=frames["t"], e=[np.asarray(e) for e in frames["e"]])
        x = res[flexible]
        result = RunResult(x["status"], x["message"], 0.0, x["simulated_s"], scene, None,
                           structure_coordinates=record)
        with tempfile.TemporaryDirectory() as tmp:
            path = REPORT.out / "img" / "scissor_mechanism.png"
            shutil.copyfile(write_mechanism_view(result, tmp), path)
        print(f"wrote {path.relative_to(ROOT)}")

    fig, axes = REPORT.figure(1, 1, 6, 4)
    ax = axes[0, 0]
    points = [(r.speed, res[r].get("deploy_s")) for r in wing if r.model != "none"]
    points = [p for p in points if p[1] is not None]
    if points:
        ax.plot(*zip(*points), "o-", label="rigid, uvlm-flat")
    calm = [res[r].get("deploy_s") for r in wing if r.model == "none"]
    if calm and calm[0] is not None:
        ax.axhline(calm[0], color="k", linestyle=":", label="rigid, still air without aero")
    points = [(r.speed, res[r].get("deploy_s")) for r in flexible_wing]
    points = [p for p in points if p[1] is not None]
    if points:
        ax.plot(*zip(*points), "s--", label="flexible (scissor_wing_flexible), uvlm-flat")
    ax.set(xlabel="flow speed (m/s)", ylabel="deployment time (s)", title="scissor_wing: latch of 'deploy'")
    REPORT.save(fig, "scissor_deployment_time", legend=8)


if __name__ == "__main__":
    sys.exit(main())
