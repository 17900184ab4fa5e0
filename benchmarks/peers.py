"""wingsim against the codes its users would pick instead: PteraSoftware (UVLM) and Exudyn (flexible multibody), the
same cases at the same accuracy, timed in interleaved pairs.

    pip install -e '.[peers]'
    python benchmarks/peers.py [--pairs 5] [--processes 3] [--quick] [--only NAME ...]

The cases are the `PeerCase`s of benchmarks/peer_pterasoftware.py and benchmarks/peer_exudyn.py
(benchmarks/peer_case.py: what is timed and compared). Each case runs one untimed warm-up of each side (imports,
numba's JIT of PteraSoftware, caches), then `--pairs` pairs, each pair wingsim then the peer, alternating which
goes first, in this one process with one BLAS thread: a busy period of a shared machine slows both sides of a
pair alike. Printed per case: the wingsim/peer ratio of the wall and of the CPU time, minimum and median over the
pairs (below 1: wingsim faster), and where a side reports per-step times, the same over its last 50 steps; the
errors of both sides against the case's refined reference. Then whole processes, as a user waits for them: each
side run once in a fresh Python process (`--process`), from its start (imports, numba's kernel load, FMU loading)
to its end, `--processes` interleaved pairs, wall and CPU time (the child's, from the kernel). wingsim's side is
what `wingsim run` runs (peer_exudyn.py: run_scene through the FMUs, built beforehand in a shared folder). Not
part of CI: the peers are optional extras.
"""
import argparse
import importlib
import importlib.util
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time

from report import process_setup, table

LAST_STEPS = 50


def peer_modules():
    """The peer modules, each with cases(quick) -> [PeerCase]; SystemExit naming the extra if a peer is missing."""
    missing = [name for name in ("pterasoftware", "exudyn") if importlib.util.find_spec(name) is None]
    if missing:
        raise SystemExit(f"{', '.join(missing)} not installed: the peers are optional extras, "
                         "pip install -e '.[peers]'")
    import peer_exudyn
    import peer_pterasoftware

    return (peer_pterasoftware, peer_exudyn)


def ratios(ours, theirs, key):
    """wingsim/peer ratios of the Measurements' `key` (wall_s, cpu_s or last_steps), one per pair."""
    value = {"wall_s": lambda m: m.wall_s, "cpu_s": lambda m: m.cpu_s,
             "last_steps": lambda m: sum(m.per_step[-LAST_STEPS:]) if len(m.per_step) >= LAST_STEPS else None}[key]
    pairs = [(value(a), value(b)) for a, b in zip(ours, theirs)]
    return [a / b for a, b in pairs if a is not None and b]


def run_case(case, pairs):
    """(wingsim Measurements, peer Measurements) of `pairs` interleaved pairs after one warm-up of each side."""
    case.ours()
    case.peer_run()
    ours, theirs = [], []
    for k in range(pairs):
        first, second = (case.ours, case.peer_run) if k % 2 == 0 else (case.peer_run, case.ours)
        a, b = first(), second()
        ours.append(a if first is case.ours else b)
        theirs.append(b if first is case.ours else a)
        print(f"  pair {k + 1}/{pairs}: wingsim {ours[-1].wall_s:.3g} s, {case.peer} {theirs[-1].wall_s:.3g} s",
              file=sys.stderr)
    return ours, theirs


def whole_process(module, index, side, quick):
    """(wall s, CPU s) of one fresh process running `side` ("ours" or "peer") of case `index` of `module` once."""
    argv = [sys.executable, __file__, "--process", side, module.__name__, str(index)] + (["--quick"] if quick else [])
    before, start = resource.getrusage(resource.RUSAGE_CHILDREN), time.perf_counter()
    subprocess.run(argv, check=True, stdout=subprocess.DEVNULL)
    wall, after = time.perf_counter() - start, resource.getrusage(resource.RUSAGE_CHILDREN)
    return wall, (after.ru_utime + after.ru_stime) - (before.ru_utime + before.ru_stime)


def whole_processes(module, index, quick, pairs):
    """wingsim/peer ratios of the wall and of the CPU time of `pairs` interleaved pairs of whole processes."""
    walls, cpus = [], []
    for k in range(pairs):
        sides = ("ours", "peer") if k % 2 == 0 else ("peer", "ours")
        times = dict(zip(sides, (whole_process(module, index, side, quick) for side in sides)))
        walls.append(times["ours"][0] / times["peer"][0])
        cpus.append(times["ours"][1] / times["peer"][1])
        print(f"  processes {k + 1}/{pairs}: wingsim {times['ours'][0]:.3g} s, peer {times['peer'][0]:.3g} s",
              file=sys.stderr)
    return walls, cpus


def summary(values):
    return f"{min(values):.2f} / {statistics.median(values):.2f}" if values else "-"


def target_met(cpu_ratios, target):
    """"<= 0.5: met" or "<= 0.5: missed" for the median CPU-time ratio against the product's target; "-" without one.

    Args:
        cpu_ratios: the CPU-time ratios wingsim / peer of the pairs.
        target: the target (PeerCase.target), or None.
    """
    if target is None or not cpu_ratios:
        return "-"
    return f"<= {target:g}: {'met' if statistics.median(cpu_ratios) <= target else 'missed'}"


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--pairs", type=int, default=5, help="interleaved pairs per case (default 5)")
    parser.add_argument("--quick", action="store_true", help="short variants of the cases (a smoke test)")
    parser.add_argument("--only", nargs="*", default=None, help="cases whose name contains one of these words")
    parser.add_argument("--processes", type=int, default=3, help="interleaved pairs of whole processes per case "
                                                                 "(default 3; 0: none)")
    parser.add_argument("--process", nargs=3, metavar=("SIDE", "MODULE", "INDEX"), help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    process_setup()
    if args.process:                     # one side of one case, once, in this fresh process (whole_process)
        side, module, index = args.process
        case = importlib.import_module(module).cases(quick=args.quick)[int(index)]
        (case.ours if side == "ours" else case.peer_run)()
        return
    modules = peer_modules()
    from peer_exudyn import FMU_FOLDER
    shared = None
    if not os.environ.get(FMU_FOLDER):                    # the FMUs the cases build, for the processes too
        shared = tempfile.TemporaryDirectory(prefix="wingsim_peers_")
        os.environ[FMU_FOLDER] = shared.name
    rows, accuracy = [], []
    for module in modules:
        for index, case in enumerate(module.cases(quick=args.quick)):
            if args.only and not any(word in case.name or word in case.peer for word in args.only):
                continue
            print(f"{case.name} against {case.peer} ...", file=sys.stderr)
            ours, theirs = run_case(case, args.pairs)
            walls, cpus = whole_processes(module, index, args.quick, args.processes) if args.processes else ([], [])
            cpu = ratios(ours, theirs, "cpu_s")
            rows.append([case.name, case.peer, summary(ratios(ours, theirs, "wall_s")), summary(cpu),
                         target_met(cpu, case.target), summary(ratios(ours, theirs, "last_steps")),
                         summary(walls), summary(cpus)])
            reference = case.reference()
            for side, runs in (("wingsim", ours), (case.peer, theirs)):
                for name, error in case.errors(runs[-1].values, reference).items():
                    accuracy.append([case.name, side, name, f"{error:.3g}"])
            print(f"  {case.what}", file=sys.stderr)
    print(table(["case", "peer", "wall wingsim/peer (min / median)", "CPU wingsim/peer (min / median)",
                 "target (CPU, median)", f"last {LAST_STEPS} steps, wall (min / median)",
                 "whole processes, wall (min / median)", "whole processes, CPU (min / median)"], rows))
    print()
    print(table(["case", "code", "error against the refined reference", "value"], accuracy))


if __name__ == "__main__":
    main()
