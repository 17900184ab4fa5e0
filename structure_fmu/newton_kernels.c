/* Generalized-alpha's Newton iteration on the ANCF structure in C: one call per correction and one per
 * factorization of the iteration matrix, on buffers allocated once (newton_kernel.py). The reference is the numpy
 * path of model.StructureModel (force_q, mass_product, constraint_*, iteration_matrix) with iteration_lu.IterationLU
 * ($WINGSIM_KERNELS=numpy); the tests compare both (tests/units/test_newton_kernel.py).
 *
 * The model (Otsuka et al. 2019, Eq. 4; Peng et al. 2019, Eqs. 23-25 and Fig. 3):
 *   E = T q + P p, E' = T q' + P p' (T by its nonzero entries, CSR by rows of E; the prescribed parts set per step)
 *   F(E, E') = f_constant + elastic(E) - sum_h torque_h grad_h    (gravity, point loads and Q in f_constant)
 *   residual = M_q q'' - T^T F + C_q q' + r_constant + G_q^T lambda,   beta' Phi
 * with the ANCF elastic force and its Hessian from element_kernels.c (passed in as function pointers), the
 * chord-axis hinges' spring actuators (joints.fold_angle_gradient, joints.actuator_torque), the mass-proportional
 * damping as its reduced matrix C_q, the prescribed motion's inertia T^T M_E P p'' in r_constant, and the
 * constraint rows: unit length and orthogonality Phi_i = c_i X_a . X_b + c0_i, then the linear rows L E - c
 * (constraints.Constraints). The iteration matrix [[S, beta' G^T], [beta' G, 0]],
 *   S = T^T (K_elastic + sum_i lambda_i H_i + sum_h (k_h + gamma' c_h) grad_h grad_h^T) T + gamma' C_q + beta' M_q,
 * is summed in the reference's order (the assembly's entries in turn, then gamma' C_q, then beta' M_q), so S and G
 * are the reference's bit for bit, gathered into LAPACK's band (or dense) storage and factorized by LAPACK
 * (scipy's, through function pointers). The residual's sums run in another order than numpy's products: it agrees
 * with the reference to round-off.
 *
 * Arithmetic: IEEE double, built with -ffp-contract=off like the other kernels.
 */
#include <math.h>
#include <string.h>

typedef int (*elastic_add_t)(long n, long g, const double *table, const double *E, const long long *dofs,
                             double *scratch, double *F);
typedef int (*elastic_jacobian_t)(long n, long g, const double *table, const double *e, double *out);
typedef void (*gbtrf_t)(int *m, int *n, int *kl, int *ku, double *ab, int *ldab, int *ipiv, int *info);
typedef void (*gbtrs_t)(char *trans, int *n, int *kl, int *ku, int *nrhs, double *ab, int *ldab, int *ipiv,
                        double *b, int *ldb, int *info);
typedef void (*getrf_t)(int *m, int *n, double *a, int *lda, int *ipiv, int *info);
typedef void (*getrs_t)(char *trans, int *n, int *nrhs, double *a, int *lda, int *ipiv, double *b, int *ldb,
                        int *info);

/* What the iteration reads and writes; every array C-contiguous, allocated by newton_kernel.py. */
typedef struct {
    long n, n_q, m;                  /* lengths of E and q, constraint rows */
    const long *t_ptr, *t_col;       /* T: CSR over the n rows of E */
    const double *t_val;
    const double *offset;            /* (n,) P p of the step */
    const double *rate_offset;       /* (n,) P p' of the step */
    const double *f_constant;        /* (n,) gravity, point loads and Q of the step, N and N m */
    const double *r_constant;        /* (n_q,) the residual's terms that are constant over the step */
    const long *m_ptr, *m_col;       /* M_q: CSR (n_q rows) */
    const double *m_val;
    const double *mass;              /* (n_q, n_q) M_q dense, for the iteration matrix */
    long damped;                     /* 1: C_q below */
    const long *c_ptr, *c_col;       /* C_q: CSR (n_q rows) */
    const double *c_val;
    const double *damping;           /* (n_q, n_q) C_q dense */
    /* elastic force and Hessian (element_kernels.c) */
    long n_elements, gauss;
    const double *table;             /* element._table */
    const long long *dofs;           /* (n_elements, 18) */
    elastic_add_t add_elastic_force;
    elastic_jacobian_t elastic_jacobian;
    double *element_scratch;         /* (36 n_elements,) */
    /* hinges (chord axis): idx (n_hinges, 9) into E; per hinge stiffness (N m/rad), its angle offset (rad),
       damping (N m s/rad) and constant torque (N m), set per step (the latch) */
    long n_hinges;
    const long *hinge_index;
    const double *hinge_parameters;  /* (n_hinges, 4): k, theta_0, c, T_const: torque k (theta - theta_0) + c theta' + T */
    /* the first n_products rows X_a . X_b: ia, ib (n_products, 3) E indices, coefficient, constant */
    long n_products;
    const long *row_a, *row_b;
    const double *row_coefficient, *row_constant;
    /* G_q: entries (source into the gathered pairs [X_a, X_b] of the rows (m, 6), target row * n_q + col, weight) */
    long n_jacobian;
    const long *pair, *jacobian_source, *jacobian_target;
    const double *jacobian_weight;
    /* the linear rows after them: L (CSR over E), c, and L T (CSR over q) */
    const long *l_ptr, *l_col, *lt_ptr, *lt_col;
    const double *l_val, *l_offset, *lt_val;
    /* the iteration matrix: its values (elastic blocks, lambda[hessian_row], hinge blocks) into S by the assembly */
    long n_values, n_assembly;
    const long *hessian_row;         /* (n_hessian,) the multiplier of each Hessian entry */
    long n_hessian;
    const long *assembly_source, *assembly_target;
    const double *assembly_weight;
    /* the factorization's storage: S entries (factor position, S flat), G and G^T entries (factor position, G flat) */
    long banded, lower, upper, rows;  /* band: LAPACK's (2 kl + ku + 1, n_q + m); dense: rows = n_q + m */
    long n_s, n_g;
    const long *s_target, *s_source, *g_target, *g_source, *gt_target, *gt_source;
    const long *order;               /* banded: the unknowns' order */
    gbtrf_t gbtrf; gbtrs_t gbtrs; getrf_t getrf; getrs_t getrs;
    /* work arrays */
    double *E, *dE, *F, *values, *S, *G, *rhs, *ordered;
} NewtonKernel;

/* E = T q + offset (offset NULL: none), dE likewise. */
static void coordinates(const NewtonKernel *s, const double *q, const double *offset, double *E) {
    for (long i = 0; i < s->n; i++) {
        double acc = offset ? offset[i] : 0.0;
        for (long k = s->t_ptr[i]; k < s->t_ptr[i + 1]; k++) acc += s->t_val[k] * q[s->t_col[k]];
        E[i] = acc;
    }
}

/* theta and d theta/dx (9,) of a chord-axis hinge, x = [a, b, n] (joints.fold_angle_gradient, its arithmetic);
 * returns 0, or 1 when s = c = 0 (no angle: the caller reports a divergence, as the NaN of the reference). */
static int fold_angle_gradient(const double *x, double *theta, double *grad) {
    const double a0 = x[0], a1 = x[1], a2 = x[2], b0 = x[3], b1 = x[4], b2 = x[5], n0 = x[6], n1 = x[7], n2 = x[8];
    const double p0 = a1 * b2 - a2 * b1, p1 = a2 * b0 - a0 * b2, p2 = a0 * b1 - a1 * b0;
    const double sn = p0 * n0 + p1 * n1 + p2 * n2, c = a0 * b0 + a1 * b1 + a2 * b2;
    const double r2 = sn * sn + c * c;
    if (!(r2 > 0.0)) return 1;
    const double w = 1.0 / r2, cw = c * w, sw = sn * w;
    grad[0] = cw * (b1 * n2 - b2 * n1) - sw * b0;
    grad[1] = cw * (b2 * n0 - b0 * n2) - sw * b1;
    grad[2] = cw * (b0 * n1 - b1 * n0) - sw * b2;
    grad[3] = cw * (n1 * a2 - n2 * a1) - sw * a0;
    grad[4] = cw * (n2 * a0 - n0 * a2) - sw * a1;
    grad[5] = cw * (n0 * a1 - n1 * a0) - sw * a2;
    grad[6] = cw * p0;
    grad[7] = cw * p1;
    grad[8] = cw * p2;
    *theta = atan2(sn, c);
    return 0;
}

/* The hinge h's gradient (9,) at E and its torque (N m) at E, dE; 1 where it has no angle. */
static int hinge_torque(const NewtonKernel *s, long h, double *grad, double *torque) {
    const long *idx = s->hinge_index + 9 * h;
    const double *p = s->hinge_parameters + 4 * h;
    double x[9], theta, rate = 0.0;
    for (int k = 0; k < 9; k++) x[k] = s->E[idx[k]];
    if (fold_angle_gradient(x, &theta, grad)) return 1;
    for (int k = 0; k < 9; k++) rate += grad[k] * s->dE[idx[k]];
    *torque = p[0] * (theta - p[1]) + p[2] * rate + p[3];
    return 0;
}

/* y += A x for A in CSR (rows rows). */
static void csr_add(long rows, const long *ptr, const long *col, const double *val, const double *x, double *y) {
    for (long i = 0; i < rows; i++) {
        double acc = 0.0;
        for (long k = ptr[i]; k < ptr[i + 1]; k++) acc += val[k] * x[col[k]];
        y[i] += acc;
    }
}

/* LU of the band matrix in LAPACK's band storage ab (ld rows, n columns; A(r, c) at row kl + ku + r - c of column
 * c, 0-based; the first kl rows are the fill-in space), with partial pivoting within the band: LAPACK dgbtf2's
 * algorithm, step for step (first largest pivot, row swaps within the updated columns, the column scaled by the
 * pivot's reciprocal, the rank-one update), written out: at these bands (kl, ku ~ 20-30) the BLAS calls of LAPACK's
 * dgbtf2 cost more than their arithmetic. pivots 1-based as LAPACK's. Returns 0, or j + 1 for a zero pivot in
 * column j (the factorization completed, as LAPACK's info). */
static int band_lu(long n, long kl, long ku, long ld, double *ab, int *pivots) {
    const long kv = ku + kl;
    int info = 0;
    long ju = 0;                          /* the last column that row swaps and updates reach so far */
#define AB(i, j) ab[(j) * ld + (i)]
    for (long j = ku + 1; j < kv && j < n; j++)          /* the fill-in space of the first columns */
        for (long i = kv - j; i < kl; i++) AB(i, j) = 0.0;
    for (long j = 0; j < n; j++) {
        if (j + kv < n)
            for (long i = 0; i < kl; i++) AB(i, j + kv) = 0.0;
        const long km = kl < n - 1 - j ? kl : n - 1 - j;
        long jp = 0;
        double largest = fabs(AB(kv, j));
        for (long i = 1; i <= km; i++)
            if (fabs(AB(kv + i, j)) > largest) { largest = fabs(AB(kv + i, j)); jp = i; }
        pivots[j] = (int)(jp + j + 1);
        if (AB(kv + jp, j) != 0.0) {
            const long reach = j + ku + jp < n - 1 ? j + ku + jp : n - 1;
            if (reach > ju) ju = reach;
            if (jp != 0)
                for (long k = 0; k <= ju - j; k++) {       /* rows j and j + jp over columns j..ju */
                    const double t = AB(kv + jp - k, j + k);
                    AB(kv + jp - k, j + k) = AB(kv - k, j + k);
                    AB(kv - k, j + k) = t;
                }
            if (km > 0) {
                const double reciprocal = 1.0 / AB(kv, j);
                for (long i = 1; i <= km; i++) AB(kv + i, j) *= reciprocal;
                for (long k = 1; k <= ju - j; k++) {       /* A(j+1.., j+k) -= l A(j, j+k) */
                    const double u = AB(kv - k, j + k);
                    if (u != 0.0)
                        for (long i = 1; i <= km; i++) AB(kv - k + i, j + k) -= AB(kv + i, j) * u;
                }
            }
        } else if (info == 0) {
            info = (int)(j + 1);
        }
    }
    return info;
}

/* x = A^-1 b in place for band_lu's factors: the row swaps and unit-lower eliminations (LAPACK dgbtrs), then the
 * upper band of kl + ku superdiagonals backwards (dtbsv). */
static void band_solve(long n, long kl, long ku, long ld, const double *ab, const int *pivots, double *x) {
    const long kd = kl + ku;
    if (kl > 0)
        for (long j = 0; j < n - 1; j++) {
            const long lm = kl < n - 1 - j ? kl : n - 1 - j, l = pivots[j] - 1;
            if (l != j) { const double t = x[l]; x[l] = x[j]; x[j] = t; }
            const double xj = x[j];
            if (xj != 0.0)
                for (long i = 1; i <= lm; i++) x[j + i] -= xj * AB(kd + i, j);
        }
    for (long j = n - 1; j >= 0; j--) {
        if (x[j] != 0.0) {
            x[j] /= AB(kd, j);
            const double t = x[j];
            for (long i = j - 1; i >= 0 && i >= j - kd; i--) x[i] -= t * AB(kd + i - j, j);
        }
    }
#undef AB
}

/* The band's (or dense matrix's) solve of rhs in place; LAPACK's info. */
static int solve(const NewtonKernel *s, const double *lu, const int *pivots, double *rhs) {
    int size = (int)(s->n_q + s->m), one = 1, info = 0;
    char trans = 'N';
    if (s->banded) {
        for (long i = 0; i < size; i++) s->ordered[i] = rhs[s->order[i]];
        band_solve(size, s->lower, s->upper, s->rows, lu, pivots, s->ordered);
        for (long i = 0; i < size; i++) rhs[s->order[i]] = s->ordered[i];
    } else {
        s->getrs(&trans, &size, &one, (double *)lu, &size, (int *)pivots, rhs, &size, &info);
    }
    return info;
}

/* One Newton correction of generalized-alpha (integrators.GeneralizedAlpha._newton): the residual
 * [M_q q'' - T^T F + C_q q' + G_q^T lambda, beta' Phi] at (q, q', q'', lambda), solved with the factorized
 * iteration matrix (lu, pivots), and q -= delta, q' -= gamma' delta, q'' -= beta' delta, lambda -= beta' delta_lambda.
 * *size = max |delta| on q. Returns 0; 1 when the residual is not finite (nothing updated); 2 when the element
 * kernel refuses its Gauss points; 3 when LAPACK's solve fails. */
int newton_correction(const NewtonKernel *s, double *q, double *dq, double *ddq, double *lam, double beta_p,
                      double gamma_p, const double *lu, const int *pivots, double *size) {
    const long n = s->n, n_q = s->n_q, m = s->m;
    double *E = s->E, *dE = s->dE, *F = s->F, *rhs = s->rhs, grad[9], torque;
    coordinates(s, q, s->offset, E);
    coordinates(s, dq, s->rate_offset, dE);
    memcpy(F, s->f_constant, n * sizeof(double));
    if (s->n_elements && s->add_elastic_force(s->n_elements, s->gauss, s->table, E, s->dofs, s->element_scratch, F))
        return 2;
    for (long h = 0; h < s->n_hinges; h++) {
        if (hinge_torque(s, h, grad, &torque)) return 1;
        const long *idx = s->hinge_index + 9 * h;
        for (int k = 0; k < 9; k++) F[idx[k]] -= torque * grad[k];
    }
    /* the equations of motion: M_q q'' - T^T F + C_q q' + G_q^T lambda */
    memset(rhs, 0, (n_q + m) * sizeof(double));
    csr_add(n_q, s->m_ptr, s->m_col, s->m_val, ddq, rhs);
    for (long i = 0; i < n; i++)
        for (long k = s->t_ptr[i]; k < s->t_ptr[i + 1]; k++) rhs[s->t_col[k]] -= s->t_val[k] * F[i];
    if (s->damped) csr_add(n_q, s->c_ptr, s->c_col, s->c_val, dq, rhs);
    for (long i = 0; i < n_q; i++) rhs[i] += s->r_constant[i];
    for (long k = 0; k < s->n_jacobian; k++) {
        const long target = s->jacobian_target[k];
        rhs[target % n_q] += lam[target / n_q] * (E[s->pair[s->jacobian_source[k]]] * s->jacobian_weight[k]);
    }
    const long np = s->n_products;
    for (long r = 0; r < m - np; r++)
        for (long k = s->lt_ptr[r]; k < s->lt_ptr[r + 1]; k++) rhs[s->lt_col[k]] += lam[np + r] * s->lt_val[k];
    /* beta' Phi */
    for (long i = 0; i < np; i++) {
        const long *a = s->row_a + 3 * i, *b = s->row_b + 3 * i;
        const double product = E[a[0]] * E[b[0]] + E[a[1]] * E[b[1]] + E[a[2]] * E[b[2]];
        rhs[n_q + i] = beta_p * (product * s->row_coefficient[i] + s->row_constant[i]);
    }
    for (long r = 0; r < m - np; r++) {
        double acc = 0.0;
        for (long k = s->l_ptr[r]; k < s->l_ptr[r + 1]; k++) acc += s->l_val[k] * E[s->l_col[k]];
        rhs[n_q + np + r] = beta_p * (acc - s->l_offset[r]);
    }
    double sum = 0.0;
    for (long i = 0; i < n_q + m; i++) sum += rhs[i];
    if (!isfinite(sum)) return 1;
    if (solve(s, lu, pivots, rhs)) return 3;
    double largest = 0.0;
    int nan = 0;
    for (long i = 0; i < n_q; i++) {
        const double d = rhs[i];
        q[i] -= d;
        dq[i] -= gamma_p * d;
        ddq[i] -= beta_p * d;
        if (isnan(d)) nan = 1;
        else if (fabs(d) > largest) largest = fabs(d);
    }
    for (long i = 0; i < m; i++) lam[i] -= beta_p * rhs[n_q + i];
    *size = nan ? NAN : largest;          /* as numpy's max: NaN if any correction is NaN */
    return 0;
}

/* The iteration matrix at (q, q', lambda) (model.StructureModel.iteration_matrix, IterationLU.factor) into lu
 * (band or dense storage, overwritten) and its LU by LAPACK with pivots. Returns 0; LAPACK's info > 0 for a singular
 * matrix; -1 where a hinge has no angle; -2 when the element kernel refuses its Gauss points. */
int newton_factor(const NewtonKernel *s, const double *q, const double *dq, const double *lam, double beta_p,
                  double gamma_p, double *lu, int *pivots) {
    const long n_q = s->n_q, m = s->m;
    double *E = s->E, *values = s->values, *S = s->S, *G = s->G, grad[9], torque;
    coordinates(s, q, s->offset, E);
    coordinates(s, dq, s->rate_offset, s->dE);
    long v = 0;
    if (s->n_elements) {       /* the elastic Hessians, element by element (gathered into the scratch) */
        double *e = s->element_scratch;
        for (long i = 0; i < 18 * s->n_elements; i++) e[i] = E[s->dofs[i]];
        if (s->elastic_jacobian(s->n_elements, s->gauss, s->table, e, values)) return -2;
        v = 324 * s->n_elements;
    }
    for (long k = 0; k < s->n_hessian; k++) values[v++] = lam[s->hessian_row[k]];
    for (long h = 0; h < s->n_hinges; h++) {
        if (hinge_torque(s, h, grad, &torque)) return -1;
        const double *p = s->hinge_parameters + 4 * h, factor = p[0] + gamma_p * p[2];
        for (int i = 0; i < 9; i++)
            for (int j = 0; j < 9; j++) values[v++] = factor * (grad[i] * grad[j]);
    }
    memset(S, 0, n_q * n_q * sizeof(double));
    for (long k = 0; k < s->n_assembly; k++)
        S[s->assembly_target[k]] += values[s->assembly_source[k]] * s->assembly_weight[k];
    if (s->damped)
        for (long i = 0; i < n_q * n_q; i++) S[i] += gamma_p * s->damping[i];
    for (long i = 0; i < n_q * n_q; i++) S[i] += beta_p * s->mass[i];
    if (m) {
        memset(G, 0, m * n_q * sizeof(double));
        for (long k = 0; k < s->n_jacobian; k++)
            G[s->jacobian_target[k]] += E[s->pair[s->jacobian_source[k]]] * s->jacobian_weight[k];
        for (long r = 0; r < m - s->n_products; r++)
            for (long k = s->lt_ptr[r]; k < s->lt_ptr[r + 1]; k++)
                G[(s->n_products + r) * n_q + s->lt_col[k]] = s->lt_val[k];
        for (long i = 0; i < m * n_q; i++) G[i] *= beta_p;
    }
    const long size = n_q + m;
    memset(lu, 0, s->rows * size * sizeof(double));
    for (long k = 0; k < s->n_s; k++) lu[s->s_target[k]] = S[s->s_source[k]];
    for (long k = 0; k < s->n_g; k++) {
        lu[s->g_target[k]] = G[s->g_source[k]];
        lu[s->gt_target[k]] = G[s->gt_source[k]];
    }
    int rows = (int)size, info = 0;
    if (s->banded) {
        info = band_lu(size, s->lower, s->upper, s->rows, lu, pivots);
    } else {
        s->getrf(&rows, &rows, lu, &rows, pivots, &info);
    }
    return info;
}
