/* Compiled strain-based kinematics sweep (C): the recursion of strain_kinematics.body_sweep (Otsuka et al. 2022,
 * Eqs. 7-8) with its derivatives along the coordinates, element by element along one body, nothing allocated.
 * Compiled once per machine by fmu_common/c_library.py (and into every structure FMU by its build) and called
 * through ctypes by strain_kinematics.body_sweep, whose numpy form is the reference ($WINGSIM_KERNELS=numpy);
 * the tests check both agree to 1e-12 relative.
 *
 *   body_sweep  the nodal H (n_el + 1, 4, 3), dH/dq (n_el + 1, 4, 3, n_q) and dH/dt at fixed q (n_el + 1, 4, 3)
 *               of a body's nodes from its root node's (row 0 of each, read) and its elements' transfer matrices:
 *               H_{k+1} = Phi_k H_k, dH_{k+1}/dq = Phi_k dH_k/dq + sum_p e_{c_k + p} dPhi_k/dxi_p H_k,
 *               dH_{k+1}/dt = Phi_k dH_k/dt
 *   body_accelerations  d2H/dt2 (n_el + 1, 4, 3) of a body's nodes from its root node's (row 0, read), at given
 *               H and dH/dt (n_el + 1, 4, 3): d2H_{k+1}/dt2 = Phi''_k H_k + 2 Phi'_k dH_k/dt + Phi_k d2H_k/dt2, with
 *               Phi' and Phi'' (n_el, 4, 4) the transfers' first and second time derivatives
 *
 * Inputs, C-contiguous doubles: n_el elements, n_q coordinates; columns (n_el,) the column of each element's
 * first strain in q (increasing); Phi (n_el, 4, 4) and dPhi (n_el, 4, 4, 4) [p, i, j] (strain_kinematics.transfer);
 * H, dH, Ht as above, rows 1.. written. Row k + 1 of dH is written in its columns below columns[k] + 4 only: the
 * caller passes zeros beyond (a node depends on no later strain). Both return 0.
 *
 * Arithmetic: IEEE double, each operation rounded on its own (c_library's flags: -ffp-contract=off, no fused
 * multiply-add; no fast-math), the sums over j in the order 0..3.
 */

long body_sweep(long n_el, long n_q, const long *columns, const double *Phi, const double *dPhi, double *H,
                double *dH, double *Ht)
{
    for (long k = 0; k < n_el; ++k) {
        const double *P = Phi + 16 * k, *dP = dPhi + 64 * k;
        const double *Ha = H + 12 * k, *Hta = Ht + 12 * k, *dHa = dH + 12 * n_q * k;
        double *Hb = H + 12 * (k + 1), *Htb = Ht + 12 * (k + 1), *dHb = dH + 12 * n_q * (k + 1);
        long width = columns[k];
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
    return 0;
}

long body_accelerations(long n_el, const double *Phi, const double *Phi_d, const double *Phi_dd, const double *H,
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
    return 0;
}
