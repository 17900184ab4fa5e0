"""Compiled ANCF element kernels (numba): the elastic force and its tangent of element.py (Otsuka et al. 2019,
Eqs. 4, 7-11 with the measures of element.py's docstring), element by element and Gauss point by Gauss point,
no temporaries beyond small scratch arrays allocated once per call. Loaded by fmu_common.compiled.load, never
imported directly (its cache must live in a stable folder); element.elastic_force's and
element.elastic_jacobian's numpy forms are the reference (the force's is also the complex-safe one the tests
differentiate).

Inputs of both, as element.elastic_force prepares them: e (n, 18) [r^A, r_x^A, r_y^A, r^B, r_x^B, r_y^B];
length (n,) m; stiffness (n, 4) [EA, EI_yy, EI_zz, GJ]; basis (n, 3 g, 5), the rows r', r'', r_y at the g Gauss
points from the slots [d = r^B - r^A, r_x^A, r_y^A, r_x^B, r_y^B] (element._slot_basis); weights (g,) Gauss
weights on [0, 1]; gram (3, 3) the axial strain field's Gram matrix (element.AXIAL_GRAM).

The kernels assume the basis's zero pattern and skip its zeros: r' and r'' are made of the slots CURVE =
(d, r_x^A, r_x^B) only (the Hermite functions in x), r_y of CHORD = (r_y^A, r_y^B) only (linear in x); any
other entry of `basis` is ignored. tests/units/test_element.py checks element._slot_basis has exactly this
pattern.
"""
import math

import numpy as np
from numba import njit

CURVE = (0, 1, 3)       # the slots r' and r'' are made of: d, r_x^A, r_x^B
CHORD = (2, 4)          # the slots r_y is made of: r_y^A, r_y^B
_CURVE_COMPONENTS = (0, 1, 2, 3, 4, 5, 9, 10, 11)       # their 9 components among the 15 slot components


@njit(cache=True, inline="always")
def _cross(a0, a1, a2, b0, b1, b2):
    return a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0


@njit(cache=True, inline="always")
def _slots_and_fields(e, basis, m, g, slots, fields):
    """Element m's slots (5, 3) [d, x^A, y^A, x^B, y^B] and its fields (3 g, 3) r', r'', r_y at the Gauss
    points, written into `slots` and `fields`."""
    for c in range(3):
        slots[0, c] = e[m, 9 + c] - e[m, c]
        slots[1, c] = e[m, 3 + c]
        slots[2, c] = e[m, 6 + c]
        slots[3, c] = e[m, 12 + c]
        slots[4, c] = e[m, 15 + c]
    for r in range(2 * g):
        for c in range(3):
            acc = 0.0
            for s in CURVE:
                acc += basis[m, r, s] * slots[s, c]
            fields[r, c] = acc
    for r in range(2 * g, 3 * g):
        for c in range(3):
            acc = 0.0
            for s in CHORD:
                acc += basis[m, r, s] * slots[s, c]
            fields[r, c] = acc


@njit(cache=True)
def elastic_force(e, length, stiffness, basis, weights, gram):
    """-dU/de per element (n, 18), N and N m: element.elastic_force's gradient, the same terms in the same
    order."""
    n, g = e.shape[0], weights.shape[0]
    out = np.empty((n, 18))
    slots = np.empty((5, 3))
    fields = np.empty((3 * g, 3))
    grads = np.empty((3 * g, 3))
    gslot = np.empty((5, 3))
    for m in range(n):
        l = length[m]
        EA, EIy, EIz, GJ = stiffness[m, 0], stiffness[m, 1], stiffness[m, 2], stiffness[m, 3]
        _slots_and_fields(e, basis, m, g, slots, fields)
        xA0, xA1, xA2 = slots[1, 0], slots[1, 1], slots[1, 2]
        yA0, yA1, yA2 = slots[2, 0], slots[2, 1], slots[2, 2]
        xB0, xB1, xB2 = slots[3, 0], slots[3, 1], slots[3, 2]
        yB0, yB1, yB2 = slots[4, 0], slots[4, 1], slots[4, 2]
        nodal_a = math.sqrt(xA0 * xA0 + xA1 * xA1 + xA2 * xA2)
        nodal_b = math.sqrt(xB0 * xB0 + xB1 * xB1 + xB2 * xB2)
        arc = 0.0
        for i in range(g):
            arc += math.sqrt(fields[i, 0] ** 2 + fields[i, 1] ** 2 + fields[i, 2] ** 2) * weights[i]
        axial0, axial1, axial2 = nodal_a - 1.0, nodal_b - 1.0, arc - 1.0
        f0 = EA * l * (axial0 * gram[0, 0] + axial1 * gram[1, 0] + axial2 * gram[2, 0])
        f1 = EA * l * (axial0 * gram[0, 1] + axial1 * gram[1, 1] + axial2 * gram[2, 1])
        f2 = EA * l * (axial0 * gram[0, 2] + axial1 * gram[1, 2] + axial2 * gram[2, 2])
        for i in range(g):
            r1 = fields[i]
            r2 = fields[g + i]
            ry = fields[2 * g + i]
            speed = math.sqrt(r1[0] ** 2 + r1[1] ** 2 + r1[2] ** 2)
            n0, n1, n2 = _cross(r1[0], r1[1], r1[2], ry[0], ry[1], ry[2])                 # r' x r_y
            a0, a1, a2 = _cross(ry[0], ry[1], ry[2], r2[0], r2[1], r2[2])                 # r_y x r''
            b0, b1, b2 = _cross(r2[0], r2[1], r2[2], r1[0], r1[1], r1[2])                 # r'' x r'
            flap = r2[0] * n0 + r2[1] * n1 + r2[2] * n2
            chordwise = r2[0] * ry[0] + r2[1] * ry[1] + r2[2] * ry[2]
            w = weights[i] * l
            cf = w * EIy * flap
            cc = w * EIz * chordwise
            axial = f2 * weights[i] / speed
            grads[i, 0] = axial * r1[0] + cf * a0
            grads[i, 1] = axial * r1[1] + cf * a1
            grads[i, 2] = axial * r1[2] + cf * a2
            grads[g + i, 0] = cf * n0 + cc * ry[0]
            grads[g + i, 1] = cf * n1 + cc * ry[1]
            grads[g + i, 2] = cf * n2 + cc * ry[2]
            grads[2 * g + i, 0] = cf * b0 + cc * r2[0]
            grads[2 * g + i, 1] = cf * b1 + cc * r2[1]
            grads[2 * g + i, 2] = cf * b2 + cc * r2[2]
        for c in range(3):              # back to the slots by basis^T, each slot from the rows it enters
            for s in CURVE:
                acc = 0.0
                for r in range(2 * g):
                    acc += basis[m, r, s] * grads[r, c]
                gslot[s, c] = acc
            for s in CHORD:
                acc = 0.0
                for r in range(2 * g, 3 * g):
                    acc += basis[m, r, s] * grads[r, c]
                gslot[s, c] = acc
        # nodal stretches and torsion (tau = 1/2 [(x_A x y_A) . y_B - (x_B x y_B) . y_A], U_t = GJ tau^2 / (2 l))
        xAyA = _cross(xA0, xA1, xA2, yA0, yA1, yA2)
        xByB = _cross(xB0, xB1, xB2, yB0, yB1, yB2)
        yAyB = _cross(yA0, yA1, yA2, yB0, yB1, yB2)
        yBxA = _cross(yB0, yB1, yB2, xA0, xA1, xA2)
        yAxB = _cross(yA0, yA1, yA2, xB0, xB1, xB2)
        tau = 0.5 * ((xAyA[0] * yB0 + xAyA[1] * yB1 + xAyA[2] * yB2) - (xByB[0] * yA0 + xByB[1] * yA1 + xByB[2] * yA2))
        ct = GJ * tau / l
        na, nb = f0 / nodal_a, f1 / nodal_b
        x_a = (xA0, xA1, xA2)
        x_b = (xB0, xB1, xB2)
        for c in range(3):
            g_d = gslot[0, c]
            out[m, c] = g_d                                                   # -(-g_d)
            out[m, 9 + c] = -g_d
            out[m, 3 + c] = -(gslot[1, c] + na * x_a[c] + ct * 0.5 * yAyB[c])
            out[m, 6 + c] = -(gslot[2, c] + ct * 0.5 * (yBxA[c] - xByB[c]))
            out[m, 12 + c] = -(gslot[3, c] + nb * x_b[c] + ct * 0.5 * yAyB[c])
            out[m, 15 + c] = -(gslot[4, c] + ct * 0.5 * (xAyA[c] - yAxB[c]))
    return out


@njit(cache=True, inline="always")
def _add_skew_pair(h, row, col, i, j, value):
    """The entries (i, j) = value and (j, i) = -value of a skew block at [row, col], and their transposes at
    [col, row]."""
    h[row + i, col + j] += value
    h[row + j, col + i] -= value
    h[col + j, row + i] += value
    h[col + i, row + j] -= value


@njit(cache=True, inline="always")
def _add_levi_civita(h, row, col, coef, v0, v1, v2):
    """h[row:row+3, col:col+3] += coef eps_ijk v_k and its transpose at [col, row]: the Hessian block
    d^2 [(a x b) . c] / da db = eps(c) of a triple product (element._triple_hessian)."""
    _add_skew_pair(h, row, col, 0, 1, coef * v2)       # eps_012 = 1
    _add_skew_pair(h, row, col, 0, 2, -coef * v1)      # eps_021 = -1
    _add_skew_pair(h, row, col, 1, 2, coef * v0)       # eps_120 = 1


@njit(cache=True)
def elastic_jacobian(e, length, stiffness, basis, weights, gram):
    """d^2U/de^2 per element (n, 18, 18), N/m, N and N m: element.elastic_jacobian's exact Hessian of the
    elastic energy, the same terms. Per Gauss point the 9 x 9 Hessian over the fields (r', r'', r_y) (bending
    outer products, the flap's Levi-Civita blocks, the chordwise identity blocks, the arc-stretch projector) is
    mapped to the 15 slot components by kron(basis rows, I_3); then the axial Gram coupling of the stretches'
    gradients, the nodal stretches' curvature and torsion; last the slots are spread to e (r^A = -d)."""
    n, g = e.shape[0], weights.shape[0]
    out = np.empty((n, 18, 18))
    slots = np.empty((5, 3))
    fields = np.empty((3 * g, 3))
    speeds = np.empty(g)            # |r'| at the Gauss points
    hp = np.empty((9, 9))           # Hessian over (r', r'', r_y) at one Gauss point
    hb = np.empty((9, 15))          # hp kron(B, I_3)
    hs = np.empty((15, 15))         # Hessian over the slots [d, x^A, y^A, x^B, y^B]
    grad_flap = np.empty(9)
    grad_chord = np.empty(9)
    grad_axial = np.empty((3, 15))
    gram_grad = np.zeros((3, 15))   # EA l gram grad_axial
    grad_tau = np.zeros(15)
    for m in range(n):
        l = length[m]
        EA, EIy, EIz, GJ = stiffness[m, 0], stiffness[m, 1], stiffness[m, 2], stiffness[m, 3]
        _slots_and_fields(e, basis, m, g, slots, fields)
        xA0, xA1, xA2 = slots[1, 0], slots[1, 1], slots[1, 2]
        yA0, yA1, yA2 = slots[2, 0], slots[2, 1], slots[2, 2]
        xB0, xB1, xB2 = slots[3, 0], slots[3, 1], slots[3, 2]
        yB0, yB1, yB2 = slots[4, 0], slots[4, 1], slots[4, 2]
        nodal_a = math.sqrt(xA0 * xA0 + xA1 * xA1 + xA2 * xA2)
        nodal_b = math.sqrt(xB0 * xB0 + xB1 * xB1 + xB2 * xB2)
        arc = 0.0
        grad_axial[:, :] = 0.0
        for i in range(g):
            speed = math.sqrt(fields[i, 0] ** 2 + fields[i, 1] ** 2 + fields[i, 2] ** 2)
            speeds[i] = speed
            arc += speed * weights[i]
            for s in CURVE:             # d(eps_arc)/d(slot) = sum_i w_i u_i B_i, r' from the CURVE slots
                coef = weights[i] * basis[m, i, s] / speed
                for c in range(3):
                    grad_axial[2, 3 * s + c] += coef * fields[i, c]
        axial0, axial1, axial2 = nodal_a - 1.0, nodal_b - 1.0, arc - 1.0
        f0 = EA * l * (axial0 * gram[0, 0] + axial1 * gram[1, 0] + axial2 * gram[2, 0])
        f1 = EA * l * (axial0 * gram[0, 1] + axial1 * gram[1, 1] + axial2 * gram[2, 1])
        f2 = EA * l * (axial0 * gram[0, 2] + axial1 * gram[1, 2] + axial2 * gram[2, 2])
        hs[:, :] = 0.0
        for i in range(g):
            r1 = fields[i]
            r2 = fields[g + i]
            ry = fields[2 * g + i]
            speed = speeds[i]
            n0, n1, n2 = _cross(r1[0], r1[1], r1[2], ry[0], ry[1], ry[2])                 # r' x r_y
            a0, a1, a2 = _cross(ry[0], ry[1], ry[2], r2[0], r2[1], r2[2])                 # r_y x r''
            b0, b1, b2 = _cross(r2[0], r2[1], r2[2], r1[0], r1[1], r1[2])                 # r'' x r'
            w = weights[i] * l
            cf, cc = w * EIy, w * EIz
            flap = cf * (r2[0] * n0 + r2[1] * n1 + r2[2] * n2)
            chord = cc * (r2[0] * ry[0] + r2[1] * ry[1] + r2[2] * ry[2])
            # c (grad m grad m^T) of flap = (r' x r_y) . r'' (gradient [r_y x r'', n, r'' x r']) and of
            # chordwise = r'' . r_y (gradient [0, r_y, r'']), both in one pass over the upper triangle
            grad_flap[0], grad_flap[1], grad_flap[2] = a0, a1, a2
            grad_flap[3], grad_flap[4], grad_flap[5] = n0, n1, n2
            grad_flap[6], grad_flap[7], grad_flap[8] = b0, b1, b2
            for p in range(3):
                grad_chord[p] = 0.0
                grad_chord[3 + p] = ry[p]
                grad_chord[6 + p] = r2[p]
            for p in range(9):
                for q in range(p, 9):
                    hp[p, q] = hp[q, p] = cf * grad_flap[p] * grad_flap[q] + cc * grad_chord[p] * grad_chord[q]
            # m Hess m: flap's Levi-Civita blocks (a = r', b = r_y, c = r''), chordwise's identity blocks
            _add_levi_civita(hp, 0, 6, flap, r2[0], r2[1], r2[2])
            _add_levi_civita(hp, 0, 3, -flap, ry[0], ry[1], ry[2])
            _add_levi_civita(hp, 6, 3, flap, r1[0], r1[1], r1[2])
            for p in range(3):
                hp[3 + p, 6 + p] += chord
                hp[6 + p, 3 + p] += chord
            # arc stretch: f_arc w_i (I - u u^T) / |r'|
            arc_coef = f2 * weights[i] / speed
            for p in range(3):
                for q in range(3):
                    hp[p, q] -= arc_coef * r1[p] * r1[q] / (speed * speed)
                hp[p, p] += arc_coef
            # to the slots: hs += kron(B, I_3)^T hp kron(B, I_3), B the rows of r', r'', r_y at this point, each
            # slot through the rows it enters (module docstring); the upper triangle of hs only, mirrored below
            for t in CURVE:
                b_first, b_second = basis[m, i, t], basis[m, g + i, t]
                for p in range(9):
                    for d in range(3):
                        hb[p, 3 * t + d] = b_first * hp[p, d] + b_second * hp[p, 3 + d]
            for t in CHORD:
                b_chord = basis[m, 2 * g + i, t]
                for p in range(9):
                    for d in range(3):
                        hb[p, 3 * t + d] = b_chord * hp[p, 6 + d]
            for s in CURVE:
                b_first, b_second = basis[m, i, s], basis[m, g + i, s]
                for c in range(3):
                    for q in range(3 * s + c, 15):
                        hs[3 * s + c, q] += b_first * hb[c, q] + b_second * hb[3 + c, q]
            for s in CHORD:
                b_chord = basis[m, 2 * g + i, s]
                for c in range(3):
                    for q in range(3 * s + c, 15):
                        hs[3 * s + c, q] += b_chord * hb[6 + c, q]
        # axial: EA l grad(eps)^T gram grad(eps), and the nodal stretches' own curvature f / |r_x| (I - u u^T);
        # every stretch is a function of the CURVE slots only
        for c in range(3):
            grad_axial[0, 3 + c] = slots[1, c] / nodal_a
            grad_axial[1, 9 + c] = slots[3, c] / nodal_b
        for k in range(3):
            for q in _CURVE_COMPONENTS:
                gram_grad[k, q] = EA * l * (gram[k, 0] * grad_axial[0, q] + gram[k, 1] * grad_axial[1, q]
                                            + gram[k, 2] * grad_axial[2, q])
        for a in range(9):
            p = _CURVE_COMPONENTS[a]
            for b in range(a, 9):
                q = _CURVE_COMPONENTS[b]
                hs[p, q] += (grad_axial[0, p] * gram_grad[0, q] + grad_axial[1, p] * gram_grad[1, q]
                             + grad_axial[2, p] * gram_grad[2, q])
        na, nb = f0 / nodal_a, f1 / nodal_b
        for p in range(3):
            for q in range(3):
                hs[3 + p, 3 + q] -= na * grad_axial[0, 3 + p] * grad_axial[0, 3 + q]
                hs[9 + p, 9 + q] -= nb * grad_axial[1, 9 + p] * grad_axial[1, 9 + q]
            hs[3 + p, 3 + p] += na
            hs[9 + p, 9 + p] += nb
        # torsion: GJ / l (grad tau grad tau^T + tau Hess tau), tau = 1/2 [(xA x yA) . yB - (xB x yB) . yA],
        # independent of d (slot components 0-2)
        xAyA = _cross(xA0, xA1, xA2, yA0, yA1, yA2)
        xByB = _cross(xB0, xB1, xB2, yB0, yB1, yB2)
        yAyB = _cross(yA0, yA1, yA2, yB0, yB1, yB2)
        yBxA = _cross(yB0, yB1, yB2, xA0, xA1, xA2)
        yAxB = _cross(yA0, yA1, yA2, xB0, xB1, xB2)
        tau = 0.5 * ((xAyA[0] * yB0 + xAyA[1] * yB1 + xAyA[2] * yB2) - (xByB[0] * yA0 + xByB[1] * yA1 + xByB[2] * yA2))
        for c in range(3):
            grad_tau[3 + c] = 0.5 * yAyB[c]
            grad_tau[6 + c] = 0.5 * (yBxA[c] - xByB[c])
            grad_tau[9 + c] = 0.5 * yAyB[c]
            grad_tau[12 + c] = 0.5 * (xAyA[c] - yAxB[c])
        ct = GJ / l
        for p in range(3, 15):
            for q in range(p, 15):
                hs[p, q] += ct * grad_tau[p] * grad_tau[q]
        ctt = 0.5 * ct * tau
        _add_levi_civita(hs, 3, 6, ctt, yB0, yB1, yB2)        # (xA x yA) . yB: a = xA, b = yA, c = yB
        _add_levi_civita(hs, 3, 12, -ctt, yA0, yA1, yA2)
        _add_levi_civita(hs, 6, 12, ctt, xA0, xA1, xA2)
        _add_levi_civita(hs, 9, 12, -ctt, yA0, yA1, yA2)      # -(xB x yB) . yA: a = xB, b = yB, c = yA
        _add_levi_civita(hs, 9, 6, ctt, yB0, yB1, yB2)
        _add_levi_civita(hs, 12, 6, -ctt, xB0, xB1, xB2)
        for p in range(15):
            for q in range(p):
                hs[p, q] = hs[q, p]
        # e's nodal vectors [r^A, r_x^A, r_y^A, r^B, r_x^B, r_y^B] from the slots [d, x^A, y^A, x^B, y^B], r^A = -d
        for u in range(6):
            su = (0, 1, 2, 0, 3, 4)[u]
            sign_u = -1.0 if u == 0 else 1.0
            for v in range(6):
                sv = (0, 1, 2, 0, 3, 4)[v]
                sign = sign_u * (-1.0 if v == 0 else 1.0)
                for c in range(3):
                    for d in range(3):
                        out[m, 3 * u + c, 3 * v + d] = sign * hs[3 * su + c, 3 * sv + d]
    return out
