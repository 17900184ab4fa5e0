/* Compiled Biot-Savart kernels (C): the segment velocity of biot_savart.py (Otsuka et al. 2019, Eq. 19, with the
 * Scully core), pair by pair without (P, S) temporaries. Compiled once per machine by fmu_common/native.py
 * (and into every aero FMU by its build) and called through ctypes; biot_savart.py's numpy kernel is the
 * reference ($WINGSIM_KERNELS=numpy) and the tests check both agree to 1e-12 relative.
 *
 * Each pair follows biot_savart._kernel operation for operation: r1 = p - a, r0 = b - a (or the unit
 * direction d of a semi-infinite segment, with |r0|^2 taken as 1), c = r0 x r1, k = r0 . (r1/|r1| - r2/|r2|)
 * (or 1 + d . r1/|r1|), divided by 4 pi (|c|^2 + delta^2 |r0|^2); a division by a zero norm gives 0 (a point at
 * a segment's end, a zero-length segment): the divisors are max(norm, TINY) and the dividends are then 0.
 *
 * Arithmetic: IEEE double, each operation rounded on its own (built with -ffp-contract=off: no fused
 * multiply-add; no fast-math), so the results equal numpy's kernel to the last bits in practice. The inner loops
 * run over independent pairs reading contiguous arrays, so that the compiler vectorizes them; `target_clones`
 * builds them for AVX-512, AVX2 and plain x86-64, and the loader picks the widest the CPU has (an ELF loader's
 * ifunc: a Windows DLL, built with mingw-w64 for a standalone FMU, has the plain x86-64 ones only).
 *
 * Arrays are C-contiguous doubles: points, normals (P, 3); starts, ends (S, 3); gamma (S,).
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__) && defined(__ELF__)
#define VECTOR_CLONES __attribute__((target_clones("avx512f", "avx2", "default")))
#else
#define VECTOR_CLONES
#endif

#define FOUR_PI (4.0 * 3.14159265358979323846)
#define TINY 2.2250738585072014e-308     /* smallest normal double, numpy.finfo(float).tiny */
#define POINT_BLOCK 256                  /* points per block of velocity_sum: coordinates and sums stay in L1 */

const long point_block = POINT_BLOCK;    /* for the tests, which sum over several blocks */

static inline __attribute__((always_inline)) double at_least_tiny(double x) { return x > TINY ? x : TINY; }

/* (c_x, c_y, c_z, k) of one pair, v = k c per unit circulation (biot_savart._kernel). */
#define INLINE static inline __attribute__((always_inline))

INLINE void pair(double r1x, double r1y, double r1z, double r0x, double r0y, double r0z, double l2,
                        double core2, int semi_infinite, double *cx, double *cy, double *cz, double *k_out) {
    double x = r0y * r1z - r0z * r1y;
    double y = r0z * r1x - r0x * r1z;
    double z = r0x * r1y - r0y * r1x;
    double n1 = sqrt(r1x * r1x + r1y * r1y + r1z * r1z);
    double k = r0x * r1x + r0y * r1y + r0z * r1z;
    if (semi_infinite) {
        k = k / at_least_tiny(n1) + 1.0;
    } else {
        double d2 = k - l2;             /* r0 . r2, exactly 0 when r2 = 0 */
        k = k / at_least_tiny(n1);
        double r2x = r1x - r0x, r2y = r1y - r0y, r2z = r1z - r0z;
        double n2 = sqrt(r2x * r2x + r2y * r2y + r2z * r2z);
        k -= d2 / at_least_tiny(n2);
    }
    double den = (x * x + y * y + z * z + core2 * l2) * FOUR_PI;
    *cx = x;
    *cy = y;
    *cz = z;
    *k_out = k / at_least_tiny(den);
}

/* Structure of arrays of the segments, 7 rows of S: a_x, a_y, a_z, r0_x, r0_y, r0_z, |r0|^2. NULL if out of
 * memory. */
static double *segments(long n_segments, const double *starts, const double *ends, int semi_infinite) {
    double *seg = malloc(sizeof(double) * 7 * (size_t)(n_segments > 0 ? n_segments : 1));
    if (!seg) return NULL;
    for (long s = 0; s < n_segments; s++) {
        for (int i = 0; i < 3; i++) {
            seg[i * n_segments + s] = starts[3 * s + i];
            seg[(3 + i) * n_segments + s] = semi_infinite ? ends[3 * s + i] : ends[3 * s + i] - starts[3 * s + i];
        }
        const double *r0 = seg + 3 * n_segments + s;
        seg[6 * n_segments + s] = semi_infinite ? 1.0
            : r0[0] * r0[0] + r0[n_segments] * r0[n_segments] + r0[2 * n_segments] * r0[2 * n_segments];
    }
    return seg;
}

/* out (P, S): n_p . v_ps per unit circulation, the segments in structure of arrays (`segments`); semi_infinite
 * is a constant where this is inlined, so that each loop is compiled without the branch. */
INLINE void normal_wash_rows(long n_points, const double *restrict points, const double *restrict normals, long S,
                             const double *restrict seg, double core2, int semi_infinite, double *restrict out) {
    const double *ax = seg, *ay = seg + S, *az = seg + 2 * S, *r0x = seg + 3 * S, *r0y = seg + 4 * S,
                 *r0z = seg + 5 * S, *l2 = seg + 6 * S;
    for (long p = 0; p < n_points; p++) {
        const double px = points[3 * p], py = points[3 * p + 1], pz = points[3 * p + 2];
        const double nx = normals[3 * p], ny = normals[3 * p + 1], nz = normals[3 * p + 2];
        double *restrict row = out + p * S;
        for (long s = 0; s < S; s++) {
            double cx, cy, cz, k;
            pair(px - ax[s], py - ay[s], pz - az[s], r0x[s], r0y[s], r0z[s], l2[s], core2, semi_infinite,
                 &cx, &cy, &cz, &k);
            row[s] = (cx * nx + ny * cy + nz * cz) * k;
        }
    }
}

/* out (P, S): n_p . v_ps per unit circulation (m/s per m^2/s). Returns 0, or -1 if out of memory. */
VECTOR_CLONES
int normal_wash(long n_points, const double *points, const double *normals, long n_segments, const double *starts,
                const double *ends, double core, int semi_infinite, double *out) {
    double *seg = segments(n_segments, starts, ends, semi_infinite);
    if (!seg) return -1;
    if (semi_infinite)
        normal_wash_rows(n_points, points, normals, n_segments, seg, core * core, 1, out);
    else
        normal_wash_rows(n_points, points, normals, n_segments, seg, core * core, 0, out);
    free(seg);
    return 0;
}

/* out (3, P, S): the components of v_ps per unit circulation, the segments in structure of arrays; semi_infinite
 * as in normal_wash_rows. */
INLINE void component_rows(long P, const double *restrict points, long S, const double *restrict seg, double core2,
                           int semi_infinite, double *restrict out) {
    const double *ax = seg, *ay = seg + S, *az = seg + 2 * S, *r0x = seg + 3 * S, *r0y = seg + 4 * S,
                 *r0z = seg + 5 * S, *l2 = seg + 6 * S;
    for (long p = 0; p < P; p++) {
        const double px = points[3 * p], py = points[3 * p + 1], pz = points[3 * p + 2];
        double *restrict ox = out + p * S, *restrict oy = out + (P + p) * S, *restrict oz = out + (2 * P + p) * S;
        for (long s = 0; s < S; s++) {
            double cx, cy, cz, k;
            pair(px - ax[s], py - ay[s], pz - az[s], r0x[s], r0y[s], r0z[s], l2[s], core2, semi_infinite,
                 &cx, &cy, &cz, &k);
            ox[s] = cx * k;
            oy[s] = cy * k;
            oz[s] = cz * k;
        }
    }
}

/* out (3, P, S): the x, y, z components of v_ps per unit circulation (m/s per m^2/s). Returns 0, or -1 if out of
 * memory. */
VECTOR_CLONES
int components(long n_points, const double *points, long n_segments, const double *starts, const double *ends,
               double core, int semi_infinite, double *out) {
    double *seg = segments(n_segments, starts, ends, semi_infinite);
    if (!seg) return -1;
    if (semi_infinite)
        component_rows(n_points, points, n_segments, seg, core * core, 1, out);
    else
        component_rows(n_points, points, n_segments, seg, core * core, 0, out);
    free(seg);
    return 0;
}

/* out (P, 3) = sum_s gamma_s v_ps (m/s): the velocity of segments of known circulations gamma (S,) m^2/s. Blocks
 * of POINT_BLOCK points; each segment is added to every point of a block in turn, so a point's sum runs over
 * the segments in order. Returns 0, or -1 if out of memory. */
VECTOR_CLONES
int velocity_sum(long n_points, const double *points, long n_segments, const double *starts, const double *ends,
                 const double *gamma, double core, int semi_infinite, double *out) {
    double px[POINT_BLOCK], py[POINT_BLOCK], pz[POINT_BLOCK], vx[POINT_BLOCK], vy[POINT_BLOCK], vz[POINT_BLOCK];
    const double core2 = core * core;
    for (long lo = 0; lo < n_points; lo += POINT_BLOCK) {
        const long m = n_points - lo < POINT_BLOCK ? n_points - lo : POINT_BLOCK;
        for (long i = 0; i < m; i++) {
            px[i] = points[3 * (lo + i)];
            py[i] = points[3 * (lo + i) + 1];
            pz[i] = points[3 * (lo + i) + 2];
            vx[i] = vy[i] = vz[i] = 0.0;
        }
        for (long s = 0; s < n_segments; s++) {
            const double g = gamma[s];
            if (g == 0.0) continue;
            const double ax = starts[3 * s], ay = starts[3 * s + 1], az = starts[3 * s + 2];
            double r0x, r0y, r0z, l2;
            if (semi_infinite) {
                r0x = ends[3 * s], r0y = ends[3 * s + 1], r0z = ends[3 * s + 2], l2 = 1.0;
            } else {
                r0x = ends[3 * s] - ax, r0y = ends[3 * s + 1] - ay, r0z = ends[3 * s + 2] - az;
                l2 = r0x * r0x + r0y * r0y + r0z * r0z;
            }
            for (long i = 0; i < m; i++) {
                double cx, cy, cz, k;
                pair(px[i] - ax, py[i] - ay, pz[i] - az, r0x, r0y, r0z, l2, core2, semi_infinite, &cx, &cy, &cz, &k);
                k *= g;
                vx[i] += cx * k;
                vy[i] += cy * k;
                vz[i] += cz * k;
            }
        }
        for (long i = 0; i < m; i++) {
            out[3 * (lo + i)] = vx[i];
            out[3 * (lo + i) + 1] = vy[i];
            out[3 * (lo + i) + 2] = vz[i];
        }
    }
    return 0;
}

/* ---------------------------------------------------------------------------------------------------------------
 * Treecode (Barnes and Hut 1986) for the velocity of finite segments of known circulations (aero_fmu/treecode.py
 * builds the tree and is the numpy reference of this evaluation).
 *
 * nodes (K, NODE_FIELDS): center c (3) m, radius rho m (every point of every segment of the node lies within rho
 * of c), monopole A = sum_i alpha_i (3), dipole D (3 x 3, row-major) D_ab = sum_i alpha_ia (m_i - c)_b, strength
 * sum_i |alpha_i|, with alpha_i = Gamma_i (b_i - a_i) m^3/s and m_i the segment's midpoint. links (K, 4): first
 * segment, segment count, first child, child count (0: a leaf). seg (7, S): the segments sorted by node, in the
 * structure of arrays of `segments` above; gamma (S,) in the same order.
 *
 * For each point p, from the root: a node with rho < theta |p - c| is far and adds its monopole and dipole
 * terms, with r = p - c, d = |r|:
 *     v = [A x r - w + 3 (D r) x r / d^2] / (4 pi d^3),   w_a = eps_abc D_bc
 * (the Biot-Savart line integral's Taylor expansion about c to first order); its truncation and the core it
 * leaves out add to bound[p]  sum |alpha| [3 rho^2 / (d - rho)^4 + delta / (2 (d - rho)^3)] / (4 pi)
 * (treecode.py derives it). A near leaf adds its segments exactly (`pair`, the cored kernel); a near node that
 * is not a leaf opens its children.
 */
#define NODE_FIELDS 17
#define TREE_STACK 1024                  /* nodes waiting per point: at most 7 per level + 8, far above any depth */
#define LEAF_CHUNK 64                    /* pairs computed before they are summed: the loop vectorizes */

const long node_fields = NODE_FIELDS;    /* for treecode.py, which packs the nodes */

/* out (P, 3) m/s and bound (P,) m/s: the treecode velocity and its error bound (above). Returns 0, or -2 if a
 * point's traversal would overflow TREE_STACK (a tree deeper than treecode.py builds). */
VECTOR_CLONES
int tree_velocity(long n_points, const double *points, const double *nodes, const long *links, long S,
                  const double *seg, const double *gamma, double core, double theta, double *out, double *bound) {
    const double *ax = seg, *ay = seg + S, *az = seg + 2 * S, *r0x = seg + 3 * S, *r0y = seg + 4 * S,
                 *r0z = seg + 5 * S, *l2 = seg + 6 * S;
    const double core2 = core * core, theta2 = theta * theta;
    long stack[TREE_STACK];
    double tx[LEAF_CHUNK], ty[LEAF_CHUNK], tz[LEAF_CHUNK];
    for (long p = 0; p < n_points; p++) {
        const double px = points[3 * p], py = points[3 * p + 1], pz = points[3 * p + 2];
        double vx = 0.0, vy = 0.0, vz = 0.0, e = 0.0;
        long top = 0;
        stack[top++] = 0;
        while (top > 0) {
            const long k = stack[--top];
            const double *n = nodes + NODE_FIELDS * k;
            const long *link = links + 4 * k;
            const double rx = px - n[0], ry = py - n[1], rz = pz - n[2];
            const double d2 = rx * rx + ry * ry + rz * rz, rho = n[3];
            if (rho * rho < theta2 * d2) {
                const double *A = n + 4, *D = n + 7;
                const double d = sqrt(d2), scale = 1.0 / (FOUR_PI * d2 * d), g = d - rho;
                const double ux = D[0] * rx + D[1] * ry + D[2] * rz;        /* D r */
                const double uy = D[3] * rx + D[4] * ry + D[5] * rz;
                const double uz = D[6] * rx + D[7] * ry + D[8] * rz;
                const double three = 3.0 / d2;
                vx += ((A[1] * rz - A[2] * ry) - (D[5] - D[7]) + three * (uy * rz - uz * ry)) * scale;
                vy += ((A[2] * rx - A[0] * rz) - (D[6] - D[2]) + three * (uz * rx - ux * rz)) * scale;
                vz += ((A[0] * ry - A[1] * rx) - (D[1] - D[3]) + three * (ux * ry - uy * rx)) * scale;
                e += n[16] * (3.0 * rho * rho / (g * g * g * g) + core / (2.0 * g * g * g)) / FOUR_PI;
            } else if (link[3] == 0) {
                const long first = link[0], last = link[0] + link[1];
                for (long lo = first; lo < last; lo += LEAF_CHUNK) {
                    const long m = last - lo < LEAF_CHUNK ? last - lo : LEAF_CHUNK;
                    for (long i = 0; i < m; i++) {
                        const long s = lo + i;
                        double cx, cy, cz, kk;
                        pair(px - ax[s], py - ay[s], pz - az[s], r0x[s], r0y[s], r0z[s], l2[s], core2, 0,
                             &cx, &cy, &cz, &kk);
                        kk *= gamma[s];
                        tx[i] = cx * kk;
                        ty[i] = cy * kk;
                        tz[i] = cz * kk;
                    }
                    for (long i = 0; i < m; i++) {
                        vx += tx[i];
                        vy += ty[i];
                        vz += tz[i];
                    }
                }
            } else {
                if (top + link[3] > TREE_STACK) return -2;
                for (long c = link[2] + link[3] - 1; c >= link[2]; c--) stack[top++] = c;
            }
        }
        out[3 * p] = vx;
        out[3 * p + 1] = vy;
        out[3 * p + 2] = vz;
        bound[p] = e;
    }
    return 0;
}
