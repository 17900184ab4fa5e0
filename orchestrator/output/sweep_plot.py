"""The picture of a sweep (``sweep.png``, written by ``wingsim sweep`` beside ``sweep.csv``): its key figures
against each grid key.

One column of panels per grid key (its values on the x axis: numbers to scale, other values in grid order), one row
per key figure that ``sweep.csv`` has (``KEY_FIGURES``: the deployment time, the aerodynamic loads, the largest
probe displacement, the energy drift and the constraint residual). With two or more grid keys, a panel draws one
line per combination of the other keys' values, labelled with them. A run whose status is not ok is circled in red
at its value (if it has one). A panel without any value (e.g. no run deployed: ``NO_VALUE_NOTE``) or whose values
are all zero says so (``plots.note_flat_panels``). Layout and legends as the run's plots
(``orchestrator.output.plots``).
"""

from __future__ import annotations

import csv
import itertools
from pathlib import Path

import numpy as np

from orchestrator.files import write_file
from orchestrator.output.plots import DPI, LEGEND_FONT, legend, note_flat_panels

SWEEP_PLOT = "sweep.png"
KEY_FIGURES = (
    ("deployment_time_s", "deployment time (s)"),
    ("aero.lift_final", "final lift (N)"),
    ("aero.CL_final", "final CL (-)"),
    ("max_abs_displacement", "largest probe displacement (m)"),
    ("energy_drift", "energy drift (-)"),
    ("max_constraint_residual", "largest constraint residual (-)"),
)
"""(sweep.csv column, axis label) of the figures drawn, in this order; ``max_abs_displacement`` stands for the
first probe's ``probes.<probe>.max_abs_displacement``."""
NO_VALUE_NOTE = "no value in any run"


def _number(text) -> float:
    try:
        return float(text)
    except (TypeError, ValueError):
        return np.nan


def read_rows(table: Path) -> list[dict[str, str]]:
    """The rows of a sweep.csv, cells as text."""
    with Path(table).open(newline="") as handle:
        return list(csv.DictReader(handle))


def figures_of(rows: list[dict[str, str]]) -> list[tuple[str, str]]:
    """The KEY_FIGURES the rows have, as (column, label), the displacement's column named for its probe."""
    columns = list(rows[0]) if rows else []
    found = []
    for column, label in KEY_FIGURES:
        if column == "max_abs_displacement":
            probes = [c for c in columns if c.startswith("probes.") and c.endswith(".max_abs_displacement")]
            if probes:
                found.append((probes[0], f"largest displacement of {probes[0].split('.')[1]} (m)"))
        elif column in columns:
            found.append((column, label))
    return found


def _axis_values(values: list[str]) -> tuple[np.ndarray, list[str] | None]:
    """x positions of a grid key's distinct values (in grid order): the numbers, or 0, 1, ... with tick labels."""
    numbers = np.array([_number(v) for v in values])
    if np.isfinite(numbers).all():
        return numbers, None
    return np.arange(len(values), dtype=float), list(values)


def sweep_figure(rows: list[dict[str, str]], grid_keys: list[str], title: str):
    """The figure (matplotlib Figure) of sweep.csv's rows (module docstring).

    Args:
        rows: sweep.csv's rows, cells as text.
        grid_keys: the grid's keys, in grid order (columns of the rows).
        title: the figure's title.
    """
    from matplotlib.figure import Figure

    figures = figures_of(rows)
    if not rows or not figures or not grid_keys:
        return None
    fig = Figure(figsize=(4.2 * len(grid_keys) + 1.5, 2.6 * len(figures) + 0.8), layout="constrained")
    axes = np.array(fig.subplots(len(figures), len(grid_keys), sharex="col", squeeze=False))
    levels = {key: list(dict.fromkeys(row[key] for row in rows)) for key in grid_keys}
    for c, key in enumerate(grid_keys):
        x_of, ticks = _axis_values(levels[key])
        position = dict(zip(levels[key], x_of))
        others = [k for k in grid_keys if k != key]
        for r, (column, label) in enumerate(figures):
            ax = axes[r, c]
            for combo in itertools.product(*(levels[k] for k in others)):
                chosen = [row for row in rows if all(row[k] == v for k, v in zip(others, combo))]
                x = np.array([position[row[key]] for row in chosen])
                y = np.array([_number(row[column]) for row in chosen])
                name = ", ".join(f"{k}={v}" for k, v in zip(others, combo)) or None
                ax.plot(x, y, "o-", markersize=4, label=name if r == 0 else None)
                failed = np.array([row.get("status") != "ok" for row in chosen], dtype=bool)
                if failed.any():
                    ax.plot(x[failed], y[failed], "o", markersize=10, markerfacecolor="none", color="tab:red",
                            label="run not ok" if r == 0 and c == 0 else None)
            ax.set_ylabel(label)
            ax.grid(True, alpha=0.3)
            if ticks is not None:
                ax.set_xticks(x_of, ticks, rotation=30)
        axes[-1, c].set_xlabel(key)
    fig.suptitle(title, fontsize=12)
    for c in range(len(grid_keys)):
        legend(fig, axes[0, c])
    for ax in axes.ravel():
        if ax.get_legend() is not None:
            for text in ax.get_legend().get_texts():
                text.set_fontsize(LEGEND_FONT)
    return fig


def write_sweep_plot(table: Path, grid_keys: list[str], title: str) -> Path | None:
    """Write ``sweep.png`` beside ``table`` (sweep.csv) from its rows; returns its path, or None (and removes a
    stale file) when there is nothing to draw. Raises on a failure (the caller warns).

    Args:
        table: the sweep.csv.
        grid_keys: the grid's keys, in grid order.
        title: the figure's title.
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    path = Path(table).with_name(SWEEP_PLOT)
    fig = sweep_figure(read_rows(table), grid_keys, title)
    if fig is None:
        path.unlink(missing_ok=True)
        return None
    FigureCanvasAgg(fig)
    note_flat_panels(fig, NO_VALUE_NOTE)
    write_file(path, lambda tmp: fig.savefig(tmp, dpi=DPI))
    return path
