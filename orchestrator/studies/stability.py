"""Stability estimates of the coupled wing: time-step limits, the added-mass limit of explicit coupling,
the lattice's added mass and lift slope, and the torsional divergence speed.

Independent of any coupled run: each is an analytic formula or a small linear model, so that a measured
stability map (benchmarks/stability.py, docs/studies/stability.md) can be checked against it. The map's
measuring tools are here too: a run under a sudden load judged stable or not (``sudden_load_run``, with
``EnergyLimit`` to stop a runaway), and the search for the largest stable step (``largest_stable_step``).

Model of the explicit coupling (``coupled_mode_radius``): one structural mode of unit modal mass and
natural frequency omega under the force of uvlm-flat's quasi-steady circulation, which is proportional to
the velocity; its time derivative, the second-order backward difference dGamma/dt, makes the force
    F_n = -mu (3 v_k - 4 v_(k-1) + v_(k-2)) / (2 h),   k = n - lag,
with mu = m_a / m_s the mode's added-mass ratio, h the coupling step, lag 0 for Gauss-Seidel (the
structure's newest state) and 1 for Jacobi. F_n is held over the step, which the structure takes in
``substeps`` generalized-alpha steps of x'' = F_n - omega^2 x in the form with an auxiliary acceleration
(Arnold and Brüls 2007; Peng et al. 2019, Eqs. 23-25):
    a_(n+1) = (alpha_f a'_n - alpha_m a_n + (1 - alpha_f) a'_(n+1)) / (1 - alpha_m),
    alpha_m = (2 rho_inf - 1) / (rho_inf + 1), alpha_f = rho_inf / (rho_inf + 1),
    gamma = 1/2 - alpha_m + alpha_f, beta = (1 - alpha_m + alpha_f)^2 / 4,
with a' the true acceleration, solving the equation of motion at the step's end, and a the auxiliary one
that updates x and v.
"""

from __future__ import annotations

import math
import time

import numpy as np

RK4_IMAGINARY = 2 * math.sqrt(2)
"""RK4's stability limit on the imaginary axis: |R(iy)| <= 1 for |y| <= 2 sqrt(2). An undamped mode has
eigenvalues +- i omega, so h omega <= 2 sqrt(2)."""
RK4_REAL = 2.785
"""RK4's limit on the negative real axis (|R(-x)| <= 1 for 0 <= x <= 2.785): heavily damped modes."""
LAGS = {"gauss-seidel": 0, "jacobi": 1}
"""Communication steps by which an explicit scheme's fluid force lags the structure's motion."""


def rk4_step_limit(omega_max: float) -> float:
    """Largest stable RK4 step (s) of an undamped linear structure whose highest natural frequency is
    ``omega_max`` (rad/s): RK4_IMAGINARY / omega_max."""
    return RK4_IMAGINARY / omega_max


def coupled_mode_radius(mu: float, lag: int, omega_h: float = 0.0, substeps: int = 4,
                        rho_inf: float = 0.8) -> float:
    """Spectral radius (-), per communication step, of one structural mode explicitly coupled with
    uvlm-flat's fluid force (the model of the module docstring).

    ``mu``: the mode's added-mass ratio m_a / m_s (-); ``lag``: 0 Gauss-Seidel, 1 Jacobi; ``omega_h``:
    omega h, the natural frequency (rad/s) times the coupling step (s); ``substeps``: generalized-alpha
    steps per coupling step; ``rho_inf``: their spectral radius at infinite frequency. For omega_h = 0 (a
    free mass) the neutral eigenvalue z = 1 (free drift) is left out. Above 1 the mode grows.
    """
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


def critical_mass_ratio(lag: int, substeps: int = 4, rho_inf: float = 0.8) -> float:
    """Largest added-mass ratio mu = m_a / m_s (-) for which explicit coupling of a free mass (no stiffness:
    the motions with omega h << 1) stays stable, ``coupled_mode_radius(mu, lag, 0, ...)`` <= 1, by
    bisection to machine precision. As ``substeps`` grows the first substep's blend of the old and the new
    force fades and the limit tends to that of v_(n+1) = v_n + h F_n / m_s: 1/2 for Gauss-Seidel (a root of
    z^2 + 3 mu z / 2 - mu / 2 at z = -1) and 0.607 for Jacobi."""
    low, high = 1e-3, 50.0
    for _ in range(60):
        mid = math.sqrt(low * high)
        stable = coupled_mode_radius(mid, lag, 0.0, substeps, rho_inf) <= 1.0 + 1e-9
        low, high = (mid, high) if stable else (low, mid)
    return low


def modal_growth(modes: dict, mu_scale: float, lag: int, step: float, steps: int, substeps: int = 4,
                 rho_inf: float = 0.8) -> tuple[float, int]:
    """(largest predicted peak kinetic energy, its mode index) after ``steps`` explicit coupling steps of
    ``step`` (s), each mode on its own.

    ``modes`` as ``lattice_added_mass`` returns them: per mode "omega" (rad/s), "mu" (added-mass ratio per
    kg/m^3) and "kinetic" (its peak kinetic energy under the load, any unit); ``mu_scale``: the air density
    (kg/m^3). Each mode starts with its kinetic energy and grows by coupled_mode_radius^2 per step (a
    decaying mode keeps its start). Coupling between the modes through the added mass is left out.
    """
    growth = np.array([max(1.0, coupled_mode_radius(mu * mu_scale, lag, omega * step, substeps, rho_inf))
                       ** (2 * steps) for mu, omega in zip(modes["mu"], modes["omega"])])
    energy = np.asarray(modes["kinetic"]) * growth
    mode = int(np.argmax(energy))
    return float(energy[mode]), mode


def tip_load_scale(scene: dict, body: str) -> tuple[float, float]:
    """(P in N, delta_s in m) of the scene's load case on ``body``: P = load.parameter EI_yy / L^2 and its
    linear static tip deflection delta_s = P L^3 / (3 EI_yy) of a clamped beam."""
    from fmu_common.wing_spec import StructureSpec
    from structure_fmu.topology import StructureTopology

    wing = StructureTopology.from_spec(StructureSpec.from_scene(scene)).bodies[body]
    P = scene["load"]["parameter"] * wing.section.flap / wing.length ** 2
    return P, P * wing.length ** 3 / (3 * wing.section.flap)


def _rest_coordinates(scene: dict):
    """(structure solver, its model, the gradient-deficient coordinates E0 at rest) of a scene."""
    from fmu_common.specs import StructureUnitSpec
    from structure_fmu.solver import StructureSolver

    solver = StructureSolver(StructureUnitSpec.from_scene(scene))
    q = solver.state.q
    E0, _, _ = solver.model.coordinates(q, np.zeros_like(q), 0.0)
    return solver, solver.model, E0


def lattice_added_mass(scene: dict, body: str) -> tuple[float, float, dict]:
    """(mu_max, mu_1, modes): added-mass ratios of the scene's uvlm lattice at zero flow speed, per kg/m^3
    of air (1/(kg/m^3)).

    M_a = -dQ/d(de') column by column, from three aero steps (h = 1 ms) with the coordinate rates de
    growing linearly in time, so dGamma/dt is exact; M is the structure's mass. mu_max is the largest
    generalized eigenvalue of (M_a, M) on the free coordinates (the span of the mass-normalized modes,
    tangent to the constraints), mu_1 = phi^T M_a phi / phi^T M phi of the first mode phi. ``modes``,
    per structural mode (``structure_fmu.modes.natural_modes``): "omega" (rad/s), "mu" (its added-mass
    ratio per kg/m^3) and "kinetic": the peak kinetic energy 1/2 (phi . f)^2 / omega^2 of the mode under
    the scene's load f applied suddenly, in units of P delta_s of ``tip_load_scale`` (summed over the
    modes 1/2 for a linear structure: energy conservation).
    """
    from scipy.linalg import eigvals

    from aero_fmu.solver import AeroSolver
    from fmu_common.specs import AeroUnitSpec
    from structure_fmu.modes import natural_modes

    solver, model, E0 = _rest_coordinates(scene)
    B = model.velocity_map(solver.state.q, solver.state.t)      # dE/dq: T (ANCF) or the strain-based map
    h, scale = 1e-3, 1e-3
    columns, spec = [], AeroUnitSpec.from_scene(scene)
    for j in range(B.shape[1]):
        aero = AeroSolver(spec, {"flow.speed": 0.0, "flow.density": 1.0})
        for k in range(3):
            aero.advance(k * h, E0, k * h * scale * B[:, j])
        columns.append(-aero.Q / scale)
    omega, shapes = natural_modes(solver)
    added = shapes.T @ B.T @ np.array(columns).T @ shapes      # (M_a, M) on the modes' span
    ratios = np.diag(added)
    P, delta = tip_load_scale(scene, body)
    load = model.force_E(E0, np.zeros_like(E0), 1.0, np.zeros_like(E0), {}) - model.gravity_E
    modal_force = shapes.T @ (B.T @ load)
    modes = {"omega": omega, "mu": ratios,
             "kinetic": 0.5 * modal_force ** 2 / np.maximum(omega ** 2, np.finfo(float).tiny) / (P * delta)}
    return float(np.max(eigvals(added).real)), float(ratios[0]), modes


def lift_slope(scene: dict, alpha: float = 0.01, speed: float = 10.0) -> float:
    """dCL/dalpha (1/rad) of the scene's lattice at rest: |CL| / alpha of the first (steady) aero step at a
    small incidence ``alpha`` (rad) in the x-y plane, at ``speed`` (m/s)."""
    from aero_fmu.solver import AeroSolver
    from fmu_common.specs import AeroUnitSpec

    _, _, E0 = _rest_coordinates(scene)
    aero = AeroSolver(AeroUnitSpec.from_scene(scene), {"flow.speed": speed, "flow.direction[1]": math.cos(alpha),
                                                      "flow.direction[2]": math.sin(alpha), "flow.direction[3]": 0.0})
    aero.advance(0.0, E0, np.zeros_like(E0))
    return abs(aero.outputs()["CL"]) / alpha


def divergence_pressure(torsional_rigidity: float, span: float, chord: float, offset: float,
                        slope: float) -> float:
    """Dynamic pressure (Pa) of torsional divergence of a clamped wing under uniform lift:
    q_D = GJ (pi / 2L)^2 / (c e a), with GJ (N m^2), span L (m), chord c (m), e (m) the aerodynamic
    centre's distance ahead of the elastic axis and a the lift slope (1/rad)."""
    return torsional_rigidity * (math.pi / (2 * span)) ** 2 / (chord * offset * slope)


def divergence_speed(pressure: float, density: float) -> float:
    """Flow speed (m/s) at which the dynamic pressure rho V^2 / 2 reaches ``pressure`` (Pa)."""
    return math.sqrt(2 * pressure / density)


def stiffness_overrides(scene: dict, body: str, youngs_modulus: float) -> list[str]:
    """``--set`` overrides giving ``body`` Young's modulus E (Pa) with every stiffness scaled with it: EA and
    EI of the plate follow from the section; GJ, the stiffnesses given explicitly and their tip values (a section
    varying along the span) are scaled by E / E_scene (a material of fixed Poisson ratio)."""
    section = next(b for b in scene["structure"]["bodies"] if b["name"] == body)["section"]
    factor = youngs_modulus / section["youngs_modulus"]
    keys = [key for name in STIFFNESSES for key in (name, f"{name}_tip")]
    given = [key for key in keys if section.get(key) is not None]
    return [f"structure.bodies.{body}.section.youngs_modulus={float(youngs_modulus)!r}",
            *(f"structure.bodies.{body}.section.{key}={float(section[key] * factor)!r}" for key in given)]


STIFFNESSES = ("torsional_rigidity", "axial_stiffness", "bending_stiffness_flap", "bending_stiffness_chord")
"""The section keys that are stiffnesses (N or N m^2): each scales with Young's modulus."""


def frequency_range(scene: dict) -> tuple[float, float]:
    """(omega_1, omega_max) rad/s: the lowest and highest natural frequencies of the scene's structure
    linearized at rest (``structure_fmu.modes``)."""
    from structure_fmu.modes import natural_frequencies
    from fmu_common.specs import StructureUnitSpec
    from structure_fmu.solver import StructureSolver

    omega = natural_frequencies(StructureSolver(StructureUnitSpec.from_scene(scene)), count=None)
    return float(omega[0]), float(omega.max())


def sudden_load_response(series, probe: str, P: float, delta: float) -> dict:
    """The response of a run to a dead load P (N) applied suddenly at t = 0, whose linear static deflection at
    ``probe`` is ``delta`` (m), against twice what an undamped linear structure can reach.

    Energy conservation bounds such a structure's kinetic energy by P^2 (K^-1)_pp / 2 = P delta / 2 and the
    probe's displacement by 2 delta (air at rest only stores or dissipates energy). Returns "ke_max" (J),
    "tip_max" (m, the probe's largest distance from its first position), "ke_bound" = P delta (J),
    "tip_bound" = 4 delta (m), "unbounded_s" (s, the first sample outside a bound; NaN if none) and
    "bounded" (no sample outside, NaN samples ignored).
    """
    position = series.positions[:, series.probe_names.index(probe)]
    displacement = np.linalg.norm(position - position[:1], axis=1)
    kinetic = series.kinetic_energy
    with np.errstate(invalid="ignore"):
        ke = float(np.nanmax(kinetic)) if len(series) else math.nan
        tip = float(np.nanmax(displacement)) if len(series) else math.nan
        outside = (kinetic > P * delta) | (displacement > 4 * delta)
    return {"ke_max": ke, "tip_max": tip, "ke_bound": P * delta, "tip_bound": 4 * delta,
            "unbounded_s": float(series.time[np.argmax(outside)]) if outside.any() else math.nan,
            "bounded": bool(ke <= P * delta and tip <= 4 * delta)}


def sudden_load_run(scene: dict, body: str, probe: str, runaway: float | None = None,
                    message: str = "runaway") -> tuple[dict, object]:
    """(record, series) of one in-process run of a scene whose load on ``body`` is applied suddenly at t = 0
    (``tip_load_scale``), judged at ``probe`` (``sudden_load_response``).

    The record: "status", "message", "simulated_s" of the run, "wall_s" (s), the response's bounds and
    maxima, "stable" and "why": "" (status "ok", within both bounds), "energy" or "displacement" (status
    "ok", that bound exceeded), "solver" (status "diverged"), "error" (status "error"), or "runaway": stopped
    by an ``EnergyLimit`` at ``runaway`` x P delta_s (J), its message starting with ``message``.
    """
    from orchestrator.run.master import run_scene

    P, delta = tip_load_scale(scene, body)
    hooks = EnergyLimit(runaway * P * delta, message) if runaway is not None else None
    start = time.perf_counter()
    result = run_scene(scene, backend="direct", units=hooks, progress=hooks)
    response = sudden_load_response(result.series, probe, P, delta)
    if result.status == "ok":
        why = ("energy" if not response["ke_max"] <= response["ke_bound"] else
               "displacement" if not response["tip_max"] <= response["tip_bound"] else "")
    else:
        stopped = hooks is not None and hooks.stopped is not None
        why = "error" if result.status == "error" else "runaway" if stopped else "solver"
    return {"status": result.status, "message": result.message, "simulated_s": result.simulated_time_s,
            "wall_s": time.perf_counter() - start, **response, "stable": not why, "why": why}, result.series


class EnergyLimit:
    """``run_scene``'s ``units`` and ``progress`` hooks that stop a run once the structure's kinetic energy
    exceeds ``limit`` (J): after a communication step past it, a ``UnitError`` with ``diverged`` True (the
    run ends "diverged", its message starting with ``message``) and ``stopped`` = that step's time (s)."""

    def __init__(self, limit: float, message: str = "kinetic energy limit"):
        from orchestrator.run import units
        self._units, self.UnitError = units, units.UnitError
        self.limit, self.message, self.structure, self.stopped = limit, message, None, None

    def make_unit(self, **kwargs):
        unit = self._units.make_unit(**kwargs)
        if kwargs["kind"] == "structure":
            self.structure = unit
        return unit

    def update(self, t: float) -> None:
        kinetic = self.structure.monitors()["kinetic_energy"]
        if not kinetic <= self.limit:
            self.stopped = t
            raise self.UnitError(f"{self.message}: kinetic energy {kinetic:.3g} J > {self.limit:.3g} J at "
                                 f"t = {t:.6g} s (run diverged, stopped here)", diverged=True)

    def finish(self, t: float, status: str) -> None:
        pass


def largest_stable_step(run, top: float, fine: int, octaves: int) -> dict:
    """The largest step h_k = top 2^(-k/fine), k = 0 ... fine x octaves, for which ``run(h)`` (a dict with a
    bool "stable") is stable, by a bracketing search: halve the step from ``top`` until a run is stable,
    then bisect that octave on the grid (stability assumed monotonic inside it); each probe is one call.

    Returns {"top", "fine", "stable": k of the largest stable grid step or None, "unstable": k of the next
    step up (unstable) or None when ``top`` is stable, "rows": {str(k): run(h_k)} of every probe}.
    """
    rows, k = {}, 0
    out = {"top": top, "fine": fine, "stable": None, "unstable": None, "rows": rows}
    while k <= fine * octaves:
        rows[str(k)] = run(top * 2.0 ** (-k / fine))
        if rows[str(k)]["stable"]:
            break
        k += fine
    else:
        return {**out, "unstable": k - fine}
    if k == 0:
        return {**out, "stable": 0}
    unstable, stable = k - fine, k
    while stable - unstable > 1:
        mid = (stable + unstable) // 2
        rows[str(mid)] = run(top * 2.0 ** (-mid / fine))
        stable, unstable = (mid, unstable) if rows[str(mid)]["stable"] else (stable, mid)
    return {**out, "stable": stable, "unstable": unstable}


def grid_step(search: dict, which: str) -> float | None:
    """The step (s) of ``largest_stable_step``'s result ``search`` at its ``which`` = "stable" or "unstable"
    end, top 2^(-k/fine), or None where that end is None."""
    k = search.get(which)
    return None if k is None else search["top"] * 2.0 ** (-k / search["fine"])


def grid_probe(search: dict, which: str) -> dict | None:
    """What ``run`` returned at the ``which`` = "stable" or "unstable" end of ``largest_stable_step``'s result
    ``search``, or None where that end is None."""
    return None if search.get(which) is None else search["rows"][str(search[which])]
