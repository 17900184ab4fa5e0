"""wingsim against the codes its users would pick instead: PteraSoftware (UVLM) and Exudyn (flexible multibody), the
same cases at the same accuracy, timed in interleaved pairs.

    pip install -e '.[peers]'
    python benchmarks/peers.py [--pairs 5] [--quick] [--only NAME ...]

The cases are the `PeerCase`s of benchmarks/peer_pterasoftware.py and benchmarks/peer_exudyn.py
(benchmarks/peer_case.py: what is timed and compared). Each case runs one untimed warm-up of each side (imports,
numba's JIT of PteraSoftware, caches), then `--pairs` pairs, each pair wingsim then the peer, alternating which
goes first, in this one process with one BLAS thread: a busy period of a shared machine slows both sides of a
pair alike. Printed per case: the wingsim/peer ratio of the wall and of the CPU time, minimum and median over the
pairs (below 1: wingsim faster), and where a side reports per-step times, the same over its last 50 steps; the
errors of both sides against the case's refined reference. Not part of CI: the peers are optional extras.
"""
import argparse
import importlib.util
import statistics
import sys

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


def summary(values):
    return f"{min(values):.2f} / {statistics.median(values):.2f}" if values else "-"


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--pairs", type=int, default=5, help="interleaved pairs per case (default 5)")
    parser.add_argument("--quick", action="store_true", help="short variants of the cases (a smoke test)")
    parser.add_argument("--only", nargs="*", default=None, help="cases whose name contains one of these words")
    args = parser.parse_args(argv)
    process_setup()
    rows, accuracy = [], []
    for module in peer_modules():
        for case in module.cases(quick=args.quick):
            if args.only and not any(word in case.name for word in args.only):
                continue
            print(f"{case.name} against {case.peer} ...", file=sys.stderr)
            ours, theirs = run_case(case, args.pairs)
            rows.append([case.name, case.peer, summary(ratios(ours, theirs, "wall_s")),
                         summary(ratios(ours, theirs, "cpu_s")), summary(ratios(ours, theirs, "last_steps"))])
            reference = case.reference()
            for side, runs in (("wingsim", ours), (case.peer, theirs)):
                for name, error in case.errors(runs[-1].values, reference).items():
                    accuracy.append([case.name, side, name, f"{error:.3g}"])
            print(f"  {case.what}", file=sys.stderr)
    print(table(["case", "peer", "wall wingsim/peer (min / median)", "CPU wingsim/peer (min / median)",
                 f"last {LAST_STEPS} steps, wall (min / median)"], rows))
    print()
    print(table(["case", "code", "error against the refined reference", "value"], accuracy))


if __name__ == "__main__":
    main()
