"""The samples a run records at each communication point.

One row per sample: time (s), each probe's global position (m), each hinge's fold angle (degrees),
the structure's energy (J) and its constraint residual (-). The column names are those of
``timeseries.csv`` (DESIGN §7).
"""

from __future__ import annotations

from typing import Mapping, Sequence

import numpy as np


class TimeSeries:
    """Recorded samples; append during the run, read as numpy arrays afterwards."""

    def __init__(self, probe_names: Sequence[str], hinge_names: Sequence[str]):
        self.probe_names = list(probe_names)
        self.hinge_names = list(hinge_names)
        self._rows: list[np.ndarray] = []

    @classmethod
    def from_arrays(cls, probe_names: Sequence[str], hinge_names: Sequence[str], time, positions,
                    fold_angles_deg, energy, constraint_residual) -> "TimeSeries":
        """Build from whole arrays: time (m,), positions (m, probes, 3), fold angles (m, hinges), ..."""
        series = cls(probe_names, hinge_names)
        m = len(time)
        table = np.column_stack([
            np.asarray(time, float),
            np.asarray(positions, float).reshape(m, 3 * len(series.probe_names)),
            np.asarray(fold_angles_deg, float).reshape(m, len(series.hinge_names)),
            np.asarray(energy, float), np.asarray(constraint_residual, float),
        ])
        series._rows = list(table)
        return series

    def append(self, time: float, positions: np.ndarray, fold_angles_deg: Mapping[str, float],
               energy: float, constraint_residual: float) -> None:
        """Add one sample; ``positions`` is (probes, 3) in m, a hinge missing from the dict gives NaN."""
        angles = [fold_angles_deg.get(h, np.nan) for h in self.hinge_names]
        self._rows.append(np.concatenate((
            [time], np.asarray(positions, float).reshape(-1), angles, [energy, constraint_residual],
        )).astype(float))

    def __len__(self) -> int:
        return len(self._rows)

    @property
    def columns(self) -> list[str]:
        """Column names in ``timeseries.csv`` order, ``time`` first."""
        probes = [f"{p}_{axis}" for p in self.probe_names for axis in "xyz"]
        hinges = [f"fold_angle_{h}" for h in self.hinge_names]
        return ["time", *probes, *hinges, "energy", "constraint_residual"]

    def table(self) -> np.ndarray:
        """All samples, shape (samples, columns)."""
        return np.array(self._rows, dtype=float).reshape(len(self._rows), len(self.columns))

    @property
    def time(self) -> np.ndarray:
        """Sample times, s, shape (samples,)."""
        return self.table()[:, 0]

    @property
    def positions(self) -> np.ndarray:
        """Probe global positions, m, shape (samples, probes, 3)."""
        k = 3 * len(self.probe_names)
        return self.table()[:, 1:1 + k].reshape(len(self), len(self.probe_names), 3)

    @property
    def fold_angles_deg(self) -> np.ndarray:
        """Hinge fold angles, degrees, shape (samples, hinges)."""
        start = 1 + 3 * len(self.probe_names)
        return self.table()[:, start:start + len(self.hinge_names)]

    @property
    def energy(self) -> np.ndarray:
        """Energy of the structure, J, shape (samples,)."""
        return self.table()[:, -2]

    @property
    def constraint_residual(self) -> np.ndarray:
        """Constraint residual (as the unit reports it), shape (samples,)."""
        return self.table()[:, -1]
