"""What the study scripts share: their command line, their record (orchestrator.studies.study), figures, tables and
the markdown report rendered from benchmarks/templates/<name>.md (Jinja2)."""
import argparse
import math
import os
import statistics
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from fmu_common.threads import limit_blas_threads  # noqa: E402 - after the path: a checkout runs without install
from orchestrator.run import allocator  # noqa: E402


def process_setup() -> None:
    """This process as wingsim's own runs set theirs up: one BLAS thread, the allocator thresholds
    (orchestrator.run.allocator)."""
    limit_blas_threads()
    allocator.tune()

STUDIES = ROOT / "docs" / "studies"              # the reports of full runs, their figures in img/
QUICK = ROOT / "results" / "studies" / "quick"   # the reports of --quick runs
RECORDS = ROOT / "results" / "studies"           # every task's numbers, one JSON line each
TEMPLATES = Path(__file__).resolve().parent / "templates"


class Report:
    """The study `name` of a script whose docstring is `doc`: its options, its record
    (RECORDS/<name>[_quick].jsonl), figures in `out`/img and the report `out`/<name>.md, where `out` is
    `full` (default STUDIES), or QUICK with --quick."""

    root = ROOT

    def __init__(self, name, doc, full=STUDIES):
        self.name, self.doc, self.full, self._study = name, doc, full, None

    def arguments(self, argv=None, **extra):
        """The options --quick, --jobs, --resume, --no-plots and `extra` ({flag: argparse keywords}), parsed
        from `argv`; one BLAS thread; the wall clock starts."""
        parser = argparse.ArgumentParser(description=self.doc.split("\n\n")[0], epilog=(
            f"Writes to {self.full.relative_to(ROOT)}/ (--quick: {QUICK.relative_to(ROOT)}/); every task's numbers "
            f"go to {RECORDS.relative_to(ROOT)}/{self.name}.jsonl (--quick: {self.name}_quick.jsonl)."))
        parser.add_argument("--quick", action="store_true", help="a few short runs (a smoke test)")
        parser.add_argument("--jobs", type=int, default=2, help="worker processes (default 2)")
        parser.add_argument("--resume", action="store_true",
                            help=f"keep the tasks recorded by the last run ({RECORDS.relative_to(ROOT)}/"
                                 f"{self.name}.jsonl), run the rest")
        parser.add_argument("--no-plots", action="store_true", help="no figures")
        for flag, options in extra.items():
            parser.add_argument(flag, **options)
        self.args = parser.parse_args(argv)
        self.argv = sys.argv[1:] if argv is None else list(argv)
        self.out = QUICK if self.args.quick else self.full
        self.start = time.perf_counter()
        process_setup()
        return self.args

    def run(self, tasks, work, **options):
        """{task: result}: orchestrator.studies.study.Study.run in --jobs workers, resumed with --resume."""
        from orchestrator.studies.study import Study

        if self._study is None:
            path = RECORDS / f"{self.name}{'_quick' if self.args.quick else ''}.jsonl"
            self._study = Study(path, resume=self.args.resume)
        return self._study.run(tasks, work, self.args.jobs, **options)

    def render(self, **fields):
        """Write `out`/<name>.md from templates/<name>.md with `fields`, the command that reproduces it (without
        --resume, which reads the same numbers back), wall (s, of the recorded runs), workers, cores, and fmt,
        span, table, pi and img(name) (whether `out`/img/<name>.png exists: the report links the figures there)."""
        from jinja2 import Environment, FileSystemLoader, StrictUndefined

        env = Environment(loader=FileSystemLoader(TEMPLATES), undefined=StrictUndefined, trim_blocks=True,
                          lstrip_blocks=True, keep_trailing_newline=True)
        env.globals.update(fmt=fmt, span=span, table=table, pi=math.pi,
                           img=lambda image: (self.out / "img" / f"{image}.png").exists())
        env.filters["fmt"] = fmt
        command = " ".join([f"python benchmarks/{self.name}.py", *(a for a in self.argv if a != "--resume")])
        path = self.out / f"{self.name}.md"
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(env.get_template(f"{self.name}.md").render(
            command=command, wall=self.wall_time(), workers=self.args.jobs, cores=os.cpu_count(),
            **fields))
        print(f"wrote {path.relative_to(ROOT)}")

    def wall_time(self):
        """Wall time (s) of the study's runs as recorded (so that --resume reports the runs, not the
        re-render), else since `arguments`."""
        recorded = self._study.wall_time if self._study is not None else None
        return recorded if recorded is not None else time.perf_counter() - self.start

    def figure(self, rows, cols, width, height):
        """A Figure (Agg) with rows x cols axes (a 2-D array), `width` x `height` inches."""
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.figure import Figure

        fig = Figure(figsize=(width, height))
        FigureCanvasAgg(fig)
        return fig, fig.subplots(rows, cols, squeeze=False)

    def save(self, fig, name, rect=(0, 0, 1, 1), dpi=100, legend=None):
        """Write `out`/img/<name>.png: every axes gridded, with a legend of font size `legend` where it has
        labelled artists, laid out inside `rect` (figure fractions)."""
        for ax in fig.axes:
            ax.grid(True, which="both", alpha=0.25)
            if legend and ax.get_legend_handles_labels()[0]:
                ax.legend(fontsize=legend)
        path = self.out / "img" / f"{name}.png"
        path.parent.mkdir(parents=True, exist_ok=True)
        fig.tight_layout(rect=rect)
        fig.savefig(path, dpi=dpi)
        print(f"wrote {path.relative_to(ROOT)} ({path.stat().st_size // 1024} KB)")

    @staticmethod
    def finish(failed, total):
        """Print the failed runs (their labels) or that all `total` were ok; the exit code."""
        print(f"{len(failed)} runs failed: {', '.join(failed)}" if failed else f"{total} runs ok")
        return 1 if failed else 0


def fmt(value, spec):
    """`value` formatted with `spec`, or "-" for None / NaN."""
    return "-" if value is None or (isinstance(value, float) and math.isnan(value)) else format(value, spec)


def span(values, spec):
    """"a to b" (min, max of `values` formatted with `spec`), or "a" when they agree to that format."""
    low, high = format(min(values), spec), format(max(values), spec)
    return low if low == high else f"{low} to {high}"


def ratio(value, ref):
    """value / ref, or None."""
    return None if value is None or not ref else value / ref


def medians(tasks, res):
    """{config: (median CPU s, [CPU s], first repeat's row)} of the tasks that ran ok in every repeat: the tasks
    (with `config()` and `repeat`) of interleaved repeats and their results `res` ({task: row with "cpu_s"})."""
    out = {}
    for config in dict.fromkeys(t.config() for t in tasks):
        rows = [(t, res[t]) for t in tasks if t.config() == config]
        rows.sort(key=lambda tr: tr[0].repeat)
        ok = all("error" not in r and r["status"] == "ok" for _, r in rows)
        cpus = [r["cpu_s"] for _, r in rows] if ok else []
        out[config] = (statistics.median(cpus) if ok else None, cpus, rows[0][1])
    return out


def table(header, rows):
    """Markdown table text."""
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    return "\n".join(lines + ["| " + " | ".join(str(c) for c in row) + " |" for row in rows])


def status(row):
    """"ok", or the status, the time reached and the message of a failed run (a row of a run or an error)."""
    if "error" in row:
        return f"error: {row['error']}".replace("|", "/").replace("\n", " ")
    if row["status"] == "ok":
        return "ok"
    reached = f" at t = {row['simulated_s']:.4g} s" if row.get("simulated_s") is not None else ""
    return f"{row['status']}{reached}: {row['message']}".replace("|", "/").replace("\n", " ")
