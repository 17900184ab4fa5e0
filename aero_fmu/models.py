"""The aero models as the aero unit realizes them: the registry from aero.model (its traits,
`fmu_common.choices.AeroModel`) to what builds the model from the aero spec and the topology, and the contract
every model keeps (`AerodynamicModel`), which AeroSolver calls.

  strip            StripTheory: quasi-steady strips (strip.py)
  uvlm-flat        UVLM with flat horseshoe legs along U, quasi-steady bound circulation (uvlm.FLAT)
  uvlm-prescribed  UVLM with a shed ring wake convected with U (uvlm.PRESCRIBED)
  uvlm-free        UVLM with a shed ring wake convected with U + w (uvlm.FREE)

none builds no aero unit (`AeroModel.builds_unit`), so it has no entry here.
"""
from __future__ import annotations

from typing import Protocol

import numpy as np

from fmu_common.errors import SceneError
from fmu_common.specs import AeroSpec

from .lattice import Lattice
from .strip import StripTheory
from .uvlm import FLAT, FREE, PRESCRIBED, UVLM


class AerodynamicModel(Protocol):
    """An aero model on a topology's lattice (Otsuka et al. 2019, Sec. V): a state that starts at rest
    (`initial_state`: time 0, not started) and is advanced to t_end (s) for the exchanged coordinates E (n,) and
    rates dE (n,) at t_end, the free stream U (3,) m/s, the density (kg/m^3) and the unit free-stream direction
    (3,), returning a new state (time, started, loads: Q, forces, outputs; `copy()`), the old one unchanged;
    `vortex_geometry` of a state for pictures (`UVLM.vortex_geometry`)."""

    lattice: Lattice

    def initial_state(self):
        """The state at rest: time 0, not started, no loads."""

    def advance(self, state, t_end: float, E: np.ndarray, dE: np.ndarray, U: np.ndarray, density: float,
                direction: np.ndarray):
        """A new state at t_end for the coordinates and rates at t_end; `state` is unchanged.

        Args:
            state: the model's state at the previous time.
            t_end: time to reach, s.
            E: (n,) exchanged coordinates at t_end, m and 1, global frame.
            dE: (n,) their rates, per s.
            U: (3,) free stream, m/s, global frame.
            density: air density, kg/m^3.
            direction: (3,) unit free-stream direction, global frame (defined also when |U| = 0).
        """

    def vortex_geometry(self, state, direction: np.ndarray) -> dict:
        """The vortex system of `state` for pictures (`UVLM.vortex_geometry`).

        Args:
            state: the model's state.
            direction: (3,) unit free-stream direction, global frame.
        """


def _uvlm(wake):
    return lambda topology, aero, max_wake_rows: UVLM(topology, aero.chordwise_panels, aero.spanwise_panels,
                                                      wake=wake, wake_length=aero.wake_length,
                                                      max_wake_rows=max_wake_rows,
                                                      wake_opening=(aero.wake_opening
                                                                    if aero.wake_far_field == "treecode" else None))


MODELS = {
    "strip": lambda topology, aero, max_wake_rows: StripTheory(topology, aero.spanwise_panels, aero.span_correction),
    "uvlm-flat": _uvlm(FLAT),
    "uvlm-prescribed": _uvlm(PRESCRIBED),
    "uvlm-free": _uvlm(FREE),
}
"""aero.model -> (topology, AeroSpec, max_wake_rows) -> AerodynamicModel."""


def build_model(topology, aero: AeroSpec, max_wake_rows: int) -> AerodynamicModel:
    """The model aero.model selects; SceneError naming aero.model for one that builds no aero unit.

    Args:
        topology: the aero unit's topology.
        aero: the aero table (panels, wake length, span correction).
        max_wake_rows: cap of shed wake rows.
    """
    name = aero.model.name
    if name not in MODELS:
        raise SceneError("aero.model", name, f"an aero model of the aero unit: one of {', '.join(map(repr, MODELS))}")
    return MODELS[name](topology, aero, max_wake_rows)
