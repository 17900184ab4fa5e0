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
 * return 0, or -1 (nothing written) when p is not in 1..MAX_POINTS.
 *
 * Arithmetic: IEEE double, each operation rounded on its own (c_library's flags: no fused multiply-add, no
 * fast-math).
 */
#define MAX_POINTS 64

static inline double dot(const double *a, const double *b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

/* r_x and r_y at point q of an element from its coordinates v (18,) and its coefficients. */
static inline void point_fields(const double *v, const double *a, double bA, double bB, double rx[3],
                                double ry[3]) {
    for (int c = 0; c < 3; c++) {
        double acc = 0.0;
        for (int j = 0; j < 6; j++) acc += a[j] * v[3 * j + c];
        rx[c] = acc;
        ry[c] = bA * v[6 + c] + bB * v[15 + c];
    }
}

int sheet_force(long n, long p, const double *table, const double *e, double *out) {
    if (p < 1 || p > MAX_POINTS) return -1;
    for (long k = 0; k < n; k++) {
        const double *t = table + k * (2 + 9 * p), *v = e + 18 * k;
        const double E = t[0], G = t[1], *w = t + 2, *a = t + 2 + p, *bA = t + 2 + 7 * p, *bB = t + 2 + 8 * p;
        double *f = out + 18 * k;
        for (int i = 0; i < 18; i++) f[i] = 0.0;
        for (long q = 0; q < p; q++) {
            double rx[3], ry[3];
            point_fields(v, a + 6 * q, bA[q], bB[q], rx, ry);
            const double e11 = 0.5 * (dot(rx, rx) - 1.0), e22 = 0.5 * (dot(ry, ry) - 1.0), gamma = dot(rx, ry);
            for (int c = 0; c < 3; c++) {
                const double gx = w[q] * (E * e11 * rx[c] + G * gamma * ry[c]);
                const double gy = w[q] * (E * e22 * ry[c] + G * gamma * rx[c]);
                for (int j = 0; j < 6; j++) f[3 * j + c] -= a[6 * q + j] * gx;
                f[6 + c] -= bA[q] * gy;
                f[15 + c] -= bB[q] * gy;
            }
        }
    }
    return 0;
}

int sheet_jacobian(long n, long p, const double *table, const double *e, double *out) {
    if (p < 1 || p > MAX_POINTS) return -1;
    for (long k = 0; k < n; k++) {
        const double *t = table + k * (2 + 9 * p), *v = e + 18 * k;
        const double E = t[0], G = t[1], *w = t + 2, *a = t + 2 + p, *bA = t + 2 + 7 * p, *bB = t + 2 + 8 * p;
        double *K = out + 324 * k;
        for (int i = 0; i < 324; i++) K[i] = 0.0;
        for (long q = 0; q < p; q++) {
            double rx[3], ry[3], hxx[3][3], hyy[3][3], hxy[3][3];
            point_fields(v, a + 6 * q, bA[q], bB[q], rx, ry);
            const double e11 = 0.5 * (dot(rx, rx) - 1.0), e22 = 0.5 * (dot(ry, ry) - 1.0), gamma = dot(rx, ry);
            for (int c = 0; c < 3; c++)
                for (int d = 0; d < 3; d++) {
                    const double eye = c == d ? 1.0 : 0.0;
                    hxx[c][d] = w[q] * (E * (rx[c] * rx[d] + e11 * eye) + G * ry[c] * ry[d]);
                    hyy[c][d] = w[q] * (E * (ry[c] * ry[d] + e22 * eye) + G * rx[c] * rx[d]);
                    hxy[c][d] = w[q] * G * (ry[c] * rx[d] + gamma * eye);   /* d/dr_x (c) d/dr_y (d) */
                }
            const double *aq = a + 6 * q;
            double b[6] = {0.0, 0.0, bA[q], 0.0, 0.0, bB[q]};
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
