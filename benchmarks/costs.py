"""The papers' cost claims measured: the flat wake against the free wake (Otsuka et al. 2019, Sec. VII.A) and the
strain-based beam against a finite-segment model (Otsuka et al. 2022, Sec. 4.4), each with the accuracy it buys.

    python benchmarks/costs.py [--quick] [--jobs 2] [--resume] [--no-plots] [--repeats 3]

Part 1 runs scenes/deploy_rigid.toml (the rigid aluminium wing of Otsuka et al. 2019) at 15 m/s, the speed of that
paper's convergence tests, with uvlm-flat and uvlm-free at its two panel settings (M = N = 1 per body, its
convergence tests; M = 2, N = 7 per body, its deployments) and two wake lengths (L_w = 5 chords, its truncation;
aero.wake_length = inf, "all wake"). Part 2 runs scenes/two_body_003.toml (Otsuka et al. 2022, Table 4) in the
strain-based and ANCF (flexible) fidelities, and a planar finite-segment chain as 2022 defines it (springs EI/l, the
clamp's too), integrated like 2022's by generalized-alpha at h = 0.01 s (FiniteSegmentAlpha below); the chain of
tests/finite_segment_chain.py (clamp 2 EI/l, DOP853 at rtol 1e-9) is the independent reference, as in
benchmarks/fidelity.py. Every scene run is `orchestrator.run.master.run_scene(scene, backend="direct")`, the path
`wingsim run --backend direct` takes. Costs are CPU times (time.process_time) of each run in its worker process,
the median of --repeats interleaved repeats (every configuration once, then again), imports excluded.
--quick: one repeat, short runs, no errors of part 2.
"""
import sys
import time
from dataclasses import dataclass

import numpy as np
from fidelity import reference_rms
from report import Report, fmt, medians, status

from orchestrator.scene.load import load_scene
from orchestrator.studies import metrics

REPORT = Report("costs", __doc__)
sys.path.insert(0, str(REPORT.root / "tests"))   # the finite-segment chain, as benchmarks/fidelity.py imports it

WAKE_SCENE = REPORT.root / "scenes" / "deploy_rigid.toml"
BEAM_SCENE = REPORT.root / "scenes" / "two_body_003.toml"
WAKE_SPEED = 15.0              # m/s, Otsuka et al. 2019, Sec. VII.A: the convergence tests' speed
WAKE_STOP, QUICK_WAKE_STOP = 0.3, 0.05      # s: the scene's stop; the wing latches at about 0.2 s at 15 m/s
CL_WINDOW = 0.2                # s, Otsuka et al. 2019, Eq. 28: CL error over 0-0.2 s
PANELS = ((1, 1), (2, 7))      # (M, N) per body: the 2019 convergence tests; its deployments
WAKE_LENGTHS = (5.0, float("inf"))   # chords: 2019's truncation L_w = 5; all wake
BEAM_STOP, QUICK_BEAM_STOP = 5.0, 0.5       # s, Otsuka et al. 2022, Eq. 24: 0-5 s
STRAIN_ELEMENTS, QUICK_STRAIN = (6, 12, 30), (6,)
ANCF_ELEMENTS, QUICK_ANCF = (6,), (6,)
SEGMENTS, QUICK_SEGMENTS = (6, 12, 30, 60, 120), (6, 30)     # per body, the generalized-alpha chain
REFERENCE_SEGMENTS = (6, 30)   # the DOP853 chain's own cost, for comparison
PAPER_WAKE = 95.0              # %, Otsuka et al. 2019, Sec. VII.A and Sec. VIII: flat-wake time 95% shorter
PAPER_BEAM = 97.0              # %, Otsuka et al. 2022, Sec. 4.4 and Sec. 6: 6 sections vs 30 finite segments


@dataclass(frozen=True)
class Wake:
    """A run of deploy_rigid at `speed` (m/s) until `stop` (s) with aero.model `model`, M x N panels per body and
    wake_length `L_w` (chords, inf: all wake); `repeat` numbers the interleaved repeats."""
    model: str
    M: int
    N: int
    L_w: float
    speed: float
    stop: float
    repeat: int

    def overrides(self):
        return [f"aero.model={self.model}", f"aero.chordwise_panels={self.M}", f"aero.spanwise_panels={self.N}",
                f"aero.wake_length={'inf' if self.L_w == float('inf') else repr(self.L_w)}",
                f"flow.speed={self.speed!r}", f"time.stop={self.stop!r}"]

    def config(self):
        return (self.model, self.M, self.N, self.L_w)


@dataclass(frozen=True)
class Beam:
    """A two_body_003 model: "strain-based" or "flexible" (run_scene), "segments-alpha" (FiniteSegmentAlpha, clamp
    EI/l) or "segments-reference" (tests/finite_segment_chain.py, DOP853, clamp 2 EI/l); `n` elements or segments
    per body; until `stop` (s); `repeat` numbers the interleaved repeats."""
    kind: str
    n: int
    stop: float
    repeat: int

    def config(self):
        return (self.kind, self.n)


class FiniteSegmentAlpha:
    """The planar finite-segment chain of Otsuka et al. 2022, Sec. 4.4 (rigid segments, rotational springs
    EI/l between neighbours and to the clamp), integrated by generalized-alpha at a fixed step h as 2022's
    (Arnold-Bruls form, rho_inf 0.8 as the shipped structure unit, Newton on the accelerations to a relative
    tolerance 1e-9 on the angles). The equations are tests/finite_segment_chain.py's (Lagrange, minimal
    coordinates, the assembled dense mass matrix), with clamp_factor = 1."""

    def __init__(self, n, h=0.01, rho_inf=0.8, clamp_factor=1.0, tol=1e-9):
        import finite_segment_chain as fsc

        self.fsc, self.c, self.h, self.tol = fsc, fsc.chain(n, clamp_factor=clamp_factor), h, tol
        r = rho_inf
        self.am, self.af = (2 * r - 1) / (r + 1), r / (r + 1)
        self.g = 0.5 - self.am + self.af
        self.b = 0.25 * (1 - self.am + self.af) ** 2

    def forces(self, q, v):
        """M(q) and the rest of the equations of motion f(q, v): M q'' + f = 0."""
        c, fsc = self.c, self.fsc
        d = q[:, None] - q[None, :]
        return (fsc.mass_matrix(c, q),
                c.mu * np.sin(d) @ v**2 + fsc.GRAVITY * c.w * np.cos(q) + c.K @ q)

    def simulate(self, stop):
        """The free end's Z (m) at every step, t = 0, h, ..., stop."""
        c, h = self.c, self.h
        am, af, g, b = self.am, self.af, self.g, self.b
        q, v = np.zeros(c.size), np.zeros(c.size)
        M, f = self.forces(q, v)
        ddq = np.linalg.solve(M, -f)
        accel = ddq.copy()
        cf = (1 - af) / (1 - am)
        steps = int(round(stop / h))
        z = [self.fsc.free_end(c, q)[1]]
        for _ in range(steps):
            a_known = (af * ddq - am * accel) / (1 - am)
            x = ddq.copy()                     # q''_{n+1}, predicted constant
            for _ in range(50):
                a_new = a_known + cf * x
                q1 = q + h * v + h * h * (0.5 - b) * accel + h * h * b * a_new
                v1 = v + h * (1 - g) * accel + h * g * a_new
                M, f = self.forces(q1, v1)
                residual = M @ x + f
                # the iteration matrix: M + h^2 beta cf (K + gravity's tangent) + h gamma cf (centrifugal tangent)
                d = q1[:, None] - q1[None, :]
                damping = 2 * c.mu * np.sin(d) * v1[None, :]
                stiffness = c.K - np.diag(self.fsc.GRAVITY * c.w * np.sin(q1))
                S = M + h * h * b * cf * stiffness + h * g * cf * damping
                dx = np.linalg.solve(S, -residual)
                x += dx
                if h * h * b * cf * np.max(np.abs(dx)) <= self.tol * max(1.0, np.max(np.abs(q1))):
                    break
            else:
                raise RuntimeError("the finite-segment chain's Newton iteration did not converge")
            a_new = a_known + cf * x
            q = q + h * v + h * h * (0.5 - b) * accel + h * h * b * a_new
            v = v + h * (1 - g) * accel + h * g * a_new
            ddq, accel = x, a_new
            z.append(self.fsc.free_end(c, q)[1])
        return np.array(z)


def warm_up():
    """Import the units in a worker before its first run, so that no run's CPU time includes them."""
    import finite_segment_chain  # noqa: F401
    import fmu_common.topology  # noqa: F401
    import orchestrator.run.units  # noqa: F401


def rms(z):
    """Otsuka et al. 2022, Eq. 24: sqrt(mean(Z^2)) (m)."""
    return float(np.sqrt(np.mean(np.asarray(z) ** 2)))


def work(task):
    """A task's CPU time (s) and its metrics."""
    if isinstance(task, Wake):
        return wake_work(task)
    return beam_work(task)


def wake_work(task):
    from orchestrator.output.results import summarize
    from orchestrator.run.master import run_scene

    cpu = time.process_time()
    result = run_scene(load_scene(WAKE_SCENE, task.overrides()), backend="direct")
    cpu = time.process_time() - cpu
    series = result.series
    return {"status": result.status, "message": result.message, "cpu_s": cpu,
            "simulated_s": result.simulated_time_s, "deploy_s": summarize(result)["deployment_time_s"],
            "cl": (series.time, series.CL) if len(series) else None}


def beam_work(task):
    import finite_segment_chain as fsc

    samples = np.linspace(0.0, task.stop, int(round(task.stop / 0.01)) + 1)
    cpu = time.process_time()
    if task.kind in ("strain-based", "flexible"):
        from orchestrator.run.master import run_scene

        result = run_scene(load_scene(BEAM_SCENE, [f"structure.fidelity={task.kind}",
                                                   f"structure.elements_per_body={task.n}",
                                                   f"time.stop={task.stop!r}"]), backend="direct")
        cpu = time.process_time() - cpu
        if result.status != "ok":
            return {"status": result.status, "message": result.message, "cpu_s": cpu,
                    "simulated_s": result.simulated_time_s}
        z = np.interp(samples, result.series.time, result.series.column("free_end_z"))
    elif task.kind == "segments-alpha":
        z = FiniteSegmentAlpha(task.n).simulate(task.stop)
        cpu = time.process_time() - cpu
    else:
        z = fsc.free_end_z(task.n, samples)
        cpu = time.process_time() - cpu
    return {"status": "ok", "message": "", "cpu_s": cpu, "rms": rms(z)}


def saving(cheap, costly):
    """100 (1 - cheap / costly) (%), or None."""
    return None if cheap is None or costly is None else 100 * (1 - cheap / costly)


def main(argv=None):
    args = REPORT.arguments(argv, **{"--repeats": {"type": int, "default": 3,
                                                   "help": "interleaved repeats of every configuration (default 3)"}})
    repeats = 1 if args.quick else args.repeats
    wake_stop = QUICK_WAKE_STOP if args.quick else WAKE_STOP
    beam_stop = QUICK_BEAM_STOP if args.quick else BEAM_STOP
    wake_configs = [(model, m, n, lw) for (m, n) in PANELS for lw in WAKE_LENGTHS
                    for model in ("uvlm-flat", "uvlm-free")]
    beam_configs = ([("strain-based", n) for n in (QUICK_STRAIN if args.quick else STRAIN_ELEMENTS)]
                    + [("flexible", n) for n in (QUICK_ANCF if args.quick else ANCF_ELEMENTS)]
                    + [("segments-alpha", n) for n in (QUICK_SEGMENTS if args.quick else SEGMENTS)]
                    + [("segments-reference", n) for n in ((6,) if args.quick else REFERENCE_SEGMENTS)])
    tasks = []
    for r in range(repeats):       # interleaved: every configuration once, then again
        tasks += [Wake(*c, WAKE_SPEED, wake_stop, r) for c in wake_configs]
        tasks += [Beam(*c, beam_stop, r) for c in beam_configs]
    res = REPORT.run(tasks, work, initializer=warm_up,
                     describe=lambda t, r: f"{r.get('status', 'error')}, {fmt(r.get('cpu_s'), '.2f')} s CPU")
    failed = [repr(t) for t in tasks if "error" in res[t] or res[t]["status"] != "ok"]
    wake = medians([t for t in tasks if isinstance(t, Wake)], res)
    beam = medians([t for t in tasks if isinstance(t, Beam)], res)

    wake_rows, wake_claims = [], []
    for m, n in PANELS:
        all_wake = wake[("uvlm-free", m, n, float("inf"))]
        for lw in WAKE_LENGTHS:
            for model in ("uvlm-flat", "uvlm-free"):
                cpu, cpus, row = wake[(model, m, n, lw)]
                err_cl = err_deploy = None
                if row.get("status") == "ok" and all_wake[2].get("status") == "ok":
                    (t, cl), (t_ref, cl_ref) = row["cl"], all_wake[2]["cl"]
                    err_cl = metrics.cl_error_pct(t, cl, t_ref, cl_ref, until=min(CL_WINDOW, wake_stop))
                    err_deploy = metrics.relative_error_pct(row["deploy_s"], all_wake[2]["deploy_s"])
                wake_rows.append([model, f"{m} x {n}", "all" if lw == float("inf") else f"{lw:g}",
                                  fmt(cpu, ".3f"), fmt(min(cpus) if cpus else None, ".3f"),
                                  fmt(max(cpus) if cpus else None, ".3f"),
                                  fmt(row.get("deploy_s"), ".4f"), fmt(err_deploy, ".3g"), fmt(err_cl, ".3g"),
                                  status(row)])
        flat = wake[("uvlm-flat", m, n, 5.0)][0]
        wake_claims.append({"panels": f"M = {m}, N = {n}", "truncated": saving(flat, wake[("uvlm-free", m, n, 5.0)][0]),
                            "whole": saving(flat, all_wake[0]),
                            "flat_inf_whole": saving(wake[("uvlm-flat", m, n, float("inf"))][0], all_wake[0])})

    reference = (None, None) if args.quick else reference_rms()   # the converged answer, as the fidelity study's
    ref_rms = reference[0]
    beam_rows = []
    names = {"strain-based": "strain-based (run_scene)", "flexible": "ANCF flexible (run_scene)",
             "segments-alpha": "finite segments, clamp EI/l, generalized-alpha h = 0.01 s",
             "segments-reference": "finite segments, clamp 2 EI/l, DOP853 rtol 1e-9 (tests/finite_segment_chain.py)"}
    for (kind, n), (cpu, cpus, row) in beam.items():
        err = metrics.relative_error_pct(row.get("rms"), ref_rms)
        beam_rows.append([names[kind], str(n), fmt(cpu, ".3f"), fmt(min(cpus) if cpus else None, ".3f"),
                          fmt(max(cpus) if cpus else None, ".3f"), fmt(row.get("rms"), ".6f"), fmt(err, ".3g"),
                          status(row)])

    def cpu_of(kind, n):
        return beam.get((kind, n), (None,))[0]

    def err_of(kind, n):
        row = beam.get((kind, n), (None, None, {}))[2]
        return metrics.relative_error_pct(row.get("rms"), ref_rms)

    # matched accuracy: the cheapest generalized-alpha chain at least as accurate as the strain-based 6 elements
    target = err_of("strain-based", 6)
    matched = None
    if target is not None:
        better = [n for (k, n) in beam if k == "segments-alpha" and (err_of(k, n) or 1e9) <= target]
        matched = min(better) if better else None
    beam_claims = {
        "paper": saving(cpu_of("strain-based", 6), cpu_of("segments-alpha", 30)),
        "same_sections": (cpu_of("strain-based", 30), cpu_of("segments-alpha", 30)),
        "matched": matched, "matched_saving": saving(cpu_of("strain-based", 6), cpu_of("segments-alpha", matched))
        if matched else None,
        "ancf_vs_sb": saving(cpu_of("flexible", 6), cpu_of("strain-based", 6)),
        "ancf_vs_fs30": saving(cpu_of("flexible", 6), cpu_of("segments-alpha", 30)),
        "sb6_vs_reference30": saving(cpu_of("strain-based", 6), cpu_of("segments-reference", 30)),
    }
    if not args.no_plots:
        plot(beam, err_of)
    total_cpu = sum(r.get("cpu_s") or 0 for r in res.values())
    REPORT.render(wake_rows=wake_rows, wake_claims=wake_claims, beam_rows=beam_rows, beam_claims=beam_claims,
                  err_of=err_of, cpu_of=cpu_of, reference=reference, matched=matched, repeats=repeats,
                  wake_stop=wake_stop, beam_stop=beam_stop, window=min(CL_WINDOW, wake_stop), speed=WAKE_SPEED,
                  quick=args.quick,
                  PAPER_WAKE=PAPER_WAKE, PAPER_BEAM=PAPER_BEAM, total_cpu=total_cpu,
                  scene=load_scene(WAKE_SCENE),
                  chord=load_scene(WAKE_SCENE)["structure"]["bodies"][0]["section"]["chord"])
    return REPORT.finish(failed, len(tasks))


def plot(beam, err_of):
    """img/costs.png: two_body_003's RMS error (%) against median CPU time (s), one line per model."""
    fig, axes = REPORT.figure(1, 1, 6, 4)
    ax = axes[0][0]
    for kind, marker in (("strain-based", "o"), ("flexible", "s"), ("segments-alpha", "^"),
                         ("segments-reference", "v")):
        points = [(beam[(k, n)][0], err_of(k, n), n) for (k, n) in beam if k == kind]
        points = [p for p in points if p[0] is not None and p[1] is not None]
        if points:
            cpu, err, n = zip(*points)
            ax.loglog(cpu, np.maximum(err, 1e-4), marker=marker, label=kind)
            for x, y, k in zip(cpu, err, n):
                ax.annotate(str(k), (x, max(y, 1e-4)), fontsize=7, xytext=(3, 3), textcoords="offset points")
    ax.set(xlabel="median CPU time (s)", ylabel="RMS error (%)", title="two_body_003: cost against accuracy")
    REPORT.save(fig, "costs", legend=8)


if __name__ == "__main__":
    sys.exit(main())
