"""Stability map: the largest stable structural step of RK4 and generalized-alpha against stiffness, and
explicit against implicit coupling against flow speed and air density.

    python benchmarks/stability.py [--quick] [--jobs 2] [--resume] [--no-plots]

scenes/stability_wing.toml, a clamped wing under a sudden tip load (templates/stability.md says what "stable"
means), in five parts: 1. the largest stable structure.step against Young's modulus; 2. a map of flow speed x
air density per coupling algorithm (the unstable runs the units did not report run on to RUN_ON_STOP);
3. the largest stable coupling.step against density; 4. structure steps per coupling step; 5. flutter at
60 m/s. The estimates the map is compared with are orchestrator.studies.stability's. --quick: a few of each.
"""
import math
import re
from collections import Counter
from dataclasses import dataclass

import numpy as np
from report import Report, fmt, span, table

from orchestrator.studies import stability
from orchestrator.scene.load import load_scene
from orchestrator.studies.stability import grid_probe, grid_step as step_of

REPORT = Report("stability", __doc__)
SCENE = REPORT.root / "scenes" / "stability_wing.toml"
AIR = 1.2                          # kg/m^3, the density factors multiply it
RUNAWAY = "stability map: runaway"
RUNAWAY_FACTOR = 100.0             # stop a run once KE > RUNAWAY_FACTOR x P delta_s
COUPLING_STEP = 1e-3               # s, coupling.step of part 2 (deploy_flexible's)
SUBSTEPS = 4                       # structure steps per coupling step in the coupled runs
RHO_INF = load_scene(SCENE)["structure"]["rho_inf"]   # generalized-alpha's in the coupled runs: the scene's
COUPLED_STOP = 0.05                # s, time.stop of the coupled runs (at least 20 coupling steps in part 3)
RUN_ON_STOP = 0.2                  # s, part 2's runs the units did not report, run on without the runaway stop
LINE_SPEED = 10.0                  # m/s, part 3 (deploy_flexible's flow speed)
LINE_TOP = 4e-3                    # s, largest coupling step of part 3: structure steps <= 1 ms (part 1's limit)
IMPLICIT_SPEEDS = (0.0, 20.0, 40.0, 60.0)   # m/s, part 2's implicit runs (each costs about ten explicit ones)
SUBSTEP_CASE = (0.5e-3, (15.0, 25.0, 35.0, 50.0), (1, 2, 4, 8))   # part 4: coupling step (s), densities, substeps
FLUTTER_CASE = (60.0, 3.0, (1e-3, 5e-4, 2.5e-4))   # part 5: speed (m/s), density factor, coupling steps (s)
INTEGRATORS = (("rk4", None), ("generalized-alpha", 1.0), ("generalized-alpha", 0.8),
               ("generalized-alpha", 0.5), ("generalized-alpha", 0.0))
ALGORITHMS = ("gauss-seidel", "jacobi", "implicit")
EXPLICIT = ("gauss-seidel", "jacobi")
SYMBOL = {"": "S", "solver": "D", "runaway": "R", "energy": "E", "displacement": "X", "error": "!"}


def probe(overrides, watch=True):
    """One run of the scene with `overrides` (orchestrator.studies.stability.sudden_load_run at the tip, stopped at
    RUNAWAY_FACTOR P delta_s if `watch`) and twist_max (deg): the tip chord line turning out of its plane at rest."""
    record, series = stability.sudden_load_run(load_scene(SCENE, overrides), "wing", "tip",
                                               RUNAWAY_FACTOR if watch else None, RUNAWAY)
    chord = [series.column(f"tip_trailing_edge_{a}") - series.column(f"tip_leading_edge_{a}") for a in "xy"]
    with np.errstate(invalid="ignore"):    # chord x at rest, turning towards the section normal y; span along z
        twist = float(np.nanmax(np.abs(np.degrees(np.arctan2(chord[1], chord[0]))))) if len(series) else math.nan
    return record | {"twist_max": twist}


# ---- the tasks (their repr is the key of their record in results/studies/stability.jsonl) -----------------
@dataclass(frozen=True)
class StepSearch:
    """Part 1: the largest stable structure.step of `integrator` (rho_inf `rho`) at Young's modulus E (Pa)."""
    E: float
    integrator: str
    rho: float | None

    def run(self):
        omega_1, omega_max = stability.frequency_range(load_scene(SCENE, stiffness(self.E)))
        period = 2 * math.pi / omega_1
        stop = 2 * period if self.rho is not None else 200 * 2 * math.pi / omega_max
        common = [*stiffness(self.E), f"structure.integrator={self.integrator}", f"time.stop={stop!r}"]
        common += [f"structure.rho_inf={self.rho!r}"] if self.rho is not None else []

        def run(h):
            sample = h * max(1, round(stop / (50 * h)))             # about 50 samples, a whole number of steps
            return probe([*common, f"structure.step={h!r}", f"coupling.step={sample!r}"], watch=False)

        return {"omega_1": omega_1, "omega_max": omega_max, "stop": stop,
                **stability.largest_stable_step(run, period / 4, fine=16, octaves=14)}


@dataclass(frozen=True)
class Coupled:
    """Parts 2, 4, 5: one uvlm-flat run of `algorithm` at flow.speed V (m/s), density factor x 1.2 kg/m^3,
    coupling.step `step` (s) in `substeps` structure steps, until `stop` (s), stopped as a runaway if `watch`."""
    algorithm: str
    V: float
    factor: float
    step: float = COUPLING_STEP
    substeps: int = SUBSTEPS
    stop: float = COUPLED_STOP
    watch: bool = True

    @property
    def label(self):
        return (f"{self.algorithm} at {self.V:g} m/s, {self.factor:g} x air, coupling step {self.step * 1e3:g} ms "
                f"in {self.substeps} steps, {self.stop:g} s")

    def run(self):
        return probe(["aero.model=uvlm-flat", f"coupling.algorithm={self.algorithm}", f"flow.speed={float(self.V)!r}",
                      f"flow.density={AIR * self.factor!r}", f"coupling.step={self.step!r}",
                      f"structure.step={self.step / self.substeps!r}", f"structure.rho_inf={RHO_INF!r}",
                      f"time.stop={self.stop!r}"], self.watch)


@dataclass(frozen=True)
class CouplingSearch:
    """Part 3: the largest stable coupling.step of `algorithm` at flow.speed V (m/s) and density factor, on the
    grid LINE_TOP 2^(-k/4) down to `octaves` octaves."""
    algorithm: str
    V: float
    factor: float
    octaves: int

    def run(self):
        return stability.largest_stable_step(
            lambda h: Coupled(self.algorithm, self.V, self.factor, h, stop=max(COUPLED_STOP, 20 * h)).run(),
            LINE_TOP, fine=4, octaves=self.octaves)


def stiffness(E):
    """--set overrides scaling every stiffness of the wing to Young's modulus E (Pa)."""
    return stability.stiffness_overrides(load_scene(SCENE), "wing", E)


def integrator_label(rho):
    return "RK4" if rho is None else f"gen-alpha rho_inf = {rho:g}"


def plan(quick=False):
    """{part: [task, ...]} in table order."""
    stiffnesses = (1e6, 1e12) if quick else tuple(10.0 ** np.arange(6, 13))
    speeds = (0.0, 40.0) if quick else (0.0, 10.0, 20.0, 30.0, 40.0, 50.0, 60.0)
    factors = (1.0, 30.0) if quick else (0.1, 0.3, 1.0, 3.0, 10.0, 20.0, 30.0, 100.0)
    (step, densities, substeps), (flutter_speed, flutter_factor, steps) = SUBSTEP_CASE, FLUTTER_CASE
    return {1: [StepSearch(E, i, r) for E in stiffnesses for i, r in (INTEGRATORS[::2][:2] if quick else INTEGRATORS)],
            2: [Coupled(a, V, f) for a in (("gauss-seidel", "implicit") if quick else ALGORITHMS) for f in factors
                for V in speeds if a != "implicit" or V in IMPLICIT_SPEEDS],
            3: [CouplingSearch("gauss-seidel", LINE_SPEED, f, 5) for f in ((1.0, 30.0) if quick else
                                                                            (0.1, 1.0, 3.0, 10.0, 20.0, 30.0, 100.0))]
               + [CouplingSearch("implicit", LINE_SPEED, f, 3)
                  for f in ((1.0,) if quick else (1.0, 10.0, 30.0, 100.0))],
            4: [Coupled("gauss-seidel", 0.0, f, step, k) for f in (densities[1:2] if quick else densities)
                for k in substeps],
            5: [Coupled(a, flutter_speed, flutter_factor, h) for a in ("gauss-seidel", "implicit")
                for h in steps[:1 if quick else 3]]}


def cost(task):
    """Rough relative cost, to start the longest tasks first."""
    if isinstance(task, StepSearch):
        return 8 if task.integrator == "rk4" else 5
    if isinstance(task, CouplingSearch):
        return 15 if task.algorithm == "implicit" else 6
    return (6 if task.algorithm == "implicit" else 1) * COUPLING_STEP / task.step * task.stop / COUPLED_STOP


def work(task):
    return task.run()


def describe(task, out):
    """One-line outcome of a task."""
    if "rows" not in out:
        return "stable" if out["stable"] else f"unstable ({out['why']}: {out['status']})"
    return f"largest stable step {fmt(step_of(out, 'stable'), '.3g')} s, {len(out['rows'])} runs"


def estimates():
    """The numbers the coupling map is compared with (orchestrator.studies.stability, independent of the runs; SI
    units, mu_* per kg/m^3 of air, mu_crit_* -), with divergence_speed(density factor) (m/s) and
    onset_factor(mu_crit), the density factor at which the lattice's largest added-mass ratio reaches it."""
    scene = load_scene(SCENE, ["aero.model=uvlm-flat"])
    body = scene["structure"]["bodies"][0]
    section, length = body["section"], body["length"]
    c = section["chord"]
    mu_max, mu_1, modes = stability.lattice_added_mass(scene, "wing")
    slope = stability.lift_slope(scene)
    e = (section["axis_position"] - 0.25) * c                          # m, aerodynamic centre ahead of the axis
    mu_crit = lambda lag, substeps=SUBSTEPS: stability.critical_mass_ratio(lag, substeps, RHO_INF)
    q_D = stability.divergence_pressure(section["torsional_rigidity"], length, c, e, slope)
    return {"m_s": section["density"] * c * section["thickness"],        # kg/m, structure per unit span
            "plate": math.pi * c ** 2 / 4,                               # m^2: m_a = rho pi c^2 / 4 per kg/m^3
            "M": scene["aero"]["chordwise_panels"], "mu_max": mu_max, "mu_1": mu_1, "modes": modes,
            "mu_crit": {a: mu_crit(lag) for a, lag in stability.LAGS.items()},
            "mu_crit_plain": {a: mu_crit(lag, 256) for a, lag in stability.LAGS.items()},
            "mu_crit_substeps": {k: mu_crit(0, k) for k in SUBSTEP_CASE[2]},
            "slope": slope, "aspect": length / c, "q_D": q_D,
            "divergence_speed": lambda factor: stability.divergence_speed(q_D, AIR * factor),
            "onset_factor": lambda mu: mu / (mu_max * AIR)}


def modal_growth(est, algorithm, factor):
    """(predicted peak kinetic energy / (P delta_s), mode) at the end of a part 2 run at 0 m/s."""
    return stability.modal_growth(est["modes"], AIR * factor, stability.LAGS[algorithm], COUPLING_STEP,
                                  round(COUPLED_STOP / COUPLING_STEP), SUBSTEPS, RHO_INF)


# ---- reading the results --------------------------------------------------------------------------------
def reason(message):
    """The units' reason in a "diverged" message, without the call, the time and the hint."""
    text = re.sub(r"^(structure|aero) unit: solver ", "", message.split("failed: ")[-1].split(". Hint")[0])
    return re.sub(r"^diverged at t = [^:]*: ", "", text).replace("|", "/")


def how(row):
    """How an unstable run failed: D/R/E/X, the time reached (s) and the units' reason or the bound exceeded."""
    text = {"runaway": f"KE {row['ke_max']:.3g} J > {RUNAWAY_FACTOR:g} P delta_s",
            "energy": f"status ok, KE max {row['ke_max']:.3g} J > P delta_s = {row['ke_bound']:.3g} J",
            "displacement": f"status ok, tip {1e3 * row['tip_max']:.3g} mm > {1e3 * row['tip_bound']:.3g} mm",
            }.get(row["why"]) or reason(row["message"])
    return f"{SYMBOL[row['why']]} at t = {row['simulated_s']:.3g} s: {text}"


def cell(out):
    """A map cell: S, or D/R/E/X and the time (ms) at which the run ended."""
    if "error" in out:
        return "error"
    return "S" if out["stable"] else f"{SYMBOL[out['why']]} {1e3 * out['simulated_s']:.0f} ms"


def search_cell(out):
    """Largest stable step (s) of a search, or why there is none."""
    if "error" in out:
        return "error"
    if out["stable"] is None:
        return f"none >= {step_of(out, 'unstable'):.3g}"
    return f"{step_of(out, 'stable'):.3g}" + (" (top of grid)" if out["unstable"] is None else "")


def failure(out):
    """how() of the smallest unstable probe of a search, or "-"."""
    return "-" if "rows" not in out or out.get("unstable") is None else how(grid_probe(out, "unstable"))


def results(res, part, ok=False, **fields):
    """The results of the tasks of `part` with `fields` (if `ok`, those without an error), in task order."""
    return [res[t] for t in part
            if all(getattr(t, k) == v for k, v in fields.items()) and not (ok and "error" in res[t])]


def find(res, part, **fields):
    """The result of the task of `part` with `fields`, or None."""
    return next(iter(results(res, part, **fields)), None)


def onset(res, part, algorithm, V):
    """(largest stable density factor, the next one, unstable) at speed V, walking up the densities."""
    stable = None
    for f in sorted({t.factor for t in part}):
        out = find(res, part, algorithm=algorithm, V=V, factor=f)
        if out is None:
            continue
        if "error" in out or not out["stable"]:
            return stable, f
        stable = f
    return stable, None


def unflagged(res, part):
    """Part 2 tasks unstable by the bounds without a "diverged" from the units."""
    return [t for t in part if "error" not in res[t] and res[t]["why"] in ("runaway", "energy", "displacement")]


def run_on(task):
    """The task that runs `task` on to RUN_ON_STOP without the runaway stop."""
    return Coupled(task.algorithm, task.V, task.factor, task.step, task.substeps, RUN_ON_STOP, watch=False)


def check_named(message):
    """Which of the units' checks stopped a "diverged" run, from its message."""
    return next((name for key, name in (("Newton", "Newton iteration"), ("NaN", "NaN/inf"),
                                        ("constraint residual", "constraint residual"),
                                        ("gradient vectors", "gradient size"),
                                        ("implicit coupling", "implicit iteration")) if key in message), "other")


# ---- tables (markdown text) -----------------------------------------------------------------------------------
def table_run_on(res, part):
    """Part 2's runs the units did not report, run on to RUN_ON_STOP: per algorithm, how many the units
    reported "diverged", when (s), how long after the response left the bounds (ms), the largest kinetic
    energy (x P delta_s), which checks stopped them, and the runs not reported. Also the count reported."""
    rows = []
    for a in ALGORITHMS:
        mine = [res[run_on(t)] for t in unflagged(res, part) if t.algorithm == a and run_on(t) in res]
        if not mine:
            continue
        reported = [r for r in mine if "error" not in r and r["why"] == "solver"]
        checks = Counter(check_named(r["message"]) for r in reported)
        lags = [1e3 * (r["simulated_s"] - r["unbounded_s"]) for r in reported if not math.isnan(r["unbounded_s"])]
        rows.append([a, str(len(mine)), str(len(reported)),
                     span([r["simulated_s"] for r in reported], ".3f") if reported else "-",
                     span(lags, ".0f") if lags else "-",
                     f"{max(r['ke_max'] / r['ke_bound'] for r in reported):.3g}" if reported else "-",
                     ", ".join(f"{name} {count}" for name, count in sorted(checks.items())) or "-",
                     str(len(mine) - len(reported))])
    return table(["algorithm", "runs", "reported \"diverged\"", "at t (s)", "after the response left the bounds (ms)",
                  "largest KE (x P delta_s)", "stopped by", f"not reported by {RUN_ON_STOP:g} s"], rows), \
        sum(int(r[2]) for r in rows)


# ---- the facts the report words -------------------------------------------------------------------------------
def stiffness_facts(res, part):
    """Part 1: RK4's bracket of its estimate and the fitted exponent of E; per rho_inf the ratios to RK4's step
    and the steps per first period; how many generalized-alpha searches ended at a Newton failure."""
    rk4 = [(t.E, res[t]) for t in part if t.rho is None and "error" not in res[t]]
    bracket = {w: [step_of(r, w) * r["omega_max"] / stability.RK4_IMAGINARY for _, r in rk4 if step_of(r, w)]
               for w in ("stable", "unstable")}
    pts = np.array([(E, step_of(r, "stable")) for E, r in rk4 if step_of(r, "stable")])
    rk4_step = {E: step_of(r, "stable") for E, r in rk4}
    ga = {}
    for rho in dict.fromkeys(t.rho for t in part if t.rho is not None):
        steps = [(t.E, step_of(res[t], "stable"), res[t]["omega_1"]) for t in part
                 if t.rho == rho and "error" not in res[t] and step_of(res[t], "stable")]
        ratios = [h / rk4_step[E] for E, h, _ in steps if rk4_step.get(E)]
        if ratios:
            ga[rho] = (span(ratios, ".0f"), span([2 * math.pi / w / h for _, h, w in steps], ".0f"))
    searches = [t for t in part if t.rho is not None and "error" not in res[t] and res[t].get("unstable") is not None]
    return {"low": span(bracket["stable"], ".3f") if bracket["stable"] else None,
            "high": span(bracket["unstable"], ".3f") if bracket["unstable"] else None,
            "exponent": float(np.polyfit(np.log(pts[:, 0]), np.log(pts[:, 1]), 1)[0]) if len(pts) > 1 else math.nan,
            "ga": ga, "ga_searches": len(searches),
            "newton": sum("Newton" in grid_probe(res[t], "unstable")["message"] for t in searches)}


def coupling_facts(res, part, est):
    """Part 2: measured onsets at the lowest speed, the free-mass estimate's overshoot, the modal prediction's
    first unstable density, and the runs the units did not report or that failed otherwise."""
    V = min(t.V for t in part)
    measured = {a: onset(res, part, a, V) for a in dict.fromkeys(t.algorithm for t in part)}
    overshoot = {}
    for a, (low, high) in measured.items():
        predicted = est["onset_factor"](est["mu_crit"][a]) if a in est["mu_crit"] else None
        if predicted is not None and high is not None and predicted > high:
            overshoot[a] = (f"{predicted / high:.2g} to {predicted / low:.2g}" if low else
                            f"at least {predicted / high:.2g}")
    first = {}
    for a in EXPLICIT:
        for f in sorted({t.factor for t in part}):
            energy, mode = modal_growth(est, a, f)
            if energy > 1.0:
                first[a] = (f, mode)
                break
    flagged = [(t, res[t]) for t in unflagged(res, part)]
    failed = [(t, res[t]) for t in part if t.algorithm == "implicit" and "error" not in res[t]
              and res[t]["why"] == "solver"]
    residuals = [float(m.group(1)) for _, r in failed
                 if (m := re.search(r"interface residual ([0-9.e+-]+) after", r["message"]))]
    run_on_table, reported = table_run_on(res, part)
    return {"V": V, "total": len(part), "measured": measured, "overshoot": overshoot, "first": first,
            "flagged": flagged, "ended_ok": [(t, r) for t, r in flagged if r["status"] == "ok"],
            "run_on": [run_on(t) for t, _ in flagged if run_on(t) in res], "run_on_table": run_on_table,
            "reported": reported,
            "errors": [(t, res[t]) for t in part if "error" in res[t] or res[t]["why"] == "error"],
            "failed": failed, "residuals": residuals, "newton": sum("Newton" in r["message"] for _, r in failed)}


def flutter_trends(res, part):
    """Part 5, per algorithm: (largest and smallest step in ms, how the peak kinetic energy moves as the step
    shrinks, the energies (J) from the largest step down, stable at the smallest step)."""
    out = {}
    for a in ("gauss-seidel", "implicit"):
        runs = sorted((t.step, res[t]) for t in part if t.algorithm == a and "error" not in res[t])
        if len(runs) > 1:
            energies = [r["ke_max"] for _, r in reversed(runs)]
            trend = ("rises" if all(np.diff(energies) > 0) else "falls" if all(np.diff(energies) < 0)
                     else "changes non-monotonically")
            out[a] = (runs[-1][0] * 1e3, runs[0][0] * 1e3, trend, energies, runs[0][1]["stable"])
    return out


def line_facts(res, part, stiffness_part):
    """Part 3: the densities without a stable Gauss-Seidel step and the smallest step tried there (s), the
    searches that ended at a Newton failure, and part 1's own limit of generalized-alpha scaled to the scene."""
    none = sorted(t.factor for t in part if t.algorithm == "gauss-seidel" and "error" not in res[t]
                  and res[t]["stable"] is None)
    smallest = min((step_of(res[t], "unstable") for t in part if t.algorithm == "gauss-seidel" and t.factor in none),
                   default=None)
    newton = [t for t in part if "error" not in res[t] and res[t].get("unstable") is not None
              and "Newton" in grid_probe(res[t], "unstable")["message"]]
    E_scene = load_scene(SCENE)["structure"]["bodies"][0]["section"]["youngs_modulus"]
    own = [step_of(res[t], "stable") * math.sqrt(t.E / E_scene) for t in stiffness_part
           if t.rho == RHO_INF and "error" not in res[t] and step_of(res[t], "stable")]
    return {"total": len(part), "none": none, "smallest": smallest, "newton": newton,
            "own": f"{span([1e3 * h for h in own], '.2g')} ms" if own else "-"}


# ---- figures ----------------------------------------------------------------------------------------------
def plot_stiffness(res, part):
    """Left: largest stable step (s) against E (Pa), log-log, with the RK4 estimate and the top of the grid;
    right: the same steps times omega_max (-), with RK4's 2 sqrt(2)."""
    fig, ((ax, bx),) = REPORT.figure(1, 2, 11.0, 4.4)
    first = {t.E: res[t] for t in reversed(part) if "error" not in res[t]}
    Es = sorted(first)
    ax.loglog(Es, [stability.rk4_step_limit(first[E]["omega_max"]) for E in Es], "k--", lw=1,
              label="RK4 estimate 2 sqrt(2) / omega_max")
    ax.loglog(Es, [first[E]["top"] for E in Es], ":", color="0.5", lw=1, label="top of the grid T_1 / 4")
    bx.axhline(stability.RK4_IMAGINARY, color="k", ls="--", lw=1, label="2 sqrt(2)")
    markers = {None: "o", 1.0: "s", 0.8: "^", 0.5: "v", 0.0: "D"}
    for rho in dict.fromkeys(t.rho for t in part):
        runs = [res[t] | {"E": t.E} for t in part if t.rho == rho and "error" not in res[t]]
        for which, fill in (("stable", None), ("unstable", "none")):
            pts = [(r["E"], step_of(r, which), r["omega_max"]) for r in runs if step_of(r, which)]
            if pts:
                E, h, w = (np.array(v) for v in zip(*pts))
                style = {"marker": markers[rho], "mfc": fill, "color": f"C{list(markers).index(rho)}", "ms": 5,
                         "ls": "-" if which == "stable" else "none", "lw": 1,
                         "label": integrator_label(rho) if which == "stable" else None}
                ax.loglog(E, h, **style)
                bx.semilogx(E, h * w, **style)
    ax.set(xlabel="Young's modulus E (Pa)", ylabel="structure.step (s)")
    bx.set(xlabel="Young's modulus E (Pa)", ylabel="structure.step x omega_max (-)", yscale="log")
    ax.set_title("Largest stable step (filled), next grid step: unstable (open)", fontsize=9)
    bx.set_title("The same in units of 1 / omega_max (highest mode)", fontsize=9)
    REPORT.save(fig, "stability_stiffness", legend=7)


STYLE = {"": ("o", "tab:green", "stable"), "solver": ("x", "tab:red", "diverged (reported by the units)"),
         "runaway": ("^", "tab:purple", f"runaway: KE > {RUNAWAY_FACTOR:g} P delta_s (not reported)"),
         "energy": ("s", "tab:orange", "status ok, KE > P delta_s"),
         "displacement": ("D", "tab:brown", "status ok, tip > 4 delta_s"), "error": ("*", "k", "status error")}


def plot_coupling(res, part, est):
    """One panel per algorithm: speed (m/s) x density factor (log), a marker per run, the divergence speed and
    the added-mass onset estimates drawn over."""
    algorithms = list(dict.fromkeys(t.algorithm for t in part))
    fig, (axes,) = REPORT.figure(1, len(algorithms), 4.2 * len(algorithms), 5.0)
    factors = np.geomspace(min(t.factor for t in part), max(t.factor for t in part), 100)
    legend = {}
    for ax, algorithm in zip(axes, algorithms):
        for t in (t for t in part if t.algorithm == algorithm and "error" not in res[t]):
            marker, color, label = STYLE[res[t]["why"]]
            legend[label], = ax.semilogy(t.V, t.factor, marker=marker, color=color, ls="none", ms=7)
        legend["torsional divergence speed (static estimate)"], = ax.semilogy(
            [est["divergence_speed"](f) for f in factors], factors, "k--", lw=1)
        if algorithm in est["mu_crit"]:
            mu = est["mu_crit"][algorithm]
            ax.axhline(est["onset_factor"](mu), color="tab:blue", lw=1, ls=":")
            ax.text(62, est["onset_factor"](mu) * 1.1, f"added-mass estimate, mu = {mu:.2f}", fontsize=6,
                    ha="right", color="tab:blue")
        ax.set(xlim=(-3, 63), ylim=(min(factors) / 1.5, max(factors) * 1.5), xlabel="flow speed (m/s)",
               ylabel="density / 1.2 kg/m^3", title=algorithm)
    fig.legend(list(legend.values()), list(legend), loc="lower center", ncol=3, fontsize=7)
    REPORT.save(fig, "stability_coupling", rect=(0, 0.1, 1, 1))


def plot_line(res, part):
    """Largest stable coupling step (s) against density factor, per algorithm."""
    fig, ((ax,),) = REPORT.figure(1, 1, 5.5, 3.8)
    for a, marker, color in (("gauss-seidel", "o", "tab:blue"), ("implicit", "s", "tab:green")):
        runs = [res[t] | {"f": t.factor} for t in part if t.algorithm == a and "error" not in res[t]]
        for which, fill, text in (("stable", None, "largest stable"),
                                  ("unstable", "none", "smallest unstable step tried")):
            pts = [(r["f"], step_of(r, which)) for r in runs if step_of(r, which)]
            if pts:
                ax.loglog(*zip(*pts), marker=marker, mfc=fill, lw=1, ls="-" if fill is None else "none", color=color,
                          label=f"{a}: {text}")
    ax.axhline(LINE_TOP, color="0.5", ls=":", lw=1, label="top of the grid")
    ax.set(xlabel="density / 1.2 kg/m^3", ylabel="coupling.step (s)")
    ax.set_title(f"uvlm-flat at {LINE_SPEED:g} m/s, {SUBSTEPS} structure steps per coupling step", fontsize=9)
    REPORT.save(fig, "stability_coupling_step", legend=7)


def main(argv=None):
    args = REPORT.arguments(argv)
    parts = plan(args.quick)
    est = estimates()
    res = REPORT.run([t for part in parts.values() for t in part], work, cost=cost, describe=describe)
    res |= REPORT.run([run_on(t) for t in unflagged(res, parts[2])], work, cost=cost, describe=describe)
    p1, p2, p3, p4, p5 = parts.values()
    if not args.no_plots:
        plot_stiffness(res, p1)
        plot_coupling(res, p2, est)
        plot_line(res, p3)
    constants = {k: v for k, v in globals().items() if k.isupper()}     # the case, as the template names it
    helpers = {f.__name__: f for f in (results, find, cell, search_cell, failure, integrator_label, modal_growth,
                                       reason)} | {"step_of": step_of}
    REPORT.render(**constants, **helpers, tasks=len(res), est=est, parts=parts, res=res, stability=stability,
                  runs=sum(len(r["rows"]) if "rows" in r else 1 for r in res.values()),
                  RK4_REAL=stability.RK4_REAL, RK4_IMAGINARY=stability.RK4_IMAGINARY,
                  algorithms=list(dict.fromkeys(t.algorithm for t in p2)),
                  divergence_speed=est["divergence_speed"], onset_factor=est["onset_factor"],
                  p1=stiffness_facts(res, p1), p2=coupling_facts(res, p2, est), p3=line_facts(res, p3, p1),
                  p5=flutter_trends(res, p5))


if __name__ == "__main__":
    main()
