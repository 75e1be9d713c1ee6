/* stability_sweep.h - what the stability files share; private to harness/stability*.c (the
 * public interface is stability.h).
 *
 * Usage (inside a sweep file):
 *   stability_row *row = stab_row_begin(s, "fresnel_schlick", "cos->0", STABILITY_ROUNDING, 24);
 *   for (int i = 0; i < s->n; i++) {
 *       float c = (float)stab_lsp(i, s->n, 1.4e-45, 0.1), f0 = (float)stab_rng_u(&s->r);
 *       ADD(row, fresnel_schlick(f0, c), stab_ref_schlick(f0, c), "F0=%.9g cos=%.9g", f0, c);
 *   }
 *   stab_row_end(row);
 *
 * The files, one job each: stability.c runs the sweeps in their fixed order (the rows' order and
 * the random stream depend on it); stability_rows.c the sample points and the row accumulator;
 * stability_ref.c the long double references; stability_sweeps.c the per-model sweeps;
 * stability_shade.c the whole-shader sweeps; stability_physics.c the physics checks;
 * stability_user.c a user's model; stability_output.c the JSON, CSV and text writers.
 */
#ifndef REFLCHECK_STABILITY_SWEEP_H
#define REFLCHECK_STABILITY_SWEEP_H

#include <math.h>
#include <stdint.h>
#include <stdio.h>

#include "cooktorrance.h"
#include "d3d9client.h"
#include "formula.h"
#include "scene.h"
#include "stability.h"
#include "user_load.h"
#include "vec.h"

typedef long double ld;
#define REF_PI FORMULA_PI_L

/* Long double vectors, for the references. */
typedef struct {
    ld x, y, z;
} ld3;

static inline ld3 l3(ld x, ld y, ld z)
{
    ld3 r = {x, y, z};
    return r;
}
static inline ld3 l3_from(vec3 a) { return l3(a.x, a.y, a.z); }
static inline ld3 l3_add(ld3 a, ld3 b) { return l3(a.x + b.x, a.y + b.y, a.z + b.z); }
static inline ld3 l3_sub(ld3 a, ld3 b) { return l3(a.x - b.x, a.y - b.y, a.z - b.z); }
static inline ld3 l3_mul(ld3 a, ld3 b) { return l3(a.x * b.x, a.y * b.y, a.z * b.z); }
static inline ld3 l3_scale(ld3 a, ld s) { return l3(a.x * s, a.y * s, a.z * s); }
static inline ld l3_dot(ld3 a, ld3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
static inline ld l3_len(ld3 a) { return sqrtl(l3_dot(a, a)); }
static inline ld3 l3_norm(ld3 a)
{
    ld l = l3_len(a);
    return l > 0 ? l3_scale(a, 1 / l) : l3(0, 0, 0);
}

/* The random stream of the sweeps (splitmix64) and one run's state. */
typedef struct {
    uint64_t s;
} rng;

typedef struct {
    stability_table *t;
    rng r;
    int n; /* samples per case */
} sweep;

/* Sample points (stability_rows.c). */
double stab_rng_u(rng *r);
double stab_rng_range(rng *r, double lo, double hi);
double stab_rng_log(rng *r, double lo, double hi);
/* i-th of n log-spaced values from lo to hi, both included. */
double stab_lsp(int i, int n, double lo, double hi);
vec3 stab_rng_dir_upper(rng *r, double cos_lo, double cos_hi);
/* Unit vector (in float) at polar cosine c from +Y, azimuth ph. */
vec3 stab_dir_at(double c, double ph);

/* The row accumulator (stability_rows.c): begin, add results (through ADD), end. */
stability_row *stab_row_begin(sweep *s, const char *fn, const char *cs, stability_kind kind, int precision);
void stab_row_end(stability_row *row);
ld stab_ulp_of(ld ref, int precision);
/* Adds one result; bit 1 of the answer: a new worst ulp error, bit 2: a new worst absolute one. */
int stab_row_add(stability_row *row, double got, ld ref);
/* 1 when the row fails a gate (stability_failures counts them). */
int stab_row_fails(const stability_row *r);

/* Records the inputs of the worst ulp and of the worst absolute error. */
#define ADD(row, got, ref, ...)                                                                                        \
    do {                                                                                                               \
        int w_ = stab_row_add((row), (got), (ref));                                                                    \
        if (w_ & 1)                                                                                                    \
            snprintf((row)->where, sizeof(row)->where, __VA_ARGS__);                                                   \
        if (w_ & 2)                                                                                                    \
            snprintf((row)->where_abs, sizeof(row)->where_abs, __VA_ARGS__);                                           \
    } while (0)

/* The long double references (stability_ref.c), each the documented formula of the function
 * of the same name. */
typedef struct {
    ld3 rgb, r_tot;
    ld alpha, weight;
} ref_d9;

typedef struct {
    ld3 diffuse, specular, reflection, emission;
    ld alpha;
} ref_terms;

ld stab_ref_clamp(ld x, ld lo, ld hi);
ld stab_ref_r0(ld n);
ld stab_ref_schlick(ld f0, ld c);
ld stab_ref_d3d9(ld r0, ld m, ld p, ld c);
ld stab_ref_dielectric(ld cos_i, ld eta);
ld stab_ref_conductor(ld cos_i, ld eta, ld k);
ld stab_ref_beckmann(ld c, ld m, ct_normalisation norm);
ld stab_ref_vcavity(ld nh, ld nv, ld nl, ld vh);
ld stab_ref_smith_g1_walter(ld c, ld m);
ld stab_ref_smith_g1_exact(ld c, ld m);
ld stab_ref_attenuation(const light *l, ld d);
ld stab_ref_spot(const light *l, ld3 dir);
ld stab_ref_lambert(ld n_l);
ld stab_ref_blinn(ld n_h, ld power);
ref_d9 stab_ref_d3d9client(const d3d9client_params *p, ld3 d, ld da, ld3 phi, ld n_v, ld n_sun);
ld3 stab_ref_ct_fresnel(const ct_params *p, ld c, const material *mat);
ld3 stab_ref_ct_specular(const ct_params *p, ld3 n, ld3 v, ld3 l, const material *mat);
/* The terms shade_eval returns, for one material at one point, in long double. */
void stab_ref_shade(const scene *sc, vec3 env_const, const material *m, vec3 xf, vec3 nf, vec3 vf, ref_terms *o);

/* The sweeps, in the order stability_run calls them; each appends its rows to s->t. */
void stab_sweep_fresnel(sweep *s);
void stab_sweep_microfacet(sweep *s);
void stab_sweep_d3d(sweep *s);
void stab_sweep_d3d9client(sweep *s);
void stab_sweep_cooktorrance(sweep *s);
void stab_sweep_shade(sweep *s);
void stab_sweep_unnormalised(sweep *s);
void stab_check_physics(sweep *s, int grid);
void stab_sweep_user(sweep *s, const reflcheck_user_model *um, int grid);

#endif
