"""Unsteady vortex-lattice method (Otsuka et al. 2019, Sec. V; Katz & Plotkin, Low-Speed Aerodynamics, Sec. 13.8).

One call `UVLM.advance(state, t_end, E, dE, U, rho, d)` gives the aero state at t_end for the structure's
coordinates E and rates dE at t_end (one aero time step from state.time):

  1. geometry of the rings from the fixed shape matrices: one matrix product (Otsuka et al. 2019, Eqs. 20, 21, 24);
     body velocities at the collocation points r' = S(x_CP, y_CP) dE (the same matrix);
  2. wake: shed and convected (`wake.py`) or flat horseshoes (no state);
  3. no penetration (Otsuka et al. 2019, Eq. 22 with the relative flow, docs/aero_api.md):
        A Gamma = -(U + w_wake - r') . n
     w_wake from the shed wake's segments with the vortex core wake.WAKE_CORE_FRACTION x the smallest
     panel dimension (its head row, lying on the bound trailing segments, with the bound core);
     A holds the bound rings (and, for the flat wake, the horseshoes); it and its LU are reused while
     the lattice moves rigidly (`factorization.BoundSystem`);
  4. pressure jump (Otsuka et al. 2019, Eq. 23) with V = U + w - r' at the collocation point (w induced by bound rings
     and wake), dGamma/dt by the second-order backward difference of Gamma(t_n), Gamma(t_{n-1}),
     Gamma(t_{n-2}) (`circulation_rate`; first order on the step after the start), panel forces
     (Eq. 25) at the rings' bound-segment midpoints, Q by Eq. (12) (`loads.py`).

Why second order: the dGamma/dt term is not small in Eq. (23) (for a heaving plate about 0.75 x 2k of
the rho V Gamma term), and the first-order difference lags it by omega dt / 2. Measured on the Otsuka et al. 2019
VI.D heaving wing (M = 10, dt = c/(MV)), C_L amplitude error against Theodorsen: k = 0.25: 1.75% first
order, 0.85% second order; k = 0.5: 6.1% and 3.1%; Wagner at s = 1: +6.1% and +4.1%.

Time convention. The first call is the start of the motion (an impulsive start at its t_end): no wake
yet (a shed-wake model has only the bound rings; the flat model its horseshoes) and dGamma/dt = 0 (the
delta-function impulse of a sudden start is not resolved by any step). A later call with t_end > time
takes a step; a call with t_end == time repeats the last step for new E, dE (the wake keeps its rows,
its head row follows the trailing edge, dGamma/dt uses the same earlier circulations and steps).

Wake models (`wake` argument, a WakeModel; aero.model uvlm-prescribed, uvlm-free, uvlm-flat, aero_fmu.models):
  PRESCRIBED: shed rings convected with U;  FREE: convected with U + w;  FLAT: no shed vorticity.

The flat wake (Otsuka et al. 2019, Sec. V) and its closed form. Each trailing-edge ring carries a horseshoe along the
free-stream direction, L_w chords long (closed by a segment there) or semi-infinite. The bound
circulation is quasi-steady: the steady solution for the instantaneous relative normal flow, with no
memory of earlier circulation; the unsteadiness enters only through dGamma/dt in Eq. (23). For a 2D
flat plate (aspect ratio -> inf, semi-infinite legs) in plunge h(t) along its normal n (the lift
direction), at zero incidence in a stream V along the chord:
  * the relative normal flow is uniform, w0 = -dh/dt, so the bound circulation is the thin-airfoil one,
    total Gamma = pi c w0, and the ring lattice reproduces it exactly for any M (vortex at 1/4, control
    point at 3/4 of each panel); the lumped vortices also have their exact centroid c/4;
  * Eq. (23) summed over the chord gives the lift per unit span
        L' = rho V Gamma + rho sum_i (dGamma_i/dt) c/M,   sum_i Gamma_i c/M = (3/4 + 1/(4M)) c Gamma
    (Gamma_i = sum_{k<=i} g_k, the vortex g_k at x_k = (k + 1/4) c/M: sum_k g_k (c - x_k + c/(4M)),
    with sum_k g_k x_k = Gamma c/4), so
        L' = -pi rho V c dh/dt - (3/4 + 1/(4M)) pi rho c^2 d2h/dt2,
  * for h = h0 sin(omega t), k = omega c / (2 V), in complex form h = h0 e^{i omega t}:
        C_L = (h0 / c) [ -4 pi i k + (6 + 2/M) pi k^2 ] e^{i omega t}
    i.e. Theodorsen's C_L = (h0 / c) [ -4 pi i k C(k) + 2 pi k^2 ] e^{i omega t} with C(k) = 1 (no wake
    lag) and an apparent-mass term (3 + 1/M) times Theodorsen's (M -> inf: 3 times). The discrete
    dGamma/dt (second-order backward difference) changes the k^2 term by O((omega dt)^2).
"""
import math
from dataclasses import dataclass

import numpy as np
from scipy.linalg.lapack import dgetrs

from . import wake as wakes
from .factorization import BoundSystem
from .flat_wake_step import FlatWakeStep, c_kernels
from .lattice import Lattice
from .loads import Loads, resultant_outputs, resultants, zero_loads
from .vlm import lift_direction, pressure_jump_forces, ring_segments

@dataclass(frozen=True)
class WakeModel:
    """How a UVLM represents its wake: `shed`, a ring row shed at each step and convected (else horseshoe legs
    from the trailing edge along U, flat, with the quasi-steady circulation); `free`, a shed wake's corners
    convected with the local velocity U + w (else with U). aero.model uvlm-flat, uvlm-prescribed, uvlm-free
    (aero_fmu.models)."""

    shed: bool
    free: bool


FLAT, PRESCRIBED, FREE = WakeModel(shed=False, free=False), WakeModel(shed=True, free=False), WakeModel(True, True)


@dataclass
class UVLMState:
    """time s; started; gamma (n_panels,) m^2/s at time; history: the circulations at the two previous step
    times (t_{n-1}, t_{n-2}) and the steps (t_n - t_{n-1}, t_{n-1} - t_{n-2}) s (0: none); corners
    (n_corners, 3) m of the rings at time; wake (wake.ShedWake or None); loads (loads.Loads)."""
    time: float
    started: bool
    gamma: np.ndarray
    history: tuple
    steps: tuple
    corners: np.ndarray
    wake: object
    loads: Loads

    def copy(self):
        """A copy that shares no array with this state."""
        return UVLMState(self.time, self.started, self.gamma.copy(), tuple(g.copy() for g in self.history),
                         tuple(self.steps), self.corners.copy(), None if self.wake is None else self.wake.copy(),
                         self.loads.copy())


def circulation_rate(gamma, history, steps):
    """dGamma/dt at t_n from Gamma(t_n) and the two previous circulations.

    The derivative of the quadratic through the three (second-order backward difference, variable steps; 3/2, -2,
    1/2 over h for equal steps), the first-order difference if h2 = 0.

    Args:
        gamma: (n_panels,) Gamma(t_n), m^2/s.
        history: (Gamma(t_{n-1}), Gamma(t_{n-2})), each (n_panels,) m^2/s.
        steps: (h1, h2) = (t_n - t_{n-1}, t_{n-1} - t_{n-2}), s.

    Returns:
        (n_panels,) m^2/s^2, or None if h1 = 0 (no previous step).
    """
    (g1, g2), (order, c) = history, rate_coefficients(steps)
    if order == 0:
        return None
    if order == 1:
        return (gamma - g1) / c[0]
    return gamma * c[0] - g1 * c[1] + g2 * c[2]


def rate_coefficients(steps):
    """The order and coefficients of `circulation_rate`'s difference, shared with the compiled step
    (FlatWakeStep.solve's `rate`).

    Args:
        steps: (h1, h2) = (t_n - t_{n-1}, t_{n-1} - t_{n-2}), s.

    Returns:
        (0, None) if h1 = 0; (1, (h1, 0, 0)): (Gamma_n - Gamma_{n-1}) / h1; (2, (c0, c1, c2)) in 1/s:
        c0 Gamma_n - c1 Gamma_{n-1} + c2 Gamma_{n-2}.
    """
    h1, h2 = steps
    if h1 <= 0:
        return 0, None
    if h2 <= 0:
        return 1, (h1, 0.0, 0.0)
    return 2, ((2 * h1 + h2) / (h1 * (h1 + h2)), (h1 + h2) / (h1 * h2), h1 / (h2 * (h1 + h2)))


class UVLM:
    """UVLM of a topology: M chordwise x N spanwise rings per body.

    The solver itself is stateless apart from the reusable factorization.

    Args:
        topology: the aero unit's topology.
        chordwise: M, rings per body along the chord.
        spanwise: N, rings per body along the span.
        wake: the WakeModel (FLAT, PRESCRIBED or FREE).
        wake_length: truncation of the wake, chords (inf: never; flat: semi-infinite legs).
        max_wake_rows: at most this many shed rows.
        wake_opening: the treecode opening parameter of the free wake's convection (wake.segment_sum), or None:
            exact sums.
    """

    def __init__(self, topology, chordwise, spanwise, wake=PRESCRIBED, wake_length=np.inf,
                 max_wake_rows=wakes.MAX_WAKE_ROWS, wake_opening=None):
        self.topology = topology
        self.lattice = Lattice(topology, chordwise, spanwise)
        self.rings = ring_segments(self.lattice)
        self.wake_model = wake
        self.wake_length = float(wake_length)
        self.max_wake_rows = int(max_wake_rows)
        self.wake_opening = wake_opening if wake.free else None
        self.system = BoundSystem(self.lattice, self.rings, flat_wake=not wake.shed, wake_length=wake_length)
        # the flat wake's step in one compiled call (flat_wake_step.py) unless $WINGSIM_KERNELS=numpy; the numpy
        # path below is its reference
        kernels = None if wake.shed else c_kernels()
        if kernels is not None:
            self.system = FlatWakeStep(self.lattice, self.system, kernels)
        lat = self.lattice
        smallest = float(min(lat.panel_span.min(), lat.panel_chord.min()))
        self.convection_core = wakes.CONVECTION_CORE_FRACTION * smallest
        self.wake_core = wakes.WAKE_CORE_FRACTION * smallest

    def initial_state(self) -> UVLMState:
        """The state at rest: time 0, not started, zero circulation, no wake."""
        n, lat = self.lattice.n_panels, self.lattice
        return UVLMState(0.0, False, np.zeros(n), (np.zeros(n), np.zeros(n)), (0.0, 0.0),
                         np.zeros((lat.n_corners, 3)), None, zero_loads(lat, self.topology.n_coordinates))

    # ------------------------------------------------------------------ one call
    def advance(self, state: UVLMState, t_end, E, dE, U, density, direction) -> UVLMState:
        """The state at t_end (see the module docstring).

        Args:
            state: the state at the previous time (unchanged).
            t_end: time to reach, s.
            E: (n,) exchanged coordinates at t_end, m and 1, global frame.
            dE: (n,) their rates, per s.
            U: (3,) the free stream, m/s, global frame.
            density: air density, kg/m^3.
            direction: (3,) the unit free-stream direction (the flat wake's legs, the drag axis; defined also when
                |U| = 0), global frame.
        """
        lat = self.lattice
        dt = float(t_end) - state.time
        n = lat.n_panels
        if not state.started:
            history, steps = (np.zeros(n), np.zeros(n)), (0.0, 0.0)
        elif dt > 0:
            history, steps = (state.gamma, state.history[0]), (dt, state.steps[0])
        else:
            history, steps = state.history, state.steps
        if isinstance(self.system, FlatWakeStep):
            return self._compiled_flat_step(t_end, E, dE, U, density, direction, history, steps)
        geometry = lat.geometry(E)
        wake = None
        if self.wake_model.shed:
            head = geometry.corners[lat.trailing_corners]                        # (B, N + 1, 3)
            if not state.started:
                wake = wakes.ShedWake.empty(head)
            elif dt > 0:
                wake = wakes.shed(state.wake, head, state.gamma[lat.trailing_panels],
                                  self._displacement(state, U, dt))
            else:
                wake = wakes.with_head(state.wake, head)
            wake = wakes.truncate(wake, self.wake_length * lat.body_chords, self.max_wake_rows)
        gamma, forces = self._solve(geometry, dE, U, density, direction, wake, history, steps)
        wake_panels = lat.N * len(lat.body_names) if wake is None else wake.n_panels
        loads = resultants(lat, geometry, forces, direction, math.sqrt(float(U @ U)), density, wake_panels)
        return UVLMState(float(t_end), True, gamma, tuple(np.array(g) for g in history),
                         tuple(float(h) for h in steps), geometry.corners, wake, loads)

    def _compiled_flat_step(self, t_end, E, dE, U, density, direction, history, steps) -> UVLMState:
        """`advance` of the flat wake in one compiled call (flat_wake_step.py): the same state as the numpy path
        to round-off."""
        step, lat = self.system, self.lattice
        order, coefficients = rate_coefficients(steps)
        step.solve(E, dE, U, direction, density, None if order == 0 else (coefficients, order, history))
        sums = step.sums
        outputs = resultant_outputs(lat, sums[:3], sums[3:12].reshape(3, 3), lift_direction(sums[12:], direction),
                                    direction, math.sqrt(float(U @ U)), density, lat.N * len(lat.body_names))
        loads = Loads(step.forces.copy(), step.application.copy(), step.Q.copy(), outputs)
        return UVLMState(float(t_end), True, step.gamma.copy(), tuple(np.array(g) for g in history),
                         tuple(float(h) for h in steps), step.corners.copy(), None, loads)

    def vortex_geometry(self, state: UVLMState, direction) -> dict:
        """The vortex system of `state` for pictures (arrays copied; m, global frame).

        Args:
            state: the UVLM state.
            direction: (3,) unit free-stream direction, global frame.

        Returns:
            {"rings": the bound ring corners (B, M + 1, N + 1, 3), "wake", "wake_gamma": a shed wake's corners and
            circulations (m^2/s), "legs": the flat wake's (unit `direction` (3,), length (B,) m)}; None where there is
            none (before the first step: all).
        """
        out = {"rings": None, "wake": None, "wake_gamma": None, "legs": None}
        if not state.started:
            return out
        lat = self.lattice
        out["rings"] = state.corners.reshape(len(lat.body_names), lat.M + 1, lat.N + 1, 3).copy()
        if state.wake is not None:
            out["wake"], out["wake_gamma"] = state.wake.corners.copy(), state.wake.gamma.copy()
        if not self.wake_model.shed:
            out["legs"] = (direction.copy(), self.wake_length * lat.body_chords)
        return out

    def _displacement(self, state, U, dt):
        """Corner displacements over the step: U dt (prescribed) or (U + w) dt with w at t_{n-1} (free)."""
        if not self.wake_model.free:
            return U * dt
        points = state.wake.corners.reshape(-1, 3)
        # bound rings and wake share the convection core: one sum over the segments of both
        bound = self._bound_segments(state.corners, self.rings.incidence @ state.gamma)
        starts, ends, circulation = (np.concatenate(parts) for parts in zip(bound, wakes.live_segments(state.wake)))
        w = wakes.segment_sum(points, starts, ends, circulation, self.convection_core, self.wake_opening)
        return (U + w).reshape(state.wake.corners.shape) * dt

    def _bound_segments(self, corners, circulation):
        """(starts (S, 3), ends (S, 3), circulations (S,)) of the bound rings' unique segments that carry a
        circulation, from the ring corners (n_corners, 3) and the unique-segment circulations incidence @ Gamma."""
        live = circulation != 0.0
        return corners[self.rings.start[live]], corners[self.rings.end[live]], circulation[live]

    def _solve(self, geometry, dE, U, density, direction, wake, history, steps):
        """Gamma (Otsuka et al. 2019, Eq. 22) and the panel forces (Eqs. 23, 25)."""
        lat = self.lattice
        A_x, A_y, lu = self.system.matrices(geometry, direction)
        relative = U - lat.collocation_matrix @ np.asarray(dE, dtype=float).reshape(-1, 3)   # U - r'
        if wake is not None:
            relative = relative + wakes.velocity(geometry.collocation, wake, self.wake_core, lat.core_radius)
        rhs = -np.einsum("ij,ij->i", relative, geometry.normal)
        gamma = dgetrs(*lu, rhs)[0]                          # LAPACK directly (lu from factorization.BoundSystem)
        v_x = np.einsum("ij,ij->i", relative, geometry.span_weight) + A_x @ gamma    # V . (l_c x n), V = U + w - r'
        v_y = np.einsum("ij,ij->i", relative, geometry.chord_weight) + A_y @ gamma   # V . (n x l_s)
        rate = circulation_rate(gamma, history, steps)
        return gamma, pressure_jump_forces(lat, geometry, gamma, v_x, v_y, density, rate)
