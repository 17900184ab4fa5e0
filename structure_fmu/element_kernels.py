"""Compiled ANCF element kernels (numba): the elastic force of element.py (Otsuka et al. 2019, Eqs. 4, 7-11 with
the measures of element.py's docstring), element by element and Gauss point by Gauss point, no temporaries.
Loaded by fmu_common.compiled.load, never imported directly (its cache must live in a stable folder);
element.elastic_force's numpy form is the reference (and the complex-safe one the tests differentiate).

Inputs as element.elastic_force prepares them: e (n, 18) [r^A, r_x^A, r_y^A, r^B, r_x^B, r_y^B]; length (n,) m;
stiffness (n, 4) [EA, EI_yy, EI_zz, GJ]; basis (n, 3 g, 5), the rows r', r'', r_y at the g Gauss points from
the slots [d = r^B - r^A, r_x^A, r_y^A, r_x^B, r_y^B] (element._slot_basis); weights (g,) Gauss weights on
[0, 1]; gram (3, 3) the axial strain field's Gram matrix (element.AXIAL_GRAM).
"""
import math

import numpy as np
from numba import njit


@njit(cache=True, inline="always")
def _cross(a0, a1, a2, b0, b1, b2):
    return a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0


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
        for c in range(3):
            slots[0, c] = e[m, 9 + c] - e[m, c]
            slots[1, c] = e[m, 3 + c]
            slots[2, c] = e[m, 6 + c]
            slots[3, c] = e[m, 12 + c]
            slots[4, c] = e[m, 15 + c]
        for r in range(3 * g):
            for c in range(3):
                acc = 0.0
                for s in range(5):
                    acc += basis[m, r, s] * slots[s, c]
                fields[r, c] = acc
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
        for s in range(5):
            for c in range(3):
                acc = 0.0
                for r in range(3 * g):
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
