"""The unit of every ``timeseries.csv`` column, taken from the units' interface tables (``structure_fmu.interface``,
``aero_fmu.interface``: each output row declares its FMI unit once) and written in the CSV's header as
``name [unit]`` (``tip_z [m]``).

FMI's unit names are kept (``m/s2``, ``N.m``, ``deg``) but the dimensionless ``1``, written ``-``; time is in s and
the implicit coupling's iterations and residual are dimensionless.
"""

from __future__ import annotations

import re

from aero_fmu.interface import AERO
from orchestrator.run.timeseries import PROBE_ROWS
from orchestrator.scene.columns import AERO_COLUMNS, MONITOR_COLUMNS
from structure_fmu.interface import STRUCTURE

DIMENSIONLESS = "-"
HEADER_CELL = re.compile(r"^(?P<name>.*\S) \[(?P<unit>[^\]]*)\]$")
"""A header cell of ``timeseries.csv``: the column's name, a space and its unit in brackets."""

_ROWS = {row.key: row for row in (*STRUCTURE.outputs, *AERO.outputs)}


def _shown(unit: str) -> str:
    return DIMENSIONLESS if unit == "1" else unit


def _row_units(key: str, items: list[str]) -> dict[str, str]:
    """{column: unit} of the interface row filed under ``key`` for each of ``items`` (a row without items: its
    one variable)."""
    row = _ROWS[key]
    if row.items is None:
        return {row.names[0]: _shown(row.unit_of(row.names[0]))}
    return {pattern.replace(row.items.placeholder, item): _shown(row.unit_of(pattern.replace(row.items.placeholder,
                                                                                              item)))
            for item in items for pattern in row.names}


def column_units(series) -> dict[str, str]:
    """{column: unit} for every column of ``series`` (an ``orchestrator.run.timeseries.TimeSeries``), in its
    column order."""
    units = {"time": "s"}
    for key in PROBE_ROWS:
        units.update(_row_units(key, series.probe_names))
    units.update(_row_units("fold_angles_deg", series.hinge_names))
    units.update(_row_units("strains", series.strain_names))
    units.update(_row_units("joints", series.joint_names))
    for name in MONITOR_COLUMNS:
        units.update(_row_units(name, []))
    if series.has_aero:
        units.update(_row_units("hinge_moments", series.hinge_names))
        for name in AERO_COLUMNS:
            units.update(_row_units(name, []))
    units.update(dict.fromkeys(series.coupling_names, DIMENSIONLESS))
    missing = [c for c in series.columns if c not in units]
    if missing:
        raise KeyError(f"no unit declared for the columns {missing}")
    return {column: units[column] for column in series.columns}


def header_cell(name: str, unit: str) -> str:
    """The header cell of a column: ``name [unit]``."""
    return f"{name} [{unit}]"


def split_header_cell(cell: str) -> tuple[str, str | None]:
    """(name, unit) of a header cell; (cell, None) for a cell without a unit."""
    found = HEADER_CELL.match(cell.strip())
    return (found["name"], found["unit"]) if found else (cell.strip(), None)
