"""The 18-DoF asymmetrically gradient-deficient ANCF beam element (000 Sec. II).

Element coordinates (000 Eq. 3): e = [r^A, r_x^A, r_y^A, r^B, r_x^B, r_y^B], 18 numbers, metres for r and
dimensionless for the gradients. Every kernel here is a pure function vectorized over elements: arrays
of element coordinates have shape (n_elements, 18), element lengths shape (n_elements,).

Position of a material point (000 Eq. 2): r(x, y) = S(x, y) e with x along the span (0..l) and y along the
chord, measured from the reference line toward the trailing edge: cubic Hermite along the span for r and
r_x, r_y linear along the span, r(x, y) = r(x, 0) + y r_y(x).

Elastic energy (000 Eq. 7) and its definitions, written down here because the paper leaves freedom:
  * axial strain   an assumed quadratic field eps(x) with the nodal stretches |r_x^A| - 1, |r_x^B| - 1 at
    the ends and the element's arc-length stretch (1/l) int |r'| dx - 1 as its mean. 000's pointwise
    u' = i . r' - 1 (Eq. 8, i along the chord) locks in membrane for slender beams: a nodal gradient shared
    by two elements cannot make it vanish in both under inextensible bending (measured: tip deflection 4%
    short of the elastica at P L^2/EI = 1 with 10 elements and EA L^2/EI = 1e6). Our field is zero for any
    inextensible bending (the chord adjusts so the arc keeps its length), equals eps for a uniform
    stretch, and has no zero-energy mode (its three measures are independent);
  * flap curvature kappa_y(x) = r''(x) . (r'(x) x r_y(x))  (bending out of the wing plane, EI_yy);
  * chord curvature kappa_z(x) = r''(x) . r_y(x)           (bending in the wing plane, EI_zz);
  * torsion        kappa_x = tau / l with tau = 1/2 [(r_x^A x r_y^A) . r_y^B - (r_x^B x r_y^B) . r_y^A],
    the symmetric form of 000 Eq. (11) with |r_x| ~ 1 and the internal constraint |r_y| = 1.
  The local section axes n(x) = r' x r_y and r_y(x) replace the element frame j, k of 000 Eqs. (9)-(10):
  on the constraint manifold they coincide to first order, and they make every measure a polynomial of e,
  so the energy is integrated exactly by 5-point Gauss quadrature and its gradient is exact.
  Every measure vanishes for any rigid motion, so a rigid motion gives zero elastic force.
"""
import numpy as np

# Gauss-Legendre points and weights on [0, 1]; 5 points integrate degree 9 exactly.
_GAUSS_XI, _GAUSS_W = np.polynomial.legendre.leggauss(5)
GAUSS_XI = 0.5 * (_GAUSS_XI + 1.0)
GAUSS_W = 0.5 * _GAUSS_W


def hermite(xi, length):
    """Span shape functions and their x-derivatives at xi = x / l.

    Returns (N, dN, ddN, L) with N, dN, ddN of shape (..., 4) for (r^A, r_x^A, r^B, r_x^B) and
    L of shape (..., 2) for (r_y^A, r_y^B). `length` broadcasts against xi.
    """
    xi, length = np.broadcast_arrays(np.asarray(xi, dtype=float), np.asarray(length, dtype=float))
    l, x2, x3 = length, xi**2, xi**3
    N = np.stack([1 - 3 * x2 + 2 * x3, l * (xi - 2 * x2 + x3), 3 * x2 - 2 * x3, l * (x3 - x2)], axis=-1)
    dN = np.stack([(6 * x2 - 6 * xi) / l, 1 - 4 * xi + 3 * x2, (6 * xi - 6 * x2) / l, 3 * x2 - 2 * xi], axis=-1)
    ddN = np.stack([(12 * xi - 6) / l**2, (6 * xi - 4) / l, (6 - 12 * xi) / l**2, (6 * xi - 2) / l], axis=-1)
    L = np.stack([1 - xi, xi], axis=-1)
    return N, dN, ddN, L


# Assumed axial strain eps(xi) = eps_A phi_A + eps_B phi_B + eps_arc phi_C: phi_A, phi_B linear minus the
# mean-free bubble, phi_C = 6 xi (1 - xi) carries the mean. AXIAL_GRAM[i, j] = int_0^1 phi_i phi_j dxi.
_PHI = np.stack([1 - GAUSS_XI - 3 * GAUSS_XI * (1 - GAUSS_XI), GAUSS_XI - 3 * GAUSS_XI * (1 - GAUSS_XI),
                 6 * GAUSS_XI * (1 - GAUSS_XI)])
AXIAL_GRAM = (_PHI * GAUSS_W) @ _PHI.T

_BASIS_CACHE = {}


def gauss_basis(length):
    """hermite() at the Gauss points for each element length, (n, 5, .), cached (lengths are constant)."""
    length = np.asarray(length, dtype=float)
    key = length.tobytes()
    if key not in _BASIS_CACHE:
        if len(_BASIS_CACHE) > 64:
            _BASIS_CACHE.clear()
        _BASIS_CACHE[key] = hermite(GAUSS_XI[None, :], length[:, None])
    return _BASIS_CACHE[key]


def shape_row(x, y, length):
    """Scalar shape row s(x, y) of 000 Eq. (2), shape (..., 6); S(x, y) = kron(s, I_3).

    Ordering follows e: [r^A, r_x^A, r_y^A, r^B, r_x^B, r_y^B]. x, y in metres.
    """
    N, _, _, L = hermite(np.asarray(x) / length, length)
    y = np.asarray(y, dtype=float)[..., None]
    return np.concatenate([N[..., :2], y * L[..., :1], N[..., 2:], y * L[..., 1:]], axis=-1)


def point_positions(e, x, y, length):
    """r(x, y) = S(x, y) e for each element: e (n, 18), x, y, length (n,) -> (n, 3), metres."""
    s = shape_row(x, y, length)
    return np.einsum("na,nai->ni", s, e.reshape(-1, 6, 3))


def flap_curvature(e, x, length):
    """Bending curvature out of the wing plane at span x of each element, 1/m, shape (n,).

    The geometric curvature of the reference line projected on the unit section normal,
    kappa_y = r'' . n / |r'|^2 with n = (r' x r_y) / |r' x r_y|: the measure of the flap energy above,
    normalized so that it is the curvature itself, also where the line stretches. Positive when the line
    bends toward +n. e (n, 18), x and length (n,) in metres. On a plate of thickness h, h/2 kappa_y is the
    extensional strain of the -n face (the +n face has its opposite): 003 Sec. 5's h/2 x kappa_y.
    """
    _, dN, ddN, L = hermite(np.asarray(x) / length, length)
    v = e.reshape(-1, 6, 3)
    r_span = [v[:, 0], v[:, 1], v[:, 3], v[:, 4]]                 # r^A, r_x^A, r^B, r_x^B
    r1 = sum(dN[:, k:k + 1] * r_span[k] for k in range(4))
    r2 = sum(ddN[:, k:k + 1] * r_span[k] for k in range(4))
    ry = L[:, :1] * v[:, 2] + L[:, 1:] * v[:, 5]
    normal = cross(r1, ry)
    return _dot(r2, normal) / (np.sqrt(_dot(normal, normal)) * _dot(r1, r1))


def mass_matrix(length, mass_per_length, first_moment, chord_inertia):
    """Constant element mass matrix (000 Eq. 5) by exact quadrature of rho * int S^T S dA dx.

    length l (m), mass_per_length rho A (kg/m), first_moment rho Q_z (kg), chord_inertia rho I_zz (kg m),
    all shape (n,), the section moments taken about the reference line (y = 0).
    Returns (n, 18, 18). Exact: the integrand is a polynomial of degree 6 in x and 5 points integrate 9.
    """
    N, _, _, L = gauss_basis(length)  # (n, g, 4), (n, g, 2)
    zero = np.zeros_like(L[..., :1])
    n_row = np.concatenate([N[..., :2], zero, N[..., 2:], zero], axis=-1)   # y^0 part of s
    m_row = np.concatenate([zero, zero, L[..., :1], zero, zero, L[..., 1:]], axis=-1)  # y^1 part
    w = GAUSS_W[None, :] * np.asarray(length)[:, None]
    nn = np.einsum("ng,nga,ngb->nab", w, n_row, n_row)
    nm = np.einsum("ng,nga,ngb->nab", w, n_row, m_row)
    mm = np.einsum("ng,nga,ngb->nab", w, m_row, m_row)
    m6 = (mass_per_length[:, None, None] * nn + first_moment[:, None, None] * (nm + nm.transpose(0, 2, 1))
          + chord_inertia[:, None, None] * mm)
    return np.einsum("nab,ij->naibj", m6, np.eye(3)).reshape(-1, 18, 18)


def distributed_force(length, mass_per_length, first_moment, acceleration):
    """Generalized force of a uniform body force field: int rho S^T g dA dx (000 Sec. II.C), (n, 18).

    acceleration: (3,) m/s^2 (gravity). Exact (polynomial integrand).
    """
    N, _, _, L = gauss_basis(length)
    w = GAUSS_W[None, :] * np.asarray(length)[:, None]
    zero = np.zeros_like(L[..., :1])
    s = (mass_per_length[:, None, None] * np.concatenate([N[..., :2], zero, N[..., 2:], zero], axis=-1)
         + first_moment[:, None, None] * np.concatenate([zero, zero, L[..., :1], zero, zero, L[..., 1:]], axis=-1))
    weights = np.einsum("ng,nga->na", w, s)
    return np.einsum("na,i->nai", weights, np.asarray(acceleration, dtype=float)).reshape(-1, 18)


def cross(a, b):
    """Cross product on the last axis; complex-safe and much faster than np.cross on small arrays."""
    out = np.empty(np.broadcast_shapes(a.shape, b.shape), dtype=np.result_type(a, b))
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    out[..., 0] = a1 * b2 - a2 * b1
    out[..., 1] = a2 * b0 - a0 * b2
    out[..., 2] = a0 * b1 - a1 * b0
    return out


def _dot(a, b):
    return np.sum(a * b, axis=-1)


def _measures(e, length):
    """Strain measures at the Gauss points and the quantities their gradients need."""
    v = e.reshape(-1, 6, 3)
    rA, xA, yA, rB, xB, yB = (v[:, k, :] for k in range(6))
    _, dN, ddN, L = gauss_basis(length)  # (n, g, .)
    d = rB - rA
    # r' and r'' at Gauss points (n, g, 3); N_A' = -N_B' and N_A'' = -N_B'' so r^A enters through d.
    r1 = dN[..., 2:3] * d[:, None] + dN[..., 1:2] * xA[:, None] + dN[..., 3:4] * xB[:, None]
    r2 = ddN[..., 2:3] * d[:, None] + ddN[..., 1:2] * xA[:, None] + ddN[..., 3:4] * xB[:, None]
    ry = L[..., 0:1] * yA[:, None] + L[..., 1:2] * yB[:, None]
    speed = np.sqrt(_dot(r1, r1))                               # |r'| at the Gauss points
    axial = np.stack([np.sqrt(_dot(xA, xA)) - 1.0, np.sqrt(_dot(xB, xB)) - 1.0,
                      speed @ GAUSS_W - 1.0], axis=-1)           # eps_A, eps_B, eps_arc
    normal = cross(r1, ry)
    flap = _dot(r2, normal)                                      # kappa_y
    chordwise = _dot(r2, ry)                                     # kappa_z
    tau = 0.5 * (_dot(cross(xA, yA), yB) - _dot(cross(xB, yB), yA))
    return dict(rA=rA, xA=xA, yA=yA, rB=rB, xB=xB, yB=yB, d=d, speed=speed,
                r1=r1, r2=r2, ry=ry, dN=dN, ddN=ddN, L=L, axial=axial, normal=normal,
                flap=flap, chordwise=chordwise, tau=tau)


def elastic_energy(e, length, stiffness):
    """Elastic energy U of 000 Eq. (7) per element, J, shape (n,).

    stiffness: (n, 4) columns EA (N), EI_yy (flap, N m^2), EI_zz (chord, N m^2), GJ (N m^2).
    """
    m = _measures(e, length)
    EA, EIy, EIz, GJ = (stiffness[:, k] for k in range(4))
    w = GAUSS_W[None, :] * np.asarray(length)[:, None]
    bending = EIy[:, None] * m["flap"] ** 2 + EIz[:, None] * m["chordwise"] ** 2
    axial = EA * length * np.einsum("ni,ij,nj->n", m["axial"], AXIAL_GRAM, m["axial"])
    return 0.5 * (np.sum(w * bending, axis=1) + axial) + 0.5 * GJ * m["tau"] ** 2 / length


def elastic_force(e, length, stiffness):
    """Generalized elastic force -dU/de per element, shape (n, 18) (000 Eq. 4).

    Exact gradient of `elastic_energy`; complex-safe so that `elastic_jacobian` can use complex steps.
    """
    m = _measures(e, length)
    EA, EIy, EIz, GJ = (stiffness[:, k] for k in range(4))
    w = GAUSS_W[None, :] * np.asarray(length)[:, None]
    # dU/d(r'), dU/d(r''), dU/d(r_y(x)) at each Gauss point
    f_axial = (EA * length)[:, None] * (m["axial"] @ AXIAL_GRAM)          # dU/d(eps_A, eps_B, eps_arc)
    cf = (w * EIy[:, None] * m["flap"])[..., None]
    cc = (w * EIz[:, None] * m["chordwise"])[..., None]
    r1, r2, ry, xA, xB = m["r1"], m["r2"], m["ry"], m["xA"], m["xB"]
    g_r1 = (f_axial[:, 2:3] * GAUSS_W[None, :] / m["speed"])[..., None] * r1 + cf * cross(ry, r2)
    g_r2 = cf * m["normal"] + cc * ry
    g_ry = cf * cross(r2, r1) + cc * r2
    dN, ddN, L = m["dN"], m["ddN"], m["L"]
    g_d = np.sum(dN[..., 2:3] * g_r1 + ddN[..., 2:3] * g_r2, axis=1)
    g_xA = np.sum(dN[..., 1:2] * g_r1 + ddN[..., 1:2] * g_r2, axis=1)
    g_xB = np.sum(dN[..., 3:4] * g_r1 + ddN[..., 3:4] * g_r2, axis=1)
    g_xA = g_xA + f_axial[:, 0:1] * xA / np.sqrt(_dot(xA, xA))[:, None]
    g_xB = g_xB + f_axial[:, 1:2] * xB / np.sqrt(_dot(xB, xB))[:, None]
    g_yA = np.sum(L[..., 0:1] * g_ry, axis=1)
    g_yB = np.sum(L[..., 1:2] * g_ry, axis=1)
    # torsion: U_t = GJ tau^2 / (2 l), tau a sum of triple products
    ct = (GJ * m["tau"] / length)[:, None]
    yA, yB = m["yA"], m["yB"]
    g_xA = g_xA + ct * 0.5 * cross(yA, yB)
    g_yA = g_yA + ct * 0.5 * (cross(yB, xA) - cross(xB, yB))
    g_xB = g_xB - ct * 0.5 * cross(yB, yA)
    g_yB = g_yB + ct * 0.5 * (cross(xA, yA) - cross(yA, xB))
    grad = np.stack([-g_d, g_xA, g_yA, g_d, g_xB, g_yB], axis=1)
    return -grad.reshape(-1, 18)


def elastic_jacobian(e, length, stiffness):
    """Tangent stiffness dU^2/de^2 = -d(force)/de per element, (n, 18, 18).

    Complex-step differentiation of `elastic_force`: exact to round-off (no subtractive cancellation),
    18 vectorized force evaluations for all elements at once.
    """
    h = 1e-30
    n = e.shape[0]
    jac = np.empty((n, 18, 18))
    for k in range(18):
        ec = e.astype(complex)
        ec[:, k] += 1j * h
        jac[:, :, k] = -elastic_force(ec, length, stiffness).imag / h
    return jac
