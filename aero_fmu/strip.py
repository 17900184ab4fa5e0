"""Quasi-steady strip theory: the cheapest aero model (aero.model = "strip"), same interface as the UVLM.

Each body is cut into N spanwise strips (aero.spanwise_panels; the chordwise panel count is not used).
Strip j uses the one-panel lattice (`Lattice(topology, 1, N)`): its "collocation" point at 3/4 chord and
mid-strip span, where the relative flow is taken, and its "application" point at 1/4 chord, where the
force acts. With V_rel = U - r'(3/4 chord) (the flow relative to the section, docs/aero_api.md), n the
section normal (Otsuka et al. 2019, Eq. 21), t_x = r_x / |r_x| the span direction and V_perp = V_rel - (V_rel . t_x) t_x
the flow in the section plane (|V_perp| = |t_x x V_rel|), thin-airfoil theory per strip gives

    sin(alpha_eff) = (V_rel . n) / |V_perp|
    f = 1/2 rho |V_perp|^2 c 2 pi sin(alpha_eff) = pi rho c |V_perp| (V_rel . n)       (N per m of span)

for small alpha_eff the lift per unit span 1/2 rho V^2 c 2 pi alpha_eff. The force is applied along the
section normal n, like the UVLM's panel forces (Otsuka et al. 2019, Eq. 25), so the strip force (N) is

    F_j = pi rho c_j |V_perp| (V_rel . n) Delta s_j n,   c_j = |r_y| c,   Delta s_j = |r_x| L / N
        = pi rho |r_y| c (V_rel . n) |r_x x V_rel| (L / N) n

at the quarter chord; Q by Otsuka et al. 2019, Eq. (12). On a planform (docs/aero.md, Planform) c_j is the
local chord at mid strip, n the normal of the twisted chord line, and a cambered section lifts from its
thin-airfoil zero-lift angle alpha_L0 (fmu_common.airfoil): V_rel . n becomes |V_perp| sin(alpha_eff - alpha_L0)
= cos(alpha_L0) (V_rel . n) - sin(alpha_L0) (V_rel . t), t = n x t_x the unit chord direction toward the
trailing edge (the strips' lattice has the chord lines only).

No division: zero in still air, and a wing moving normal to
itself in still air (alpha_eff = 90 deg, e.g. deployment at 0 m/s) gets a normal force resisting the
motion (2 pi instead of a flat plate's drag coefficient of about 2: the linear theory is outside its
range there), not a chordwise one. The 3/4-chord point carries the pitch-rate effect of quasi-steady
theory; there is no wake, no induced downwash (each strip is 2D) and no apparent mass. For a plate
pitched by alpha in a stream V along the chord C_L = 2 pi sin(alpha) cos(alpha); in plunge h(t) along n,
C_L = -2 pi (h'/V) sqrt(1 + (h'/V)^2).

Finite span (aero.span_correction): each strip is 2D, so on a wing of aspect ratio A the 2 pi lift slope
overestimates the wing's by 1/(finite-span factor). With "helmbold" (the default) every strip force is
scaled by Helmbold's lifting-line lift slope over 2 pi,

    a / (2 pi) = A / (2 + sqrt(A^2 + 4)),   A = b^2 / S,

b the sum of the body lengths (the deployed span of a folding wing) and S the sum of the planform areas. It
tends to 1 for a slender wing (0.998 at A = 1000) and to A / 4 (slender-wing theory, pi A / 2) for a
short one; for a rectangular wing it is within about 7% of our vortex lattice between A = 4 and 8
(docs/aero.md). "none" keeps the 2D slope (the formulas above, exactly).
"""
from dataclasses import dataclass

import numpy as np

from .lattice import Lattice
from .loads import Loads, resultants, zero_loads


def aspect_ratio(topology) -> float:
    """A = b^2 / S of the wing: b the sum of the body lengths (m), S the sum of the planform areas (m^2).

    Args:
        topology: the aero unit's topology.
    """
    bodies = topology.bodies.values()
    span = sum(b.length for b in bodies)
    return span ** 2 / sum(b.planform.area for b in bodies)


def helmbold_factor(aspect: float) -> float:
    """Helmbold's lift slope of a wing of aspect ratio A over the 2D 2 pi: A / (2 + sqrt(A^2 + 4)).

    Args:
        aspect: A, the aspect ratio.
    """
    return aspect / (2.0 + np.sqrt(aspect ** 2 + 4.0))


@dataclass
class StripState:
    """time s; started; loads (loads.Loads)."""
    time: float
    started: bool
    loads: Loads

    def copy(self):
        """A copy that shares no array with this state."""
        return StripState(self.time, self.started, self.loads.copy())


class StripTheory:
    """Quasi-steady strip theory on N strips per body (module docstring).

    Args:
        topology: the aero unit's topology.
        spanwise: N, strips per body.
        span_correction: "helmbold": the lift slope scaled by `helmbold_factor`; any other value: 2 pi.
    """

    def __init__(self, topology, spanwise, span_correction="helmbold"):
        self.topology = topology
        self.lattice = Lattice(topology, 1, spanwise, camber=False)
        alpha0 = self.lattice.zero_lift_angle
        self._camber = (np.cos(alpha0), np.sin(alpha0))
        self.lift_slope_factor = (helmbold_factor(aspect_ratio(topology)) if span_correction == "helmbold"
                                  else 1.0)

    def initial_state(self) -> StripState:
        """The state at rest: time 0, not started, no loads."""
        return StripState(0.0, False, zero_loads(self.lattice, self.topology.n_coordinates))

    def vortex_geometry(self, state: StripState, direction) -> dict:
        """No vortex system: every entry of `UVLM.vortex_geometry` None.

        Args:
            state: the strip state.
            direction: (3,) unit free-stream direction, global frame.
        """
        return {"rings": None, "wake": None, "wake_gamma": None, "legs": None}

    def advance(self, state, t_end, E, dE, U, density, direction) -> StripState:
        """Strip forces at t_end. Memoryless: only the current E, dE matter.

        Args:
            state: the state at the previous time.
            t_end: time to reach, s.
            E: (n,) exchanged coordinates at t_end, m and 1, global frame.
            dE: (n,) their rates, per s.
            U: (3,) free stream, m/s, global frame.
            density: air density, kg/m^3.
            direction: (3,) unit free-stream direction, global frame.
        """
        lat = self.lattice
        geometry = lat.geometry(E)
        relative = U - lat.collocation_matrix @ np.asarray(dE, dtype=float).reshape(-1, 3)    # V_rel (P, 3)
        normal = geometry.normal
        if not lat.flat:      # the section's normal: a twisted surface's normal off the reference line leans spanwise
            span = geometry.r_x / np.sqrt(np.sum(geometry.r_x ** 2, axis=1))[:, None]
            normal = normal - np.sum(normal * span, axis=1)[:, None] * span
            normal /= np.sqrt(np.sum(normal ** 2, axis=1))[:, None]
        chordwise = np.cross(normal, geometry.r_x)                                            # toward the trailing edge
        chordwise /= np.sqrt(np.sum(chordwise ** 2, axis=1))[:, None]
        cos0, sin0 = self._camber                            # |V_perp| sin(alpha_eff - alpha_L0), module docstring
        normal_flow = cos0 * np.sum(relative * normal, axis=1) - sin0 * np.sum(relative * chordwise, axis=1)
        chord = np.sqrt(np.sum(geometry.r_y ** 2, axis=1)) * lat.chord                        # |r_y| c
        in_plane = np.sqrt(np.sum(np.cross(geometry.r_x, relative) ** 2, axis=1))              # |V_perp| |r_x|
        forces = ((self.lift_slope_factor * np.pi * density) * chord * normal_flow * in_plane
                  * lat.panel_span)[:, None] * normal
        loads = resultants(lat, geometry, forces, direction, float(np.linalg.norm(U)), density, 0)
        return StripState(float(t_end), True, loads)
