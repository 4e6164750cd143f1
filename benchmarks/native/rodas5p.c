/* Rodas5P on the slip law with mass, in plain C: the twin of the project's numba kernel
 * (integrators/own/rodas5p.py + integrators/own/engine.py `run` for one loading segment).
 *
 * Same operations as the numba code, in the same order, so that (built with
 * -ffp-contract=off: no FMA, as numba without fastmath) it takes the same steps to the bit:
 *   problems/formulations.py   ode_rhs, ode_jacobian (slip law, with mass), peak_function
 *   integrators/own/linalg.py  factor, lu3 (partial pivoting, reciprocal diagonal), lu_solve3
 *   integrators/own/rodas5p.py _attempt (A5P, C5P, G5P, H5P)
 *   integrators/own/engine.py  _initial_step, _step, rodas_reject/rodas_accept (q = 5),
 *                              _crossed, _scan (bisection on the dense output), _save_until,
 *                              the clock every CLOCK_EVERY accepted steps
 *   integrators/core/events.py compiled_roots, sign_change, carry_signs, observe, record
 * Not ported: the arrest (an underflow stops the run), load switches/two-speed loading
 * (one segment of constant loading E = q[4] from 0 to tau_end), the step budget.
 *
 * Input: a text file (the first line a comment) with
 *   q[8] z0[3] tau_end rtol atol ln(10 E_slow) ln(E_slow) ln(E) h(0)
 * Usage: rodas5p INPUT [REPEATS]   prints the counters, the final state and the min time.
 * Build: gcc -O3 -ffp-contract=off rodas5p.c -lm (benchmarks/devtools/c_twin.py does, and
 * writes the input). Diagnostic builds: -DNO_SCAN (no event location), -DSELECT (the bisection
 * branch-free, as LLVM compiled the engine's before it was written as runs of one-sided steps),
 * -DCOUNT (scans, passes and bisection steps).
 */
#define _POSIX_C_SOURCE 200809L
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <stdint.h>

enum { Q_LAW, Q_BETA, Q_C, Q_D, Q_E, Q_G, Q_QS, Q_LAWP, N_Q };
enum { START, END, H_EXTREMUM, PEAK };
static const int DIRS[4] = {1, -1, 0, -1};
#define AT_ROOT 1e-300
#define MAX_PASSES 64
#define CLOCK_EVERY 256
#define FLOOR_STEPS 100
#define STICK_PEAKS 1

typedef struct {
    double beta, c, d, e, g;                 /* the problem (slip law, with mass) */
    double rtol, atol, ln10es, lnes, lne, tau_end, h0;
    double z0[3];
} Prob;

/* ---- Rodas5P tableau (rodas5p.py) ---- */
static const double G5P = 0.21193756319429014;
static const double A5P[8][8] = {
    {0},
    {3.0},
    {2.849394379747939, 0.45842242204463923},
    {-6.954028509809101, 2.489845061869568, -10.358996098473584},
    {2.8029986275628964, 0.5072464736228206, -0.3988312541770524, -0.04721187230404641},
    {-7.502846399306121, 2.561846144803919, -11.627539656261098, -0.18268767659942256,
     0.030198172008377946},
    {-7.502846399306121, 2.561846144803919, -11.627539656261098, -0.18268767659942256,
     0.030198172008377946, 1.0},
    {-7.502846399306121, 2.561846144803919, -11.627539656261098, -0.18268767659942256,
     0.030198172008377946, 1.0, 1.0}};
static const double C5P[8][8] = {
    {0},
    {-14.155112264123755},
    {-17.97296035885952, -2.859693295451294},
    {147.12150275711716, -1.41221402718213, 71.68940251302358},
    {165.43517024871676, -0.4592823456491126, 42.90938336958603, -5.961986721573306},
    {24.854864614690072, -3.0009227002832186, 47.4931110020768, 5.5814197821558125,
     -0.6610691825249471},
    {30.91273214028599, -3.1208243349937974, 77.79954646070892, 34.28646028294783,
     -19.097331116725623, -28.087943162872662},
    {37.80277123390563, -3.2571969029072276, 112.26918849496327, 66.9347231244047,
     -40.06618937091002, -54.66780262877968, -9.48861652309627}};
static const double H5P[3][8] = {
    {25.948786856663858, -2.5579724845846235, 10.433815404888879, -2.3679251022685204,
     0.524948541321073, 1.1241088310450404, 0.4272876194431874, -0.17202221070155493},
    {-9.91568850695171, -0.9689944594115154, 3.0438037242978453, -24.495224566215796,
     20.176138334709044, 15.98066361424651, -6.789040303419874, -6.710236069923372},
    {11.419903575922262, 2.8879645146136994, 72.92137995996029, 80.12511834622643,
     -52.072871366152654, -59.78993625266729, -0.15582684282751913, 4.883087185713722}};

static inline double pymax(double a, double b) { return b > a ? b : a; }
static inline double pymin(double a, double b) { return b < a ? b : a; }

/* ---- the ODE form (formulations.py, slip law with mass) ---- */
static inline void rhs(const Prob *P, const double *z, double *out)
{
    double h = z[0], u = z[1], s = z[2];
    double w = exp(u);
    double ds = -w * (u + s);
    out[0] = P->e - w;
    out[1] = (P->c * h - P->d * (u + P->beta * s)) / w - P->g;
    out[2] = ds;
}

static inline void jacobian(const Prob *P, const double *z, double J[3][3])
{
    double h = z[0], u = z[1], s = z[2], beta = P->beta, c = P->c, d = P->d;
    double w = exp(u);
    double dfs_du = -w * (u + s) - w, dfs_ds = -w;
    J[0][0] = 0.0; J[0][1] = -w; J[0][2] = 0.0;
    double inv_w = 1.0 / w;
    double fu = (c * h - d * (u + beta * s)) * inv_w;
    J[1][0] = c * inv_w; J[1][1] = -d * inv_w - fu; J[1][2] = -d * beta * inv_w;
    J[2][0] = 0.0; J[2][1] = dfs_du; J[2][2] = dfs_ds;
}

static inline void roots(const Prob *P, const double *z, double *g)
{
    g[0] = z[1] - P->ln10es; g[1] = z[1] - P->lnes; g[2] = z[1] - P->lne;
    double v = P->c * z[0] - P->d * (z[1] + P->beta * z[2]);
    if (P->g != 0.0) v -= P->g * exp(z[1]);
    g[3] = v;
}

/* ---- linalg.py ---- */
static inline int factor(double hg, const double J[3][3], double M[3][3], int piv[3])
{
    for (int i = 0; i < 3; i++) {
        for (int j = 0; j < 3; j++) M[i][j] = -hg * J[i][j];
        M[i][i] += 1.0;
    }
    int regular = 1;
    for (int k = 0; k < 3; k++) {
        int p = k;
        for (int i = k + 1; i < 3; i++)
            if (fabs(M[i][k]) > fabs(M[p][k])) p = i;
        piv[k] = p;
        regular &= M[p][k] != 0.0;
        if (p != k)
            for (int j = 0; j < 3; j++) { double t = M[k][j]; M[k][j] = M[p][j]; M[p][j] = t; }
        double inv = 1.0 / M[k][k];
        M[k][k] = inv;
        for (int i = k + 1; i < 3; i++) {
            M[i][k] *= inv;
            for (int j = k + 1; j < 3; j++) M[i][j] -= M[i][k] * M[k][j];
        }
    }
    return regular;
}

static inline void lu_solve3(const double a[3][3], const int piv[3], double *b)
{
    for (int k = 0; k < 3; k++) {
        int p = piv[k];
        if (p != k) { double t = b[k]; b[k] = b[p]; b[p] = t; }
    }
    b[1] -= a[1][0] * b[0];
    b[2] -= a[2][0] * b[0] + a[2][1] * b[1];
    b[2] *= a[2][2];
    b[1] = (b[1] - a[1][2] * b[2]) * a[1][1];
    b[0] = (b[0] - a[0][1] * b[1] - a[0][2] * b[2]) * a[0][0];
}

/* ---- rodas5p.py _attempt ---- */
static double attempt(const Prob *P, double hs, const double J[3][3], const double *z0,
                      const double *f0, double *z1, double D[3][3])
{
    double M[3][3], K[8][3], u[3], fb[3];
    int piv[3];
    double hg = hs * G5P;
    int regular = factor(hg, J, M, piv);
    for (int s = 0; s < 8; s++) {
        for (int i = 0; i < 3; i++) {
            double acc = z0[i];
            for (int j = 0; j < s; j++) acc += A5P[s][j] * K[j][i];
            u[i] = acc;
        }
        if (s == 0) { fb[0] = f0[0]; fb[1] = f0[1]; fb[2] = f0[2]; }
        else rhs(P, u, fb);
        for (int i = 0; i < 3; i++) {
            double acc = 0.0;
            for (int j = 0; j < s; j++) acc += C5P[s][j] * K[j][i];
            K[s][i] = hg * fb[i] + G5P * acc;
        }
        lu_solve3(M, piv, K[s]);
    }
    double errmax = 0.0;
    for (int i = 0; i < 3; i++) {
        z1[i] = u[i] + K[7][i];
        double r = fabs(K[7][i]) / (P->atol + P->rtol * pymax(fabs(z0[i]), fabs(z1[i])));
        if (!(r <= errmax)) errmax = r;
    }
    if (errmax <= 1.0)
        for (int i = 0; i < 3; i++)
            for (int r = 0; r < 3; r++) {
                double acc = 0.0;
                for (int s = 0; s < 8; s++) acc += H5P[r][s] * K[s][i];
                D[r][i] = acc;
            }
    return regular && isfinite(errmax) ? errmax : INFINITY;
}

/* ---- engine.py: controllers (RODAS, q = 5) ---- */
static const double SAFETY = 0.9, FAC_MIN = 1.0 / 6.0, FAC_MAX = 5.0, QCTRL = 5.0;

static inline double rodas_reject(double errmax, double hs)
{
    if (errmax == INFINITY) return hs * 0.1;
    return hs * (1.0 / pymin(1.0 / FAC_MIN, pymax(1.0 / FAC_MAX, pow(errmax, 1.0 / QCTRL) / SAFETY)));
}

typedef struct { double hacc, erracc, nacc, reject; } Ctrl;

static inline double rodas_accept(Ctrl *C, double errmax, double hs)
{
    double q = QCTRL;
    double fac = pymin(1.0 / FAC_MIN, pymax(1.0 / FAC_MAX, pow(errmax, 1.0 / q) / SAFETY));
    if (C->nacc >= 1) {
        double gus = C->hacc / hs * pow(errmax * errmax / C->erracc, 1.0 / q) / SAFETY;
        fac = pymax(fac, pymin(1.0 / FAC_MIN, pymax(1.0 / FAC_MAX, gus)));
    }
    C->hacc = hs; C->erracc = pymax(1e-2, errmax); C->nacc += 1;
    double h_next = hs / fac;
    if (C->reject != 0.0) h_next = pymin(h_next, hs);
    return h_next;
}

/* ---- engine.py: _initial_step ---- */
static double max_abs_ratio(const double *a, const double *b)
{
    double m = fabs(a[0]) / b[0];
    for (int i = 1; i < 3; i++) {
        double r = fabs(a[i]) / b[i];
        if (r > m || r != r) m = r;
        if (m != m) break;
    }
    return m;
}

static double initial_step(const Prob *P, const double *z, const double *f, double t_left)
{
    double trial[3], f1[3], scale[3];
    for (int i = 0; i < 3; i++) scale[i] = P->atol + P->rtol * fabs(z[i]);
    double d0 = max_abs_ratio(z, scale), d1 = max_abs_ratio(f, scale);
    double small = !(d1 < d0) ? d0 : d1;
    double h0 = small >= 1e-5 ? 0.01 * d0 / d1 : 1e-6;
    for (int i = 0; i < 3; i++) trial[i] = z[i] + h0 * f[i];
    rhs(P, trial, f1);
    for (int i = 0; i < 3; i++) f1[i] = f1[i] - f[i];
    double big = max_abs_ratio(f1, scale) / h0;
    big = big > d1 ? big : d1;
    double h1;
    if (big > 1e-15) h1 = pow(0.01 / big, 1.0 / 5);
    else h1 = 1e-3 * h0 > 1e-6 ? 1e-3 * h0 : 1e-6;
    double h = 100.0 * h0;
    double second = h1 > 0.0 ? h1 : 1e-3 * h0;
    if (second < h) h = second;
    if (t_left < h) h = t_left;
    return h;
}

/* ---- events.py ---- */
static inline int sign_change(double a, double b)
{
    if (a < 0.0 && (b > 0.0 || (b == 0.0 && a < -AT_ROOT))) return 1;
    if (a > 0.0 && (b < 0.0 || (b == 0.0 && a > AT_ROOT))) return -1;
    return 0;
}

static inline void carry_signs(const double *old, double *nw)
{
    for (int k = 0; k < 4; k++)
        if (nw[k] == 0.0 && old[k] != 0.0) nw[k] = old[k] > 0.0 ? AT_ROOT : -AT_ROOT;
}

typedef struct { double in_event, h_max, ev_start, ev_slip, h_min, w_peak, tau_peak, n, h0; } Rec;

static inline void observe(Rec *r, double h)
{
    if (r->in_event != 0.0) { if (h < r->h_min) r->h_min = h; }
    else if (h > r->h_max) r->h_max = h;
}

static int record(Rec *r, double ev[][8], int kind, double tau, double h, double u, double load)
{
    double slip = load - (h - r->h0);
    if (kind == START && r->in_event == 0.0) {
        r->in_event = 1.0; r->ev_start = tau; r->ev_slip = slip;
        r->h_min = h; r->w_peak = exp(u); r->tau_peak = tau;
    } else if (kind == PEAK && r->in_event != 0.0) {
        if (exp(u) > r->w_peak) { r->w_peak = exp(u); r->tau_peak = tau; }
    } else if (kind == H_EXTREMUM) {
        observe(r, h);
    } else if (kind == END && r->in_event != 0.0) {
        if (h < r->h_min) r->h_min = h;
        int n = (int)r->n;
        double row[8] = {r->ev_start, tau, r->h_max, r->h_min, r->w_peak, r->tau_peak, r->ev_slip, slip};
        memcpy(ev[n], row, sizeof row);
        r->n = n + 1; r->in_event = 0.0; r->h_max = h;
        return 1;
    }
    return 0;
}

/* ---- the run ---- */
typedef struct {
    double tau, tau_old, cursor, t_ret;
    double z[3], f[3], zo[3], fo[3], D[3][3], zr[3];
    double G[3][4];
} Run;

typedef struct { long steps, rejected, nfev, njev, roots[4], crossing_steps; } Counters;

static inline void dense(const Run *R, double x, double *out)
{
    double y = 1.0 - x;
    for (int i = 0; i < 3; i++)
        out[i] = y * R->zo[i] + x * (R->z[i] + y * (R->D[0][i] + x * (R->D[1][i] + x * R->D[2][i])));
}

static inline int crossed(const double G0[4], const double g[4])
{
    for (int k = 0; k < 4; k++) {
        int sign = sign_change(G0[k], g[k]);
        if (sign != 0 && (DIRS[k] == 0 || DIRS[k] == sign)
            && (STICK_PEAKS || k != PEAK || G0[END] > 0.0 || g[END] > 0.0))
            return 1;
    }
    return 0;
}

static double cursor_time(double t0, double dt, double x, double lo, double hi)
{
    double t = pymin(pymax(t0 + x * dt, lo), hi);
    while (t < hi && (t - t0) / dt < x) t = nextafter(t, INFINITY);
    return t;
}

#ifdef COUNT
static long n_bisect, n_scan, n_pass;
#endif
static int scan(const Prob *P, Run *R, double t_end)
{
#ifdef COUNT
    n_scan++;
#endif
    double t0 = R->tau_old, dt = R->tau - R->tau_old;
    double x_end = (t_end - t0) / dt;
    double zt[3], z_end[3], g_end[4], g_new[4], gt[4], x_root[4];
    if (t_end < R->tau) dense(R, x_end, z_end);
    else memcpy(z_end, R->z, sizeof z_end);
    roots(P, z_end, g_end);
    int passes = 0;
    for (;;) {
        double x_cur = (R->cursor - t0) / dt;
#ifdef COUNT
        n_pass++;
#endif
        dense(R, x_cur, zt);
        roots(P, zt, g_new);
        for (int k = 0; k < 4; k++) {
            double g0 = R->G[0][k], g1 = g_end[k], ga = g_new[k], lo = x_cur, hi = x_end;
            if (sign_change(g0, g1) == 0) hi = INFINITY;
            else if (ga == 0.0 || (ga > 0.0 && g1 > 0.0) || (ga < 0.0 && g1 < 0.0)) hi = x_cur;
            while (lo < hi && hi < INFINITY) {
                double mid = 0.5 * (lo + hi);
                if (mid <= lo || mid >= hi) break;
#ifdef COUNT
                n_bisect++;
#endif
                dense(R, mid, zt);
                roots(P, zt, gt);
#ifdef SELECT
                /* branch-free update (what LLVM makes of the numba code): the next midpoint
                   waits for this evaluation */
                {
                    uint64_t c = -(uint64_t)(gt[k] != 0.0 && (gt[k] > 0.0) == (ga > 0.0));
                    uint64_t bl, bh, bm;
                    memcpy(&bl, &lo, 8); memcpy(&bh, &hi, 8); memcpy(&bm, &mid, 8);
                    bl = (bl & ~c) | (bm & c); bh = (bh & c) | (bm & ~c);
                    memcpy(&lo, &bl, 8); memcpy(&hi, &bh, 8);
                }
#else
                if (gt[k] != 0.0 && (gt[k] > 0.0) == (ga > 0.0)) lo = mid;
                else hi = mid;
#endif
            }
            x_root[k] = hi;
        }
        double best = x_root[0];
        for (int k = 1; k < 4; k++)
            if (x_root[k] < best || x_root[k] != x_root[k]) best = x_root[k];
        if (best == INFINITY || passes > MAX_PASSES) {
            carry_signs(R->G[0], g_end);
            R->cursor = R->t_ret = t_end;
            memcpy(R->zr, z_end, sizeof z_end);
            memcpy(R->G[0], g_end, sizeof g_end);
            return 0;
        }
        passes++;
        double t_root = best == x_cur ? R->cursor : best == x_end ? t_end
                        : cursor_time(t0, dt, best, R->cursor, t_end);
        if (best == x_end) memcpy(R->zr, z_end, sizeof z_end);
        else dense(R, best, R->zr);
        roots(P, R->zr, g_new);
        for (int k = 0; k < 4; k++) R->G[1][k] = 0.0;
        for (int k = 0; k < 4; k++)
            if (x_root[k] == best) {
                double sign = g_end[k] > R->G[0][k] ? 1.0 : -1.0;
                g_new[k] = sign * pymax(fabs(g_new[k]), AT_ROOT);
                if ((DIRS[k] == 0 || DIRS[k] == sign) && (STICK_PEAKS || k != PEAK || g_new[END] > 0.0))
                    R->G[1][k] = sign;
            }
        carry_signs(R->G[0], g_new);
        R->cursor = t_root;
        memcpy(R->G[0], g_new, sizeof g_new);
        if (R->G[1][0] != 0.0 || R->G[1][1] != 0.0 || R->G[1][2] != 0.0 || R->G[1][3] != 0.0) {
            R->t_ret = t_root;
            return 1;
        }
    }
}

static double monotonic(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + (double)ts.tv_nsec * 1e-9;
}

static int finite3(const double *a) { return isfinite(a[0]) && isfinite(a[1]) && isfinite(a[2]); }

enum { DONE = 0, NONFINITE = 3, UNDERFLOW = 4, WALL_TIME = 6 };

/* The whole solve: one segment [0, tau_end] at E = P->e; save grid {0, tau_end}. */
static int solve(const Prob *P, double deadline, Run *R, Counters *N, Rec *rec, double ev[][8],
                 double saved_end[3])
{
    memset(R, 0, sizeof *R);
    memset(N, 0, sizeof *N);
    *rec = (Rec){0.0, P->h0, NAN, NAN, NAN, NAN, NAN, 0.0, P->h0};
    const double tau_end = P->tau_end, t_bound = tau_end, tiny = 1e-12 * tau_end;
    Ctrl C = {0.0, 0.0, 0.0, 0.0};
    double J[3][3], z0[3], f0[3], z1[3], f1[3], D[3][3], g[4];
    int saved = 0;                                /* the save point tau_end filled */
    /* start (engine.start) */
    memcpy(R->z, P->z0, sizeof R->z);
    rhs(P, R->z, R->f);
    double h = initial_step(P, R->z, R->f, t_bound - 0.0);
    R->tau = R->tau_old = R->cursor = 0.0;
    N->nfev += 2;
    roots(P, R->z, R->G[0]);
    if (!finite3(R->f)) return NONFINITE;
    long n = 0, floor_steps = 0;
    for (;;) {
        if (R->cursor < R->tau) {
#ifdef NO_SCAN
            /* no location: the signs at the step's end (carry_signs as the scan's end) */
            double g_end[4];
            roots(P, R->z, g_end);
            carry_signs(R->G[0], g_end);
            memcpy(R->G[0], g_end, sizeof g_end);
            R->cursor = R->tau;
            int found = 0;
            R->t_ret = R->tau;
#else
            int found = scan(P, R, R->tau);
#endif
            double t_ret = R->t_ret;
            /* _save_until(t_ret, not found): the one save point left is tau_end */
            if (!saved && (tau_end < t_ret || (!found && tau_end == t_ret))) {
                if (tau_end == R->tau) memcpy(saved_end, R->z, 3 * sizeof(double));
                else dense(R, (tau_end - R->tau_old) / (R->tau - R->tau_old), saved_end);
                observe(rec, saved_end[0]);
                saved = 1;
            }
            if (found) {
                double load = 0.0 + P->e * (t_ret - 0.0);
                int ended = 0;
                for (int k = 0; k < 4; k++)
                    if (R->G[1][k] != 0.0) {
                        N->roots[k]++;
                        ended = record(rec, ev, k, t_ret, R->zr[0], R->zr[1], load) || ended;
                    }
                observe(rec, R->zr[0]);
                memcpy(R->G[2], R->G[1], sizeof R->G[1]);
                continue;
            }
        }
        if (R->cursor >= t_bound) {               /* the end: observe, done */
            observe(rec, R->z[0]);
            if (!saved) { memcpy(saved_end, R->z, 3 * sizeof(double)); saved = 1; }
            return DONE;
        }
        if (n % CLOCK_EVERY == CLOCK_EVERY - 1 && monotonic() > deadline) return WALL_TIME;
        if (floor_steps >= FLOOR_STEPS) return UNDERFLOW;
        /* _step */
        double tau = R->tau, hprop = h;
        memcpy(z0, R->z, sizeof z0);
        memcpy(f0, R->f, sizeof f0);
        jacobian(P, z0, J);
        N->njev++;
        int last = tau + hprop >= t_bound;
        double hs = last ? t_bound - tau : hprop;
        if (tau + hs == tau) hs = nextafter(tau, INFINITY) - tau;
        long attempts = 0;
        double errmax;
        for (;;) {
            if (tau + hs == tau) return UNDERFLOW;      /* (no arrest in this twin) */
            attempts++;
            errmax = attempt(P, hs, J, z0, f0, z1, D);
            N->nfev += 7;
            if (errmax <= 1.0) {
                rhs(P, z1, f1);
                N->nfev++;
                if (finite3(z1) && finite3(f1)) break;
                errmax = INFINITY;
            }
            last = 0;
            C.reject = 1.0;
            hs = rodas_reject(errmax, hs);
        }
        double h_next = rodas_accept(&C, errmax, hs);
        C.reject = 0.0;
        if (last) h_next = pymax(h_next, hprop);
        double tau_new = last ? t_bound : tau + hs;
        memcpy(R->zo, z0, sizeof z0); memcpy(R->fo, f0, sizeof f0);
        memcpy(R->z, z1, sizeof z1); memcpy(R->f, f1, sizeof f1);
        memcpy(R->D, D, sizeof D);
        N->rejected += attempts - 1;
        n++;
        N->steps++;
        if (tau_new - R->tau <= 0x1p-40 * R->tau) floor_steps++;
        else floor_steps = 0;
        R->tau_old = R->tau; R->tau = tau_new; h = h_next;
        roots(P, R->z, g);
        if (!crossed(R->G[0], g)) {
            if (!saved && tau_end <= tau_new) { memcpy(saved_end, R->z, 3 * sizeof(double)); saved = 1; observe(rec, saved_end[0]); }
            carry_signs(R->G[0], g);
            R->cursor = tau_new;
            memcpy(R->G[0], g, sizeof g);
        } else {
            N->crossing_steps++;
        }
    }
    (void)tiny;
}

static double now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return ts.tv_sec + 1e-9 * ts.tv_nsec;
}

int main(int argc, char **argv)
{
    if (argc < 2) { fprintf(stderr, "usage: %s INPUT [REPEATS]\n", argv[0]); return 2; }
    FILE *fh = fopen(argv[1], "r");
    if (!fh) { perror(argv[1]); return 2; }
    char line[4096];
    double v[N_Q + 3 + 7];
    int nv = 0;
    while (nv < (int)(sizeof v / sizeof v[0]) && fgets(line, sizeof line, fh)) {
        if (line[0] == '#') continue;
        char *s = line, *end;
        for (;;) {
            double x = strtod(s, &end);
            if (end == s) break;
            if (nv < (int)(sizeof v / sizeof v[0])) v[nv++] = x;
            s = end;
        }
    }
    fclose(fh);
    if (nv != N_Q + 3 + 7) { fprintf(stderr, "%s: %d numbers, expected %d\n", argv[1], nv, N_Q + 10); return 2; }
    if (v[Q_LAW] != 0.0 || v[Q_QS] != 0.0) {
        fprintf(stderr, "only the slip law with mass (q[LAW] = 0, q[QS] = 0)\n");
        return 2;
    }
    Prob P = {.beta = v[Q_BETA], .c = v[Q_C], .d = v[Q_D], .e = v[Q_E], .g = v[Q_G],
              .z0 = {v[8], v[9], v[10]}, .tau_end = v[11], .rtol = v[12], .atol = v[13],
              .ln10es = v[14], .lnes = v[15], .lne = v[16], .h0 = v[17]};
    int repeats = argc > 2 ? atoi(argv[2]) : 200;
    Run R; Counters N; Rec rec = {0}; double ev[64][8], zend[3] = {0};
    int status = 0;
    double best = INFINITY, total = 0.0;
    for (int r = 0; r < repeats; r++) {
        double t0 = now();
        status = solve(&P, INFINITY, &R, &N, &rec, ev, zend);
        double dt = now() - t0;
        total += dt;
        if (dt < best) best = dt;
    }
    long att = N.steps + N.rejected;
#ifdef COUNT
    printf("scans %ld passes %ld bisection steps %ld (per repeat)\n", n_scan / repeats, n_pass / repeats, n_bisect / repeats);
#endif
    printf("status %d steps %ld rejected %ld nfev %ld njev %ld roots [%ld, %ld, %ld, %ld] events %d "
           "crossing_steps %ld\n", status, N.steps, N.rejected, N.nfev, N.njev, N.roots[0],
           N.roots[1], N.roots[2], N.roots[3], (int)rec.n, N.crossing_steps);
    printf("z_end %.17g %.17g %.17g\n", zend[0], zend[1], zend[2]);
    printf("tau %.17g  min %.3f us  mean %.3f us  per attempt: min %.4f us  mean %.4f us\n",
           R.tau, best * 1e6, total / repeats * 1e6, best / att * 1e6, total / repeats / att * 1e6);
    return status;
}
