/* One step of the flat-wake UVLM (uvlm-flat) in C: from the exchanged coordinates E, dE to the circulations, the
 * panel forces and the generalized force Q, on buffers allocated once (flat_wake_step.py). The reference is the numpy
 * path of uvlm.UVLM (lattice.Lattice.geometry, factorization.BoundSystem, vlm.pressure_jump_forces,
 * loads.resultants; $WINGSIM_KERNELS=numpy), which the tests compare with to 1e-12 relative.
 *
 *   1. geometry (Otsuka et al. 2019, Eqs. 20, 21, 24): every lattice point is a shape row on the slot array
 *      X = E.reshape(-1, 3); each row has at most K non-zero entries (one element's slots), gathered by index;
 *      the mean surface's offsets, tangents, normals, areas and edge weights as Lattice.geometry;
 *   2. the influence matrices A = n . T, A_x = span_weight . T, A_y = chord_weight . T of the bound rings and the
 *      flat horseshoe legs (Otsuka et al. 2019, Eqs. 19, 22; the Biot-Savart pair of biot_savart.c with the Scully
 *      core), the segment circulations linear in Gamma through sparse (CSR) weights, and the LU of A with partial
 *      pivoting; reused while the lattice moves rigidly (BoundSystem's rule: a cheap distance test here, the
 *      Kabsch fit by the caller);
 *   3. Gamma from A Gamma = -(U - r') . n (Eq. 22), the tangential products V . span_weight + A_x Gamma and
 *      V . chord_weight + A_y Gamma, the pressure jump with dGamma/dt (Eq. 23, the Kutta-Joukowski edge form of
 *      vlm.pressure_jump_forces), the panel forces (Eq. 25) and Q = sum_p S(x_a, y_a)^T a (Eq. 12) by scatter;
 *      the sums the resultants need (total force, first moment sum_p x_p f_p^T, area-weighted normal).
 *
 * Arithmetic: IEEE double, built with -ffp-contract=off like the other kernels; the sums run in another order than
 * numpy's matrix products, so the results agree with the reference to round-off, not bit for bit.
 */
#include <math.h>
#include <string.h>

#define FOUR_PI (4.0 * 3.14159265358979323846)
#define TINY 2.2250738585072014e-308     /* smallest normal double, numpy.finfo(float).tiny */

/* What one step reads and writes; every array C-contiguous double (or long), allocated by flat_wake_step.py. */
typedef struct {
    long n_slots, n_rows, K, n_corners, n_panels, M, N, flat;
    long lapack_lu;              /* 1: the caller factorizes A with LAPACK (large lattices), 0: factorize here */
    const long *row_index;       /* (n_rows, K) slot of each shape entry (rows: corners, collocation, application,
                                    r_x, r_y at the collocation points, then the corners' r_x, r_y if not flat) */
    const double *row_value;     /* (n_rows, K) its value (0 in the padding) */
    const double *surface;       /* (6, P): y_x, h_x, y_f, h_f at the collocation point, y_x, h_x at the bound segment */
    const double *corner_offset; /* (n_corners,) m: normal offset of the mean surface at the corners */
    const double *colloc_offset; /* (P,) m: at the collocation points */
    const double *panel_span;    /* (P,) m */
    long n_segments;             /* finite segments between nodes (corners, then the far ends of finite legs) */
    const long *seg_start, *seg_end, *seg_ptr, *seg_col;
    const double *seg_val;       /* CSR (n_segments, P): segment circulation = weights @ Gamma */
    long n_legs;                 /* semi-infinite legs from corners along the free stream (0: none) */
    const long *leg_start, *leg_ptr, *leg_col;
    const double *leg_val;
    long n_far;                  /* far ends of finite legs: corner far_head[k] + far_length[k] * direction */
    const long *far_head;
    const double *far_length;
    double core, tolerance;      /* vortex core radius, m; rigid tolerance, m */
    const double *E, *dE;        /* (3 n_slots,) inputs */
    const double *scalars;       /* U (3), direction (3), density, rate coefficients c0, c1, c2, its order */
    const double *history;       /* (2, P): Gamma(t_{n-1}), Gamma(t_{n-2}) */
    double *points;              /* (n_rows, 3) the gathered rows */
    double *nodes;               /* (n_corners + n_far, 3) */
    double *normal, *span_weight, *chord_weight, *relative;   /* (P, 3) */
    double *area;                /* (P,) */
    double *A, *A_x, *A_y;       /* (P, P) row-major */
    double *LU;                  /* (P, P) column-major (LAPACK's layout): A, then its LU */
    long *pivots;                /* (P,) 0-based pivot rows */
    double *distances, *reference_distances;   /* (n_corners,) */
    double *reference;           /* (n_corners + 3 P, 3): corners, collocation, r_x, r_y of the reference geometry */
    double *reference_direction; /* (3,) */
    long *has_reference;         /* (1,) */
    double *gamma, *v_x, *v_y;   /* (P,) */
    double *forces;              /* (P, 3) */
    double *Q;                   /* (3 n_slots,) */
    double *sums;                /* (15,): total force, first moment (3 x 3, row-major), sum area * normal */
    long *bad;                   /* (1,): the first panel of zero area */
    double *segment_table;       /* (6 S,) scratch: the segments in structure of arrays, S the larger count */
    double *wash;                /* (3 S,) scratch: n . v, w_s . v, w_c . v of one collocation point */
} FlatWakeStep;

#define INLINE static inline __attribute__((always_inline))

/* the segment loop built for AVX-512, AVX2 and plain x86-64, as in biot_savart.c */
#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__) && defined(__ELF__)
#define VECTOR_CLONES __attribute__((target_clones("avx512f", "avx2", "default")))
#else
#define VECTOR_CLONES
#endif

INLINE double at_least_tiny(double x) { return x > TINY ? x : TINY; }

INLINE void cross(const double *a, const double *b, double *out) {
    double x = a[1] * b[2] - a[2] * b[1], y = a[2] * b[0] - a[0] * b[2], z = a[0] * b[1] - a[1] * b[0];
    out[0] = x;
    out[1] = y;
    out[2] = z;
}

INLINE double dot(const double *a, const double *b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

/* v / |v| (a zero vector stays zero), lattice._unit_rows. */
INLINE void unit(double *v) {
    double norm = sqrt(dot(v, v));
    double d = norm > 0 ? norm : 1.0;
    v[0] /= d;
    v[1] /= d;
    v[2] /= d;
}

/* The velocity per unit circulation at p of the segment from a along r0 (b - a, or the unit direction of a
 * semi-infinite segment), with the Scully core: biot_savart.c's pair. */
INLINE void segment_velocity(const double *p, const double *a, const double *r0, double core2, int semi_infinite,
                             double *v) {
    double r1x = p[0] - a[0], r1y = p[1] - a[1], r1z = p[2] - a[2];
    double x = r0[1] * r1z - r0[2] * r1y, y = r0[2] * r1x - r0[0] * r1z, z = r0[0] * r1y - r0[1] * r1x;
    double n1 = sqrt(r1x * r1x + r1y * r1y + r1z * r1z);
    double k = r0[0] * r1x + r0[1] * r1y + r0[2] * r1z, l2 = 1.0;
    if (semi_infinite) {
        k = k / at_least_tiny(n1) + 1.0;
    } else {
        l2 = r0[0] * r0[0] + r0[1] * r0[1] + r0[2] * r0[2];
        double d2 = k - l2;             /* r0 . r2, exactly 0 when r2 = 0 */
        k = k / at_least_tiny(n1);
        double r2x = r1x - r0[0], r2y = r1y - r0[1], r2z = r1z - r0[2];
        k -= d2 / at_least_tiny(sqrt(r2x * r2x + r2y * r2y + r2z * r2z));
    }
    k /= at_least_tiny((x * x + y * y + z * z + core2 * l2) * FOUR_PI);
    v[0] = x * k;
    v[1] = y * k;
    v[2] = z * k;
}

/* out (rows, 3) = S X over the rows' K gathered entries. */
static void gather(const FlatWakeStep *s, long first, long rows, const double *X, double *out) {
    for (long r = first; r < first + rows; r++) {
        const long *index = s->row_index + r * s->K;
        const double *value = s->row_value + r * s->K;
        double x = 0.0, y = 0.0, z = 0.0;
        for (long k = 0; k < s->K; k++) {
            const double *slot = X + 3 * index[k];
            x += value[k] * slot[0];
            y += value[k] * slot[1];
            z += value[k] * slot[2];
        }
        double *o = out + 3 * (r - first);
        o[0] = x;
        o[1] = y;
        o[2] = z;
    }
}

/* Lattice.geometry at E, the relative flow U - r' at the collocation points, and the corners' distances from the
 * first corner (rigid.distances_from_first). */
static void geometry(FlatWakeStep *s) {
    const long nc = s->n_corners, P = s->n_panels;
    gather(s, 0, s->n_rows, s->E, s->points);
    double *corners = s->nodes, *colloc = s->points + 3 * nc, *r_x = s->points + 3 * (nc + 2 * P),
           *r_y = s->points + 3 * (nc + 3 * P);
    memcpy(corners, s->points, sizeof(double) * 3 * (size_t)nc);
    const double *y_x = s->surface, *h_x = y_x + P, *y_f = h_x + P, *h_f = y_f + P, *b_x = h_f + P, *b_h = b_x + P;
    if (!s->flat) {
        const double *tx = s->points + 3 * (nc + 4 * P), *ty = tx + 3 * nc;
        for (long c = 0; c < nc; c++) {
            double n[3];
            cross(tx + 3 * c, ty + 3 * c, n);
            unit(n);
            for (int i = 0; i < 3; i++) corners[3 * c + i] += s->corner_offset[c] * n[i];
        }
    }
    for (long p = 0; p < P; p++) {
        const double *rx = r_x + 3 * p, *ry = r_y + 3 * p;
        double n0[3], t_f[3], t_x[3], c[3], edge[3], scaled[3];
        cross(rx, ry, n0);
        unit(n0);
        for (int i = 0; i < 3; i++) t_f[i] = y_f[p] * ry[i];
        if (!s->flat) {
            for (int i = 0; i < 3; i++) {
                colloc[3 * p + i] += s->colloc_offset[p] * n0[i];
                t_f[i] += h_f[p] * n0[i];
            }
        }
        for (int i = 0; i < 3; i++) t_x[i] = rx[i] + y_x[p] * ry[i] + h_x[p] * n0[i];
        cross(t_x, t_f, c);
        double norm = sqrt(dot(c, c)), d = norm > 0 ? norm : 1.0;
        double *normal = s->normal + 3 * p;
        for (int i = 0; i < 3; i++) normal[i] = c[i] / d;
        for (int i = 0; i < 3; i++) {
            edge[i] = s->panel_span[p] * (rx[i] + b_x[p] * ry[i] + b_h[p] * n0[i]);
            scaled[i] = t_f[i] / (double)s->M;
        }
        s->area[p] = norm * s->panel_span[p] / (double)s->M;
        cross(scaled, normal, s->span_weight + 3 * p);
        cross(normal, edge, s->chord_weight + 3 * p);
    }
    gather(s, nc, P, s->dE, s->relative);           /* r' at the collocation points */
    for (long p = 0; p < P; p++)
        for (int i = 0; i < 3; i++) s->relative[3 * p + i] = s->scalars[i] - s->relative[3 * p + i];
    for (long c = 0; c < nc; c++) {
        double o[3] = {corners[3 * c] - corners[0], corners[3 * c + 1] - corners[1], corners[3 * c + 2] - corners[2]};
        s->distances[c] = sqrt(dot(o, o));
    }
}

/* wn, wx, wy (S,): n . v, w_s . v, w_c . v at `at` of the S segments in structure of arrays (a_x, a_y, a_z, r0_x,
 * r0_y, r0_z rows of S); semi_infinite is a constant where this is inlined, so that the loop vectorizes. */
INLINE void wash_row(const double *at, const double *n, const double *ws, const double *wc, long S,
                     const double *restrict seg, double core2, int semi_infinite, double *restrict wn,
                     double *restrict wx, double *restrict wy) {
    const double *ax = seg, *ay = seg + S, *az = seg + 2 * S, *r0x = seg + 3 * S, *r0y = seg + 4 * S,
                 *r0z = seg + 5 * S;
    for (long g = 0; g < S; g++) {
        double p[3] = {at[0], at[1], at[2]}, a[3] = {ax[g], ay[g], az[g]}, r0[3] = {r0x[g], r0y[g], r0z[g]}, v[3];
        segment_velocity(p, a, r0, core2, semi_infinite, v);
        wn[g] = dot(n, v);
        wx[g] = dot(ws, v);
        wy[g] = dot(wc, v);
    }
}

/* Adds the wash of `count` segments (finite, or semi-infinite along `direction`) to A, A_x, A_y: per collocation
 * point one vectorized pass over the segments, then the CSR weights. */
VECTOR_CLONES
static void add_segments(FlatWakeStep *s, long count, const long *start, const long *end, const long *ptr,
                         const long *col, const double *val, const double *direction) {
    const long P = s->n_panels;
    const double core2 = s->core * s->core;
    const double *colloc = s->points + 3 * s->n_corners;
    double *seg = s->segment_table, *wn = s->wash, *wx = wn + count, *wy = wx + count;
    for (long g = 0; g < count; g++) {
        const double *from = s->nodes + 3 * start[g];
        for (int i = 0; i < 3; i++) {
            seg[i * count + g] = from[i];
            seg[(3 + i) * count + g] = direction ? direction[i] : s->nodes[3 * end[g] + i] - from[i];
        }
    }
    for (long p = 0; p < P; p++) {
        const double *at = colloc + 3 * p, *n = s->normal + 3 * p, *ws = s->span_weight + 3 * p,
                     *wc = s->chord_weight + 3 * p;
        if (direction)
            wash_row(at, n, ws, wc, count, seg, core2, 1, wn, wx, wy);
        else
            wash_row(at, n, ws, wc, count, seg, core2, 0, wn, wx, wy);
        double *a = s->A + p * P, *a_x = s->A_x + p * P, *a_y = s->A_y + p * P;
        for (long g = 0; g < count; g++)
            for (long j = ptr[g]; j < ptr[g + 1]; j++) {
                a[col[j]] += val[j] * wn[g];
                a_x[col[j]] += val[j] * wx[g];
                a_y[col[j]] += val[j] * wy[g];
            }
    }
}

/* 0, or -2 when a pivot of the LU is below 1e-13 times the largest (factorization.BoundSystem's test; also NaN or
 * inf pivots). */
static int pivots_ok(const FlatWakeStep *s) {
    const long n = s->n_panels;
    double smallest = INFINITY, largest = 0.0;
    for (long k = 0; k < n; k++) {
        double d = fabs(s->LU[k * n + k]);
        if (isnan(d) || isinf(d)) return -2;
        if (d < smallest) smallest = d;
        if (d > largest) largest = d;
    }
    return smallest > 1e-13 * largest ? 0 : -2;
}

/* A (row-major) into LU column-major, LAPACK's layout. */
static void copy_to_columns(FlatWakeStep *s) {
    const long n = s->n_panels;
    for (long i = 0; i < n; i++)
        for (long j = 0; j < n; j++) s->LU[j * n + i] = s->A[i * n + j];
}

/* LU of A in place in LU (column-major) with partial pivoting, LAPACK dgetf2's algorithm (the first largest
 * magnitude as the pivot, 0-based pivot rows as scipy gives them); the updates run down contiguous columns. */
static void factorize(FlatWakeStep *s) {
    const long n = s->n_panels;
    double *lu = s->LU;
    for (long k = 0; k < n; k++) {
        double *restrict column = lu + k * n;
        long piv = k;
        double best = fabs(column[k]);
        for (long i = k + 1; i < n; i++)
            if (fabs(column[i]) > best) best = fabs(column[i]), piv = i;
        s->pivots[k] = piv;
        if (piv != k)
            for (long j = 0; j < n; j++) {
                double t = lu[j * n + k];
                lu[j * n + k] = lu[j * n + piv];
                lu[j * n + piv] = t;
            }
        double pivot = column[k];
        if (pivot == 0.0) continue;
        for (long i = k + 1; i < n; i++) column[i] /= pivot;
        for (long j = k + 1; j < n; j++) {
            double *restrict target = lu + j * n;
            double u = target[k];
            for (long i = k + 1; i < n; i++) target[i] -= column[i] * u;
        }
    }
}

/* The reference for reuse becomes the current geometry. */
static void keep_reference(FlatWakeStep *s) {
    const long nc = s->n_corners, P = s->n_panels;
    memcpy(s->reference, s->nodes, sizeof(double) * 3 * (size_t)nc);
    memcpy(s->reference + 3 * nc, s->points + 3 * nc, sizeof(double) * 3 * (size_t)P);
    memcpy(s->reference + 3 * (nc + P), s->points + 3 * (nc + 2 * P), sizeof(double) * 6 * (size_t)P);
    memcpy(s->reference_distances, s->distances, sizeof(double) * (size_t)nc);
    memcpy(s->reference_direction, s->scalars + 3, sizeof(double) * 3);
    s->has_reference[0] = 1;
}

/* The influence matrices at the current geometry and, unless lapack_lu, their LU; 0, 3 (A is in LU for the caller
 * to factorize with LAPACK), -1 (a panel of zero area: s->bad) or -2 (a singular matrix). The reference for reuse
 * becomes this geometry only when the factorization succeeds. */
static int build(FlatWakeStep *s) {
    const long nc = s->n_corners, P = s->n_panels;
    const double *direction = s->scalars + 3;
    for (long p = 0; p < P; p++)
        if (!(s->area[p] > 0)) {        /* also true for a NaN area */
            s->bad[0] = p;
            return -1;
        }
    s->has_reference[0] = 0;
    for (long k = 0; k < s->n_far; k++)             /* vlm.leg_ends */
        for (int i = 0; i < 3; i++)
            s->nodes[3 * (nc + k) + i] = s->nodes[3 * s->far_head[k] + i] + s->far_length[k] * direction[i];
    memset(s->A, 0, sizeof(double) * (size_t)(P * P));
    memset(s->A_x, 0, sizeof(double) * (size_t)(P * P));
    memset(s->A_y, 0, sizeof(double) * (size_t)(P * P));
    add_segments(s, s->n_segments, s->seg_start, s->seg_end, s->seg_ptr, s->seg_col, s->seg_val, NULL);
    if (s->n_legs > 0)
        add_segments(s, s->n_legs, s->leg_start, NULL, s->leg_ptr, s->leg_col, s->leg_val, direction);
    copy_to_columns(s);
    if (s->lapack_lu) return 3;
    factorize(s);
    if (pivots_ok(s) != 0) return -2;
    keep_reference(s);
    return 0;
}

/* Gamma, the panel forces, Q and the sums of the loads with the current factorization. */
static void solve(FlatWakeStep *s) {
    const long P = s->n_panels, M = s->M, N = s->N;
    const double density = s->scalars[6], c0 = s->scalars[7], c1 = s->scalars[8], c2 = s->scalars[9];
    const int order = (int)s->scalars[10];     /* of the difference dGamma/dt: 0 (none), 1 or 2 */
    double *g = s->gamma;
    for (long p = 0; p < P; p++) g[p] = -dot(s->relative + 3 * p, s->normal + 3 * p);
    for (long k = 0; k < P; k++)
        if (s->pivots[k] != k) {
            double t = g[k];
            g[k] = g[s->pivots[k]];
            g[s->pivots[k]] = t;
        }
    for (long j = 0; j < P; j++) {                  /* L y = P b, then U Gamma = y, down the columns */
        const double *column = s->LU + j * P;
        for (long i = j + 1; i < P; i++) g[i] -= column[i] * g[j];
    }
    for (long j = P - 1; j >= 0; j--) {
        const double *column = s->LU + j * P;
        g[j] /= column[j];
        for (long i = 0; i < j; i++) g[i] -= column[i] * g[j];
    }
    memset(s->Q, 0, sizeof(double) * 3 * (size_t)s->n_slots);
    memset(s->sums, 0, sizeof(double) * 15);
    const double *application = s->points + 3 * (s->n_corners + P);
    for (long p = 0; p < P; p++) {
        double vx = dot(s->relative + 3 * p, s->span_weight + 3 * p), vy = dot(s->relative + 3 * p,
                                                                               s->chord_weight + 3 * p);
        const double *ax = s->A_x + p * P, *ay = s->A_y + p * P;
        double sx = 0.0, sy = 0.0;
        for (long q = 0; q < P; q++) {
            sx += ax[q] * g[q];
            sy += ay[q] * g[q];
        }
        vx += sx;
        vy += sy;
        s->v_x[p] = vx;
        s->v_y[p] = vy;
        long j = p % N, i = (p / N) % M;
        double d_span = j > 0 ? g[p] - g[p - 1] : g[p], d_chord = i > 0 ? g[p] - g[p - N] : g[p];
        double jump = density * (vx * d_span + vy * d_chord);
        if (order) {        /* uvlm.circulation_rate, operation for operation */
            double rate = order == 1 ? (g[p] - s->history[p]) / c0
                                     : g[p] * c0 - s->history[p] * c1 + s->history[P + p] * c2;
            jump = jump + density * rate * s->area[p];
        }
        double *f = s->forces + 3 * p;
        const double *n = s->normal + 3 * p, *x = application + 3 * p;
        for (int k = 0; k < 3; k++) f[k] = jump * n[k];
        for (int k = 0; k < 3; k++) {
            s->sums[k] += f[k];
            s->sums[12 + k] += s->area[p] * n[k];
            for (int l = 0; l < 3; l++) s->sums[3 + 3 * k + l] += x[k] * f[l];
        }
        const long row = s->n_corners + P + p;     /* the application row: Q += S(x_a, y_a)^T f */
        for (long k = 0; k < s->K; k++) {
            double w = s->row_value[row * s->K + k], *q = s->Q + 3 * s->row_index[row * s->K + k];
            q[0] += w * f[0];
            q[1] += w * f[1];
            q[2] += w * f[2];
        }
    }
}

/* Whether the lattice is where the reference was, bit for bit (a wing at rest): rigid_fit's identity, so that the
 * matrices are reused without the caller's fit. */
static int unmoved(const FlatWakeStep *s) {
    const long nc = s->n_corners, P = s->n_panels;
    return memcmp(s->reference, s->nodes, sizeof(double) * 3 * (size_t)nc) == 0
        && memcmp(s->reference + 3 * nc, s->points + 3 * nc, sizeof(double) * 3 * (size_t)P) == 0
        && memcmp(s->reference + 3 * (nc + P), s->points + 3 * (nc + 2 * P), sizeof(double) * 6 * (size_t)P) == 0
        && memcmp(s->reference_direction, s->scalars + 3, sizeof(double) * 3) == 0;
}

/* One step. mode 0: the geometry at E, then, if a reference exists and no corner distance from the first corner
 * changed by more than 2 tolerance (rigid.may_be_rigid), return 2: the caller fits the rigid motion and calls
 * again with mode 1 (reuse the reference's matrices) or 2 (rebuild), the geometry kept; a lattice exactly where
 * the reference was reuses them at once. A build with lapack_lu returns 3 with A in LU: the caller factorizes it
 * in place with LAPACK, writes the pivots and calls mode 3 (test the pivots, solve). Returns 0 (solved with the
 * reference's matrices), 1 (solved after a build), 3, -1 (panel s->bad has zero area) or -2 (singular). */
int flat_wake_step(FlatWakeStep *s, int mode) {
    if (mode == 0) {
        geometry(s);
        if (s->has_reference[0]) {
            int rigid = 1;
            for (long c = 0; c < s->n_corners; c++)      /* false for a NaN distance too */
                if (!(fabs(s->distances[c] - s->reference_distances[c]) <= 2 * s->tolerance)) rigid = 0;
            if (rigid && unmoved(s)) mode = 1;
            else if (rigid) return 2;
        }
    }
    if (mode == 0 || mode == 2) {
        int status = build(s);
        if (status != 0) return status;
    } else if (mode == 3) {
        if (pivots_ok(s) != 0) return -2;
        keep_reference(s);
    }
    solve(s);
    return mode != 1;
}
