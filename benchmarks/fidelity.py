"""Structural fidelities traded: the strain-based beam (Otsuka et al. 2022) against the ANCF beam (flexible and
rigid, Otsuka et al. 2019), error against the converged answer and CPU time, on two scenes.

    python benchmarks/fidelity.py [--quick] [--jobs 2] [--resume] [--no-plots]

two_body_003 (Otsuka et al. 2022, Sec. 4.4): the RMS of the free end's Z over 0-5 s (Eq. 24) for 2 to 48 elements
per body; its converged answer is the independent finite-segment chain of tests/finite_segment_chain.py,
refined and extrapolated (Richardson). deploy_flexible at 10 m/s (the shipped uvlm-flat coupling): the
deployment time, the peak strain at 0.02 m and the tip deflection at 0.2 s for 3 to 15 elements per body;
its converged answer is the ANCF run with 15 elements per body at h = 1e-4 s. --quick: 0.5 s and 0.05 s, few
levels. Each run is timed by the CPU time of its worker process.

The trade at equal accuracy: for each scene, the cheapest run of each fidelity that meets ACCURACY (CPU time),
and with --instructions the instructions each of those runs executes (valgrind's callgrind, counted on the whole
process less the same run stopped after its first coupling step: a number that does not depend on the machine's
load), about two minutes of valgrind per pair.
"""
import argparse
import json
import re
import shutil
import subprocess
import sys
import time
from dataclasses import asdict, dataclass

import numpy as np
from report import ROOT, Report, fmt, status

from orchestrator.studies import metrics
from orchestrator.run.master import run_scene
from orchestrator.output.results import summarize
from orchestrator.scene.load import load_scene

REPORT = Report("fidelity", __doc__)
FIDELITIES = ("strain-based", "flexible", "rigid")
TWO_BODY_ELEMENTS = (2, 3, 6, 12, 24, 48)
DEPLOY_ELEMENTS = (3, 7, 15)
DEPLOY_STEPS = (5e-4, 1e-3)                    # s, longer structure steps for 3 and 7 elements per body
ACCURACY = {"two_body_003": {"rms_z": 0.5}, "deploy_flexible": {"deploy_s": 0.5, "tip": 1.0}}
"""The accuracy the fidelities are compared at: the largest error (%) of each metric against the converged answer."""
METRIC_NAMES = {"rms_z": "RMS Z", "deploy_s": "deployment time", "tip": "tip deflection at 0.2 s"}
FIRST_STEP = {"two_body_003": 0.01, "deploy_flexible": 1e-3}   # s, the scenes' coupling steps
DEPLOY_REFERENCE = ("flexible", 15, 1e-4)      # fidelity, elements per body, structure step (s)
SPAN = 0.3                                     # m, deploy_flexible deployed


@dataclass(frozen=True)
class Run:
    """One run: scene ('two_body_003' or 'deploy_flexible'), fidelity, elements per body, structure step (s;
    None: the scene's), stop time (s)."""
    scene: str
    fidelity: str
    elements: int
    step: float | None
    stop: float

    def overrides(self):
        out = [f"structure.fidelity={self.fidelity}", f"structure.elements_per_body={self.elements}",
               f"time.stop={self.stop!r}"]
        if self.fidelity == "rigid" and self.scene == "deploy_flexible":   # the rigid wing's own integrator
            rigid = load_scene(ROOT / "scenes" / "deploy_rigid.toml")["structure"]
            out += [f"structure.integrator={rigid['integrator']}", f"structure.step={rigid['step']!r}"]
        elif self.step is not None:
            out.append(f"structure.step={self.step!r}")
        if self.scene == "deploy_flexible":
            out.append("flow.speed=10")
        return out


def work(run):
    """The run's metrics and its CPU time (s)."""
    cpu = time.process_time()
    result = run_scene(load_scene(ROOT / "scenes" / f"{run.scene}.toml", run.overrides()), backend="direct")
    cpu = time.process_time() - cpu
    out = {"status": result.status, "message": result.message, "cpu_s": cpu,
           "simulated_s": float(result.series.time[-1]) if len(result.series.time) else None}
    if result.status != "ok":
        return out
    series = result.series
    if run.scene == "two_body_003":
        z = series.column("free_end_z")
        out["rms_z"] = float(np.sqrt(np.mean(z ** 2)))            # Otsuka et al. 2022, Eq. (24)
    else:
        summary = summarize(result)
        out["deploy_s"] = summary["deployment_time_s"]
        out["strain"] = summary["strain_gauges"]["strain_20mm"]["peak"]
        if run.stop >= 0.2:
            out["tip"] = metrics.tip_deflection(series.time, series.column("tip_x"), series.column("tip_y"), 0.2)
    return out


@dataclass(frozen=True)
class Count:
    """The instructions of a Run (`instructions`)."""
    run: Run


def instructions(count):
    """{"instructions": the instructions of count.run less those of the same run stopped after its first coupling
    step (imports, scene, units, compilations), both counted whole by valgrind's callgrind}."""
    run = count.run
    first = Run(run.scene, run.fidelity, run.elements, run.step, FIRST_STEP[run.scene])
    return {"instructions": _callgrind(run) - _callgrind(first)}


def _callgrind(run):
    """Instructions valgrind's callgrind counts in a process that does `work(run)` (the --one option)."""
    command = ["valgrind", "--tool=callgrind", "--callgrind-out-file=/dev/null", sys.executable, __file__,
               "--one", json.dumps(asdict(run))]
    out = subprocess.run(command, capture_output=True, text=True, cwd=ROOT)
    found = re.search(r"Collected : (\d+)", out.stderr)
    if out.returncode or not found:
        raise RuntimeError(f"callgrind of {run}: exit {out.returncode}: {out.stderr[-500:]}")
    return int(found.group(1))


def cheapest(runs, res, scene, fidelity, reference):
    """The Run of `fidelity` on `scene` with the least CPU time among those within ACCURACY of `reference`
    ({metric: converged value}), or None."""
    def within(r):
        return all(error(r.get(k), reference.get(k)) is not None and error(r.get(k), reference[k]) <= bound
                   for k, bound in ACCURACY[scene].items())
    fits = [run for run in runs if run.scene == scene and run.fidelity == fidelity and res[run].get("status") == "ok"
            and within(res[run])]
    return min(fits, key=lambda run: res[run]["cpu_s"], default=None)


def reference_rms():
    """(RMS of the free end's Z, its error estimate) (m) of the finite-segment chain, extrapolated."""
    sys.path.insert(0, str(ROOT / "tests"))
    from finite_segment_chain import extrapolated_rms

    reference = extrapolated_rms()
    return reference.value, reference.error


def error(value, reference):
    """|value - reference| / |reference| in %, or None."""
    return None if value is None or reference is None else 100 * abs(value - reference) / abs(reference)


def main():
    args = REPORT.arguments(**{
        "--instructions": {"action": "store_true",
                           "help": "count the instructions of the cheapest runs at equal accuracy (valgrind)"},
        "--one": {"help": argparse.SUPPRESS, "default": None}})
    if args.one:                      # a worker of _callgrind: one run, nothing written
        work(Run(**json.loads(args.one)))
        return 0
    two_body_stop, deploy_stop = (0.5, 0.05) if args.quick else (5.0, 0.25)
    two_body = TWO_BODY_ELEMENTS[:3] if args.quick else TWO_BODY_ELEMENTS
    deploy = DEPLOY_ELEMENTS[:2] if args.quick else DEPLOY_ELEMENTS
    runs = [Run("two_body_003", f, n, None, two_body_stop) for f in FIDELITIES[:2] for n in two_body]
    runs.append(Run("two_body_003", "rigid", 1, None, two_body_stop))
    runs += [Run("deploy_flexible", f, n, None, deploy_stop) for f in FIDELITIES[:2] for n in deploy]
    runs += [Run("deploy_flexible", f, n, h, deploy_stop) for f in FIDELITIES[:2] for n in deploy[:2]
             for h in (() if args.quick else DEPLOY_STEPS)]
    runs.append(Run("deploy_flexible", "rigid", 1, None, deploy_stop))
    reference_run = Run("deploy_flexible", DEPLOY_REFERENCE[0], DEPLOY_REFERENCE[1], DEPLOY_REFERENCE[2], deploy_stop)
    runs.append(reference_run)
    res = REPORT.run(runs, work)
    failed = [repr(r) for r in runs if "error" in res[r] or res[r]["status"] != "ok"]
    rms_reference, rms_uncertainty = (None, None) if args.quick else reference_rms()
    ref = res[reference_run]

    def row(run, metrics_of, first):
        """Table cells: fidelity, elements, step (s), CPU s, the first metric with format `first`, the errors (%),
        status."""
        r = res[run]
        value, *errors = metrics_of(r)
        step = "scene's" if run.step is None else fmt(run.step, "g")
        return ([run.fidelity, str(run.elements), step, fmt(r.get("cpu_s"), ".2f"), fmt(value, first)]
                + [fmt(e, ".3g") for e in errors] + [status(r)])

    two_body_rows = [row(r, lambda x: (x.get("rms_z"), error(x.get("rms_z"), rms_reference)), ".6f")
                     for r in runs if r.scene == "two_body_003"]
    deploy_rows = [row(r, lambda x: (x.get("deploy_s"), error(x.get("deploy_s"), ref.get("deploy_s")),
                                     error(x.get("strain"), ref.get("strain")), error(x.get("tip"), ref.get("tip"))),
                       ".5f") for r in runs if r.scene == "deploy_flexible" and r != reference_run]
    references = {"two_body_003": {"rms_z": rms_reference},
                  "deploy_flexible": {k: ref.get(k) for k in ACCURACY["deploy_flexible"]}}
    pairs = {scene: [cheapest([r for r in runs if r != reference_run], res, scene, f, references[scene])
                     for f in FIDELITIES[:2]] for scene in ACCURACY}
    counted = {}
    if args.instructions and shutil.which("valgrind") is None:
        sys.exit("--instructions needs valgrind (callgrind) on PATH")
    if args.instructions:
        counts = [Count(run) for pair in pairs.values() for run in pair if run is not None]
        counted = {c.run: n.get("instructions") for c, n in REPORT.run(counts, instructions).items()}
    trade_rows = []
    for scene, (strain_based, flexible) in pairs.items():
        cells = [scene, ", ".join(f"{METRIC_NAMES[k]} {b:g}%" for k, b in ACCURACY[scene].items())]
        for run in (strain_based, flexible):
            step = "the scene's step" if run is None or run.step is None else f"h = {run.step:g} s"
            cells.append("none" if run is None else
                         f"{run.elements} elements, {step}: {res[run]['cpu_s']:.2f} s"
                         + (f", {counted[run] / 1e9:.2f} G instructions" if run in counted else ""))
        both = strain_based is not None and flexible is not None
        cells.append(fmt(res[strain_based]["cpu_s"] / res[flexible]["cpu_s"], ".2f") if both else "-")
        cells.append(fmt(counted[strain_based] / counted[flexible], ".2f")
                     if both and strain_based in counted and flexible in counted else "-")
        trade_rows.append(cells)
        print(f"{scene} at equal accuracy: " + " | ".join(cells[2:]))
    if not args.no_plots:
        plot(runs, res, rms_reference, ref)
    REPORT.render(two_body_rows=two_body_rows, deploy_rows=deploy_rows, rms_reference=rms_reference,
                  rms_uncertainty=rms_uncertainty, reference=ref, reference_run=reference_run, quick=args.quick,
                  two_body_stop=two_body_stop, deploy_stop=deploy_stop, trade_rows=trade_rows)
    return REPORT.finish(failed, len(runs))


def plot(runs, res, rms_reference, ref):
    """img/fidelity.png: error (%) against CPU time (s), one line per fidelity, one panel per scene."""
    fig, axes = REPORT.figure(1, 2, 10, 4)
    panels = (("two_body_003", "rms_z", rms_reference, "two_body_003: RMS of the free end's Z"),
              ("deploy_flexible", "deploy_s", ref.get("deploy_s"), "deploy_flexible 10 m/s: deployment time"))
    for ax, (scene, key, reference, title) in zip(axes[0], panels):
        for fidelity, marker in zip(FIDELITIES, ("o", "s", "^")):
            points = [(res[r]["cpu_s"], error(res[r].get(key), reference), r.elements) for r in runs
                      if r.scene == scene and r.fidelity == fidelity and res[r].get(key) is not None
                      and r.step is None]
            points = [p for p in points if p[1] is not None]
            if points:
                cpu, err, n = zip(*points)
                ax.loglog(cpu, np.maximum(err, 1e-4), marker=marker, label=fidelity)
                for x, y, k in zip(cpu, err, n):
                    ax.annotate(str(k), (x, max(y, 1e-4)), fontsize=7, xytext=(3, 3), textcoords="offset points")
        ax.set(xlabel="CPU time (s)", ylabel="error (%)", title=title)
    REPORT.save(fig, "fidelity", legend=8)


if __name__ == "__main__":
    sys.exit(main())
