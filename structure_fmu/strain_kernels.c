/* Compiled strain-based kinematics (C): the closed-form element transfers and the recursion along a body of
 * strain_kinematics (Otsuka et al. 2022, Eqs. 7-8) with its derivatives along the coordinates and in time, nothing
 * allocated. Compiled once per machine by fmu_common/c_library.py (and into every structure FMU by its build) and
 * called through ctypes by strain_kinematics.transfers and kinematics, whose numpy forms are the
 * reference ($WINGSIM_KERNELS=numpy); the tests check both agree to 1e-12 relative.
 *
 *   body_kinematics  one body's nodes in the model's arrays: its root node from what it hangs from (the parent's
 *               tip node `parent`, or `ground` (3, 4, 3): H, dH/dt, d2H/dt2 of a ground point or a driven root)
 *               by H_root = C(eta) H_parent, C = blockdiag(1, c) (Eq. 8), with c (3, 3), dc/deta (n_eta, 3, 3) at
 *               q's columns offset.., c' and c'' (3, 3) at zero parameter acceleration; then along its elements
 *               H_{k+1} = Phi_k H_k (Eq. 7), dH_{k+1}/dq = Phi_k dH_k/dq + sum_p e_{c_k + p} dPhi_k/dxi_p H_k,
 *               dH_{k+1}/dt = Phi_k dH_k/dt at fixed q; the rates dH/dt = dH/dq q' + dH/dt; the accelerations at
 *               q'' = 0, d2H_{k+1}/dt2 = Phi''_k H_k + 2 Phi'_k dH_k/dt + Phi_k d2H_k/dt2.
 *               Arrays of the whole model, C-contiguous doubles: H, Ht, Hd, Hdd (n_nodes, 4, 3), dH (n_nodes,
 *               4, 3, n_q); Phi, Phi', Phi'' (n_elements, 4, 4), dPhi (n_elements, 4, 4, 4) [p, i, j]; the body's
 *               nodes are first..first + n_el, its elements first_element..first_element + n_el - 1; columns
 *               (n_el,) the column of each element's first strain in q (increasing). A node's dH is written in
 *               its columns up to its last strain only: the caller passes zeros (a node depends on no later
 *               strain). Returns 0.
 *
 * Arithmetic: IEEE double, each operation rounded on its own (c_library's flags: -ffp-contract=off, no fused
 * multiply-add; no fast-math), the sums over j in the order 0..3.
 */

#include <stdint.h>    /* columns: int64 as numpy passes them, on every platform (a C long is 32 bits on Windows) */

static void sweep(long n_el, long n_q, const int64_t *columns, const double *Phi, const double *dPhi, double *H,
                  double *dH, double *Ht)
{
    for (long k = 0; k < n_el; ++k) {
        const double *P = Phi + 16 * k, *dP = dPhi + 64 * k;
        const double *Ha = H + 12 * k, *Hta = Ht + 12 * k, *dHa = dH + 12 * n_q * k;
        double *Hb = H + 12 * (k + 1), *Htb = Ht + 12 * (k + 1), *dHb = dH + 12 * n_q * (k + 1);
        long width = (long)columns[k];
        for (long i = 0; i < 4; ++i) {
            for (long c = 0; c < 3; ++c) {
                double h = 0.0, ht = 0.0;
                for (long j = 0; j < 4; ++j) {
                    h += P[4 * i + j] * Ha[3 * j + c];
                    ht += P[4 * i + j] * Hta[3 * j + c];
                }
                Hb[3 * i + c] = h;
                Htb[3 * i + c] = ht;
                double *out = dHb + (3 * i + c) * n_q;
                for (long q = 0; q < width; ++q) {
                    double s = 0.0;
                    for (long j = 0; j < 4; ++j)
                        s += P[4 * i + j] * dHa[(3 * j + c) * n_q + q];
                    out[q] = s;
                }
                for (long p = 0; p < 4; ++p) {
                    double s = 0.0;
                    for (long j = 0; j < 4; ++j)
                        s += dP[16 * p + 4 * i + j] * Ha[3 * j + c];
                    out[width + p] = s;
                }
            }
        }
    }
}

static void accelerations(long n_el, const double *Phi, const double *Phi_d, const double *Phi_dd, const double *H,
                          const double *Hd, double *Hdd)
{
    for (long k = 0; k < n_el; ++k) {
        const double *P = Phi + 16 * k, *Pd = Phi_d + 16 * k, *Pdd = Phi_dd + 16 * k;
        const double *Ha = H + 12 * k, *Hda = Hd + 12 * k, *Hdda = Hdd + 12 * k;
        double *Hddb = Hdd + 12 * (k + 1);
        for (long i = 0; i < 4; ++i) {
            for (long c = 0; c < 3; ++c) {
                double a = 0.0, b = 0.0, d = 0.0;
                for (long j = 0; j < 4; ++j) {
                    a += Pdd[4 * i + j] * Ha[3 * j + c];
                    b += Pd[4 * i + j] * Hda[3 * j + c];
                    d += P[4 * i + j] * Hdda[3 * j + c];
                }
                Hddb[3 * i + c] = a + 2.0 * b + d;
            }
        }
    }
}

long body_kinematics(long n_el, long n_q, long first, long first_element, long parent, const int64_t *columns,
                     const double *ground, const double *c, long n_eta, long offset, const double *dc,
                     const double *c_dot, const double *c_ddot, const double *Phi, const double *dPhi,
                     const double *Phi_d, const double *Phi_dd, const double *dq, double *H, double *dH, double *Ht,
                     double *Hd, double *Hdd)
{
    /* what the root hangs from: the parent's tip node, or the ground's H, dH/dt, d2H/dt2 (no q) */
    const double *Hp = parent >= 0 ? H + 12 * parent : ground;
    const double *dHp = parent >= 0 ? dH + 12 * n_q * parent : 0;
    const double *Htp = parent >= 0 ? Ht + 12 * parent : ground + 12;
    const double *Hpd = parent >= 0 ? Hd + 12 * parent : ground + 12;
    const double *Hpdd = parent >= 0 ? Hdd + 12 * parent : ground + 24;
    double *Hr = H + 12 * first, *dHr = dH + 12 * n_q * first, *Htr = Ht + 12 * first, *Hddr = Hdd + 12 * first;
    /* the root node: H_root = C(eta) H_parent, C = blockdiag(1, c) (Otsuka et al. 2022, Eq. 8), and its derivatives */
    for (long col = 0; col < 3; ++col) {
        Hr[col] = Hp[col];
        Htr[col] = Htp[col];
        Hddr[col] = Hpdd[col];
        if (dHp)
            for (long q = 0; q < n_q; ++q)
                dHr[col * n_q + q] = dHp[col * n_q + q];
    }
    for (long i = 0; i < 3; ++i)
        for (long col = 0; col < 3; ++col) {
            double h = 0.0, ht = 0.0, hdd = 0.0;
            for (long j = 0; j < 3; ++j) {
                const double p = Hp[3 * (1 + j) + col];
                h += c[3 * i + j] * p;
                ht += c[3 * i + j] * Htp[3 * (1 + j) + col];
                hdd += c_ddot[3 * i + j] * p + 2.0 * c_dot[3 * i + j] * Hpd[3 * (1 + j) + col]
                       + c[3 * i + j] * Hpdd[3 * (1 + j) + col];
            }
            Hr[3 * (1 + i) + col] = h;
            Htr[3 * (1 + i) + col] = ht;
            Hddr[3 * (1 + i) + col] = hdd;
            double *out = dHr + (3 * (1 + i) + col) * n_q;
            if (dHp)
                for (long q = 0; q < n_q; ++q) {
                    double s = 0.0;
                    for (long j = 0; j < 3; ++j)
                        s += c[3 * i + j] * dHp[(3 * (1 + j) + col) * n_q + q];
                    out[q] = s;
                }
            for (long k = 0; k < n_eta; ++k) {
                double s = 0.0;
                for (long j = 0; j < 3; ++j)
                    s += dc[9 * k + 3 * i + j] * Hp[3 * (1 + j) + col];
                out[offset + k] += s;
            }
        }
    /* along the body: H, dH/dq, dH/dt (Eq. 7), then dH/dt at q' and d2H/dt2 at q'' = 0 */
    sweep(n_el, n_q, columns, Phi + 16 * first_element, dPhi + 64 * first_element, Hr, dHr, Htr);
    for (long node = 0; node <= n_el; ++node)
        for (long r = 0; r < 12; ++r) {
            const double *row = dHr + (12 * node + r) * n_q;
            double s = 0.0;
            for (long q = 0; q < n_q; ++q)
                s += row[q] * dq[q];
            Hd[12 * (first + node) + r] = s + Htr[12 * node + r];
        }
    accelerations(n_el, Phi + 16 * first_element, Phi_d + 16 * first_element, Phi_dd + 16 * first_element, Hr,
                  Hd + 12 * first, Hddr);
    return 0;
}

/* element_transfers  the closed-form transfer matrices of constant-strain elements (strain_kinematics, module
 *               docstring; Otsuka et al. 2022, Eq. 7): Phi (n_el, 4, 4) and dPhi (n_el, 4, 4, 4) [p, i, j] =
 *               d Phi / d xi_p; with rates (n_el, 4) given (not NULL) also Phi' = sum_p rate_p dPhi_p and
 *               Phi'' (n_el, 4, 4), the second time derivative at zero strain acceleration. Inputs: series
 *               (9, terms) the power-series coefficients of f_k, f_k', f_k'' (k = 1, 2, 3) in s = theta^2
 *               (strain_kinematics._SERIES), strains (n_el, 4), lengths (n_el,). Every element must turn by at
 *               most THETA_MAX (the caller sends the others to the block exponential). Returns 0.
 */

static void skew3(const double v[3], double out[9])
{
    out[0] = 0.0;   out[1] = -v[2]; out[2] = v[1];
    out[3] = v[2];  out[4] = 0.0;   out[5] = -v[0];
    out[6] = -v[1]; out[7] = v[0];  out[8] = 0.0;
}

static void product3(const double a[9], const double b[9], double out[9])
{
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) {
            double s = 0.0;
            for (int k = 0; k < 3; ++k)
                s += a[3 * i + k] * b[3 * k + j];
            out[3 * i + j] = s;
        }
}

long element_transfers(long n_el, const double *series, long terms, const double *strains, const double *rates,
                       const double *lengths, double *Phi, double *dPhi, double *Phi_d, double *Phi_dd)
{
    for (long e = 0; e < n_el; ++e) {
        const double *xi = strains + 4 * e;
        const double ds = lengths[e];
        double w[3] = {-ds * xi[1], -ds * xi[2], -ds * xi[3]};
        const double s = w[0] * w[0] + w[1] * w[1] + w[2] * w[2];
        double f[9] = {0.0};                      /* [k][j]: the j-th derivative in s of f_{k+1} */
        double power = 1.0;
        for (long n = 0; n < terms; ++n) {
            for (int r = 0; r < 9; ++r)
                f[r] += power * series[r * terms + n];
            power *= s;
        }
        const double a = f[0], da = f[1], d2a = f[2], b = f[3], db = f[4], d2b = f[5], c = f[6], dc = f[7],
                     d2c = f[8];
        double Om[9], Om2[9];
        skew3(w, Om);
        product3(Om, Om, Om2);
        const double stretch = ds * (1.0 + xi[0]);
        double *P_ = Phi + 16 * e, *dP_ = dPhi + 64 * e;
        for (int i = 0; i < 16; ++i)
            P_[i] = 0.0;
        for (int i = 0; i < 64; ++i)
            dP_[i] = 0.0;
        P_[0] = 1.0;
        for (int j = 0; j < 3; ++j) {
            const double eye = j == 0 ? 1.0 : 0.0;
            P_[1 + j] = stretch * (eye + b * Om[j] + c * Om2[j]);               /* ds (1 + eps_x) e_1^T P */
            dP_[1 + j] = ds * (eye + b * Om[j] + c * Om2[j]);                   /* d/d eps_x */
            for (int i = 0; i < 3; ++i)
                P_[4 * (1 + i) + 1 + j] = (i == j ? 1.0 : 0.0) + a * Om[3 * i + j] + b * Om2[3 * i + j];   /* R */
        }
        for (int p = 1; p < 4; ++p) {       /* along kappa: u = dw/dkappa = -ds e_p, sigma = ds(s)/dkappa = 2 w . u */
            double u[3] = {0.0, 0.0, 0.0}, U[9], UOm[9], OmU[9];
            u[p - 1] = -ds;
            skew3(u, U);
            product3(U, Om, UOm);
            product3(Om, U, OmU);
            const double sigma = -2.0 * ds * w[p - 1];
            double *D = dP_ + 16 * p;
            for (int i = 0; i < 3; ++i)
                for (int j = 0; j < 3; ++j) {
                    const int m = 3 * i + j;
                    const double sym = UOm[m] + OmU[m];
                    D[4 * (1 + i) + 1 + j] = da * sigma * Om[m] + a * U[m] + db * sigma * Om2[m] + b * sym;
                    if (i == 0)
                        D[1 + j] = stretch * (db * sigma * Om[m] + b * U[m] + dc * sigma * Om2[m] + c * sym);
                }
        }
        if (!rates)
            continue;
        const double *v = rates + 4 * e;
        double *Pd = Phi_d + 16 * e, *Pdd = Phi_dd + 16 * e;
        for (int i = 0; i < 16; ++i) {
            Pd[i] = v[0] * dP_[i] + v[1] * dP_[16 + i] + v[2] * dP_[32 + i] + v[3] * dP_[48 + i];
            Pdd[i] = 0.0;
        }
        double u[3] = {-ds * v[1], -ds * v[2], -ds * v[3]}, U[9], UOm[9], OmU[9], UU[9];
        skew3(u, U);
        product3(U, Om, UOm);
        product3(Om, U, OmU);
        product3(U, U, UU);
        const double sigma = 2.0 * (w[0] * u[0] + w[1] * u[1] + w[2] * u[2]);
        const double tau = 2.0 * (u[0] * u[0] + u[1] * u[1] + u[2] * u[2]);
        for (int i = 0; i < 3; ++i)
            for (int j = 0; j < 3; ++j) {
                const int m = 3 * i + j;
                const double sym = UOm[m] + OmU[m];
                Pdd[4 * (1 + i) + 1 + j] = (d2a * sigma * sigma + da * tau) * Om[m] + 2.0 * da * sigma * U[m]
                    + (d2b * sigma * sigma + db * tau) * Om2[m] + 2.0 * db * sigma * sym + 2.0 * b * UU[m];
                if (i == 0) {
                    const double dP1 = db * sigma * Om[m] + b * U[m] + dc * sigma * Om2[m] + c * sym;
                    const double d2P = (d2b * sigma * sigma + db * tau) * Om[m] + 2.0 * db * sigma * U[m]
                        + (d2c * sigma * sigma + dc * tau) * Om2[m] + 2.0 * dc * sigma * sym + 2.0 * c * UU[m];
                    Pdd[1 + j] = ds * (2.0 * v[0] * dP1 + (1.0 + xi[0]) * d2P);
                }
            }
    }
    return 0;
}
