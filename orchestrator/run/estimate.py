"""How long a run will take and how much it will write, announced before and early in the run.

- Output size, before the run: ``timeseries.csv`` has one row per communication point
  (``fmu_common.scene_bounds.communication_steps``) and one column per ``new_series`` column, each value written
  as ``%.12g`` and a separator, CSV_BYTES_PER_VALUE bytes at most; above LARGE_OUTPUT_BYTES a note says so
  and how to make it smaller.
- Run time, after a short warm-up: ``orchestrator.run.progress.Progress`` (its docstring).
"""
from __future__ import annotations

from fmu_common.scene_bounds import communication_steps
from orchestrator.run.master import new_series
from orchestrator.run.progress import REDUCE

CSV_BYTES_PER_VALUE = 20
"""Bytes of one value in timeseries.csv at most: ``%.12g`` writes at most a sign, 12 significant digits, a point
and an exponent (``-1.23456789012e-100``: 19 characters), and a separator. Zeros and ``nan`` are shorter, so the
file is smaller: the estimate is a bound."""
LARGE_OUTPUT_BYTES = 20 * 2**20
"""A timeseries.csv above this size gets a note before the run."""


def csv_bytes(scene: dict) -> int:
    """A bound on the size (bytes) of the run's timeseries.csv, header aside: rows x columns x CSV_BYTES_PER_VALUE."""
    return communication_steps(scene) * len(new_series(scene).columns) * CSV_BYTES_PER_VALUE


def output_note(scene: dict) -> str | None:
    """The note for a timeseries.csv that may exceed LARGE_OUTPUT_BYTES, else None."""
    size = csv_bytes(scene)
    if size <= LARGE_OUTPUT_BYTES:
        return None
    rows, columns = communication_steps(scene), len(new_series(scene).columns)
    return (f"timeseries.csv will be up to {size / 2**20:.0f} MiB ({rows:,} rows x {columns} columns); to make it "
            f"smaller, {REDUCE}")

