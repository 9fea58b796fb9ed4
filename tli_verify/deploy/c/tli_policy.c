/*
 * tli_policy.c -- see tli_policy.h. C99, libc + libm only.
 *
 * Mirrors the Python runtime (tli_verify.runtime.executive.LTLDSPolicy, with cuts supplied
 * by the caller): the automaton's Mealy step and monitor, the planner's choice per state
 * (exported), the invariance-failure rule, the LPV-DS f(x) = sum_k gamma_k(x) A_k (x - x*)
 * (tli_verify.ds.lpvds, the single-state path: same products, same summation order) and the
 * modulation (tli_verify.boundary.modulation.Modulator.__call__ with a control period:
 * eq. 7, the sampled-data cap and the corner guard's P-metric projection by least-distance
 * programming, Lawson-Hanson NNLS).
 */
#include "tli_policy.h"

#include <errno.h>
#include <limits.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* Compile with -ffp-contract=off (see tli_policy.h): no fused multiply-add. */

#define MAXR (TLI_MAX_CUTS + 1) /* rows of the guard's QP: the cuts and the Lyapunov row */
#define MAXQ (TLI_MAX_DIM * (TLI_MAX_DIM + 1) / 2 + TLI_MAX_DIM)

/* ------------------------------------------------------------------ SHA-256 (FIPS 180-4) */
static const uint32_t K256[64] = {
    0x428a2f98, 0x71374491, 0xb5c0fbcf, 0xe9b5dba5, 0x3956c25b, 0x59f111f1, 0x923f82a4,
    0xab1c5ed5, 0xd807aa98, 0x12835b01, 0x243185be, 0x550c7dc3, 0x72be5d74, 0x80deb1fe,
    0x9bdc06a7, 0xc19bf174, 0xe49b69c1, 0xefbe4786, 0x0fc19dc6, 0x240ca1cc, 0x2de92c6f,
    0x4a7484aa, 0x5cb0a9dc, 0x76f988da, 0x983e5152, 0xa831c66d, 0xb00327c8, 0xbf597fc7,
    0xc6e00bf3, 0xd5a79147, 0x06ca6351, 0x14292967, 0x27b70a85, 0x2e1b2138, 0x4d2c6dfc,
    0x53380d13, 0x650a7354, 0x766a0abb, 0x81c2c92e, 0x92722c85, 0xa2bfe8a1, 0xa81a664b,
    0xc24b8b70, 0xc76c51a3, 0xd192e819, 0xd6990624, 0xf40e3585, 0x106aa070, 0x19a4c116,
    0x1e376c08, 0x2748774c, 0x34b0bcb5, 0x391c0cb3, 0x4ed8aa4a, 0x5b9cca4f, 0x682e6ff3,
    0x748f82ee, 0x78a5636f, 0x84c87814, 0x8cc70208, 0x90befffa, 0xa4506ceb, 0xbef9a3f7,
    0xc67178f2};

#define ROR(x, r) (((x) >> (r)) | ((x) << (32 - (r))))

static void sha256_block(uint32_t h[8], const unsigned char *b) {
    uint32_t w[64], a, bb, c, d, e, f, g, hh, t1, t2;
    int i;
    for (i = 0; i < 16; i++)
        w[i] = ((uint32_t)b[4 * i] << 24) | ((uint32_t)b[4 * i + 1] << 16) |
               ((uint32_t)b[4 * i + 2] << 8) | (uint32_t)b[4 * i + 3];
    for (i = 16; i < 64; i++) {
        uint32_t s0 = ROR(w[i - 15], 7) ^ ROR(w[i - 15], 18) ^ (w[i - 15] >> 3);
        uint32_t s1 = ROR(w[i - 2], 17) ^ ROR(w[i - 2], 19) ^ (w[i - 2] >> 10);
        w[i] = w[i - 16] + s0 + w[i - 7] + s1;
    }
    a = h[0]; bb = h[1]; c = h[2]; d = h[3]; e = h[4]; f = h[5]; g = h[6]; hh = h[7];
    for (i = 0; i < 64; i++) {
        t1 = hh + (ROR(e, 6) ^ ROR(e, 11) ^ ROR(e, 25)) + ((e & f) ^ (~e & g)) + K256[i] + w[i];
        t2 = (ROR(a, 2) ^ ROR(a, 13) ^ ROR(a, 22)) + ((a & bb) ^ (a & c) ^ (bb & c));
        hh = g; g = f; f = e; e = d + t1; d = c; c = bb; bb = a; a = t1 + t2;
    }
    h[0] += a; h[1] += bb; h[2] += c; h[3] += d; h[4] += e; h[5] += f; h[6] += g; h[7] += hh;
}

void tli_sha256(const void *data, size_t len, unsigned char out[32]) {
    uint32_t h[8] = {0x6a09e667, 0xbb67ae85, 0x3c6ef372, 0xa54ff53a,
                     0x510e527f, 0x9b05688c, 0x1f83d9ab, 0x5be0cd19};
    const unsigned char *p = (const unsigned char *)data;
    unsigned char tail[128];
    size_t full = len / 64, rest = len % 64, i, tl;
    uint64_t bits = (uint64_t)len * 8u;
    for (i = 0; i < full; i++) sha256_block(h, p + 64 * i);
    memset(tail, 0, sizeof tail);
    if (rest) memcpy(tail, p + 64 * full, rest);
    tail[rest] = 0x80;
    tl = rest + 1 + 8 <= 64 ? 64 : 128;
    for (i = 0; i < 8; i++) tail[tl - 1 - i] = (unsigned char)(bits >> (8 * i));
    sha256_block(h, tail);
    if (tl == 128) sha256_block(h, tail + 64);
    for (i = 0; i < 8; i++) {
        out[4 * i] = (unsigned char)(h[i] >> 24);
        out[4 * i + 1] = (unsigned char)(h[i] >> 16);
        out[4 * i + 2] = (unsigned char)(h[i] >> 8);
        out[4 * i + 3] = (unsigned char)h[i];
    }
}

/* ------------------------------------------------------------------ data */
typedef struct {
    int mode, next_mode, K, n_cuts, cap;
    double *attractor, *P, *priors, *means, *covs, *center, *comp, *A, *b;
    double *W, *pts, *h, *PinvW, *q;
    unsigned char *deg;
    int any_deg;
    double *Ps, *L, *metric; /* symmetrised P, its Cholesky factor, L^-T */
} tli_ds;

struct tli_policy {
    int n, n_inputs, n_modes, n_states, n_initial, n_edges, n_ds, max_online;
    long total_k, total_cuts;
    double dt, kappa, deg_tol, bnd_tol, guard_tol;
    uint64_t free_mask, goal_inputs, input_mask;
    uint64_t *progress;
    unsigned char *is_goal;
    int *st_mode, *st_goal, *st_ds, *st_planned;
    uint64_t *st_inputs;
    unsigned char *is_initial;
    int *initial;
    int *e_start, *e_to;
    uint64_t *e_on, *e_off;
    tli_ds *ds;
    char hex[65];
    /* the stall rule (runtime.stall): off when window == 0 */
    long window, dwell_steps;
    double stall_radius, stall_progress;
    double *levels;  /* per DS: lambda_min(P) r^2 */
    int *reentry;    /* per mode: the re-entry DS, -1 none */
    double *trend;   /* ring of the last `window` values of V */
    /* run state */
    int started, state, mode, planned, cur_ds, holding, pending;
    long steps;
    double entry[TLI_MAX_DIM], last[TLI_MAX_DIM];
    int re_active, re_mode, stall_state, stall_ds;  /* re-entry under way; (state, DS) watched */
    uint64_t re_reading;
    long stall_count, trend_len, trend_head;
    /* the one allocation */
    unsigned char *block;
    size_t used, size;
};

/* ------------------------------------------------------------------ loader */
typedef struct {
    const char *s;
    size_t len, pos;
    int line;
    char *err;
    size_t errlen;
    int code;
    tli_policy *p;
} parser;

static int fail(parser *ps, int code, const char *fmt, ...) {
    va_list ap;
    if (ps->code) return ps->code;
    ps->code = code;
    if (ps->err && ps->errlen) {
        int k = snprintf(ps->err, ps->errlen, "line %d: ", ps->line);
        if (k < 0) k = 0;
        if ((size_t)k < ps->errlen) {
            va_start(ap, fmt);
            vsnprintf(ps->err + k, ps->errlen - (size_t)k, fmt, ap);
            va_end(ap);
        }
    }
    return code;
}

static void *take(parser *ps, size_t count, size_t size) {
    tli_policy *p = ps->p;
    size_t bytes, at;
    if (ps->code) return NULL;
    if (count && size > ((size_t)-1) / count) { fail(ps, TLI_E_SIZE, "size overflow"); return NULL; }
    bytes = count * size;
    at = (p->used + 7u) & ~(size_t)7u;
    if (at > p->size || bytes > p->size - at) {
        fail(ps, TLI_E_SIZE, "sizes beyond the header (more data than the header declares)");
        return NULL;
    }
    p->used = at + bytes;
    return p->block + at;
}

/* next whitespace-separated token; counts lines */
static int token(parser *ps, const char **t, size_t *n) {
    while (ps->pos < ps->len && (ps->s[ps->pos] == ' ' || ps->s[ps->pos] == '\n' ||
                                 ps->s[ps->pos] == '\t' || ps->s[ps->pos] == '\r')) {
        if (ps->s[ps->pos] == '\n') ps->line++;
        ps->pos++;
    }
    if (ps->pos >= ps->len) return fail(ps, TLI_E_FORMAT, "truncated: unexpected end of data");
    *t = ps->s + ps->pos;
    *n = 0;
    while (ps->pos < ps->len && ps->s[ps->pos] != ' ' && ps->s[ps->pos] != '\n' &&
           ps->s[ps->pos] != '\t' && ps->s[ps->pos] != '\r') {
        ps->pos++;
        (*n)++;
    }
    return TLI_OK;
}

static int expect(parser *ps, const char *kw) {
    const char *t;
    size_t n;
    if (ps->code || token(ps, &t, &n)) return ps->code;
    if (n != strlen(kw) || memcmp(t, kw, n) != 0)
        return fail(ps, TLI_E_FORMAT, "expected '%s', got '%.*s'", kw, (int)(n > 40 ? 40 : n), t);
    return TLI_OK;
}

static int read_long(parser *ps, long lo, long hi, long *out, const char *what) {
    const char *t;
    size_t n;
    char buf[32];
    char *end;
    long v;
    if (ps->code || token(ps, &t, &n)) return ps->code;
    if (n == 0 || n >= sizeof buf) return fail(ps, TLI_E_FORMAT, "%s: not an integer", what);
    memcpy(buf, t, n);
    buf[n] = 0;
    errno = 0;
    v = strtol(buf, &end, 10);
    if (*end || errno) return fail(ps, TLI_E_FORMAT, "%s: not an integer: '%s'", what, buf);
    if (v < lo || v > hi)
        return fail(ps, TLI_E_SIZE, "%s = %ld is outside %ld..%ld", what, v, lo, hi);
    *out = v;
    return TLI_OK;
}

static int read_int(parser *ps, int lo, int hi, int *out, const char *what) {
    long v = 0;
    if (read_long(ps, lo, hi, &v, what)) return ps->code;
    *out = (int)v;
    return TLI_OK;
}

static int read_mask(parser *ps, int bits, uint64_t *out, const char *what) {
    const char *t;
    size_t n;
    char buf[32];
    char *end;
    unsigned long long v;
    if (ps->code || token(ps, &t, &n)) return ps->code;
    if (n == 0 || n >= sizeof buf || t[0] == '-')
        return fail(ps, TLI_E_FORMAT, "%s: not a mask", what);
    memcpy(buf, t, n);
    buf[n] = 0;
    errno = 0;
    v = strtoull(buf, &end, 10);
    if (*end || errno) return fail(ps, TLI_E_FORMAT, "%s: not a mask: '%s'", what, buf);
    if (bits < 64 && (v >> bits) != 0)
        return fail(ps, TLI_E_SIZE, "%s: bit beyond the %d declared", what, bits);
    *out = (uint64_t)v;
    return TLI_OK;
}

static int read_doubles(parser *ps, double *out, long count, const char *what) {
    long i;
    for (i = 0; i < count; i++) {
        const char *t;
        size_t n;
        char buf[64];
        char *end;
        double v;
        if (ps->code || token(ps, &t, &n)) return ps->code;
        if (n == 0 || n >= sizeof buf) return fail(ps, TLI_E_FORMAT, "%s: not a number", what);
        memcpy(buf, t, n);
        buf[n] = 0;
        v = strtod(buf, &end);
        if (*end) return fail(ps, TLI_E_FORMAT, "%s[%ld]: not a number: '%s'", what, i, buf);
        if (!isfinite(v)) return fail(ps, TLI_E_NUMBER, "%s[%ld]: not finite: '%s'", what, i, buf);
        out[i] = v;
    }
    return TLI_OK;
}

static int read_name(parser *ps, const char *what) {
    const char *t;
    size_t n, i;
    if (ps->code || token(ps, &t, &n)) return ps->code;
    if (n == 1 && t[0] == '-') return TLI_OK;
    if (n % 2) return fail(ps, TLI_E_FORMAT, "%s: not hex-encoded", what);
    for (i = 0; i < n; i++)
        if (!((t[i] >= '0' && t[i] <= '9') || (t[i] >= 'a' && t[i] <= 'f')))
            return fail(ps, TLI_E_FORMAT, "%s: not hex-encoded", what);
    return TLI_OK;
}

/* Cholesky P = L L^T (lower, row-major); 0 if not positive definite */
static int cholesky(const double *P, double *L, int n) {
    int i, j, k;
    memset(L, 0, sizeof(double) * (size_t)n * (size_t)n);
    for (j = 0; j < n; j++) {
        double s = P[j * n + j];
        for (k = 0; k < j; k++) s -= L[j * n + k] * L[j * n + k];
        if (!(s > 0.0) || !isfinite(s)) return 0;
        L[j * n + j] = sqrt(s);
        for (i = j + 1; i < n; i++) {
            double t = P[i * n + j];
            for (k = 0; k < j; k++) t -= L[i * n + k] * L[j * n + k];
            L[i * n + j] = t / L[j * n + j];
        }
    }
    return 1;
}

/* solve P x = b with P = L L^T */
static void chol_solve(const double *L, int n, const double *b, double *x) {
    int i, k;
    double y[TLI_MAX_DIM];
    for (i = 0; i < n; i++) {
        double s = b[i];
        for (k = 0; k < i; k++) s -= L[i * n + k] * y[k];
        y[i] = s / L[i * n + i];
    }
    for (i = n - 1; i >= 0; i--) {
        double s = y[i];
        for (k = i + 1; k < n; k++) s -= L[k * n + i] * x[k];
        x[i] = s / L[i * n + i];
    }
}

/* precompute cut j of DS d (Modulator.build); 0 when the plane leaves x* outside */
static int prepare_cut(const tli_policy *p, tli_ds *d, int j) {
    int n = p->n, i;
    double h = 0.0, nrm = 0.0, scale;
    const double *w = d->W + (size_t)j * n, *pt = d->pts + (size_t)j * n;
    for (i = 0; i < n; i++) {
        double r = pt[i] - d->attractor[i];
        h += w[i] * r;
        nrm += r * r;
    }
    scale = sqrt(nrm);
    if (scale < 1.0) scale = 1.0;
    d->deg[j] = fabs(h) <= p->deg_tol * scale;
    if (!d->deg[j] && h < 0) return 0;
    d->h[j] = d->deg[j] ? 0.0 : h;
    if (d->deg[j]) d->any_deg = 1;
    chol_solve(d->L, n, w, d->PinvW + (size_t)j * n);
    d->q[j] = 0.0;
    for (i = 0; i < n; i++) d->q[j] += w[i] * d->PinvW[(size_t)j * n + i];
    return 1;
}

/* 1 when the automaton has an edge from a state of mode a to a state of mode b */
static int mode_edge(const tli_policy *p, int a, int b) {
    int s, e;
    for (s = 0; s < p->n_states; s++) {
        if (p->st_mode[s] != a) continue;
        for (e = p->e_start[s]; e < p->e_start[s + 1]; e++)
            if (p->st_mode[p->e_to[e]] == b) return 1;
    }
    return 0;
}

/* The stall rule's per-DS levels and per-mode re-entry DS, each checked: a level is at most
 * lambda_min(P) r^2 (so V below it puts x within r of x*: P - (level / r^2)(1 - 1e-6) I must
 * be positive definite), and a re-entry DS of mode m belongs to a mode p != m, is planned into
 * m, and the automaton has mode transitions m -> p and p -> m (runtime.stall.reentry_route). */
static int parse_stall(parser *ps) {
    tli_policy *p = ps->p;
    int n = p->n, d, m, i;
    double r2 = p->stall_radius * p->stall_radius;
    if (expect(ps, "levels") || read_doubles(ps, p->levels, p->n_ds, "levels")) return ps->code;
    for (d = 0; d < p->n_ds; d++) {
        double M[TLI_MAX_DIM * TLI_MAX_DIM], L[TLI_MAX_DIM * TLI_MAX_DIM];
        double c = p->levels[d] / r2 * (1.0 - 1e-6);
        if (!(p->levels[d] > 0))
            return fail(ps, TLI_E_NUMBER, "ds %d: stall level not > 0", d);
        memcpy(M, p->ds[d].Ps, sizeof(double) * (size_t)n * (size_t)n);
        for (i = 0; i < n; i++) M[i * n + i] -= c;
        if (!cholesky(M, L, n))
            return fail(ps, TLI_E_NUMBER, "ds %d: stall level %.17g is above lambda_min(P) r^2 "
                        "(V below it would not put x within r = %.17g of x*)", d,
                        p->levels[d], p->stall_radius);
    }
    if (expect(ps, "reentry")) return ps->code;
    for (m = 0; m < p->n_modes; m++) {
        const tli_ds *v;
        if (read_int(ps, -1, p->n_ds - 1, &p->reentry[m], "reentry")) return ps->code;
        if (p->reentry[m] < 0) {  /* none: only where no DS could re-enter m */
            int d2;
            for (d2 = 0; d2 < p->n_ds; d2++) {
                const tli_ds *w = &p->ds[d2];
                if (w->mode != m && w->next_mode == m && mode_edge(p, m, w->mode) &&
                    mode_edge(p, w->mode, m))
                    return fail(ps, TLI_E_FORMAT, "mode %d: no re-entry DS, but DS %d of a "
                                "predecessor is planned into it (the rule would be off there)",
                                m, d2);
            }
            continue;
        }
        v = &p->ds[p->reentry[m]];
        if (v->mode == m || v->next_mode != m || !mode_edge(p, m, v->mode) ||
            !mode_edge(p, v->mode, m))
            return fail(ps, TLI_E_FORMAT, "mode %d: re-entry DS %d is not a DS of a "
                        "predecessor planned into it (mode %d -> %d, both ways in the "
                        "automaton)", m, p->reentry[m], v->mode, m);
    }
    return TLI_OK;
}

static int parse(parser *ps) {
    tli_policy *p = ps->p;
    int i, j, n, version = 0, di;
    long sizes[11], kseen = 0, cseen = 0, q;
    const char *names[11] = {"dim", "inputs", "modes", "states", "initial", "edges", "ds",
                             "components", "cuts", "max_online_cuts", "stall window"};
    long lims[11] = {TLI_MAX_DIM, TLI_MAX_BITS, TLI_MAX_BITS, 1000000, 1000000, 10000000,
                     100000, 10000000, 10000000, TLI_MAX_CUTS, TLI_MAX_STALL_WINDOW};
    double mod[4];
    if (expect(ps, "tli-policy-text")) return ps->code;
    if (read_int(ps, 0, INT_MAX, &version, "schema version")) return ps->code;
    if (version != TLI_POLICY_SCHEMA_VERSION)
        return fail(ps, TLI_E_VERSION, "schema version %d, this evaluator reads %d", version,
                    TLI_POLICY_SCHEMA_VERSION);
    if (expect(ps, "name") || read_name(ps, "name")) return ps->code;
    if (expect(ps, "sizes")) return ps->code;
    for (i = 0; i < 11; i++)
        if (read_long(ps, i == 0 || i == 3 || i == 4 || i == 6 || i == 7 ? 1 : 0, lims[i],
                      &sizes[i], names[i]))
            return ps->code;
    n = p->n = (int)sizes[0];
    p->n_inputs = (int)sizes[1];
    p->n_modes = (int)sizes[2];
    p->n_states = (int)sizes[3];
    p->n_initial = (int)sizes[4];
    p->n_edges = (int)sizes[5];
    p->n_ds = (int)sizes[6];
    p->total_k = sizes[7];
    p->total_cuts = sizes[8];
    p->max_online = (int)sizes[9];
    p->window = sizes[10];
    if (n < 2) return fail(ps, TLI_E_SIZE, "dim = %d: at least 2", n);
    if (p->window == 1) return fail(ps, TLI_E_SIZE, "stall window = 1: 0 (no stall rule) or >= 2");
    if (p->n_modes < 1) return fail(ps, TLI_E_SIZE, "modes = 0");
    p->input_mask = p->n_inputs == 64 ? ~(uint64_t)0 : (((uint64_t)1 << p->n_inputs) - 1u);
    /* the one block: every array, sized from the header */
    {
        size_t nn = (size_t)n * (size_t)n, K = (size_t)p->total_k;
        size_t cap = (size_t)p->total_cuts + (size_t)p->n_ds * (size_t)p->max_online;
        size_t qd = (size_t)n * (size_t)(n + 1) / 2 + (size_t)n + 1;
        size_t dbl = (size_t)p->n_ds * (5 * nn + 2 * (size_t)n + 8) + K * (1 + (size_t)n + 2 * nn + qd + (size_t)n)
                     + cap * (3 * (size_t)n + 2 + 1);
        size_t other = (size_t)p->n_modes * 9 + (size_t)p->n_states * (4 * 4 + 8 + 1 + 8) +
                       (size_t)p->n_initial * 4 + (size_t)(p->n_states + 1) * 4 +
                       (size_t)p->n_edges * (4 + 16) + (size_t)p->n_ds * sizeof(tli_ds) + 64 * 16;
        dbl += (size_t)p->n_ds + (size_t)p->window;        /* stall levels, trend */
        other += (size_t)p->n_modes * 4;                    /* re-entry DS per mode */
        p->size = dbl * 8 + other + ((size_t)p->n_ds + 16) * 256;
        if (((size_t)p->n_states + (size_t)p->n_edges + K + (size_t)p->total_cuts) * 2 > ps->len)
            return fail(ps, TLI_E_SIZE, "sizes beyond the file: the header declares more "
                        "records than %zu bytes can hold", ps->len);
        p->block = (unsigned char *)calloc(1, p->size);
        if (!p->block) return fail(ps, TLI_E_SIZE, "cannot allocate %zu bytes", p->size);
    }
    if (expect(ps, "dt") || read_doubles(ps, &p->dt, 1, "dt")) return ps->code;
    if (!(p->dt > 0)) return fail(ps, TLI_E_NUMBER, "dt must be > 0");
    if (expect(ps, "modulation") || read_doubles(ps, mod, 4, "modulation")) return ps->code;
    p->kappa = mod[0]; p->deg_tol = mod[1]; p->bnd_tol = mod[2]; p->guard_tol = mod[3];
    if (!(p->kappa > 0) || mod[1] < 0 || mod[2] < 0 || mod[3] < 0)
        return fail(ps, TLI_E_NUMBER, "modulation constants must be >= 0 (barrier rate > 0)");
    {   /* "stall 0", or "stall 1 radius progress dwell_steps window" */
        int on;
        long win;
        double sp[2];
        if (expect(ps, "stall") || read_int(ps, 0, 1, &on, "stall")) return ps->code;
        if (on != (p->window > 0))
            return fail(ps, TLI_E_FORMAT, "stall %d but the header's stall window is %ld", on,
                        p->window);
        if (on) {
            if (read_doubles(ps, sp, 2, "stall") ||
                read_long(ps, 1, 1000000000L, &p->dwell_steps, "stall dwell steps") ||
                read_long(ps, 2, TLI_MAX_STALL_WINDOW, &win, "stall window"))
                return ps->code;
            if (win != p->window)
                return fail(ps, TLI_E_SIZE, "stall window %ld, the header says %ld", win,
                            p->window);
            if (!(sp[0] > 0) || !(sp[1] >= 0 && sp[1] < 1))
                return fail(ps, TLI_E_NUMBER, "stall rule: need radius > 0 and 0 <= progress "
                            "< 1");
            p->stall_radius = sp[0];
            p->stall_progress = sp[1];
            p->levels = (double *)take(ps, (size_t)p->n_ds, 8);
            p->reentry = (int *)take(ps, (size_t)p->n_modes, 4);
            p->trend = (double *)take(ps, (size_t)p->window, 8);
            if (ps->code) return ps->code;
        }
    }
    {
        const char *src[5] = {"spec", "model", "certificate", "task", "evidence"};
        for (i = 0; i < 5; i++) {
            const char *t;
            size_t tn;
            if (expect(ps, "source") || expect(ps, src[i]) || token(ps, &t, &tn)) return ps->code;
            if (!((tn == 1 && t[0] == '-') || tn == 64))
                return fail(ps, TLI_E_FORMAT, "source %s: not a SHA-256", src[i]);
        }
    }
    for (i = 0; i < p->n_inputs; i++)
        if (expect(ps, "input") || read_name(ps, "input")) return ps->code;
    if (expect(ps, "free") || read_mask(ps, p->n_inputs, &p->free_mask, "free")) return ps->code;
    p->progress = (uint64_t *)take(ps, (size_t)p->n_modes, 8);
    p->is_goal = (unsigned char *)take(ps, (size_t)p->n_modes, 1);
    if (ps->code) return ps->code;
    for (i = 0; i < p->n_modes; i++) {
        int g;
        if (expect(ps, "mode") || read_name(ps, "mode") ||
            read_mask(ps, p->n_modes, &p->progress[i], "mode progress") ||
            read_int(ps, 0, 1, &g, "mode goal"))
            return ps->code;
        p->is_goal[i] = (unsigned char)g;
    }
    if (expect(ps, "goal_inputs") || read_mask(ps, p->n_inputs, &p->goal_inputs, "goal_inputs"))
        return ps->code;
    p->st_mode = (int *)take(ps, (size_t)p->n_states, 4);
    p->st_goal = (int *)take(ps, (size_t)p->n_states, 4);
    p->st_ds = (int *)take(ps, (size_t)p->n_states, 4);
    p->st_planned = (int *)take(ps, (size_t)p->n_states, 4);
    p->st_inputs = (uint64_t *)take(ps, (size_t)p->n_states, 8);
    p->is_initial = (unsigned char *)take(ps, (size_t)p->n_states, 1);
    if (ps->code) return ps->code;
    for (i = 0; i < p->n_states; i++) {
        int id;
        if (expect(ps, "state") || read_int(ps, i, i, &id, "state id") ||
            read_int(ps, 0, p->n_modes - 1, &p->st_mode[i], "state mode") ||
            read_int(ps, 0, INT_MAX, &p->st_goal[i], "state goal") ||
            read_mask(ps, p->n_inputs, &p->st_inputs[i], "state inputs") ||
            read_int(ps, 0, p->n_ds - 1, &p->st_ds[i], "state ds") ||
            read_int(ps, -1, p->n_modes - 1, &p->st_planned[i], "state planned"))
            return ps->code;
    }
    p->initial = (int *)take(ps, (size_t)p->n_initial, 4);
    if (ps->code || expect(ps, "initial")) return ps->code;
    for (i = 0; i < p->n_initial; i++) {
        if (read_int(ps, 0, p->n_states - 1, &p->initial[i], "initial")) return ps->code;
        p->is_initial[p->initial[i]] = 1;
    }
    p->e_start = (int *)take(ps, (size_t)p->n_states + 1, 4);
    p->e_to = (int *)take(ps, (size_t)p->n_edges + 1, 4);
    p->e_on = (uint64_t *)take(ps, (size_t)p->n_edges + 1, 8);
    p->e_off = (uint64_t *)take(ps, (size_t)p->n_edges + 1, 8);
    if (ps->code) return ps->code;
    {
        int prev = 0;
        for (i = 0; i < p->n_edges; i++) {
            int from;
            if (expect(ps, "edge") || read_int(ps, 0, p->n_states - 1, &from, "edge from") ||
                read_int(ps, 0, p->n_states - 1, &p->e_to[i], "edge to") ||
                read_mask(ps, p->n_inputs, &p->e_on[i], "edge on") ||
                read_mask(ps, p->n_inputs, &p->e_off[i], "edge off"))
                return ps->code;
            if (from < prev) return fail(ps, TLI_E_FORMAT, "edges not sorted by source");
            while (prev < from) p->e_start[++prev] = i;
            p->e_start[from + 1] = i + 1;
            prev = from;
        }
        for (j = prev + 1; j <= p->n_states; j++) p->e_start[j] = p->n_edges;
        p->e_start[0] = 0;
    }
    p->ds = (tli_ds *)take(ps, (size_t)p->n_ds, sizeof(tli_ds));
    if (ps->code) return ps->code;
    q = (long)n * (n + 1) / 2 + n;
    for (di = 0; di < p->n_ds; di++) {
        tli_ds *d = &p->ds[di];
        size_t nn = (size_t)n * (size_t)n;
        int K, c;
        if (expect(ps, "ds") || read_name(ps, "ds key") ||
            read_int(ps, 0, p->n_modes - 1, &d->mode, "ds mode") ||
            read_int(ps, -1, p->n_modes - 1, &d->next_mode, "ds next mode") ||
            read_int(ps, 1, TLI_MAX_COMPONENTS, &d->K, "ds components") ||
            read_int(ps, 0, TLI_MAX_CUTS, &d->n_cuts, "ds cuts"))
            return ps->code;
        K = d->K;
        kseen += K;
        cseen += d->n_cuts;
        if (kseen > p->total_k) return fail(ps, TLI_E_SIZE, "components beyond the header's %ld", p->total_k);
        if (cseen > p->total_cuts) return fail(ps, TLI_E_SIZE, "cuts beyond the header's %ld", p->total_cuts);
        d->cap = d->n_cuts + p->max_online;
        if (d->cap > TLI_MAX_CUTS)
            return fail(ps, TLI_E_SIZE, "ds %d: %d cuts + %d online slots exceed %d", di,
                        d->n_cuts, p->max_online, TLI_MAX_CUTS);
        d->attractor = (double *)take(ps, (size_t)n, 8);
        d->P = (double *)take(ps, nn, 8);
        d->Ps = (double *)take(ps, nn, 8);
        d->L = (double *)take(ps, nn, 8);
        d->metric = (double *)take(ps, nn, 8);
        d->priors = (double *)take(ps, (size_t)K, 8);
        d->means = (double *)take(ps, (size_t)K * n, 8);
        d->covs = (double *)take(ps, (size_t)K * nn, 8);
        d->center = (double *)take(ps, (size_t)n, 8);
        d->comp = (double *)take(ps, (size_t)K * (size_t)(q + 1), 8);
        d->A = (double *)take(ps, (size_t)K * nn, 8);
        d->b = (double *)take(ps, (size_t)K * n, 8);
        d->W = (double *)take(ps, (size_t)d->cap * n, 8);
        d->pts = (double *)take(ps, (size_t)d->cap * n, 8);
        d->PinvW = (double *)take(ps, (size_t)d->cap * n, 8);
        d->h = (double *)take(ps, (size_t)d->cap, 8);
        d->q = (double *)take(ps, (size_t)d->cap, 8);
        d->deg = (unsigned char *)take(ps, (size_t)d->cap, 1);
        if (ps->code) return ps->code;
        if (expect(ps, "attractor") || read_doubles(ps, d->attractor, n, "attractor") ||
            expect(ps, "P") || read_doubles(ps, d->P, (long)nn, "P") ||
            expect(ps, "priors") || read_doubles(ps, d->priors, K, "priors") ||
            expect(ps, "means") || read_doubles(ps, d->means, (long)K * n, "means") ||
            expect(ps, "covs") || read_doubles(ps, d->covs, (long)(K * nn), "covs") ||
            expect(ps, "center") || read_doubles(ps, d->center, n, "center"))
            return ps->code;
        for (i = 0; i < K; i++) {
            if (!(d->priors[i] > 0)) return fail(ps, TLI_E_NUMBER, "ds %d: prior %d not > 0", di, i);
            if (expect(ps, "component") ||
                read_doubles(ps, d->comp + (size_t)i * (size_t)(q + 1), q + 1, "component"))
                return ps->code;
        }
        if (expect(ps, "A") || read_doubles(ps, d->A, (long)(K * nn), "A") ||
            expect(ps, "b") || read_doubles(ps, d->b, (long)K * n, "b"))
            return ps->code;
        for (i = 0; i < n; i++)
            for (j = 0; j < n; j++)
                d->Ps[i * n + j] = 0.5 * (d->P[i * n + j] + d->P[j * n + i]);
        if (!cholesky(d->Ps, d->L, n))
            return fail(ps, TLI_E_NUMBER, "ds %d: P is not symmetric positive definite", di);
        /* metric = L^-T: column j of L^-1 ... solve L y = e_j, metric[j][i] = y[i] */
        for (j = 0; j < n; j++) {
            double y[TLI_MAX_DIM];
            for (i = 0; i < n; i++) {
                double s = i == j ? 1.0 : 0.0;
                int k;
                for (k = 0; k < i; k++) s -= d->L[i * n + k] * y[k];
                y[i] = s / d->L[i * n + i];
            }
            for (i = 0; i < n; i++) d->metric[j * n + i] = y[i]; /* (L^-1)[i][j] -> L^-T[j][i] */
        }
        for (c = 0; c < d->n_cuts; c++) {
            double buf[2 * TLI_MAX_DIM], nrm = 0.0;
            if (expect(ps, "cut") || read_doubles(ps, buf, 2L * n, "cut")) return ps->code;
            memcpy(d->W + (size_t)c * n, buf, sizeof(double) * (size_t)n);
            memcpy(d->pts + (size_t)c * n, buf + n, sizeof(double) * (size_t)n);
            for (i = 0; i < n; i++) nrm += buf[i] * buf[i];
            if (fabs(sqrt(nrm) - 1.0) > 1e-6)
                return fail(ps, TLI_E_NUMBER, "ds %d cut %d: normal is not a unit vector", di, c);
            if (!prepare_cut(p, d, c))
                return fail(ps, TLI_E_NUMBER, "ds %d cut %d leaves the attractor outside", di, c);
        }
    }
    if (kseen != p->total_k || cseen != p->total_cuts)
        return fail(ps, TLI_E_SIZE, "the header declares %ld components and %ld cuts, the data "
                    "has %ld and %ld", p->total_k, p->total_cuts, kseen, cseen);
    for (i = 0; i < p->n_states; i++)
        if (p->ds[p->st_ds[i]].mode != p->st_mode[i])
            return fail(ps, TLI_E_FORMAT, "state %d runs a DS of another mode", i);
    if (p->window > 0 && parse_stall(ps)) return ps->code;
    if (expect(ps, "end")) return ps->code;
    return TLI_OK;
}

static void set_err(char *err, size_t errlen, const char *fmt, ...) {
    va_list ap;
    if (!err || !errlen) return;
    va_start(ap, fmt);
    vsnprintf(err, errlen, fmt, ap);
    va_end(ap);
}

int tli_policy_load_buffer(const char *data, size_t len, tli_policy **out, char *err,
                           size_t errlen) {
    static const char hexd[] = "0123456789abcdef";
    size_t body, i;
    unsigned char digest[32];
    char hex[65];
    parser ps;
    tli_policy *p;
    if (err && errlen) err[0] = 0;
    if (!out || !data) {
        set_err(err, errlen, "NULL argument");
        return TLI_E_ARG;
    }
    *out = NULL;
    /* the closing line: "sha256 <64 hex>\n" at the very end */
    if (len < 72 || data[len - 1] != '\n' || memcmp(data + len - 72, "sha256 ", 7) != 0 ||
        (len > 72 && data[len - 73] != '\n')) {
        set_err(err, errlen, "truncated or malformed: no closing 'sha256 <hex>' line");
        return TLI_E_FORMAT;
    }
    body = len - 72;
    tli_sha256(data, body, digest);
    for (i = 0; i < 32; i++) {
        hex[2 * i] = hexd[digest[i] >> 4];
        hex[2 * i + 1] = hexd[digest[i] & 15];
    }
    hex[64] = 0;
    if (memcmp(hex, data + body + 7, 64) != 0) {
        set_err(err, errlen, "hash mismatch: the file says %.64s, its content hashes to %s "
                "(edited or corrupted)", data + body + 7, hex);
        return TLI_E_HASH;
    }
    p = (tli_policy *)calloc(1, sizeof *p);
    if (!p) {
        set_err(err, errlen, "out of memory");
        return TLI_E_SIZE;
    }
    memcpy(p->hex, hex, 65);
    memset(&ps, 0, sizeof ps);
    ps.s = data;
    ps.len = body;
    ps.line = 1;
    ps.err = err;
    ps.errlen = errlen;
    ps.p = p;
    if (parse(&ps) != TLI_OK) {
        tli_policy_free(p);
        return ps.code;
    }
    {   /* nothing after "end" but whitespace */
        size_t k;
        for (k = ps.pos; k < body; k++)
            if (data[k] != '\n' && data[k] != ' ') {
                tli_policy_free(p);
                set_err(err, errlen, "data after 'end'");
                return TLI_E_FORMAT;
            }
    }
    *out = p;
    return TLI_OK;
}

int tli_policy_load(const char *path, tli_policy **out, char *err, size_t errlen) {
    FILE *f;
    long size;
    char *buf;
    size_t got;
    int rc;
    if (err && errlen) err[0] = 0;
    if (!path || !out) {
        set_err(err, errlen, "NULL argument");
        return TLI_E_ARG;
    }
    *out = NULL;
    f = fopen(path, "rb");
    if (!f) {
        set_err(err, errlen, "%s: cannot open: %s", path, strerror(errno));
        return TLI_E_IO;
    }
    if (fseek(f, 0, SEEK_END) != 0 || (size = ftell(f)) < 0 || fseek(f, 0, SEEK_SET) != 0 ||
        size > (1L << 30)) {
        fclose(f);
        set_err(err, errlen, "%s: cannot read (or larger than 1 GiB)", path);
        return TLI_E_IO;
    }
    buf = (char *)malloc((size_t)size + 1);
    if (!buf) {
        fclose(f);
        set_err(err, errlen, "%s: out of memory", path);
        return TLI_E_IO;
    }
    got = fread(buf, 1, (size_t)size, f);
    fclose(f);
    if (got != (size_t)size) {
        free(buf);
        set_err(err, errlen, "%s: short read", path);
        return TLI_E_IO;
    }
    rc = tli_policy_load_buffer(buf, got, out, err, errlen);
    free(buf);
    return rc;
}

void tli_policy_free(tli_policy *p) {
    if (!p) return;
    free(p->block);
    free(p);
}

int tli_policy_dim(const tli_policy *p) { return p->n; }
int tli_policy_n_inputs(const tli_policy *p) { return p->n_inputs; }
int tli_policy_n_modes(const tli_policy *p) { return p->n_modes; }
int tli_policy_n_ds(const tli_policy *p) { return p->n_ds; }
int tli_policy_ds_mode(const tli_policy *p, int ds) {
    return ds >= 0 && ds < p->n_ds ? p->ds[ds].mode : -1;
}
int tli_policy_n_cuts(const tli_policy *p, int ds) {
    return ds >= 0 && ds < p->n_ds ? p->ds[ds].n_cuts : -1;
}
double tli_policy_dt(const tli_policy *p) { return p->dt; }
const char *tli_policy_sha256(const tli_policy *p) { return p->hex; }

/* ------------------------------------------------------------------ LPV-DS (eq. 4) */
static void ds_nominal(const tli_policy *p, const tli_ds *d, const double *x, double *f) {
    int n = p->n, K = d->K, i, j, k, l;
    int qd = n * (n + 1) / 2 + n;
    double u[TLI_MAX_DIM], z[TLI_MAX_DIM], phi[MAXQ], logp[TLI_MAX_COMPONENTS];
    double top, total, gz;
    for (i = 0; i < n; i++) u[i] = x[i] - d->center[i];
    l = 0;
    for (i = 0; i < n; i++)
        for (j = i; j < n; j++) phi[l++] = u[i] * u[j];
    for (i = 0; i < n; i++) phi[l++] = u[i];
    for (k = 0; k < K; k++) {
        const double *row = d->comp + (size_t)k * (size_t)(qd + 1);
        double s = row[qd]; /* the constant first, then left to right (Python's sum) */
        for (l = 0; l < qd; l++) s += phi[l] * row[l];
        logp[k] = s;
    }
    top = logp[0];
    for (k = 1; k < K; k++)
        if (logp[k] > top) top = logp[k];
    total = 0.0;
    for (k = 0; k < K; k++) {
        logp[k] = exp(logp[k] - top);
        total += logp[k];
    }
    for (k = 0; k < K; k++) logp[k] = logp[k] / total; /* gamma_k */
    for (i = 0; i < n; i++) z[i] = x[i] - d->attractor[i];
    for (j = 0; j < n; j++) f[j] = 0.0;
    /* f_j = sum_k sum_i (gamma_k z_i) A_k[j][i], k outer, i inner (the runtime's order) */
    for (j = 0; j < n; j++) {
        double s = 0.0;
        for (k = 0; k < K; k++) {
            const double *Ak = d->A + (size_t)k * (size_t)n * (size_t)n;
            for (i = 0; i < n; i++) {
                gz = logp[k] * z[i];
                s += gz * Ak[j * n + i];
            }
        }
        f[j] = s;
    }
}

/* ------------------------------------------------------------------ modulation (eq. 7 + guard) */
static double dot(const double *a, const double *b, int n) {
    double s = 0.0;
    int i;
    for (i = 0; i < n; i++) s += a[i] * b[i];
    return s;
}

/* Lawson-Hanson NNLS: min ||E y - r||, y >= 0; E is M x K (row-major, ld = K) */
static void nnls(const double *E, int M, int K, const double *r, double *y) {
    unsigned char passive[MAXR];
    double z[MAXR], res[TLI_MAX_DIM + 1];
    double Q[(TLI_MAX_DIM + 1) * MAXR], rhs[TLI_MAX_DIM + 1];
    int idx[MAXR];
    int i, j, it, outer = 0;
    const double tol = 1e-12;
    for (j = 0; j < K; j++) { y[j] = 0.0; passive[j] = 0; }
    for (;;) {
        int t = -1, np;
        double best = 0.0;
        for (i = 0; i < M; i++) {
            double s = r[i];
            for (j = 0; j < K; j++) s -= E[i * K + j] * y[j];
            res[i] = s;
        }
        for (j = 0; j < K; j++) {
            double s = 0.0;
            for (i = 0; i < M; i++) s += E[i * K + j] * res[i];
            if (!passive[j] && s > tol && s > best) { best = s; t = j; }
        }
        if (t < 0 || ++outer > 3 * K + 10) return;
        passive[t] = 1;
        for (it = 0; it < 3 * K + 10; it++) {
            /* least squares on the passive columns: Householder QR */
            int c, k2;
            double alpha = 2.0;
            np = 0;
            for (j = 0; j < K; j++)
                if (passive[j]) idx[np++] = j;
            for (i = 0; i < M; i++) {
                rhs[i] = r[i];
                for (c = 0; c < np; c++) Q[i * MAXR + c] = E[i * K + idx[c]];
            }
            for (c = 0; c < np && c < M; c++) {
                double nrm = 0.0, vv, beta;
                for (i = c; i < M; i++) nrm += Q[i * MAXR + c] * Q[i * MAXR + c];
                nrm = sqrt(nrm);
                if (nrm == 0.0) continue;
                if (Q[c * MAXR + c] > 0) nrm = -nrm;
                Q[c * MAXR + c] -= nrm; /* v = x - nrm e1 stored in column c */
                vv = 0.0;
                for (i = c; i < M; i++) vv += Q[i * MAXR + c] * Q[i * MAXR + c];
                if (vv == 0.0) { Q[c * MAXR + c] = nrm; continue; }
                for (k2 = c + 1; k2 < np; k2++) {
                    double s = 0.0;
                    for (i = c; i < M; i++) s += Q[i * MAXR + c] * Q[i * MAXR + k2];
                    beta = 2.0 * s / vv;
                    for (i = c; i < M; i++) Q[i * MAXR + k2] -= beta * Q[i * MAXR + c];
                }
                {
                    double s = 0.0;
                    for (i = c; i < M; i++) s += Q[i * MAXR + c] * rhs[i];
                    beta = 2.0 * s / vv;
                    for (i = c; i < M; i++) rhs[i] -= beta * Q[i * MAXR + c];
                }
                Q[c * MAXR + c] = nrm; /* R's diagonal */
            }
            for (c = (np < M ? np : M) - 1; c >= 0; c--) {
                double s = rhs[c];
                for (k2 = c + 1; k2 < np && k2 < M; k2++) s -= Q[c * MAXR + k2] * z[idx[k2]];
                z[idx[c]] = Q[c * MAXR + c] != 0.0 ? s / Q[c * MAXR + c] : 0.0;
            }
            for (c = M; c < np; c++) z[idx[c]] = 0.0;
            {
                int ok = 1;
                for (c = 0; c < np; c++)
                    if (z[idx[c]] <= 0.0) ok = 0;
                if (ok) {
                    for (j = 0; j < K; j++) y[j] = passive[j] ? z[j] : 0.0;
                    break;
                }
            }
            for (c = 0; c < np; c++) {
                j = idx[c];
                if (z[j] <= 0.0) {
                    double a = y[j] / (y[j] - z[j]);
                    if (a < alpha) alpha = a;
                }
            }
            for (c = 0; c < np; c++) {
                j = idx[c];
                y[j] += alpha * (z[j] - y[j]);
                if (y[j] <= tol) { y[j] = 0.0; passive[j] = 0; }
            }
        }
    }
}

/* argmin ||v - g||_P s.t. A v <= c (k rows) by least-distance programming; 0 if empty */
static int project(const tli_ds *d, int n, const double *g, const double *A, const double *c,
                   int k, double *v) {
    double AM[MAXR * TLI_MAX_DIM], e[MAXR], E[(TLI_MAX_DIM + 1) * MAXR], y[MAXR];
    double rhs[TLI_MAX_DIM + 1], r[TLI_MAX_DIM + 1] = {0}, zz[TLI_MAX_DIM], scale = 0.0;
    int i, j, l, kk = 0;
    for (i = 0; i < k; i++) {
        double nrm = 0.0, ei = dot(A + i * n, g, n) - c[i];
        double row[TLI_MAX_DIM];
        for (j = 0; j < n; j++) { /* (A metric)[i][j] = sum_l A[i][l] metric[l][j] */
            double s = 0.0;
            for (l = 0; l < n; l++) s += A[i * n + l] * d->metric[l * n + j];
            row[j] = s;
            nrm += s * s;
        }
        nrm = sqrt(nrm);
        if (!(nrm > 0.0)) {
            if (ei > 0.0) return 0;
            continue;
        }
        for (j = 0; j < n; j++) AM[kk * n + j] = row[j] / nrm;
        e[kk] = ei / nrm;
        if (fabs(e[kk]) > scale) scale = fabs(e[kk]);
        kk++;
    }
    if (scale == 0.0) {
        memcpy(v, g, sizeof(double) * (size_t)n);
        return 1;
    }
    for (j = 0; j < n; j++)
        for (i = 0; i < kk; i++) E[j * kk + i] = -AM[i * n + j];
    for (i = 0; i < kk; i++) E[n * kk + i] = e[i] / scale;
    for (j = 0; j < n; j++) rhs[j] = 0.0;
    rhs[n] = 1.0;
    nnls(E, n + 1, kk, rhs, y);
    for (j = 0; j <= n; j++) {
        double s = 0.0;
        for (i = 0; i < kk; i++) s += E[j * kk + i] * y[i];
        r[j] = s - rhs[j];
    }
    if (!(fabs(r[n]) > 1e-12)) return 0;
    for (j = 0; j < n; j++) zz[j] = -scale * r[j] / r[n];
    for (j = 0; j < n; j++) v[j] = g[j] + dot(d->metric + j * n, zz, n);
    return 1;
}

static int admits(const double *A, const double *c, int k, int n, const double *v,
                  const double *g, double tol) {
    int i, j;
    for (i = 0; i < k; i++) {
        double s = 0.0, m = 0.0;
        for (j = 0; j < n; j++) {
            s += A[i * n + j] * v[j];
            m += fabs(A[i * n + j]) * (fabs(v[j]) + fabs(g[j]));
        }
        if (!(s <= c[i] + tol * (fabs(c[i]) + m))) return 0;
    }
    return 1;
}

/* M(x) f (Modulator.__call__ with dt, one state, certified: P given) */
static void modulate(const tli_policy *p, const tli_ds *d, const double *x, const double *f,
                     double *out) {
    int n = p->n, m = d->n_cuts, i, j, a = 0, guard = 0;
    double D[TLI_MAX_DIM], S[TLI_MAX_CUTS], G[TLI_MAX_CUTS], B[TLI_MAX_CUTS];
    unsigned char app[TLI_MAX_CUTS];
    double V = 0.0, g, wf, cap = 1.0 / p->dt, nd = 0.0, rate = 1.0 / p->dt;
    int active;
    if (m == 0) {
        memcpy(out, f, sizeof(double) * (size_t)n);
        return;
    }
    for (i = 0; i < n; i++) D[i] = x[i] - d->attractor[i];
    G[0] = 0.0;
    for (j = 0; j < m; j++) S[j] = dot(D, d->W + j * n, n);
    if (d->any_deg) {
        for (i = 0; i < n; i++)
            for (j = 0; j < n; j++) V += D[i] * d->Ps[i * n + j] * D[j];
    }
    for (j = 0; j < m; j++) {
        if (!d->deg[j]) G[j] = S[j] / d->h[j];
        else G[j] = V > 0.0 ? 1.0 + S[j] * fabs(S[j]) / (d->q[j] * V) : 0.0;
    }
    for (j = 1; j < m; j++)
        if (G[j] > G[a]) a = j;
    g = G[a];
    wf = dot(d->W + a * n, f, n);
    active = g > 0.0 && g <= 1.0 + p->bnd_tol && wf > 0.0;
    {
        double coef = 0.0, cq = 0.0, radial = 0.0;
        if (active && !d->deg[a]) {
            coef = wf / d->h[a];
            if (coef > cap) coef = cap;
        }
        for (i = 0; i < n; i++) out[i] = f[i] - coef * D[i];
        if (active && d->deg[a]) {
            cq = wf / d->q[a];
            radial = -S[a] / (V > 0.0 ? V : 1.0);
            for (i = 0; i < n; i++) out[i] -= cq * d->PinvW[a * n + i] + (cq * radial) * D[i];
        }
    }
    /* screen: a row can only break where w_i . v > b_i / dt */
    nd = sqrt(dot(D, D, n));
    for (j = 0; j < m; j++) {
        B[j] = d->h[j] - S[j];
        app[j] = B[j] >= -p->bnd_tol * (1.0 + nd + d->h[j]);
        if (app[j] && dot(out, d->W + j * n, n) > rate * (B[j] > 0.0 ? B[j] : 0.0)) guard = 1;
    }
    if (!guard) return;
    {
        double grad[TLI_MAX_DIM], Vg = 0.0, vb, t, bound[TLI_MAX_CUTS], mag[TLI_MAX_DIM];
        double Am[MAXR * TLI_MAX_DIM], cm[MAXR], v[TLI_MAX_DIM];
        int todo = 0, k = 0;
        for (i = 0; i < n; i++)
            for (j = 0; j < n; j++) Vg += D[i] * d->Ps[i * n + j] * D[j];
        for (j = 0; j < n; j++) {
            double s = 0.0;
            for (i = 0; i < n; i++) s += D[i] * d->Ps[i * n + j];
            grad[j] = s;
        }
        vb = dot(grad, f, n);
        t = Vg > 0.0 ? (-vb / Vg > 0.0 ? -vb / Vg : 0.0) : 0.0;
        if (t > 1.0 / p->dt) t = 1.0 / p->dt;
        if (vb < -Vg / p->dt) vb = -Vg / p->dt;
        for (j = 0; j < m; j++) bound[j] = (1.0 / p->dt) * (B[j] > 0.0 ? B[j] : 0.0);
        for (i = 0; i < n; i++) mag[i] = fabs(out[i]) + fabs(out[i]);
        for (j = 0; j < m && !todo; j++) {
            double wm = 0.0;
            if (!app[j]) continue;
            for (i = 0; i < n; i++) wm += mag[i] * fabs(d->W[j * n + i]);
            if (dot(out, d->W + j * n, n) > bound[j] + p->guard_tol * (fabs(bound[j]) + wm)) todo = 1;
        }
        if (!todo) {
            double gm = 0.0;
            for (i = 0; i < n; i++) gm += fabs(grad[i]) * mag[i];
            if (dot(grad, out, n) > vb + p->guard_tol * (fabs(vb) + gm)) todo = 1;
        }
        if (!todo) return;
        for (j = 0; j < m; j++) {
            if (!app[j]) continue;
            memcpy(Am + k * n, d->W + j * n, sizeof(double) * (size_t)n);
            cm[k++] = bound[j];
        }
        memcpy(Am + k * n, grad, sizeof(double) * (size_t)n);
        cm[k++] = vb;
        if (project(d, n, out, Am, cm, k, v) && admits(Am, cm, k, n, v, out, p->guard_tol)) {
            memcpy(out, v, sizeof(double) * (size_t)n);
        } else {
            for (i = 0; i < n; i++) out[i] = -t * D[i];
        }
    }
}

int tli_policy_ds_velocity(const tli_policy *p, int ds, const double *x, int mod, double *v) {
    double f[TLI_MAX_DIM];
    int i;
    if (!p || !x || !v || ds < 0 || ds >= p->n_ds) return TLI_E_ARG;
    for (i = 0; i < p->n; i++)
        if (!isfinite(x[i])) return TLI_E_ARG;
    ds_nominal(p, &p->ds[ds], x, f);
    if (mod) modulate(p, &p->ds[ds], x, f, v);
    else memcpy(v, f, sizeof(double) * (size_t)p->n);
    return TLI_OK;
}

/* ------------------------------------------------------------------ executive */
static int next_state(const tli_policy *p, int s, uint64_t reading) {
    int e;
    for (e = p->e_start[s]; e < p->e_start[s + 1]; e++)
        if ((reading & p->e_on[e]) == p->e_on[e] && (reading & p->e_off[e]) == 0) return p->e_to[e];
    return -1;
}

/* a state entered with this reading: same strategy memory first, then initial, then id */
static int resync(const tli_policy *p, uint64_t reading) {
    int goal = p->started ? p->st_goal[p->state] : 0, best = -1, s;
    for (s = 0; s < p->n_states; s++) {
        if (p->st_inputs[s] != reading) continue;
        if (best < 0) { best = s; continue; }
        {
            int kb0 = p->st_goal[best] != goal, ks0 = p->st_goal[s] != goal;
            int kb1 = !p->is_initial[best], ks1 = !p->is_initial[s];
            if (ks0 < kb0 || (ks0 == kb0 && ks1 < kb1)) best = s;
        }
    }
    return best;
}

static void enter(tli_policy *p, int s) {
    p->state = s;
    p->mode = p->st_mode[s];
    p->planned = p->st_planned[s];
    p->cur_ds = p->st_ds[s];
}

static void fill(const tli_policy *p, tli_step_info *info, unsigned flags) {
    if (!info) return;
    info->state = p->state;
    info->mode = p->mode;
    info->planned = p->planned;
    info->ds = p->holding ? -1 : p->cur_ds;
    info->steps = p->steps;
    if (p->is_goal[p->mode] && (p->goal_inputs & ~p->st_inputs[p->state]) == 0)
        flags |= TLI_F_DONE;
    if (p->holding) flags |= TLI_F_HOLDING;
    info->flags = flags;
}

static int check_x(const tli_policy *p, const double *x) {
    int i;
    if (!x) return 0;
    for (i = 0; i < p->n; i++)
        if (!isfinite(x[i])) return 0;
    return 1;
}

int tli_policy_reset(tli_policy *p, const double *x0, uint64_t reading, tli_step_info *info) {
    int s = -1, i;
    unsigned flags = 0;
    if (!p || !check_x(p, x0) || (reading & ~p->input_mask)) return TLI_E_ARG;
    p->started = 0;
    p->steps = 0;
    p->pending = 0;
    p->holding = 0;
    p->re_active = 0;
    p->stall_count = p->trend_len = p->trend_head = 0;
    p->stall_state = p->stall_ds = -1;
    for (i = 0; i < p->n_initial; i++)
        if (p->st_inputs[p->initial[i]] == (reading & ~p->free_mask)) { s = p->initial[i]; break; }
    if (s < 0) {
        flags |= TLI_F_ASSUMPTION;
        s = resync(p, reading);
        if (s < 0) {
            p->holding = 1;
            s = p->initial[0];
        }
    }
    enter(p, s);
    memcpy(p->entry, x0, sizeof(double) * (size_t)p->n);
    memcpy(p->last, x0, sizeof(double) * (size_t)p->n);
    p->started = 1;
    if (info) info->failed_mode = info->failed_ds = -1;
    fill(p, info, flags);
    return TLI_OK;
}

void tli_policy_notify_perturbation(tli_policy *p) {
    if (p) p->pending = 1;
}

enum { CAUSE_FAILURE = 0, CAUSE_PERTURBATION = 1, CAUSE_ASSUMPTION = 2 };

/* V = (x - x*)^T P (x - x*) of DS d */
static double lyapunov(const tli_policy *p, const tli_ds *d, const double *x) {
    double r[TLI_MAX_DIM], v = 0.0;
    int i, j, n = p->n;
    for (i = 0; i < n; i++) r[i] = x[i] - d->attractor[i];
    for (j = 0; j < n; j++) {
        double c = 0.0;
        for (i = 0; i < n; i++) c += r[i] * d->P[i * n + j];
        v += c * r[j];
    }
    return v;
}

/* The stall rule's test after the automaton step (runtime.stall; LTLDSPolicy.monitor): V of
 * the DS run below its level for dwell_steps steps (converged), or not down by a fraction
 * `progress` over the last `window` steps (blocked), with the automaton state and DS unchanged
 * and no perturbation: the mode is re-entered from its predecessor's DS. */
static void monitor(tli_policy *p, int perturbed, unsigned *flags) {
    const tli_ds *d;
    double value, oldest;
    int m = p->mode, blocked;
    if (p->holding || p->is_goal[m]) {
        p->stall_count = 0;
        return;
    }
    if (p->stall_state != p->state || p->stall_ds != p->cur_ds || perturbed) {
        p->stall_state = p->state;
        p->stall_ds = p->cur_ds;
        p->stall_count = 0;
        p->trend_len = p->trend_head = 0;
    }
    d = &p->ds[p->cur_ds];
    value = lyapunov(p, d, p->last);
    if (p->trend_len < p->window) {
        p->trend[(p->trend_head + p->trend_len) % p->window] = value;
        p->trend_len++;
    } else {  /* full: the oldest gives way */
        p->trend[p->trend_head] = value;
        p->trend_head = (p->trend_head + 1) % p->window;
    }
    oldest = p->trend[p->trend_head];
    blocked = p->trend_len == p->window && value > (1.0 - p->stall_progress) * oldest;
    p->stall_count = value < p->levels[p->cur_ds] ? p->stall_count + 1 : 0;
    if (p->stall_count < p->dwell_steps && !blocked) return;
    p->stall_count = 0;
    p->trend_len = p->trend_head = 0;
    if (p->reentry[m] < 0) return;
    p->re_active = 1;
    p->re_mode = m;
    p->re_reading = p->st_inputs[p->state];
    p->cur_ds = p->reentry[m];
    p->mode = p->ds[p->cur_ds].mode;
    p->planned = m;
    memcpy(p->entry, p->last, sizeof(double) * (size_t)p->n);
    *flags |= TLI_F_STALL | TLI_F_MODE_CHANGE;
}

int tli_policy_decide(tli_policy *p, const double *x, uint64_t reading, int perturbed,
                      tli_step_info *info) {
    int cause, new_state, new_mode, old_mode, planned, n;
    unsigned flags = 0;
    if (!p || !check_x(p, x) || (reading & ~p->input_mask)) return TLI_E_ARG;
    if (!p->started) return TLI_E_STATE;
    n = p->n;
    if (info) info->failed_mode = info->failed_ds = -1;
    p->steps++;
    perturbed = perturbed || p->pending;
    p->pending = 0;
    if (perturbed) flags |= TLI_F_PERTURBED;
    if (p->re_active) {  /* the stall rule's re-entry: until its DS converges or the reading changes */
        int converged = lyapunov(p, &p->ds[p->cur_ds], x) < p->levels[p->cur_ds];
        memcpy(p->last, x, sizeof(double) * (size_t)n);
        if ((reading & ~p->free_mask) == p->re_reading && !converged) {
            fill(p, info, flags);  /* a perturbation does not end it */
            return TLI_OK;
        }
        p->re_active = 0;
        p->pending = perturbed;  /* a changed reading is the next period's automaton step */
        enter(p, p->state);
        memcpy(p->entry, x, sizeof(double) * (size_t)n);
        flags |= TLI_F_REENTERED | TLI_F_MODE_CHANGE;
        fill(p, info, flags);  /* no stall test in the return's period (as the executive) */
        return TLI_OK;
    }
    cause = perturbed ? CAUSE_PERTURBATION : CAUSE_FAILURE;
    if (p->holding && !perturbed) cause = CAUSE_ASSUMPTION;
    new_state = next_state(p, p->state, reading);
    if (new_state >= 0) {
        p->holding = 0;
    } else {
        flags |= TLI_F_ASSUMPTION;
        new_state = resync(p, reading);
        if (new_state < 0) {
            p->holding = 1;
            fill(p, info, flags);
            return TLI_OK;
        }
        p->holding = 0;
        if (!perturbed) cause = CAUSE_ASSUMPTION;
    }
    new_mode = p->st_mode[new_state];
    old_mode = p->mode;
    planned = p->planned;
    if (new_mode != old_mode) {
        int expected = new_mode == planned;
        int progress = (int)((p->progress[old_mode] >> new_mode) & 1u);
        if (!expected && !progress && cause == CAUSE_FAILURE) {
            flags |= TLI_F_FAILURE;
            if (info) {
                info->failed_mode = old_mode;
                info->failed_ds = p->cur_ds;
                memcpy(info->entry, p->entry, sizeof(double) * (size_t)n);
                memcpy(info->last_inside, p->last, sizeof(double) * (size_t)n);
                memcpy(info->outside, x, sizeof(double) * (size_t)n);
            }
        }
        enter(p, new_state);
        if (!expected) flags |= TLI_F_REPLAN;
        flags |= TLI_F_MODE_CHANGE;
        memcpy(p->entry, x, sizeof(double) * (size_t)n);
    } else {
        if (new_state != p->state) enter(p, new_state);
        if (perturbed) memcpy(p->entry, x, sizeof(double) * (size_t)n);
    }
    memcpy(p->last, x, sizeof(double) * (size_t)n);
    if (p->window > 0) monitor(p, perturbed, &flags);
    fill(p, info, flags);
    return TLI_OK;
}

int tli_policy_velocity(tli_policy *p, double *v) {
    double f[TLI_MAX_DIM];
    if (!p || !v) return TLI_E_ARG;
    if (!p->started) return TLI_E_STATE;
    if (p->holding || p->cur_ds < 0) {
        memset(v, 0, sizeof(double) * (size_t)p->n);
        return TLI_OK;
    }
    ds_nominal(p, &p->ds[p->cur_ds], p->last, f);
    modulate(p, &p->ds[p->cur_ds], p->last, f, v);
    return TLI_OK;
}

int tli_policy_step(tli_policy *p, const double *x, uint64_t reading, int perturbed, double *v,
                    tli_step_info *info) {
    int rc = tli_policy_decide(p, x, reading, perturbed, info);
    if (rc != TLI_OK) return rc;
    return tli_policy_velocity(p, v);
}

int tli_policy_add_cut(tli_policy *p, int mode, const double *normal, const double *point,
                       char *err, size_t errlen) {
    int n, di, i, any = 0;
    double nrm = 0.0;
    if (err && errlen) err[0] = 0;
    if (!p || !normal || !point || mode < 0 || mode >= p->n_modes || !check_x(p, normal) ||
        !check_x(p, point)) {
        set_err(err, errlen, "bad argument");
        return TLI_E_ARG;
    }
    n = p->n;
    for (i = 0; i < n; i++) nrm += normal[i] * normal[i];
    if (fabs(sqrt(nrm) - 1.0) > 1e-6) {
        set_err(err, errlen, "cut normal must be a unit vector, its norm is %.9g", sqrt(nrm));
        return TLI_E_CUT;
    }
    for (di = 0; di < p->n_ds; di++) { /* check every DS of the mode first: all or nothing */
        const tli_ds *d = &p->ds[di];
        double h = 0.0, r2 = 0.0, scale;
        if (d->mode != mode) continue;
        any = 1;
        if (d->n_cuts >= d->cap) {
            set_err(err, errlen, "cut storage full: DS %d of mode %d holds %d cuts (capacity %d)",
                    di, mode, d->n_cuts, d->cap);
            return TLI_E_FULL;
        }
        for (i = 0; i < n; i++) {
            double r = point[i] - d->attractor[i];
            h += normal[i] * r;
            r2 += r * r;
        }
        scale = sqrt(r2) > 1.0 ? sqrt(r2) : 1.0;
        if (!(h > 1e-9 * scale)) {
            set_err(err, errlen, "cut leaves the attractor of DS %d on or outside its plane "
                    "(w . (p - x*) = %.6g)", di, h);
            return TLI_E_CUT;
        }
    }
    if (!any) {
        set_err(err, errlen, "mode %d has no DS", mode);
        return TLI_E_ARG;
    }
    for (di = 0; di < p->n_ds; di++) {
        tli_ds *d = &p->ds[di];
        if (d->mode != mode) continue;
        memcpy(d->W + (size_t)d->n_cuts * n, normal, sizeof(double) * (size_t)n);
        memcpy(d->pts + (size_t)d->n_cuts * n, point, sizeof(double) * (size_t)n);
        prepare_cut(p, d, d->n_cuts); /* h > 0 checked: never refused here */
        d->n_cuts++;
    }
    return TLI_OK;
}
