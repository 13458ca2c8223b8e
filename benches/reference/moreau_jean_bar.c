/* The C-loop reference of the Moreau–Jean speed comparison (issue 18).
 *
 * The same step as `cargo bench -p signorini-core --bench moreau_jean`: the `bar` scene (N
 * linear elements, L = E = rho = A = 1, lumped mass, fixed left end, one contact at the right
 * end, gap 1e-3 + 1e-7, initial velocity 1 toward the obstacle, e = 0), Moreau–Jean theta = 1/2,
 * h = 1e-4 (Acary 2016, (21a)–(21d), doi:10.1002/zamm.201400231), the iteration matrix
 * W = M + theta^2 h^2 K factorised once as a tridiagonal L D L^T, one forward and one backward
 * recurrence per step, the index set (24), the one-contact LCP in closed form, and the energy
 * terms at every step (kinetic, strain, contact work, balance residual). Written the
 * straightforward way a C programmer would: one-sided L D L^T, one running sum per term.
 *
 *     cc -O2 -o /tmp/mj_ref benches/reference/moreau_jean_bar.c && /tmp/mj_ref [N ...]
 *
 * Prints one JSON line per N (default 100, 1000, 10000, 100000) with the thread's on-CPU time
 * (CLOCK_THREAD_CPUTIME_ID, best of 5), steps/s and ns per dof and step, like the Rust bench.
 * scripts/siconos/bench.py builds and runs it when `cc` is present.
 */
#define _POSIX_C_SOURCE 199309L
#include <stdio.h>
#include <stdlib.h>
#include <time.h>

static double cpu_now(void) {
    struct timespec ts;
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* Solves L D L^T x = b in place (l[i] = L[i][i-1], inv_d[i] = 1/D[i]). */
static void ldlt_solve(int n, const double *l, const double *inv_d, double *b) {
    for (int i = 1; i < n; i++) b[i] -= l[i] * b[i - 1];
    for (int i = 0; i < n; i++) b[i] *= inv_d[i];
    for (int i = n - 2; i >= 0; i--) b[i] -= l[i + 1] * b[i + 1];
}

/* Runs `steps` steps; returns the on-CPU seconds and writes the largest |balance residual|. */
static double run(int n, long steps, double *max_residual, double *tip) {
    const double h = 1e-4, theta = 0.5, gap = 1e-3 + 1e-7;
    const double he = 1.0 / n, k = 1.0 / he;
    double *m = malloc(n * sizeof *m), *l = malloc(n * sizeof *l);
    double *inv_d = malloc(n * sizeof *inv_d), *col = malloc(n * sizeof *col);
    double *q = malloc(n * sizeof *q), *v = malloc(n * sizeof *v);
    double *dv = malloc(n * sizeof *dv), *t = malloc(n * sizeof *t);
    /* Lumped mass (the tip node carries half an element), stiffness tridiag(-k, 2k, -k) with
     * the tip row k, -k. */
    for (int i = 0; i < n; i++) m[i] = i == n - 1 ? 0.5 * he : he;
    const double c = theta * theta * h * h;
    double d = m[0] + c * 2.0 * k;
    inv_d[0] = 1.0 / d;
    l[0] = 0.0;
    for (int i = 1; i < n; i++) {
        double a = m[i] + c * (i == n - 1 ? k : 2.0 * k), e = -c * k;
        l[i] = e / d;
        d = a - l[i] * e;
        inv_d[i] = 1.0 / d;
    }
    /* Delassus operator of the contact G = -e_{n-1}: col = W^-1 G, w = G^T col. */
    for (int i = 0; i < n; i++) col[i] = 0.0;
    col[n - 1] = -1.0;
    ldlt_solve(n, l, inv_d, col);
    const double w = -col[n - 1];
    for (int i = 0; i < n; i++) { q[i] = 0.0; v[i] = 1.0; }
    double kin = 0.0, strain = 0.0;
    for (int i = 0; i < n; i++) kin += 0.5 * m[i] * v[i] * v[i];
    double worst = 0.0;
    double t0 = cpu_now();
    for (long s = 0; s < steps; s++) {
        /* Free velocity: W dv = -h K (q + theta h v). */
        for (int i = 0; i < n; i++) t[i] = q[i] + theta * h * v[i];
        for (int i = 0; i < n; i++) {
            double kt = (i == n - 1 ? k : 2.0 * k) * t[i];
            if (i > 0) kt -= k * t[i - 1];
            if (i < n - 1) kt -= k * t[i + 1];
            dv[i] = -h * kt;
        }
        ldlt_solve(n, l, inv_d, dv);
        /* Index set (24) and the one-contact LCP: U = -(v + dv) at the tip. */
        double p = 0.0;
        if (gap - q[n - 1] - h * v[n - 1] <= 0.0 && -v[n - 1] <= 0.0) {
            double u_free = -(v[n - 1] + dv[n - 1]);
            if (u_free < 0.0) p = -u_free / w;
            if (p != 0.0)
                for (int i = 0; i < n; i++) dv[i] += p * col[i];
        }
        /* Update (21b), energies, contact work U_{k+theta} P. */
        double kin_new = 0.0, strain_new = 0.0, work_contact = -p * (v[n - 1] + theta * dv[n - 1]);
        for (int i = 0; i < n; i++) {
            double vt = v[i] + theta * dv[i];
            q[i] += h * vt;
            v[i] += dv[i];
            kin_new += 0.5 * m[i] * v[i] * v[i];
            double e = i > 0 ? q[i] - q[i - 1] : q[i];
            strain_new += 0.5 * k * e * e;
        }
        double r = (kin_new + strain_new) - (kin + strain) - work_contact;
        if (r < 0.0) r = -r;
        if (r > worst) worst = r;
        kin = kin_new;
        strain = strain_new;
    }
    double used = cpu_now() - t0;
    *max_residual = worst;
    *tip = q[n - 1];
    free(m); free(l); free(inv_d); free(col); free(q); free(v); free(dv); free(t);
    return used;
}

int main(int argc, char **argv) {
    int defaults[] = {100, 1000, 10000, 100000};
    int count = argc > 1 ? argc - 1 : 4;
    for (int a = 0; a < count; a++) {
        int n = argc > 1 ? atoi(argv[a + 1]) : defaults[a];
        if (n < 2) { fprintf(stderr, "N must be >= 2, got %s\n", argv[a + 1]); return 2; }
        long steps = (long)(2e7 / n);
        if (steps < 50) steps = 50;
        double best = 1e300, residual = 0.0, tip = 0.0;
        for (int r = 0; r < 5; r++) {
            double s = run(n, steps, &residual, &tip);
            if (s < best) best = s;
        }
        double sps = steps / best;
        printf("{\"bench\":\"c_reference_moreau_jean_bar\",\"elements\":%d,\"steps\":%ld,\"h\":0.0001,"
               "\"cpu_seconds\":%.4f,\"steps_per_s\":%.0f,\"ns_per_dof_step\":%.2f,"
               "\"max_abs_balance_residual\":%.3e,\"q_tip_final\":%.9e}\n",
               n, steps, best, sps, 1e9 / (sps * n), residual, tip);
        fflush(stdout);
    }
    return 0;
}
