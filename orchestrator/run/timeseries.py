"""The samples a run records at each communication point.

One row per sample: time (s), each probe's global position (``<probe>_x/_y/_z``, m), then each probe's global
velocity (``<probe>_vx/_vy/_vz``, m/s), then each probe's global acceleration (``<probe>_ax/_ay/_az``, m/s^2), each
hinge's fold angle (degrees), each strain gauge's surface strain (-, a column named as the gauge), each joint
monitor (``<joint>_point_mismatch`` in m, ``<joint>_axis_product`` or ``<joint>_axis_error``, -, for every joint
with a parent), the structure's energy (J), its kinetic energy (J), its constraint residual (-) and the work of
the point loads and Q on it since t = 0 (``external_work``, J: energy minus it changes only by damping and driven
motions), and, for a scene with an aero unit, each hinge's aerodynamic moment about its axis
``hinge_moment_<hinge>`` (N m), the lift coefficient ``CL`` (-) and the ``lift`` (N), and, for implicit coupling,
the iterations ``coupling_iterations`` the master took in the communication step ending at that sample and the
relative interface residual ``coupling_residual`` (-) it accepted (0 and NaN at t = 0). The column names are those
of ``timeseries.csv`` (README, Outputs); columns are only ever added, never renamed, and are read back by name
(``column``), never by a fixed position.
"""

from __future__ import annotations

from typing import Mapping, Sequence

import numpy as np

from orchestrator.scene.columns import AERO_COLUMNS, COUPLING_COLUMNS, MONITOR_COLUMNS, hinge_moment_column
from structure_fmu.interface import PROBES, STRUCTURE

PROBE_ROWS = ("probe_positions", "probe_velocities", "probe_accelerations")
"""The structure unit's per-probe output rows (``structure_fmu.interface``) the series records, in column order:
every probe's position (m), then every probe's velocity (m/s), then every probe's acceleration (m/s^2), each
global x, y, z."""
_ROWS = {row.key: row for row in STRUCTURE.outputs if row.key in PROBE_ROWS}
INITIAL_ROWS = 64
"""Rows the series holds before it first grows (``reserve`` sets the number a run needs at once)."""


def probe_columns(probe: str, row: str) -> list[str]:
    """The ``timeseries.csv`` columns of ``probe`` for the output row ``row`` (one of PROBE_ROWS): the unit's
    output names with the probe's name in place (``<probe>_x`` .., ``<probe>_vx`` .., ``<probe>_ax`` ..)."""
    return [name.replace(PROBES.placeholder, probe) for name in _ROWS[row].names]


class TimeSeries:
    """Recorded samples; append during the run, read as numpy arrays afterwards. The samples lie in one preallocated
    block of rows (NaN until written), which doubles when full: a sample costs no allocation."""

    def __init__(self, probe_names: Sequence[str], hinge_names: Sequence[str], aero: bool = False,
                 coupling: bool = False, strain_names: Sequence[str] = (), joint_names: Sequence[str] = ()):
        self.probe_names = list(probe_names)
        self.hinge_names = list(hinge_names)
        self.strain_names = list(strain_names)
        self.joint_names = list(joint_names)
        self.hinge_moment_names = [hinge_moment_column(h) for h in self.hinge_names] if aero else []
        self.aero_names = self.hinge_moment_names + list(AERO_COLUMNS) if aero else []
        self.coupling_names = list(COUPLING_COLUMNS) if coupling else []
        self._width = len(self.columns)
        self._block = np.full((INITIAL_ROWS, self._width), np.nan)   # the samples, in rows 0 .. _size - 1
        self._size = 0
        # named column positions (time, probes' positions, velocities and accelerations, hinges, strains, monitors,
        # aero), from the layout of ``columns``
        k = 3 * len(self.probe_names)
        self._positions = slice(1, 1 + k)
        self._velocities = slice(1 + k, 1 + 2 * k)
        self._accelerations = slice(1 + 2 * k, 1 + 3 * k)
        self._folds = slice(1 + 3 * k, 1 + 3 * k + len(self.hinge_names))
        self._strains = slice(self._folds.stop, self._folds.stop + len(self.strain_names))
        self._joints = slice(self._strains.stop, self._strains.stop + len(self.joint_names))
        self._monitor = {name: self._joints.stop + i for i, name in enumerate(MONITOR_COLUMNS)}
        start = self._joints.stop + len(MONITOR_COLUMNS)
        self._monitor.update({name: start + i for i, name in enumerate(self.aero_names)})
        start += len(self.aero_names)
        self._monitor.update({name: start + i for i, name in enumerate(self.coupling_names)})

    @property
    def has_aero(self) -> bool:
        """True when the series has the aero columns (CL, lift)."""
        return bool(self.aero_names)

    @property
    def has_coupling(self) -> bool:
        """True when the series has the implicit coupling's columns (coupling_iterations, coupling_residual)."""
        return bool(self.coupling_names)

    @classmethod
    def from_arrays(cls, probe_names: Sequence[str], hinge_names: Sequence[str], time, positions,
                    fold_angles_deg, energy, constraint_residual, kinetic_energy=None, external_work=None,
                    aero: Mapping[str, Sequence[float]] | None = None,
                    coupling: Mapping[str, Sequence[float]] | None = None,
                    strains: Mapping[str, Sequence[float]] | None = None,
                    joints: Mapping[str, Sequence[float]] | None = None,
                    velocities: Sequence | None = None, accelerations: Sequence | None = None) -> "TimeSeries":
        """Build from whole arrays: time (m,), positions (m, probes, 3), fold angles (m, hinges),
        energy, constraint residual and kinetic energy (m,) each; no kinetic energy gives NaN;
        velocities and accelerations (m, probes, 3) likewise (NaN without them).
        ``aero``: {"CL": (m,), "lift": (m,), "hinge_moment_<hinge>": (m,)} for a series with the aero columns (a
        missing one is NaN);
        ``coupling``: {"coupling_iterations": (m,), "coupling_residual": (m,)} likewise; ``strains``:
        {gauge name: (m,)} for a series with strain gauge columns; ``joints`` {joint monitor: (m,)} likewise."""
        strains, joints = strains or {}, joints or {}
        series = cls(probe_names, hinge_names, aero=aero is not None, coupling=coupling is not None,
                     strain_names=list(strains), joint_names=list(joints))
        m = len(time)
        kinetic = np.full(m, np.nan) if kinetic_energy is None else kinetic_energy
        work = np.full(m, np.nan) if external_work is None else external_work
        monitors = {"energy": energy, "kinetic_energy": kinetic, "constraint_residual": constraint_residual,
                    "external_work": work}
        aero, coupling = aero or {}, coupling or {}
        k = 3 * len(series.probe_names)
        rates = [np.full((m, k), np.nan) if x is None else np.asarray(x, float).reshape(m, k)
                 for x in (velocities, accelerations)]
        table = np.column_stack([
            np.asarray(time, float),
            np.asarray(positions, float).reshape(m, k), *rates,
            np.asarray(fold_angles_deg, float).reshape(m, len(series.hinge_names)),
            *(np.asarray(strains[name], float).reshape(m) for name in series.strain_names),
            *(np.asarray(joints[name], float).reshape(m) for name in series.joint_names),
            *(np.asarray(monitors[name], float).reshape(m) for name in MONITOR_COLUMNS),
            *(np.asarray(aero.get(name, np.full(m, np.nan)), float).reshape(m) for name in series.aero_names),
            *(np.asarray(coupling.get(name, np.full(m, np.nan)), float).reshape(m)
              for name in series.coupling_names),
        ])
        series._block, series._size = table.reshape(m, series._width), m
        return series

    def append(self, time: float, positions: np.ndarray, fold_angles_deg: Mapping[str, float],
               energy: float, constraint_residual: float, kinetic_energy: float = np.nan,
               external_work: float = np.nan,
               aero: Mapping[str, float] | None = None, coupling: Mapping[str, float] | None = None,
               strains: Mapping[str, float] | None = None, joints: Mapping[str, float] | None = None,
               velocities: np.ndarray | None = None, accelerations: np.ndarray | None = None) -> None:
        """Add one sample; ``positions`` is (probes, 3) in m, ``velocities`` (probes, 3) in m/s and
        ``accelerations`` (probes, 3) in m/s^2 (NaN without them), a hinge missing from the dict gives NaN,
        energies are in J; ``aero`` {"CL": -, "lift": N, "hinge_moment_<hinge>": N m}, ``coupling``
        {"coupling_iterations": -, "coupling_residual": -}, ``strains`` {gauge name: -} and ``joints`` {joint
        monitor: m or -} (missing values, or no dict, give NaN)."""
        angles = [fold_angles_deg.get(h, np.nan) for h in self.hinge_names]
        strains, joints = strains or {}, joints or {}
        monitors = {"energy": energy, "kinetic_energy": kinetic_energy, "constraint_residual": constraint_residual,
                    "external_work": external_work}
        aero, coupling = aero or {}, coupling or {}
        k = 3 * len(self.probe_names)
        rates = [np.full(k, np.nan) if x is None else np.asarray(x, float).reshape(k)
                 for x in (velocities, accelerations)]
        self.new_row()[:] = np.concatenate((
            [time], np.asarray(positions, float).reshape(-1), *rates, angles,
            [strains.get(n, np.nan) for n in self.strain_names],
            [joints.get(n, np.nan) for n in self.joint_names],
            [monitors[n] for n in MONITOR_COLUMNS],
            [aero.get(n, np.nan) for n in self.aero_names], [coupling.get(n, np.nan) for n in self.coupling_names],
        )).astype(float)

    def reserve(self, rows: int) -> None:
        """Make room for ``rows`` samples in all, so that a run of that many points never grows the block."""
        if rows > len(self._block):
            grown = np.full((rows, self._width), np.nan)
            grown[:self._size] = self._block[:self._size]
            self._block = grown

    def new_row(self) -> np.ndarray:
        """The next sample's row, (columns,), all NaN, counted from now on; the caller writes its values in it
        (``orchestrator.run.recording.Recorder``)."""
        if self._size == len(self._block):
            self.reserve(2 * max(1, self._size))
        row = self._block[self._size]
        self._size += 1
        return row

    def __len__(self) -> int:
        return self._size

    @property
    def columns(self) -> list[str]:
        """Column names in ``timeseries.csv`` order, ``time`` first."""
        probes = [name for key in PROBE_ROWS for p in self.probe_names for name in probe_columns(p, key)]
        hinges = [f"fold_angle_{h}" for h in self.hinge_names]
        return ["time", *probes, *hinges, *self.strain_names, *self.joint_names, *MONITOR_COLUMNS, *self.aero_names,
                *self.coupling_names]

    def table(self) -> np.ndarray:
        """All samples, shape (samples, columns)."""
        return self._block[:self._size].copy()

    def column(self, name: str) -> np.ndarray:
        """The samples of the column called ``name`` (a ``timeseries.csv`` header), shape (samples,)."""
        if name in self._monitor:
            return self.table()[:, self._monitor[name]]
        columns = self.columns
        if name not in columns:
            raise KeyError(f"no column {name!r}; the columns are {', '.join(columns)}")
        return self.table()[:, columns.index(name)]

    @property
    def time(self) -> np.ndarray:
        """Sample times, s, shape (samples,)."""
        return self.column("time")

    @property
    def positions(self) -> np.ndarray:
        """Probe global positions, m, shape (samples, probes, 3)."""
        return self.table()[:, self._positions].reshape(len(self), len(self.probe_names), 3)

    @property
    def velocities(self) -> np.ndarray:
        """Probe global velocities, m/s, shape (samples, probes, 3)."""
        return self.table()[:, self._velocities].reshape(len(self), len(self.probe_names), 3)

    @property
    def accelerations(self) -> np.ndarray:
        """Probe global accelerations, m/s^2, shape (samples, probes, 3)."""
        return self.table()[:, self._accelerations].reshape(len(self), len(self.probe_names), 3)

    @property
    def fold_angles_deg(self) -> np.ndarray:
        """Hinge fold angles, degrees, shape (samples, hinges)."""
        return self.table()[:, self._folds]

    @property
    def strains(self) -> np.ndarray:
        """Strain gauge surface strains, -, shape (samples, gauges)."""
        return self.table()[:, self._strains]

    @property
    def energy(self) -> np.ndarray:
        """Energy of the structure, J, shape (samples,)."""
        return self.column("energy")

    @property
    def external_work(self) -> np.ndarray:
        """Work of the point loads and Q on the structure since t = 0, J, shape (samples,)."""
        return self.column("external_work")

    @property
    def kinetic_energy(self) -> np.ndarray:
        """Kinetic energy of the structure, J, shape (samples,)."""
        return self.column("kinetic_energy")

    @property
    def constraint_residual(self) -> np.ndarray:
        """Constraint residual (as the unit reports it), shape (samples,)."""
        return self.column("constraint_residual")

    @property
    def hinge_moments(self) -> np.ndarray:
        """Aerodynamic moment about each hinge's axis, N m, shape (samples, hinges); (samples, 0) without the aero
        columns."""
        return self.table()[:, [self._monitor[name] for name in self.hinge_moment_names]]

    @property
    def CL(self) -> np.ndarray:
        """Lift coefficient (-), shape (samples,); KeyError for a series without the aero columns."""
        return self.column("CL")

    @property
    def lift(self) -> np.ndarray:
        """Lift (N), shape (samples,); KeyError for a series without the aero columns."""
        return self.column("lift")
