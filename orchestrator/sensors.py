"""The scene's probes and strain gauges: fixed material points read from the exchanged coordinates e.

Their shape rows are built once per run (`Topology.point_rows`), so that a sample is one matrix product:
a probe's position is r = S(x, y) e (000 Eq. 2); a strain gauge reads the surface strain
surface_distance x kappa_y, the flap curvature of the reference line at its span (003 Sec. 5:
h/2 x kappa_y, `structure_fmu.element.flap_curvature`).
"""
import numpy as np

from structure_fmu.element import flap_curvature


class Sensors:
    """Probes and strain gauges of a resolved scene on a topology."""

    def __init__(self, scene: dict, topology) -> None:
        probes = scene["probes"]
        gauges = scene.get("strain_gauges", [])
        n_slots = 3 * topology.n_nodes
        self._probe_rows = np.array([topology.point_rows(p["body"], p["span"], p["chord"])[0] for p in probes]
                                    ).reshape(len(probes), n_slots)           # (n_probes, n_slots): position
        self._gauge_rows = np.array([topology.point_rows(g["body"], g["span"])[1:] for g in gauges]
                                    ).reshape(len(gauges), 3, n_slots)        # r', r'', r_y at each gauge
        self._surface_distance = np.array([g["surface_distance"] for g in gauges], dtype=float)
        self.strain_names = [g["name"] for g in gauges]

    def positions(self, e: np.ndarray) -> np.ndarray:
        """Probe positions (n_probes, 3), m."""
        return self._probe_rows @ np.asarray(e, dtype=float).reshape(-1, 3)

    def strains(self, e: np.ndarray) -> dict:
        """Surface strain of each gauge, {name: strain (-)}."""
        derivatives = self._gauge_rows @ np.asarray(e, dtype=float).reshape(-1, 3)     # (n_gauges, 3, 3)
        values = self._surface_distance * flap_curvature(derivatives)
        return dict(zip(self.strain_names, values.tolist()))
