"""The scene's probes and strain gauges: fixed material points of the wing read from its coordinates.

A probe at (body, span x, chord fraction) is a material point: its global position is r = S(x, y) e
(Otsuka et al. 2019, Eq. 2) and, S being constant for a material point, its velocity is r' = S(x, y) de and its
acceleration r'' = S(x, y) dde.
A strain gauge reads the extensional strain of the plate surface at distance d from the reference line,
eps = d kappa_y (Euler-Bernoulli: strain = distance from the neutral surface x curvature), kappa_y the
flap curvature of the reference line at the gauge's span: that of the cubic interpolation of the nodal vectors
(`structure_fmu.element.flap_curvature`; the ANCF element's own field), or, for a gauge reading the model's own
curvature in a model whose elements carry it (the strain-based element's constant kappa_y, Otsuka et al. 2022,
Sec. 5), that element's.

The shape rows are built once (`Topology.point_rows`), so that a sample is one matrix product on
X = e.reshape(-1, 3). Everything is in the global frame: positions in m, velocities in m/s, strains in 1.

The structure unit publishes these as outputs named like the columns of wingsim's timeseries.csv
(`output_names`).
"""
from __future__ import annotations

import numpy as np

from fmu_common.specs import ProbeSpec, StrainGaugeSpec, StructureUnitSpec

from .element import flap_curvature

AXES = "xyz"


def probe_output_names(probe: str) -> tuple[list[str], list[str], list[str]]:
    """The names of a probe's outputs.

    Args:
        probe: the probe's name.

    Returns:
        (position names ``<probe>_x/_y/_z``, velocity names ``<probe>_vx/_vy/_vz``, acceleration names
        ``<probe>_ax/_ay/_az``).
    """
    return [f"{probe}_{a}" for a in AXES], [f"{probe}_v{a}" for a in AXES], [f"{probe}_a{a}" for a in AXES]


def output_names(probe_names: list[str], gauge_names: list[str]) -> list[str]:
    """Names of the sensor outputs in the structure unit's order.

    Every probe's position, then every probe's velocity, then every probe's acceleration, then the gauges' strains.

    Args:
        probe_names: the probes' names.
        gauge_names: the strain gauges' names.
    """
    names = [probe_output_names(p) for p in probe_names]
    return [n for kind in range(3) for group in names for n in group[kind]] + list(gauge_names)


class Sensors:
    """Probes and strain gauges on a topology.

    Args:
        probes: the probes (fmu_common.specs.ProbeSpec).
        gauges: the strain gauges (fmu_common.specs.StrainGaugeSpec).
        topology: the StructureTopology they sit on.
    """

    def __init__(self, probes: tuple[ProbeSpec, ...], gauges: tuple[StrainGaugeSpec, ...], topology) -> None:
        n_slots = 3 * topology.n_nodes
        self._probes, self._gauges = tuple(probes), tuple(gauges)
        self.probe_names = [p.name for p in probes]
        self.gauge_names = [g.name for g in gauges]
        self._probe_rows = np.array([topology.point_rows(p.body, p.span, p.chord)[0] for p in probes]
                                    ).reshape(len(probes), n_slots)           # (n_probes, n_slots): r = S e
        self._gauge_rows = np.array([topology.point_rows(g.body, g.span)[1:] for g in gauges]
                                    ).reshape(len(gauges), 3, n_slots)        # r', r'', r_y at each gauge
        self._surface_distance = np.array([g.surface_distance for g in gauges], dtype=float)   # m
        self._reads_model = np.array([g.curvature == "model" for g in gauges], dtype=bool)
        self._gauge_elements = np.array([topology.locate(g.body, g.span, 0.0)[0] for g in gauges], dtype=int)
        # the probes' rows, then the gauges' rows: what `outputs` reads from e, in one product
        self._position_rows = np.concatenate([self._probe_rows, self._gauge_rows.reshape(-1, n_slots)])

    @classmethod
    def from_spec(cls, spec: StructureUnitSpec, topology) -> "Sensors":
        """The sensors of the structure unit's spec (its probes and strain gauges).

        Args:
            spec: the structure unit's spec (fmu_common.specs.StructureUnitSpec).
            topology: the StructureTopology.
        """
        return cls(spec.probes, spec.strain_gauges, topology)

    def positions(self, e: np.ndarray) -> np.ndarray:
        """Probe positions.

        Args:
            e: (n,) exchanged coordinates, m and 1, global frame.

        Returns:
            (n_probes, 3) m, global frame.
        """
        return self._probe_rows @ np.asarray(e, dtype=float).reshape(-1, 3)

    def velocities(self, de: np.ndarray) -> np.ndarray:
        """Probe velocities; also the accelerations (m/s^2) from dde, with the same rows.

        Args:
            de: (n,) rates of the exchanged coordinates, per s.

        Returns:
            (n_probes, 3) m/s, global frame.
        """
        return np.dot(self._probe_rows, np.asarray(de, dtype=float).reshape(-1, 3))

    def strains(self, e: np.ndarray, element_curvatures: np.ndarray | None = None) -> np.ndarray:
        """Surface strain of each gauge: d kappa_y, positive when the gauged (-n) face stretches (`flap_curvature`).

        Args:
            e: (n,) exchanged coordinates, m and 1, global frame.
            element_curvatures: (n_elements,) each element's own flap curvature, 1/m, read by the gauges of
                curvature "model"; None: the model's own curvature is the cubic field (the ANCF element).

        Returns:
            (n_gauges,) 1.
        """
        if not self.gauge_names:
            return np.zeros(0)
        return self._strains(self._gauge_rows @ np.asarray(e, dtype=float).reshape(-1, 3), element_curvatures)

    def _strains(self, derivatives, element_curvatures):
        """`strains` from r', r'', r_y at each gauge (n_gauges, 3, 3) and the elements' own curvatures."""
        curvature = flap_curvature(derivatives)
        if element_curvatures is not None:
            curvature = np.where(self._reads_model, element_curvatures[self._gauge_elements], curvature)
        return self._surface_distance * curvature

    def output_declarations(self) -> list[tuple[str, str, str]]:
        """(name, unit, description) of each output, in the order of ``outputs`` (`output_names`)."""
        where = [f"probe {p.name} (body {p.body}, span {p.span:g} m, chord fraction {p.chord:g})"
                 for p in self._probes]
        positions = [(name, "m", f"global {a} position of {w}")
                     for p, w in zip(self.probe_names, where) for name, a in zip(probe_output_names(p)[0], AXES)]
        velocities = [(name, "m/s", f"global {a} velocity of {w}")
                      for p, w in zip(self.probe_names, where) for name, a in zip(probe_output_names(p)[1], AXES)]
        accelerations = [(name, "m/s2", f"global {a} acceleration of {w}")
                         for p, w in zip(self.probe_names, where) for name, a in zip(probe_output_names(p)[2], AXES)]
        strains = [(g.name, "1", f"surface strain of strain gauge {g.name} (body {g.body}, span {g.span:g} m, "
                                 f"{g.surface_distance:g} m from the reference line, {g.curvature} curvature)")
                   for g in self._gauges]
        return positions + velocities + accelerations + strains

    def output_names(self) -> list[str]:
        """Names of the outputs, in the order of ``outputs`` (`output_names`)."""
        return output_names(self.probe_names, self.gauge_names)

    def outputs(self, e: np.ndarray, de: np.ndarray, dde: np.ndarray,
                element_curvatures: np.ndarray | None = None) -> np.ndarray:
        """All readings flat, in the order of ``output_names``.

        Args:
            e: (n,) exchanged coordinates, m and 1, global frame.
            de: (n,) their rates, per s.
            dde: (n,) their accelerations, per s^2.
            element_curvatures: (n_elements,) 1/m or None, as in `strains`.

        Returns:
            positions (m), velocities (m/s), accelerations (m/s^2), strains (1).
        """
        n_probes, n_gauges = len(self.probe_names), len(self.gauge_names)
        at_e = np.dot(self._position_rows, np.asarray(e, dtype=float).reshape(-1, 3))
        strains = (self._strains(at_e[n_probes:].reshape(n_gauges, 3, 3), element_curvatures) if n_gauges
                   else np.zeros(0))
        return np.concatenate([at_e[:n_probes].ravel(), self.velocities(de).ravel(), self.velocities(dde).ravel(),
                               strains])
