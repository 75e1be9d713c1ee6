/* stability.h - numerical stability sweeps of the float reflection models (docs/models.md §5)
 * against a long double reference, plus the physics checks (monotonic Fresnel, directional
 * albedo <= 1 for the physically normalised models, and where ct1982 and the euclid norm
 * break it).
 *
 * Usage:
 *   stability_options o = {0};            zero = defaults (STABILITY_DEFAULT_SAMPLES per case)
 *   stability_table t;
 *   if (stability_run(&o, &t) != RC_OK) ...            only fails on bad options
 *   stability_write_csv(stdout, &t); stability_write_json(f, &t);
 *   cJSON *doc = stability_json(&t); ... cJSON_Delete(doc);    the same JSON as a document
 *   if (stability_failures(&t)) ...                    NaN/Inf/negative for finite input
 * The table is a plain struct (no heap); stability_run fills it completely.
 *
 * Reference: every row's reference re-evaluates the function's documented formula (its header
 * comment, guards and caps included) in long double from the very same float inputs, so the
 * difference is the float function's own error. On x86-64 long double has a 64-bit
 * significand: 40 bits beyond float, 11 beyond double; glibc's expl/powl/logl/erfl are
 * accurate to a few long double ulps, so the reference's own error is below 1e-9 float ulp
 * and 1e-2 double ulp (x 100 where exp/pow amplify, see stability_ref.c) - far below the
 * 0.5 ulp a correctly rounded result already has. MPFR is therefore not needed.
 * max_ulp is |result - reference| / ulp(reference) in the result's own precision (float
 * or double): 0.5 is a correctly rounded result. Rows of kind STABILITY_APPROX compare an
 * approximation with the exact physics (Schlick vs exact Fresnel, Smith Walter vs erf form);
 * for them max_abs is the meaningful figure, not the ulps.
 * Rows of kind STABILITY_PHYSICS carry a check: monotonicity, or an albedo / weight value.
 */
#ifndef REFLCHECK_STABILITY_H
#define REFLCHECK_STABILITY_H

#include <stdio.h>

#include <cJSON.h>

#include "status.h"

#define STABILITY_DEFAULT_SAMPLES 4000
#define STABILITY_MAX_SAMPLES     10000000
#define STABILITY_MAX_ROWS        256

typedef struct {
    int samples;     /* samples per sweep case; 0 = STABILITY_DEFAULT_SAMPLES */
    unsigned seed;   /* PRNG seed of the random part of each sweep; 0 = fixed default */
    int albedo_grid; /* albedo quadrature: grid x grid stratified samples; 0 = 96 */
    /* A user's model (scene/user_load.h) to sweep too, NULL = none: its rows (function
     * "user[NAME]") count NaN, Inf and negative outputs over grazing, peak and random inputs with
     * every parameter at its bounds, take the output at float-rounded directions (the
     * rasterizer's geometry) against the output at the exact directions (APPROX: the model's
     * sensitivity to float input, no long double form exists), and report its largest
     * directional albedo (not gated: a user's model need not conserve energy). */
    const struct reflcheck_user_model *user;
} stability_options;

typedef enum { STABILITY_ROUNDING, STABILITY_APPROX, STABILITY_PHYSICS } stability_kind;

typedef struct {
    char function[40];  /* e.g. "fresnel_schlick", "shade_eval[cook-torrance walter]" */
    char case_name[56]; /* the extreme swept, e.g. "cos->0 (grazing)" */
    stability_kind kind;
    int precision;       /* significand bits of the result: 24 float, 53 double; 0 physics */
    long samples;        /* evaluations (each RGB channel counts once) */
    double max_ulp;      /* ROUNDING: largest |f - ref| / ulp(ref) */
    double max_rel;      /* largest |f - ref| / |ref| (ref != 0) */
    double max_abs;      /* largest |f - ref| */
    char where[128];     /* the inputs of the largest ulp error (PHYSICS: of the value) */
    char where_abs[128]; /* the inputs of the largest absolute error */
    long nan, inf;       /* outputs that are NaN / Inf for finite input: must be 0 */
    long negative;       /* negative outputs where the exact value is >= 0: must be 0 */
    int check_ok;        /* PHYSICS: 1 holds, 0 broken (as documented or a bug), -1 n/a */
    int expect_ok;       /* PHYSICS: 1 the check gates (must hold), 0 reported break */
    double value;        /* PHYSICS: the albedo maximum, or the largest drop in ulps */
    double aux;          /* PHYSICS d3d9client rows: the smallest diffuse weight 1 - |lambda| */
    char note[200];      /* PHYSICS verdict or ROUNDING remark */
} stability_row;

typedef struct {
    int n_rows;
    int samples;       /* per case, as run */
    int ldbl_mant_dig; /* the reference's significand bits (64 on x86-64) */
    stability_row rows[STABILITY_MAX_ROWS];
} stability_table;

/* Runs every sweep and check. RC_ERR_RANGE for samples outside [16, STABILITY_MAX_SAMPLES]
 * or albedo_grid outside [8, 2048]; *out is filled only on RC_OK. Deterministic for a seed. */
rc_status stability_run(const stability_options *o, stability_table *out);

/* Rows that fail a gate: NaN, Inf, or a negative output for finite input, or a gating
 * physics check (expect_ok = 1) that does not hold. */
int stability_failures(const stability_table *t);

/* The first row whose function and case start with the given prefixes (NULL = any), or NULL. */
const stability_row *stability_find(const stability_table *t, const char *function, const char *case_prefix);

/* The table as a JSON document (cJSON, through core/jsonio): {"reference_mantissa_bits",
 * "samples", "failures", "rows": [{"function", "case", "kind", ...}]}, figures to 6 significant
 * digits, null where not finite. NULL when memory runs out; free with cJSON_Delete. */
cJSON *stability_json(const stability_table *t);

/* Writers: that JSON document, CSV with a header line, and a fixed-width text table for the
 * terminal. Return 0, or -1 on a write error (or no memory for the JSON). */
int stability_write_json(FILE *f, const stability_table *t);
int stability_write_csv(FILE *f, const stability_table *t);
int stability_write_text(FILE *f, const stability_table *t);

/* reflcheck stability [--json FILE] [--csv FILE] [--samples N]: prints the table, exits 1 if
 * any gate fails (also declared for cli/cli.c). */
int cli_stability(int argc, char **argv);

#endif
