"""The higher-order shear-deformable ANCF beam element of Peng et al. 2019 (Eqs. 1-10), on the 18 coordinates of
the Otsuka et al. 2019 element.

Element coordinates: e = [r^A, r_x^A, r_y^A, r^B, r_x^B, r_y^B] (Peng et al. 2019, Eq. 2, with 3-vectors), 18
numbers, metres for r and dimensionless for the gradients; the position r(x, y) = S(x, y) e (Eq. 1) on the shape
functions of fmu_common.shape_functions (cubic Hermite along x for r and r_x, r_y linear along x): the element's
mass matrix and body forces are those of `element`. Every kernel is a pure function vectorized over elements:
arrays of element coordinates have shape (n, 18), element lengths (n,), sections (n, 7) with the columns of
`SECTION_COLUMNS` (or (n, g, 7) at the element's g Gauss points along x, for a section that varies along the
span; E and G, the material's, are constant).

Elastic energy, written down here because the paper is planar:
  * the sheet of the section's chord (x along the span, y along the chord from the reference line) is the
    paper's continuum, in 3D: the deformation gradient J = [r_x(x, y), r_y(x, y)] (3 x 2; Eq. 5 with
    J_0 = I, the reference state being straight with x, y the arc length and the chord coordinate), the Green
    strain eps = 1/2 (J^T J - I) (Eq. 6): eps_11 = (r_x . r_x - 1) / 2, eps_22 = (r_y . r_y - 1) / 2, and the
    engineering shear strain gamma_12 = r_x . r_y (= 2 eps_12);
  * the energy density W = 1/2 (E eps_11^2 + E eps_22^2 + G gamma_12^2) (Eqs. 8-10 with lambda = 0; the shear
    term is 1/2 G gamma^2 = 2 mu eps_12^2: Eqs. 7 and 9 as printed, D33 = 2 mu on eps_12, give half of it).
    Poisson locking: the Poisson coupling lambda is left out (the paper's nu = 0), because r_y is constant
    through the chord and cannot carry the linear transverse contraction of bending, so Eq. 9's law would
    stiffen bending to lambda + 2 mu = E (1 - nu) / ((1 + nu) (1 - 2 nu)); G = E / (2 (1 + nu)) keeps the
    material's shear modulus (nu: the section's poissons_ratio, default 0);
  * W is integrated over the section: exactly, 5 Gauss points along x (W is of degree 8 in x) times 3 across
    the chord (degree 4 in y), times the plate thickness h; a section that varies along the span (a section array
    (n, g, 7) at the g Gauss points of each element, element.VARYING_POINTS) is integrated over its trapezoid,
    the 3 points across the local chord c(x) from the local leading edge, times the local h(x): W c h is then of
    degree 10 in x, which 7 points integrate exactly;
  * out of the sheet, where the continuum of the chord has no thickness coordinate, the element keeps the flap
    bending (EI_yy) and torsion (GJ) of `element` (the curvature of the reference line along the sheet's normal
    and the twist of r_y; Kirchhoff-like, shear-rigid). In planar motion in the sheet's plane these terms
    vanish and the element is the planar element of the paper.
Every strain vanishes for a rigid motion, so a rigid motion gives zero elastic force. Unlike the Otsuka et al.
2019 element, r_y is free: |r_y| and r_x . r_y are strains here, not constraints.
"""
import ctypes
from pathlib import Path

import numpy as np

from fmu_common import c_library

from . import element

SECTION_COLUMNS = ("youngs_modulus", "shear_modulus", "chord", "leading_edge", "thickness", "flap", "torsion")
"""The columns of a section array (n, 7): E (Pa), G (Pa), chord c (m), the leading edge's y (m, from the
reference line, negative ahead of it), plate thickness h (m), EI_yy (N m^2) and GJ (N m^2)."""

_CHORD_XI, _CHORD_W = np.polynomial.legendre.leggauss(3)
CHORD_XI = 0.5 * (_CHORD_XI + 1.0)     # Gauss points on [0, 1] across the chord; 3 integrate degree 5 exactly
CHORD_W = 0.5 * _CHORD_W
C_SOURCE = Path(__file__).with_name("shear_element_kernels.c")   # the compiled sheet force and tangent


def section_table(sections):
    """The section array (n, 7) of SECTION_COLUMNS from plate sections: G = E / (2 (1 + nu)), the leading edge at
    -a c from the reference line.

    Args:
        sections: the n elements' plate Sections (structure_fmu.section; thickness, youngs_modulus given), or
            (n, g) nested lists of them at the elements' Gauss points (structure_fmu.model.element_sections).

    Returns:
        (n, 7), or (n, g, 7), SI.
    """
    def row(s):
        return [s.youngs_modulus, s.youngs_modulus / (2.0 * (1.0 + s.poissons_ratio)), s.chord,
                s.leading_edge, s.thickness, s.flap, s.torsion]
    if len(sections) and isinstance(sections[0], list):
        return np.array([[row(s) for s in points] for points in sections])
    return np.array([row(s) for s in sections]).reshape(-1, 7)


def _material(section):
    """E and G (Pa) per element, (n, 1) each, from a section array (n, 7) or (n, g, 7)."""
    per_element = section if section.ndim == 2 else section[:, 0]
    return per_element[:, :1], per_element[:, 1:2]


def _point_basis(length, section):
    """Coefficients of r_x(x, y) and r_y(x, y) on the six nodal vectors at the section's Gauss points, and the
    points' weights (m^3: l w_x c w_y h).

    Args:
        length: (n,) l, m.
        section: (n, 7) or (n, gx, 7) columns SECTION_COLUMNS.

    Returns:
        (a (n, P, 6) with r_x = sum_j a_j v_j (1/m on r^A, r^B; dimensionless on r_x, r_y), b (n, P, 6) with
        r_y = sum_j b_j v_j, weights (n, P) m^3), P = 3 gx points (gx = 5 for (n, 7)), x-major.
    """
    length = np.asarray(length, dtype=float)
    gx = element.points_of((section, 2))
    _, dN, _, L = element.gauss_basis(length, gx)                  # (n, gx, 4), (n, gx, 2)
    chord, lead, thickness = (element.at_points(section[..., k], gx) for k in (2, 3, 4))     # (n, gx) each
    y = lead[..., None] + chord[..., None] * CHORD_XI                # (n, gx, 3), m
    n, gy = len(length), len(CHORD_W)
    a = np.zeros((n, gx, gy, 6))
    a[..., [0, 1, 3, 4]] = dN[:, :, None, :]
    a[..., 2] = -y / length[:, None, None]                         # y r_y' = y (r_y^B - r_y^A) / l
    a[..., 5] = y / length[:, None, None]
    b = np.zeros((n, gx, gy, 6))
    b[..., 2], b[..., 5] = L[:, :, None, 0], L[:, :, None, 1]
    weights = (length[:, None, None] * element.gauss_rule(gx)[1][None, :, None]
               * (chord * thickness)[..., None] * CHORD_W[None, None, :])
    return a.reshape(n, -1, 6), b.reshape(n, -1, 6), weights.reshape(n, -1)


def _strains(e, length, section):
    """r_x, r_y (n, P, 3) and eps_11, eps_22, gamma_12 (n, P) at the Gauss points, with the basis."""
    a, b, weights = _point_basis(length, section)
    v = e.reshape(-1, 6, 3)
    rx, ry = a @ v, b @ v
    e11 = 0.5 * (np.einsum("npc,npc->np", rx, rx) - 1.0)
    e22 = 0.5 * (np.einsum("npc,npc->np", ry, ry) - 1.0)
    gamma = np.einsum("npc,npc->np", rx, ry)
    return dict(a=a, b=b, weights=weights, rx=rx, ry=ry, e11=e11, e22=e22, gamma=gamma)


def _out_of_sheet(section):
    """The stiffness table of `element` (n, 4), or (n, g, 4), for the flap bending and torsion only:
    [0, EI_yy, 0, GJ]."""
    zero = np.zeros_like(section[..., 5])
    return np.stack([zero, section[..., 5], zero, section[..., 6]], axis=-1)


def sheet_energy(e, length, section):
    """Elastic energy of the sheet's continuum per element, int W dV (Peng et al. 2019, Eq. 10).

    Args:
        e: (n, 18) element coordinates, m (r) and 1 (r_x, r_y), global frame.
        length: (n,) l, m.
        section: (n, 7) or (n, g, 7) columns SECTION_COLUMNS.

    Returns:
        (n,) J.
    """
    s = _strains(e, length, section)
    E, G = _material(section)
    density = 0.5 * (E * (s["e11"] ** 2 + s["e22"] ** 2) + G * s["gamma"] ** 2)
    return np.sum(s["weights"] * density, axis=1)


def sheet_force(e, length, section):
    """Generalized elastic force of the sheet, -d(sheet_energy)/de.

    dW/dr_x = E eps_11 r_x + G gamma r_y, dW/dr_y = E eps_22 r_y + G gamma r_x at each Gauss point, mapped to the
    nodal vectors by the shape functions' coefficients. Complex-safe (the tests' complex step). Real coordinates
    run the C kernel of shear_element_kernels.c (fmu_common.c_library; equal to 1e-12) unless
    $WINGSIM_KERNELS = numpy.

    Args:
        e: (n, 18) element coordinates, m (r) and 1 (r_x, r_y), global frame.
        length: (n,) l, m.
        section: (n, 7) or (n, g, 7) columns SECTION_COLUMNS.

    Returns:
        (n, 18) N and N m, global frame.
    """
    kernels = c_kernels() if np.isrealobj(e) else None
    if kernels is not None:
        return _compiled(kernels.sheet_force, e, length, section, (18,))
    s = _strains(e, length, section)
    E, G = (m[..., None] for m in _material(section))
    w = s["weights"][..., None]
    g_rx = w * (E * s["e11"][..., None] * s["rx"] + G * s["gamma"][..., None] * s["ry"])
    g_ry = w * (E * s["e22"][..., None] * s["ry"] + G * s["gamma"][..., None] * s["rx"])
    grad = np.swapaxes(s["a"], 1, 2) @ g_rx + np.swapaxes(s["b"], 1, 2) @ g_ry      # (n, 6, 3)
    return -grad.reshape(-1, 18)


def sheet_jacobian(e, length, section):
    """Tangent stiffness of the sheet, d^2(sheet_energy)/de^2, exact.

    At each point, with eye I: d^2W/dr_x^2 = E (r_x r_x^T + eps_11 I) + G r_y r_y^T,
    d^2W/dr_y^2 = E (r_y r_y^T + eps_22 I) + G r_x r_x^T, d^2W/dr_x dr_y = G (r_y r_x^T + gamma I); mapped by the
    coefficients a, b of r_x and r_y on the nodal vectors. Real coordinates run the C kernel unless
    $WINGSIM_KERNELS = numpy; this numpy form is the reference.

    Args:
        e: (n, 18) element coordinates, m (r) and 1 (r_x, r_y), global frame.
        length: (n,) l, m.
        section: (n, 7) or (n, g, 7) columns SECTION_COLUMNS.

    Returns:
        (n, 18, 18) N/m, N and N m.
    """
    kernels = c_kernels() if np.isrealobj(e) else None
    if kernels is not None:
        return _compiled(kernels.sheet_jacobian, e, length, section, (18, 18))
    s = _strains(e, length, section)
    E, G = (m[..., None, None] for m in _material(section))
    rx, ry, eye = s["rx"], s["ry"], np.eye(3)
    outer = lambda u, v: u[..., :, None] * v[..., None, :]     # noqa: E731
    hxx = E * (outer(rx, rx) + s["e11"][..., None, None] * eye) + G * outer(ry, ry)
    hyy = E * (outer(ry, ry) + s["e22"][..., None, None] * eye) + G * outer(rx, rx)
    hxy = G * (outer(ry, rx) + s["gamma"][..., None, None] * eye)
    a, b, w = s["a"], s["b"], s["weights"]
    K = (np.einsum("np,npi,npj,npcd->nicjd", w, a, a, hxx) + np.einsum("np,npi,npj,npcd->nicjd", w, b, b, hyy)
         + np.einsum("np,npi,npj,npcd->nicjd", w, a, b, hxy)
         + np.einsum("np,npi,npj,npdc->nicjd", w, b, a, hxy))
    return K.reshape(-1, 18, 18)


def elastic_energy(e, length, section):
    """Elastic energy U per element: the sheet's continuum plus the flap bending and torsion of `element`.

    Peng et al. 2019, Eq. 10

    Args:
        e: (n, 18) element coordinates, m (r) and 1 (r_x, r_y), global frame.
        length: (n,) l, m.
        section: (n, 7) or (n, g, 7) columns SECTION_COLUMNS.

    Returns:
        (n,) J.
    """
    return sheet_energy(e, length, section) + element.elastic_energy(e, length, _out_of_sheet(section))


def elastic_force(e, length, section):
    """Generalized elastic force -dU/de per element (of `elastic_energy`).

    Args:
        e: (n, 18) element coordinates, m (r) and 1 (r_x, r_y), global frame.
        length: (n,) l, m.
        section: (n, 7) or (n, g, 7) columns SECTION_COLUMNS.

    Returns:
        (n, 18) N and N m, global frame.
    """
    return sheet_force(e, length, section) + element.elastic_force(e, length, _out_of_sheet(section))


def elastic_jacobian(e, length, section):
    """Tangent stiffness d^2U/de^2 per element (of `elastic_energy`), exact.

    Args:
        e: (n, 18) element coordinates, m (r) and 1 (r_x, r_y), global frame.
        length: (n,) l, m.
        section: (n, 7) or (n, g, 7) columns SECTION_COLUMNS.

    Returns:
        (n, 18, 18).
    """
    return sheet_jacobian(e, length, section) + element.elastic_jacobian(e, length, _out_of_sheet(section))


def c_kernels():
    """The C library of shear_element_kernels.c (fmu_common.c_library), its functions typed; None when
    $WINGSIM_KERNELS selects the numpy kernels."""
    signature = (ctypes.c_int, [ctypes.c_long, ctypes.c_long, ctypes.c_void_p, ctypes.c_void_p, ctypes.c_void_p])
    return c_library.kernels(C_SOURCE, {"sheet_force": signature, "sheet_jacobian": signature})


_TABLES: dict[tuple, tuple] = {}


def _table(length, section):
    """The C kernels' table per element (shear_element_kernels.c): [E, G, weights (P,), a (P, 6), b_A (P,),
    b_B (P,)], cached per lengths and sections (at most 64 kept), its address and P."""
    length = np.ascontiguousarray(length, dtype=float)
    section = np.ascontiguousarray(section, dtype=float)
    key = (length.tobytes(), section.shape, section.tobytes())
    found = _TABLES.get(key)
    if found is None:
        if (length.ndim != 1 or section.ndim not in (2, 3) or section.shape[0] != len(length)
                or section.shape[-1] != len(SECTION_COLUMNS)):
            raise ValueError(f"shear element kernels: length {length.shape}, section {section.shape}; expected (n,), "
                             f"(n, {len(SECTION_COLUMNS)}) or (n, g, {len(SECTION_COLUMNS)})")
        if len(_TABLES) > 64:
            _TABLES.clear()
        a, b, weights = _point_basis(length, section)
        table = np.ascontiguousarray(np.concatenate([np.concatenate(_material(section), axis=1), weights,
                                                     a.reshape(len(length), -1), b[..., 2], b[..., 5]], axis=1))
        found = _TABLES[key] = (table, table.ctypes.data, weights.shape[1])
    return found


def _compiled(kernel, e, length, section, shape):
    """`kernel` of shear_element_kernels.c on e (n, 18), length (n,) and section (n, 7) or (n, g, 7): its result,
    (n, *shape)."""
    e = np.ascontiguousarray(e, dtype=float)
    if e.shape != (len(length), 18):
        raise ValueError(f"shear element kernels: e {e.shape} for {len(length)} element lengths; expected (n, 18)")
    out = np.empty((len(e), *shape))
    if len(e):
        table, address, points = _table(length, section)    # the table is held until the C call returns
        status = kernel(len(e), points, address, e.ctypes.data, out.ctypes.data)
        if status != 0:
            raise ValueError(f"the shear element C kernels refused {points} Gauss points (shear_element_kernels.c)")
    return out
