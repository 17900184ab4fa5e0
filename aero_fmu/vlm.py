"""Steady vortex-lattice method: bound vortex rings and a flat horseshoe wake (Otsuka et al. 2019, Sec. V).

Unknowns are the ring circulations Gamma (n_panels,) m^2/s. Every vortex system is a set of straight
segments whose circulations are linear in Gamma through a sparse +-1 "weights" matrix (segment
circulation = weights @ Gamma); a segment shared by two rings is evaluated once. The pieces:

  * `ring_segments(lattice)`: which corners make each unique bound segment and its incidence; topology
    only, built once.
  * `bound_segments`, `horseshoe_wake`: the segments at one geometry.
  * `influence_matrix`: A[p, q] = n_p . v_q(r_CP,p), the normal wash at collocation point p of ring q
    with unit circulation (Otsuka et al. 2019, Eqs. 19-22). The bound part depends on E only, so a solver keeps it (and,
    with a flat wake, the LU of A) while the geometry does not change; `SteadyVLM` does so.
  * solve A Gamma = -(U . n) (Otsuka et al. 2019, Eq. 22 with zero body velocity);
  * `pressure_forces`: Otsuka et al. 2019, Eq. (23) (its steady part unless dGamma/dt is given) and Eq. (25);
  * `kutta_joukowski_forces`: rho Gamma V x dl on the bound segments, the independent check.

Sign convention: a positive Gamma, with the flow going from the leading to the trailing edge, gives a
force along +n = r_x x r_y (Otsuka et al. 2019, Eq. 25 with Delta p > 0), see `Lattice`.
"""
import math
from dataclasses import dataclass

import numpy as np
import scipy.linalg
import scipy.sparse

from .biot_savart import influence
from .lattice import Lattice


@dataclass(frozen=True)
class Segments:
    """Straight vortex segments: starts (S, 3) m; ends (S, 3) m, or unit directions when semi_infinite;
    weights (S, n_panels) sparse, so that the segment circulations are weights @ Gamma."""
    starts: np.ndarray
    ends: np.ndarray
    weights: object
    semi_infinite: bool = False


@dataclass(frozen=True)
class RingSegments:
    """Unique segments of the bound rings: corner indices start, end (S,); incidence (S, n_panels)
    sparse +-1; trailing (S,) True for the last ring row's trailing segments (a quarter panel behind the
    trailing edge), which the first wake segment cancels in steady flow (Kutta condition)."""
    start: np.ndarray
    end: np.ndarray
    incidence: object
    trailing: np.ndarray


def ring_segments(lattice: Lattice) -> RingSegments:
    """The unique segments of the bound rings and their incidence.

    Spanwise segments (b, i, j) -> (b, i, j+1), i = 0..M, then chordwise (b, i, j) -> (b, i+1, j), j = 0..N, with
    the +-1 incidence of the ring legs (i,j)->(i+1,j)->(i+1,j+1)->(i,j+1)->(i,j).

    Args:
        lattice: the Lattice.
    """
    M, N, B = lattice.M, lattice.N, len(lattice.body_names)
    nc = (M + 1) * (N + 1)
    b, i, j = (a.ravel() for a in np.meshgrid(np.arange(B), np.arange(M + 1), np.arange(N), indexing="ij"))
    span_start, span_end = b * nc + i * (N + 1) + j, b * nc + i * (N + 1) + j + 1
    span_id = lambda bb, ii, jj: (bb * (M + 1) + ii) * N + jj
    n_span = B * (M + 1) * N
    b2, i2, j2 = (a.ravel() for a in np.meshgrid(np.arange(B), np.arange(M), np.arange(N + 1), indexing="ij"))
    chord_start, chord_end = b2 * nc + i2 * (N + 1) + j2, b2 * nc + (i2 + 1) * (N + 1) + j2
    chord_id = lambda bb, ii, jj: n_span + (bb * M + ii) * (N + 1) + jj
    # panels (b, i, j) and their four legs
    bp, ip, jp = (a.ravel() for a in np.meshgrid(np.arange(B), np.arange(M), np.arange(N), indexing="ij"))
    panel = np.arange(len(bp))
    rows = np.concatenate([chord_id(bp, ip, jp), span_id(bp, ip + 1, jp), chord_id(bp, ip, jp + 1),
                           span_id(bp, ip, jp)])
    signs = np.repeat([1.0, 1.0, -1.0, -1.0], len(panel))
    n_segments = n_span + B * M * (N + 1)
    incidence = scipy.sparse.csr_matrix((signs, (rows, np.tile(panel, 4))), shape=(n_segments, len(panel)))
    trailing = np.zeros(n_segments, dtype=bool)
    trailing[:n_span] = i == M
    return RingSegments(np.concatenate([span_start, chord_start]), np.concatenate([span_end, chord_end]),
                        incidence, trailing)


def bound_segments(rings: RingSegments, corners) -> Segments:
    """The bound rings' segments at the corner positions of one geometry.

    Args:
        rings: the RingSegments.
        corners: (n_corners, 3) m, global frame.
    """
    return Segments(corners[rings.start], corners[rings.end], rings.incidence)


def horseshoe_weights(lattice: Lattice):
    """Sparse weights of the horseshoe wake (topology only, built once per lattice).

    Args:
        lattice: the Lattice.

    Returns:
        (legs, span, -span): legs (B (N+1), n_panels) maps Gamma to the trailing legs from the trailing corners,
        span (B N, n_panels) to the spanwise closing segments of finite legs, -span to the horseshoes' bound
        segments.
    """
    B, N, n_p = len(lattice.body_names), lattice.N, lattice.n_panels
    panels = lattice.trailing_panels                        # (B, N)
    # column j of wake "rings": legs (M, j) -> far_j (+1), far_j -> far_{j+1} (+1), (M, j+1) -> far_{j+1}
    # reversed (-1), and the bound segment (M, j+1) -> (M, j), i.e. -1 on (M, j) -> (M, j+1)
    leg_rows = np.concatenate([np.arange(B * (N + 1)).reshape(B, N + 1)[:, :-1].ravel(),
                               np.arange(B * (N + 1)).reshape(B, N + 1)[:, 1:].ravel()])
    leg_cols = np.concatenate([panels.ravel(), panels.ravel()])
    leg_signs = np.repeat([1.0, -1.0], B * N)
    legs = scipy.sparse.csr_matrix((leg_signs, (leg_rows, leg_cols)), shape=(B * (N + 1), n_p))
    span = scipy.sparse.csr_matrix((np.ones(B * N), (np.arange(B * N), panels.ravel())), shape=(B * N, n_p))
    return legs, span, -span


def leg_ends(lattice: Lattice, heads, direction, wake_length):
    """Far ends of finite horseshoe legs: wake_length chords of their body along the free stream.

    Args:
        lattice: the Lattice.
        heads: (B, N + 1, 3) the trailing corners, m, global frame.
        direction: (3,) unit free-stream direction (an array), global frame.
        wake_length: chords.

    Returns:
        (B, N + 1, 3) m, global frame.
    """
    return heads + (wake_length * lattice.body_chords)[:, None, None] * direction


def horseshoe_wake(lattice: Lattice, corners, direction, wake_length=np.inf) -> list:
    """Flat wake: a horseshoe behind each trailing-edge ring, with that ring's circulation.

    Otsuka et al. 2019, Sec. V

    The legs start at the last rings' trailing corners (a quarter panel behind the trailing edge) and run
    along the unit `direction` (the free stream) for wake_length chords of their body, closed there by a
    starting-vortex segment; wake_length = inf gives semi-infinite legs and no closing segment. The
    horseshoe's bound segment runs opposite to the last ring's trailing segment, so the two cancel: the
    circulation leaves the trailing edge only through the legs (steady Kutta condition).

    Args:
        lattice: the Lattice.
        corners: (n_corners, 3) m, global frame.
        direction: (3,) unit free-stream direction, global frame.
        wake_length: chords (inf: semi-infinite legs).

    Returns:
        a list of Segments.
    """
    d = np.asarray(direction, dtype=float)
    legs, span, bound = horseshoe_weights(lattice)
    te = corners[lattice.trailing_corners]                  # (B, N+1, 3)
    te_start, te_end = te[:, :-1].reshape(-1, 3), te[:, 1:].reshape(-1, 3)
    out = [Segments(te_start, te_end, bound)]
    starts = te.reshape(-1, 3)
    if np.isinf(wake_length):
        out.append(Segments(starts, np.broadcast_to(d, starts.shape), legs, semi_infinite=True))
    else:
        far = leg_ends(lattice, te, d, wake_length)
        out.append(Segments(starts, far.reshape(-1, 3), legs))
        out.append(Segments(far[:, :-1].reshape(-1, 3), far[:, 1:].reshape(-1, 3), span))
    return out


def influence_matrix(points, normals, systems, core) -> np.ndarray:
    """A: normal wash n_p . v at `points` per unit ring circulation, summed over the vortex systems.

    Otsuka et al. 2019, Eqs. 19, 22

    Args:
        points: (P, 3) m, global frame.
        normals: (P, 3) unit normals, global frame.
        systems: the vortex systems (Segments).
        core: vortex core radius (m), see biot_savart.py.

    Returns:
        (P, n_panels) 1/m.
    """
    return sum(influence(points, s.starts, s.ends, s.weights, core, s.semi_infinite, normals) for s in systems)


def induced_velocity(points, systems, gamma, core) -> np.ndarray:
    """Velocity induced at points by the vortex systems with ring circulations gamma.

    Args:
        points: (P, 3) m, global frame.
        systems: the vortex systems (Segments).
        gamma: (n_panels,) m^2/s.
        core: vortex core radius, m.

    Returns:
        (P, 3) m/s, global frame.
    """
    return sum(influence(points, s.starts, s.ends, s.weights @ gamma[:, None], core, s.semi_infinite)[:, :, 0]
               for s in systems)


def pressure_forces(lattice: Lattice, geometry, gamma, velocity, density, dgamma_dt=None) -> np.ndarray:
    """Panel forces from the fluid velocity relative to each panel. See `pressure_jump_forces`.

    Otsuka et al. 2019, Eqs. 23, 25

    Args:
        lattice: the Lattice.
        geometry: its Geometry.
        gamma: (n_panels,) m^2/s.
        velocity: (n_panels, 3) V, the fluid velocity relative to the panel at its collocation point, m/s, global
            frame.
        density: kg/m^3.
        dgamma_dt: (n_panels,) m^2/s^2, or None (steady).

    Returns:
        (n_panels, 3) panel forces a, N, global frame.
    """
    v_s = np.sum(velocity * geometry.span_weight, axis=1)
    v_c = np.sum(velocity * geometry.chord_weight, axis=1)
    return pressure_jump_forces(lattice, geometry, gamma, v_s, v_c, density, dgamma_dt)


def pressure_jump_forces(lattice: Lattice, geometry, gamma, v_s, v_c, density, dgamma_dt=None) -> np.ndarray:
    """Panel forces from the tangential velocity products.

    Otsuka et al. 2019, Eqs. 23, 25

    Delta p_ij = rho [V . (tau_x (G_ij - G_i,j-1) / Delta x + tau_y (G_ij - G_i-1,j) / Delta y) + dG_ij/dt]
    with V the fluid velocity relative to the panel at its collocation point, tau the unit tangents
    (Eq. 24), Delta x, Delta y the panel's span and chord lengths, G_i,-1 = G_-1,j = 0 at the body's root edge
    and leading edge; a = Delta p * area * n (Eq. 25). On a panel that is not a rectangle (taper, sweep, twist,
    camber) the same jump is the normal part of the Kutta-Joukowski force rho V x (sum of the panel's edge
    vortices): with l_c its chordwise and l_s its spanwise (bound) edge,

        Delta p * area = rho [(G_ij - G_i,j-1) V . (l_c x n) + (G_ij - G_i-1,j) V . (n x l_s)] + rho dG_ij/dt area,

    which on a rectangle (l_c = Delta y tau_y, l_s = Delta x tau_x) is Eq. 23 times the area:
    l_c x n = Delta y tau_x, n x l_s = Delta x tau_y. Geometry.span_weight = l_c x n, chord_weight = n x l_s.

    Args:
        lattice: the Lattice.
        geometry: its Geometry.
        gamma: (n_panels,) m^2/s.
        v_s: (n_panels,) V . span_weight, m^2/s.
        v_c: (n_panels,) V . chord_weight, m^2/s.
        density: kg/m^3.
        dgamma_dt: (n_panels,) m^2/s^2, or None (steady).

    Returns:
        (n_panels, 3) panel forces a, N, global frame.
    """
    M, N = lattice.M, lattice.N
    G = np.asarray(gamma, dtype=float).reshape(-1, M, N)
    dG_span, dG_chord = G.copy(), G.copy()                 # G_ij - G_i,j-1 and G_ij - G_i-1,j
    dG_span[:, :, 1:] -= G[:, :, :-1]
    dG_chord[:, 1:] -= G[:, :-1]
    jump = density * (v_s * dG_span.ravel() + v_c * dG_chord.ravel())          # Delta p * area, N
    if dgamma_dt is not None:
        jump = jump + density * np.asarray(dgamma_dt, dtype=float) * geometry.area
    return jump[:, None] * geometry.normal


def kutta_joukowski_forces(segments: Segments, gamma_segments, velocity, density) -> np.ndarray:
    """Force rho Gamma_s V_s x (b_s - a_s) on each finite segment.

    Args:
        segments: the Segments.
        gamma_segments: (S,) their circulations, m^2/s.
        velocity: (S, 3) V_s at each segment's middle, m/s, global frame.
        density: kg/m^3.

    Returns:
        (S, 3) N, global frame.
    """
    dl = segments.ends - segments.starts
    return density * np.asarray(gamma_segments)[:, None] * np.cross(velocity, dl)


def lift_axis(geometry, flow_velocity) -> np.ndarray:
    """Unit lift direction: the area-weighted mean normal without its component along the free stream.

    Args:
        geometry: the lattice's Geometry.
        flow_velocity: (3,) free stream, m/s, global frame.

    Returns:
        (3,) global frame.
    """
    return lift_direction(geometry.area @ geometry.normal, flow_velocity)


def lift_direction(area_normal, flow_velocity) -> np.ndarray:
    """Unit lift direction from the area-weighted normal sum_p area_p n_p (`lift_axis`).

    Args:
        area_normal: (3,) sum_p area_p n_p, m^2, global frame.
        flow_velocity: (3,) free stream, m/s, global frame.

    Returns:
        (3,) global frame.
    """
    # on three Python floats: a dozen numpy calls on (3,) arrays would cost more than the arithmetic
    n = np.asarray(area_normal, dtype=float).tolist()
    u = _unit_floats(np.asarray(flow_velocity, dtype=float).tolist())
    if u is not None:
        along = n[0] * u[0] + n[1] * u[1] + n[2] * u[2]
        n = [n[i] - along * u[i] for i in range(3)]
    axis = _unit_floats(n)
    return np.zeros(3) if axis is None else np.array(axis)   # zero only if the flow is normal to the whole wing


def _unit_floats(v):
    """v / |v| for three floats, None if |v| is 0 or not finite (`_unit`)."""
    norm = math.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
    return [x / norm for x in v] if norm > 0 and math.isfinite(norm) else None


def _unit(v):
    norm = float(np.sqrt(np.dot(v, v)))
    return v / norm if norm > 0 and np.isfinite(norm) else None


@dataclass(frozen=True)
class SteadySolution:
    """CL (-), lift (N), gamma (n_panels,) m^2/s, forces (n_panels, 3) N at the application points,
    velocity (n_panels, 3) m/s at the collocation points (free stream + induced), geometry, and the
    vortex systems [bound, *wake] (Segments)."""
    CL: float
    lift: float
    gamma: np.ndarray
    forces: np.ndarray
    velocity: np.ndarray
    geometry: object
    systems: list


class SteadyVLM:
    """Steady VLM of one topology with a flat horseshoe wake.

    Keeps the bound influence matrix per geometry and the LU of the full matrix per (geometry, wake direction).

    Args:
        topology: the aero unit's topology.
        chordwise: M, panels per body along the chord.
        spanwise: N, panels per body along the span.
        wake_length: chords (inf: semi-infinite legs).
        lattice: a Lattice to use (None: built from the topology).
    """

    def __init__(self, topology, chordwise, spanwise, wake_length=np.inf, lattice=None):
        self.lattice = lattice or Lattice(topology, chordwise, spanwise)
        self.rings = ring_segments(self.lattice)
        self.wake_length = float(wake_length)
        self._bound = (None, None)    # (E bytes, (geometry, bound segments, A_bound))
        self._full = (None, None)     # ((E bytes, direction bytes), (wake systems, LU))

    def bound_part(self, E):
        """The bound part at E, recomputed only when E changes.

        Args:
            E: (n,) exchanged coordinates, m and 1, global frame.

        Returns:
            (geometry, bound segments, A_bound).
        """
        E = np.asarray(E, dtype=float)
        key = E.tobytes()
        if self._bound[0] != key:
            geometry = self.lattice.geometry(E)
            bound = bound_segments(self.rings, geometry.corners)
            A = influence_matrix(geometry.collocation, geometry.normal, [bound], self.lattice.core_radius)
            self._bound = (key, (geometry, bound, A))
        return self._bound[1]

    def _factorized(self, E, direction):
        """(wake segments, LU of A_bound + A_wake) at E for the wake `direction`, cached."""
        geometry, _, A_bound = self.bound_part(E)
        key = (np.asarray(E, dtype=float).tobytes(), direction.tobytes())
        if self._full[0] != key:
            wake = horseshoe_wake(self.lattice, geometry.corners, direction, self.wake_length)
            A = A_bound + influence_matrix(geometry.collocation, geometry.normal, wake, self.lattice.core_radius)
            self._full = (key, (wake, scipy.linalg.lu_factor(A, check_finite=False)))
        return self._full[1]

    def solve(self, E, flow_velocity, density, lift_direction=None) -> SteadySolution:
        """Circulations, panel forces and C_L = lift / (q S), S the reference area; C_L = 0 at zero dynamic pressure.

        Otsuka et al. 2019, Eqs. 22, 23 (steady part), 25

        Args:
            E: (n,) exchanged coordinates, m and 1, global frame.
            flow_velocity: (3,) free stream, m/s, global frame.
            density: kg/m^3.
            lift_direction: (3,) unit lift direction, or None for `lift_axis`.

        Returns:
            the SteadySolution.
        """
        U = np.asarray(flow_velocity, dtype=float)
        geometry, bound, _ = self.bound_part(E)
        direction = _unit(U)
        if direction is None:   # still air: the wake direction is immaterial (Gamma = 0); use the chord
            direction = _unit(geometry.area @ geometry.r_y)
        wake, lu = self._factorized(E, direction)
        gamma = scipy.linalg.lu_solve(lu, -(geometry.normal @ U), check_finite=False)
        systems = [bound, *wake]
        velocity = U + induced_velocity(geometry.collocation, systems, gamma, self.lattice.core_radius)
        forces = pressure_forces(self.lattice, geometry, gamma, velocity, density)
        axis = lift_axis(geometry, U) if lift_direction is None else _unit(np.asarray(lift_direction, float))
        lift = float(np.sum(forces @ axis))
        q = 0.5 * density * float(U @ U)
        CL = lift / (q * self.lattice.reference_area) if q > 0 else 0.0
        return SteadySolution(CL, lift, gamma, forces, velocity, geometry, systems)

    def segment_forces(self, solution, flow_velocity, density):
        """Kutta-Joukowski forces rho Gamma_s V_s x dl_s on the bound segments of a solution.

        The independent check of Otsuka et al. 2019, Eq. 23.

        Net circulation per segment (the trailing row is cancelled by the wake's bound segment), V_s = U + induced
        velocity at the segment middle (the vortex core makes a segment's own and its collinear neighbours'
        contributions zero there).

        Args:
            solution: a SteadySolution of `solve`.
            flow_velocity: (3,) free stream, m/s, global frame.
            density: kg/m^3.

        Returns:
            (S, 3) N, global frame.
        """
        bound = solution.systems[0]
        gamma_s = self.rings.incidence @ solution.gamma
        gamma_s[self.rings.trailing] = 0.0
        middle = 0.5 * (bound.starts + bound.ends)
        V = np.asarray(flow_velocity, float) + induced_velocity(middle, solution.systems, solution.gamma,
                                                                self.lattice.core_radius)
        return kutta_joukowski_forces(bound, gamma_s, V, density)


def steady_lift(topology, E, M, N, flow_velocity, density, wake_length=np.inf):
    """The steady VLM with a flat horseshoe wake. See `SteadyVLM.solve`.

    Args:
        topology: the aero unit's topology.
        E: (n,) exchanged coordinates, m and 1, global frame.
        M: panels per body along the chord.
        N: panels per body along the span.
        flow_velocity: (3,) free stream, m/s, global frame.
        density: kg/m^3.
        wake_length: chords (inf: semi-infinite legs).

    Returns:
        (C_L, Gamma (n_panels,) m^2/s, panel forces (n_panels, 3) N).
    """
    s = SteadyVLM(topology, M, N, wake_length).solve(E, flow_velocity, density)
    return s.CL, s.gamma, s.forces
