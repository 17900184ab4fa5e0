/* The structure unit's step on the ANCF models in C, on buffers allocated once (step_kernel.py): a whole
 * generalized-alpha step (predictor, factorizations of the iteration matrix, Newton corrections and their control) in
 * one call, the steps of a communication step with the solver's checks in one call (alpha_steps), and a whole RK4
 * step with its constraint projection in one call. The reference is the numpy path of
 * model.StructureModel (force_q, mass_product, constraint_*, iteration_matrix), iteration_lu.IterationLU and
 * integrators.RK4 ($WINGSIM_KERNELS=numpy); the tests compare both (tests/units/test_step_kernel.py).
 *
 * The model (Otsuka et al. 2019, Eqs. 4-5):
 *   E = T q + P p, E' = T q' + P p' (T by its nonzero entries, CSR by rows of E; the prescribed parts per stage)
 *   F(E, E') = f_constant + elastic(E) - sum_h torque_h grad_h     (gravity, point loads and Q in f_constant)
 *   F_q = T^T F - C_q q' - r_constant                              (r_constant: T^T M_E P p'' + T^T C_E P p')
 *   M_q q'' + G_q^T lambda = F_q,  Phi(E) = 0
 * with the ANCF elastic force and its Hessian from element_kernels.c (passed in as function pointers), the
 * chord-axis hinges' spring actuators (joints.fold_angle_gradient, joints.actuator_torque), the mass-proportional
 * damping as its reduced matrix C_q or the damping of deformation (damping.deformation_damping_force, its tangent
 * alpha (I - P)^T M (I - P) damping.deformation_damping_matrix), and the constraint rows: unit length and orthogonality Phi_i = c_i X_a . X_b +
 * c0_i, then the linear rows L E - c (constraints.Constraints). What varies with time only (the prescribed motion,
 * the loads, the latches) is set by the caller per stage: stage 0 is t (generalized-alpha: the step's end), 1 and 2
 * RK4's t + h/2 and t + h.
 *
 * Generalized-alpha (Peng et al. 2019, Eqs. 23-25 and Fig. 3): the residual [M_q q'' - F_q + G_q^T lambda, beta' Phi]
 * and the iteration matrix [[S, beta' G^T], [beta' G, 0]],
 *   S = T^T (K_elastic + sum_i lambda_i H_i + sum_h (k_h + gamma' c_h) grad_h grad_h^T + gamma' D) T + gamma' C_q
 *       + beta' M_q,
 * summed in the reference's order (the assembly's entries in turn, then gamma' C_q, then beta' M_q), so that S and G
 * are the reference's bit for bit, gathered into LAPACK's band (or dense) storage; the band is factorized here
 * (LAPACK dgbtf2's algorithm), a dense matrix by LAPACK (scipy's, through function pointers).
 *
 * RK4 (Otsuka et al. 2019, Sec. VI; integrators.RK4 and integrators.constrained_accelerations): at each stage q'' and
 * lambda from the index-1 equations by the Schur complement G M_q^-1 G^T (Cholesky), then the mass-weighted
 * projection of q and q' onto the constraints.
 *
 * The sums run in another order than numpy's products: the residual, the accelerations and the states agree with the
 * reference to round-off. Arithmetic: IEEE double, built with -ffp-contract=off like the other kernels.
 */
#include <float.h>
#include <math.h>
#include <string.h>

typedef int (*elastic_add_t)(long n, long g, const double *table, const double *E, const long long *dofs,
                             double *scratch, double *F);
typedef int (*elastic_jacobian_t)(long n, long g, const double *table, const double *e, double *out);
typedef void (*getrf_t)(int *m, int *n, double *a, int *lda, int *ipiv, int *info);
typedef void (*getrs_t)(char *trans, int *n, int *nrhs, double *a, int *lda, int *ipiv, double *b, int *ldb,
                        int *info);

/* the banded LU's loops built for AVX-512, AVX2 and plain x86-64, as in biot_savart.c (without fused multiply-add,
 * -ffp-contract=off: every build gives the same bits) */
#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__) && defined(__ELF__)
#define VECTOR_CLONES __attribute__((target_clones("avx512f", "avx2", "default")))
#else
#define VECTOR_CLONES
#endif

#define PI 3.141592653589793        /* math.pi */
#define STAGES 3                     /* the times a step evaluates: t, t + h/2, t + h */
#define PROJECTIONS 4                /* integrators.project: Newton projections of q at most */
#define PROJECTION_TOLERANCE 1e-13   /* integrators.project: |Phi_i| below which q is on the constraints */

/* What the step reads and writes; every array C-contiguous, allocated by step_kernel.py. */
typedef struct {
    long n, n_q, m;                  /* lengths of E and q, constraint rows */
    const long *t_ptr, *t_col;       /* T: CSR over the n rows of E */
    const double *t_val;
    const double *offset;            /* (STAGES, n) P p */
    const double *rate_offset;       /* (STAGES, n) P p' */
    const double *accel_offset;      /* (STAGES, n) P p'' (the constraints' acceleration term) */
    long moving;                     /* 1: the prescribed motion moves (P p', P p'' not zero) */
    const double *f_constant;        /* (STAGES, n) gravity, point loads and Q, N and N m */
    const double *r_constant;        /* (STAGES, n_q) the reduced force's terms that depend on time only */
    const long *m_ptr, *m_col;       /* M_q: CSR (n_q rows) */
    const double *m_val;
    const double *mass;              /* (n_q, n_q) M_q dense, for the iteration matrix */
    const double *mass_inverse;      /* (n_q, n_q) M_q^-1 (RK4) */
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
    /* hinges (chord axis): idx (n_hinges, 9) into E; per hinge stiffness (N m/rad), its neutral angle (rad),
       damping (N m s/rad) and constant torque (N m): torque k (theta - theta_0) + c theta' + T_const */
    long n_hinges;
    const long *hinge_index;
    const double *hinge_parameters;  /* (n_hinges, 4) */
    /* the bodies whose deformation is damped: E[start..start + size) each, alpha (1/s), its mass block (size, size)
       at mass_offset in body_mass */
    long n_damped;
    const long *body_start, *body_size, *body_mass_offset;
    const double *body_alpha, *body_mass;
    /* the first n_products rows c X_a . X_b + c0: ia, ib (n_products, 3) E indices, coefficient, constant */
    long n_products;
    const long *row_a, *row_b;
    const double *row_coefficient, *row_constant;
    /* G_q: entries (source into the gathered pairs [X_a, X_b] of the rows (n_products, 6), target row * n_q + col,
       weight) */
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
    getrf_t getrf; getrs_t getrs;
    /* work arrays */
    double *E, *dE, *F, *Fq, *values, *S, *G, *rhs, *ordered;
    double *MinvGt, *schur, *stage_q, *stage_v, *accelerations, *multipliers, *vector;
    double *body_work;               /* (2 size + 9 size) of the largest damped body */
    long *nonzero;                   /* (m, n_q + 1): per row of G its count of nonzero columns, then the columns */
} StepKernel;

/* E = T q + offset, (offset NULL: none). */
static void map_coordinates(const StepKernel *s, const double *q, const double *offset, double *E) {
    for (long i = 0; i < s->n; i++) {
        double acc = offset ? offset[i] : 0.0;
        for (long k = s->t_ptr[i]; k < s->t_ptr[i + 1]; k++) acc += s->t_val[k] * q[s->t_col[k]];
        E[i] = acc;
    }
}

/* s->E and s->dE at (q, q') and the stage's prescribed motion. */
static void coordinates(const StepKernel *s, const double *q, const double *dq, int stage) {
    map_coordinates(s, q, s->offset + stage * s->n, s->E);
    map_coordinates(s, dq, s->moving ? s->rate_offset + stage * s->n : NULL, s->dE);
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
static int hinge_torque(const StepKernel *s, long h, double *grad, double *torque) {
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

/* c = a x b */
static void cross(const double *a, const double *b, double *c) {
    c[0] = a[1] * b[2] - a[2] * b[1];
    c[1] = a[2] * b[0] - a[0] * b[2];
    c[2] = a[0] * b[1] - a[1] * b[0];
}

/* W (3, 9), omega = W d(root)/dt, for the root node's [r, r_x, r_y] (damping.frame_angular_velocity_map): the frame
 * e_1 = r_x / |r_x|, e_2 = r_y, e_3 = e_1 x e_2, omega = 1/2 sum_i e_i x de_i. */
static void angular_velocity_map(const double *root, double W[3][9]) {
    const double *x = root + 3, *y = root + 6;
    const double nx = sqrt(x[0] * x[0] + x[1] * x[1] + x[2] * x[2]);
    double e1[3] = {x[0] / nx, x[1] / nx, x[2] / nx}, e3[3], de1[3][3], de3[3][3];
    cross(e1, y, e3);
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++) de1[i][j] = ((i == j ? 1.0 : 0.0) - e1[i] * e1[j]) / nx;   /* d e1 / d r_x */
    for (int j = 0; j < 3; j++) {            /* d e3 / d r_x = -[e2]x de1 = -(e2 x de1[:, j]) */
        double column[3] = {de1[0][j], de1[1][j], de1[2][j]}, c[3];
        cross(y, column, c);
        for (int i = 0; i < 3; i++) de3[i][j] = -c[i];
    }
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++) W[i][j] = 0.0;
    for (int j = 0; j < 3; j++) {
        double a[3] = {de1[0][j], de1[1][j], de1[2][j]}, b[3] = {de3[0][j], de3[1][j], de3[2][j]}, ca[3], cb[3];
        cross(e1, a, ca);                    /* [e1]x de1 + [e3]x de3_dx, column j */
        cross(e3, b, cb);
        for (int i = 0; i < 3; i++) W[i][3 + j] = 0.5 * (ca[i] + cb[i]);
        double unit[3] = {0.0, 0.0, 0.0}, cy[3], c3[3], d3[3];
        unit[j] = 1.0;
        cross(y, unit, cy);                  /* [e2]x e_j */
        cross(e1, unit, d3);                 /* d e3 / d r_y = [e1]x, column j */
        cross(e3, d3, c3);
        for (int i = 0; i < 3; i++) W[i][6 + j] = 0.5 * (cy[i] + c3[i]);
    }
}

/* The arm a rigid rotation of a body acts on at its node j, vector k (0: r - r_root, 1: r_x, 2: r_y). */
static void arm(const double *E, long j, int k, double *a) {
    for (int c = 0; c < 3; c++) a[c] = k == 0 ? E[9 * j + c] - E[c] : E[9 * j + 3 * k + c];
}

/* F[body] += -alpha (I - P)^T M (I - P) dE on every damped body (damping.deformation_damping_force): v = dE less the
 * rigid velocity of the root frame, y = M v, F = -alpha (y - P^T y), P^T y on the root coordinates only. */
static void deformation_damping(const StepKernel *s, double *F) {
    for (long b = 0; b < s->n_damped; b++) {
        const long start = s->body_start[b], size = s->body_size[b], nodes = size / 9;
        const double *E = s->E + start, *dE = s->dE + start, *M = s->body_mass + s->body_mass_offset[b];
        double *v = s->body_work, *y = v + size, W[3][9], omega[3] = {0.0, 0.0, 0.0}, a[3], w[3], sum[3] = {0, 0, 0};
        angular_velocity_map(E, W);
        for (int i = 0; i < 3; i++)
            for (int j = 0; j < 9; j++) omega[i] += W[i][j] * dE[j];
        for (long j = 0; j < nodes; j++)
            for (int k = 0; k < 3; k++) {
                arm(E, j, k, a);
                cross(omega, a, w);
                for (int c = 0; c < 3; c++) v[9 * j + 3 * k + c] = dE[9 * j + 3 * k + c] - (w[c] + (k == 0 ? dE[c] : 0.0));
            }
        for (long i = 0; i < size; i++) {
            double acc = 0.0;
            for (long j = 0; j < size; j++) acc += M[i * size + j] * v[j];
            y[i] = acc;
        }
        double moment[3] = {0.0, 0.0, 0.0}, back[9];
        for (long j = 0; j < nodes; j++)
            for (int k = 0; k < 3; k++) {
                arm(E, j, k, a);
                cross(a, y + 9 * j + 3 * k, w);
                for (int c = 0; c < 3; c++) moment[c] += w[c];
                if (k == 0)
                    for (int c = 0; c < 3; c++) sum[c] += y[9 * j + c];
            }
        for (int j = 0; j < 9; j++) back[j] = W[0][j] * moment[0] + W[1][j] * moment[1] + W[2][j] * moment[2];
        for (int c = 0; c < 3; c++) back[c] += sum[c];
        for (int j = 0; j < 9; j++) y[j] -= back[j];
        for (long i = 0; i < size; i++) F[start + i] -= s->body_alpha[b] * y[i];
    }
}

/* values[0..size^2) = gamma' alpha (I - P)^T M (I - P) of damped body b (damping.deformation_damping_matrix): P
 * has 9 nonzero columns (the root's), P9 = -[arm]x W (+ I on the root's r), so that (I - P)^T M (I - P) = M - M P9
 * - (M P9)^T + P9^T M P9 on the root's rows and columns. */
static void deformation_damping_block(const StepKernel *s, long b, double gamma_p, double *values) {
    const long start = s->body_start[b], size = s->body_size[b], nodes = size / 9;
    const double *E = s->E + start, *M = s->body_mass + s->body_mass_offset[b], alpha = s->body_alpha[b];
    double *P = s->body_work, *MP = P + 9 * size, W[3][9], a[3];     /* P9 (size, 9), M P9 (size, 9) */
    angular_velocity_map(E, W);
    for (long j = 0; j < nodes; j++)
        for (int k = 0; k < 3; k++) {
            arm(E, j, k, a);
            for (int col = 0; col < 9; col++) {       /* -(a x W[:, col]) */
                double wc[3] = {W[0][col], W[1][col], W[2][col]}, r[3];
                cross(a, wc, r);
                for (int c = 0; c < 3; c++)
                    P[(9 * j + 3 * k + c) * 9 + col] = -r[c] + (k == 0 && col == c ? 1.0 : 0.0);
            }
        }
    for (long i = 0; i < size; i++)
        for (int col = 0; col < 9; col++) {
            double acc = 0.0;
            for (long j = 0; j < size; j++) acc += M[i * size + j] * P[j * 9 + col];
            MP[i * 9 + col] = acc;
        }
    for (long i = 0; i < size; i++)
        for (long j = 0; j < size; j++) {
            double x = M[i * size + j];
            if (j < 9) x -= MP[i * 9 + j];
            if (i < 9) x -= MP[j * 9 + i];
            if (i < 9 && j < 9) {
                double acc = 0.0;
                for (long k = 0; k < size; k++) acc += P[k * 9 + i] * MP[k * 9 + j];
                x += acc;
            }
            values[i * size + j] = gamma_p * (alpha * x);
        }
}

/* s->Fq = F_q (n_q,) at s->E, s->dE and q' (model.StructureModel.force_q). Returns 0; 1 where a hinge has no angle;
 * 2 when the element kernel refuses its Gauss points. */
static int reduced_force(const StepKernel *s, const double *dq, int stage) {
    const long n = s->n, n_q = s->n_q;
    double *F = s->F, *Fq = s->Fq, grad[9], torque;
    memcpy(F, s->f_constant + stage * n, n * sizeof(double));
    if (s->n_elements && s->add_elastic_force(s->n_elements, s->gauss, s->table, s->E, s->dofs, s->element_scratch, F))
        return 2;
    for (long h = 0; h < s->n_hinges; h++) {
        if (hinge_torque(s, h, grad, &torque)) return 1;
        const long *idx = s->hinge_index + 9 * h;
        for (int k = 0; k < 9; k++) F[idx[k]] -= torque * grad[k];
    }
    deformation_damping(s, F);
    const double *constant = s->r_constant + stage * n_q;
    for (long i = 0; i < n_q; i++) Fq[i] = -constant[i];
    for (long i = 0; i < n; i++)
        for (long k = s->t_ptr[i]; k < s->t_ptr[i + 1]; k++) Fq[s->t_col[k]] += s->t_val[k] * F[i];
    if (s->damped)
        for (long i = 0; i < n_q; i++) {
            double acc = 0.0;
            for (long k = s->c_ptr[i]; k < s->c_ptr[i + 1]; k++) acc += s->c_val[k] * dq[s->c_col[k]];
            Fq[i] -= acc;
        }
    return 0;
}

/* Phi (m,) at s->E. */
static void constraint_residual(const StepKernel *s, double *phi) {
    const double *E = s->E;
    const long np = s->n_products;
    for (long i = 0; i < np; i++) {
        const long *a = s->row_a + 3 * i, *b = s->row_b + 3 * i;
        const double product = E[a[0]] * E[b[0]] + E[a[1]] * E[b[1]] + E[a[2]] * E[b[2]];
        phi[i] = product * s->row_coefficient[i] + s->row_constant[i];
    }
    for (long r = 0; r < s->m - np; r++) {
        double acc = 0.0;
        for (long k = s->l_ptr[r]; k < s->l_ptr[r + 1]; k++) acc += s->l_val[k] * E[s->l_col[k]];
        phi[np + r] = acc - s->l_offset[r];
    }
}

/* G_q's nonzero entries at s->E into G (m, n_q), whose other entries the caller has zeroed. */
static void constraint_jacobian_entries(const StepKernel *s, double *G) {
    const long n_q = s->n_q;
    for (long k = 0; k < s->n_jacobian; k++)
        G[s->jacobian_target[k]] += s->E[s->pair[s->jacobian_source[k]]] * s->jacobian_weight[k];
    for (long r = 0; r < s->m - s->n_products; r++)
        for (long k = s->lt_ptr[r]; k < s->lt_ptr[r + 1]; k++) G[(s->n_products + r) * n_q + s->lt_col[k]] = s->lt_val[k];
}

/* G_q (m, n_q) dense at s->E. */
static void constraint_jacobian(const StepKernel *s, double *G) {
    memset(G, 0, s->m * s->n_q * sizeof(double));
    constraint_jacobian_entries(s, G);
}

/* (dPhi/dE) x (m,) at s->E (constraints.Constraints.rate). */
static void constraint_rate(const StepKernel *s, const double *x, double *out) {
    const double *E = s->E;
    const long np = s->n_products;
    for (long i = 0; i < np; i++) {
        const long *a = s->row_a + 3 * i, *b = s->row_b + 3 * i;
        double acc = 0.0;
        for (int c = 0; c < 3; c++) acc += E[a[c]] * x[b[c]] + E[b[c]] * x[a[c]];
        out[i] = acc * s->row_coefficient[i];
    }
    for (long r = 0; r < s->m - np; r++) {
        double acc = 0.0;
        for (long k = s->l_ptr[r]; k < s->l_ptr[r + 1]; k++) acc += s->l_val[k] * x[s->l_col[k]];
        out[np + r] = acc;
    }
}

/* LU of the band matrix in LAPACK's band storage ab (ld rows, n columns; A(r, c) at row kl + ku + r - c of column
 * c, 0-based; the first kl rows are the fill-in space), with partial pivoting within the band: LAPACK dgbtf2's
 * algorithm, step for step (first largest pivot, row swaps within the updated columns, the column scaled by the
 * pivot's reciprocal, the rank-one update), written out: at these bands (kl, ku ~ 20-30) the BLAS calls of LAPACK's
 * dgbtf2 cost more than their arithmetic. pivots (3 n): LAPACK's, 1-based; then, for band_solve, each column's last
 * nonzero row of L (as an offset below the diagonal) and first nonzero row of U (a row index): the band is sparse
 * within (about half of it is zeros on deploy_flexible), and the solves skip what is zero. Returns 0, or j + 1 for a
 * zero pivot in column j (the factorization completed, as LAPACK's info). */
VECTOR_CLONES static int band_lu(long n, long kl, long ku, long ld, double *ab, int *pivots) {
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
        pivots[n + j] = 0;
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
                long last = 0;                             /* the last nonzero of l: the band is sparse within */
                for (long i = 1; i <= km; i++) {
                    AB(kv + i, j) *= reciprocal;
                    if (AB(kv + i, j) != 0.0) last = i;
                }
                pivots[n + j] = (int)last;
                for (long k = 1; k <= ju - j; k++) {       /* A(j+1.., j+k) -= l A(j, j+k) */
                    const double u = AB(kv - k, j + k);
                    if (u != 0.0)
                        for (long i = 1; i <= last; i++) AB(kv - k + i, j + k) -= AB(kv + i, j) * u;
                }
            }
        } else if (info == 0) {
            info = (int)(j + 1);
        }
    }
    for (long j = 0; j < n; j++) {       /* U's first nonzero row in each column (the diagonal's if none above) */
        long i = j - kv > 0 ? j - kv : 0;
        while (i < j && AB(kv + i - j, j) == 0.0) i++;
        pivots[2 * n + j] = (int)i;
    }
    return info;
}

/* x = A^-1 b in place for band_lu's factors: the row swaps and unit-lower eliminations (LAPACK dgbtrs), then the
 * upper band of kl + ku superdiagonals backwards (dtbsv), each column within its nonzeros (band_lu's pivots). */
VECTOR_CLONES static void band_solve(long n, long kl, long ku, long ld, const double *ab, const int *pivots,
                                     double *x) {
    const long kd = kl + ku;
    if (kl > 0)
        for (long j = 0; j < n - 1; j++) {
            const long lm = pivots[n + j], l = pivots[j] - 1;
            if (l != j) { const double t = x[l]; x[l] = x[j]; x[j] = t; }
            const double xj = x[j];
            if (xj != 0.0)
                for (long i = 1; i <= lm; i++) x[j + i] -= xj * AB(kd + i, j);
        }
    for (long j = n - 1; j >= 0; j--) {
        if (x[j] != 0.0) {
            x[j] /= AB(kd, j);
            const double t = x[j];
            const double *column = &AB(kd - j, j);      /* column[i] = AB(kd + i - j, j): contiguous in i */
            for (long i = pivots[2 * n + j]; i < j; i++) x[i] -= t * column[i];
        }
    }
#undef AB
}

/* The band's (or dense matrix's) solve of rhs in place; LAPACK's info. */
static int solve(const StepKernel *s, const double *lu, const int *pivots, double *rhs) {
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

/* One Newton correction of generalized-alpha (integrators.GeneralizedAlpha._newton) at stage 0: the residual
 * [M_q q'' - F_q + G_q^T lambda, beta' Phi] at (q, q', q'', lambda), solved with the factorized iteration matrix
 * (lu, pivots), and q -= delta, q' -= gamma' delta, q'' -= beta' delta, lambda -= beta' delta_lambda.
 * *size = max |delta| on q (NaN if any is). Returns 0; 1 when the residual is not finite (nothing updated); 2 when
 * the element kernel refuses its Gauss points; 3 when LAPACK's solve fails. */
int newton_correction(const StepKernel *s, double *q, double *dq, double *ddq, double *lam, double beta_p,
                      double gamma_p, const double *lu, const int *pivots, double *size) {
    const long n_q = s->n_q, m = s->m;
    double *rhs = s->rhs;
    coordinates(s, q, dq, 0);
    const int status = reduced_force(s, dq, 0);
    if (status) return status;
    memset(rhs, 0, n_q * sizeof(double));
    csr_add(n_q, s->m_ptr, s->m_col, s->m_val, ddq, rhs);
    for (long i = 0; i < n_q; i++) rhs[i] -= s->Fq[i];
    for (long k = 0; k < s->n_jacobian; k++) {
        const long target = s->jacobian_target[k];
        rhs[target % n_q] += lam[target / n_q] * (s->E[s->pair[s->jacobian_source[k]]] * s->jacobian_weight[k]);
    }
    const long np = s->n_products;
    for (long r = 0; r < m - np; r++)
        for (long k = s->lt_ptr[r]; k < s->lt_ptr[r + 1]; k++) rhs[s->lt_col[k]] += lam[np + r] * s->lt_val[k];
    constraint_residual(s, rhs + n_q);
    for (long i = 0; i < m; i++) rhs[n_q + i] *= beta_p;
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

/* The iteration matrix at (q, q', lambda) and stage 0 (model.StructureModel.iteration_matrix, IterationLU.factor)
 * into lu (band or dense storage, overwritten) and its LU with pivots (1-based, LAPACK's). Returns 0; j + 1 for a
 * zero pivot in column j (LAPACK's info); -1 where a hinge has no angle; -2 when the element kernel refuses its Gauss
 * points. */
int newton_factor(const StepKernel *s, const double *q, const double *dq, const double *lam, double beta_p,
                  double gamma_p, double *lu, int *pivots) {
    const long n_q = s->n_q, m = s->m;
    double *values = s->values, *S = s->S, *G = s->G, grad[9], torque;
    coordinates(s, q, dq, 0);
    long v = 0;
    if (s->n_elements) {       /* the elastic Hessians, element by element (gathered into the scratch) */
        double *e = s->element_scratch;
        for (long i = 0; i < 18 * s->n_elements; i++) e[i] = s->E[s->dofs[i]];
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
    for (long b = 0; b < s->n_damped; b++) {
        deformation_damping_block(s, b, gamma_p, values + v);
        v += s->body_size[b] * s->body_size[b];
    }
    /* S's entries in the pattern only (the assembly's targets are among them): the assembly's sums, then
       + gamma' C_q, then + beta' M_q, each entry in the reference's order */
    for (long k = 0; k < s->n_s; k++) S[s->s_source[k]] = 0.0;
    for (long k = 0; k < s->n_assembly; k++)
        S[s->assembly_target[k]] += values[s->assembly_source[k]] * s->assembly_weight[k];
    if (m) {                   /* G's entries in the pattern only (constraint_jacobian's, in its order) */
        for (long k = 0; k < s->n_g; k++) G[s->g_source[k]] = 0.0;
        constraint_jacobian_entries(s, G);
    }
    const long size = n_q + m;
    memset(lu, 0, s->rows * size * sizeof(double));
    for (long k = 0; k < s->n_s; k++) {
        const long i = s->s_source[k];
        double x = S[i];
        if (s->damped) x += gamma_p * s->damping[i];
        lu[s->s_target[k]] = x + beta_p * s->mass[i];
    }
    for (long k = 0; k < s->n_g; k++) {      /* beta' G and beta' G^T */
        lu[s->g_target[k]] = beta_p * G[s->g_source[k]];
        lu[s->gt_target[k]] = beta_p * G[s->gt_source[k]];
    }
    if (s->banded) return band_lu(size, s->lower, s->upper, s->rows, lu, pivots);
    int rows = (int)size, info = 0;
    s->getrf(&rows, &rows, lu, &rows, pivots, &info);
    return info;
}

void alpha_predictor(long n, const double *q0, const double *dq0, const double *ddq0, const double *accel0,
                     const double *c, int displacement, double *q, double *dq, double *ddq, double *a_known,
                     double *largest);

/* alpha_step's factorization of the iteration matrix at (q, q', lambda) into the spare, which is then the matrix
 * (*lu, *pivots) where it succeeds; newton_factor's status. */
static int factor_into_spare(const StepKernel *s, const double *q, const double *dq, const double *lam, double beta_p,
                             double gamma_p, double *spare_lu, int *spare_pivots, const double **lu,
                             const int **pivots) {
    const int status = newton_factor(s, q, dq, lam, beta_p, gamma_p, spare_lu, spare_pivots);
    if (!status) {
        *lu = spare_lu;
        *pivots = spare_pivots;
    }
    return status;
}

/* One generalized-alpha step (integrators.GeneralizedAlpha._newton, the same arithmetic and tests in the same order):
 * the predictor (alpha_predictor, from q0, q0', q0'', a0 with its coefficients c) into x = [q, q', q'', a, a_known,
 * lambda] (5 n_q + m; lambda from lambda0), the iteration matrix factorized at the predictor where asked, then Newton
 * corrections (newton_correction) with the factorized iteration matrix until the correction, or the error it leaves,
 * is within the tolerance; after two or more corrections with a matrix, a correction above 0.3 times the one before
 * refactorizes it at the iterate. Each factorization goes into (spare_lu, spare_pivots), which is then the matrix: a
 * matrix given, (lu, pivots), is never modified (a saved solver state may hold it). Last a = a_known + c[3] q''.
 * control: beta', gamma', the Newton tolerance, the velocity tolerance over it, the first correction's error
 * estimate factor eta, 1 to factorize at the predictor, the iterations allowed, 1 for the displacement predictor.
 * out: the corrections taken, the last correction, the first one, eta (as updated), the factorizations made, the
 * status of a failed factorization. Returns 0 when converged; 1 when a residual is not finite; 2 when the element
 * kernel refuses its Gauss points; 3 when LAPACK's solve fails; 4 when the iteration diverges; 5 when it has not
 * converged within the iterations allowed (x holds the predictor where none is allowed); 6 when a factorization
 * fails (its status in out[5], newton_factor's). */
int alpha_step(const StepKernel *s, const double *q0, const double *dq0, const double *ddq0, const double *accel0,
               const double *lam0, const double *c, const double *control, const double *lu, const int *pivots,
               double *spare_lu, int *spare_pivots, double *x, double *out) {
    const long n = s->n_q, m = s->m;
    double *q = x, *dq = x + n, *ddq = x + 2 * n, *accel = x + 3 * n, *a_known = x + 4 * n, *lam = x + 5 * n;
    const double beta_p = control[0], gamma_p = control[1];
    const int factorized_here = control[5] != 0.0;
    const long max_iterations = (long)control[6];
    double largest[2], eta = control[4], previous = 0.0, first = 0.0, size = 0.0;
    long fresh = 0, iterations = 0, factorized = 0;
    int status = 5;
    alpha_predictor(n, q0, dq0, ddq0, accel0, c, control[7] != 0.0, q, dq, ddq, a_known, largest);
    if (m) memcpy(lam, lam0, m * sizeof(double));
    /* the tolerance applies to q and to q' (GeneralizedAlpha._newton) */
    const double q_scale = largest[0] > 1.0 ? largest[0] : 1.0, dq_scale = largest[1] > 1.0 ? largest[1] : 1.0;
    const double velocity_scale = control[3] * dq_scale / gamma_p;
    const double tol = control[2] * (velocity_scale < q_scale ? velocity_scale : q_scale);
    if (factorized_here) {
        const int factored = factor_into_spare(s, q, dq, lam, beta_p, gamma_p, spare_lu, spare_pivots, &lu, &pivots);
        if (factored) {
            out[5] = factored;
            status = 6;
        } else {
            factorized++;
        }
        eta = pow(eta > DBL_EPSILON ? eta : DBL_EPSILON, 0.8);
    }
    for (long iteration = 0; status != 6 && iteration < max_iterations; iteration++) {
        const int corrected = newton_correction(s, q, dq, ddq, lam, beta_p, gamma_p, lu, pivots, &size);
        if (corrected) { status = corrected; break; }
        iterations++;
        if (iteration == 0) first = size;
        /* stop when the correction, or the error it leaves (rate / (1 - rate) times it), is within the tolerance */
        const double rate = previous > 0.0 ? size / previous : 1.0;
        if (iteration == 1 && factorized_here && fresh == 1) eta = rate < 1.0 ? rate / (1.0 - rate) : 1.0;
        const double estimate = iteration == 0 && factorized_here ? eta
                                : previous > 0.0 && rate < 0.5 ? rate / (1.0 - rate) : INFINITY;
        if (size <= tol || estimate * size <= tol) { status = 0; break; }
        if (!isfinite(size) || size > 100.0 * (tol > first ? tol : first)) { status = 4; break; }
        fresh++;
        if (fresh >= 2 && size > 0.3 * previous) {       /* the matrix is no longer the tangent at the iterate */
            const int factored = factor_into_spare(s, q, dq, lam, beta_p, gamma_p, spare_lu, spare_pivots, &lu,
                                                   &pivots);
            if (factored) { out[5] = factored; status = 6; break; }
            factorized++;
            fresh = 0;
        }
        previous = size;
    }
    for (long i = 0; i < n; i++) accel[i] = a_known[i] + c[3] * ddq[i];
    out[0] = (double)iterations;
    out[1] = size;
    out[2] = first;
    out[3] = eta;
    out[4] = (double)factorized;
    return status;
}

/* x = S^-1 b in place in b for the symmetric positive definite S (k, k), overwritten by its Cholesky factor L
 * (lower, S = L L^T, LAPACK dposv's); 1 when S is not positive definite. */
static int cholesky_solve(long k, double *S, double *b) {
    for (long j = 0; j < k; j++) {
        double d = S[j * k + j];
        for (long p = 0; p < j; p++) d -= S[j * k + p] * S[j * k + p];
        if (!(d > 0.0)) return 1;
        d = sqrt(d);
        S[j * k + j] = d;
        for (long i = j + 1; i < k; i++) {
            double acc = S[i * k + j];
            for (long p = 0; p < j; p++) acc -= S[i * k + p] * S[j * k + p];
            S[i * k + j] = acc / d;
        }
    }
    for (long i = 0; i < k; i++) {                    /* L y = b */
        double acc = b[i];
        for (long p = 0; p < i; p++) acc -= S[i * k + p] * b[p];
        b[i] = acc / S[i * k + i];
    }
    for (long i = k - 1; i >= 0; i--) {               /* L^T x = y */
        double acc = b[i];
        for (long p = i + 1; p < k; p++) acc -= S[p * k + i] * b[p];
        b[i] = acc / S[i * k + i];
    }
    return 0;
}

/* s->MinvGt (n_q, m) = M_q^-1 G^T and s->schur (m, m) = G M_q^-1 G^T for G (m, n_q). */
static void schur_complement(const StepKernel *s, const double *G) {
    const long n_q = s->n_q, m = s->m;
    for (long r = 0; r < m; r++) {      /* G's rows are sparse (a node's coordinates): their nonzero columns */
        long *list = s->nonzero + r * (n_q + 1), count = 0;
        for (long j = 0; j < n_q; j++)
            if (G[r * n_q + j] != 0.0) list[1 + count++] = j;
        list[0] = count;
    }
    for (long i = 0; i < n_q; i++)
        for (long r = 0; r < m; r++) {
            const long *list = s->nonzero + r * (n_q + 1);
            double acc = 0.0;
            for (long k = 1; k <= list[0]; k++) acc += s->mass_inverse[i * n_q + list[k]] * G[r * n_q + list[k]];
            s->MinvGt[i * m + r] = acc;
        }
    for (long r = 0; r < m; r++) {
        const long *list = s->nonzero + r * (n_q + 1);
        for (long c = 0; c < m; c++) {
            double acc = 0.0;
            for (long k = 1; k <= list[0]; k++) acc += G[r * n_q + list[k]] * s->MinvGt[list[k] * m + c];
            s->schur[r * m + c] = acc;
        }
    }
}

/* x -= M_q^-1 G^T y for the Schur solve y = (G M_q^-1 G^T)^-1 b (b overwritten by y); 1 when the complement is not
 * positive definite. */
static int subtract_projection(const StepKernel *s, double *b, double *x) {
    if (cholesky_solve(s->m, s->schur, b)) return 1;
    for (long i = 0; i < s->n_q; i++) {
        double acc = 0.0;
        for (long r = 0; r < s->m; r++) acc += s->MinvGt[i * s->m + r] * b[r];
        x[i] -= acc;
    }
    return 0;
}

/* q'' (n_q,) and lambda (m,) of the index-1 equations at (q, q') and the stage (integrators.constrained_accelerations):
 * M_q^-1 F_q less M_q^-1 G^T lambda, lambda from the Schur complement with the right-hand side G M_q^-1 F_q - gamma,
 * gamma = -(d^2 Phi/dt^2 - G q''). Returns reduced_force's status, or 3 when the complement is not positive
 * definite (a rank-deficient constraint Jacobian). */
static int accelerations(const StepKernel *s, const double *q, const double *v, int stage, double *a, double *lam) {
    const long n_q = s->n_q, m = s->m, np = s->n_products;
    coordinates(s, q, v, stage);
    const int status = reduced_force(s, v, stage);
    if (status) return status;
    for (long i = 0; i < n_q; i++) {
        double acc = 0.0;
        for (long j = 0; j < n_q; j++) acc += s->mass_inverse[i * n_q + j] * s->Fq[j];
        a[i] = acc;
    }
    if (!m) return 0;
    constraint_jacobian(s, s->G);
    schur_complement(s, s->G);
    /* lam = G M^-1 F - gamma, gamma = -2 c dX_a . dX_b (the quadratic rows; 0 on the linear ones) - (dPhi/dE) P p'' */
    if (s->moving) constraint_rate(s, s->accel_offset + stage * s->n, lam);
    else memset(lam, 0, m * sizeof(double));
    for (long i = 0; i < np; i++) {
        const long *ia = s->row_a + 3 * i, *ib = s->row_b + 3 * i;
        const double *dE = s->dE;
        lam[i] += 2.0 * s->row_coefficient[i] * (dE[ia[0]] * dE[ib[0]] + dE[ia[1]] * dE[ib[1]] + dE[ia[2]] * dE[ib[2]]);
    }
    for (long r = 0; r < m; r++) {
        const long *list = s->nonzero + r * (n_q + 1);
        double acc = 0.0;
        for (long k = 1; k <= list[0]; k++) acc += s->G[r * n_q + list[k]] * a[list[k]];
        lam[r] += acc;
    }
    return subtract_projection(s, lam, a) ? 3 : 0;
}

/* q'' (n_q,) and lambda (m,) of the index-1 equations at (q, q') and stage 0's time (integrators.
 * constrained_accelerations): `accelerations`'s status. */
int index1_accelerations(const StepKernel *s, const double *q, const double *v, double *a, double *lam) {
    return accelerations(s, q, v, 0, a, lam);
}

/* The mass-weighted projection of q onto Phi = 0 and of q' onto dPhi/dt = 0 at stage 2 (integrators.project), in
 * place. Returns 0, or 3 when a Schur complement is not positive definite. */
static int project(const StepKernel *s, double *q, double *dq) {
    const int stage = 2;
    double *phi = s->vector;
    int on = 0;
    for (int k = 0; k < PROJECTIONS && !on; k++) {
        coordinates(s, q, dq, stage);
        constraint_residual(s, phi);
        on = 1;
        for (long i = 0; i < s->m; i++)
            if (!(-PROJECTION_TOLERANCE < phi[i] && phi[i] < PROJECTION_TOLERANCE)) on = 0;   /* false for NaN */
        if (on) break;
        constraint_jacobian(s, s->G);
        schur_complement(s, s->G);
        if (subtract_projection(s, phi, q)) return 3;
    }
    if (!on) coordinates(s, q, dq, stage);
    constraint_jacobian(s, s->G);
    schur_complement(s, s->G);
    constraint_rate(s, s->dE, phi);
    return subtract_projection(s, phi, dq) ? 3 : 0;
}

/* One RK4 step of h (integrators.RK4.step) from (q, v) at the stages' times t, t + h/2, t + h, followed by the
 * projection: q_new, v_new (n_q,), the first stage's a1 (n_q,) and lambda (m,). Returns 0; 1 where a hinge has no
 * angle, 2 when the element kernel refuses its Gauss points, 3 when a Schur complement is not positive definite. */
int rk4_step(const StepKernel *s, const double *q, const double *v, double h, double *q_new, double *v_new,
             double *a1, double *lam) {
    const long n_q = s->n_q;
    const double half = 0.5 * h;
    double *a2 = s->accelerations, *a3 = a2 + n_q, *a4 = a3 + n_q, *sq = s->stage_q, *sv = s->stage_v;
    double *v2 = v_new;                                    /* v2 is kept in v_new until the end */
    int status = accelerations(s, q, v, 0, a1, lam);
    if (status) return status;
    for (long i = 0; i < n_q; i++) { v2[i] = v[i] + half * a1[i]; sq[i] = q[i] + half * v[i]; }
    if ((status = accelerations(s, sq, v2, 1, a2, s->multipliers))) return status;
    for (long i = 0; i < n_q; i++) { sv[i] = v[i] + half * a2[i]; sq[i] = q[i] + half * v2[i]; }
    if ((status = accelerations(s, sq, sv, 1, a3, s->multipliers))) return status;
    for (long i = 0; i < n_q; i++) { sq[i] = q[i] + h * sv[i]; sv[i] = v[i] + h * a3[i]; }
    if ((status = accelerations(s, sq, sv, 2, a4, s->multipliers))) return status;
    /* the weights h/6 (1, 2, 2, 1) with the stage rates v_i = v + c_i h a_{i-1} substituted (integrators.RK4.step) */
    const double h2 = h * h / 6, h6 = h / 6;
    for (long i = 0; i < n_q; i++) {
        const double a23 = a2[i] + a3[i];
        q_new[i] = q[i] + h * v[i] + h2 * (a1[i] + a23);
        v_new[i] = v[i] + h6 * (a1[i] + a4[i] + 2.0 * a23);
    }
    return s->m ? project(s, q_new, v_new) : 0;
}

/* Generalized-alpha's predictor (integrators.GeneralizedAlpha._predictor), element by element in the numpy path's
 * order of operations (the same bits): from q, q', q'' and a of the step's start, the q, q', q'' and a_known of the
 * Newton iteration's start, "acceleration" (q''_{n+1} = q''_n) or "displacement" (the a_{n+1} that cancels the
 * accelerations in q_{n+1}). c: alpha_f, alpha_m, 1 - alpha_m, (1 - alpha_f) / (1 - alpha_m), h (1 - gamma),
 * h gamma, h, h^2 (1/2 - beta), h^2 beta, -(1/2 - beta) / beta, 1 - alpha_f (Peng et al. 2019, Eqs. 23-24).
 * largest[0], largest[1]: max |q|, max |q'| of the prediction (NaN if any is NaN). */
void alpha_predictor(long n, const double *q0, const double *dq0, const double *ddq0, const double *accel0,
                     const double *c, int displacement, double *q, double *dq, double *ddq, double *a_known,
                     double *largest) {
    const double af = c[0], am = c[1], one_am = c[2], ratio = c[3], c1 = c[4], c2 = c[5], h = c[6], c3 = c[7],
                 c4 = c[8], cd = c[9], one_af = c[10];
    double lq = 0.0, ldq = 0.0;
    int nan_q = 0, nan_dq = 0;
    for (long i = 0; i < n; i++) {
        const double known = (af * ddq0[i] - am * accel0[i]) / one_am;
        double a_new, dd;
        if (displacement) {
            a_new = cd * accel0[i];
            dd = (a_new - known) * one_am / one_af;
        } else {
            dd = ddq0[i];
            a_new = known + ratio * dd;
        }
        a_known[i] = known;
        ddq[i] = dd;
        dq[i] = dq0[i] + c1 * accel0[i] + c2 * a_new;
        q[i] = q0[i] + h * dq0[i] + c3 * accel0[i] + c4 * a_new;
        if (isnan(q[i])) nan_q = 1; else if (fabs(q[i]) > lq) lq = fabs(q[i]);
        if (isnan(dq[i])) nan_dq = 1; else if (fabs(dq[i]) > ldq) ldq = fabs(dq[i]);
    }
    largest[0] = nan_q ? NAN : lq;
    largest[1] = nan_dq ? NAN : ldq;
}

/* E and dE/dt (n,) at (q, q') and stage 0's prescribed motion, the largest |Phi| of the constraint rows (NaN if any
 * is) and each hinge's fold angle (joints.fold_angle) into angles (n_hinges,); solver.StructureSolver's checks and
 * outputs of a state. Returns the largest |Phi|. */
double evaluate_state(const StepKernel *s, const double *q, const double *dq, double *E, double *dE, double *angles) {
    coordinates(s, q, dq, 0);
    memcpy(E, s->E, s->n * sizeof(double));
    memcpy(dE, s->dE, s->n * sizeof(double));
    double *phi = s->vector, largest = 0.0;
    int nan = 0;
    constraint_residual(s, phi);
    for (long i = 0; i < s->m; i++) {
        if (isnan(phi[i])) nan = 1;
        else if (fabs(phi[i]) > largest) largest = fabs(phi[i]);
    }
    for (long h = 0; h < s->n_hinges; h++) {
        const long *idx = s->hinge_index + 9 * h;
        double x[9];
        for (int k = 0; k < 9; k++) x[k] = E[idx[k]];
        const double p0 = x[1] * x[5] - x[2] * x[4], p1 = x[2] * x[3] - x[0] * x[5], p2 = x[0] * x[4] - x[1] * x[3];
        angles[h] = atan2(p0 * x[6] + p1 * x[7] + p2 * x[8], x[0] * x[3] + x[1] * x[4] + x[2] * x[5]);
    }
    return nan ? NAN : largest;
}

/* Generalized-alpha steps of one communication step in one call: for each step k, of h[k], alpha_step with the
 * acceleration predictor (its coefficients c + 11 k, beta' and gamma' in bg[2 k], bg[2 k + 1]) at that step's
 * time-dependent terms (terms: per step a row [P p, P p', P p'', f_constant, r_constant] of 4 n + n_q, `prepare`'s at
 * the step's end; NULL: stage 0's, which then hold for every step), the iteration matrix factorized at the predictor
 * where none is given yet or its h differs from h[k] (integrators.GeneralizedAlpha._newton's rule), then the end
 * state evaluated (evaluate_state) and checked, and the external work integrated, as solver.StructureSolver.advance
 * does per step. A step is committed only when it needs nothing of the per-step path: the loop stops before a step
 * whose Newton iteration fails (the per-step path then retries it from the displacement predictor or reports it),
 * whose state may fail the solver's checks (any q or q' not finite, max |Phi| not <= 1e-4, a gradient entry not
 * <= 1e3), or in which a hinge with a stop reaches it (the per-step path records the latch). The state, the matrix
 * and eta are then those at that step's start, so that the per-step path takes the step as if the loop had not.
 * control: the Newton tolerance, the velocity tolerance over it, eta at the start, the iterations allowed, the h of
 * the given matrix (lu, pivots; NULL: none), the power of the external force at the start (W), the work so far (J),
 * the number of steps. q0, q0', q0'', a0, lambda0: the state at the start. Factorizations go into the two owned
 * buffers (lu_a, piv_a) and (lu_b, piv_b), never into the given matrix (a saved solver state may hold it).
 * force: the external force whose power on dE the work integrates (StructureModel.external_force_E), N and N m: one
 * row (n,), or one per step with terms. stops: (n_hinges,) each hinge's stop angle (rad), NaN where it has none or
 * is latched. angles: (n_hinges,) the fold angles at the start on entry, at the last committed state on return.
 * scratch: 2 (5 n_q + m) + 2 n + n_hinges. On return x = [q, q', q'', a, a_known, lambda], E, dE hold the last
 * committed state (where one was committed) and out: the steps committed, the corrections taken in them, eta, the
 * matrix (0 the given, 1 lu_a, 2 lu_b), its h, the power at the last committed state, the work there, max |Phi|
 * there. Returns 0 when every step is committed, 1 when the loop stopped before a step. */
int alpha_steps(const StepKernel *s, const double *h, const double *c, const double *bg, const double *control,
                const double *terms, const double *q0, const double *dq0, const double *ddq0, const double *accel0,
                const double *lam0, const double *lu, const int *pivots, double *lu_a, int *piv_a, double *lu_b,
                int *piv_b, const double *force, const double *stops, double *angles, double *scratch, double *x,
                double *E, double *dE, double *out) {
    const long n = s->n_q, m = s->m, size = 5 * n + m, n_steps = (long)control[7], row = 4 * s->n + n;
    double *states[2] = {scratch, scratch + size}, *E_new = scratch + 2 * size, *dE_new = E_new + s->n,
           *angles_new = dE_new + s->n;
    StepKernel at = *s;                            /* the model at step k's terms */
    const double *current_lu = lu;
    const int *current_pivots = pivots;
    int current = 0;                               /* 0: the given matrix, 1: lu_a, 2: lu_b */
    double eta = control[2], matrix_h = lu ? control[4] : NAN, power = control[5], work = control[6];
    double residual = NAN, step_out[6];
    long committed = 0, corrections = 0;
    int stopped = 0;
    for (long k = 0; k < n_steps; k++) {
        double *y = states[k % 2];
        const double *f = force;
        if (terms) {
            const double *t = terms + k * row;
            at.offset = t;
            at.rate_offset = t + s->n;
            at.accel_offset = t + 2 * s->n;
            at.f_constant = t + 3 * s->n;
            at.r_constant = t + 4 * s->n;
            f = force + k * s->n;
        }
        /* the spare: an owned buffer that is not the matrix */
        double *spare_lu = current == 1 ? lu_b : lu_a;
        int *spare_pivots = current == 1 ? piv_b : piv_a;
        const double step_control[8] = {bg[2 * k], bg[2 * k + 1], control[0], control[1], eta,
                                         current_lu == NULL || matrix_h != h[k] ? 1.0 : 0.0, control[3], 0.0};
        if (alpha_step(&at, q0, dq0, ddq0, accel0, m ? lam0 : NULL, c + 11 * k, step_control, current_lu,
                       current_pivots, spare_lu, spare_pivots, y, step_out)) { stopped = 1; break; }
        const double *q = y, *dq = y + n;
        int ok = 1;
        for (long i = 0; i < n && ok; i++) ok = isfinite(q[i]) && isfinite(dq[i]);
        const double phi = ok ? evaluate_state(&at, q, dq, E_new, dE_new, angles_new) : NAN;
        ok = ok && phi <= 1e-4;
        for (long i = 0; i < s->n && ok; i++) ok = i % 9 < 3 || fabs(E_new[i]) <= 1e3;
        for (long j = 0; j < s->n_hinges && ok; j++) {
            const double a = angles[j] - stops[j], b = angles_new[j] - stops[j];
            ok = !(a * b <= 0.0 && fabs(a - b) < PI);
        }
        if (!ok) { stopped = 1; break; }
        /* committed: the step's matrix, eta, power and work (StructureSolver.advance: the trapezoidal rule) */
        if (step_out[4] > 0.0) {
            current = spare_lu == lu_a ? 1 : 2;
            current_lu = spare_lu;
            current_pivots = spare_pivots;
            matrix_h = h[k];
        }
        eta = step_out[3];
        double p = 0.0;
        for (long i = 0; i < s->n; i++) p += f[i] * dE_new[i];
        work = work + 0.5 * h[k] * (power + p);
        power = p;
        residual = phi;
        corrections += (long)step_out[0];
        for (long j = 0; j < s->n_hinges; j++) angles[j] = angles_new[j];
        memcpy(E, E_new, s->n * sizeof(double));
        memcpy(dE, dE_new, s->n * sizeof(double));
        q0 = y; dq0 = y + n; ddq0 = y + 2 * n; accel0 = y + 3 * n; lam0 = y + 5 * n;
        committed++;
    }
    if (committed) memcpy(x, states[(committed - 1) % 2], size * sizeof(double));
    out[0] = (double)committed;
    out[1] = (double)corrections;
    out[2] = eta;
    out[3] = (double)current;
    out[4] = matrix_h;
    out[5] = power;
    out[6] = work;
    out[7] = residual;
    return stopped;
}
