"""Shed vortex-ring wakes (Otsuka et al. 2019, Sec. V; Katz & Plotkin, Low-Speed Aerodynamics, Sec. 13.8): state and
vectorized kernels. The flat (horseshoe) wake has no state: see `factorization.BoundSystem`.

Layout. Each of the B bodies sheds N columns of rings from its trailing edge. `ShedWake.corners`
(B, R + 1, N + 1, 3) m holds R + 1 corner rows: row 0 is the head, on the trailing segment of the last
bound ring row (a quarter panel behind the trailing edge, `lattice.Lattice`), row r + 1 the back edge of
wake ring r; `gamma` (B, R, N) m^2/s the ring circulations, ring 0 the newest. Rings circulate like the
bound rings, (r, j) -> (r+1, j) -> (r+1, j+1) -> (r, j+1), so a shed ring continues its bound ring.

Kutta condition and shedding (one step t_{n-1} -> t_n): the wake is convected (all rows, including the
head), then a new ring is put in front, between the current trailing segment and the convected old head,
carrying the circulation of its trailing-edge bound ring at t_{n-1}. The net vortex on the trailing
segment is then Gamma_TE(t_n) - Gamma_TE(t_{n-1}): the vorticity shed during the step, a quarter panel
behind the trailing edge; in steady flow it vanishes (the steady Kutta condition).

Convection: `uvlm-prescribed` moves every corner with the free stream U (the wake stays flat and rigid);
`uvlm-free` with the local velocity U + w, w induced by the bound rings and the wake at t_{n-1} (explicit
Euler), evaluated with the larger vortex core CONVECTION_CORE_FRACTION x the smallest panel dimension so
that rolled-up corners near other segments get smooth velocities.

Vortex cores (Scully, biot_savart.py). At the collocation points the wake's segments use the core
WAKE_CORE_FRACTION x the smallest panel dimension, except the head row, which lies on the bound trailing
segments and takes the bound core so that the two cancel exactly in steady flow. A wake vortex passing
a collocation point (another body's wake, a wing moving through its own wake at low speed) then induces
at most Gamma / (4 pi delta): the forces stay bounded. The price is a relative change (delta / h)^2 of
a segment's influence at distance h: the steady limit of an AR-4 wing (M = 4) moves by 5.5e-4 in C_L;
2D cases do not change. Smaller cores measured on a wing heaving in still air with the free wake (its
CPs cross its own wake): peak lift 31 N with 0.1, 64 N with 0.05, 12900 N with 0.03 (the apparent-mass
force is 15 N): the wing re-sheds the spikes and the free wake goes chaotic.

Far field (aero.wake_far_field, aero.wake_opening). The free wake's convection velocity sums the O(R N) bound and
wake segments at the R (N + 1) corners: O(R^2) per step, O(R^3) over a run. With an opening parameter theta
`segment_sum` runs the treecode (treecode.py): a cluster of segments far from a corner (radius < theta x distance)
enters by its monopole and dipole, near segments exactly; O(R log R) per step. The velocity at the collocation
points (`velocity`) stays the exact sum: it is O(R) per step, and the loads follow it directly (a velocity error
there is a normal-wash error; at theta = 0.3 it moved the CL of the AR-8 plate by 0.1%, where the convection's
moved it by 1e-6). None: every segment summed exactly (the reference).

Truncation: ring r is kept while its back row is within `wake_length` chords of the head row (largest
Euclidean distance over span stations smaller than the body's L_w c, for any body), at least the newest
ring, at most `max_rows` rings; older rings are dropped (their vorticity leaves the model: the last kept
ring's back segment carries its circulation, as in Otsuka et al. 2019, Sec. VII.A).
"""
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from fmu_common.scene_bounds import MAX_WAKE_ROWS

from . import treecode
from .biot_savart import influence

CONVECTION_CORE_FRACTION = 0.1   # core for free-wake convection, x the smallest reference panel dimension
WAKE_CORE_FRACTION = 0.1         # core of the wake's segments at the collocation points (head row excepted)


@dataclass
class ShedWake:
    """corners (B, R + 1, N + 1, 3) m and gamma (B, R, N) m^2/s; see the module docstring."""
    corners: np.ndarray
    gamma: np.ndarray
    GROWING_AXES: ClassVar[dict] = {"corners": 1, "gamma": 1}   # R grows: a saved wake may have other rows

    @classmethod
    def empty(cls, head):
        """No rings yet: only the head row.

        Args:
            head: (B, N + 1, 3) the trailing segments' corners, m, global frame.
        """
        head = np.asarray(head, dtype=float)
        return cls(head[:, None].copy(), np.zeros((head.shape[0], 0, head.shape[1] - 1)))

    @property
    def n_rows(self):
        """R, the rows of rings shed."""
        return self.gamma.shape[1]

    @property
    def n_panels(self):
        """B R N, the rings of the wake."""
        return self.gamma.size

    def copy(self):
        """A copy that shares no array with this wake."""
        return ShedWake(self.corners.copy(), self.gamma.copy())


def segments(wake: ShedWake):
    """The wake's unique segments.

    Spanwise segment (r, j) -> (r, j+1), r = 0..R: Gamma_{r-1,j} - Gamma_{r,j} (zero outside);
    chordwise segment (r, j) -> (r+1, j), j = 0..N: Gamma_{r,j} - Gamma_{r,j-1} (zero outside).
    `head` marks the spanwise segments of row 0, which lie on the bound trailing segments.

    Args:
        wake: the ShedWake.

    Returns:
        (starts (S, 3) m, ends (S, 3) m, circulations (S,) m^2/s, head (S,) bool), global frame.
    """
    c, g = wake.corners, wake.gamma
    B, R, N = g.shape
    padded = np.zeros((B, R + 2, N))
    padded[:, 1:-1] = g
    span = padded[:, :-1] - padded[:, 1:]                         # (B, R + 1, N)
    padded = np.zeros((B, R, N + 2))
    padded[:, :, 1:-1] = g
    chord = padded[:, :, 1:] - padded[:, :, :-1]                  # (B, R, N + 1)
    starts = np.concatenate([c[:, :, :-1].reshape(-1, 3), c[:, :-1].reshape(-1, 3)])
    ends = np.concatenate([c[:, :, 1:].reshape(-1, 3), c[:, 1:].reshape(-1, 3)])
    head = np.zeros((B, R + 1, N), dtype=bool)
    head[:, 0] = True
    head = np.concatenate([head.ravel(), np.zeros(chord.size, dtype=bool)])
    return starts, ends, np.concatenate([span.ravel(), chord.ravel()]), head


def live_segments(wake: ShedWake):
    """The wake's unique segments (`segments`) that carry a circulation (not, e.g., the inner trailing legs in 2D flow).

    Args:
        wake: the ShedWake.

    Returns:
        (starts (S, 3) m, ends (S, 3) m, circulations (S,) m^2/s), global frame.
    """
    starts, ends, circulation, _ = segments(wake)
    live = circulation != 0.0
    return starts[live], ends[live], circulation[live]


def segment_sum(points, starts, ends, circulation, core, opening=None):
    """Velocity induced at points by finite segments of known circulations, with a Scully core.

    Otsuka et al. 2019, Eq. 19; the far field by the treecode (Barnes and Hut 1986) when `opening` is given.

    Args:
        points: (P, 3) m, global frame.
        starts: (S, 3) m, global frame.
        ends: (S, 3) m, global frame.
        circulation: (S,) m^2/s.
        core: Scully core radius, m.
        opening: the treecode's opening parameter theta in (0, 1), or None: the exact sum over every segment.

    Returns:
        (P, 3) m/s, global frame.
    """
    if opening is None or len(starts) == 0 or len(points) == 0:
        return influence(points, starts, ends, np.asarray(circulation, dtype=float)[:, None], core)[:, :, 0]
    return treecode.velocity(points, treecode.build(starts, ends, circulation), core, opening)[0]


def velocity(points, wake: ShedWake, core, head_core):
    """Velocity induced by the wake at points, with a Scully core.

    Otsuka et al. 2019, Eq. 19

    Args:
        points: (P, 3) m, global frame.
        wake: the ShedWake.
        core: Scully core radius, m.
        head_core: the core of the head row's spanwise segments, m: the bound core, so that they cancel the
            bound trailing segments they lie on exactly in steady flow.

    Returns:
        (P, 3) m/s, global frame.
    """
    if wake.n_rows == 0:
        return np.zeros((len(points), 3))
    starts, ends, circulation, head = segments(wake)
    live = circulation != 0.0                                     # e.g. the inner trailing legs in 2D flow
    cores = [(live & ~head, core), (live & head, head_core)]
    return sum(influence(points, starts[m], ends[m], circulation[m, None], c)[:, :, 0] for m, c in cores)


def shed(wake: ShedWake, head, head_gamma, displacement) -> ShedWake:
    """Convect every corner, then put a new ring in front (Kutta condition).

    Args:
        wake: the ShedWake.
        head: (B, N + 1, 3) the new head row, m, global frame.
        head_gamma: (B, N) the new ring's circulation, m^2/s: the trailing-edge bound rings' circulation of the
            previous step.
        displacement: (B, R + 1, N + 1, 3) or (3,) convection of the corners, m, global frame.
    """
    moved = wake.corners + displacement
    return ShedWake(np.concatenate([np.asarray(head, float)[:, None], moved], axis=1),
                    np.concatenate([np.asarray(head_gamma, float)[:, None], wake.gamma], axis=1))


def with_head(wake: ShedWake, head) -> ShedWake:
    """The same wake with its head row moved (a step repeated at the same time).

    Args:
        wake: the ShedWake.
        head: (B, N + 1, 3) the head row, m, global frame.
    """
    corners = wake.corners.copy()
    corners[:, 0] = head
    return ShedWake(corners, wake.gamma.copy())


def truncate(wake: ShedWake, max_length, max_rows=MAX_WAKE_ROWS) -> ShedWake:
    """Drop the rings whose back row lies too far from the head row, keeping at least one (module docstring).

    Args:
        wake: the ShedWake.
        max_length: (B,) L_w c per body, m.
        max_rows: at most this many rings.
    """
    R = wake.n_rows
    if R == 0:
        return wake
    distance = np.sqrt(np.sum((wake.corners[:, 1:] - wake.corners[:, :1]) ** 2, axis=-1)).max(axis=2)  # (B, R)
    inside = np.any(distance <= np.asarray(max_length)[:, None] * (1 + 1e-9), axis=0)                  # (R,)
    keep = int(np.flatnonzero(inside)[-1]) + 1 if inside.any() else 1
    keep = min(max(keep, 1), int(max_rows))
    if keep == R:
        return wake
    return ShedWake(wake.corners[:, :keep + 1].copy(), wake.gamma[:, :keep].copy())
