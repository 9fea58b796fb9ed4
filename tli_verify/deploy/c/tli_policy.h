/*
 * tli_policy.h -- dependency-free C99 evaluator of a certified LTL-DS policy artifact
 * (tli-verify, `tli export`; paper eq. 6: task automaton + modulated LPV-DS per mode).
 *
 * Loads the text form (NAME.tli.txt) that `tli export` writes next to NAME.tli.json,
 * validates it (magic and schema version, sizes against the header, finite numbers, SPD P,
 * unit cut normals with x* inside, stall levels and re-entry DS, its own SHA-256), then runs
 * one call per control period: sensor bits in -> automaton state, mode and modulated velocity
 * out, with the executive's stall rule when the artifact carries one (runtime.stall).
 *
 * Needs libc and libm only. All memory is allocated by tli_policy_load (one block);
 * reset/decide/velocity/step/add_cut never allocate. Not thread-safe per policy object:
 * one object per control loop.
 *
 * Build: cc -std=c99 -O2 -ffp-contract=off -c tli_policy.c   (link with -lm)
 * (-ffp-contract=off keeps a*b+c as two roundings, as Python evaluates it: with it the
 *  nominal DS velocity is bit-for-bit the Python runtime's.)
 */
#ifndef TLI_POLICY_H
#define TLI_POLICY_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

#define TLI_POLICY_SCHEMA_VERSION 2
#define TLI_MAX_DIM 32          /* largest state dimension n */
#define TLI_MAX_BITS 64         /* most sensors, most modes (one 64-bit mask each) */
#define TLI_MAX_CUTS 64         /* most cuts per DS: the model's plus the online storage */
#define TLI_MAX_COMPONENTS 256  /* most GMM components per DS */
#define TLI_MAX_STALL_WINDOW 1000000L /* most control steps the stall rule looks back over */

/* status codes (0 = ok) */
enum {
    TLI_OK = 0,
    TLI_E_IO = 1,        /* file cannot be read */
    TLI_E_FORMAT = 2,    /* malformed or truncated text form */
    TLI_E_VERSION = 3,   /* not a tli-policy-text file of this schema version */
    TLI_E_HASH = 4,      /* the sha256 line is not the hash of the body */
    TLI_E_SIZE = 5,      /* a count beyond the header or beyond the limits above */
    TLI_E_NUMBER = 6,    /* a number is not finite, or a matrix is not valid (P not SPD ...) */
    TLI_E_ARG = 7,       /* bad argument: NULL, non-finite state, unknown sensor bit */
    TLI_E_FULL = 8,      /* add_cut: the fixed cut storage of a DS of the mode is full */
    TLI_E_CUT = 9,       /* add_cut: normal not unit, or x* of a DS of the mode not inside */
    TLI_E_STATE = 10     /* decide/velocity before reset */
};

/* tli_step_info.flags */
#define TLI_F_MODE_CHANGE 1u   /* the mode changed this step */
#define TLI_F_REPLAN 2u        /* ... to a mode other than the planned next one */
#define TLI_F_FAILURE 4u       /* invariance failure: a cut is due (triple below) */
#define TLI_F_ASSUMPTION 8u    /* the reading violates the environment assumptions */
#define TLI_F_HOLDING 16u      /* no automaton state matches: zero velocity */
#define TLI_F_DONE 32u         /* a goal mode (with the goal sensors true) */
#define TLI_F_PERTURBED 64u    /* the step was reported perturbed */
#define TLI_F_STALL 128u       /* the stall rule fired: the mode's DS converged (or is blocked)
                                  without the next reading; the predecessor's DS re-enters it */
#define TLI_F_REENTERED 256u   /* the re-entry ended: back to the stalled mode */

typedef struct tli_policy tli_policy;

typedef struct {
    int state;        /* automaton state id */
    int mode;         /* mode index (artifact's automaton.modes order) */
    int planned;      /* planned next mode index, -1 in a goal mode */
    int ds;           /* DS index run (artifact's ds order), -1 while holding */
    unsigned flags;   /* TLI_F_* */
    long steps;       /* control steps since reset */
    /* with TLI_F_FAILURE: the mode and DS that failed and (x^0, x^{T_f-1}, x^{T_f}) */
    int failed_mode;
    int failed_ds;
    double entry[TLI_MAX_DIM];
    double last_inside[TLI_MAX_DIM];
    double outside[TLI_MAX_DIM];
} tli_step_info;

/* Load and validate a text-form artifact. Returns TLI_OK and *out, or a code and a message
 * in err (always NUL-terminated when errlen > 0); *out is NULL on error. */
int tli_policy_load(const char *path, tli_policy **out, char *err, size_t errlen);
/* The same from a buffer (need not be NUL-terminated; only read during the call). */
int tli_policy_load_buffer(const char *data, size_t len, tli_policy **out, char *err,
                           size_t errlen);
void tli_policy_free(tli_policy *p);

int tli_policy_dim(const tli_policy *p);
int tli_policy_n_inputs(const tli_policy *p);
int tli_policy_n_modes(const tli_policy *p);
int tli_policy_n_ds(const tli_policy *p);
int tli_policy_ds_mode(const tli_policy *p, int ds);
int tli_policy_n_cuts(const tli_policy *p, int ds);
double tli_policy_dt(const tli_policy *p);
/* The artifact's content hash (64 hex digits + NUL): the JSON's content_sha256. */
const char *tli_policy_sha256(const tli_policy *p);

/* Start an episode at x0 (n doubles) with the first reading (bit i = sensor i). */
int tli_policy_reset(tli_policy *p, const double *x0, uint64_t reading, tli_step_info *info);
/* One control step, part 1: the automaton on the reading at x (perturbed: a perturbation
 * moved the state since the last step). Sets info (TLI_F_FAILURE: a cut is due). */
int tli_policy_decide(tli_policy *p, const double *x, uint64_t reading, int perturbed,
                      tli_step_info *info);
/* Part 2: M(x) f(x) of the DS chosen by the last decide, at its x (zero while holding). */
int tli_policy_velocity(tli_policy *p, double *v);
/* decide + velocity. */
int tli_policy_step(tli_policy *p, const double *x, uint64_t reading, int perturbed,
                    double *v, tli_step_info *info);
/* The next step follows a perturbation (as decide(..., perturbed=1)). */
void tli_policy_notify_perturbation(tli_policy *p);
/* Add a cut (unit normal w, point p; n doubles each) to the region of a mode: every DS of
 * the mode gets it (as Model.add_cut). Refused, nothing changed, with TLI_E_FULL when a DS
 * of the mode has no free slot, TLI_E_CUT when the normal is not unit (|norm-1| > 1e-6) or
 * the plane leaves a DS's x* on or outside it. */
int tli_policy_add_cut(tli_policy *p, int mode, const double *normal, const double *point,
                       char *err, size_t errlen);
/* Nominal f(x) of DS ds (no cuts), and M(x) f(x) with its cuts: for tests and tools. */
int tli_policy_ds_velocity(const tli_policy *p, int ds, const double *x, int modulate,
                           double *v);

/* SHA-256 of len bytes into out[32] (exported for tests). */
void tli_sha256(const void *data, size_t len, unsigned char out[32]);

#ifdef __cplusplus
}
#endif
#endif /* TLI_POLICY_H */
