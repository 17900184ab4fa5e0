"""The vortex-ring lattice of each body, as fixed shape-function matrices on the exchanged coordinates.

Each body (length L, chord c, reference line at chord fraction a) carries M chordwise x N spanwise
panels of uniform size: panel (i, j) spans the chord fractions [i/M, (i+1)/M] (0 at the leading edge,
1 at the trailing edge) and the span stations [j L/N, (j+1) L/N] from the body's root. A material point
(span s, chord fraction f) lies on the element k = floor(s / l) of its body at x = s - k l (the last
element takes s = L), y = body.chord_offset(f) = (f - a) c, i.e. measured from the reference line
along r_y toward the trailing edge (Otsuka et al. 2019, Eq. 2).

Katz & Plotkin placement: ring (i, j) has its leading (bound) segment at the panel's quarter chord,
f = (i + 1/4)/M, and its trailing segment at the next panel's quarter chord, so the last ring's trailing
segment lies a quarter panel behind the trailing edge, f = 1 + 1/(4M) (the linear field
r(x, y) = r(x, 0) + y r_y(x) extends it off the plate). The collocation point is at the panel's
three-quarter chord, f = (i + 3/4)/M, at mid panel span. The force of a panel acts at the middle of its
bound segment, f = (i + 1/4)/M at mid span (the lumped-vortex centre of pressure).

Every point is r = S(x, y) e on its element (Otsuka et al. 2019, Eq. 20), and S = kron(s, I_3) with the scalar shape row
s of `fmu_common.shape_functions`. We therefore store scalar matrices acting on the slot array
X = E.reshape(-1, 3) (row 3 node + k holds r, r_x, r_y of a node): points = Sc @ X is the same as
kron(Sc, I_3) @ E (Otsuka et al. 2019, Eq. 20), nine times fewer operations. Likewise the tangents at the collocation
points r_x = Sx @ X (S_x: x-derivative of S) and r_y = Sy @ X (S_y = dS/dy: the r_y interpolation), from
which n = r_x x r_y / |r_x x r_y| (Otsuka et al. 2019, Eq. 21) and tau_x, tau_y (Otsuka et al. 2019, Eq. 24).
All matrices are built once; `geometry(E)` is one matrix product.
"""
import dataclasses
from dataclasses import dataclass

import numpy as np

from fmu_common.airfoil import FLAT
from fmu_common.shape_functions import hermite, shape_row
from fmu_common.vectors import cross

CORE_FRACTION = 1e-3   # vortex core radius / smallest reference panel dimension (see biot_savart.py)


@dataclass(frozen=True)
class Geometry:
    """The lattice at one E. Points in metres (global frame); tangents dimensionless.

    corners (n_corners, 3); collocation, application, r_x, r_y, normal (n_panels, 3) with r_x, r_y the element's
    tangents at the collocation point and normal the unit normal of the mean surface there (Otsuka et al. 2019,
    Eq. 21: r_x x r_y on a flat planform); area (n_panels,) m^2; span_weight, chord_weight (n_panels, 3) m: the
    panel's chordwise edge l_c x n and n x its spanwise (bound) edge l_s, which turn ring circulation differences
    into the pressure jump (aero_fmu.vlm.pressure_jump_forces).
    """
    corners: np.ndarray
    collocation: np.ndarray
    application: np.ndarray
    r_x: np.ndarray
    r_y: np.ndarray
    normal: np.ndarray
    area: np.ndarray
    span_weight: np.ndarray
    chord_weight: np.ndarray


def shape_rows(x, y, length):
    """s(x, y), s_x = ds/dx and s_y = ds/dy, the shape function rows for [r^A, r_x^A, r_y^A, r^B, r_x^B, r_y^B].

    Otsuka et al. 2019, Eq. 2

    Args:
        x: position along the element, 0..l, m.
        y: position along the chord, m.
        length: l, the element length, m.

    Returns:
        (s (..., 6), s_x (..., 6) 1/m, s_y (..., 6) 1/m).
    """
    x, y, length = np.broadcast_arrays(*(np.asarray(v, dtype=float) for v in (x, y, length)))
    _, dN, _, L = hermite(x / length, length)
    s = shape_row(x, y, length)
    dL = np.stack([-1.0 / length, 1.0 / length], axis=-1)
    yy = y[..., None]
    s_x = np.concatenate([dN[..., :2], yy * dL[..., :1], dN[..., 2:], yy * dL[..., 1:]], axis=-1)
    zero = np.zeros_like(L[..., :1])
    s_y = np.concatenate([zero, zero, L[..., :1], zero, zero, L[..., 1:]], axis=-1)
    return s, s_x, s_y


class Lattice:
    """Vortex-ring lattice of all bodies of a topology, M chordwise x N spanwise panels per body.

    Numbering (body-major, row-major): corner (b, i, j), i = 0..M chordwise, j = 0..N spanwise, is
    b (M+1)(N+1) + i (N+1) + j; panel (b, i, j), i < M, j < N, is b M N + i N + j.
    Attributes: `rings` (n_panels, 4) corner indices of each ring in circulation order
    (i, j) -> (i+1, j) -> (i+1, j+1) -> (i, j+1), so a positive circulation induces velocity along -n
    inside the ring and, in a flow from leading to trailing edge, makes a force along +n (Otsuka et al. 2019,
    Eq. 25); `trailing_corners` (n_bodies, N + 1) and `trailing_panels` (n_bodies, N); per panel `panel_span`
    (L / N, m), `panel_chord` (local chord / M at mid panel span, m), `chord` (local chord, m), `twist` (rad) and
    `zero_lift_angle` (rad, thin-airfoil theory of its body's camber line) at mid panel span, `body` (body index);
    `body_chords` (B,) root chords, m; `reference_area` (the sum of the planform areas, m^2) and `core_radius` (m).

    Args:
        topology: the aero unit's topology.
        chordwise: M, panels per body along the chord.
        spanwise: N, panels per body along the span.
        core_fraction: the vortex core radius as a fraction of the smallest panel length.
        camber: False: the chord lines only (strip theory takes the camber as a zero-lift angle instead).
    """

    def __init__(self, topology, chordwise, spanwise, core_fraction=CORE_FRACTION, camber=True):
        M, N = int(chordwise), int(spanwise)
        if M < 1 or N < 1:
            raise ValueError(f"panels must be >= 1 (chordwise {chordwise}, spanwise {spanwise})")
        self.M, self.N = M, N
        self.n_slots = 3 * topology.n_nodes
        self.body_names = list(topology.bodies)
        bodies = [topology.bodies[name] for name in self.body_names]
        planforms = [b.planform if camber else dataclasses.replace(b.planform, camber=FLAT) for b in bodies]
        B = len(bodies)
        slots = topology.element_dofs()[:, ::3] // 3          # (n_elements, 6) slot of each shape entry
        lengths = topology.element_lengths()
        i_c, j_c = np.meshgrid(np.arange(M + 1), np.arange(N + 1), indexing="ij")
        i_p, j_p = np.meshgrid(np.arange(M), np.arange(N), indexing="ij")
        parts = {"corner": [], "collocation": [], "application": [], "grid": []}
        for body, planform in zip(bodies, planforms):
            # span stations as exact fractions num / den of the body length; chord fractions as floats
            # (rows is called only in this pass of the loop)
            rows = lambda num, den, frac: _body_rows(body, planform, num.ravel(), den,  # noqa: B023
                                                     frac.ravel(), slots, lengths, self.n_slots)
            parts["corner"].append(rows(j_c, N, (i_c + 0.25) / M))
            parts["collocation"].append(rows(2 * j_p + 1, 2 * N, (i_p + 0.75) / M))
            parts["application"].append(rows(2 * j_p + 1, 2 * N, (i_p + 0.25) / M))
            parts["grid"].append(rows(j_c, N, i_c / M))
        stack = lambda name, k: np.concatenate([p[k] for p in parts[name]], axis=-2 if k == 0 else -1)
        self.corner_matrix = stack("corner", 0)[0]               # Sc (n_corners, n_slots)
        self.collocation_matrix = stack("collocation", 0)[0]     # Sp
        self.tangent_x_matrix = stack("collocation", 0)[1]       # Sx
        self.tangent_y_matrix = stack("collocation", 0)[2]       # Sy
        self.application_matrix = stack("application", 0)[0]    # Sa: panel force points (Otsuka et al. 2019, Eq. 12)
        self.grid_matrix = stack("grid", 0)[0]                   # panel edges: f = i/M (leading edge 0, trailing 1)
        # mean surface: normal offsets h of corners, collocation and grid points, and the surface's derivatives
        # (y_x, h_x, y_f, h_f) at the collocation point and (y_x, h_x) along the bound segment
        self.flat = all(p.flat for p in planforms)
        self._corner_offset, self._collocation_offset = stack("corner", 1)[1], stack("collocation", 1)[1]
        self._grid_offset = stack("grid", 1)[1]
        self._grid_tangents = (stack("grid", 0)[1], stack("grid", 0)[2])
        self._surface = stack("collocation", 1)[2:]
        self._bound_slope = stack("application", 1)[2:4]
        offset_rows = [stack("corner", 0)[1], stack("corner", 0)[2]] if not self.flat else []
        self._all = np.vstack([self.corner_matrix, self.collocation_matrix, self.application_matrix,
                               self.tangent_x_matrix, self.tangent_y_matrix, *offset_rows])
        nc, n_p = (M + 1) * (N + 1), M * N
        self.n_corners, self.n_panels = B * nc, B * n_p
        corner = lambda b, i, j: b * nc + i * (N + 1) + j
        b_p = np.repeat(np.arange(B), n_p)
        ii, jj = np.tile(i_p.ravel(), B), np.tile(j_p.ravel(), B)
        self.rings = np.stack([corner(b_p, ii, jj), corner(b_p, ii + 1, jj), corner(b_p, ii + 1, jj + 1),
                               corner(b_p, ii, jj + 1)], axis=1)
        self.trailing_corners = corner(np.arange(B)[:, None], M, np.arange(N + 1)[None, :])
        self.trailing_panels = np.arange(B)[:, None] * n_p + (M - 1) * N + np.arange(N)[None, :]
        self.body = b_p
        mid_span = np.concatenate([(j_p.ravel() + 0.5) * b.length / N for b in bodies])
        self.panel_span = np.repeat([b.length / N for b in bodies], n_p)
        self.chord = np.concatenate([p.chord(x) for p, x in zip(planforms, mid_span.reshape(B, n_p))])
        self.panel_chord = self.chord / M
        self.twist = np.concatenate([p.twist(x) for p, x in zip(planforms, mid_span.reshape(B, n_p))])
        self.zero_lift_angle = np.repeat([b.planform.camber.zero_lift_angle() for b in bodies], n_p)
        self.body_chords = np.array([b.chord for b in bodies], dtype=float)
        self.reference_area = float(sum(p.area for p in planforms))
        self.core_radius = core_fraction * float(min(self.panel_span.min(), self.panel_chord.min()))

    def point_rows(self):
        """What `geometry` reads, for a kernel that gathers instead of multiplying (aero_fmu.flat_wake_step).

        Returns:
            (rows, surface, corner_offset, collocation_offset): rows (n_rows, n_slots), the shape rows of the
            corners, collocation points, application points, r_x and r_y at the collocation points, then (not flat)
            r_x and r_y at the corners; surface (6, n_panels): y_x, h_x, y_f, h_f at the collocation point and y_x,
            h_x along the bound segment; the mean surface's normal offsets (m) at the corners (n_corners,) and at
            the collocation points (n_panels,).
        """
        return (self._all, np.concatenate([self._surface, self._bound_slope]), self._corner_offset,
                self._collocation_offset)

    # ------------------------------------------------------------------ per time step
    def geometry(self, E):
        """The lattice at the exchanged coordinates E: one matrix product, and the normal offsets of the mean surface.

        Otsuka et al. 2019, Eqs. 20-21, 24

        With n0 the unit r_x x r_y and the surface's derivatives y_x, h_x, y_f, h_f (fmu_common.planform), the mean
        surface's tangents are T_x = r_x + y_x r_y + h_x n0 and T_f = y_f r_y + h_f n0, its unit normal
        n = T_x x T_f / |T_x x T_f| (r_x x r_y on a flat planform, Eq. 21), the panel area |T_x x T_f| L / (N M),
        and the panel's edges l_s = (L / N) T_x (along the bound segment) and l_c = T_f / M.

        Args:
            E: (9 n_nodes,) exchanged coordinates, m and 1, global frame.

        Returns:
            the Geometry.
        """
        X = np.asarray(E, dtype=float).reshape(-1, 3)
        P = self._all @ X
        nc, n_p = self.n_corners, self.n_panels
        corners, colloc, app = P[:nc], P[nc:nc + n_p], P[nc + n_p:nc + 2 * n_p]
        r_x, r_y = P[nc + 2 * n_p:nc + 3 * n_p], P[nc + 3 * n_p:nc + 4 * n_p]
        n0 = _unit_rows(cross(r_x, r_y))
        y_x, h_x, y_f, h_f = self._surface
        t_f = y_f[:, None] * r_y
        if not self.flat:
            corner_tangents = P[nc + 4 * n_p:]
            corners = corners + self._corner_offset[:, None] * _unit_rows(cross(corner_tangents[:nc],
                                                                                corner_tangents[nc:]))
            colloc = colloc + self._collocation_offset[:, None] * n0
            t_f = t_f + h_f[:, None] * n0
        t_x = r_x + y_x[:, None] * r_y + h_x[:, None] * n0
        c = cross(t_x, t_f)
        norm = np.sqrt(np.einsum("ij,ij->i", c, c))
        normal = c / np.where(norm > 0, norm, 1.0)[:, None]
        b_x, b_h = self._bound_slope
        span_edge = self.panel_span[:, None] * (r_x + b_x[:, None] * r_y + b_h[:, None] * n0)
        return Geometry(corners, colloc, app, r_x, r_y, normal, norm * self.panel_span / self.M,
                        cross(t_f / self.M, normal), cross(normal, span_edge))

    def grid_points(self, E):
        """Panel edge points at chord fractions i/M (leading edge 0, trailing edge 1) on the mean surface.

        Args:
            E: (9 n_nodes,) exchanged coordinates, m and 1, global frame.

        Returns:
            (n_corners, 3) m, global frame.
        """
        X = np.asarray(E, dtype=float).reshape(-1, 3)
        points = self.grid_matrix @ X
        if self.flat:
            return points
        n0 = _unit_rows(cross(self._grid_tangents[0] @ X, self._grid_tangents[1] @ X))
        return points + self._grid_offset[:, None] * n0

    def generalized_force(self, forces):
        """Q of panel forces acting at the application points, virtual-work consistent with r = S e.

        Q = sum_panels S(x_a, y_a)^T a.

        Otsuka et al. 2019, Eq. 12

        Args:
            forces: (n_panels, 3) panel forces a, N, global frame.

        Returns:
            (9 n_nodes,) N and N m, global frame.
        """
        return (self.application_matrix.T @ np.asarray(forces, dtype=float)).ravel()

    @staticmethod
    def full(matrix):
        """kron(matrix, I_3): the form acting on E directly.

        Otsuka et al. 2019, Eq. 20

        Args:
            matrix: (n, n_nodes * 3) rows on the nodal vectors.

        Returns:
            (3 n, 9 n_nodes).
        """
        return np.kron(matrix, np.eye(3))


def _unit_rows(v):
    """Each row of v (n, 3) divided by its norm (a zero row stays zero)."""
    norm = np.sqrt(np.einsum("ij,ij->i", v, v))
    return v / np.where(norm > 0, norm, 1.0)[:, None]


def _body_rows(body, planform, num, den, fraction, slots, lengths, n_slots):
    """(rows, surface) of the material points of `body` at span s = num / den * L and chord `fraction`:
    rows (3, n, n_slots) the scalar shape rows (s, s_x, s_y) at (x, y), each point on exactly one element,
    k = floor(s / l) (the last element takes s = L), computed in integers so that points on element ends are
    placed exactly; surface (6, n) = `Planform.surface` (y, h, y_x, h_x, y_f, h_f) at (s, fraction)."""
    n_el = len(body.elements)
    k_local = np.minimum(num * n_el // den, n_el - 1)
    k = np.asarray(body.elements)[k_local]
    x = (num * n_el / den - k_local) * (body.length / n_el)
    surface = np.stack(planform.surface(num / den * body.length, fraction))
    out = np.zeros((3, len(num), n_slots))
    out[:, np.arange(len(num))[:, None], slots[k]] = np.stack(shape_rows(x, surface[0], lengths[k]))
    return out, surface
