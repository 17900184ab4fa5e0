"""Stability map (issue 5, part 3): the largest stable structural step of RK4 and generalized-alpha against
stiffness, and explicit against implicit coupling against flow speed and air density.

    python benchmarks/stability.py [--quick] [--jobs 2] [--parts 1 2 3 4 5] [--no-plots]

The case is scenes/stability_wing.toml: the PVC wing body of deploy_flexible (003 Table 5), 0.15 m, clamped,
7 elements, no damping, a tip load P = 0.1 EI_yy / L^2 applied suddenly at t = 0 (linear static tip deflection
delta_s = P L^3 / (3 EI_yy) = L / 30). Every probe is one real run, `orchestrator.master.run_scene(scene,
backend="direct")` (what `wingsim run scenes/stability_wing.toml --backend direct --set ...` runs); runs and
searches go to `--jobs` processes, one BLAS thread each.

Stable (the doc states it too): the run ends with status "ok", its kinetic energy never exceeds P delta_s and
its tip never moves more than 4 delta_s from where it started. An undamped linear structure under a suddenly
applied dead load in still air keeps KE <= P^2 (K^-1)_tip,tip / 2 = P delta_s / 2 and |tip displacement| <=
2 delta_s (energy conservation; aerodynamics in still air only store or dissipate energy), so the bounds are
twice the largest physical response. A run whose kinetic energy exceeds 100 P delta_s is stopped there
(status "diverged", message starting with RUNAWAY), only to save time: it is unstable by the definition anyway.

Parts:
  1. structure only: E = 1e6 ... 1e12 Pa (every stiffness scaled with E: EA and EI from the plate, GJ = the
     scene's GJ x E / 2.83 GPa, a material of fixed Poisson ratio; P scales with EI); RK4 and
     generalized-alpha with rho_inf = 1, 0.8, 0.5, 0: the largest stable structure.step on the grid
     h_k = h_top 2^(-k/16) (4.4 % apart), h_top = T_1 / 4 (T_1 the first bending period): halve from h_top
     until a run is stable, then bisect the last octave on the grid. Runs last 2 T_1 (generalized-alpha) or
     200 periods 2 pi / omega_max of the highest mode (RK4: about 450 steps at its limit). Analytic RK4
     limit 2 sqrt(2) / omega_max (RK4 on the imaginary axis; omega_max from structure_fmu.modes).
  2. coupled with uvlm-flat: flow.speed 0 ... 60 m/s x flow.density 0.1 ... 100 x 1.2 kg/m^3, gauss-seidel
     and jacobi at every point, implicit (Aitken, the defaults) at 0, 20, 40, 60 m/s; coupling.step = 1 ms,
     the structure in 4 generalized-alpha steps (rho_inf = 0.8) per coupling step, 50 ms (about one
     first-mode period). Compared with the added-mass onset (2D flat plate, and the lattice's own added mass
     against a free mass so coupled: lattice_added_mass, critical_mass_ratio; then mode by mode, each structural
     mode with its own frequency and added mass through the coupled step: coupled_mode_radius, modal_growth)
     and the torsional divergence speed of the wing. The runs unstable by the bounds that the units did not
     report "diverged" are then run on to RUN_ON_STOP = 0.2 s without the runaway stop (as a user's run would
     go): whether, when and by which check the units report them.
  3. the largest stable coupling.step at 10 m/s against density, gauss-seidel (down to 5 octaves) and
     implicit (3 octaves, at 1, 10, 30, 100 x air), grid 4 ms x 2^(-k/4), 4 structure steps per coupling
     step, runs of max(50 ms, 20 coupling steps).
  4. gauss-seidel at 0 m/s, coupling.step = 0.5 ms, 15, 25, 35, 50 x air, the structure in 1, 2, 4, 8 steps per
     coupling step, against critical_mass_ratio's prediction.
  5. gauss-seidel and implicit at 60 m/s, 3 x air (where part 2's explicit and implicit maps disagree) at
     coupling steps 1, 0.5, 0.25 ms: kinetic energy and tip twist (flutter of the undamped wing).
--quick: two stiffnesses, RK4 and rho_inf = 0.8, a 2 x 2 coupling grid (gauss-seidel, implicit), part 3 at two
densities, part 4 at 25 x air, part 5 at 1 ms; tables only.

A full run writes docs/stability.md (tables, numbers, the command and its wall time) and, unless --no-plots,
docs/img/stability_stiffness.png, stability_coupling.png and stability_coupling_step.png.
"""
import argparse
import math
import os
import re
import sys
import time
from collections import Counter
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):   # one BLAS thread per process
    os.environ.setdefault(_var, "1")

from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from orchestrator import units as real_units  # noqa: E402
from orchestrator.master import run_scene  # noqa: E402
from orchestrator.scene import load_scene  # noqa: E402
from structure_fmu.modes import natural_frequencies, natural_modes  # noqa: E402
from structure_fmu.solver import StructureSolver  # noqa: E402
from structure_fmu.topology import Topology  # noqa: E402

SCENE = ROOT / "scenes" / "stability_wing.toml"
IMG = ROOT / "docs" / "img"
DOC = ROOT / "docs" / "stability.md"
AIR = 1.2                          # kg/m^3, the density factors multiply it
RK4_IMAGINARY = 2 * math.sqrt(2)   # |R(iy)| <= 1 for |y| <= 2 sqrt(2): undamped modes, eigenvalues +- i omega
RK4_REAL = 2.785                   # |R(-x)| <= 1 for 0 <= x <= 2.785: the limit for real (damped) eigenvalues
RUNAWAY = "stability map: runaway"
RUNAWAY_FACTOR = 100.0             # stop a run once KE > RUNAWAY_FACTOR x P delta_s
COUPLING_STEP = 1e-3               # s, coupling.step of part 2 (deploy_flexible's)
SUBSTEPS = 4                       # structure steps per coupling step in the coupled runs (0.25 ms in part 2)
RHO_INF = 0.8                      # generalized-alpha's rho_inf in the coupled runs (the scene's)
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


# ---- the case, its bounds and one probe -----------------------------------------------------------------
def scene_overrides(E=None):
    """--set overrides scaling every stiffness of the wing to Young's modulus E (Pa; None: the scene's)."""
    if E is None:
        return []
    section = load_scene(SCENE)["structure"]["bodies"][0]["section"]
    factor = E / section["youngs_modulus"]
    return [f"structure.bodies.wing.section.youngs_modulus={float(E)!r}",
            f"structure.bodies.wing.section.torsional_rigidity={float(section['torsional_rigidity'] * factor)!r}"]


def load_scale(scene):
    """(P N, delta_s m): the tip load P = load.parameter EI_yy / L^2 and its linear static tip deflection
    P L^3 / (3 EI_yy)."""
    body = Topology.from_scene(scene).bodies["wing"]
    P = scene["load"]["parameter"] * body.section.flap / body.length ** 2
    return P, P * body.length ** 3 / (3 * body.section.flap)


def frequencies(E=None):
    """(omega_1, omega_max) rad/s of the clamped wing at stiffness E, linearized at rest (structure_fmu.modes)."""
    omega = natural_frequencies(StructureSolver(load_scene(SCENE, scene_overrides(E))), count=None)
    return float(omega[0]), float(omega.max())


class Watch:
    """run_scene's `units` and `progress` hooks: keeps the structure unit and, after every communication step,
    stops the run with a diverged UnitError once its kinetic energy exceeds `limit` (J)."""

    UnitError = real_units.UnitError

    def __init__(self, limit):
        self.limit, self.structure = limit, None

    def make_unit(self, **kwargs):
        unit = real_units.make_unit(**kwargs)
        if kwargs["kind"] == "structure":
            self.structure = unit
        return unit

    def update(self, t):
        kinetic = self.structure.monitors()["kinetic_energy"]
        if not kinetic <= self.limit:
            raise real_units.UnitError(f"{RUNAWAY}: kinetic energy {kinetic:.3g} J > {self.limit:.3g} J at "
                                       f"t = {t:.6g} s (run diverged, stopped here)", diverged=True)

    def finish(self, t, status):
        pass


def probe(overrides, watch=True):
    """One run of the scene with `overrides`: a dict with status, message (str), simulated_s, wall_s, ke_max (J),
    tip_max (m), ke_bound = P delta_s (J), tip_bound = 4 delta_s (m), unbounded_s (the first sample time, s, with
    KE > P delta_s or the tip beyond 4 delta_s; NaN if none), stable (bool) and why: "" (stable),
    "solver" (the units reported "diverged"), "error" (status "error": a failure that is not a divergence),
    "runaway" (stopped by Watch, only if `watch`), "energy" or "displacement" (status "ok" but a bound exceeded)."""
    scene = load_scene(SCENE, overrides)
    P, delta = load_scale(scene)
    hooks = Watch(RUNAWAY_FACTOR * P * delta) if watch else None
    start = time.perf_counter()
    result = run_scene(scene, backend="direct", units=hooks, progress=hooks)
    series = result.series
    positions = series.positions[:, series.probe_names.index("tip")]
    chord = (series.positions[:, series.probe_names.index("tip_trailing_edge")]
             - series.positions[:, series.probe_names.index("tip_leading_edge")])
    displacement = np.linalg.norm(positions - positions[:1], axis=1)
    with np.errstate(invalid="ignore"):
        tip = float(np.nanmax(displacement)) if len(positions) else math.nan
        ke = float(np.nanmax(series.kinetic_energy)) if len(positions) else math.nan
        # twist: the tip chord line (x at rest) turning towards the section normal (y), span along z
        twist = float(np.nanmax(np.abs(np.degrees(np.arctan2(chord[:, 1], chord[:, 0]))))) if len(chord) else math.nan
        outside = (series.kinetic_energy > P * delta) | (displacement > 4 * delta)
    unbounded = float(series.time[np.argmax(outside)]) if outside.any() else math.nan
    row = {"status": result.status, "message": result.message, "simulated_s": result.simulated_time_s,
           "wall_s": time.perf_counter() - start, "ke_max": ke, "tip_max": tip, "twist_max": twist,
           "ke_bound": P * delta, "tip_bound": 4 * delta, "unbounded_s": unbounded}
    if result.status == "error":
        why = "error"
    elif result.status != "ok":
        why = "runaway" if result.message.startswith(RUNAWAY) else "solver"
    elif not ke <= P * delta:
        why = "energy"
    elif not tip <= 4 * delta:
        why = "displacement"
    else:
        why = ""
    return {**row, "stable": not why, "why": why}


def largest_stable(run, top, fine, octaves):
    """Bracketing search on the grid top 2^(-k/fine), k = 0 ... fine x octaves: halve the step from `top` until
    run(step) is stable, then bisect the last octave on the grid (stability assumed monotonic inside it).
    Returns (k_stable or None, k_unstable or None, {k: probe row})."""
    rows, k = {}, 0
    while k <= fine * octaves:
        rows[k] = run(top * 2.0 ** (-k / fine))
        if rows[k]["stable"]:
            break
        k += fine
    else:
        return None, k - fine, rows
    if k == 0:
        return 0, None, rows
    unstable, stable = k - fine, k
    while stable - unstable > 1:
        mid = (stable + unstable) // 2
        rows[mid] = run(top * 2.0 ** (-mid / fine))
        if rows[mid]["stable"]:
            stable = mid
        else:
            unstable = mid
    return stable, unstable, rows


# ---- the jobs -------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class StepSearch:
    """Part 1: the largest stable structure.step of `integrator` (rho_inf `rho`) at Young's modulus E (Pa)."""
    E: float
    integrator: str
    rho: float | None

    @property
    def label(self):
        return f"E = {self.E:.0e} Pa, {integrator_label(self.integrator, self.rho)}"

    def run(self):
        omega_1, omega_max = frequencies(self.E)
        period = 2 * math.pi / omega_1
        stop = 2 * period if self.rho is not None else 200 * 2 * math.pi / omega_max
        common = [*scene_overrides(self.E), f"structure.integrator={self.integrator}", f"time.stop={stop!r}"]
        if self.rho is not None:
            common.append(f"structure.rho_inf={self.rho!r}")

        def run(h):
            sample = h * max(1, round(stop / (50 * h)))             # about 50 samples, a whole number of steps
            return probe([*common, f"structure.step={h!r}", f"coupling.step={sample!r}"], watch=False)

        top = period / 4
        stable, unstable, rows = largest_stable(run, top, fine=16, octaves=14)
        return {"omega_1": omega_1, "omega_max": omega_max, "top": top, "fine": 16, "stop": stop,
                "stable": stable, "unstable": unstable, "rows": rows}


@dataclass(frozen=True)
class CouplingPoint:
    """Part 2: one coupled run of `algorithm` at flow.speed V (m/s) and flow.density factor x 1.2 kg/m^3."""
    algorithm: str
    V: float
    factor: float

    @property
    def label(self):
        return f"{self.algorithm} at {self.V:g} m/s, {self.factor:g} x air"

    def run(self):
        return probe(coupled(self.algorithm, self.V, self.factor, COUPLING_STEP, COUPLED_STOP))


@dataclass(frozen=True)
class RunOnPoint(CouplingPoint):
    """Part 2, second pass: a CouplingPoint the units did not report, run on to RUN_ON_STOP without the
    runaway stop, as a user's run of it would go."""

    @property
    def label(self):
        return f"{super().label}, run on to {RUN_ON_STOP:g} s"

    def run(self):
        return probe(coupled(self.algorithm, self.V, self.factor, COUPLING_STEP, RUN_ON_STOP), watch=False)


@dataclass(frozen=True)
class CouplingStepSearch:
    """Part 3: the largest stable coupling.step of `algorithm` at flow.speed V (m/s) and density factor, on the
    grid LINE_TOP 2^(-k/4) down to `octaves` octaves."""
    algorithm: str
    V: float
    factor: float
    octaves: int

    @property
    def label(self):
        return f"coupling step of {self.algorithm} at {self.V:g} m/s, {self.factor:g} x air"

    def run(self):
        def run(h):
            return probe(coupled(self.algorithm, self.V, self.factor, h, max(COUPLED_STOP, 20 * h)))

        stable, unstable, rows = largest_stable(run, LINE_TOP, fine=4, octaves=self.octaves)
        return {"top": LINE_TOP, "fine": 4, "stable": stable, "unstable": unstable, "rows": rows}


@dataclass(frozen=True)
class SubstepPoint:
    """Part 4: Gauss-Seidel at 0 m/s, density factor x 1.2 kg/m^3, SUBSTEP_CASE's coupling step taken by the
    structure in `substeps` generalized-alpha steps."""
    factor: float
    substeps: int

    @property
    def label(self):
        return f"gauss-seidel at 0 m/s, {self.factor:g} x air, {self.substeps} structure steps per coupling step"

    def run(self):
        return probe(coupled("gauss-seidel", 0.0, self.factor, SUBSTEP_CASE[0], COUPLED_STOP, self.substeps))


@dataclass(frozen=True)
class FlutterPoint:
    """Part 5: `algorithm` at FLUTTER_CASE's speed and density with coupling.step `step` (s)."""
    algorithm: str
    step: float

    @property
    def label(self):
        V, factor, _ = FLUTTER_CASE
        return f"{self.algorithm} at {V:g} m/s, {factor:g} x air, coupling step {self.step * 1e3:g} ms"

    def run(self):
        V, factor, _ = FLUTTER_CASE
        return probe(coupled(self.algorithm, V, factor, self.step, COUPLED_STOP))


def coupled(algorithm, V, factor, step, stop, substeps=SUBSTEPS):
    """Overrides of a uvlm-flat run at flow.speed V (m/s), density factor x 1.2 kg/m^3, coupling.step `step`
    taken by the structure in `substeps` equal steps, until `stop` (s)."""
    return ["aero.model=uvlm-flat", f"coupling.algorithm={algorithm}", f"flow.speed={float(V)!r}",
            f"flow.density={AIR * factor!r}", f"coupling.step={step!r}", f"structure.step={step / substeps!r}",
            f"structure.rho_inf={RHO_INF!r}", f"time.stop={stop!r}"]


def integrator_label(integrator, rho):
    return "RK4" if rho is None else f"gen-alpha rho_inf = {rho:g}"


def plan(quick=False):
    """{part: [job, ...]} in table order."""
    stiffnesses = (1e6, 1e12) if quick else tuple(10.0 ** np.arange(6, 13))
    integrators = INTEGRATORS[::2][:2] if quick else INTEGRATORS
    speeds = (0.0, 40.0) if quick else (0.0, 10.0, 20.0, 30.0, 40.0, 50.0, 60.0)
    factors = (1.0, 30.0) if quick else (0.1, 0.3, 1.0, 3.0, 10.0, 20.0, 30.0, 100.0)
    algorithms = ("gauss-seidel", "implicit") if quick else ALGORITHMS
    line = (1.0, 30.0) if quick else (0.1, 1.0, 3.0, 10.0, 20.0, 30.0, 100.0)
    implicit_line = (1.0,) if quick else (1.0, 10.0, 30.0, 100.0)
    _, densities, substeps = SUBSTEP_CASE
    return {1: [StepSearch(E, i, r) for E in stiffnesses for i, r in integrators],
            2: [CouplingPoint(a, V, f) for a in algorithms for f in factors for V in speeds
                if a != "implicit" or V in IMPLICIT_SPEEDS],
            3: [CouplingStepSearch("gauss-seidel", LINE_SPEED, f, 5) for f in line]
               + [CouplingStepSearch("implicit", LINE_SPEED, f, 3) for f in implicit_line],
            4: [SubstepPoint(f, k) for f in (densities[1:2] if quick else densities) for k in substeps],
            5: [FlutterPoint(a, h) for a in ("gauss-seidel", "implicit") for h in FLUTTER_CASE[2][:1 if quick else 3]]}


def estimated_cost(job):
    """Rough relative cost, to start the longest jobs first."""
    if isinstance(job, StepSearch):
        return 8 if job.integrator == "rk4" else 5
    if isinstance(job, CouplingStepSearch):
        return 15 if job.algorithm == "implicit" else 6
    if isinstance(job, SubstepPoint):
        return 1
    if isinstance(job, FlutterPoint):
        return (6 if job.algorithm == "implicit" else 1) * COUPLING_STEP / job.step
    if isinstance(job, RunOnPoint):
        return RUN_ON_STOP / COUPLED_STOP
    return 6 if job.algorithm == "implicit" else 1


def work(job):
    """job.run() in a worker, with its wall time; an exception becomes {"error": message}."""
    start = time.perf_counter()
    try:
        out = job.run()
    except Exception as err:                      # noqa: BLE001 - reported in the doc, never dropped
        out = {"error": f"{type(err).__name__}: {err}"}
    return {**out, "job_wall_s": time.perf_counter() - start}


def run_all(jobs, workers):
    """{job: result} of all `jobs`, longest first, one progress line per finished job."""
    results, start = {}, time.perf_counter()
    with ProcessPoolExecutor(max_workers=max(1, workers)) as pool:
        futures = {pool.submit(work, job): job for job in sorted(jobs, key=estimated_cost, reverse=True)}
        for k, future in enumerate(as_completed(futures), 1):
            job = futures[future]
            results[job] = out = future.result()
            print(f"[{k}/{len(jobs)} {time.perf_counter() - start:6.1f} s] {job.label}: {brief(out)} "
                  f"({out['job_wall_s']:.1f} s)", flush=True)
    return results


def brief(out):
    """One-line outcome of a job."""
    if "error" in out:
        return f"error: {out['error']}"
    if "rows" not in out:
        return "stable" if out["stable"] else f"unstable ({out['why']}: {out['status']})"
    return f"largest stable step {fmt(step_of(out, 'stable'), '.3g')} s, {len(out['rows'])} runs"


def step_of(out, which):
    """The grid step (s) of a search's `which` = "stable" | "unstable" end, or None."""
    k = out.get(which)
    return None if k is None else out["top"] * 2.0 ** (-k / out["fine"])


def span(values, spec):
    """"a to b" (min, max of `values` formatted with `spec`), or "a" when they agree to that format."""
    low, high = format(min(values), spec), format(max(values), spec)
    return low if low == high else f"{low} to {high}"


def fmt(value, spec):
    """`value` formatted with `spec`, or "-" for None / NaN."""
    return "-" if value is None or (isinstance(value, float) and math.isnan(value)) else format(value, spec)


# ---- estimates (independent of the runs) ----------------------------------------------------------------
def coupled_mode_radius(mu, lag, omega_h=0.0, substeps=SUBSTEPS, rho_inf=RHO_INF):
    """Spectral radius, per communication step, of one structural mode (unit modal mass, natural frequency
    omega, omega_h = omega h with h the coupling step) explicitly coupled with uvlm's fluid force. The force
    of communication step n is F_n = -mu (3 v_k - 4 v_(k-1) + v_(k-2)) / (2 h), k = n - lag (the second-order
    dGamma/dt of a circulation proportional to the velocity, mu = m_a / m_s the mode's added-mass ratio; lag 0
    Gauss-Seidel: the structure's newest state, lag 1 Jacobi), held over the step, which the structure takes in
    `substeps` generalized-alpha steps (004 Eqs. 23-25, rho_inf) of x'' = F_n - omega^2 x: the true
    acceleration of each step solves it at the step's end, the auxiliary one a_(n+1) = (alpha_f a'_n - alpha_m
    a_n + (1 - alpha_f) a'_(n+1)) / (1 - alpha_m) updates x and v (Eq. 23). For omega_h = 0 (a free mass) the
    neutral z = 1 (free drift) is left out."""
    am, af = (2 * rho_inf - 1) / (rho_inf + 1), rho_inf / (rho_inf + 1)
    gamma, beta = 0.5 - am + af, 0.25 * (1 - am + af) ** 2
    k, hs = omega_h * omega_h, 1.0 / substeps
    blend = (1 - af) / (1 - am)

    def step(x):                          # x = (x_n, v_n, v_(n-1), v_(n-2), v_(n-3), a_n, a'_n), h = 1
        position, v, a, true = x[0], x[1:5], x[5], x[6]
        force = -mu * (3 * v[lag] - 4 * v[lag + 1] + v[lag + 2]) / 2
        speed = v[0]
        for _ in range(substeps):
            known = (af * true - am * a) / (1 - am)                        # a_(n+1) = known + blend a'_(n+1)
            predicted = position + hs * speed + hs * hs * (0.5 - beta) * a
            new_true = (force - k * (predicted + hs * hs * beta * known)) / (1 + k * hs * hs * beta * blend)
            new = known + blend * new_true
            position = predicted + hs * hs * beta * new
            speed += hs * ((1 - gamma) * a + gamma * new)
            a, true = new, new_true
        return np.array([position, speed, v[0], v[1], v[2], a, true])
    z = np.linalg.eigvals(np.array([step(e) for e in np.eye(7)]).T)
    if omega_h == 0.0:
        z = z[np.abs(z - 1.0) > 1e-7]
    return float(np.max(np.abs(z)))


def critical_mass_ratio(lag, substeps=SUBSTEPS, rho_inf=RHO_INF):
    """Largest added-mass ratio mu = m_a / m_s for which explicit coupling of a free mass m_s (no stiffness: the
    motions with omega h << 1) with uvlm's fluid force stays stable (`coupled_mode_radius` <= 1, bisection). As
    substeps grows the first step's blend of old and new force fades and the limit tends to 0.5 (Gauss-Seidel)
    and 0.61 (Jacobi), those of v_(n+1) = v_n + h F_n / m_s."""
    low, high = 1e-3, 50.0
    for _ in range(60):
        mid = math.sqrt(low * high)
        low, high = (mid, high) if coupled_mode_radius(mid, lag, 0.0, substeps, rho_inf) <= 1.0 + 1e-9 else (low, mid)
    return low


def lattice_added_mass():
    """(mu_max, mu_1, modal) per kg/m^3 of air: the added-mass ratio of the uvlm-flat lattice at V = 0, i.e. the
    largest generalized eigenvalue of (M_a, M) on the wing's free coordinates (tangent to the constraints), and
    the ratio of modal masses phi^T M_a phi / phi^T M phi of the first bending mode phi. M_a = -dQ/d(de') column
    by column from aero steps with de growing linearly in time (dGamma/dt is then exact), M the structure's mass.
    modal, per structural mode (`structure_fmu.modes.natural_modes`, mass-normalized): "omega" (rad/s), "mu"
    (its added-mass ratio per kg/m^3) and "kinetic" (the peak kinetic energy 1/2 (phi . f)^2 / omega^2 of the
    mode under the suddenly applied tip load f, in units of P delta_s; summed over the modes it is 1/2)."""
    from aero_fmu.solver import AeroSolver
    from scipy.linalg import eigvals

    scene = load_scene(SCENE, ["aero.model=uvlm-flat"])
    solver = StructureSolver(scene)
    model, q = solver.model, solver.state.q
    E0, _, _ = model.coordinates(q, np.zeros_like(q), 0.0)
    h, scale = 1e-3, 1e-3
    columns = []
    for j in range(model.T.shape[1]):
        aero = AeroSolver(scene, {"flow.speed": 0.0, "flow.density": 1.0})
        for k in range(3):
            aero.advance(k * h, E0, k * h * scale * model.T[:, j])
        columns.append(-aero.Q / scale)
    omega, shapes = natural_modes(solver)
    # the mass-normalized shapes span the constraints' tangent space: (M_a, M) there is shapes^T M_a shapes
    added = shapes.T @ model.T.T @ np.array(columns).T @ shapes
    ratios = np.diag(added)                                             # phi^T M_a phi / phi^T M phi per mode
    P, delta = load_scale(scene)
    load = model.force_E(E0, np.zeros_like(E0), 1.0, np.zeros_like(E0), {}) - model.gravity_E   # the tip load
    modal_force = shapes.T @ (model.T.T @ load)
    modal = {"omega": omega, "mu": ratios,
             "kinetic": 0.5 * modal_force ** 2 / np.maximum(omega ** 2, np.finfo(float).tiny) / (P * delta)}
    return float(np.max(eigvals(added).real)), float(ratios[0]), modal


def lift_slope():
    """dCL/dalpha (1/rad) of the uvlm-flat lattice of the wing at a small incidence (first, steady step)."""
    from aero_fmu.solver import AeroSolver

    scene = load_scene(SCENE, ["aero.model=uvlm-flat"])
    q = StructureSolver(scene).state.q
    model = StructureSolver(scene).model
    E0, _, _ = model.coordinates(q, np.zeros_like(q), 0.0)
    alpha = 0.01
    aero = AeroSolver(scene, {"flow.speed": 10.0, "flow.direction_x": math.cos(alpha),
                              "flow.direction_y": math.sin(alpha), "flow.direction_z": 0.0})
    aero.advance(0.0, E0, np.zeros_like(E0))
    return abs(aero.outputs()["CL"]) / alpha


def estimates():
    """The numbers the coupling map is compared with (SI units; mu_* per kg/m^3 of air, mu_crit_* -)."""
    scene = load_scene(SCENE, ["aero.model=uvlm-flat"])
    body = scene["structure"]["bodies"][0]
    section, span = body["section"], body["length"]
    c, M = section["chord"], scene["aero"]["chordwise_panels"]
    mu_max, mu_1, modal = lattice_added_mass()
    slope = lift_slope()
    e = (section.get("axis_position", 0.5) - 0.25) * c                   # m, aerodynamic centre ahead of the axis
    _, _, substeps = SUBSTEP_CASE
    return {"m_s": section["density"] * c * section["thickness"],        # kg/m, structure per unit span
            "plate": math.pi * c ** 2 / 4,                               # m^2: m_a = rho pi c^2 / 4 per kg/m^3
            "model_factor": 3 + 1 / M, "M": M, "mu_max": mu_max, "mu_1": mu_1, "modal": modal,
            "mu_crit": {a: critical_mass_ratio(lag) for a, lag in (("gauss-seidel", 0), ("jacobi", 1))},
            "mu_crit_plain": {a: critical_mass_ratio(lag, substeps=256) for a, lag in (("gauss-seidel", 0),
                                                                                     ("jacobi", 1))},
            "mu_crit_substeps": {k: critical_mass_ratio(0, substeps=k) for k in substeps},
            "slope": slope, "aspect": span / c,
            "q_D": section["torsional_rigidity"] * (math.pi / (2 * span)) ** 2 / (c * e * slope)}   # Pa


def divergence_speed(est, factor):
    """Torsional divergence speed (m/s) at density factor x 1.2 kg/m^3: q_D = GJ (pi / 2L)^2 / (c e a)."""
    return math.sqrt(2 * est["q_D"] / (AIR * factor))


def modal_growth(est, algorithm, factor):
    """(peak kinetic energy / (P delta_s), mode index) predicted at the end of a part 2 run at 0 m/s: each
    structural mode on its own starts with its peak kinetic energy under the sudden tip load and grows by
    coupled_mode_radius^2 per communication step (with its omega h and added-mass ratio at density factor x
    1.2 kg/m^3; a decaying mode keeps its start), the largest of them. Above 1 the run breaks the energy bound."""
    modal, lag = est["modal"], {"gauss-seidel": 0, "jacobi": 1}[algorithm]
    steps = round(COUPLED_STOP / COUPLING_STEP)
    growth = np.array([max(1.0, coupled_mode_radius(mu * AIR * factor, lag, omega * COUPLING_STEP)) ** (2 * steps)
                       for mu, omega in zip(modal["mu"], modal["omega"])])
    energy = modal["kinetic"] * growth
    mode = int(np.argmax(energy))
    return float(energy[mode]), mode


def predicted_onset(est, mu_crit):
    """Density factor (x 1.2 kg/m^3) at which the lattice's largest added-mass ratio reaches mu_crit."""
    return mu_crit / (est["mu_max"] * AIR)


# ---- tables ---------------------------------------------------------------------------------------------
def table(header, rows):
    """Markdown table lines."""
    return ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)] + ["| " + " | ".join(r) + " |" for r in rows]


def search_cell(out):
    """Largest stable step (s) of a search, or why there is none."""
    if "error" in out:
        return "error"
    stable = step_of(out, "stable")
    if stable is None:
        return f"none >= {step_of(out, 'unstable'):.3g}"
    return f"{stable:.3g}" + (" (top of grid)" if out["unstable"] is None else "")


def reason(message):
    """The units' reason in a "diverged" message, without the call, the time and the hint."""
    text = message.split("failed: ")[-1].split(". Hint")[0]
    text = re.sub(r"^(structure|aero) unit: solver ", "", text)
    return re.sub(r"^diverged at t = [^:]*: ", "", text).replace("|", "/")


def how(row):
    """How an unstable run failed: D/R/E/X, the time reached (s) and the units' reason or the bound exceeded."""
    if row["why"] in ("solver", "error"):
        text = reason(row["message"])
    elif row["why"] == "runaway":
        text = f"KE {row['ke_max']:.3g} J > {RUNAWAY_FACTOR:g} P delta_s"
    elif row["why"] == "energy":
        text = f"status ok, KE max {row['ke_max']:.3g} J > P delta_s = {row['ke_bound']:.3g} J"
    else:
        text = f"status ok, tip {1e3 * row['tip_max']:.3g} mm > {1e3 * row['tip_bound']:.3g} mm"
    return f"{SYMBOL[row['why']]} at t = {row['simulated_s']:.3g} s: {text}"


def cell(out):
    """A map cell: S, or D/R/E/X and the time (ms) at which the run ended."""
    if "error" in out:
        return "error"
    return "S" if out["stable"] else f"{SYMBOL[out['why']]} {1e3 * out['simulated_s']:.0f} ms"


def failure(out):
    """how() of the smallest unstable probe of a search, or "-"."""
    return "-" if "rows" not in out or out.get("unstable") is None else how(out["rows"][out["unstable"]])


def rk4_of(jobs, res, E):
    """The RK4 search result at stiffness E, or None."""
    return next((res[j] for j in jobs if j.E == E and j.rho is None and "error" not in res[j]), None)


def table_stiffness(jobs, res):
    """Part 1 rows: per E the modes, the RK4 estimate and the measured limits of every integrator."""
    names = list(dict.fromkeys((j.integrator, j.rho) for j in jobs if j.rho is not None))
    rows = []
    for E in sorted({j.E for j in jobs}):
        first = next((res[j] for j in jobs if j.E == E and "error" not in res[j]), None)
        if first is None:
            rows.append([f"{E:.0e}", "error"] + [""] * (4 + len(names)))
            continue
        estimate = RK4_IMAGINARY / first["omega_max"]
        rk4 = rk4_of(jobs, res, E)
        measured = step_of(rk4, "stable") if rk4 else None
        row = [f"{E:.0e}", f"{first['omega_1']:.4g}", f"{first['omega_max']:.4g}", f"{estimate:.3g}",
               f"{fmt(measured, '.3g')} / {fmt(step_of(rk4, 'unstable') if rk4 else None, '.3g')}",
               fmt(None if measured is None else measured / estimate, ".3f")]
        for name in names:
            out = res[next(j for j in jobs if j.E == E and (j.integrator, j.rho) == name)]
            ga = None if "error" in out else step_of(out, "stable")
            row.append(f"{search_cell(out)} ({fmt(ga / measured if ga and measured else None, '.0f')}x)")
        rows.append(row)
    return table(["E (Pa)", "omega_1 (rad/s)", "omega_max (rad/s)", "2 sqrt(2) / omega_max (s)",
                  "RK4 stable / unstable (s)", "RK4 / estimate"]
                 + [f"gen-alpha rho_inf = {r:g} (s, x RK4)" for _, r in names], rows)


def table_failures(jobs, res):
    """Part 1: how the smallest unstable grid step failed, per search."""
    return table(["E (Pa)", "integrator", "smallest unstable step (s)", "how it failed", "runs"],
                 [[f"{j.E:.0e}", integrator_label(j.integrator, j.rho), fmt(step_of(res[j], "unstable"), ".3g"),
                   failure(res[j]), str(len(res[j]["rows"]))] for j in jobs if "error" not in res[j]])


SYMBOL = {"": "S", "solver": "D", "runaway": "R", "energy": "E", "displacement": "X", "error": "!"}


def point(jobs, res, algorithm, V, factor):
    """The result of part 2's run (algorithm, V, factor), or None if there is none."""
    job = next((j for j in jobs if (j.algorithm, j.V, j.factor) == (algorithm, V, factor)), None)
    return None if job is None else res[job]


def table_map(algorithm, jobs, res):
    """Part 2 rows for one algorithm: density factor x speed, one symbol per run ("." not run)."""
    speeds = sorted({j.V for j in jobs})
    rows = []
    for f in sorted({j.factor for j in jobs}):
        cells = [point(jobs, res, algorithm, V, f) for V in speeds]
        rows.append([f"{f:g} ({AIR * f:.3g})"] + ["." if c is None else cell(c) for c in cells])
    return table(["density x 1.2 (kg/m^3) \\ speed (m/s)"] + [f"{V:g}" for V in speeds], rows)


def onset(algorithm, jobs, res, V):
    """(largest stable density factor, the next one, unstable) at speed V, walking up the densities."""
    stable = None
    for f in sorted({j.factor for j in jobs}):
        out = point(jobs, res, algorithm, V, f)
        if out is None:
            continue
        if "error" in out or not out["stable"]:
            return stable, f
        stable = f
    return stable, None


def unflagged(jobs, res):
    """Part 2 runs unstable by the bounds without a "diverged" from the units: (job, row) pairs."""
    return [(j, res[j]) for j in jobs if "error" not in res[j] and res[j]["why"] in ("runaway", "energy", "displacement")]


def run_on_jobs(jobs, res):
    """Part 2's second pass: a RunOnPoint for each run the units did not report."""
    return [RunOnPoint(j.algorithm, j.V, j.factor) for j, _ in unflagged(jobs, res)]


def run_on_pairs(jobs, res):
    """(part 2 job, the row of its RunOnPoint) for each run the units did not report that was run on."""
    pairs = zip((j for j, _ in unflagged(jobs, res)), run_on_jobs(jobs, res))
    return [(j, res[k]) for j, k in pairs if k in res]


def check_named(message):
    """Which of the units' checks stopped a "diverged" run, from its message."""
    for key, name in (("Newton", "Newton iteration"), ("NaN", "NaN/inf"), ("constraint residual", "constraint residual"),
                      ("gradient vectors", "gradient size"), ("implicit coupling", "implicit iteration")):
        if key in message:
            return name
    return "other"


def run_on_rows(pairs):
    """Per algorithm, over its (job, row) pairs run on to RUN_ON_STOP: runs, how many the units reported
    "diverged", when (s), how long after the response first left the bounds (ms), the largest kinetic energy
    (x P delta_s), which checks stopped them, and the runs still "ok" or failing otherwise."""
    rows = []
    for a in ALGORITHMS:
        mine = [r for j, r in pairs if j.algorithm == a]
        if not mine:
            continue
        reported = [r for r in mine if "error" not in r and r["why"] == "solver"]
        others = len(mine) - len(reported)
        checks = Counter(check_named(r["message"]) for r in reported)
        lags = [1e3 * (r["simulated_s"] - r["unbounded_s"]) for r in reported if not math.isnan(r["unbounded_s"])]
        rows.append([a, str(len(mine)), str(len(reported)),
                     span([r["simulated_s"] for r in reported], ".3f") if reported else "-",
                     span(lags, ".0f") if lags else "-",
                     f"{max(r['ke_max'] / r['ke_bound'] for r in reported):.3g}" if reported else "-",
                     ", ".join(f"{name} {count}" for name, count in sorted(checks.items())) or "-",
                     str(others)])
    return rows


def run_on_section(pairs):
    """Doc lines: part 2's runs the units did not report, run on to RUN_ON_STOP as a user's run would go."""
    rows = run_on_rows(pairs)
    reported = sum(int(r[2]) for r in rows)
    L = [f"Run on to {RUN_ON_STOP:g} s without the benchmark's stop ({RUN_ON_STOP / COUPLED_STOP:g} times the map's "
         f"runs), as a user's run of the same case would go, {reported} of these {len(pairs)} runs ended \"diverged\" "
         "from the units:", ""]
    L += table(["algorithm", "runs", "reported \"diverged\"", "at t (s)", "after the response left the bounds (ms)",
                "largest KE (x P delta_s)", "stopped by", f"not reported by {RUN_ON_STOP:g} s"], rows)
    L += ["", "The time is the last communication point before the failing step; the response left the bounds at "
          "the first sample with KE > P delta_s or the tip beyond 4 delta_s."]
    if reported == len(pairs):
        L[-1] += (" A user's run of such a case does end \"diverged\" (with the explicit-coupling hint for "
                  "gauss-seidel and jacobi), but only once its response is far past anything physical: the units check "
                  "the numerics (NaN/inf, constraint residual, gradient size, the Newton iteration), not the response. "
                  "The samples before the failure are kept as they were computed.")
    else:
        L[-1] += (f" {len(pairs) - reported} were not reported by {RUN_ON_STOP:g} s: a user's run of such a case can "
                  "end \"ok\" with a response past the physical bounds, since the units check the numerics (NaN/inf, "
                  "constraint residual, gradient size, the Newton iteration), not the response.")
    return L


def table_line(jobs, res):
    """Part 3 rows: density factor, largest stable coupling step per algorithm, and how the next one failed."""
    rows = []
    for f in sorted({j.factor for j in jobs}):
        row = [f"{f:g} ({AIR * f:.3g})"]
        for a in ("gauss-seidel", "implicit"):
            job = next((j for j in jobs if j.algorithm == a and j.factor == f), None)
            row += ["not run", "-"] if job is None else [search_cell(res[job]), failure(res[job])]
        rows.append(row)
    return table(["density x 1.2 (kg/m^3)", "gauss-seidel: largest stable coupling step (s)", "smallest unstable step tried",
                  "implicit: largest stable coupling step (s)", "smallest unstable step tried"], rows)


def table_substeps(jobs, res, est):
    """Part 4 rows: structure steps per coupling step, the predicted onset, the outcome per density."""
    factors = sorted({j.factor for j in jobs})
    rows = []
    for k in sorted({j.substeps for j in jobs}):
        cells = []
        for f in factors:
            out = res[next(j for j in jobs if (j.factor, j.substeps) == (f, k))]
            cells.append(cell(out))
        mu = est["mu_crit_substeps"][k] if est else None
        stable = [f for f, c in zip(factors, cells) if c == "S"]
        unstable = [f for f, c in zip(factors, cells) if c != "S"]
        measured = (f"> {factors[-1]:g}" if not unstable else f"<= {factors[0]:g}" if not stable
                    else f"{max(stable):g} to {min(unstable):g}")
        rows.append([str(k), fmt(mu, ".3f"), fmt(predicted_onset(est, mu) if est else None, ".3g"), measured] + cells)
    return table(["structure steps per coupling step", "mu_crit", "predicted onset (x air)", "measured onset (x air)"]
                 + [f"{f:g} x air" for f in factors], rows)


def table_flutter(jobs, res):
    """Part 5 rows: coupling step, then per algorithm the outcome, KE max (J) and largest tip twist (deg)."""
    rows = []
    for h in sorted({j.step for j in jobs}, reverse=True):
        row = [f"{h * 1e3:g}"]
        for a in ("gauss-seidel", "implicit"):
            job = next((j for j in jobs if (j.algorithm, j.step) == (a, h)), None)
            out = {"error": "not run"} if job is None else res[job]
            row += [out["error"], "-", "-"] if "error" in out else [cell(out), f"{out['ke_max']:.3g}",
                                                                    f"{out['twist_max']:.3g}"]
        rows.append(row)
    return table(["coupling step (ms)", "gauss-seidel", "KE max (J)", "tip twist max (deg)", "implicit",
                  "KE max (J)", "tip twist max (deg)"], rows)


# ---- figures --------------------------------------------------------------------------------------------
def figure(cols, width, height):
    """A Figure (Agg) with `cols` axes in a row, `width` x `height` inches."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(width, height))
    FigureCanvasAgg(fig)
    return fig, fig.subplots(1, cols, squeeze=False)[0]


def save(fig, name, rect=(0, 0, 1, 1)):
    """Write docs/img/stability_<name>.png, the axes laid out inside `rect` (figure fractions)."""
    path = IMG / f"stability_{name}.png"
    fig.tight_layout(rect=rect)
    fig.savefig(path, dpi=100)
    print(f"wrote {path.relative_to(ROOT)} ({path.stat().st_size // 1024} KB)")


def plot_stiffness(jobs, res):
    """Left: largest stable step (s) against E (Pa), log-log, with the RK4 estimate and the top of the grid;
    right: the same steps times omega_max (-), with RK4's 2 sqrt(2)."""
    fig, (ax, bx) = figure(2, 11.0, 4.4)
    first = {j.E: res[j] for j in reversed(jobs) if "error" not in res[j]}
    Es = sorted(first)
    ax.loglog(Es, [RK4_IMAGINARY / first[E]["omega_max"] for E in Es], "k--", lw=1,
              label="RK4 estimate 2 sqrt(2) / omega_max")
    ax.loglog(Es, [first[E]["top"] for E in Es], ":", color="0.5", lw=1, label="top of the grid T_1 / 4")
    bx.axhline(RK4_IMAGINARY, color="k", ls="--", lw=1, label="2 sqrt(2)")
    markers = {None: "o", 1.0: "s", 0.8: "^", 0.5: "v", 0.0: "D"}
    for integrator, rho in dict.fromkeys((j.integrator, j.rho) for j in jobs):
        runs = [res[j] | {"E": j.E} for j in jobs if (j.integrator, j.rho) == (integrator, rho) and "error" not in res[j]]
        for which, fill in (("stable", None), ("unstable", "none")):
            pts = [(r["E"], step_of(r, which), r["omega_max"]) for r in runs if step_of(r, which)]
            if not pts:
                continue
            E, h, w = (np.array(v) for v in zip(*pts))
            label = integrator_label(integrator, rho) if which == "stable" else None
            style = {"marker": markers[rho], "mfc": fill, "color": f"C{list(markers).index(rho)}", "ms": 5}
            ax.loglog(E, h, ls="-" if which == "stable" else "none", lw=1, label=label, **style)
            bx.semilogx(E, h * w, ls="-" if which == "stable" else "none", lw=1, label=label, **style)
    ax.set(xlabel="Young's modulus E (Pa)", ylabel="structure.step (s)")
    bx.set(xlabel="Young's modulus E (Pa)", ylabel="structure.step x omega_max (-)")
    bx.set_yscale("log")
    ax.set_title("Largest stable step (filled), next grid step: unstable (open)", fontsize=9)
    bx.set_title("The same in units of 1 / omega_max (highest mode)", fontsize=9)
    for a in (ax, bx):
        a.grid(True, which="both", alpha=0.25)
        a.legend(fontsize=7)
    save(fig, "stiffness")


STYLE = {"": ("o", "tab:green", "stable"), "solver": ("x", "tab:red", "diverged (reported by the units)"),
         "runaway": ("^", "tab:purple", f"runaway: KE > {RUNAWAY_FACTOR:g} P delta_s (not reported)"),
         "energy": ("s", "tab:orange", "status ok, KE > P delta_s"),
         "displacement": ("D", "tab:brown", "status ok, tip > 4 delta_s"),
         "error": ("*", "k", "status error")}


def plot_coupling(jobs, res, est):
    """One panel per algorithm: speed (m/s) x density factor (log), a marker per run, the divergence speed and
    the added-mass onset estimates drawn over."""
    algorithms = [a for a in ALGORITHMS if any(j.algorithm == a for j in jobs)]
    fig, axes = figure(len(algorithms), 4.2 * len(algorithms), 5.0)
    factors = np.geomspace(min(j.factor for j in jobs), max(j.factor for j in jobs), 100)
    legend = {}
    for ax, algorithm in zip(axes, algorithms):
        for j in (j for j in jobs if j.algorithm == algorithm and "error" not in res[j]):
            marker, color, label = STYLE[res[j]["why"]]
            legend[label], = ax.semilogy(j.V, j.factor, marker=marker, color=color, ls="none", ms=7)
        legend["torsional divergence speed (static estimate)"], = ax.semilogy(
            [divergence_speed(est, f) for f in factors], factors, "k--", lw=1)
        if algorithm in est["mu_crit"]:
            mu = est["mu_crit"][algorithm]
            ax.axhline(predicted_onset(est, mu), color="tab:blue", lw=1, ls=":")
            ax.text(62, predicted_onset(est, mu) * 1.1, f"added-mass estimate, mu = {mu:.2f}", fontsize=6,
                    ha="right", color="tab:blue")
        ax.set_xlim(-3, 63)
        ax.set_ylim(min(factors) / 1.5, max(factors) * 1.5)
        ax.set(xlabel="flow speed (m/s)", ylabel="density / 1.2 kg/m^3", title=algorithm)
        ax.grid(True, which="both", alpha=0.25)
    fig.legend(list(legend.values()), list(legend), loc="lower center", ncol=3, fontsize=7)
    save(fig, "coupling", rect=(0, 0.1, 1, 1))


def plot_line(jobs, res):
    """Largest stable coupling step (s) against density factor, per algorithm."""
    fig, (ax,) = figure(1, 5.5, 3.8)
    for a, marker in (("gauss-seidel", "o"), ("implicit", "s")):
        runs = [res[j] | {"f": j.factor} for j in jobs if j.algorithm == a and "error" not in res[j]]
        stable = [(r["f"], step_of(r, "stable")) for r in runs if step_of(r, "stable")]
        unstable = [(r["f"], step_of(r, "unstable")) for r in runs if step_of(r, "unstable")]
        color = "tab:blue" if a == "gauss-seidel" else "tab:green"
        if stable:
            ax.loglog(*zip(*stable), marker=marker, lw=1, color=color, label=f"{a}: largest stable")
        if unstable:
            ax.loglog(*zip(*unstable), marker=marker, mfc="none", ls="none", color=color,
                      label=f"{a}: smallest unstable step tried")
    ax.axhline(LINE_TOP, color="0.5", ls=":", lw=1, label="top of the grid")
    ax.set(xlabel="density / 1.2 kg/m^3", ylabel="coupling.step (s)",
           title=f"uvlm-flat at {LINE_SPEED:g} m/s, {SUBSTEPS} structure steps per coupling step")
    ax.title.set_fontsize(9)
    ax.grid(True, which="both", alpha=0.25)
    ax.legend(fontsize=7)
    save(fig, "coupling_step")


def own_limit(jobs, res):
    """Part 1's largest stable generalized-alpha step (rho_inf = RHO_INF) scaled to the scene's E as E^-1/2, as
    text ("-" if part 1 has none)."""
    E_scene = load_scene(SCENE)["structure"]["bodies"][0]["section"]["youngs_modulus"]
    steps = [step_of(res[j], "stable") * math.sqrt(j.E / E_scene) for j in jobs
             if j.rho == RHO_INF and "error" not in res[j] and step_of(res[j], "stable")]
    return f"{span([1e3 * h for h in steps], '.2g')} ms" if steps else "-"


# ---- the doc --------------------------------------------------------------------------------------------
def rk4_facts(jobs, res):
    """Doc lines on RK4 against its estimate and the scaling with E."""
    rk4 = [(j.E, res[j]) for j in jobs if j.rho is None and "error" not in res[j]]
    low = [step_of(r, "stable") * r["omega_max"] / RK4_IMAGINARY for _, r in rk4 if step_of(r, "stable")]
    high = [step_of(r, "unstable") * r["omega_max"] / RK4_IMAGINARY for _, r in rk4 if step_of(r, "unstable")]
    if not low or not high:
        return ["- RK4: no bracketed limit (see the table)."]
    pts = np.array([(E, step_of(r, "stable")) for E, r in rk4 if step_of(r, "stable")])
    b = float(np.polyfit(np.log(pts[:, 0]), np.log(pts[:, 1]), 1)[0]) if len(pts) > 1 else math.nan
    return [f"- RK4: the largest stable grid step is {span(low, '.3f')} times the estimate 2 sqrt(2) / "
            f"omega_max and the next grid step, {span(high, '.3f')} times it, is unstable: the "
            "estimate brackets the measured limit to the grid's 4.4 %. 2 sqrt(2) = 2.828 is RK4's limit on the "
            "imaginary axis, where an undamped mode's eigenvalues +- i omega lie; "
            f"{RK4_REAL} / omega_max (the limit on the negative real axis, for real eigenvalues of heavily damped "
            f"modes) is {RK4_REAL / RK4_IMAGINARY:.3f} of it and does not apply to this undamped wing. Fitted: "
            f"largest stable step ~ E^{b:.3f} (the scaled problem is similar at every E: -0.5)."]


def ga_facts(jobs, res):
    """Doc lines on generalized-alpha: its largest steps against RK4's and the first period."""
    lines = []
    for integrator, rho in dict.fromkeys((j.integrator, j.rho) for j in jobs if j.rho is not None):
        runs = [(j.E, res[j]) for j in jobs if (j.integrator, j.rho) == (integrator, rho) and "error" not in res[j]]
        steps = [(E, step_of(r, "stable"), r["omega_1"]) for E, r in runs if step_of(r, "stable")]
        ratios = [h / step_of(rk4_of(jobs, res, E), "stable") for E, h, _ in steps
                  if rk4_of(jobs, res, E) and step_of(rk4_of(jobs, res, E), "stable")]
        per = [2 * math.pi / w / h for _, h, w in steps]
        if ratios:
            lines.append(f"  - rho_inf = {rho:g}: {span(ratios, '.0f')} times RK4's largest step, "
                         f"{span(per, '.0f')} steps per first-bending period.")
    ga = [j for j in jobs if j.rho is not None and "error" not in res[j] and res[j].get("unstable") is not None]
    newton = sum("Newton" in res[j]["rows"][res[j]["unstable"]]["message"] for j in ga)
    cause = ("its largest step is set by the Newton iteration of a step, which the solver reports as \"diverged\""
             if ga and newton == len(ga) else
             f"the smallest unstable step failed in the Newton iteration of a step in {newton} of {len(ga)} searches")
    return ["- Generalized-alpha is unconditionally stable for linear problems; on this nonlinear, constrained",
            f"  beam {cause} (table below):"] + lines


def free_mass_miss(jobs, res, est, V):
    """Text: by what factor the free-mass estimate overshoots the measured onsets at speed V (where it does)."""
    parts = []
    for a in ("gauss-seidel", "jacobi"):
        low, high = onset(a, jobs, res, V)
        predicted = predicted_onset(est, est["mu_crit"][a])
        if high is not None and predicted > high:
            above = f"{predicted / high:.2g} to {predicted / low:.2g}" if low else f"at least {predicted / high:.2g}"
            parts.append(f"{a}'s by a factor {above}")
    return f", and overshoots {' and '.join(parts)}" if parts else ""


def modal_section(jobs, res, est, V):
    """Part 2's added-mass onsets at speed V explained mode by mode (modal_growth) against the measured map."""
    factors = sorted({j.factor for j in jobs})
    modal, algorithms = est["modal"], ("gauss-seidel", "jacobi")
    rows, first = [], {}
    for f in factors:
        row = [f"{f:g}"]
        for a in algorithms:
            energy, mode = modal_growth(est, a, f)
            out = point(jobs, res, a, V, f)
            if energy > 1.0:
                first.setdefault(a, (f, mode))
            row += [f"{energy:.3g} ({modal['omega'][mode] / (2 * math.pi):.0f} Hz)", "-" if out is None else cell(out)]
        rows.append(row)

    def said(a):
        if a not in first:
            return f"{a}: none on the grid"
        f, mode = first[a]
        omega = modal["omega"][mode]
        return (f"{a} from {f:g} x air (the {omega / (2 * math.pi):.0f} Hz mode, omega h = {omega * COUPLING_STEP:.2f}, "
                f"added-mass ratio {modal['mu'][mode] * AIR:.4f} at 1.2 kg/m^3)")
    steps = round(COUPLED_STOP / COUPLING_STEP)
    return ["Mode by mode. A mode that oscillates within a coupling step reacts to the held, lagged fluid force",
            "differently from a free mass: `coupled_mode_radius` takes one structural mode (its omega h, its own",
            "added-mass ratio phi^T M_a phi / phi^T M phi) through the same coupled step, and `modal_growth` starts",
            "each mode with its peak kinetic energy under the sudden tip load (summed over the modes:",
            f"{modal['kinetic'].sum():.4f} P delta_s, the physical bound 1/2) and grows it by",
            f"the step's spectral radius squared over the run's {steps} steps. The largest mode's predicted peak "
            "kinetic energy / (P delta_s), against the map's bound 1 and the measured run:",
            "",
            *table(["density x 1.2 (kg/m^3)", "gauss-seidel predicted (mode)", "gauss-seidel measured",
                    "jacobi predicted (mode)", "jacobi measured"], rows),
            "",
            f"Predicted to break the bound: {'; '.join(said(a) for a in algorithms)}. Where the predicted and "
            "measured onsets agree, the onset is set not by the mode with the most added mass but by one that "
            "oscillates within a coupling step (omega h above 1), whose lagged added-mass force pumps energy in "
            "faster than the integrator damps it. Left out: the coupling between modes through M_a, and the flow "
            "(these are the map's rows at 0 m/s)."]


def coupling_section(jobs, res, est):
    """Part 2 of the doc: the maps, the added-mass and divergence estimates against the measured onsets."""
    speeds = sorted({j.V for j in jobs})
    algorithms = [a for a in ALGORITHMS if any(j.algorithm == a for j in jobs)]
    ratio_2d = est["model_factor"] * est["plate"] / est["m_s"] * AIR
    gs, jac = est["mu_crit"]["gauss-seidel"], est["mu_crit"]["jacobi"]
    L = ["## 2. Explicit against implicit coupling: flow speed and air density",
         "",
         f"The wing coupled with uvlm-flat (M = {est['M']}, N = 7), coupling.step = {COUPLING_STEP * 1e3:g} ms, "
         f"the structure in {SUBSTEPS} generalized-alpha steps of {COUPLING_STEP / SUBSTEPS * 1e3:g} ms per coupling "
         f"step (rho_inf = {RHO_INF:g}), {COUPLED_STOP * 1e3:g} ms per run (about one first-bending period), zero "
         "incidence (the tip load alone excites the wing). `gauss-seidel` and `jacobi` are explicit; `implicit`",
         "iterates each step to coupling.tolerance = 1e-6 with Aitken relaxation (the defaults), at "
         + ", ".join(f"{V:g}" for V in IMPLICIT_SPEEDS) + " m/s only (an implicit run costs about ten explicit ones).",
         "One symbol per run: S stable; D diverged (status \"diverged\" from the units or the implicit coupling);",
         "! status \"error\" (a failure that is not a divergence); "
         f"R runaway (kinetic energy above {RUNAWAY_FACTOR:g} P delta_s, stopped by the benchmark before "
         "the units reported anything); E status \"ok\" but KE > P delta_s; X status \"ok\" but tip > 4 delta_s;",
         ". not run.",
         ""]
    for a in algorithms:
        L += [f"**{a}**", "", *table_map(a, jobs, res), ""]
    L += ["![coupling stability map](img/stability_coupling.png)", ""]
    measured = []
    for a in algorithms:
        low, high = onset(a, jobs, res, speeds[0])
        measured.append(f"{a} stable up to {fmt(low, 'g')} x air, unstable at {fmt(high, 'g')} x air" if high
                        else f"{a} stable up to {fmt(low, 'g')} x air (all)")
    m_a = est["plate"] * AIR
    L += ["### Added mass: why explicit coupling fails in dense air",
          "",
          "The air a wing accelerates has inertia: a flat plate of chord c carries the added mass",
          "m_a = rho pi c^2 / 4 per unit span (Theodorsen's apparent mass). An explicit scheme applies the fluid",
          "force of the previous motion; that force is proportional to the acceleration, and one step late it",
          "overcorrects: the structure accelerates against last step's fluid force, the fluid answers with a larger",
          "opposite force, and the motion flips sign and grows every step once m_a / m_s passes a number of order",
          "one, whatever the step (Causin, Gerbeau and Nobile 2005). For uvlm-flat the force is the second-order",
          "backward difference of a circulation proportional to the velocity; the limit ratio mu_crit of a free",
          "mass so coupled (function critical_mass_ratio) depends on how the structure integrates the held force:",
          f"with {SUBSTEPS} generalized-alpha steps per coupling step (rho_inf = {RHO_INF:g}) Gauss-Seidel is "
          f"stable up to mu = {gs:.3f} and Jacobi up to {jac:.3f}; with many steps (the plain",
          f"v_(n+1) = v_n + h F_n / m_s) {est['mu_crit_plain']['gauss-seidel']:.3f} and "
          f"{est['mu_crit_plain']['jacobi']:.3f}.",
          "",
          f"- Structure: m_s = rho_s c h = {est['m_s']:.4g} kg/m. 2D flat plate at 1.2 kg/m^3: m_a = {m_a:.3g} kg/m, "
          f"m_a / m_s = {m_a / est['m_s']:.4f}.",
          f"- uvlm-flat's quasi-steady circulation carries (3 + 1/M) = {est['model_factor']:.2f} times Theodorsen's "
          f"apparent mass (aero_fmu/uvlm.py): in 2D its ratio is {ratio_2d:.4f} at 1.2 kg/m^3, and Gauss-Seidel "
          f"would fail from {gs / ratio_2d:.3g} x air.",
          f"- The lattice itself (aspect ratio {est['aspect']:.0f}, tip relief) carries less: the largest ratio of its "
          f"added mass to the wing's mass over all shapes is {est['mu_max'] * AIR:.4f} at 1.2 kg/m^3, "
          f"{est['mu_1'] * AIR:.4f} for the first bending mode (function lattice_added_mass). Predicted onset: "
          f"Gauss-Seidel {predicted_onset(est, gs):.3g} x air, Jacobi {predicted_onset(est, jac):.3g} x air.",
          f"- Measured at {speeds[0]:g} m/s: {'; '.join(measured)}.",
          "- The estimate treats a free mass (omega h << 1) in one shape" + free_mass_miss(jobs, res, est, speeds[0])
          + ".",
          "",
          *modal_section(jobs, res, est, speeds[0]),
          ""]
    L += ["### Torsional divergence: where no coupling scheme helps",
          "",
          "The reference line is at mid-chord and the lift acts near the quarter chord, so lift twists the wing",
          "nose-up; above the dynamic pressure q_D = GJ (pi / 2L)^2 / (c e a) (e = c / 4, a the lift slope; uniform",
          f"lift, a first estimate) the twist grows without bound. With the lattice's lift slope a = {est['slope']:.3f}"
          f" /rad (2D: 2 pi = 6.283) q_D = {est['q_D']:.0f} Pa, a divergence speed of "
          + ", ".join(f"{divergence_speed(est, f):.0f} m/s at {f:g} x air" for f in (1, 10, 30, 100)) + ".",
          "Beyond it (dashed line in the figure) the wing itself is unstable and no coupling scheme can be stable;",
          "below it an undamped wing can still flutter (the last table of this part).",
          ""]
    flagged = unflagged(jobs, res)
    ended_ok = [(j, r) for j, r in flagged if r["status"] == "ok"]
    if flagged:
        L += ["### Unstable runs the units did not report", "",
              f"{len(flagged)} of {len(jobs)} runs were unstable without a \"diverged\" from the units: the master "
              "watches only the units' own checks (NaN/inf, constraint residual, gradient size, Newton, the implicit "
              f"iteration), not the response. {len(flagged) - len(ended_ok)} of them (R) were stopped by the "
              f"benchmark at {RUNAWAY_FACTOR:g} P delta_s, up to "
              f"{max((r['ke_max'] for _, r in flagged), default=0):.3g} J of kinetic energy and "
              f"{1e3 * max((r['tip_max'] for _, r in flagged), default=0):.3g} mm of tip displacement, before "
              f"any unit complained. {len(ended_ok)} ended with status \"ok\" although a bound was exceeded"
              + (":" if ended_ok else "."), ""]
        if ended_ok:
            L += table(["algorithm", "speed (m/s)", "density x 1.2", "KE max (J)", "P delta_s (J)", "tip max (mm)",
                        "4 delta_s (mm)"],
                       [[j.algorithm, f"{j.V:g}", f"{j.factor:g}", f"{r['ke_max']:.3g}", f"{r['ke_bound']:.3g}",
                         f"{1e3 * r['tip_max']:.3g}", f"{1e3 * r['tip_bound']:.3g}"] for j, r in ended_ok]) + [""]
        run_on = run_on_pairs(jobs, res)
        if run_on:
            L += run_on_section(run_on) + [""]
    errors = [(j, res[j]) for j in jobs if "error" in res[j] or res[j]["why"] == "error"]
    if errors:
        L += ["Runs that ended with status \"error\" (not a divergence):", ""]
        L += [f"- {j.label}: {r.get('error') or reason(r['message'])}" for j, r in errors] + [""]
    failed = [(j, res[j]) for j in jobs if j.algorithm == "implicit" and "error" not in res[j] and res[j]["why"] == "solver"]
    if failed:
        residuals = [float(m.group(1)) for _, r in failed
                     if (m := re.search(r"interface residual ([0-9.e+-]+) after", r["message"]))]
        newton = sum("Newton" in r["message"] for _, r in failed)
        L += [f"Implicit runs that stopped as \"diverged\": {newton} of {len(failed)} because the structure's Newton "
              "iteration (generalized-alpha, inside a coupling iteration) failed, "
              f"{len(residuals)} because the interface residual did not fall below 1e-6 in 50 iterations; of these, "
              f"{sum(r < 10e-6 for r in residuals)} ended within ten times the tolerance (the Aitken iteration stalls) "
              f"and {sum(r > 1e-2 for r in residuals)} above 1e-2 (the iteration diverges, in the first step: past "
              "the divergence speed a held force no longer converges):", ""]
        L += table(["speed (m/s)", "density x 1.2", "t (s)", "message"],
                   [[f"{j.V:g}", f"{j.factor:g}", f"{r['simulated_s']:.3g}",
                     reason(r["message"])] for j, r in failed])
        L += [""]
    return L


def flutter_facts(jobs, res):
    """Doc lines on part 5: how each scheme's peak kinetic energy moves as the coupling step shrinks."""
    lines = []
    for a in ("gauss-seidel", "implicit"):
        runs = sorted((j.step, res[j]) for j in jobs if j.algorithm == a and "error" not in res[j])
        if len(runs) < 2:
            continue
        energies = [r["ke_max"] for _, r in reversed(runs)]          # largest step first
        trend = ("rises" if all(np.diff(energies) > 0) else "falls" if all(np.diff(energies) < 0)
                 else "changes non-monotonically")
        lines.append(f"- {a}: as the coupling step shrinks from {runs[-1][0] * 1e3:g} to {runs[0][0] * 1e3:g} ms the "
                     f"peak kinetic energy {trend} ({', '.join(f'{e:.3g}' for e in energies)} J); at the smallest step "
                     f"the run is {'stable' if runs[0][1]['stable'] else 'unstable'}.")
    return lines


def line_facts(jobs, res):
    """Doc lines on part 3: the densities without any stable Gauss-Seidel step, and what stopped the top steps."""
    lines = []
    none = sorted(j.factor for j in jobs if j.algorithm == "gauss-seidel" and "error" not in res[j]
                  and step_of(res[j], "stable") is None)
    if none:
        smallest = min(step_of(res[j], "unstable") for j in jobs if j.algorithm == "gauss-seidel" and j.factor in none)
        lines.append(f"- Gauss-Seidel has no stable coupling step at {', '.join(f'{f:g}' for f in none)} x air, down to "
                     f"{smallest * 1e3:.3g} ms: the added-mass instability does not go away with a smaller step.")
    newton = [j for j in jobs if "error" not in res[j] and res[j].get("unstable") is not None
              and "Newton" in res[j]["rows"][res[j]["unstable"]]["message"]]
    if newton:
        lines.append(f"- {len(newton)} of {len(jobs)} searches ended at a step where the structure's Newton iteration "
                     "failed, not the coupling: " + ", ".join(f"{j.algorithm} at {j.factor:g} x air" for j in newton)
                     + ".")
    return lines


def write_doc(parts, res, est, wall, args):
    """docs/stability.md from the results (every number from the runs or the estimates above)."""
    p1, p2, p3, p4, p5 = (parts.get(k, []) for k in (1, 2, 3, 4, 5))
    runs = sum(len(r["rows"]) if "rows" in r else 1 for r in res.values())
    command = "python benchmarks/stability.py" + (f" --jobs {args.jobs}" if args.jobs != 2 else "")
    L = ["# Stability map",
         "",
         f"Written by `{command}`: {runs} runs in {len(res)} jobs, {wall / 60:.1f} min wall time on {args.jobs} "
         f"process{'es' if args.jobs > 1 else ''} (a shared machine). Every number below comes from these runs or "
         "from the estimates in `benchmarks/stability.py`; rerun the command to refresh it.",
         "",
         "## The case and what \"stable\" means",
         "",
         "`scenes/stability_wing.toml`: the inner PVC body of `deploy_flexible` (003 Table 5: 0.15 m span,",
         "chord 0.05 m, plate 2 mm, 1425 kg/m^3, E = 2.83 GPa, GJ = 0.18 N m^2) alone, clamped at its root,",
         "7 elements, no damping, no gravity. A tip load P = 0.1 EI_yy / L^2 along the section normal is applied",
         "suddenly at t = 0: its linear static tip deflection is delta_s = P L^3 / (3 EI_yy) = L / 30 = 5 mm at",
         "every stiffness, and the jump excites every mode, so an unstable scheme shows within a few hundred steps.",
         "",
         "A run is **stable** when",
         "",
         "1. it ends with status \"ok\" (the structure unit stops a run as \"diverged\" on NaN/inf, a constraint",
         "   residual above 1e-4, gradient vectors above 1e3, or a Newton failure of generalized-alpha; the implicit",
         "   coupling when a step does not converge),",
         "2. its kinetic energy never exceeds P delta_s, and",
         "3. its tip never moves more than 4 delta_s from where it started.",
         "",
         "An undamped linear structure under a suddenly applied dead load keeps KE <= P^2 (K^-1)_tip,tip / 2 =",
         "P delta_s / 2 and its tip within 2 delta_s of the start (energy conservation; air at rest only stores or",
         "dissipates energy), so 2. and 3. allow twice the largest physical response. In moving air the free",
         "stream can feed the wing (divergence, flutter): such runs count as unstable too, their response is not",
         "bounded, and the estimates below tell the physical from the numerical instability. A run whose kinetic",
         f"energy passes {RUNAWAY_FACTOR:g} P delta_s is stopped there to save time (\"runaway\").",
         "",
         "The largest stable step is found by a bracketing search on a geometric grid h_k = h_top 2^(-k/n): halve",
         "the step from h_top until a run is stable, then bisect that octave on the grid (assuming stability is",
         "monotonic inside it); each probe is a real run. The result is the largest stable grid step, and the",
         "next grid step up was unstable.",
         ""]
    if p1:
        L += ["## 1. Largest stable structural step against stiffness",
              "",
              "Structure only. E from 1e6 to 1e12 Pa with every stiffness scaled with it (EA and EI from the plate,",
              "GJ = 0.18 N m^2 x E / 2.83 GPa: a material of fixed Poisson ratio); the load scales with EI, so the",
              "deflections are the same at every E and only the time scale changes (frequencies as sqrt(E)).",
              "Grid: h_top = T_1 / 4 (T_1 = 2 pi / omega_1, the first bending period), 16 steps per octave (4.4 %",
              "apart), down to 14 octaves. Runs last 2 T_1 (generalized-alpha) or 200 periods of the highest mode,",
              "200 x 2 pi / omega_max (RK4: about 450 steps at its limit). omega_1 and omega_max are the lowest and",
              "highest natural frequencies of the discretized beam linearized at rest (`structure_fmu/modes.py`).",
              "",
              *table_stiffness(p1, res),
              "",
              "A generalized-alpha cell: its largest stable step (s), and that step over RK4's.",
              "",
              "![largest stable step against stiffness](img/stability_stiffness.png)",
              "",
              *rk4_facts(p1, res),
              *ga_facts(p1, res),
              "",
              "How the smallest unstable grid step failed:",
              "",
              *table_failures(p1, res),
              ""]
    if p2:
        L += coupling_section(p2, res, est)
    if p5:
        V, factor, _ = FLUTTER_CASE
        L += ["### Flutter: where the explicit and the implicit map disagree",
              "",
              f"At {V:g} m/s and {factor:g} x air (below the static divergence speed, "
              f"{divergence_speed(est, factor):.0f} m/s) the same case at three coupling steps, the structure in "
              f"{SUBSTEPS} steps per coupling step. The tip twist is the angle of the tip chord line (probes "
              "tip_leading_edge, tip_trailing_edge) out of its plane at rest. The wing has no structural damping, so "
              "a bending-torsion flutter has nothing to stop it; a scheme that converges with the step must show "
              "the same growth at every small enough step.",
              "",
              *table_flutter(p5, res),
              "",
              *flutter_facts(p5, res),
              ""]
    if p3:
        L += ["## 3. Largest stable coupling step at 10 m/s",
              "",
              f"uvlm-flat at {LINE_SPEED:g} m/s (deploy_flexible's speed), coupling.step on the grid "
              f"{LINE_TOP * 1e3:g} ms x 2^(-k/4) (19 % apart), the structure in {SUBSTEPS} steps per coupling step as "
              f"in part 2; Gauss-Seidel down to 5 octaves, implicit (more expensive) down to 3; runs of max(50 ms, "
              f"20 coupling steps). At the top the structure's step is {LINE_TOP / SUBSTEPS * 1e3:g} ms, close to "
              f"generalized-alpha's own limit on this wing in still air ({own_limit(p1, res)} from part 1, "
              "rho_inf = 0.8, scaled to E = 2.83 GPa as E^-1/2): a failure there can be the structure's Newton "
              "iteration, as the messages say.",
              "",
              *table_line(p3, res),
              "",
              *line_facts(p3, res),
              "",
              "![largest stable coupling step](img/stability_coupling_step.png)",
              ""]
    if p4:
        step, _, _ = SUBSTEP_CASE
        L += ["### Gauss-Seidel's added-mass limit depends on the structure's steps per coupling step",
              "",
              f"Gauss-Seidel at 0 m/s, coupling.step = {step * 1e3:g} ms, the structure taking it in 1, 2, 4 or 8 "
              f"generalized-alpha steps (rho_inf = {RHO_INF:g}). With one step the integrator's auxiliary "
              "acceleration blends the previous coupling step's force into the velocity update (004 Eqs. 23-25), "
              "which damps the sign-alternating mode; with more steps the blend fades and the limit falls towards "
              f"the plain {est['mu_crit_plain']['gauss-seidel']:.3f} (critical_mass_ratio). Predicted onsets use "
              "the lattice's largest added-mass ratio:",
              "",
              *table_substeps(p4, res, est),
              ""]
    DOC.write_text("\n".join(L) + "\n")
    print(f"wrote {DOC.relative_to(ROOT)}")


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="a few short searches and runs, tables only")
    parser.add_argument("--jobs", type=int, default=2, help="worker processes (default 2)")
    parser.add_argument("--parts", type=int, nargs="+", default=[1, 2, 3, 4, 5], choices=[1, 2, 3, 4, 5])
    parser.add_argument("--no-plots", action="store_true", help="print the tables only")
    args = parser.parse_args(argv)

    parts = {p: jobs for p, jobs in plan(args.quick).items() if p in args.parts}
    start = time.perf_counter()
    est = estimates() if {2, 4, 5} & set(parts) else None
    res = run_all([j for jobs in parts.values() for j in jobs], args.jobs)
    if 2 in parts and not args.quick:
        res.update(run_all(run_on_jobs(parts[2], res), args.jobs))
    wall = time.perf_counter() - start
    if 1 in parts:
        print("\n" + "\n".join(table_stiffness(parts[1], res)))
        print("\n" + "\n".join(table_failures(parts[1], res)))
    for a in ALGORITHMS if 2 in parts else ():
        if any(j.algorithm == a for j in parts[2]):
            print(f"\n{a}\n" + "\n".join(table_map(a, parts[2], res)))
    run_on = run_on_pairs(parts[2], res) if 2 in parts else []
    if run_on:
        print("\n" + "\n".join(run_on_section(run_on)))
    if 3 in parts:
        print("\n" + "\n".join(table_line(parts[3], res)))
    if 4 in parts:
        print("\n" + "\n".join(table_substeps(parts[4], res, est)))
    if 5 in parts:
        print("\n" + "\n".join(table_flutter(parts[5], res)))
    print(f"\n{len(res)} jobs in {wall:.0f} s wall time on {args.jobs} processes")
    if args.quick or sorted(parts) != [1, 2, 3, 4, 5]:
        return
    if not args.no_plots:
        IMG.mkdir(parents=True, exist_ok=True)
        plot_stiffness(parts[1], res)
        plot_coupling(parts[2], res, est)
        plot_line(parts[3], res)
    write_doc(parts, res, est, wall, args)


if __name__ == "__main__":
    main()
