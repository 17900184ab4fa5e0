/* Compiled kernels of the shear-deformable element's sheet (C): the elastic force and its tangent of
 * shear_element.sheet_force and shear_element.sheet_jacobian (Peng et al. 2019, Eqs. 5-10 with the engineering
 * shear strain and lambda = 0, in 3D), element by element and Gauss point by Gauss point, nothing allocated.
 * Compiled once per machine by fmu_common/c_library.py (and into every structure FMU by its build) and called
 * through ctypes; the numpy forms are the reference ($WINGSIM_KERNELS=numpy) and the tests check both agree to
 * 1e-12 relative.
 *
 *   sheet_force     out (n, 18): -dU/de per element, N (on r) and N m (on r_x, r_y)
 *   sheet_jacobian  out (n, 18, 18): d^2U/de^2 per element, the exact Hessian, symmetric
 *
 * with U = sum_p w_p W(r_x, r_y), W = 1/2 (E eps_11^2 + E eps_22^2 + G gamma^2), eps_11 = (r_x . r_x - 1) / 2,
 * eps_22 = (r_y . r_y - 1) / 2, gamma = r_x . r_y, and at each point r_x = sum_j a_j v_j,
 * r_y = b_A r_y^A + b_B r_y^B on the nodal vectors v = [r^A, r_x^A, r_y^A, r^B, r_x^B, r_y^B].
 *
 * Inputs of both, C-contiguous doubles: n elements, p Gauss points per element; table (n, 2 + 9 p), per element
 * [E (Pa), G (Pa), w (p,) m^3, a (p, 6), b_A (p,), b_B (p,)] (shear_element._table); e (n, 18) (m and 1). Both
 * return 0, or -1 (nothing written) when p < 1.
 *
 * Arithmetic: IEEE double, each operation rounded on its own (c_library's flags: no fused multiply-add, no
 * fast-math).
 */
static inline double dot(const double *a, const double *b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

/* One element's row of the table: E, G (Pa) and the arrays of its p points. */
typedef struct {
    double E, G;
    const double *w, *a, *bA, *bB;
} Table;

static inline Table table_row(const double *table, long k, long p) {
    const double *t = table + k * (2 + 9 * p);
    Table row = {t[0], t[1], t + 2, t + 2 + p, t + 2 + 7 * p, t + 2 + 8 * p};
    return row;
}

/* r_x, r_y and the strains eps_11, eps_22, gamma at point q of an element from its coordinates v (18,). */
static inline void point_strains(const double *v, Table s, long q, double rx[3], double ry[3], double *e11,
                                 double *e22, double *gamma) {
    const double *a = s.a + 6 * q;
    for (int c = 0; c < 3; c++) {
        double acc = 0.0;
        for (int j = 0; j < 6; j++) acc += a[j] * v[3 * j + c];
        rx[c] = acc;
        ry[c] = s.bA[q] * v[6 + c] + s.bB[q] * v[15 + c];
    }
    *e11 = 0.5 * (dot(rx, rx) - 1.0);
    *e22 = 0.5 * (dot(ry, ry) - 1.0);
    *gamma = dot(rx, ry);
}

int sheet_force(long n, long p, const double *table, const double *e, double *out) {
    if (p < 1) return -1;
    for (long k = 0; k < n; k++) {
        const Table s = table_row(table, k, p);
        const double *v = e + 18 * k, E = s.E, G = s.G;
        double *f = out + 18 * k;
        for (int i = 0; i < 18; i++) f[i] = 0.0;
        for (long q = 0; q < p; q++) {
            double rx[3], ry[3], e11, e22, gamma;
            point_strains(v, s, q, rx, ry, &e11, &e22, &gamma);
            for (int c = 0; c < 3; c++) {
                const double gx = s.w[q] * (E * e11 * rx[c] + G * gamma * ry[c]);
                const double gy = s.w[q] * (E * e22 * ry[c] + G * gamma * rx[c]);
                for (int j = 0; j < 6; j++) f[3 * j + c] -= s.a[6 * q + j] * gx;
                f[6 + c] -= s.bA[q] * gy;
                f[15 + c] -= s.bB[q] * gy;
            }
        }
    }
    return 0;
}

int sheet_jacobian(long n, long p, const double *table, const double *e, double *out) {
    if (p < 1) return -1;
    for (long k = 0; k < n; k++) {
        const Table s = table_row(table, k, p);
        const double *v = e + 18 * k, E = s.E, G = s.G, *w = s.w;
        double *K = out + 324 * k;
        for (int i = 0; i < 324; i++) K[i] = 0.0;
        for (long q = 0; q < p; q++) {
            double rx[3], ry[3], hxx[3][3], hyy[3][3], hxy[3][3], e11, e22, gamma;
            point_strains(v, s, q, rx, ry, &e11, &e22, &gamma);
            for (int c = 0; c < 3; c++)
                for (int d = 0; d < 3; d++) {
                    const double eye = c == d ? 1.0 : 0.0;
                    hxx[c][d] = w[q] * (E * (rx[c] * rx[d] + e11 * eye) + G * ry[c] * ry[d]);
                    hyy[c][d] = w[q] * (E * (ry[c] * ry[d] + e22 * eye) + G * rx[c] * rx[d]);
                    hxy[c][d] = w[q] * G * (ry[c] * rx[d] + gamma * eye);   /* d/dr_x (c) d/dr_y (d) */
                }
            const double *aq = s.a + 6 * q;
            const double b[6] = {0.0, 0.0, s.bA[q], 0.0, 0.0, s.bB[q]};
            for (int i = 0; i < 6; i++)
                for (int j = 0; j < 6; j++) {
                    const double xx = aq[i] * aq[j], yy = b[i] * b[j], xy = aq[i] * b[j], yx = b[i] * aq[j];
                    if (xx == 0.0 && yy == 0.0 && xy == 0.0 && yx == 0.0) continue;
                    for (int c = 0; c < 3; c++)
                        for (int d = 0; d < 3; d++)
                            K[(3 * i + c) * 18 + 3 * j + d] += xx * hxx[c][d] + yy * hyy[c][d] + xy * hxy[c][d]
                                                               + yx * hxy[d][c];
                }
        }
    }
    return 0;
}
