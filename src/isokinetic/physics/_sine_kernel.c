/* The compiled kernels of isokinetic.physics.sine_grid: Radau IIA over the grid of a periodic drive
 * (integrate) and the exact sweep of a force channel's mode over a piecewise constant input (mode_sweep).
 *
 * Compiled ahead of time when the package is installed (pyproject.toml, [tool.setuptools] ext-modules), so that
 * a fresh process pays no compiler at start-up (each Snakemake job is a fresh Python). The method is that of
 * sine_grid.py's module docstring, written statement for statement from the numba kernel it replaced (equal to it
 * within 6e-16 of the pressure scale: docs/diagnosis.md, "Compiled once, when installed");
 * tests/physics/test_sine_grid.py checks the result against LSODA and the integrated mode equation. Arrays arrive
 * through the buffer protocol: C-contiguous float64 (complex128 for the mode's outputs), their formats and sizes
 * checked here. No global state; the GIL is released while a kernel runs.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <complex.h>
#include <math.h>
#include <string.h>

/* the parameters: amp, omega, h, area, beta, v01, v02, c1p, c1n, c2p, c2n, leak, gas, b_oil, g1, g2, p0, low, scale */
#define NPAR 19

/* (y, dy/dtau) of the drive at t (SineDrive: Y sin wt + sum A_k (sin(k w t + th_k) - sin th_k)) */
static void motion(double t, const double *par, const double *ks, const double *aks, const double *ths,
                   Py_ssize_t nk, double start, double *y_out, double *v_out)
{
    double ph = par[1] * t;
    double y = par[0] * sin(ph);
    double v = par[0] * cos(ph);
    for (Py_ssize_t i = 0; i < nk; i++) {
        double arg = ks[i] * ph + ths[i];
        y += aks[i] * sin(arg);
        v += ks[i] * aks[i] * cos(arg);
    }
    *y_out = y - start;
    *v_out = par[1] * v;
}

/* (Q_N, dQ_N/ddp): Eq. (7) with the direction's c1, c2, plus leakage */
static void flow(double p, const double *par, double *q, double *dq)
{
    double c1p = par[7], c1n = par[8], c2p = par[9], c2n = par[10], leak = par[11];
    double m = fabs(p), root;
    if (m == 0.0) {
        *q = 0.0;
        *dq = 1.0 / (c1p > 1e-300 ? c1p : 1e-300) + leak;
        return;
    }
    if (p >= 0.0) {
        root = sqrt(c1p * c1p + 4.0 * c2p * m);
        *q = 2.0 * m / (c1p + root) + leak * p;
    } else {
        root = sqrt(c1n * c1n + 4.0 * c2n * m);
        *q = -2.0 * m / (c1n + root) + leak * p;
    }
    *dq = 1.0 / root + leak;
}

/* Eq. (1) at position y and speed v: f[0..1] the rates of the state, f[2..5] their Jacobian J11, J12, J21, J22
 * (one state dp = p1 with the composite volume of Eq. (2); with the gas law the two chamber pressures p1, p2) */
static void rhs(double y, double v, double p1, double p2, const double *par, double *f)
{
    double area = par[3], beta = par[4], v01 = par[5], v02 = par[6];
    double qin = area * v, q, dq;
    if (par[12] < 0.5) {
        flow(p1, par, &q, &dq);
        double cap = beta * ((v01 - area * y) * (v02 + area * y) / (v01 + v02));
        f[0] = (qin - q) / cap;
        f[1] = 0.0;
        f[2] = -dq / cap;
        f[3] = 0.0;
        f[4] = 0.0;
        f[5] = 0.0;
        return;
    }
    double b_oil = par[13], g1 = par[14], g2 = par[15], low = par[17];
    double u1 = 1.0 / (low > p1 ? low : p1);
    double u2 = 1.0 / (low > p2 ? low : p2);
    double cap1 = b_oil * (v01 - area * y) + g1 * u1 * (u1 - b_oil);
    double cap2 = b_oil * (v02 + area * y) + g2 * u2 * (u2 - b_oil);
    flow(p1 - p2, par, &q, &dq);
    double net = qin - q;
    double s1 = g1 * u1 * u1 * (b_oil - 2.0 * u1);
    double s2 = g2 * u2 * u2 * (b_oil - 2.0 * u2);
    f[0] = net / cap1;
    f[1] = -net / cap2;
    f[2] = (-dq - net / cap1 * s1) / cap1;
    f[3] = dq / cap1;
    f[4] = dq / cap2;
    f[5] = (-dq + net / cap2 * s2) / cap2;
}

/* LU factors of big (n x n, row stride 6) with partial pivoting, in place */
static void factor(double big[6][6], Py_ssize_t piv[6], int n)
{
    for (int col = 0; col < n; col++) {
        int p = col;
        for (int r = col + 1; r < n; r++)
            if (fabs(big[r][col]) > fabs(big[p][col]))
                p = r;
        piv[col] = p;
        if (p != col)
            for (int c = 0; c < n; c++) {
                double tmp = big[col][c];
                big[col][c] = big[p][c];
                big[p][c] = tmp;
            }
        for (int r = col + 1; r < n; r++) {
            big[r][col] /= big[col][col];
            double m = big[r][col];
            if (m != 0.0)
                for (int c = col + 1; c < n; c++)
                    big[r][c] -= m * big[col][c];
        }
    }
}

/* res <- big^-1 res from the factors of factor() */
static void back(double big[6][6], const Py_ssize_t piv[6], double res[6], int n)
{
    for (int col = 0; col < n; col++) {
        Py_ssize_t p = piv[col];
        if (p != col) {
            double tmp = res[col];
            res[col] = res[p];
            res[p] = tmp;
        }
        for (int r = col + 1; r < n; r++)
            res[r] -= big[r][col] * res[col];
    }
    for (int r = n - 1; r >= 0; r--) {
        double acc = res[r];
        for (int c = r + 1; c < n; c++)
            acc -= big[r][c] * res[c];
        res[r] = acc / big[r][r];
    }
}

/* Simplified Newton on the stage increments Z_i = hh sum_j A_ij f(t + c_j hh, z + Z_j) from `stage` (the
 * iteration matrix built and factorised once, from the Jacobian at the predicted stages); then z += Z_3 */
static void newton(double z[2], int dim, double hh, const double my[3], const double mv[3], double stage[3][2],
                   const double *par, const double *ra, int iterations, double tol)
{
    double fst[3][2] = {{0.0}}, jst[3][2][2] = {{{0.0}}}, big[6][6], res[6], f[6];
    Py_ssize_t piv[6];
    int n = 3 * dim;
    for (int it = 0; it < iterations; it++) {
        for (int i = 0; i < 3; i++) {
            double q2 = dim == 2 ? z[1] + stage[i][1] : 0.0;
            rhs(my[i], mv[i], z[0] + stage[i][0], q2, par, f);
            fst[i][0] = f[0];
            fst[i][1] = f[1];
            jst[i][0][0] = f[2];
            jst[i][0][1] = f[3];
            jst[i][1][0] = f[4];
            jst[i][1][1] = f[5];
        }
        if (it == 0) {
            for (int i = 0; i < 3; i++)
                for (int d = 0; d < dim; d++)
                    for (int j = 0; j < 3; j++)
                        for (int e = 0; e < dim; e++)
                            big[i * dim + d][j * dim + e] = -hh * ra[3 * i + j] * jst[j][d][e]
                                + ((i == j && d == e) ? 1.0 : 0.0);
            factor(big, piv, n);
        }
        for (int i = 0; i < 3; i++)
            for (int d = 0; d < dim; d++) {
                double acc = stage[i][d];
                for (int j = 0; j < 3; j++)
                    acc -= hh * ra[3 * i + j] * fst[j][d];
                res[i * dim + d] = acc;
            }
        back(big, piv, res, n);
        double size = 0.0;
        for (int i = 0; i < 3; i++)
            for (int d = 0; d < dim; d++) {
                stage[i][d] -= res[i * dim + d];
                double a = fabs(res[i * dim + d]);
                if (a > size)
                    size = a;
            }
        if (size <= tol * par[18])
            break;
    }
    for (int d = 0; d < dim; d++)
        z[d] += stage[2][d];
}

/* dp and ddp/dtau of state z at grid point j */
static void store(Py_ssize_t j, double y, double v, const double z[2], int dim, const double *par, double *out_p,
                  double *out_f)
{
    double f[6];
    if (dim == 2) {
        rhs(y, v, z[0], z[1], par, f);
        out_p[j] = z[0] - z[1];
        out_f[j] = f[0] - f[1];
    } else {
        rhs(y, v, z[0], 0.0, par, f);
        out_p[j] = z[0];
        out_f[j] = f[0];
    }
}

/* Radau IIA over n_steps grid steps from rest; fills out_p, out_f; returns the index of the first point of the
 * cycle that repeats the one before (-1: none). stage_y, stage_v: per_cycle rows of 4 (the three stages, then the
 * grid point). */
static Py_ssize_t integrate_grid(const double *par, const double *ks, const double *aks, const double *ths,
                                 Py_ssize_t nk, const double *ra, const double *rc, Py_ssize_t n_steps,
                                 Py_ssize_t per_cycle, Py_ssize_t substeps, double first_sub, double converged,
                                 int iterations, double tol, const double *stage_y, const double *stage_v,
                                 double *out_p, double *out_f)
{
    int dim = par[12] > 0.5 ? 2 : 1;
    double start = 0.0;
    for (Py_ssize_t i = 0; i < nk; i++)
        start += aks[i] * sin(ths[i]);
    double z[2] = {dim == 2 ? par[16] : 0.0, dim == 2 ? par[16] : 0.0};
    double stage[3][2] = {{0.0}}, my[3], mv[3], f[6];
    store(0, stage_y[3], stage_v[3], z, dim, par, out_p, out_f);
    double ratio = pow(1.0 / first_sub, 1.0 / (double)(substeps - 1));
    double hh = par[2] * (ratio - 1.0) / (pow(ratio, (double)substeps) - 1.0);
    double t = 0.0;
    for (Py_ssize_t j = -substeps; j < n_steps; j++) {
        if (j < 0) {
            for (int i = 0; i < 3; i++)
                motion(t + rc[i] * hh, par, ks, aks, ths, nk, start, &my[i], &mv[i]);
        } else {
            if (j == 0)
                continue;
            hh = par[2];
            t = (double)j * par[2];
            Py_ssize_t k = j % per_cycle;
            for (int i = 0; i < 3; i++) {
                my[i] = stage_y[4 * k + i];
                mv[i] = stage_v[4 * k + i];
            }
        }
        if (j < 0 || j == 1) {   /* Euler's predictor after a change of step, else the last step's increments */
            double y0, v0;
            motion(t, par, ks, aks, ths, nk, start, &y0, &v0);
            rhs(y0, v0, z[0], dim == 2 ? z[1] : 0.0, par, f);
            for (int i = 0; i < 3; i++) {
                stage[i][0] = rc[i] * hh * f[0];
                if (dim == 2)
                    stage[i][1] = rc[i] * hh * f[1];
            }
        }
        newton(z, dim, hh, my, mv, stage, par, ra, iterations, tol);
        if (j < 0) {
            t += hh;
            hh *= ratio;
            if (j == -1) {
                Py_ssize_t k1 = 1 % per_cycle;
                store(1, stage_y[4 * k1 + 3], stage_v[4 * k1 + 3], z, dim, par, out_p, out_f);
            }
            continue;
        }
        Py_ssize_t k1 = (j + 1) % per_cycle;
        store(j + 1, stage_y[4 * k1 + 3], stage_v[4 * k1 + 3], z, dim, par, out_p, out_f);
        if ((j + 1) % per_cycle == 0 && j + 1 >= 3 * per_cycle) {
            double worst = 0.0;   /* the change from cycle to cycle, changing no more (a drift) or none */
            for (Py_ssize_t k = j + 1 - per_cycle; k < j + 1; k++) {
                double c = fabs(out_p[k + 1] - 2.0 * out_p[k + 1 - per_cycle] + out_p[k + 1 - 2 * per_cycle]);
                if (c > worst)
                    worst = c;
            }
            if (worst <= converged * par[18])
                return j + 1 - per_cycle;
        }
    }
    return -1;
}

/* w and W = int_0 w of the mode w' = lam w + sigma(t) at the sorted queries, segment by segment */
static void sweep(const double *jumps, const double *signs, Py_ssize_t n_jumps, double complex lam,
                  const double *queries, Py_ssize_t n_q, double complex *w_out, double complex *big_out)
{
    double complex w = 0.0, big = 0.0;
    double t = 0.0, sigma = 0.0;
    Py_ssize_t k = 0;
    for (Py_ssize_t q = 0; q < n_q; q++) {
        double target = queries[q];
        for (;;) {
            double nxt = k < n_jumps ? jumps[k] : INFINITY;
            double stop = nxt < target ? nxt : target;
            double d = stop - t;
            if (d > 0.0) {
                if (lam == 0.0) {
                    big += w * d + 0.5 * sigma * d * d;
                    w += sigma * d;
                } else {
                    double complex e = cexp(lam * d);
                    double complex a = w + sigma / lam;
                    big += -sigma / lam * d + a * (e - 1.0) / lam;
                    w = -sigma / lam + a * e;
                }
                t = stop;
            }
            if (nxt <= target) {
                sigma = signs[k];
                k += 1;
            } else {
                break;
            }
        }
        w_out[q] = w;
        big_out[q] = big;
    }
}

/* The buffer of `obj`: C-contiguous items of struct format `format` ("d": float64, "Zd": complex128), `count` of
 * them (count < 0: any number), writable where asked; the error names the argument. */
static int array_of(PyObject *obj, Py_buffer *buf, const char *format, Py_ssize_t count, int writable,
                    const char *name)
{
    if (PyObject_GetBuffer(obj, buf, PyBUF_FORMAT | PyBUF_C_CONTIGUOUS | (writable ? PyBUF_WRITABLE : 0)) < 0) {
        buf->obj = NULL;
        PyErr_Clear();
        PyErr_Format(PyExc_TypeError, "%s: a C-contiguous%s array of format '%s' expected", name,
                     writable ? " writable" : "", format);
        return 0;
    }
    const char *f = buf->format ? buf->format : "B";
    if (f[0] == '<' || f[0] == '=' || f[0] == '@')
        f++;
    if (strcmp(f, format) != 0) {
        PyErr_Format(PyExc_TypeError, "%s: items of format '%s' expected, '%s' given", name, format, f);
        return 0;
    }
    if (count >= 0 && buf->len / buf->itemsize != count) {
        PyErr_Format(PyExc_ValueError, "%s: %zd items expected, %zd given", name, count, buf->len / buf->itemsize);
        return 0;
    }
    return 1;
}

static void release(Py_buffer *bufs, int n)
{
    for (int i = 0; i < n; i++)
        if (bufs[i].obj != NULL)
            PyBuffer_Release(&bufs[i]);
}

PyDoc_STRVAR(integrate_doc,
"integrate(par, ks, aks, ths, radau_a, radau_c, n_steps, per_cycle, substeps, first_sub, converged,\n"
"          newton_iterations, newton_tol, stage_y, stage_v, out_p, out_f) -> int\n\n"
"Radau IIA over the grid from rest (isokinetic.physics.sine_grid): float64 arrays, par of 19 items, radau_a 3 x 3,\n"
"stage_y and stage_v per_cycle x 4, out_p and out_f (written) n_steps + 1; returns the index of the first point\n"
"of the cycle that repeats the one before (-1: none).");

static PyObject *py_integrate(PyObject *self, PyObject *args)
{
    PyObject *o[10];
    Py_buffer b[10];
    memset(b, 0, sizeof(b));
    Py_ssize_t n_steps, per_cycle, substeps;
    double first_sub, converged, tol;
    int iterations;
    if (!PyArg_ParseTuple(args, "OOOOOOnnnddidOOOO", &o[0], &o[1], &o[2], &o[3], &o[4], &o[5], &n_steps,
                          &per_cycle, &substeps, &first_sub, &converged, &iterations, &tol, &o[6], &o[7], &o[8],
                          &o[9]))
        return NULL;
    if (per_cycle < 1 || substeps < 2 || n_steps < 1)
        return PyErr_Format(PyExc_ValueError, "per_cycle >= 1, substeps >= 2 and n_steps >= 1 expected");
    int ok = array_of(o[0], &b[0], "d", NPAR, 0, "par") && array_of(o[1], &b[1], "d", -1, 0, "ks");
    Py_ssize_t nk = ok ? b[1].len / b[1].itemsize : 0;
    ok = ok && array_of(o[2], &b[2], "d", nk, 0, "aks") && array_of(o[3], &b[3], "d", nk, 0, "ths")
        && array_of(o[4], &b[4], "d", 9, 0, "radau_a") && array_of(o[5], &b[5], "d", 3, 0, "radau_c")
        && array_of(o[6], &b[6], "d", 4 * per_cycle, 0, "stage_y")
        && array_of(o[7], &b[7], "d", 4 * per_cycle, 0, "stage_v")
        && array_of(o[8], &b[8], "d", n_steps + 1, 1, "out_p") && array_of(o[9], &b[9], "d", n_steps + 1, 1, "out_f");
    if (!ok) {
        release(b, 10);
        return NULL;
    }
    Py_ssize_t out;
    Py_BEGIN_ALLOW_THREADS
    out = integrate_grid(b[0].buf, b[1].buf, b[2].buf, b[3].buf, nk, b[4].buf, b[5].buf, n_steps, per_cycle,
                         substeps, first_sub, converged, iterations, tol, b[6].buf, b[7].buf, b[8].buf, b[9].buf);
    Py_END_ALLOW_THREADS
    release(b, 10);
    return PyLong_FromSsize_t(out);
}

PyDoc_STRVAR(sweep_doc,
"mode_sweep(jumps, signs, lam, queries, w_out, big_w_out) -> None\n\n"
"w and W = int_0 w of the mode w' = lam w + sigma(t) at the sorted queries (isokinetic.physics.sine_grid):\n"
"jumps, signs, queries float64; w_out, big_w_out complex128 (written), as many as the queries.");

static PyObject *py_mode_sweep(PyObject *self, PyObject *args)
{
    PyObject *o[5];
    Py_buffer b[5];
    memset(b, 0, sizeof(b));
    Py_complex lam;
    if (!PyArg_ParseTuple(args, "OODOOO", &o[0], &o[1], &lam, &o[2], &o[3], &o[4]))
        return NULL;
    int ok = array_of(o[0], &b[0], "d", -1, 0, "jumps") && array_of(o[2], &b[2], "d", -1, 0, "queries");
    Py_ssize_t n_jumps = ok ? b[0].len / b[0].itemsize : 0, n_q = ok ? b[2].len / b[2].itemsize : 0;
    ok = ok && array_of(o[1], &b[1], "d", n_jumps, 0, "signs") && array_of(o[3], &b[3], "Zd", n_q, 1, "w_out")
        && array_of(o[4], &b[4], "Zd", n_q, 1, "big_w_out");
    if (!ok) {
        release(b, 5);
        return NULL;
    }
    double complex l = lam.real + lam.imag * I;
    Py_BEGIN_ALLOW_THREADS
    sweep(b[0].buf, b[1].buf, n_jumps, l, b[2].buf, n_q, b[3].buf, b[4].buf);
    Py_END_ALLOW_THREADS
    release(b, 5);
    Py_RETURN_NONE;
}

static PyMethodDef methods[] = {
    {"integrate", py_integrate, METH_VARARGS, integrate_doc},
    {"mode_sweep", py_mode_sweep, METH_VARARGS, sweep_doc},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {
    PyModuleDef_HEAD_INIT, "_sine_kernel",
    "The compiled kernels of isokinetic.physics.sine_grid (Radau IIA on a periodic drive's grid; a mode's sweep).",
    -1, methods,
};

PyMODINIT_FUNC PyInit__sine_kernel(void)
{
    return PyModule_Create(&module);
}
