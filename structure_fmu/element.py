"""The 18-DoF asymmetrically gradient-deficient ANCF beam element (Otsuka et al. 2019, Sec. II).

Element coordinates (Otsuka et al. 2019, Eq. 3): e = [r^A, r_x^A, r_y^A, r^B, r_x^B, r_y^B], 18 numbers, metres
for r and dimensionless for the gradients. Every kernel here is a pure function vectorized over elements: arrays
of element coordinates have shape (n_elements, 18), element lengths shape (n_elements,).

Position of a material point (Otsuka et al. 2019, Eq. 2): r(x, y) = S(x, y) e, the shape functions of
fmu_common.shape_functions (shared with the aero unit).

Elastic energy (Otsuka et al. 2019, Eq. 7) and its definitions, written down here because the paper leaves freedom:
  * axial strain   an assumed quadratic field eps(x) with the nodal stretches |r_x^A| - 1, |r_x^B| - 1 at
    the ends and the element's arc-length stretch (1/l) int |r'| dx - 1 as its mean. Otsuka et al. 2019's pointwise
    u' = i . r' - 1 (Eq. 8, i along the chord) locks in membrane for slender beams: a nodal gradient shared
    by two elements cannot make it vanish in both under inextensible bending (measured: tip deflection 4%
    short of the elastica at P L^2/EI = 1 with 10 elements and EA L^2/EI = 1e6). Our field is zero for any
    inextensible bending (the chord adjusts so the arc keeps its length), equals eps for a uniform
    stretch, and has no zero-energy mode (its three measures are independent);
  * flap curvature kappa_y(x) = r''(x) . (r'(x) x r_y(x))  (bending out of the wing plane, EI_yy);
  * chord curvature kappa_z(x) = r''(x) . r_y(x)           (bending in the wing plane, EI_zz);
  * torsion        kappa_x = tau / l with tau = 1/2 [(r_x^A x r_y^A) . r_y^B - (r_x^B x r_y^B) . r_y^A],
    the symmetric form of Otsuka et al. 2019, Eq. (11) with |r_x| ~ 1 and the internal constraint |r_y| = 1.
  The local section axes n(x) = r' x r_y and r_y(x) replace the element frame j, k of Otsuka et al. 2019, Eqs. (9)-(10):
  on the constraint manifold they coincide to first order, and they make every measure a polynomial of e,
  so the energy is integrated exactly by 5-point Gauss quadrature and its gradient is exact.
  Every measure vanishes for any rigid motion, so a rigid motion gives zero elastic force.

Sections that vary along the span: every section property may be given at the Gauss points of the element
(arrays (n, g) and (n, g, 4) in place of (n,) and (n, 4), g the number of points of the rule, `gauss_rule`), and
the integrals take it there: the mass matrix and body force with rho A(x), rho Q_z(x), rho I_zz(x), rho I_yy(x);
the bending energy with EI_yy(x), EI_zz(x); the axial energy through the Gram matrix of the assumed strain field
weighted by EA(x), int EA phi_i phi_j dx; the torsion, whose measure is constant over the element, with the mean
of GJ(x). A plate whose chord and thickness both vary linearly has EI ~ c h^3 of degree 4 in x: with the squared
curvature (degree 8) the integrand is of degree 12, which VARYING_POINTS = 7 points integrate exactly.
"""
import ctypes
import functools
import math
from pathlib import Path

import numpy as np

from fmu_common import c_library
from fmu_common.c_library import address as _address
from fmu_common.shape_functions import hermite
from fmu_common.vectors import cross

CONSTANT_POINTS = 5
"""Gauss points per element of a constant section: 5 integrate degree 9 exactly."""
VARYING_POINTS = 7
"""Gauss points per element of a section that varies along the span: 7 integrate degree 13 exactly (module)."""


@functools.cache
def gauss_rule(points):
    """Gauss-Legendre points and weights on [0, 1]: (xi (points,), w (points,)), exact to degree 2 points - 1.

    Args:
        points: the number of points.
    """
    xi, w = np.polynomial.legendre.leggauss(points)
    xi, w = 0.5 * (xi + 1.0), 0.5 * w
    xi.flags.writeable = w.flags.writeable = False      # shared by every caller (cached)
    return xi, w


GAUSS_XI, GAUSS_W = gauss_rule(CONSTANT_POINTS)


@functools.cache
def axial_shapes(points):
    """The assumed axial strain's shapes at the Gauss points of `points`, (3, points): eps(xi) = eps_A phi_A +
    eps_B phi_B + eps_arc phi_C, phi_A, phi_B linear minus the mean-free bubble, phi_C = 6 xi (1 - xi) carrying
    the mean.

    Args:
        points: the number of Gauss points (`gauss_rule`).
    """
    xi, _ = gauss_rule(points)
    return np.stack([1 - xi - 3 * xi * (1 - xi), xi - 3 * xi * (1 - xi), 6 * xi * (1 - xi)])


# AXIAL_GRAM[i, j] = int_0^1 phi_i phi_j dxi (degree 4: exact on 5 points)
AXIAL_GRAM = (axial_shapes(CONSTANT_POINTS) * GAUSS_W) @ axial_shapes(CONSTANT_POINTS).T
C_SOURCE = Path(__file__).with_name("element_kernels.c")    # the compiled force and tangent (fmu_common.c_library)
_ARRAY = ctypes.c_void_p    # a C-contiguous float64 array, passed as its data address


def _cached_per_lengths(build):
    """`build(length, points)` cached per array of element lengths (constant in a run) and number of Gauss
    points: the bases below are built once per model; at most 64 kept."""
    cache = {}

    @functools.wraps(build)
    def cached(length, points=CONSTANT_POINTS):
        length = np.asarray(length, dtype=float)
        key = (length.tobytes(), points)
        if key not in cache:
            if len(cache) > 64:
                cache.clear()
            cache[key] = build(length, points)
        return cache[key]
    return cached


@_cached_per_lengths
def gauss_basis(length, points=CONSTANT_POINTS):
    """hermite() at the Gauss points for each element length, cached (lengths are constant).

    Args:
        length: (n,) element lengths, m.
        points: Gauss points per element (`gauss_rule`).

    Returns:
        the arrays of hermite(), each (n, points, .).
    """
    return hermite(gauss_rule(points)[0][None, :], length[:, None])


def points_of(*properties):
    """The number of Gauss points g of section properties given at the Gauss points; CONSTANT_POINTS when every
    one is given per element or None. ValueError when they disagree.

    Args:
        *properties: pairs (array, its rank per element): an array of one more rank holds the values at the g
            Gauss points on its second axis ((n, g) for (n,), (n, g, k) for (n, k)).
    """
    found = {np.shape(p)[1] for p, rank in properties if p is not None and np.ndim(p) > rank}
    if len(found) > 1:
        raise ValueError(f"section properties at different numbers of Gauss points: {sorted(found)}")
    return found.pop() if found else CONSTANT_POINTS


def at_points(values, points):
    """Per-element section values (n,) spread over the Gauss points, (n, points); (n, points) as they are.

    Args:
        values: (n,) or (n, points).
        points: the number of Gauss points per element.
    """
    values = np.asarray(values, dtype=float)
    return values if values.ndim == 2 else np.repeat(values[:, None], points, axis=1)


def flap_curvature(derivatives):
    """Bending curvature out of the wing plane of the reference line.

    The geometric curvature projected on the unit section normal, kappa_y = r'' . n / |r'|^2 with
    n = (r' x r_y) / |r' x r_y|: the measure of the flap energy above, normalized so that it is the
    curvature itself, also where the line stretches. Positive when the line bends toward +n. On a plate of
    thickness h, h/2 kappa_y is the extensional strain of the -n face (the +n face has its opposite):
    Otsuka et al. 2022, Sec. 5's h/2 x kappa_y. With |r' x r_y|^2 = |r'|^2 |r_y|^2 - (r' . r_y)^2, on Python
    floats point by point: the strain gauges read it at a few points per communication step, where numpy's
    per-call cost would be most of the time.

    Args:
        derivatives: (..., 3, 3) the rows r' (1), r'' (1/m) along the span and the chord vector r_y (1) at the same
            points, global frame.

    Returns:
        (...,) 1/m.
    """
    derivatives = np.asarray(derivatives, dtype=float)
    out = []
    for (a0, a1, a2), r2, (c0, c1, c2) in derivatives.reshape(-1, 3, 3).tolist():    # r', r'', r_y
        n0, n1, n2 = a1 * c2 - a2 * c1, a2 * c0 - a0 * c2, a0 * c1 - a1 * c0      # r' x r_y
        r1r1, ryry, r1ry = a0 * a0 + a1 * a1 + a2 * a2, c0 * c0 + c1 * c1 + c2 * c2, a0 * c0 + a1 * c1 + a2 * c2
        out.append((r2[0] * n0 + r2[1] * n1 + r2[2] * n2) / (math.sqrt(r1r1 * ryry - r1ry * r1ry) * r1r1))
    return np.array(out).reshape(derivatives.shape[:-2])


def mass_matrix(length, mass_per_length, first_moment, chord_inertia, rotary_inertia=None):
    """Constant element mass matrix by exact quadrature of rho * int S^T S dA dx, plus the section's rotary inertia.

    Otsuka et al. 2019, Eq. 5

    The rotary term is rho I_yy int S'^T S' dx, S' = dS/dx on the reference line (the Hermite shape on r and r_x),
    so that it is the Rayleigh beam's kinetic energy 1/2 rho I_yy |dr'/dt|^2 per unit length (Otsuka et al. 2022,
    Table 4's rho I_yy): a rigid turn of the line at rate omega about an axis across it adds rho I_yy l omega^2 / 2
    (whether the turn is about the chord or about the section normal). The section moments are taken about the
    reference line (y = 0). Exact: the integrands are polynomials of degree 6 in x at most and 5 points integrate 9;
    with properties varying along the span (given at the VARYING_POINTS Gauss points: a plate's rho A ~ c h is of
    degree 2, rho Q_z ~ c^2 h of 3, rho I_zz ~ c^3 h of 4) of degree 10 at most, and 7 points integrate 13.

    Args:
        length: (n,) l, m.
        mass_per_length: (n,) rho A, kg/m, or (n, g) at the element's g Gauss points (`gauss_rule`).
        first_moment: (n,) or (n, g) rho Q_z, kg.
        chord_inertia: (n,) or (n, g) rho I_zz, kg m.
        rotary_inertia: (n,) or (n, g) rho I_yy, kg m; None: 0.

    Returns:
        (n, 18, 18), kg (r rows) and kg m (gradient rows), on the element coordinates e.
    """
    g = points_of((mass_per_length, 1), (first_moment, 1), (chord_inertia, 1), (rotary_inertia, 1))
    N, dN, _, L = gauss_basis(length, g)  # (n, g, 4), (n, g, 2)
    zero = np.zeros_like(L[..., :1])
    n_row = np.concatenate([N[..., :2], zero, N[..., 2:], zero], axis=-1)   # y^0 part of s
    m_row = np.concatenate([zero, zero, L[..., :1], zero, zero, L[..., 1:]], axis=-1)  # y^1 part
    w = gauss_rule(g)[1][None, :] * np.asarray(length)[:, None]
    nm = np.einsum("ng,nga,ngb->nab", w * at_points(first_moment, g), n_row, m_row)
    m6 = (np.einsum("ng,nga,ngb->nab", w * at_points(mass_per_length, g), n_row, n_row) + nm + nm.transpose(0, 2, 1)
          + np.einsum("ng,nga,ngb->nab", w * at_points(chord_inertia, g), m_row, m_row))
    if rotary_inertia is not None:
        d_row = np.concatenate([dN[..., :2], zero, dN[..., 2:], zero], axis=-1)    # r' on the six vectors
        m6 = m6 + np.einsum("ng,nga,ngb->nab", w * at_points(rotary_inertia, g), d_row, d_row)
    return np.einsum("nab,ij->naibj", m6, np.eye(3)).reshape(-1, 18, 18)


def distributed_force(length, mass_per_length, first_moment, acceleration):
    """Generalized force of a uniform body force field: int rho S^T g dA dx. Exact (polynomial integrand).

    Otsuka et al. 2019, Sec. II.C

    Args:
        length: (n,) l, m.
        mass_per_length: (n,) rho A, kg/m, or (n, g) at the element's g Gauss points (`gauss_rule`).
        first_moment: (n,) or (n, g) rho Q_z, kg.
        acceleration: (3,) g, m/s^2 (gravity), global frame.

    Returns:
        (n, 18) N and N m, global frame.
    """
    g = points_of((mass_per_length, 1), (first_moment, 1))
    N, _, _, L = gauss_basis(length, g)
    w = gauss_rule(g)[1][None, :] * np.asarray(length)[:, None]
    zero = np.zeros_like(L[..., :1])
    s = (at_points(mass_per_length, g)[..., None] * np.concatenate([N[..., :2], zero, N[..., 2:], zero], axis=-1)
         + at_points(first_moment, g)[..., None] * np.concatenate([zero, zero, L[..., :1], zero, zero, L[..., 1:]],
                                                                   axis=-1))
    weights = np.einsum("ng,nga->na", w, s)
    return np.einsum("na,i->nai", weights, np.asarray(acceleration, dtype=float)).reshape(-1, 18)


def _dot(a, b):
    """a . b on the last axis (einsum: the fastest of the reductions on these small arrays)."""
    return np.einsum("...i,...i->...", a, b)


@functools.cache
def _cycle(g):
    """The rows (r_y, r'', r') and (r'', r', r_y) of the fields [r'; r''; r_y] at g Gauss points."""
    return np.r_[2 * g:3 * g, g:2 * g, 0:g], np.r_[g:2 * g, 0:g, 2 * g:3 * g]


@_cached_per_lengths
def _slot_basis(length, points=CONSTANT_POINTS):
    """B (n, 3 g, 5): [r'; r''; r_y] at the g Gauss points (rows k g + i) from the five vectors
    [d = r^B - r^A, r_x^A, r_y^A, r_x^B, r_y^B] of each element, cached per lengths. r^A enters only through
    d because N_A' = -N_B' and N_A'' = -N_B''; r' = B[:g] @ slots, and the gradient of a function of
    (r', r'', r_y) at the Gauss points maps back by B^T: one batched product each way."""
    _, dN, ddN, L = gauss_basis(length, points)
    zero = np.zeros_like(L[..., 0])
    first = np.stack([dN[..., 2], dN[..., 1], zero, dN[..., 3], zero], axis=-1)
    second = np.stack([ddN[..., 2], ddN[..., 1], zero, ddN[..., 3], zero], axis=-1)
    chord = np.stack([zero, zero, L[..., 0], zero, L[..., 1]], axis=-1)
    return np.concatenate([first, second, chord], axis=1)


def stiffness_terms(stiffness):
    """The stiffness of the energy's terms from a stiffness table: (g, axial (n, 3, 3) = int_0^1 EA phi_i phi_j dxi
    N, the Gram matrix of the assumed axial strain weighted by EA; EI_yy (n, g) and EI_zz (n, g) at the Gauss
    points, N m^2; GJ (n,) its mean over the element, N m^2).

    Args:
        stiffness: (n, 4) per element or (n, g, 4) at the element's g Gauss points (`gauss_rule`), columns EA (N),
            EI_yy, EI_zz, GJ (N m^2).
    """
    stiffness = np.asarray(stiffness, dtype=float)
    if stiffness.ndim == 2:
        g = CONSTANT_POINTS
        return (g, stiffness[:, 0, None, None] * AXIAL_GRAM, at_points(stiffness[:, 1], g),
                at_points(stiffness[:, 2], g), stiffness[:, 3])
    g = stiffness.shape[1]
    phi, w = axial_shapes(g), gauss_rule(g)[1]
    axial = np.einsum("ng,g,ig,jg->nij", stiffness[..., 0], w, phi, phi)
    return g, axial, stiffness[..., 1], stiffness[..., 2], stiffness[..., 3] @ w


def _fields(e, length, g):
    """The element's nodal vectors v (n, 6, 3), its slot basis, r', r'', r_y at the g Gauss points (n, g, 3) each,
    |r'| (n, g), the nodal |r_x| (n, 2) and the axial strains [eps_A, eps_B, eps_arc] (n, 3): what the energy
    and its gradients share (`_measures`, `_energy_measures`)."""
    v = e.reshape(-1, 6, 3)
    slots = v[:, [3, 1, 2, 4, 5]]                                           # (n, 5, 3): [d, xA, yA, xB, yB]
    slots[:, 0] -= v[:, 0]
    basis = _slot_basis(length, g)
    fields = basis @ slots                                  # (n, 3 g, 3): r', r'', r_y at the Gauss points
    r1 = fields[:, :g]
    speed = np.sqrt(_dot(r1, r1))                                           # |r'|
    nodal = np.sqrt(_dot(v[:, [1, 4]], v[:, [1, 4]]))                       # |r_x^A|, |r_x^B|, (n, 2)
    axial = np.concatenate([nodal - 1.0, (speed @ gauss_rule(g)[1] - 1.0)[:, None]], axis=1)  # eps_A, eps_B, eps_arc
    return v, basis, fields, speed, nodal, axial


def _measures(e, length, g):
    """Strain measures at the g Gauss points and the quantities their gradients need."""
    v, basis, fields, speed, nodal, axial = _fields(e, length, g)
    xA, yA, xB, yB = v[:, 1], v[:, 2], v[:, 4], v[:, 5]
    r1, r2, ry = fields[:, :g], fields[:, g:2 * g], fields[:, 2 * g:]
    # the cyclic products r_y x r'', r'' x r', r' x r_y (= n) in one call
    crossed = cross(fields[:, _cycle(g)[0]], fields[:, _cycle(g)[1]])
    ry_r2, r2_r1, normal = crossed[:, :g], crossed[:, g:2 * g], crossed[:, 2 * g:]
    # torsion: the triple products of tau and, for its gradient, the cross products they are made of
    triple = cross(v[:, [1, 4, 2, 5, 2]], v[:, [2, 5, 5, 1, 4]])    # xA x yA, xB x yB, yA x yB, yB x xA, yA x xB
    tau = 0.5 * (_dot(triple[:, 0], yB) - _dot(triple[:, 1], yA))
    return dict(xA=xA, yA=yA, xB=xB, yB=yB, speed=speed, nodal=nodal, basis=basis, r1=r1, r2=r2, ry=ry, axial=axial,
                normal=normal, ry_r2=ry_r2, r2_r1=r2_r1, flap=_dot(r2, normal), chordwise=_dot(r2, ry), tau=tau,
                triple=triple)


def _energy_measures(e, length, g):
    """The strain measures the energy reads, (flap r''.n (n, g), chordwise r''.r_y (n, g), axial (n, 3), tau (n,)),
    by the same arithmetic as `_measures` (the same numbers, bit for bit) without the cross products only the
    gradients need: the energy is an output read at communication points, the gradients are the step's."""
    v, _, fields, _, _, axial = _fields(e, length, g)
    r1, r2, ry = fields[:, :g], fields[:, g:2 * g], fields[:, 2 * g:]
    frames = cross(v[:, [1, 4]], v[:, [2, 5]])                             # xA x yA, xB x yB
    tau = 0.5 * (_dot(frames[:, 0], v[:, 5]) - _dot(frames[:, 1], v[:, 2]))
    return _dot(r2, cross(r1, ry)), _dot(r2, ry), axial, tau


def elastic_energy(e, length, stiffness):
    """Elastic energy U per element.

    Otsuka et al. 2019, Eq. 7

    Real coordinates run the C kernel of element_kernels.c (fmu_common.c_library; the same terms, equal to 1e-12)
    unless $WINGSIM_KERNELS = numpy; the numpy form below is complex-safe.

    Args:
        e: (n, 18) element coordinates, m (r) and 1 (r_x, r_y), global frame.
        length: (n,) l, m.
        stiffness: (n, 4) columns EA (N), EI_yy (flap, N m^2), EI_zz (chord, N m^2), GJ (N m^2), or (n, g, 4)
            at the element's g Gauss points (`stiffness_terms`).

    Returns:
        (n,) J.
    """
    kernels = c_kernels() if np.isrealobj(e) else None
    if kernels is not None:
        return _compiled(kernels.elastic_energy, e, length, stiffness, ())
    g, gram, EIy, EIz, GJ = stiffness_terms(stiffness)
    flap, chordwise, strains, tau = _energy_measures(e, length, g)
    w = gauss_rule(g)[1][None, :] * np.asarray(length)[:, None]
    bending = EIy * flap ** 2 + EIz * chordwise ** 2
    axial = length * np.einsum("ni,nij,nj->n", strains, gram, strains)
    return 0.5 * (np.sum(w * bending, axis=1) + axial) + 0.5 * GJ * tau ** 2 / length


def elastic_force(e, length, stiffness):
    """Generalized elastic force -dU/de per element.

    Otsuka et al. 2019, Eq. 4

    Exact gradient of `elastic_energy`; complex-safe, so that a complex step differentiates it exactly (the
    tests' reference for `elastic_jacobian`). Real coordinates run the C kernel of element_kernels.c
    (fmu_common.c_library; the same terms, equal to 1e-12) unless $WINGSIM_KERNELS = numpy.

    Args:
        e: (n, 18) element coordinates, m (r) and 1 (r_x, r_y), global frame.
        length: (n,) l, m.
        stiffness: (n, 4) columns EA (N), EI_yy (N m^2), EI_zz (N m^2), GJ (N m^2), or (n, g, 4) at the
            element's g Gauss points (`stiffness_terms`).

    Returns:
        (n, 18) N and N m, global frame.
    """
    kernels = c_kernels() if np.isrealobj(e) else None
    if kernels is not None:
        return _compiled(kernels.elastic_force, e, length, stiffness, (18,))
    g, gram, EIy, EIz, GJ = stiffness_terms(stiffness)
    m = _measures(e, length, g)
    weights = gauss_rule(g)[1]
    w = weights[None, :] * np.asarray(length)[:, None]
    # dU/d(r'), dU/d(r''), dU/d(r_y(x)) at each Gauss point
    f_axial = length[:, None] * np.einsum("ni,nij->nj", m["axial"], gram)   # dU/d(eps_A, eps_B, eps_arc)
    cf = (w * EIy * m["flap"])[..., None]
    cc = (w * EIz * m["chordwise"])[..., None]
    r1, r2, ry = m["r1"], m["r2"], m["ry"]
    g_r1 = (f_axial[:, 2:3] * weights[None, :] / m["speed"])[..., None] * r1 + cf * m["ry_r2"]
    g_r2 = cf * m["normal"] + cc * ry
    g_ry = cf * m["r2_r1"] + cc * r2
    g = np.swapaxes(m["basis"], 1, 2) @ np.concatenate([g_r1, g_r2, g_ry], axis=1)   # (n, 5, 3) on the slots
    g_d, g_xA, g_yA, g_xB, g_yB = (g[:, k] for k in range(5))
    xA, xB = m["xA"], m["xB"]
    nodal = (f_axial[:, :2] / m["nodal"])[..., None]                        # dU/d|r_x| / |r_x| at A and B
    g_xA = g_xA + nodal[:, 0] * xA
    g_xB = g_xB + nodal[:, 1] * xB
    # torsion: U_t = GJ tau^2 / (2 l), tau a sum of triple products
    ct = (GJ * m["tau"] / length)[:, None]
    xA_yA, xB_yB, yA_yB, yB_xA, yA_xB = (m["triple"][:, k] for k in range(5))
    g_xA = g_xA + ct * 0.5 * yA_yB
    g_yA = g_yA + ct * 0.5 * (yB_xA - xB_yB)
    g_xB = g_xB + ct * 0.5 * yA_yB
    g_yB = g_yB + ct * 0.5 * (xA_yA - yA_xB)
    grad = np.stack([-g_d, g_xA, g_yA, g_d, g_xB, g_yB], axis=1)
    return -grad.reshape(-1, 18)


_EPSILON = np.zeros((3, 3, 3))   # Levi-Civita symbol
_EPSILON[0, 1, 2] = _EPSILON[1, 2, 0] = _EPSILON[2, 0, 1] = 1.0
_EPSILON[0, 2, 1] = _EPSILON[2, 1, 0] = _EPSILON[1, 0, 2] = -1.0
# e's six nodal vectors [r^A, r_x^A, r_y^A, r^B, r_x^B, r_y^B] from the slots [d, x^A, y^A, x^B, y^B]
_NODE_COMPONENTS = (3 * np.array([0, 1, 2, 0, 3, 4])[:, None] + np.arange(3)).ravel()    # (18,) into 15
_NODE_SIGNS = np.repeat([-1.0, 1.0, 1.0, 1.0, 1.0, 1.0], 3)                             # r^A = -d


def _triple_hessian(c):
    """d^2 [(a x b) . c] / da db = eps_ijk c_k, (..., 3, 3); the other blocks follow by cyclic order:
    d^2/da dc = -eps(b), d^2/db dc = eps(a)."""
    return np.einsum("ijk,...k->...ij", _EPSILON, c)


@_cached_per_lengths
def _field_basis(length, points=CONSTANT_POINTS):
    """(n, g, 9, 15): [r'; r''; r_y] at each of the g = `points` Gauss points from the 15 slot components, kron of
    `_slot_basis` with I_3, cached per lengths and g."""
    g = points
    basis = _slot_basis(length, g).reshape(-1, 3, g, 5).transpose(0, 2, 1, 3)          # (n, g, field, slot)
    return np.einsum("ngas,ij->ngaisj", basis, np.eye(3)).reshape(-1, g, 9, 15)


def elastic_jacobian(e, length, stiffness):
    """Tangent stiffness dU^2/de^2 = -d(force)/de per element: the exact second derivative of `elastic_energy`.

    Otsuka et al. 2019, Eqs. 7-11 (with the definitions of the module docstring)

    Per Gauss point, the bending and arc-stretch terms are functions of the fields (r', r'', r_y): their
    Hessian there is c (grad m grad m^T + m Hess m) for each squared measure m (flap = (r' x r_y) . r'' has
    Levi-Civita blocks, chordwise = r'' . r_y identity blocks, |r'| the projector (I - u u^T) / |r'|), mapped
    to the slots [d, x^A, y^A, x^B, y^B] by `_field_basis`; the axial quadratic form couples the stretches'
    gradients across points and nodes; torsion is two triple products of nodal vectors. r^A enters only as
    -d (a translation does not strain). Checked against complex-step and finite differences of
    `elastic_force` (tests/units/test_element.py). Real coordinates run the C kernel of element_kernels.c
    (fmu_common.c_library; the same terms, equal to 1e-12) unless $WINGSIM_KERNELS = numpy; this numpy form is
    the reference.

    Args:
        e: (n, 18) element coordinates, m (r) and 1 (r_x, r_y), global frame.
        length: (n,) l, m.
        stiffness: (n, 4) columns EA (N), EI_yy (N m^2), EI_zz (N m^2), GJ (N m^2), or (n, g, 4) at the
            element's g Gauss points (`stiffness_terms`).

    Returns:
        (n, 18, 18).
    """
    kernels = c_kernels() if np.isrealobj(e) else None
    if kernels is not None:
        return _compiled(kernels.elastic_jacobian, e, length, stiffness, (18, 18))
    g, gram, EIy, EIz, GJ = stiffness_terms(stiffness)
    m = _measures(e, length, g)
    n, eye = e.shape[0], np.eye(3)
    weights = gauss_rule(g)[1]
    w = weights[None, :] * np.asarray(length)[:, None]
    cf, cc = w * EIy, w * EIz
    r1, r2, ry, speed = m["r1"], m["r2"], m["ry"], m["speed"]
    # per Gauss point over the fields (r', r'', r_y): (n, g, 9, 9)
    grad_flap = np.concatenate([m["ry_r2"], m["normal"], m["r2_r1"]], axis=-1)
    grad_chord = np.concatenate([np.zeros_like(r2), ry, r2], axis=-1)
    H = (cf[..., None, None] * (grad_flap[..., :, None] * grad_flap[..., None, :])
         + cc[..., None, None] * (grad_chord[..., :, None] * grad_chord[..., None, :]))
    flap = (cf * m["flap"])[..., None, None]
    chord = (cc * m["chordwise"])[..., None, None]
    f_axial = length[:, None] * np.einsum("ni,nij->nj", m["axial"], gram)   # dU/d(eps_A, eps_B, eps_arc)
    unit = r1 / speed[..., None]
    arc = (f_axial[:, 2:3] * weights[None, :] / speed)[..., None, None]
    upper = {(0, 2): flap * _triple_hessian(r2), (0, 1): -flap * _triple_hessian(ry),   # flap: a = r', b = r_y,
             (2, 1): flap * _triple_hessian(r1) + chord * eye}                           # c = r''
    for (a, b), block in upper.items():
        H[..., 3 * a:3 * a + 3, 3 * b:3 * b + 3] += block
        H[..., 3 * b:3 * b + 3, 3 * a:3 * a + 3] += np.swapaxes(block, -1, -2)
    H[..., 0:3, 0:3] += arc * (eye - unit[..., :, None] * unit[..., None, :])
    fields = _field_basis(length, g)
    hessian = (np.swapaxes(fields, -1, -2) @ H @ fields).sum(axis=1)    # (n, 15, 15) on the slots
    # axial: l grad(eps)^T (int EA phi phi^T) grad(eps), and the nodal stretches' own curvature
    nodal = m["nodal"]
    uA, uB = m["xA"] / nodal[:, :1], m["xB"] / nodal[:, 1:]
    grad_axial = np.zeros((n, 3, 15))
    grad_axial[:, 0, 3:6], grad_axial[:, 1, 9:12] = uA, uB
    grad_axial[:, 2] = np.einsum("g,ngi,ngis->ns", weights, unit, fields[:, :, 0:3])
    hessian += length[:, None, None] * (np.swapaxes(grad_axial, 1, 2) @ gram @ grad_axial)
    hessian[:, 3:6, 3:6] += (f_axial[:, 0] / nodal[:, 0])[:, None, None] * (eye - uA[:, :, None] * uA[:, None, :])
    hessian[:, 9:12, 9:12] += (f_axial[:, 1] / nodal[:, 1])[:, None, None] * (eye - uB[:, :, None] * uB[:, None, :])
    # torsion: GJ / l (grad tau grad tau^T + tau Hess tau), tau = 1/2 [(xA x yA) . yB - (xB x yB) . yA]
    xA, yA, xB, yB = m["xA"], m["yA"], m["xB"], m["yB"]
    xA_yA, xB_yB, yA_yB, yB_xA, yA_xB = (m["triple"][:, k] for k in range(5))
    grad_tau = np.concatenate([np.zeros_like(xA), 0.5 * yA_yB, 0.5 * (yB_xA - xB_yB), 0.5 * yA_yB,
                               0.5 * (xA_yA - yA_xB)], axis=-1)
    ct = GJ / length
    hessian += ct[:, None, None] * (grad_tau[:, :, None] * grad_tau[:, None, :])
    blocks = np.zeros((n, 15, 15))
    for (p, q, r), sign, (a, b, c) in (((1, 2, 4), 0.5, (xA, yA, yB)), ((3, 4, 2), -0.5, (xB, yB, yA))):
        pairs = (((p, q), _triple_hessian(c)), ((p, r), -_triple_hessian(b)), ((q, r), _triple_hessian(a)))
        for (i, j), block in pairs:
            blocks[:, 3 * i:3 * i + 3, 3 * j:3 * j + 3] += sign * block
    hessian += (ct * m["tau"])[:, None, None] * (blocks + np.swapaxes(blocks, 1, 2))
    return hessian[:, _NODE_COMPONENTS][:, :, _NODE_COMPONENTS] * (_NODE_SIGNS[:, None] * _NODE_SIGNS[None, :])


def add_elastic_force(E, dofs, length, stiffness, F, scratch):
    """F[dofs] += elastic_force(E[dofs]): every element's elastic force on the whole structure's coordinates, in one
    C call (element_kernels.c's add_elastic_force: gathered, computed and added element by element) unless
    $WINGSIM_KERNELS = numpy, whose reference is `elastic_force` summed by np.bincount (equal to 1e-12).

    Args:
        E: (n_E,) the structure's coordinates, m and 1, global frame.
        dofs: (n, 18) C-contiguous int64 indices of each element's coordinates in E.
        length: (n,) l, m.
        stiffness: (n, 4) or (n, g, 4), as `elastic_force` takes it.
        F: (n_E,) C-contiguous float64, added to in place, N and N m.
        scratch: (36 n,) C-contiguous float64 the C kernel works in (overwritten).

    Returns:
        F.
    """
    kernels = c_kernels()
    if kernels is None:
        F += np.bincount(dofs.ravel(), elastic_force(E[dofs], length, stiffness).ravel(), len(F))
        return F
    E = np.ascontiguousarray(E, dtype=float)
    if not E.flags.writeable:
        E = E.copy()                                # `_address` reads writable arrays only
    if dofs.shape != (len(length), 18) or dofs.dtype != np.int64 or scratch.size < 36 * len(length):
        raise ValueError(f"element kernels: dofs {dofs.shape} {dofs.dtype}, scratch {scratch.size} for "
                         f"{len(length)} elements; expected (n, 18) int64 and 36 n")
    if len(length):
        table, address, g = _table(length, stiffness)  # the table is held until the C call returns
        _check(kernels.add_elastic_force(len(length), g, address, _address(E), _address(dofs), _address(scratch),
                                         _address(F)), g)
    return F


def c_kernels():
    """The C library of element_kernels.c (fmu_common.c_library), its functions typed; None when $WINGSIM_KERNELS
    selects the numpy kernels."""
    signature = (ctypes.c_int, [ctypes.c_long, ctypes.c_long, _ARRAY, _ARRAY, _ARRAY])
    gathered = (ctypes.c_int, [ctypes.c_long, ctypes.c_long, _ARRAY, _ARRAY, _ARRAY, _ARRAY, _ARRAY])
    return c_library.kernels(C_SOURCE, {"elastic_energy": signature, "elastic_force": signature,
                                        "elastic_jacobian": signature, "add_elastic_force": gathered})


def _compiled(kernel, e, length, stiffness, shape):
    """`kernel` of element_kernels.c (elastic_energy, elastic_force or elastic_jacobian) on e (n, 18), length (n,)
    and stiffness (n, 4) or (n, g, 4): its result, (n, *shape)."""
    e = np.ascontiguousarray(e, dtype=float)
    if not e.flags.writeable:
        e = e.copy()                                # `_address` reads writable arrays only
    if e.shape != (len(length), 18):
        raise ValueError(f"element kernels: e {e.shape} for {len(length)} element lengths; expected (n, 18)")
    out = np.empty((len(e), *shape))
    if len(e):
        table, address, g = _table(length, stiffness)  # the table is held until the C call returns
        _check(kernel(len(e), g, address, _address(e), _address(out)), g)
    return out


_TABLES: dict[tuple, tuple] = {}


def _table(length, stiffness):
    """The C kernels' table of the arguments that are constant in a run (element_kernels.c: the Gauss weights
    (g,), length (n,) m, the EA-weighted axial Gram matrices (n, 3, 3) N, EI_yy and EI_zz at the Gauss points
    (n, g, 2) N m^2, the mean GJ (n,) N m^2, the slot basis (n, 3 g, 5), one after the other; `stiffness_terms`),
    its address and g, cached per lengths and stiffnesses (at most 64 kept)."""
    length = np.ascontiguousarray(length, dtype=float)
    stiffness = np.ascontiguousarray(stiffness, dtype=float)
    key = (length.tobytes(), stiffness.shape, stiffness.tobytes())
    found = _TABLES.get(key)
    if found is None:
        if length.ndim != 1 or stiffness.shape[0] != len(length) or stiffness.shape[-1] != 4 or stiffness.ndim > 3:
            raise ValueError(f"element kernels: length {length.shape}, stiffness {stiffness.shape}; expected (n,), "
                             "(n, 4) or (n, g, 4)")
        if len(_TABLES) > 64:
            _TABLES.clear()
        g, gram, EIy, EIz, GJ = stiffness_terms(stiffness)
        table = np.concatenate([gauss_rule(g)[1], length, gram.ravel(), np.stack([EIy, EIz], axis=-1).ravel(), GJ,
                                _slot_basis(length, g).ravel()])
        found = _TABLES[key] = (table, _address(table), g)
    return found


def _check(status, g):
    """ValueError for a C kernel's status -1 (more Gauss points g than its scratch arrays hold)."""
    if status != 0:
        raise ValueError(f"the element C kernels cannot take {g} Gauss points (element_kernels.c, MAX_GAUSS)")
