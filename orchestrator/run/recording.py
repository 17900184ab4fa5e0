"""One sample per communication point: the units' recorded outputs copied into the time series' next row.

A unit reads the output rows it records in one call (``Unit.monitor_values()``: one fmi2GetReal through an FMU),
as one vector laid out row by row (``Unit.monitor_layout``, a ``MonitorRow`` per row). ``Recorder`` matches that
layout with the columns of the ``TimeSeries`` once, when the run starts, and then copies every sample with one
index gather per unit into the series' preallocated rows: nothing per step builds a dictionary or loops over
values in Python. A column no unit reports holds NaN, as does a value equal to its row's ``pending`` mark.
"""
from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np

from orchestrator.run.timeseries import PROBE_ROWS, TimeSeries, probe_columns
from orchestrator.scene.columns import AERO_COLUMNS, MONITOR_COLUMNS, hinge_moment_column


class MonitorRow(NamedTuple):
    """Where one output row of a unit's table (``fmu_common.interface.Output``) lies in the unit's vector of
    recorded outputs: its ``key`` (e.g. ``probe_positions``), its ``items`` (the scene's probes, hinges, ... in
    the order of the vector, maybe none; None for a row of one value, not per item), the values per item
    ``width``, the slice ``where`` of the vector, and the value ``pending`` that means "none yet" (None: every value
    is one)."""

    key: str
    items: tuple[str, ...] | None
    width: int
    where: slice
    pending: float | None = None


def monitor_dict(layout: tuple[MonitorRow, ...], values: np.ndarray) -> dict:
    """The vector ``values`` of a unit's recorded outputs as {row key: value}: a float for a row without items;
    {item: float} for a row of one value per item (items whose value is the row's ``pending`` left out);
    {item: array (width,)} otherwise."""
    out = {}
    for row in layout:
        part = values[row.where]
        if row.items is None:
            out[row.key] = float(part[0])
        elif row.width == 1:
            out[row.key] = {item: float(v) for item, v in zip(row.items, part)
                            if row.pending is None or v != row.pending}
        else:
            out[row.key] = dict(zip(row.items, part.reshape(-1, row.width).copy()))
    return out


class _Gather:
    """Which values of one unit's vector go to which columns of a series row (``source`` -> ``target``), and the
    targets to clear where a value is its row's pending mark."""

    def __init__(self) -> None:
        self.source: list[int] = []
        self.target: list[int] = []
        self.pending: list[tuple[int, int, float]] = []   # (source, target, pending value)

    def add(self, row: MonitorRow, item_index: int, columns: list[int]) -> None:
        """The values of item `item_index` of `row` (the row's only value for a row without items) to `columns`."""
        start = row.where.start + item_index * row.width
        self.source += range(start, start + len(columns))
        self.target += columns
        if row.pending is not None:
            self.pending += [(start + k, column, row.pending) for k, column in enumerate(columns)]

    def arrays(self) -> tuple[np.ndarray, np.ndarray]:
        """(source, target) as index arrays."""
        return np.array(self.source, dtype=np.intp), np.array(self.target, dtype=np.intp)


class Recorder:
    """Records the samples of a run into ``series`` from the ``structure`` unit and the ``aero`` unit (or None).

    Construction matches the units' ``monitor_layout`` with the series' columns: the probes' positions (always),
    velocities and accelerations (when the structure unit reads them), the fold angles, the strain gauges, the
    joint monitors, the scalar monitors and, with an aero unit, CL, the lift and the hinge moments. A probe or a
    strain gauge of the series that the structure unit does not report is an error (RuntimeError naming it: an
    FMU built before the probe or the gauge was declared); any other column a unit does not report holds NaN."""

    def __init__(self, series: TimeSeries, structure: Any, aero: Any = None):
        self.series, self.structure, self.aero = series, structure, aero
        columns = {name: k for k, name in enumerate(series.columns)}
        rows = {row.key: row for row in structure.monitor_layout}
        self._latch = rows.get("latch_times")
        gather = _Gather()
        for key in PROBE_ROWS:
            row = rows.get(key)
            if row is None and key != PROBE_ROWS[0]:
                continue                 # velocities and accelerations not read: NaN
            for p in series.probe_names:
                if row is None or p not in row.items:
                    raise RuntimeError(f"the structure unit reports no {key} output for the probe {p!r}: rebuild the "
                                       "FMUs (wingsim build)")
                gather.add(row, row.items.index(p), [columns[c] for c in probe_columns(p, key)])
        strains = rows.get("strains")
        for g in series.strain_names:
            if strains is None or g not in strains.items:
                raise RuntimeError(f"the structure unit reports no output for the strain gauge {g!r}: rebuild the "
                                   "FMUs (wingsim build)")
            gather.add(strains, strains.items.index(g), [columns[g]])
        self._per_item(gather, rows.get("fold_angles_deg"), series.hinge_names,
                       [columns[f"fold_angle_{h}"] for h in series.hinge_names])
        self._per_item(gather, rows.get("joints"), series.joint_names, [columns[j] for j in series.joint_names])
        self._scalars(gather, rows, MONITOR_COLUMNS, columns)
        self._structure = gather.arrays()
        self._structure_pending = gather.pending
        self._aero = self._aero_pending = None
        if aero is not None and series.has_aero:
            rows = {row.key: row for row in aero.monitor_layout}
            gather = _Gather()
            self._per_item(gather, rows.get("hinge_moments"), series.hinge_names,
                           [columns[hinge_moment_column(h)] for h in series.hinge_names])
            self._scalars(gather, rows, AERO_COLUMNS, columns)
            self._aero, self._aero_pending = gather.arrays(), gather.pending
        self._coupling = np.array([columns[c] for c in series.coupling_names], dtype=np.intp)
        self._latest: np.ndarray | None = None     # the structure's vector of the last sample

    @staticmethod
    def _per_item(gather: _Gather, row: MonitorRow | None, names: list[str], targets: list[int]) -> None:
        """The columns `targets` of the items `names` of a row of one value per item; an item the unit does not
        report (or the whole row) stays NaN."""
        if row is None:
            return
        for name, column in zip(names, targets):
            if name in row.items:
                gather.add(row, row.items.index(name), [column])

    @staticmethod
    def _scalars(gather: _Gather, rows: dict, keys: tuple[str, ...], columns: dict) -> None:
        """The columns of the rows of one value `keys`; a row the unit does not report stays NaN."""
        for key in keys:
            if key in rows:
                gather.add(rows[key], 0, [columns[key]])

    def record(self, t: float, coupling: tuple[int, float] | None = None) -> None:
        """Append the sample at communication point ``t`` (s), with the coupling record (iterations, residual) of an
        implicit coupling (None: NaN). The units are read first: a failed read appends nothing."""
        values = self.structure.monitor_values()
        aero = self.aero.monitor_values() if self._aero is not None else None
        row = self.series.new_row()
        row[0] = t
        source, target = self._structure
        row[target] = values[source]
        for k, column, pending in self._structure_pending:
            if values[k] == pending:
                row[column] = np.nan
        if aero is not None:
            source, target = self._aero
            row[target] = aero[source]
            for k, column, pending in self._aero_pending:
                if aero[k] == pending:
                    row[column] = np.nan
        if coupling is not None and self._coupling.size:
            row[self._coupling] = coupling
        self._latest = values

    def latch_times(self) -> dict[str, float]:
        """{hinge: the time it latched, s} as the structure unit reported it at the last sample (hinges that have not
        latched left out); {} before any sample or for a unit that does not report them."""
        if self._latest is None or self._latch is None:
            return {}
        return monitor_dict((self._latch,), self._latest)["latch_times"]
