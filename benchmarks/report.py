"""What the study scripts share: where they write, the command line they have in common, markdown from
templates (benchmarks/templates/*.md, Jinja2), tables and figures."""
import argparse
import math
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from fmu_common.threads import limit_blas_threads

STUDIES = ROOT / "docs" / "studies"          # the reports of full runs, their figures in img/
QUICK = ROOT / "results" / "studies" / "quick"   # the reports of --quick runs
RECORDS = ROOT / "results" / "studies"       # every task's numbers, one JSON line each (orchestrator.study)
TEMPLATES = Path(__file__).resolve().parent / "templates"


def arguments(doc, parts=None, argv=None, **extra):
    """The common options (--quick, --jobs, --resume, --no-plots, --parts when `parts`) and `extra`
    {flag: argparse keywords}, parsed from `argv`."""
    parser = argparse.ArgumentParser(description=doc.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="a few short runs (a smoke test)")
    parser.add_argument("--jobs", type=int, default=2, help="worker processes (default 2)")
    parser.add_argument("--resume", action="store_true",
                        help="keep the tasks recorded by the last run (results/studies/NAME.jsonl), run the rest")
    parser.add_argument("--no-plots", action="store_true", help="no figures")
    if parts:
        parser.add_argument("--parts", type=int, nargs="+", choices=parts, default=list(parts))
    for flag, options in extra.items():
        parser.add_argument(flag, **options)
    limit_blas_threads()
    return parser.parse_args(argv)


def command(script, argv=None):
    """The command line that ran, as the report quotes it."""
    return " ".join([f"python benchmarks/{script}", *(sys.argv[1:] if argv is None else argv)])


def fmt(value, spec):
    """`value` formatted with `spec`, or "-" for None / NaN."""
    return "-" if value is None or (isinstance(value, float) and math.isnan(value)) else format(value, spec)


def span(values, spec):
    """"a to b" (min, max of `values` formatted with `spec`), or "a" when they agree to that format."""
    low, high = format(min(values), spec), format(max(values), spec)
    return low if low == high else f"{low} to {high}"


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


def render(name, out, **fields):
    """Write OUT/<name>.md from benchmarks/templates/<name>.md with `fields`, and fmt, span, table, pi and
    img(name) (whether OUT/img/<name>.png exists: the report links the figures there)."""
    from jinja2 import Environment, FileSystemLoader, StrictUndefined

    env = Environment(loader=FileSystemLoader(TEMPLATES), undefined=StrictUndefined, trim_blocks=True,
                      lstrip_blocks=True, keep_trailing_newline=True)
    env.globals.update(fmt=fmt, span=span, table=table, pi=math.pi,
                       img=lambda image: (Path(out) / "img" / f"{image}.png").exists())   # link what exists
    env.filters["fmt"] = fmt
    path = Path(out) / f"{name}.md"
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(env.get_template(f"{name}.md").render(**fields))
    print(f"wrote {path.relative_to(ROOT)}")


def figure(rows, cols, width, height):
    """A Figure (Agg) with rows x cols axes (a 2-D array), `width` x `height` inches."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(width, height))
    FigureCanvasAgg(fig)
    return fig, fig.subplots(rows, cols, squeeze=False)


def save(fig, out, name, rect=(0, 0, 1, 1), dpi=100):
    """Write OUT/img/<name>.png, the axes laid out inside `rect` (figure fractions)."""
    path = Path(out) / "img" / f"{name}.png"
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.tight_layout(rect=rect)
    fig.savefig(path, dpi=dpi)
    print(f"wrote {path.relative_to(ROOT)} ({path.stat().st_size // 1024} KB)")
