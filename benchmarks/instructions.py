"""Instructions of the communication steps of a run through `wingsim run`'s path, counted by valgrind's callgrind.

    python benchmarks/instructions.py [--scenes deploy_rigid deploy_flexible spin_up] [--stop SCENE=SECONDS ...]
                                      [--set KEY=VALUE ...] [--backend fmu|direct] [--split]

Why instructions: wall time on a shared machine moves with whatever else runs there; an instruction count of the
same run is repeatable whatever the load (perf's counters are not available everywhere, valgrind is). Needs
valgrind (and setarch, util-linux): without them the script says so and exits with status 2.

How, per scene (as shipped, with the --set overrides, stopped at its stop time: STOP, or --stop):
1. outside valgrind: build the scene's FMUs with the project's build (`orchestrator.build.fmus.build_fmus`, as
   `wingsim run` builds them), then one short warm-up run, which compiles the C kernels into their per-user cache
   (`fmu_common.compiled`), so that neither the build nor a compilation is counted;
2. in a fresh process under `valgrind --tool=callgrind`, the run as `wingsim run SCENE` runs it: one BLAS thread
   and the allocator's thresholds (`report.process_setup`), `orchestrator.run.master.run_scene` with the FMU
   backend on the built FMUs (the units loaded through fmpy as a user's run loads them), or in-process with
   `--backend direct`; with BLAS pools of one thread from the start, a fixed hash seed (REPEATABLE) and the
   addresses not randomized (`setarch -R`), so that a count repeats to a few thousand instructions;
3. the same in another fresh process with time.stop = coupling.step: the run stopped after its first
   communication step.
Each total is the Ir of the callgrind output file's `summary:` (or `totals:`) line. Their difference is the
instructions of the communication steps after the first: starting Python, importing, loading and initialising
the units, the first step (its one-off first calls into LAPACK and the FMU libraries) and terminating are in
both runs alike and cancel; what is left is the per-step cost a longer run repeats. (The only other difference
is the size of the result series the master allocates, a few allocations.)

--split also reads from the same two output files the inclusive counts of the units' FMI calls (the FMU backend
only: callgrind sees C functions, not Python methods such as `StructureSolver.advance`) and splits the steps
after the first into each unit's fmi2DoStep, both units' fmi2GetReal and fmi2SetReal (the exchange, in which
the units also compute the outputs read) and the rest (the master: coupling, checks, recording, ctypes).
"""
import argparse
import os
import pickle
import re
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

from report import ROOT, table

STOP = {"deploy_rigid": 0.3, "deploy_flexible": 0.03, "spin_up": 1.0}   # s, per scene (--stop overrides)
# The counted processes' environment: without these, two counts of one run differ by millions of instructions
# (a BLAS thread pool started at import, before the one-thread limit, whose threads callgrind counts too; the
# hash seed); with them by about 1e5, and by a few thousand with the addresses not randomized (setarch -R).
# The runs' own BLAS calls are on one thread either way.
REPEATABLE = {"OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "PYTHONHASHSEED": "0"}
SPLIT_UNITS = {"structure fmi2DoStep": "structure", "aero fmi2DoStep": "aero"}   # --split's columns: their unit
SPLIT_EXCHANGE = "fmi2GetReal, fmi2SetReal (both units)"

# The child under valgrind: the run as `wingsim run` runs it, nothing else (argv: scene pickle, backend, FMU folder).
CHILD = """
import pickle, sys
sys.path.insert(0, {benchmarks!r})
from report import process_setup
from orchestrator.run.master import run_scene
process_setup()
with open(sys.argv[1], "rb") as file:
    scene = pickle.load(file)
result = run_scene(scene, backend=sys.argv[2], fmu_dir=sys.argv[3] if sys.argv[3] != "-" else None)
if result.status != "ok":
    sys.exit(f"{{scene['name']}}: {{result.status}}: {{result.message}}")
"""


class CountError(RuntimeError):
    """A count that could not be made: valgrind missing, a run that failed, an output file without totals."""


def total_instructions(text: str) -> int:
    """Ir, the instructions executed, of a callgrind output file's text: the first event of its `events:` line
    counted on its `summary:` line (newer callgrind) or `totals:` line. CountError when there is neither or Ir is
    not among the events."""
    events = re.search(r"^events:\s*(.+)$", text, re.MULTILINE)
    names = events.group(1).split() if events else ["Ir"]
    if "Ir" not in names:
        raise CountError(f"callgrind counted {names}, not Ir (instructions)")
    for key in ("summary", "totals"):
        found = re.findall(rf"^{key}:\s*(.+)$", text, re.MULTILINE)
        if found:
            return int(found[-1].split()[names.index("Ir")])
    raise CountError("the callgrind output has no summary: or totals: line")


def _named(value: str, names: dict[str, str]) -> str:
    """The name of a compressed callgrind name `(id) name` (defining id) or `(id)` (referring to it)."""
    match = re.match(r"\((\d+)\)\s*(.*)$", value)
    if match is None:
        return value
    if match.group(2):
        names[match.group(1)] = match.group(2)
    return names[match.group(1)]


def inclusive_counts(text: str, functions: set[str]) -> dict[tuple[str, str], int]:
    """{(function, object file): inclusive Ir} of the functions named in `functions`, from a callgrind output
    file's text: the sum of the costs of every call to them (callgrind's `calls=` lines, each followed by the
    call's inclusive cost). Kept apart per object file, since both FMUs export the same fmi2 functions
    (callgrind_annotate would merge them into one line)."""
    declared = re.search(r"^positions:\s*(.+)$", text, re.MULTILINE)
    positions = len(declared.group(1).split()) if declared else 1      # callgrind's default: line
    events = re.search(r"^events:\s*(.+)$", text, re.MULTILINE)
    column = positions + (events.group(1).split().index("Ir") if events else 0)
    objects, function_names = {}, {}
    object_of = {}                     # function id -> its object file, from the fn= blocks (under their ob=)
    ob, callee, call_cost_next = None, None, False
    by_callee: dict[str, int] = {}     # function id -> inclusive Ir of the calls to it
    for line in text.splitlines():
        if call_cost_next:
            call_cost_next = False
            fields = line.split()
            if function_names.get(callee) in functions and len(fields) > column:
                by_callee[callee] = by_callee.get(callee, 0) + int(fields[column])
            continue
        key, _, value = line.partition("=")
        if key == "ob":
            ob = _named(value, objects)
        elif key == "cob":
            _named(value, objects)
        elif key in ("fn", "cfn"):
            match = re.match(r"\((\d+)\)", value)
            ident = match.group(1) if match else value     # uncompressed names are their own id
            function_names[ident] = _named(value, function_names) if match else value
            if key == "fn":
                object_of[ident] = ob
            else:
                callee = ident
        elif key == "calls":
            call_cost_next = True
    unresolved = [function_names[ident] for ident in by_callee if ident not in object_of]
    if unresolved:
        raise CountError(f"callgrind output: calls to {unresolved} of a function never listed with its object")
    counts: dict[tuple[str, str], int] = {}
    for ident, count in by_callee.items():
        key = (function_names[ident], object_of[ident])
        counts[key] = counts.get(key, 0) + count
    return counts


def split_by_unit(counts: dict[tuple[str, str], int], function: str, unit_names: list[str]) -> dict[str, int]:
    """{unit: inclusive Ir of `function`} from `inclusive_counts`' {(function, object file): Ir}: the object files
    of the FMU binaries are named after the unit's model identifier (pythonfmu: `<identifier>_pythonfmu.so`);
    CountError for an object of no unit or of two."""
    out = {unit: 0 for unit in unit_names}
    for (name, obj), count in counts.items():
        if name != function:
            continue
        units = [unit for unit in unit_names if Path(obj).name.startswith(f"{unit}_")]
        if len(units) != 1:
            raise CountError(f"{function} in {obj}: of {len(units)} of the units {unit_names}")
        out[units[0]] += count
    return out


def counted(scene_file: Path, backend: str, fmu_dir: Path | None, out_file: Path) -> int:
    """Ir of one run of the pickled scene in a fresh process under callgrind, which writes `out_file`."""
    code = CHILD.format(benchmarks=str(Path(__file__).resolve().parent))
    command = ["setarch", "-R", "valgrind", "--tool=callgrind", f"--callgrind-out-file={out_file}",
               sys.executable, "-c", code, str(scene_file), backend, str(fmu_dir) if fmu_dir else "-"]
    done = subprocess.run(command, cwd=ROOT, capture_output=True, text=True, env={**os.environ, **REPEATABLE})
    if done.returncode != 0:
        raise CountError(f"{' '.join(command[:5])} ... exited with {done.returncode}:\n{done.stderr[-3000:]}")
    return total_instructions(out_file.read_text())


def count_scene(scene: dict, backend: str, split: bool, work: Path) -> dict:
    """The counts of one scene (module docstring): {"steps": communication steps after the first, "whole": Ir
    of the whole run, "first": Ir of the run stopped after the first step, "split": {part: Ir of the steps after
    the first} with `split`}."""
    from orchestrator.build.fmus import build_fmus
    from orchestrator.run.master import run_scene

    step, stop = scene["coupling"]["step"], scene["time"]["stop"]
    first = {**scene, "time": {**scene["time"], "stop": step}}
    fmu_dir = None
    if backend == "fmu":
        fmu_dir = work / scene["name"]
        build_fmus(scene, fmu_dir)
    warm = run_scene({**scene, "time": {**scene["time"], "stop": 2 * step}}, backend=backend, fmu_dir=fmu_dir)
    if warm.status != "ok":
        raise CountError(f"{scene['name']} (warm-up): {warm.status}: {warm.message}")
    totals, files = {}, {}
    for label, run in (("whole", scene), ("first", first)):
        scene_file, files[label] = work / f"{scene['name']}-{label}.pickle", work / f"{scene['name']}-{label}.out"
        scene_file.write_bytes(pickle.dumps(run))
        totals[label] = counted(scene_file, backend, fmu_dir, files[label])
    out = {"steps": round(stop / step) - 1, **totals}
    if split:
        units = [fmu.stem for fmu in sorted(fmu_dir.glob("*.fmu"))]
        parts = {}
        for label, file in files.items():
            counts = inclusive_counts(file.read_text(), {"fmi2DoStep", "fmi2GetReal", "fmi2SetReal"})
            steps = split_by_unit(counts, "fmi2DoStep", units)
            parts[label] = {**{part: steps.get(unit) for part, unit in SPLIT_UNITS.items()},
                            SPLIT_EXCHANGE: sum(count for (name, _), count in counts.items() if name != "fmi2DoStep")}
        out["split"] = {part: None if parts["whole"][part] is None else parts["whole"][part] - parts["first"][part]
                        for part in parts["whole"]}
    return out


def missing_tools() -> list[str]:
    """The programs the counts need that are not on PATH."""
    return [tool for tool in ("valgrind", "setarch") if shutil.which(tool) is None]


def parse_stops(items, parser) -> dict[str, float]:
    """{scene: stop s} of the --stop items SCENE=SECONDS; a parser error naming a bad item."""
    stops = {}
    for item in items:
        name, _, value = item.partition("=")
        try:
            stops[name] = float(value)
        except ValueError:
            parser.error(f"--stop {item}: expected SCENE=SECONDS, e.g. deploy_rigid=0.3")
    return stops


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", nargs="+", default=list(STOP), help="scene file stems (default: the three)")
    parser.add_argument("--stop", nargs="+", default=[], metavar="SCENE=SECONDS",
                        help="stop times, s (default " + ", ".join(f"{k} {v:g}" for k, v in STOP.items()) + ")")
    parser.add_argument("--set", nargs="+", default=[], metavar="KEY=VALUE", dest="overrides",
                        help="scene keys to override, as wingsim run --set (e.g. record.probes=position)")
    parser.add_argument("--backend", choices=["fmu", "direct"], default="fmu",
                        help="fmu: through the built FMUs, as wingsim run (default); direct: the units in-process")
    parser.add_argument("--split", action="store_true",
                        help="also the instructions in each unit's fmi2DoStep and the rest (FMU backend only)")
    args = parser.parse_args(argv)
    if args.split and args.backend != "fmu":
        parser.error("--split reads the units' fmi2DoStep: it needs --backend fmu")
    missing = missing_tools()
    if missing:
        print(f"error: {' and '.join(missing)} not found: this script counts instructions with valgrind's callgrind "
              "(e.g. apt-get install valgrind util-linux)", file=sys.stderr)
        return 2
    stops = {**STOP, **parse_stops(args.stop, parser)}
    unknown = [name for name in args.scenes if name not in stops]
    if unknown:
        parser.error(f"no stop time for {', '.join(unknown)}: give --stop {unknown[0]}=SECONDS")

    from orchestrator.scene.load import load_scene
    from report import process_setup

    process_setup()                      # the warm-up runs as the counted ones
    rows, split_rows = [], []
    with tempfile.TemporaryDirectory() as tmp:
        for name in args.scenes:
            scene = load_scene(ROOT / "scenes" / f"{name}.toml", [f"time.stop={stops[name]}"] + args.overrides)
            step = scene["coupling"]["step"]
            if scene["time"]["stop"] < 2 * step:
                parser.error(f"{name}: time.stop = {scene['time']['stop']:g} s is less than two communication "
                             f"steps ({step:g} s)")
            print(f"{name}: counting {scene['time']['stop']:g} s ({args.backend}) ...", file=sys.stderr, flush=True)
            try:
                c = count_scene(scene, args.backend, args.split, Path(tmp))
            except CountError as err:
                print(f"error: {name}: {err}", file=sys.stderr)
                return 1
            steps = c["whole"] - c["first"]
            rows.append([name, f"{step:g} .. {scene['time']['stop']:g} s ({c['steps']} steps)", f"{steps:,}",
                         f"{steps / c['steps']:,.0f}", f"{c['whole']:,}", f"{c['first']:,}"])
            if args.split:
                rest = steps - sum(count or 0 for count in c["split"].values())
                split_rows.append([name] + ["-" if count is None else f"{count:,} ({count / c['steps']:,.0f})"
                                            for count in [*c["split"].values(), rest]])
    sets = f", --set {' '.join(args.overrides)}" if args.overrides else ""
    print(f"\nInstructions (callgrind Ir), backend {args.backend}{sets}: the whole run less the run stopped after "
          f"its first communication step\n")
    print(table(["scene", "window", "instructions (steps after the first)", "per communication step",
                 "whole run", "run stopped after the first step"], rows))
    if split_rows:
        print("\nOf the steps after the first, inclusive of the FMI calls, and the rest; per step in brackets\n")
        print(table(["scene", *SPLIT_UNITS, SPLIT_EXCHANGE, "rest"], split_rows))
    return 0


if __name__ == "__main__":
    sys.exit(main())
