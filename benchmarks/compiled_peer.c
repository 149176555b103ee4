/* The paper's scheme on Example 1's string as a plain C loop: the compiled limit of docs/explanation/performance.md.
 *
 * The same equations as peers.paper_peer (finite differences = the lumped FEM, scaled by dt^2/dx):
 *     (I + r T) eta^{n+1} = 2 eta^n - eta^{n-1} + a T eta^n + dt^2 F(eta^n, v^n),
 *     F = (1/eps) chi{eta < 0} (-v)^+,  v^n = (eta^n - eta^{n-1}) / dt,
 * with T = tridiag(-1, 2, -1) on the interior nodes, r = (alpha dt + dt^2)/dx^2 and a = alpha dt/dx^2. The
 * constant tridiagonal matrix is factorised once (Thomas); a step is one sweep for the right-hand side and the
 * forward elimination, and one back-substitution. Rows of eta and v are copied out at the stored steps.
 *
 * With `energies` the loop also does what stringcontact's step does besides the solve: the terms of the
 * discrete energy identity (docs/explanation/performance.md, timestepping/paper.py) in the FEM's scaling, M = dx, K = T/dx
 * over every node (the ends included), C = alpha K, f = dx F, summed into the ledger
 *     E(t) = kinetic + elastic, D_visc, D_con, D_num,
 * and min eta as the driver keeps it. One extra sweep per step: K eta^{n+1} and the seven dot products fused.
 *
 * Built by benchmarks/peers.py (`build_compiled`) with the system's C compiler into a temporary folder.
 */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

static double penalty(double e, double v, double inv_eps)
{
    return (e < 0.0 && v < 0.0) ? -v * inv_eps : 0.0;
}

/* ledger (out, 6 doubles): kinetic, elastic, viscous, contact and numerical dissipation, min eta. eta and
 * eta_old (N + 1 nodes each): the first state, read only. */
int march(int N, int nt, double dt, double dx, double alpha, double eps, double h_left, double h_right,
          const double *eta, const double *eta_old, int n_stored, const int64_t *stored, double *rows_eta, double *rows_v,
          int energies, double *ledger)
{
    const int n = N + 1; /* nodes 0..N; the unknowns are 1..N-1 */
    const double r = (alpha * dt + dt * dt) / (dx * dx), a = alpha * dt / (dx * dx);
    const double dt2 = dt * dt, inv_eps = 1.0 / eps, inv_dt = 1.0 / dt, inv_dx = 1.0 / dx; /* multiplied: a division costs several */
    double *c = malloc(sizeof(double) * n), *inv_den = malloc(sizeof(double) * n), *d = malloc(sizeof(double) * n);
    double *K_now = malloc(sizeof(double) * n), *K_new = malloc(sizeof(double) * n);
    double *buffers[3] = {malloc(sizeof(double) * n), malloc(sizeof(double) * n), malloc(sizeof(double) * n)};
    if (!c || !inv_den || !d || !K_now || !K_new || !buffers[0] || !buffers[1] || !buffers[2]) {
        free(c), free(inv_den), free(d), free(K_now), free(K_new);
        free(buffers[0]), free(buffers[1]), free(buffers[2]);
        return 1;
    }
    double *now = buffers[0], *old = buffers[1], *new = buffers[2]; /* rotated, never copied */
    memcpy(now, eta, sizeof(double) * n);
    memcpy(old, eta_old, sizeof(double) * n);

    /* Thomas: the constant factor of (I + r T) */
    c[1] = -r / (1.0 + 2.0 * r);
    inv_den[1] = 1.0 / (1.0 + 2.0 * r);
    for (int i = 2; i < N; ++i) {
        inv_den[i] = 1.0 / (1.0 + 2.0 * r + r * c[i - 1]);
        c[i] = -r * inv_den[i];
    }

    double kin = 0.0, el = 0.0, visc = 0.0, con = 0.0, num = 0.0, min_eta = now[1];
    for (int i = 2; i < N; ++i) /* as the driver: the interior at t = 0, then every node */
        min_eta = now[i] < min_eta ? now[i] : min_eta;
    if (energies) {
        K_now[0] = (now[0] - now[1]) * inv_dx;
        K_now[N] = (now[N] - now[N - 1]) * inv_dx;
        el = 0.5 * (now[0] * K_now[0] + now[N] * K_now[N]);
        for (int i = 1; i < N; ++i) {
            double v = (now[i] - old[i]) * inv_dt;
            K_now[i] = (2.0 * now[i] - now[i - 1] - now[i + 1]) * inv_dx;
            kin += 0.5 * dx * v * v;
            el += 0.5 * now[i] * K_now[i];
        }
    }
    int row = 0;
    for (int step = 0; step <= nt; ++step) {
        if (row < n_stored && stored[row] == step) { /* the row of eta and v at this step */
            double *re = rows_eta + (size_t)row * n, *rv = rows_v + (size_t)row * n;
            memcpy(re, now, sizeof(double) * n);
            rv[0] = rv[N] = 0.0;
            for (int i = 1; i < N; ++i)
                rv[i] = (now[i] - old[i]) * inv_dt;
            ++row;
        }
        if (step == nt)
            break;
        /* right-hand side and forward elimination in one sweep */
        double prev = 0.0;
        for (int i = 1; i < N; ++i) {
            double e = now[i];
            double rhs = 2.0 * e - old[i] + a * (2.0 * e - now[i - 1] - now[i + 1])
                         + dt2 * penalty(e, (e - old[i]) * inv_dt, inv_eps);
            if (i == 1)
                rhs += r * h_left;
            if (i == N - 1)
                rhs += r * h_right;
            prev = d[i] = (rhs + r * prev) * inv_den[i];
        }
        new[0] = h_left;
        new[N] = h_right;
        new[N - 1] = d[N - 1];
        for (int i = N - 2; i >= 1; --i)
            new[i] = d[i] - c[i] * new[i + 1];

        if (energies) { /* the identity's terms, as stringcontact's step books them, and min eta */
            double vMv1 = 0.0, vMv0 = 0.0, vCv = 0.0, vf = 0.0, fv0 = 0.0;
            K_new[0] = (new[0] - new[1]) * inv_dx;
            K_new[N] = (new[N] - new[N - 1]) * inv_dx;
            double eKe1 = new[0] * K_new[0] + new[N] * K_new[N], eKe0 = new[0] * K_now[0] + new[N] * K_now[N];
            min_eta = new[0] < min_eta ? new[0] : min_eta;
            min_eta = new[N] < min_eta ? new[N] : min_eta;
            for (int i = 1; i < N; ++i) {
                double v1 = (new[i] - now[i]) * inv_dt, v0 = (now[i] - old[i]) * inv_dt;
                double f = dx * penalty(now[i], v0, inv_eps);
                K_new[i] = (2.0 * new[i] - new[i - 1] - new[i + 1]) * inv_dx;
                vMv1 += dx * v1 * v1;
                vMv0 += dx * v1 * v0;
                vCv += v1 * (K_new[i] - K_now[i]);
                vf += v1 * f;
                fv0 += f * v0;
                eKe1 += new[i] * K_new[i];
                eKe0 += new[i] * K_now[i];
                if (new[i] < min_eta)
                    min_eta = new[i];
            }
            double kin_new = 0.5 * vMv1, el_new = 0.5 * eKe1, work = -dt * vf;
            double split = 0.5 * (work - dt * fv0);
            num += kin_new + kin + el_new + el - (vMv0 + eKe0) - (split - work);
            visc += alpha * vCv; /* dt v.Cv with C v = alpha (K eta^{n+1} - K eta^n)/dt */
            con += split;
            kin = kin_new;
            el = el_new;
            double *swap = K_now;
            K_now = K_new;
            K_new = swap;
        }
        double *spare = old; /* eta^{n-1} <- eta^n <- eta^{n+1} */
        old = now;
        now = new;
        new = spare;
    }
    ledger[0] = kin;
    ledger[1] = el;
    ledger[2] = visc;
    ledger[3] = con;
    ledger[4] = num;
    ledger[5] = min_eta;
    free(c), free(inv_den), free(d), free(K_now), free(K_new);
    free(buffers[0]), free(buffers[1]), free(buffers[2]);
    return 0;
}
