/* Compiled ANCF element kernels (C): the elastic force and its tangent of element.py (Otsuka et al. 2019,
 * Eqs. 4, 7-11 with the measures of element.py's docstring), element by element and Gauss point by Gauss point,
 * scratch arrays on the stack, nothing allocated. Compiled once per machine by fmu_common/c_library.py (and into
 * every structure FMU by its build) and called through ctypes by element.elastic_force and
 * element.elastic_jacobian, whose numpy forms are the reference ($WINGSIM_KERNELS=numpy; the force's is also the
 * complex-safe one the tests differentiate); the tests check both agree to 1e-12 relative.
 *
 *   elastic_energy    out (n,): U per element, J, the elastic energy of Otsuka et al. 2019, Eq. 7 (read by the
 *                     energy monitor, an output: the step needs only its derivatives)
 *   elastic_force     out (n, 18): -dU/de per element, N (on r) and N m (on r_x, r_y), Otsuka et al. 2019,
 *                     Eq. 4, U the elastic energy of Eq. 7
 *   elastic_jacobian  out (n, 18, 18): d^2U/de^2 per element, N/m, N and N m, the exact Hessian of that energy
 *                     (Eqs. 7-11), symmetric
 *   add_elastic_force F[dofs[m, k]] += elastic_force's out[m, k]: every element's force gathered from and added
 *                     into the vectors of the whole structure, E and F (element.add_elastic_force), in one call
 *
 * Inputs of each, as element.py prepares them, C-contiguous doubles: n elements, g Gauss points; e (n, 18)
 * [r^A, r_x^A, r_y^A, r^B, r_x^B, r_y^B] (m and 1); table, the arguments that are constant in a run, one after
 * the other (g + 11 n + 17 g n numbers, element._table, element.stiffness_terms):
 *   weights (g,)         Gauss weights on [0, 1] (element.gauss_rule)
 *   length (n,)          m
 *   gram (n, 3, 3)       the axial strain field's Gram matrix weighted by EA, int_0^1 EA phi_i phi_j dxi (N)
 *   bending (n, g, 2)    [EI_yy, EI_zz] at the Gauss points (N m^2): a section may vary along the span
 *   torsion (n,)         GJ, its mean over the element (N m^2)
 *   basis (n, 3 g, 5)    the rows r', r'', r_y at the Gauss points from the slots [d = r^B - r^A, r_x^A, r_y^A,
 *                        r_x^B, r_y^B] (element._slot_basis; 1/m and 1/m^2 on r', r'')
 * Each returns 0, or -1 (nothing written) when g is not in 1..MAX_GAUSS, the size of the scratch arrays.
 *
 * The kernels assume the basis's zero pattern and skip its zeros: r' and r'' are made of the slots CURVE =
 * (d, r_x^A, r_x^B) only (the Hermite functions in x), r_y of CHORD = (r_y^A, r_y^B) only (linear in x); any
 * other entry of `basis` is ignored. tests/units/test_element.py checks element._slot_basis has exactly this
 * pattern.
 *
 * Arithmetic: IEEE double, each operation rounded on its own (c_library's flags: -ffp-contract=off, no fused
 * multiply-add; no fast-math); the terms are those of element.py's numpy forms.
 */
#include <math.h>

/* the force's and tangent's loops built for AVX-512, AVX2 and plain x86-64, as in step_kernels.c (without fused
 * multiply-add, -ffp-contract=off: every build gives the same bits) */
#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__) && defined(__ELF__)
#define VECTOR_CLONES __attribute__((target_clones("avx512f", "avx2", "default")))
#else
#define VECTOR_CLONES
#endif

#define MAX_GAUSS 8                          /* Gauss points per element the scratch arrays hold */
#define INLINE static inline __attribute__((always_inline))

static const int CURVE[3] = {0, 1, 3};       /* the slots r' and r'' are made of: d, r_x^A, r_x^B */
static const int CHORD[2] = {2, 4};          /* the slots r_y is made of: r_y^A, r_y^B */
static const int CURVE_COMPONENTS[9] = {0, 1, 2, 3, 4, 5, 9, 10, 11};   /* their 9 components among the 15 */
static const int NODE_SLOT[6] = {0, 1, 2, 0, 3, 4};    /* e's nodal vectors from the slots, r^A = -d */

/* c = a x b */
INLINE void cross(const double *a, const double *b, double *c) {
    c[0] = a[1] * b[2] - a[2] * b[1];
    c[1] = a[2] * b[0] - a[0] * b[2];
    c[2] = a[0] * b[1] - a[1] * b[0];
}

INLINE double dot(const double *a, const double *b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

/* The element's slots (5, 3) [d, x^A, y^A, x^B, y^B] from its coordinates e (18,), and its fields (3 g, 3) r',
 * r'', r_y at the Gauss points from its basis (3 g, 5). */
INLINE void slots_and_fields(const double *e, const double *basis, int g, double slots[5][3],
                             double fields[][3]) {
    for (int c = 0; c < 3; c++) {
        slots[0][c] = e[9 + c] - e[c];
        slots[1][c] = e[3 + c];
        slots[2][c] = e[6 + c];
        slots[3][c] = e[12 + c];
        slots[4][c] = e[15 + c];
    }
    for (int r = 0; r < 2 * g; r++)
        for (int c = 0; c < 3; c++) {
            double acc = 0.0;
            for (int k = 0; k < 3; k++) acc += basis[5 * r + CURVE[k]] * slots[CURVE[k]][c];
            fields[r][c] = acc;
        }
    for (int r = 2 * g; r < 3 * g; r++)
        for (int c = 0; c < 3; c++) {
            double acc = 0.0;
            for (int k = 0; k < 2; k++) acc += basis[5 * r + CHORD[k]] * slots[CHORD[k]][c];
            fields[r][c] = acc;
        }
}

/* The derivatives of the axial energy l eps^T gram eps / 2 (gram weighted by EA, symmetric) by the three strain
 * measures (eps_A, eps_B, eps_arc) = (|r_x^A| - 1, |r_x^B| - 1, arc - 1), N. */
INLINE void axial_forces(double l, double nodal_a, double nodal_b, double arc, const double *gram, double f[3]) {
    const double axial0 = nodal_a - 1.0, axial1 = nodal_b - 1.0, axial2 = arc - 1.0;
    for (int k = 0; k < 3; k++)
        f[k] = l * (axial0 * gram[k] + axial1 * gram[3 + k] + axial2 * gram[6 + k]);
}

/* The cross products the torsion is made of, tau = 1/2 [(x^A x y^A) . y^B - (x^B x y^B) . y^A] (element.py's
 * torsion measure, Otsuka et al. 2019, Eq. 11), from the slots: rows x^A x y^A, x^B x y^B, y^A x y^B,
 * y^B x x^A, y^A x x^B; returns tau. */
INLINE double torsion(double slots[5][3], double triple[5][3]) {
    cross(slots[1], slots[2], triple[0]);
    cross(slots[3], slots[4], triple[1]);
    cross(slots[2], slots[4], triple[2]);
    cross(slots[4], slots[1], triple[3]);
    cross(slots[2], slots[3], triple[4]);
    return 0.5 * (dot(triple[0], slots[4]) - dot(triple[1], slots[2]));
}

/* out (n,) = U per element (header): per Gauss point the two bendings w l (EI_yy flap^2 + EI_zz chordwise^2),
 * flap = r'' . (r' x r_y), chordwise = r'' . r_y, and the arc length; then the stretches' Gram form
 * l eps^T gram eps and the torsion GJ tau^2 / l, all halved (element.elastic_energy's terms). */
int elastic_energy(long n, long g, const double *table, const double *e, double *out) {
    if (g < 1 || g > MAX_GAUSS) return -1;
    const double *weights = table, *length = weights + g, *grams = length + n, *bending = grams + 9 * n,
                 *torsions = bending + 2 * g * n, *basis = torsions + n;
    double slots[5][3], fields[3 * MAX_GAUSS][3], normal[3], xa_ya[3], xb_yb[3];
    for (long m = 0; m < n; m++) {
        const double l = length[m], *gram = grams + 9 * m, *EI = bending + 2 * g * m;
        slots_and_fields(e + 18 * m, basis + 15 * g * m, (int)g, slots, fields);
        double arc = 0.0, bent = 0.0;
        for (int i = 0; i < g; i++) {
            const double *r1 = fields[i], *r2 = fields[g + i], *ry = fields[2 * g + i];
            cross(r1, ry, normal);
            const double flap = dot(r2, normal), chordwise = dot(r2, ry);
            arc += sqrt(dot(r1, r1)) * weights[i];
            bent += weights[i] * l * (EI[2 * i] * flap * flap + EI[2 * i + 1] * chordwise * chordwise);
        }
        const double eps[3] = {sqrt(dot(slots[1], slots[1])) - 1.0, sqrt(dot(slots[3], slots[3])) - 1.0, arc - 1.0};
        double axial = 0.0;
        for (int i = 0; i < 3; i++)
            for (int j = 0; j < 3; j++) axial += eps[i] * gram[3 * i + j] * eps[j];
        cross(slots[1], slots[2], xa_ya);
        cross(slots[3], slots[4], xb_yb);
        const double tau = 0.5 * (dot(xa_ya, slots[4]) - dot(xb_yb, slots[2]));
        out[m] = 0.5 * (bent + l * axial) + 0.5 * torsions[m] * tau * tau / l;
    }
    return 0;
}

/* out (n, 18) = -dU/de per element (header): per Gauss point the gradients by the fields r', r'', r_y of the arc
 * stretch and the two bendings, back to the slots by basis^T; then the nodal stretches and torsion. */
VECTOR_CLONES int elastic_force(long n, long g, const double *table, const double *e, double *out) {
    if (g < 1 || g > MAX_GAUSS) return -1;
    const double *weights = table, *length = weights + g, *grams = length + n, *bending = grams + 9 * n,
                 *torsions = bending + 2 * g * n, *basis = torsions + n;
    double slots[5][3], fields[3 * MAX_GAUSS][3], speeds[MAX_GAUSS], grads[3 * MAX_GAUSS][3], gslot[5][3],
           triple[5][3], f[3];
    for (long m = 0; m < n; m++) {
        const double *b = basis + 15 * g * m;
        const double l = length[m], GJ = torsions[m], *gram = grams + 9 * m, *EI = bending + 2 * g * m;
        slots_and_fields(e + 18 * m, b, (int)g, slots, fields);
        const double nodal_a = sqrt(dot(slots[1], slots[1])), nodal_b = sqrt(dot(slots[3], slots[3]));
        double arc = 0.0;
        for (int i = 0; i < g; i++) {
            speeds[i] = sqrt(dot(fields[i], fields[i]));     /* |r'| */
            arc += speeds[i] * weights[i];
        }
        axial_forces(l, nodal_a, nodal_b, arc, gram, f);
        /* dU/d(r'), dU/d(r''), dU/d(r_y) at each Gauss point */
        for (int i = 0; i < g; i++) {
            const double *r1 = fields[i], *r2 = fields[g + i], *ry = fields[2 * g + i];
            const double speed = speeds[i];
            double normal[3], ry_r2[3], r2_r1[3];
            cross(r1, ry, normal);              /* r' x r_y */
            cross(ry, r2, ry_r2);               /* r_y x r'' */
            cross(r2, r1, r2_r1);               /* r'' x r' */
            const double flap = dot(r2, normal), chordwise = dot(r2, ry);
            const double w = weights[i] * l;
            const double cf = w * EI[2 * i] * flap, cc = w * EI[2 * i + 1] * chordwise;
            const double axial = f[2] * weights[i] / speed;
            for (int c = 0; c < 3; c++) {
                grads[i][c] = axial * r1[c] + cf * ry_r2[c];
                grads[g + i][c] = cf * normal[c] + cc * ry[c];
                grads[2 * g + i][c] = cf * r2_r1[c] + cc * r2[c];
            }
        }
        for (int c = 0; c < 3; c++) {           /* back to the slots by basis^T, each slot from the rows it enters */
            for (int k = 0; k < 3; k++) {
                double acc = 0.0;
                for (int r = 0; r < 2 * g; r++) acc += b[5 * r + CURVE[k]] * grads[r][c];
                gslot[CURVE[k]][c] = acc;
            }
            for (int k = 0; k < 2; k++) {
                double acc = 0.0;
                for (int r = 2 * g; r < 3 * g; r++) acc += b[5 * r + CHORD[k]] * grads[r][c];
                gslot[CHORD[k]][c] = acc;
            }
        }
        /* nodal stretches, and torsion U_t = GJ tau^2 / (2 l) */
        const double tau = torsion(slots, triple);
        const double ct = GJ * tau / l, na = f[0] / nodal_a, nb = f[1] / nodal_b;
        double *o = out + 18 * m;
        for (int c = 0; c < 3; c++) {
            const double g_d = gslot[0][c];
            o[c] = g_d;                         /* -(-g_d) */
            o[9 + c] = -g_d;
            o[3 + c] = -(gslot[1][c] + na * slots[1][c] + ct * 0.5 * triple[2][c]);
            o[6 + c] = -(gslot[2][c] + ct * 0.5 * (triple[3][c] - triple[1][c]));
            o[12 + c] = -(gslot[3][c] + nb * slots[3][c] + ct * 0.5 * triple[2][c]);
            o[15 + c] = -(gslot[4][c] + ct * 0.5 * (triple[0][c] - triple[4][c]));
        }
    }
    return 0;
}

/* h[row + i][col + j] += value, h[row + j][col + i] -= value, and their transposes at [col, row]: one pair of a
 * skew 3 x 3 block of the symmetric matrix h (`stride` doubles per row). */
INLINE void add_skew_pair(double *h, int stride, int row, int col, int i, int j, double value) {
    h[(row + i) * stride + col + j] += value;
    h[(row + j) * stride + col + i] -= value;
    h[(col + j) * stride + row + i] += value;
    h[(col + i) * stride + row + j] -= value;
}

/* h[row:row+3, col:col+3] += coef eps_ijk v_k and its transpose at [col, row]: the Hessian block
 * d^2 [(a x b) . c] / da db = eps(c) of a triple product (element._triple_hessian). */
INLINE void add_levi_civita(double *h, int stride, int row, int col, double coef, const double *v) {
    add_skew_pair(h, stride, row, col, 0, 1, coef * v[2]);       /* eps_012 = 1 */
    add_skew_pair(h, stride, row, col, 0, 2, -coef * v[1]);      /* eps_021 = -1 */
    add_skew_pair(h, stride, row, col, 1, 2, coef * v[0]);       /* eps_120 = 1 */
}

/* out (n, 18, 18) = d^2U/de^2 per element (header). Per Gauss point the 9 x 9 Hessian over the fields (r', r'',
 * r_y) (bending outer products, the flap's Levi-Civita blocks, the chordwise identity blocks, the arc-stretch
 * projector) is mapped to the 15 slot components by kron(basis rows, I_3); then the axial Gram coupling of the
 * stretches' gradients, the nodal stretches' curvature and torsion; last the slots are spread to e (r^A = -d). */
VECTOR_CLONES int elastic_jacobian(long n, long g, const double *table, const double *e, double *out) {
    if (g < 1 || g > MAX_GAUSS) return -1;
    const double *weights = table, *length = weights + g, *grams = length + n, *bending = grams + 9 * n,
                 *torsions = bending + 2 * g * n, *basis = torsions + n;
    double slots[5][3], fields[3 * MAX_GAUSS][3], speeds[MAX_GAUSS], triple[5][3], f[3];
    double hp[9][9];                /* Hessian over (r', r'', r_y) at one Gauss point */
    double hb[9][15];               /* hp kron(B, I_3) */
    double hs[15][15];              /* Hessian over the slots [d, x^A, y^A, x^B, y^B] */
    double grad_flap[9], grad_chord[9], grad_axial[3][15], gram_grad[3][15], grad_tau[15];
    for (long m = 0; m < n; m++) {
        const double *b = basis + 15 * g * m;
        const double l = length[m], GJ = torsions[m], *gram = grams + 9 * m, *EI = bending + 2 * g * m;
        slots_and_fields(e + 18 * m, b, (int)g, slots, fields);
        const double nodal_a = sqrt(dot(slots[1], slots[1])), nodal_b = sqrt(dot(slots[3], slots[3]));
        double arc = 0.0;
        for (int k = 0; k < 3; k++)
            for (int q = 0; q < 15; q++) grad_axial[k][q] = 0.0;
        for (int i = 0; i < g; i++) {
            const double speed = sqrt(dot(fields[i], fields[i]));
            speeds[i] = speed;
            arc += speed * weights[i];
            for (int k = 0; k < 3; k++) {       /* d(eps_arc)/d(slot) = sum_i w_i u_i B_i, r' from the CURVE slots */
                const int s = CURVE[k];
                const double coef = weights[i] * b[5 * i + s] / speed;
                for (int c = 0; c < 3; c++) grad_axial[2][3 * s + c] += coef * fields[i][c];
            }
        }
        axial_forces(l, nodal_a, nodal_b, arc, gram, f);
        for (int p = 0; p < 15; p++)
            for (int q = 0; q < 15; q++) hs[p][q] = 0.0;
        for (int i = 0; i < g; i++) {
            const double *r1 = fields[i], *r2 = fields[g + i], *ry = fields[2 * g + i];
            const double speed = speeds[i];
            double normal[3], ry_r2[3], r2_r1[3];
            cross(r1, ry, normal);              /* r' x r_y */
            cross(ry, r2, ry_r2);               /* r_y x r'' */
            cross(r2, r1, r2_r1);               /* r'' x r' */
            const double w = weights[i] * l;
            const double cf = w * EI[2 * i], cc = w * EI[2 * i + 1];
            const double flap = cf * dot(r2, normal), chord = cc * dot(r2, ry);
            /* c (grad m grad m^T) of flap = (r' x r_y) . r'' (gradient [r_y x r'', n, r'' x r']) and of
             * chordwise = r'' . r_y (gradient [0, r_y, r'']), both in one pass over the upper triangle */
            for (int c = 0; c < 3; c++) {
                grad_flap[c] = ry_r2[c];
                grad_flap[3 + c] = normal[c];
                grad_flap[6 + c] = r2_r1[c];
                grad_chord[c] = 0.0;
                grad_chord[3 + c] = ry[c];
                grad_chord[6 + c] = r2[c];
            }
            for (int p = 0; p < 9; p++)
                for (int q = p; q < 9; q++)
                    hp[p][q] = hp[q][p] = cf * grad_flap[p] * grad_flap[q] + cc * grad_chord[p] * grad_chord[q];
            /* m Hess m: flap's Levi-Civita blocks (a = r', b = r_y, c = r''), chordwise's identity blocks */
            add_levi_civita(&hp[0][0], 9, 0, 6, flap, r2);
            add_levi_civita(&hp[0][0], 9, 0, 3, -flap, ry);
            add_levi_civita(&hp[0][0], 9, 6, 3, flap, r1);
            for (int p = 0; p < 3; p++) {
                hp[3 + p][6 + p] += chord;
                hp[6 + p][3 + p] += chord;
            }
            /* arc stretch: f_arc w_i (I - u u^T) / |r'| */
            const double arc_coef = f[2] * weights[i] / speed;
            for (int p = 0; p < 3; p++) {
                for (int q = 0; q < 3; q++) hp[p][q] -= arc_coef * r1[p] * r1[q] / (speed * speed);
                hp[p][p] += arc_coef;
            }
            /* to the slots: hs += kron(B, I_3)^T hp kron(B, I_3), B the rows of r', r'', r_y at this point, each
             * slot through the rows it enters (header); the upper triangle of hs only, mirrored below */
            for (int k = 0; k < 3; k++) {
                const int t = CURVE[k];
                const double b_first = b[5 * i + t], b_second = b[5 * (g + i) + t];
                for (int p = 0; p < 9; p++)
                    for (int d = 0; d < 3; d++) hb[p][3 * t + d] = b_first * hp[p][d] + b_second * hp[p][3 + d];
            }
            for (int k = 0; k < 2; k++) {
                const int t = CHORD[k];
                const double b_chord = b[5 * (2 * g + i) + t];
                for (int p = 0; p < 9; p++)
                    for (int d = 0; d < 3; d++) hb[p][3 * t + d] = b_chord * hp[p][6 + d];
            }
            for (int k = 0; k < 3; k++) {
                const int s = CURVE[k];
                const double b_first = b[5 * i + s], b_second = b[5 * (g + i) + s];
                for (int c = 0; c < 3; c++)
                    for (int q = 3 * s + c; q < 15; q++)
                        hs[3 * s + c][q] += b_first * hb[c][q] + b_second * hb[3 + c][q];
            }
            for (int k = 0; k < 2; k++) {
                const int s = CHORD[k];
                const double b_chord = b[5 * (2 * g + i) + s];
                for (int c = 0; c < 3; c++)
                    for (int q = 3 * s + c; q < 15; q++) hs[3 * s + c][q] += b_chord * hb[6 + c][q];
            }
        }
        /* axial: l grad(eps)^T gram grad(eps), and the nodal stretches' own curvature f / |r_x| (I - u u^T);
         * every stretch is a function of the CURVE slots only */
        for (int c = 0; c < 3; c++) {
            grad_axial[0][3 + c] = slots[1][c] / nodal_a;
            grad_axial[1][9 + c] = slots[3][c] / nodal_b;
        }
        for (int k = 0; k < 3; k++)
            for (int a = 0; a < 9; a++) {
                const int q = CURVE_COMPONENTS[a];
                gram_grad[k][q] = l * (gram[3 * k] * grad_axial[0][q] + gram[3 * k + 1] * grad_axial[1][q]
                                       + gram[3 * k + 2] * grad_axial[2][q]);
            }
        for (int a = 0; a < 9; a++) {
            const int p = CURVE_COMPONENTS[a];
            for (int c = a; c < 9; c++) {
                const int q = CURVE_COMPONENTS[c];
                hs[p][q] += grad_axial[0][p] * gram_grad[0][q] + grad_axial[1][p] * gram_grad[1][q]
                            + grad_axial[2][p] * gram_grad[2][q];
            }
        }
        const double na = f[0] / nodal_a, nb = f[1] / nodal_b;
        for (int p = 0; p < 3; p++) {
            for (int q = 0; q < 3; q++) {
                hs[3 + p][3 + q] -= na * grad_axial[0][3 + p] * grad_axial[0][3 + q];
                hs[9 + p][9 + q] -= nb * grad_axial[1][9 + p] * grad_axial[1][9 + q];
            }
            hs[3 + p][3 + p] += na;
            hs[9 + p][9 + p] += nb;
        }
        /* torsion: GJ / l (grad tau grad tau^T + tau Hess tau), independent of d (slot components 0-2) */
        const double tau = torsion(slots, triple);
        for (int c = 0; c < 3; c++) {
            grad_tau[c] = 0.0;
            grad_tau[3 + c] = 0.5 * triple[2][c];
            grad_tau[6 + c] = 0.5 * (triple[3][c] - triple[1][c]);
            grad_tau[9 + c] = 0.5 * triple[2][c];
            grad_tau[12 + c] = 0.5 * (triple[0][c] - triple[4][c]);
        }
        const double ct = GJ / l;
        for (int p = 3; p < 15; p++)
            for (int q = p; q < 15; q++) hs[p][q] += ct * grad_tau[p] * grad_tau[q];
        const double ctt = 0.5 * ct * tau;
        add_levi_civita(&hs[0][0], 15, 3, 6, ctt, slots[4]);       /* (xA x yA) . yB: a = xA, b = yA, c = yB */
        add_levi_civita(&hs[0][0], 15, 3, 12, -ctt, slots[2]);
        add_levi_civita(&hs[0][0], 15, 6, 12, ctt, slots[1]);
        add_levi_civita(&hs[0][0], 15, 9, 12, -ctt, slots[2]);     /* -(xB x yB) . yA: a = xB, b = yB, c = yA */
        add_levi_civita(&hs[0][0], 15, 9, 6, ctt, slots[4]);
        add_levi_civita(&hs[0][0], 15, 12, 6, -ctt, slots[3]);
        for (int p = 0; p < 15; p++)
            for (int q = 0; q < p; q++) hs[p][q] = hs[q][p];
        /* e's nodal vectors [r^A, r_x^A, r_y^A, r^B, r_x^B, r_y^B] from the slots [d, x^A, y^A, x^B, y^B] */
        double *o = out + 324 * m;
        for (int u = 0; u < 6; u++)
            for (int v = 0; v < 6; v++) {
                const double sign = (u == 0 ? -1.0 : 1.0) * (v == 0 ? -1.0 : 1.0);
                const int su = NODE_SLOT[u], sv = NODE_SLOT[v];
                for (int c = 0; c < 3; c++)
                    for (int d = 0; d < 3; d++) o[(3 * u + c) * 18 + 3 * v + d] = sign * hs[3 * su + c][3 * sv + d];
            }
    }
    return 0;
}

/* F[dofs[i]] += elastic_force(E[dofs])[i], i over the n x 18 element coordinates: dofs (n, 18) int64 indices into E
 * and F, scratch 36 n doubles (the gathered e and the forces). Returns elastic_force's status (F untouched on -1). */
int add_elastic_force(long n, long g, const double *table, const double *E, const long long *dofs, double *scratch,
                      double *F) {
    double *e = scratch, *f = scratch + 18 * n;
    for (long i = 0; i < 18 * n; i++) e[i] = E[dofs[i]];
    const int status = elastic_force(n, g, table, e, f);
    if (status != 0) return status;
    for (long i = 0; i < 18 * n; i++) F[dofs[i]] += f[i];
    return 0;
}
