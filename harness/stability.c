/* stability.c - sweeps of the float models against long double references (see stability.h).
 *
 * Each ref_* function restates one model function's documented formula, guards and caps in
 * long double, from the same float inputs. Where a formula cancels (1 - c, cos_i - eta cos_t)
 * the reference cancels in the same place, so its error grows by the same factor as the
 * function's; the ratio stays 2^-40 (float results) or 2^-11 (double results), which still
 * resolves 0.01 ulp. Sweeps mix log-spaced values of the extreme parameter with seeded
 * random values of the others, so a run is reproducible.
 */
#include "stability.h"

#include <float.h>
#include <math.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "cooktorrance.h"
#include "d3d.h"
#include "d3d9client.h"
#include "env.h"
#include "formula.h"
#include "fresnel.h"
#include "jsonio.h"
#include "microfacet.h"
#include "mesh.h"
#include "scene.h"
#include "shade.h"
#include "user_load.h"

typedef long double ld;
#define REF_PI FORMULA_PI_L

/* ------------------------------------------------------------------ long double vectors */

typedef struct {
    ld x, y, z;
} ld3;

static ld3 l3(ld x, ld y, ld z)
{
    ld3 r = {x, y, z};
    return r;
}
static ld3 l3_from(vec3 a) { return l3(a.x, a.y, a.z); }
static ld3 l3_add(ld3 a, ld3 b) { return l3(a.x + b.x, a.y + b.y, a.z + b.z); }
static ld3 l3_sub(ld3 a, ld3 b) { return l3(a.x - b.x, a.y - b.y, a.z - b.z); }
static ld3 l3_mul(ld3 a, ld3 b) { return l3(a.x * b.x, a.y * b.y, a.z * b.z); }
static ld3 l3_scale(ld3 a, ld s) { return l3(a.x * s, a.y * s, a.z * s); }
static ld l3_dot(ld3 a, ld3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
static ld l3_len(ld3 a) { return sqrtl(l3_dot(a, a)); }
static ld3 l3_norm(ld3 a)
{
    ld l = l3_len(a);
    return l > 0 ? l3_scale(a, 1 / l) : l3(0, 0, 0);
}

/* -------------------------------------------------------------------- reference formulas */

static ld ref_clamp(ld x, ld lo, ld hi) { return x < lo ? lo : (x > hi ? hi : x); }
static ld ref_satf(ld x) { return formula_sat_l(x); }

static ld ref_r0(ld n) { return formula_r0_l(n); }

static ld ref_schlick(ld f0, ld c) { return ref_satf(formula_schlick_l(f0, c)); }

static ld ref_d3d9(ld r0, ld m, ld p, ld c)
{
    return ref_satf(formula_d3d9_fresnel_l(r0, m, powl(formula_one_minus_cos_l(c), formula_d3d9_power_l(p))));
}

static ld ref_dielectric(ld cos_i, ld eta)
{
    if (!(eta > 0))
        return 1;
    if (cos_i < 0) {
        cos_i = -cos_i;
        eta = 1 / eta;
    }
    return formula_fresnel_dielectric_l(ref_clamp(cos_i, 0, 1), eta);
}

static ld ref_conductor(ld cos_i, ld eta, ld k)
{
    return formula_fresnel_conductor_l(ref_clamp(fabsl(cos_i), 0, 1), fabsl(eta), fabsl(k));
}

static ld ref_beckmann(ld c, ld m, ct_normalisation norm)
{
    if (c <= 0)
        return 0;
    if (c > 1)
        c = 1;
    if (m <= 0)
        return c >= 1 ? MICROFACET_D_MAX : 0;
    /* long double's exponent range (1e+-4932) holds m^2 and c^4 for every float m, c. */
    return formula_beckmann_d_l((1 - c) * (1 + c), c * c, 1 / (m * m),
                                formula_beckmann_log_norm_l(m, norm != CT_CT1982));
}

static ld ref_vcavity(ld nh, ld nv, ld nl, ld vh) { return formula_vcavity_g_l(nh, nv, nl, vh); }

static ld ref_smith_g1_walter(ld c, ld m) { return formula_smith_g1_walter_l(c, m); }

static ld ref_smith_g1_exact(ld c, ld m) { return formula_smith_g1_exact_l(c, m); }

static ld ref_attenuation(const light *l, ld d)
{
    if (l->kind == LIGHT_SUN)
        return 1;
    return formula_attenuation_l(l->a0, l->a1, l->a2, d, d * d, l->range);
}

static ld ref_spot(const light *l, ld3 dir)
{
    if (l->kind != LIGHT_SPOT)
        return 1;
    ld rho = l3_dot(l3_norm(l3_from(l->direction)), dir);
    ld cos_in = cosl((ld)l->inner / 2), cos_out = cosl((ld)l->outer / 2);
    ld cone = formula_spot_cone_l(cos_in, cos_out);
    if (l->profile == SPOT_SMOOTH)
        return formula_spot_smooth_l(rho, cos_in, cos_out, cone);
    return formula_spot_d3d_l(rho, cos_in, cos_out, cone, l->falloff);
}

static ld ref_lambert(ld n_l) { return formula_d3d_lambert_l(n_l); }

static ld ref_blinn(ld n_h, ld power) { return formula_blinn_l(n_h, power); }

/* d3d_half_vector: zero when |L + V| < 1e-6 (the function's documented threshold). */
static ld3 ref_half(ld3 l, ld3 v)
{
    ld3 s = l3_add(l3_norm(l), l3_norm(v));
    return l3_scale(s, formula_half_scale_l(l3_len(s)));
}

static ld ref_colour_norm(ld3 c, colour_norm norm)
{
    d3d9client_norm_weights w = d3d9client_norm_weights_of(norm);
    return formula_colour_norm_l(c.x, c.y, c.z, w.w_max, w.w_r, w.w_g, w.w_b, w.w_euclid);
}

typedef struct {
    ld3 rgb, r_tot;
    ld alpha, weight;
} ref_d9;

static ref_d9 ref_d3d9client(const d3d9client_params *p, ld3 d, ld da, ld3 phi, ld n_v, ld n_sun)
{
    ref_d9 r;
    ld R = ref_d3d9(p->r0, p->m, p->p, n_v);
    ld3 lam = l3_from(p->reflect), s = l3_from(p->fresnel_colour);
    r.r_tot = l3(formula_d3d9_r_tot_l(lam.x, s.x, R, phi.x), formula_d3d9_r_tot_l(lam.y, s.y, R, phi.y),
                 formula_d3d9_r_tot_l(lam.z, s.z, R, phi.z));
    r.weight = formula_d3d9_diffuse_weight_l(ref_colour_norm(lam, p->norm));
    ld dw = p->sun_angle ? r.weight * formula_d3d9_sun_factor_l(ref_d3d9(p->r0, p->m, p->p, n_sun)) : r.weight;
    r.rgb = l3(formula_d3d9_colour_l(d.x, dw, r.r_tot.x), formula_d3d9_colour_l(d.y, dw, r.r_tot.y),
               formula_d3d9_colour_l(d.z, dw, r.r_tot.z));
    r.alpha = formula_d3d9_alpha_l(da, ref_colour_norm(r.r_tot, p->norm));
    return r;
}

static ld3 ref_ct_fresnel(const ct_params *p, ld c, const material *mat)
{
    if (p->f == F_ONE)
        return l3(1, 1, 1);
    if (p->f == F_EXACT && mat) {
        if (mat->conductor)
            return l3(ref_conductor(c, mat->eta.x, mat->k.x), ref_conductor(c, mat->eta.y, mat->k.y),
                      ref_conductor(c, mat->eta.z, mat->k.z));
        ld f = ref_dielectric(c, mat->ior);
        return l3(f, f, f);
    }
    return l3(ref_schlick(p->f0.x, c), ref_schlick(p->f0.y, c), ref_schlick(p->f0.z, c));
}

static ld ref_ct_g(const ct_params *p, ld nh, ld nv, ld nl, ld vh)
{
    switch (p->g) {
    case G_SMITH_WALTER: return ref_smith_g1_walter(nv, p->m) * ref_smith_g1_walter(nl, p->m);
    case G_SMITH_EXACT: return ref_smith_g1_exact(nv, p->m) * ref_smith_g1_exact(nl, p->m);
    case G_VCAVITY:
    default: return ref_vcavity(nh, nv, nl, vh);
    }
}

static ld3 ref_ct_specular(const ct_params *p, ld3 n, ld3 v, ld3 l, const material *mat)
{
    ld3 nd = l3_norm(n), vd = l3_norm(v), lv = l3_norm(l);
    ld n_l = l3_dot(nd, lv), n_v = l3_dot(nd, vd);
    if (n_l <= 0 || n_v <= 0)
        return l3(0, 0, 0);
    n_l = formula_cos_floor_l(n_l);
    n_v = formula_cos_floor_l(n_v);
    ld3 hs = l3_add(lv, vd);
    ld hl = l3_len(hs);
    if (hl < (ld)FORMULA_HALF_MIN)
        return l3(0, 0, 0);
    ld3 h = l3_scale(hs, formula_half_scale_l(hl));
    ld n_h = l3_dot(nd, h), v_h = ref_clamp(l3_dot(vd, h), 0, 1);
    ld d = ref_beckmann(n_h, p->m, p->norm);
    ld g = ref_ct_g(p, n_h, n_v, n_l, v_h);
    ld3 r = l3_scale(l3_mul(l3_from(p->ks), ref_ct_fresnel(p, v_h, mat)),
                     formula_ct_lobe_l(d, g, formula_ct_k_l(p->norm != CT_CT1982), n_v));
    ld cap = COOKTORRANCE_MAX;
    return l3(ref_clamp(r.x, -cap, cap), ref_clamp(r.y, -cap, cap), ref_clamp(r.z, -cap, cap));
}

/* ------------------------------------------------------------------------- accumulation */

typedef struct {
    uint64_t s;
} rng;

static double rng_u(rng *r)
{
    /* splitmix64: tiny, seedable, good enough to scatter sweep points. */
    uint64_t z = (r->s += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    z ^= z >> 31;
    return (double)(z >> 11) * 0x1p-53;
}

static double rng_range(rng *r, double lo, double hi) { return lo + (hi - lo) * rng_u(r); }
static double rng_log(rng *r, double lo, double hi) { return lo * pow(hi / lo, rng_u(r)); }

/* i-th of n log-spaced values from lo to hi, both included. */
static double lsp(int i, int n, double lo, double hi)
{
    return n < 2 ? lo : lo * pow(hi / lo, (double)i / (double)(n - 1));
}

static vec3 rng_dir_upper(rng *r, double cos_lo, double cos_hi)
{
    double c = rng_range(r, cos_lo, cos_hi), ph = rng_range(r, 0.0, 2.0 * (double)REF_PI);
    double s = sqrt(fmax(0.0, 1.0 - c * c));
    return v3((float)(s * cos(ph)), (float)c, (float)(s * sin(ph)));
}

/* Unit vector (in float) at polar cosine c from +Y, azimuth ph. */
static vec3 dir_at(double c, double ph)
{
    double s = sqrt(fmax(0.0, (1.0 - c) * (1.0 + c)));
    return v3((float)(s * cos(ph)), (float)c, (float)(s * sin(ph)));
}

typedef struct {
    stability_table *t;
    rng r;
    int n; /* samples per case */
} sweep;

static stability_row *row_begin(sweep *s, const char *fn, const char *cs, stability_kind kind, int precision)
{
    stability_table *t = s->t;
    if (t->n_rows >= STABILITY_MAX_ROWS)
        abort(); /* a programming error: raise STABILITY_MAX_ROWS with the new rows */
    stability_row *row = &t->rows[t->n_rows++];
    memset(row, 0, sizeof *row);
    snprintf(row->function, sizeof row->function, "%s", fn);
    snprintf(row->case_name, sizeof row->case_name, "%s", cs);
    row->kind = kind;
    row->precision = precision;
    row->max_ulp = -1.0;
    row->max_abs = -1.0;
    row->check_ok = -1;
    row->expect_ok = 1;
    return row;
}

static void row_end(stability_row *row)
{
    if (row->max_ulp < 0.0)
        row->max_ulp = 0.0;
    if (row->max_abs < 0.0)
        row->max_abs = 0.0;
}

static ld ulp_of(ld ref, int precision)
{
    ld a = fabsl(ref);
    if (precision == 24) {
        if (a < (ld)FLT_MIN)
            return 0x1p-149L;
        if (a > (ld)FLT_MAX)
            a = FLT_MAX;
        return ldexpl(1.0L, ilogbl(a) - 23);
    }
    if (a < (ld)DBL_MIN)
        return 0x1p-1074L;
    if (a > (ld)DBL_MAX)
        a = DBL_MAX;
    return ldexpl(1.0L, ilogbl(a) - 52);
}

/* Adds one result; returns bit 1 for a new worst ulp error, bit 2 for a new worst absolute
 * error (the caller then records the inputs). Sweeps only pass finite inputs, so a NaN or
 * Inf result is always counted. */
static int row_add(stability_row *row, double got, ld ref)
{
    row->samples++;
    if (isnan(got)) {
        row->nan++;
        return 0;
    }
    if (isinf(got)) {
        row->inf++;
        return 0;
    }
    if (got < 0.0 && ref >= 0)
        row->negative++;
    ld diff = fabsl((ld)got - ref);
    double u = (double)(diff / ulp_of(ref, row->precision));
    double ab = (double)diff;
    /* Relative error only where the reference is a normal number of the result's type:
     * below that the result is denormal or 0 by design and the ulp figure says it all. */
    if (fabsl(ref) >= (row->precision == 24 ? (ld)FLT_MIN : (ld)DBL_MIN)) {
        double rel = (double)(diff / fabsl(ref));
        if (rel > row->max_rel)
            row->max_rel = rel;
    }
    int worst = 0;
    if (u > row->max_ulp) {
        row->max_ulp = u;
        worst |= 1;
    }
    if (ab > row->max_abs) {
        row->max_abs = ab;
        worst |= 2;
    }
    return worst;
}

/* Records the inputs of the worst ulp and of the worst absolute error. */
#define ADD(row, got, ref, ...)                                                                                        \
    do {                                                                                                               \
        int w_ = row_add((row), (got), (ref));                                                                         \
        if (w_ & 1)                                                                                                    \
            snprintf((row)->where, sizeof(row)->where, __VA_ARGS__);                                                   \
        if (w_ & 2)                                                                                                    \
            snprintf((row)->where_abs, sizeof(row)->where_abs, __VA_ARGS__);                                           \
    } while (0)

/* ------------------------------------------------------------------------ Fresnel sweeps */

static void sweep_fresnel(sweep *s)
{
    int n = s->n;
    stability_row *row;

    row = row_begin(s, "fresnel_r0_from_ior", "n->1 (1 +- 2^-23..0.1)", STABILITY_ROUNDING, 24);
    for (int i = 0; i < n; i++) {
        float ior = (float)(1.0 + (i % 2 ? -1.0 : 1.0) * lsp(i / 2, n / 2, 0x1p-23, 0.1));
        ADD(row, fresnel_r0_from_ior(ior), ref_r0(ior), "n=%.9g", ior);
    }
    row_end(row);
    row = row_begin(s, "fresnel_r0_from_ior", "n->inf (1..FLT_MAX)", STABILITY_ROUNDING, 24);
    for (int i = 0; i < n; i++) {
        float ior = (float)lsp(i, n, 1.0, FLT_MAX);
        ADD(row, fresnel_r0_from_ior(ior), ref_r0(ior), "n=%.9g", ior);
    }
    row_end(row);
    row = row_begin(s, "fresnel_r0_from_ior", "n->0+ (denormal..1)", STABILITY_ROUNDING, 24);
    for (int i = 0; i < n; i++) {
        float ior = (float)lsp(i, n, 1.4e-45, 1.0);
        ADD(row, fresnel_r0_from_ior(ior), ref_r0(ior), "n=%.9g", ior);
    }
    row_end(row);

    struct {
        const char *name;
        double c_lo, c_hi;
        int near_one;
        double f_lo, f_hi;
        int f_log;
    } sc[] = {
        {"cos->0 (denormal..0.1)", 1.4e-45, 0.1, 0, 0.0, 1.0, 0},
        {"cos->1 (1-2^-24..0.9)", 0x1p-24, 0.1, 1, 0.0, 1.0, 0},
        {"F0->0 (n->1, 1e-38..1e-2)", 1e-3, 1.0, 0, 1e-38, 1e-2, 1},
        {"F0->1 (n->inf)", 1e-3, 1.0, 0, 0.999, 1.0, 0},
        {"bad input F0 in [-10,10]", 1e-3, 1.0, 0, -10.0, 10.0, 0},
    };
    for (size_t k = 0; k < sizeof sc / sizeof sc[0]; k++) {
        row = row_begin(s, "fresnel_schlick", sc[k].name, STABILITY_ROUNDING, 24);
        for (int i = 0; i < n; i++) {
            double cv = k < 2 ? lsp(i, n, sc[k].c_lo, sc[k].c_hi) : rng_range(&s->r, sc[k].c_lo, sc[k].c_hi);
            float c = (float)(sc[k].near_one ? 1.0 - cv : cv);
            float f0 =
                (float)(sc[k].f_log ? lsp(i, n, sc[k].f_lo, sc[k].f_hi) : rng_range(&s->r, sc[k].f_lo, sc[k].f_hi));
            ADD(row, fresnel_schlick(f0, c), ref_schlick(f0, c), "F0=%.9g cos=%.9g", f0, c);
        }
        row_end(row);
    }

    struct {
        const char *name;
        int mode;
    } dc[] = {
        {"p->0 (1e-6..0.1)", 0},      {"p>=1e4 (1e4..1e7)", 1},   {"cos->0 (denormal..0.1)", 2},
        {"cos->1 (1-2^-24..0.9)", 3}, {"bad input R0>1, m<0", 4}, {"huge R0, m (saturation)", 5},
    };
    for (size_t k = 0; k < sizeof dc / sizeof dc[0]; k++) {
        row = row_begin(s, "fresnel_d3d9", dc[k].name, STABILITY_ROUNDING, 24);
        for (int i = 0; i < n; i++) {
            float r0 = (float)rng_range(&s->r, 0.0, 0.25), m = 1.0f - r0;
            float p = (float)rng_range(&s->r, 0.5, 8.0), c = (float)rng_u(&s->r);
            switch (dc[k].mode) {
            case 0: p = (float)lsp(i, n, 1e-6, 0.1); break;
            case 1:
                p = (float)lsp(i, n, 1e4, 1e7);
                c = (float)rng_log(&s->r, 1e-8, 1e-2);
                break;
            case 2: c = (float)lsp(i, n, 1.4e-45, 0.1); break;
            case 3: c = (float)(1.0 - lsp(i, n, 0x1p-24, 0.1)); break;
            case 4:
                r0 = (float)rng_range(&s->r, 1.0, 100.0);
                m = (float)rng_range(&s->r, -100.0, 0.0);
                break;
            default:
                r0 = (float)((i % 2 ? -1 : 1) * lsp(i, n, 1e30, FLT_MAX));
                m = (float)((i % 3 ? 1 : -1) * lsp(n - 1 - i, n, 1e30, FLT_MAX));
                break;
            }
            ADD(row, fresnel_d3d9(r0, m, p, c), ref_d3d9(r0, m, p, c), "R0=%.9g m=%.9g p=%.9g cos=%.9g", r0, m, p, c);
        }
        row_end(row);
    }

    /* The double exact references, judged in double ulps. */
    row = row_begin(s, "fresnel_dielectric", "cos->0 (1e-300..0.1)", STABILITY_ROUNDING, 53);
    for (int i = 0; i < n; i++) {
        double c = lsp(i, n, 1e-300, 0.1), eta = rng_range(&s->r, 1.01, 3.0);
        if (i % 2)
            eta = 1.0 / eta;
        ADD(row, fresnel_dielectric(c, eta), ref_dielectric(c, eta), "cos=%.17g eta=%.17g", c, eta);
    }
    row_end(row);
    row = row_begin(s, "fresnel_dielectric", "n->1 (1 +- 1e-15..1e-2)", STABILITY_ROUNDING, 53);
    for (int i = 0; i < n; i++) {
        double eta = 1.0 + (i % 2 ? -1.0 : 1.0) * lsp(i / 2, n / 2, 1e-15, 1e-2), c = rng_u(&s->r);
        ADD(row, fresnel_dielectric(c, eta), ref_dielectric(c, eta), "cos=%.17g eta=%.17g", c, eta);
    }
    row_end(row);
    row = row_begin(s, "fresnel_dielectric", "n->inf (1e3..1e150), n->0", STABILITY_ROUNDING, 53);
    for (int i = 0; i < n; i++) {
        double eta = lsp(i / 2, n / 2, 1e3, 1e150), c = rng_u(&s->r);
        if (i % 2)
            eta = 1.0 / eta;
        ADD(row, fresnel_dielectric(c, eta), ref_dielectric(c, eta), "cos=%.17g eta=%.17g", c, eta);
    }
    row_end(row);
    row = row_begin(s, "fresnel_dielectric", "near total internal reflection", STABILITY_ROUNDING, 53);
    for (int i = 0; i < n; i++) {
        double eta = 1.0 / 1.5, cc = sqrt(1.0 - eta * eta);
        double c = cc + (i % 2 ? -1.0 : 1.0) * lsp(i / 2, n / 2, 1e-16, 1e-2);
        ADD(row, fresnel_dielectric(c, eta), ref_dielectric(c, eta), "cos=%.17g eta=%.17g", c, eta);
    }
    row_end(row);
    row = row_begin(s, "fresnel_conductor", "cos->0, eta/k 1e-3..1e3", STABILITY_ROUNDING, 53);
    for (int i = 0; i < n; i++) {
        double c = i % 2 ? lsp(i / 2, n / 2, 1e-300, 0.1) : rng_u(&s->r);
        double eta = rng_log(&s->r, 1e-3, 1e3), k = rng_log(&s->r, 1e-3, 1e3);
        ADD(row, fresnel_conductor(c, eta, k), ref_conductor(c, eta, k), "cos=%.17g eta=%.9g k=%.9g", c, eta, k);
    }
    row_end(row);

    /* Approximation error against the exact dielectric (Figure 1's numbers). */
    struct {
        const char *fn;
        double ior, p;
    } ap[] = {
        {"schlick p=5 vs exact", 1.33, 5.0}, {"schlick p=5 vs exact", 1.5, 5.0}, {"schlick p=5 vs exact", 2.4, 5.0},
        {"d3d9 p=2 vs exact", 1.5, 2.0},     {"d3d9 p=4 vs exact", 1.5, 4.0},
    };
    for (size_t k = 0; k < sizeof ap / sizeof ap[0]; k++) {
        char cs[56];
        snprintf(cs, sizeof cs, "n=%.3g, angle 0..90 deg", ap[k].ior);
        row = row_begin(s, ap[k].fn, cs, STABILITY_APPROX, 24);
        float r0 = fresnel_r0_from_ior((float)ap[k].ior);
        for (int i = 0; i < n; i++) {
            double deg = 90.0 * i / (n - 1);
            float c = (float)cos(deg * (double)REF_PI / 180.0);
            float f = fresnel_d3d9(r0, 1.0f - r0, (float)ap[k].p, c);
            ADD(row, f, ref_dielectric(c, ap[k].ior), "angle=%.4g deg", deg);
        }
        row_end(row);
    }
}

/* -------------------------------------------------------------------- microfacet sweeps */

static void sweep_microfacet(sweep *s)
{
    int n = s->n;
    stability_row *row;
    static const char *dname[2] = {"microfacet_beckmann_d[walter]", "microfacet_beckmann_d[ct1982]"};
    struct {
        const char *name;
        int mode;
    } bc[] = {
        {"cos_h->0 (denormal..0.1)", 0},
        {"cos_h->1 (1-2^-24..0.9)", 1},
        {"m->0 (1e-6..1e-2)", 2},
        {"m->inf (1..1e3)", 3},
        {"denormal m", 4},
    };
    for (int norm = 0; norm < 2; norm++) {
        ct_normalisation cn = norm ? CT_CT1982 : CT_WALTER;
        for (size_t k = 0; k < sizeof bc / sizeof bc[0]; k++) {
            row = row_begin(s, dname[norm], bc[k].name, STABILITY_ROUNDING, 24);
            for (int i = 0; i < n; i++) {
                float c = (float)rng_u(&s->r), m = (float)rng_log(&s->r, 0.01, 1.0);
                switch (bc[k].mode) {
                case 0:
                    c = (float)lsp(i, n, 1.4e-45, 0.1);
                    m = (float)rng_log(&s->r, 1.0, 1e3);
                    break;
                case 1:
                    c = (float)(1.0 - lsp(i, n, 0x1p-24, 0.1));
                    m = (float)rng_log(&s->r, 1e-6, 1.0);
                    break;
                case 2:
                    m = (float)lsp(i, n, 1e-6, 1e-2);
                    c = (float)cos(rng_range(&s->r, 0.0, 5.0 * m)); /* inside the lobe */
                    break;
                case 3: m = (float)lsp(i, n, 1.0, 1e3); break;
                default:
                    m = (float)lsp(i, n, 1.4e-45, 1e-38);
                    c = (float)(1.0 - rng_log(&s->r, 1e-8, 1.0));
                    break;
                }
                ADD(row, microfacet_beckmann_d(c, m, cn), ref_beckmann(c, m, cn), "cos_h=%.9g m=%.9g", c, m);
            }
            row_end(row);
        }
    }

    struct {
        const char *name;
        int mode;
    } vc[] = {
        {"V.H->0 (denormal..1e-3)", 0},
        {"cos->0 (N.V, N.L)", 1},
        {"random unit-vector geometry", 2},
    };
    for (size_t k = 0; k < sizeof vc / sizeof vc[0]; k++) {
        row = row_begin(s, "microfacet_vcavity_g", vc[k].name, STABILITY_ROUNDING, 24);
        for (int i = 0; i < n; i++) {
            float nh = (float)rng_u(&s->r), nv = (float)rng_u(&s->r), nl = (float)rng_u(&s->r),
                  vh = (float)rng_u(&s->r);
            if (vc[k].mode == 0) {
                vh = (float)lsp(i, n, 1.4e-45, 1e-3);
            } else if (vc[k].mode == 1) {
                nv = (float)lsp(i, n, 1.4e-45, 0.1);
                nl = (float)rng_log(&s->r, 1.4e-45, 0.1);
            } else {
                vec3 nn = v3(0, 1, 0), v = rng_dir_upper(&s->r, -0.2, 1.0), l = rng_dir_upper(&s->r, -0.2, 1.0);
                vec3 h = v3_norm(v3_add(v, l));
                nh = v3_dot(nn, h);
                nv = v3_dot(nn, v);
                nl = v3_dot(nn, l);
                vh = v3_dot(v, h);
            }
            ADD(row, microfacet_vcavity_g(nh, nv, nl, vh), ref_vcavity(nh, nv, nl, vh),
                "nh=%.9g nv=%.9g nl=%.9g vh=%.9g", nh, nv, nl, vh);
        }
        row_end(row);
    }

    struct {
        const char *name;
        int mode;
    } sc[] = {
        {"cos->0 (denormal..0.1)", 0}, {"cos->1 (1-2^-24..0.9)", 1}, {"m->0 (1e-6..1e-2)", 2},
        {"m->inf (1..1e3)", 3},        {"a near 1.6 (branch)", 4},
    };
    for (int exact = 0; exact < 2; exact++) {
        for (size_t k = 0; k < sizeof sc / sizeof sc[0]; k++) {
            row = row_begin(s, exact ? "microfacet_smith_g1_exact" : "microfacet_smith_g1_walter", sc[k].name,
                            STABILITY_ROUNDING, exact ? 53 : 24);
            for (int i = 0; i < n; i++) {
                float c = (float)rng_u(&s->r), m = (float)rng_log(&s->r, 0.01, 1.0);
                switch (sc[k].mode) {
                case 0: c = (float)lsp(i, n, 1.4e-45, 0.1); break;
                case 1: c = (float)(1.0 - lsp(i, n, 0x1p-24, 0.1)); break;
                case 2:
                    m = (float)lsp(i, n, 1e-6, 1e-2);
                    c = (float)rng_log(&s->r, 1e-8, 1.0);
                    break;
                case 3: m = (float)lsp(i, n, 1.0, 1e3); break;
                default: {
                    /* 1/(m tan) = 1.6 +- a little: tan = 1/(1.6 m) */
                    double t = 1.0 / (1.6 * m) * (1.0 + rng_range(&s->r, -1e-6, 1e-6));
                    c = (float)(1.0 / sqrt(1.0 + t * t));
                    break;
                }
                }
                if (exact)
                    ADD(row, microfacet_smith_g1_exact(c, m), ref_smith_g1_exact(c, m), "cos=%.9g m=%.9g", c, m);
                else
                    ADD(row, microfacet_smith_g1_walter(c, m), ref_smith_g1_walter(c, m), "cos=%.9g m=%.9g", c, m);
            }
            row_end(row);
        }
    }
    row = row_begin(s, "smith G1 walter vs exact", "m 0.01..1, all angles", STABILITY_APPROX, 24);
    for (int i = 0; i < n; i++) {
        float c = (float)rng_u(&s->r), m = (float)rng_log(&s->r, 0.01, 1.0);
        ADD(row, microfacet_smith_g1_walter(c, m), ref_smith_g1_exact(c, m), "cos=%.9g m=%.9g", c, m);
    }
    row_end(row);
}

/* ------------------------------------------------------------------------- D3D sweeps */

static void sweep_d3d(sweep *s)
{
    int n = s->n;
    stability_row *row;
    struct {
        const char *name;
        int mode;
    } bc[] = {
        {"P->0 (1e-6..0.1)", 0},
        {"P>=1e4 (1e4..1e7)", 1},
        {"N.H->0 (denormal..0.1)", 2},
        {"N.H->1 (1-2^-24..0.9)", 3},
    };
    for (size_t k = 0; k < sizeof bc / sizeof bc[0]; k++) {
        row = row_begin(s, "d3d_blinn", bc[k].name, STABILITY_ROUNDING, 24);
        for (int i = 0; i < n; i++) {
            float nh = (float)rng_u(&s->r), p = (float)rng_log(&s->r, 1.0, 128.0);
            switch (bc[k].mode) {
            case 0: p = (float)lsp(i, n, 1e-6, 0.1); break;
            case 1:
                p = (float)lsp(i, n, 1e4, 1e7);
                nh = (float)(1.0 - rng_log(&s->r, 1e-8, 1e-2));
                break;
            case 2:
                nh = (float)lsp(i, n, 1.4e-45, 0.1);
                p = (float)rng_log(&s->r, 1e-3, 4.0);
                break;
            default:
                nh = (float)(1.0 - lsp(i, n, 0x1p-24, 0.1));
                p = (float)rng_log(&s->r, 1.0, 1e4);
                break;
            }
            ADD(row, d3d_blinn(nh, p), ref_blinn(nh, p), "N.H=%.9g P=%.9g", nh, p);
        }
        row_end(row);
    }

    row = row_begin(s, "d3d_lambert", "N.L over [-1,1], denormal", STABILITY_ROUNDING, 24);
    for (int i = 0; i < n; i++) {
        float nl = i % 2 ? (float)rng_range(&s->r, -1.0, 1.0) : (float)lsp(i, n, 1.4e-45, 1.0);
        ADD(row, d3d_lambert(nl), ref_lambert(nl), "N.L=%.9g", nl);
    }
    row_end(row);

    struct {
        const char *name;
        int mode;
    } ac[] = {
        {"d->0 (denormal..1e-3)", 0},
        {"d->inf (1e3..FLT_MAX)", 1},
        {"a0=a1=a2=0", 2},
        {"random a, range", 3},
    };
    for (size_t k = 0; k < sizeof ac / sizeof ac[0]; k++) {
        row = row_begin(s, "d3d_attenuation", ac[k].name, STABILITY_ROUNDING, 24);
        for (int i = 0; i < n; i++) {
            light l;
            light_init(&l);
            float d = (float)rng_log(&s->r, 1e-3, 1e3);
            switch (ac[k].mode) {
            case 0:
                d = (float)lsp(i, n, 1.4e-45, 1e-3);
                l.a0 = (float)(i % 3 == 0 ? 0.0 : rng_u(&s->r));
                break;
            case 1:
                d = (float)lsp(i, n, 1e3, FLT_MAX);
                l.a1 = (float)(i % 2 ? rng_u(&s->r) : 0.0);
                break;
            case 2:
                l.a0 = l.a1 = l.a2 = 0.0f;
                d = (float)rng_log(&s->r, 1.4e-45, FLT_MAX);
                break;
            default:
                l.a0 = (float)rng_u(&s->r);
                l.a1 = (float)rng_u(&s->r);
                l.a2 = (float)rng_u(&s->r);
                l.range = (float)rng_log(&s->r, 1e-2, 1e4);
                break;
            }
            ADD(row, d3d_attenuation(&l, d), ref_attenuation(&l, d), "d=%.9g a=(%.3g,%.3g,%.3g)", d, l.a0, l.a1, l.a2);
        }
        row_end(row);
    }

    struct {
        const char *fn;
        spot_profile prof;
        const char *name;
        int mode;
    } pc[] = {
        {"d3d_spot[d3d]", SPOT_D3D, "rho near outer edge", 0},
        {"d3d_spot[d3d]", SPOT_D3D, "rho near inner edge", 1},
        {"d3d_spot[d3d]", SPOT_D3D, "falloff 0..1e4, random rho", 2},
        {"d3d_spot[smooth]", SPOT_SMOOTH, "rho near outer edge", 0},
        {"d3d_spot[smooth]", SPOT_SMOOTH, "rho near inner edge", 1},
        {"d3d_spot[smooth]", SPOT_SMOOTH, "random cones, rho", 2},
    };
    for (size_t k = 0; k < sizeof pc / sizeof pc[0]; k++) {
        row = row_begin(s, pc[k].fn, pc[k].name, STABILITY_ROUNDING, 24);
        for (int i = 0; i < n; i++) {
            light l;
            light_init(&l);
            l.kind = LIGHT_SPOT;
            l.profile = pc[k].prof;
            l.direction = rng_dir_upper(&s->r, -1.0, 1.0);
            l.inner = (float)rng_range(&s->r, 0.05, 2.0);
            l.outer = l.inner + (float)rng_range(&s->r, 0.01, 1.0);
            l.falloff = (float)rng_range(&s->r, 0.5, 4.0);
            double half;
            if (pc[k].mode == 0)
                half = 0.5 * (double)l.outer * (1.0 - (i % 2 ? -1 : 1) * lsp(i / 2, n / 2, 1e-7, 1e-2));
            else if (pc[k].mode == 1)
                half = 0.5 * (double)l.inner * (1.0 + (i % 2 ? -1 : 1) * lsp(i / 2, n / 2, 1e-7, 1e-2));
            else {
                half = rng_range(&s->r, 0.0, 0.5 * (double)l.outer * 1.1);
                l.falloff = (float)(i % 2 ? lsp(i, n, 1e-6, 1e4) : rng_range(&s->r, 0.0, 8.0));
            }
            /* A unit vector at angle `half` from the axis. */
            ld3 ax = l3_norm(l3_from(l.direction));
            ld3 perp = l3_norm(fabsl(ax.x) < 0.9L ? l3(0, ax.z, -ax.y) : l3(-ax.z, 0, ax.x));
            ld3 dir = l3_add(l3_scale(ax, cosl(half)), l3_scale(perp, sinl(half)));
            vec3 df = v3((float)dir.x, (float)dir.y, (float)dir.z);
            ADD(row, d3d_spot(&l, df), ref_spot(&l, l3_from(df)), "half-angle=%.9g inner=%.6g outer=%.6g falloff=%.6g",
                half, l.inner, l.outer, l.falloff);
        }
        row_end(row);
    }
}

/* ---------------------------------------------------------------- D3D9Client combine */

static void sweep_d3d9client(sweep *s)
{
    int n = s->n;
    static const char *nname[4] = {"max", "mean", "luminance", "euclid"};
    struct {
        const char *name;
        int mode;
    } cc[] = {
        {"grazing N.V (denormal..0.1)", 0}, {"HDR phi and d up to 1e6", 1},
        {"sun angle (8), N.L->0", 2},       {"p->0 and p>=1e4", 3},
        {"bright lambda (euclid < 0)", 4},
    };
    for (size_t k = 0; k < sizeof cc / sizeof cc[0]; k++) {
        stability_row *row = row_begin(s, "d3d9client_combine", cc[k].name, STABILITY_ROUNDING, 24);
        for (int i = 0; i < n; i++) {
            material mat;
            material_init(&mat);
            d3d9client_params *p = &mat.d9;
            p->norm = (colour_norm)(i % 4);
            p->r0 = fresnel_r0_from_ior((float)rng_range(&s->r, 1.0, 3.0));
            p->m = 1.0f - p->r0;
            p->p = (float)rng_range(&s->r, 1.0, 5.0);
            p->reflect = v3((float)rng_u(&s->r), (float)rng_u(&s->r), (float)rng_u(&s->r));
            vec3 d = v3((float)rng_u(&s->r), (float)rng_u(&s->r), (float)rng_u(&s->r));
            vec3 phi = v3((float)rng_u(&s->r), (float)rng_u(&s->r), (float)rng_u(&s->r));
            float nv = (float)rng_u(&s->r), nsun = (float)rng_u(&s->r), da = (float)rng_u(&s->r);
            switch (cc[k].mode) {
            case 0: nv = (float)lsp(i, n, 1.4e-45, 0.1); break;
            case 1:
                phi = v3_scale(phi, (float)lsp(i, n, 1.0, 1e6));
                d = v3_scale(d, (float)rng_log(&s->r, 1e-6, 1e6));
                break;
            case 2:
                p->sun_angle = 1;
                nsun = (float)lsp(i, n, 1.4e-45, 0.1);
                break;
            case 3: p->p = (float)(i % 2 ? lsp(i, n, 1e-6, 0.1) : lsp(i, n, 1e4, 1e7)); break;
            default: p->reflect = v3s((float)rng_range(&s->r, 0.8, 1.0)); break;
            }
            d3d9client_result r;
            d3d9client_combine(p, d, da, phi, nv, nsun, &r);
            ref_d9 e = ref_d3d9client(p, l3_from(d), da, l3_from(phi), nv, nsun);
            const float got[4] = {r.rgb.x, r.rgb.y, r.rgb.z, r.alpha};
            const ld want[4] = {e.rgb.x, e.rgb.y, e.rgb.z, e.alpha};
            static const char *what[4] = {"rgb.r", "rgb.g", "rgb.b", "alpha"};
            for (int j = 0; j < 4; j++)
                ADD(row, got[j], want[j], "%s norm=%s N.V=%.9g N.sun=%.9g p=%.6g d=%.6g phi=%.6g", what[j],
                    nname[p->norm], nv, nsun, p->p, d.x, phi.x);
        }
        row_end(row);
    }
}

/* -------------------------------------------------------------- Cook-Torrance specular */

static void ct_variant(int i, ct_params *p, material *mat)
{
    static const ct_geometry gs[3] = {G_VCAVITY, G_SMITH_WALTER, G_SMITH_EXACT};
    static const ct_fresnel fs[3] = {F_SCHLICK, F_EXACT, F_EXACT};
    p->g = gs[i % 3];
    p->f = fs[(i / 3) % 3];
    mat->conductor = (i / 3) % 3 == 2;
    mat->eta = v3(0.18f, 0.42f, 1.37f); /* gold-like complex index, per channel */
    mat->k = v3(3.42f, 2.35f, 1.77f);
    p->ks = v3(1.0f, 0.9f, 0.8f);
}

static void sweep_cooktorrance(sweep *s)
{
    int n = s->n;
    static const char *gname[3] = {"vcavity", "smith-walter", "smith-exact"};
    struct {
        const char *name;
        int mode;
    } cc[] = {
        {"grazing view (N.V denormal..0.1)", 0},
        {"grazing light (N.L->0)", 1},
        {"V.H->0 (L ~ -V)", 2},
        {"N.L < 0", 3},
        {"m->0 (1e-6..1e-2)", 4},
        {"m->inf (1..1e3)", 5},
        {"zero-length / denormal normal", 6},
        {"random geometry", 7},
    };
    for (int norm = 0; norm < 2; norm++) {
        for (size_t k = 0; k < sizeof cc / sizeof cc[0]; k++) {
            stability_row *row = row_begin(s, norm ? "cooktorrance_specular[ct1982]" : "cooktorrance_specular[walter]",
                                           cc[k].name, STABILITY_ROUNDING, 24);
            for (int i = 0; i < n; i++) {
                material mat;
                material_init(&mat);
                ct_params *p = &mat.ct;
                p->norm = norm ? CT_CT1982 : CT_WALTER;
                ct_variant(i, p, &mat);
                p->m = (float)rng_log(&s->r, 0.05, 1.0);
                vec3 nn = v3(0, 1, 0);
                vec3 v = rng_dir_upper(&s->r, 0.0, 1.0), l = rng_dir_upper(&s->r, 0.0, 1.0);
                double ph = rng_range(&s->r, 0.0, 2.0 * (double)REF_PI);
                switch (cc[k].mode) {
                case 0: v = dir_at(lsp(i, n, 1.4e-45, 0.1), ph); break;
                case 1: l = dir_at(lsp(i, n, 1.4e-45, 0.1), ph); break;
                case 2: {
                    /* L close to -V: both graze, |L + V| from 1e-8 to 1e-2 */
                    double e = lsp(i, n, 1e-8, 1e-2);
                    v = dir_at(0.5 * e, ph);
                    l = dir_at(0.5 * e, ph + (double)REF_PI - e);
                    break;
                }
                case 3: l = rng_dir_upper(&s->r, -1.0, 0.0); break;
                case 4: {
                    p->m = (float)lsp(i, n, 1e-6, 1e-2);
                    /* L near the mirror direction of V, within a few m, so D is not 0 */
                    double th = rng_range(&s->r, 0.0, 1.3), dth = rng_range(&s->r, -3.0, 3.0) * p->m;
                    v = dir_at(cos(th), ph);
                    l = dir_at(cos(th + dth), ph + (double)REF_PI + rng_range(&s->r, -3.0, 3.0) * p->m);
                    break;
                }
                case 5: p->m = (float)lsp(i, n, 1.0, 1e3); break;
                case 6: nn = i % 2 ? v3s(0.0f) : v3(0.0f, (float)lsp(i, n, 1.4e-45, 1e-38), 0.0f); break;
                default:
                    v = rng_dir_upper(&s->r, -0.1, 1.0);
                    l = rng_dir_upper(&s->r, -0.1, 1.0);
                    break;
                }
                vec3 got = cooktorrance_specular(p, nn, v, l, &mat);
                ld3 want = ref_ct_specular(p, l3_from(nn), l3_from(v), l3_from(l), &mat);
                const float g3[3] = {got.x, got.y, got.z};
                const ld w3[3] = {want.x, want.y, want.z};
                for (int j = 0; j < 3; j++)
                    ADD(row, g3[j], w3[j], "ch%d G=%s F=%s m=%.6g N.V=%.6g N.L=%.6g", j, gname[p->g],
                        p->f == F_SCHLICK ? "schlick"
                        : mat.conductor   ? "conductor"
                                          : "dielectric",
                        p->m, v3_dot(v3_norm(nn), v), v3_dot(v3_norm(nn), l));
            }
            row_end(row);
        }
    }
    stability_row *row =
        row_begin(s, "cooktorrance_reflection_weight", "N.V denormal..1, all F", STABILITY_ROUNDING, 24);
    for (int i = 0; i < n; i++) {
        material mat;
        material_init(&mat);
        ct_variant(i, &mat.ct, &mat);
        mat.ct.f0 = v3((float)rng_u(&s->r), (float)rng_u(&s->r), (float)rng_u(&s->r));
        float nv = (float)(i % 2 ? lsp(i, n, 1.4e-45, 1.0) : rng_range(&s->r, -1.0, 1.0));
        vec3 got = cooktorrance_reflection_weight(&mat.ct, nv, &mat);
        ld3 want = ref_ct_fresnel(&mat.ct, ref_clamp(nv, 0, 1), &mat);
        ADD(row, got.x, want.x, "N.V=%.9g", nv);
        ADD(row, got.y, want.y, "N.V=%.9g", nv);
        ADD(row, got.z, want.z, "N.V=%.9g", nv);
    }
    row_end(row);
}

/* ----------------------------------------------------------------------- shade_eval */

typedef struct {
    ld3 diffuse, specular, reflection, emission;
    ld alpha;
} ref_terms;

static int ref_light_incident(const light *l, ld3 x, ld3 *to_l, ld3 *e_perp)
{
    if (l->kind == LIGHT_SUN) {
        *to_l = l3_scale(l3_norm(l3_from(l->direction)), -1);
        *e_perp = l3_from(l->intensity);
        return 1;
    }
    ld3 d = l3_sub(l3_from(l->position), x);
    ld dist = l3_len(d);
    if (!(dist > 0))
        return 0;
    *to_l = l3_scale(d, 1 / dist);
    ld a = ref_attenuation(l, dist) * ref_spot(l, l3_scale(*to_l, -1));
    *e_perp = l3_scale(l3_from(l->intensity), a);
    return a > 0;
}

static void ref_shade(const scene *sc, vec3 env_const, const material *m, vec3 xf, vec3 nf, vec3 vf, ref_terms *o)
{
    ld3 x = l3_from(xf), n = l3_from(nf), v = l3_from(vf);
    const d3d_params *d = &m->d3d;
    ld3 diffuse = l3(0, 0, 0), spec = l3(0, 0, 0);
    ld3 eye = l3_from(sc->camera.eye), e_inf = l3_norm(l3_sub(eye, l3_from(sc->camera.target)));
    memset(o, 0, sizeof *o);
    o->alpha = 1;
    if (m->model == MODEL_COOK_TORRANCE) {
        ld3 kd = l3(formula_lambert_brdf_l(m->albedo.x), formula_lambert_brdf_l(m->albedo.y),
                    formula_lambert_brdf_l(m->albedo.z));
        for (int i = 0; i < sc->n_lights; i++) {
            ld3 to_l, e;
            if (!ref_light_incident(&sc->lights[i], x, &to_l, &e))
                continue;
            ld n_l = l3_dot(n, to_l);
            if (n_l <= 0)
                continue;
            diffuse = l3_add(diffuse, l3_scale(l3_mul(kd, e), n_l));
            spec = l3_add(spec, l3_mul(ref_ct_specular(&m->ct, n, v, to_l, m), e));
        }
        o->diffuse = diffuse;
        o->specular = spec;
        ld3 refl = l3_sub(l3_scale(n, 2 * l3_dot(n, v)), v);
        if (m->ct.reflection && l3_dot(refl, refl) > 0)
            o->reflection = l3_mul(l3_from(env_const), ref_ct_fresnel(&m->ct, ref_clamp(l3_dot(n, v), 0, 1), m));
        o->emission = l3_from(d->emissive);
        return;
    }
    /* D3D (also the lit diffuse of D3D9Client); clamp is off in every sweep. */
    diffuse = l3_mul(l3_from(d->ambient), l3_from(sc->global_ambient));
    for (int i = 0; i < sc->n_lights; i++) {
        const light *l = &sc->lights[i];
        ld3 to_l, e;
        if (!ref_light_incident(l, x, &to_l, &e))
            continue;
        ld atten = l->kind == LIGHT_SUN
                       ? 1
                       : ref_attenuation(l, l3_len(l3_sub(l3_from(l->position), x))) * ref_spot(l, l3_scale(to_l, -1));
        diffuse = l3_add(diffuse, l3_scale(l3_mul(l3_from(d->ambient), l3_from(l->ambient)), atten));
        ld n_l = l3_dot(n, to_l);
        if (n_l <= 0)
            continue;
        ld3 colour = l3_scale(e, 1 / REF_PI);
        diffuse = l3_add(diffuse, l3_scale(l3_mul(l3_from(d->diffuse), colour), ref_lambert(n_l)));
        ld3 h = ref_half(to_l, d->local_viewer ? v : e_inf);
        spec = l3_add(spec, l3_scale(l3_mul(l3_from(d->specular), colour), ref_blinn(l3_dot(n, h), d->power)));
    }
    o->diffuse = diffuse;
    o->specular = spec;
    o->emission = l3_from(d->emissive);
    if (m->model != MODEL_D3D9CLIENT)
        return;
    ld3 refl = l3_sub(l3_scale(n, 2 * l3_dot(n, v)), v);
    ld3 phi = l3_dot(refl, refl) > 0 ? l3_from(env_const) : l3(0, 0, 0);
    ld n_sun = 0;
    if (m->d9.sun_angle && sc->n_lights > 0) {
        const light *sun = &sc->lights[0];
        for (int i = 0; i < sc->n_lights; i++)
            if (sc->lights[i].kind == LIGHT_SUN) {
                sun = &sc->lights[i];
                break;
            }
        ld3 to_l, e;
        if (ref_light_incident(sun, x, &to_l, &e))
            n_sun = l3_dot(n, to_l);
    }
    ref_d9 r = ref_d3d9client(&m->d9, diffuse, m->d9.alpha, phi, l3_dot(n, v), n_sun);
    o->diffuse = l3_sub(r.rgb, r.r_tot);
    o->reflection = r.r_tot;
    o->alpha = r.alpha;
}

/* shade_eval_n on a batch of one lane: the batch kernel's answer for one input. */
static void shade_eval_one_lane(const shade_context *ctx, const shade_plan *plan, vec3 x, vec3 n, vec3 v,
                                shade_terms *t)
{
    shade_batch_in in;
    shade_batch_out out;
    in.n = 1;
    shade_batch_set_input(&in, 0, x, n, v);
    shade_eval_n(ctx, plan, &in, &out);
    shade_batch_get_terms(&out, 0, t);
}

static void shade_material(int model, material *m)
{
    material_init(m);
    m->albedo = v3(0.8f, 0.6f, 0.3f);
    m->d3d.diffuse = m->albedo;
    m->d3d.specular = v3(0.9f, 0.7f, 0.5f);
    m->d3d.ambient = v3(0.2f, 0.1f, 0.05f);
    m->d3d.emissive = v3(0.01f, 0.02f, 0.03f);
    m->d3d.power = 32.0f;
    switch (model) {
    case 0: m->model = MODEL_D3D; break;
    case 1:
        m->model = MODEL_D3D9CLIENT;
        m->d9.reflect = v3(0.9f, 0.6f, 0.2f);
        m->d9.sun_angle = 1;
        break;
    default:
        m->model = MODEL_COOK_TORRANCE;
        m->ct.norm = model == 2 ? CT_WALTER : CT_CT1982;
        m->ct.g = model == 2 ? G_SMITH_EXACT : G_VCAVITY;
        m->ct.f = model == 2 ? F_EXACT : F_SCHLICK;
        m->ct.m = 0.2f;
        break;
    }
}

static void sweep_shade(sweep *s)
{
    int n = s->n;
    static const char *mname[4] = {"shade_eval[d3d]", "shade_eval[d3d9client]", "shade_eval[ct walter smith F-exact]",
                                   "shade_eval[ct ct1982 vcavity schlick]"};
    /* The SIMD batch kernels the shading loop runs (shade_batch.c), on the same inputs; the
     * exact Smith G and Fresnel have none (shade_batch_ct_supported). */
    static const char *bname[4] = {"shade_eval_n[d3d]", "shade_eval_n[d3d9client]", NULL,
                                   "shade_eval_n[ct ct1982 vcavity schlick]"};
    static const char *tname[5] = {"diffuse", "specular", "reflection", "emission", "alpha"};
    struct {
        const char *name;
        int mode;
    } cc[] = {
        {"grazing view (N.V denormal..0.1)", 0}, {"grazing light (N.L->0)", 1},          {"N.L < 0", 2},
        {"light distance->0 (1e-30..1e-3)", 3},  {"light distance->inf (1e3..1e30)", 4}, {"a0=a1=a2=0", 5},
        {"HDR intensity, env 1e6", 6},           {"zero-length / denormal normal", 7},   {"m->0 or P->0 / P>=1e4", 8},
        {"random lights (point/sun/spot)", 9},
    };
    scene *sc = malloc(sizeof *sc);
    if (!sc)
        abort();
    for (int model = 0; model < 4; model++) {
        for (size_t k = 0; k < sizeof cc / sizeof cc[0]; k++) {
            stability_row *row = row_begin(s, mname[model], cc[k].name, STABILITY_ROUNDING, 24);
            stability_row *brow =
                bname[model] != NULL ? row_begin(s, bname[model], cc[k].name, STABILITY_ROUNDING, 24) : NULL;
            for (int i = 0; i < n; i++) {
                scene_init(sc);
                sc->camera.eye = v3(0.3f, 1.7f, 4.1f);
                sc->global_ambient = v3(0.05f, 0.04f, 0.03f);
                material *m = &sc->materials[0];
                shade_material(model, m);
                sc->n_materials = 1;
                sc->n_lights = 1;
                light *l = &sc->lights[0];
                l->intensity = v3(10.0f, 8.0f, 6.0f);
                l->ambient = v3(0.1f, 0.1f, 0.1f);
                vec3 env_c = v3(0.5f, 0.6f, 0.7f);
                vec3 x =
                    v3((float)rng_range(&s->r, -1, 1), (float)rng_range(&s->r, -1, 1), (float)rng_range(&s->r, -1, 1));
                vec3 nn = v3(0, 1, 0);
                double ph = rng_range(&s->r, 0.0, 2.0 * (double)REF_PI);
                vec3 v = rng_dir_upper(&s->r, 0.0, 1.0);
                vec3 ldir = rng_dir_upper(&s->r, 0.0, 1.0);
                double dist = rng_log(&s->r, 0.1, 10.0);
                switch (cc[k].mode) {
                case 0: v = dir_at(lsp(i, n, 1.4e-45, 0.1), ph); break;
                case 1: ldir = dir_at(lsp(i, n, 1.4e-45, 0.1), ph); break;
                case 2: ldir = rng_dir_upper(&s->r, -1.0, 0.0); break;
                case 3:
                    dist = lsp(i, n, 1e-30, 1e-3);
                    x = v3s(0.0f);
                    break;
                case 4:
                    dist = lsp(i, n, 1e3, 1e30);
                    x = v3s(0.0f);
                    break;
                case 5: l->a0 = l->a1 = l->a2 = 0.0f; break;
                case 6:
                    l->intensity = v3_scale(l->intensity, (float)lsp(i, n, 1.0, 1e5));
                    env_c = v3_scale(env_c, (float)lsp(n - 1 - i, n, 1.0, 1.4e6));
                    break;
                case 7: nn = i % 2 ? v3s(0.0f) : v3(0.0f, (float)lsp(i, n, 1.4e-45, 1e-38), 0.0f); break;
                case 8:
                    m->ct.m = (float)lsp(i, n, 1e-6, 1e-2);
                    m->d3d.power = (float)(i % 2 ? lsp(i, n, 1e-6, 0.1) : lsp(i, n, 1e4, 1e7));
                    m->d9.p = m->d3d.power;
                    /* light near V's mirror direction, so the narrow lobes are hit */
                    ldir = v3_reflect(v, v3_norm(v3_add(nn, v3((float)rng_range(&s->r, -0.01, 0.01), 0.0f,
                                                               (float)rng_range(&s->r, -0.01, 0.01)))));
                    break;
                default:
                    l->kind = (light_kind)(i % 3);
                    l->direction = rng_dir_upper(&s->r, -1.0, -0.2);
                    l->inner = (float)rng_range(&s->r, 0.3, 1.5);
                    l->outer = l->inner + (float)rng_range(&s->r, 0.05, 0.5);
                    l->profile = (spot_profile)(i % 2);
                    l->a0 = (float)rng_u(&s->r);
                    l->a1 = (float)rng_u(&s->r);
                    ldir = rng_dir_upper(&s->r, -0.2, 1.0);
                    break;
                }
                l->position = v3_add(x, v3_scale(ldir, (float)dist));
                if (l->kind == LIGHT_SPOT)
                    l->direction = v3_norm(v3_add(v3_neg(ldir), v3((float)rng_range(&s->r, -0.3, 0.3), 0.0f, 0.0f)));
                if (l->kind == LIGHT_SUN)
                    l->direction = v3_neg(ldir);
                env_map env = {.kind = ENV_CONSTANT, .constant = env_c, .scale = v3s(1.0f)};
                shade_context ctx;
                shade_context_make(sc, &env, &ctx);
                shade_plan plan;
                shade_plan_make(&ctx, m, &plan);
                shade_terms t[2];
                shade_eval(&ctx, &plan, x, nn, v, &t[0]);
                if (brow != NULL)
                    shade_eval_one_lane(&ctx, &plan, x, nn, v, &t[1]);
                ref_terms e;
                ref_shade(sc, env_c, m, x, nn, v, &e);
                const ld3 ev[4] = {e.diffuse, e.specular, e.reflection, e.emission};
                for (int b = 0; b < (brow != NULL ? 2 : 1); b++) {
                    stability_row *r = b ? brow : row;
                    const vec3 gv[4] = {t[b].diffuse, t[b].specular, t[b].reflection, t[b].emission};
                    for (int j = 0; j < 4; j++) {
                        const float g3[3] = {gv[j].x, gv[j].y, gv[j].z};
                        const ld w3[3] = {ev[j].x, ev[j].y, ev[j].z};
                        for (int c = 0; c < 3; c++)
                            ADD(r, g3[c], w3[c], "%s.%c N.V=%.6g N.L=%.6g d=%.6g I=%.3g env=%.3g m=%.3g P=%.3g",
                                tname[j], "rgb"[c], v3_dot(nn, v), v3_dot(nn, ldir), dist, l -> intensity.x, env_c.x,
                                m->ct.m, m->d3d.power);
                    }
                    ADD(r, t[b].alpha, e.alpha, "alpha N.V=%.6g", v3_dot(nn, v));
                }
            }
            row_end(row);
            if (brow != NULL)
                row_end(brow);
        }
    }
    free(sc);
}

/* D3DRS_NORMALIZENORMALS off under scale (seed 003), the stiff case of scaled meshes: an object
 * scaled by 10 (D3D's normal a tenth long: N.L and N.H shrink) and by 0.1 (ten times long: both
 * pass 1 and D3D's clamp to [0, 1] must hold them). Each scale also varies per axis by up to
 * 2x and the rotation is random, so the length 1/|S R^T n| (mesh_normal_length_of, float) is
 * checked against its long double value, and the D3D shading (scalar and SIMD lane) on that
 * float normal against the long double model on the same input. */
static void sweep_unnormalised(sweep *s)
{
    static const struct {
        const char *name;
        double scale;
    } sc_case[] = {{"normalize_normals false, scale 10", 10.0}, {"normalize_normals false, scale 0.1", 0.1}};
    static const char *tname[4] = {"diffuse", "specular", "reflection", "emission"};
    int n = s->n;
    scene *sc = malloc(sizeof *sc);
    if (!sc)
        abort();
    for (size_t k = 0; k < sizeof sc_case / sizeof *sc_case; k++) {
        stability_row *lrow = row_begin(s, "mesh_normal_length_of", sc_case[k].name, STABILITY_ROUNDING, 24);
        stability_row *row = row_begin(s, "shade_eval[d3d]", sc_case[k].name, STABILITY_ROUNDING, 24);
        stability_row *brow = row_begin(s, "shade_eval_n[d3d]", sc_case[k].name, STABILITY_ROUNDING, 24);
        for (int i = 0; i < n; i++) {
            scene_init(sc);
            sc->camera.eye = v3(0.3f, 1.7f, 4.1f);
            sc->global_ambient = v3(0.05f, 0.04f, 0.03f);
            material *m = &sc->materials[0];
            shade_material(0, m);
            m->d3d.normalize_normals = 0;
            m->d3d.power = (float)rng_log(&s->r, 1.0, 1e4);
            sc->n_materials = 1;
            object *o = &sc->objects[0];
            o->scale = v3((float)(sc_case[k].scale * rng_log(&s->r, 0.5, 2.0)),
                          (float)(sc_case[k].scale * rng_log(&s->r, 0.5, 2.0)),
                          (float)(sc_case[k].scale * rng_log(&s->r, 0.5, 2.0)));
            o->rotate = v3((float)rng_range(&s->r, -3.2, 3.2), (float)rng_range(&s->r, -3.2, 3.2),
                           (float)rng_range(&s->r, -3.2, 3.2));
            sc->n_objects = 1;
            sc->n_lights = 1;
            light *l = &sc->lights[0];
            l->kind = (light_kind)(i % 3);
            l->intensity = v3(10.0f, 8.0f, 6.0f);
            l->ambient = v3(0.1f, 0.1f, 0.1f);
            vec3 x = v3((float)rng_range(&s->r, -1, 1), (float)rng_range(&s->r, -1, 1), (float)rng_range(&s->r, -1, 1));
            /* A unit world normal in any direction, the viewer on its side (as the shading loop
             * turns it), the light anywhere around. */
            vec3 ax = rng_dir_upper(&s->r, -1.0, 1.0), v = rng_dir_upper(&s->r, -1.0, 1.0);
            if (v3_dot(ax, v) < 0.0f)
                v = v3_neg(v);
            vec3 ldir = rng_dir_upper(&s->r, -1.0, 1.0);
            l->position = v3_add(x, v3_scale(ldir, (float)rng_log(&s->r, 0.1, 10.0)));
            l->direction = v3_neg(ldir);
            l->inner = 1.0f;
            l->outer = 2.0f;

            mesh_normal_length nl;
            mesh_normal_length_make(o, &nl);
            float len = mesh_normal_length_of(&nl, ax);
            /* Long double: 1/|S R^T n| with R from the same Euler angles (Rz Ry Rx). */
            ld cx = cosl(o->rotate.x), sx = sinl(o->rotate.x), cy = cosl(o->rotate.y), sy = sinl(o->rotate.y);
            ld cz = cosl(o->rotate.z), sz = sinl(o->rotate.z);
            ld r[3][3] = {{cz * cy, cz * sy * sx - sz * cx, cz * sy * cx + sz * sx},
                          {sz * cy, sz * sy * sx + cz * cx, sz * sy * cx - cz * sx},
                          {-sy, cy * sx, cy * cx}};
            ld3 a = l3_from(ax);
            ld rt[3] = {r[0][0] * a.x + r[1][0] * a.y + r[2][0] * a.z, r[0][1] * a.x + r[1][1] * a.y + r[2][1] * a.z,
                        r[0][2] * a.x + r[1][2] * a.y + r[2][2] * a.z};
            ld3 srt = l3(o->scale.x * rt[0], o->scale.y * rt[1], o->scale.z * rt[2]);
            ADD(lrow, len, 1 / l3_len(srt), "scale=(%.4g,%.4g,%.4g)", o->scale.x, o->scale.y, o->scale.z);

            vec3 nn = v3_scale(ax, len);
            shade_context ctx;
            shade_context_make(sc, NULL, &ctx);
            shade_plan plan;
            shade_plan_make(&ctx, m, &plan);
            shade_terms t[2];
            shade_eval(&ctx, &plan, x, nn, v, &t[0]);
            shade_eval_one_lane(&ctx, &plan, x, nn, v, &t[1]);
            ref_terms e;
            ref_shade(sc, v3s(0.0f), m, x, nn, v, &e);
            const ld3 ev[4] = {e.diffuse, e.specular, e.reflection, e.emission};
            for (int b = 0; b < 2; b++) {
                stability_row *rw = b ? brow : row;
                const vec3 gv[4] = {t[b].diffuse, t[b].specular, t[b].reflection, t[b].emission};
                for (int j = 0; j < 4; j++) {
                    const float g3[3] = {gv[j].x, gv[j].y, gv[j].z};
                    const ld w3[3] = {ev[j].x, ev[j].y, ev[j].z};
                    for (int c = 0; c < 3; c++)
                        ADD(rw, g3[c], w3[c], "%s.%c |N|=%.6g N.L=%.6g P=%.6g light %d", tname[j], "rgb"[c], v3_len(nn),
                            v3_dot(nn, ldir), m -> d3d.power, (int)l->kind);
                }
            }
        }
        row_end(lrow);
        row_end(row);
        row_end(brow);
    }
    free(sc);
}

/* -------------------------------------------------------------------- physics checks */

/* Largest decrease, in ulps of the result's precision, of f over increasing angle. Near
 * normal incidence f is flat (neighbouring angles differ by less than one ulp), so a
 * decrease up to tol_ulp = twice the function's own rounding error (measured by the sweeps:
 * 0.5 ulp for the float functions, < 4 ulp for fresnel_dielectric away from n -> 1) is
 * evaluation noise, not a violation. */
typedef double (*fresnel_of_cos)(double c, const void *arg);

static double fr_dielectric(double c, const void *arg) { return fresnel_dielectric(c, *(const double *)arg); }
static double fr_conductor(double c, const void *arg)
{
    const double *a = arg;
    return fresnel_conductor(c, a[0], a[1]);
}
static double fr_schlick(double c, const void *arg) { return fresnel_schlick((float)*(const double *)arg, (float)c); }
static double fr_d3d9(double c, const void *arg)
{
    const double *a = arg;
    return fresnel_d3d9((float)a[0], (float)(1.0 - a[0]), (float)a[1], (float)c);
}

static void check_monotonic(sweep *s, const char *fn, const char *cs, fresnel_of_cos f, const void *arg, int precision,
                            double tol_ulp, int gate, const char *why, int steps)
{
    stability_row *row = row_begin(s, fn, cs, STABILITY_PHYSICS, 0);
    double prev = f(1.0, arg), worst = 0.0, worst_deg = 0.0;
    long viol = 0;
    for (int i = 1; i <= steps; i++) {
        double deg = 90.0 * i / steps;
        double c =
            precision == 24 ? (double)(float)cos(deg * (double)REF_PI / 180.0) : cos(deg * (double)REF_PI / 180.0);
        double cur = f(c, arg);
        row->samples++;
        if (isnan(cur))
            row->nan++;
        if (isinf(cur))
            row->inf++;
        double drop = (prev - cur) / (double)ulp_of(prev, precision);
        if (drop > worst) {
            worst = drop;
            worst_deg = deg;
        }
        if (drop > tol_ulp)
            viol++;
        prev = cur;
    }
    row->check_ok = viol == 0;
    row->expect_ok = gate;
    row->value = worst;
    snprintf(row->where, sizeof row->where, "largest drop at %.4g deg", worst_deg);
    snprintf(row->note, sizeof row->note, "%s: %ld decreases > %.3g ulp over %d angles; largest %.3g ulp%s%s",
             viol ? "NOT monotonic" : "monotonic", viol, tol_ulp, steps, worst, why ? "; " : "", why ? why : "");
}

/* Directional albedo of cooktorrance_specular (which includes N.L) at view angle theta_o,
 * by Beckmann importance sampling of H on a stratified grid x grid of cell centres:
 * estimate = mean of spec(L) / pdf(L), pdf(L) = D_walter(H) (N.H) / (4 V.H). Samples whose
 * L falls below the surface or whose V.H <= 0 add 0 (the lobe is 0 there). */
static double ct_albedo(const material *mat, double theta_o, int grid)
{
    double m = mat->ct.m, sum = 0.0;
    double inv_m2 = 1.0 / (m * m), log_norm = formula_beckmann_log_norm_d(m, 1);
    vec3 nn = v3(0, 1, 0);
    dvec3 v = dv3(sin(theta_o), cos(theta_o), 0.0);
    vec3 vf = v3_from_d(v);
    for (int i = 0; i < grid; i++) {
        double u1 = (i + 0.5) / grid;
        double tan2 = -m * m * log(1.0 - u1);
        double ch = 1.0 / sqrt(1.0 + tan2), sh = sqrt(tan2) * ch;
        for (int j = 0; j < grid; j++) {
            double ph = 2.0 * (double)REF_PI * (j + 0.5) / grid;
            dvec3 h = dv3(sh * cos(ph), ch, sh * sin(ph));
            double vh = dv3_dot(v, h);
            if (vh <= 0.0)
                continue;
            dvec3 l = dv3_sub(dv3_scale(h, 2.0 * vh), v);
            if (l.y <= 0.0)
                continue;
            /* The sampled density: (4.12) with Walter's normalisation. */
            double d = formula_beckmann_d_d(sh * sh, ch * ch, inv_m2, log_norm);
            double pdf = d * ch / (4.0 * vh);
            vec3 f = cooktorrance_specular(&mat->ct, nn, vf, v3_from_d(l), mat);
            sum += (double)f.x / pdf;
        }
    }
    return sum / ((double)grid * grid);
}

static const double albedo_ms[] = {0.05, 0.1, 0.2, 0.3, 0.5, 0.75, 1.0};
static const double albedo_tiny_ms[] = {1e-4, 1e-3, 1e-2};

static void check_albedo_ct(sweep *s, int grid, const char *fn, ct_normalisation norm, ct_geometry g, ct_fresnel f,
                            int gate, double tol, const double *ms, size_t n_ms, const char *why)
{
    static const double th[] = {0, 15, 30, 45, 60, 70, 80, 85, 89};
    char cs[56];
    snprintf(cs, sizeof cs, "max directional albedo, m %.3g..%.3g", ms[0], ms[n_ms - 1]);
    stability_row *row = row_begin(s, fn, cs, STABILITY_PHYSICS, 0);
    material mat;
    material_init(&mat);
    mat.ct.norm = norm;
    mat.ct.g = g;
    mat.ct.f = f;
    mat.ior = 1.5f;
    double worst = -1.0, wm = 0, wt = 0;
    for (size_t a = 0; a < n_ms; a++) {
        mat.ct.m = (float)ms[a];
        for (size_t b = 0; b < sizeof th / sizeof th[0]; b++) {
            double al = ct_albedo(&mat, th[b] * (double)REF_PI / 180.0, grid);
            row->samples++;
            if (isnan(al))
                row->nan++;
            if (al > worst) {
                worst = al;
                wm = ms[a];
                wt = th[b];
            }
        }
    }
    row->value = worst;
    row->check_ok = worst <= 1.0 + tol;
    row->expect_ok = gate;
    snprintf(row->where, sizeof row->where, "m=%.3g view=%.3g deg", wm, wt);
    snprintf(row->note, sizeof row->note, "albedo max %.6f (limit 1 + %.0e quadrature tolerance): %s%s%s", worst, tol,
             row->check_ok ? "energy conserving"
             : gate        ? "VIOLATION"
                           : "breaks energy conservation",
             why ? "; " : "", why ? why : "");
}

static void check_physics(sweep *s, int grid)
{
    int steps = s->n * 10;
    /* The exact unpolarised reflectance is monotonic only for n < 2 + sqrt(3) = 3.732 (and for
     * n < 1 up to total internal reflection): beyond, Rp's Brewster zero pulls the average
     * below R0 (at n = 10 down to 0.48 from 0.67 near 84 deg). So n <= 3.7 gates, 10 and 1000
     * are reported. n = 1.0001 is reported too: the rs/rp differences cancel as n -> 1 (see
     * the n->1 rounding row), which is numerical noise of ~1e4 ulp on a 2.5e-9 reflectance. */
    static const struct {
        double n;
        int gate;
        const char *why;
    } iors[] = {
        {1.0001, 0, "numerical: rs, rp cancel as n -> 1"},
        {1.33, 1, NULL},
        {1.5, 1, NULL},
        {2.4, 1, NULL},
        {3.7, 1, NULL},
        {1.0 / 1.5, 1, NULL},
        {10.0, 0, "physical: n > 2+sqrt(3) dips below R0"},
        {1000.0, 0, "physical: n > 2+sqrt(3) dips below R0"},
    };
    for (size_t i = 0; i < sizeof iors / sizeof iors[0]; i++) {
        char cs[56];
        snprintf(cs, sizeof cs, "monotonic in angle, n=%.5g", iors[i].n);
        check_monotonic(s, "fresnel_dielectric", cs, fr_dielectric, &iors[i].n, 53, 8.0, iors[i].gate, iors[i].why,
                        steps);
    }
    static const double f0s[] = {0.0, 0.02, 0.04, 0.5, 1.0};
    for (size_t i = 0; i < sizeof f0s / sizeof f0s[0]; i++) {
        char cs[56];
        snprintf(cs, sizeof cs, "monotonic in angle, F0=%.3g", f0s[i]);
        check_monotonic(s, "fresnel_schlick", cs, fr_schlick, &f0s[i], 24, 1.0, 1, NULL, steps);
    }
    static const double d9[][2] = {{0.04, 2.0}, {0.04, 4.0}, {0.04, 1e-3}, {0.25, 1e4}};
    for (size_t i = 0; i < sizeof d9 / sizeof d9[0]; i++) {
        char cs[56];
        snprintf(cs, sizeof cs, "monotonic in angle, R0=%.3g p=%.3g", d9[i][0], d9[i][1]);
        check_monotonic(s, "fresnel_d3d9", cs, fr_d3d9, d9[i], 24, 1.0, 1, NULL, steps);
    }
    /* Conductors are not monotonic in general (a shallow dip near grazing for large k):
     * reported, not gated. */
    static const double cd[][2] = {{0.18, 3.42}, {1.2, 7.0}, {2.9, 3.0}};
    for (size_t i = 0; i < sizeof cd / sizeof cd[0]; i++) {
        char cs[56];
        snprintf(cs, sizeof cs, "monotonic in angle, n=%.3g+%.3gi", cd[i][0], cd[i][1]);
        check_monotonic(s, "fresnel_conductor", cs, fr_conductor, cd[i], 53, 8.0, 0,
                        "physical: conductors dip before grazing", steps);
    }

    /* Lambert: a white Lambert surface reflects everything. Midpoint rule in mu = cos theta,
     * exact for the linear integrand mu / pi. */
    stability_row *row = row_begin(s, "microfacet_lambert_brdf", "white albedo (rho = 1)", STABILITY_PHYSICS, 0);
    double sum = 0.0;
    for (int i = 0; i < grid; i++)
        sum += microfacet_lambert_brdf(1.0) * ((i + 0.5) / grid) * 2.0 * (double)REF_PI / grid;
    row->samples = grid;
    row->value = sum;
    row->check_ok = fabs(sum - 1.0) < 1e-12; /* rounding of grid additions only */
    snprintf(row->note, sizeof row->note, "albedo %.15f", sum);

    /* Quadrature tolerance: against a 1536^2 grid, the 96^2 estimate differs by at most 5e-4
     * for the Smith rows with m >= 0.05 (4.5e-3 for V-cavity at m = 1, 89 deg, reported only).
     * Where the albedo comes close to 1 (normal view, small m) every sample weight G V.H /
     * (N.V N.H) = G <= 1, so the estimate itself cannot exceed 1 there. 1e-3 = 2x margin. */
    double tol = 1e-3;
    size_t nm = sizeof albedo_ms / sizeof albedo_ms[0], nt = sizeof albedo_tiny_ms / sizeof albedo_tiny_ms[0];
    check_albedo_ct(s, grid, "albedo ct walter smith-exact F=1", CT_WALTER, G_SMITH_EXACT, F_ONE, 1, tol, albedo_ms, nm,
                    NULL);
    check_albedo_ct(s, grid, "albedo ct walter smith-walter F=1", CT_WALTER, G_SMITH_WALTER, F_ONE, 1, tol, albedo_ms,
                    nm, NULL);
    check_albedo_ct(s, grid, "albedo ct walter smith-exact F n=1.5", CT_WALTER, G_SMITH_EXACT, F_EXACT, 1, tol,
                    albedo_ms, nm, NULL);
    check_albedo_ct(s, grid, "albedo ct walter vcavity F=1", CT_WALTER, G_VCAVITY, F_ONE, 0, tol, albedo_ms, nm, NULL);
    check_albedo_ct(s, grid, "albedo ct1982 vcavity F=1", CT_CT1982, G_VCAVITY, F_ONE, 0, tol, albedo_ms, nm,
                    "ct1982: D without pi, k = pi (4x walter)");
    check_albedo_ct(s, grid, "albedo ct1982 smith-exact F n=1.5", CT_CT1982, G_SMITH_EXACT, F_EXACT, 0, tol, albedo_ms,
                    nm, "ct1982: D without pi, k = pi (4x walter)");
    check_albedo_ct(s, grid, "albedo ct walter smith-exact F=1", CT_WALTER, G_SMITH_EXACT, F_ONE, 0, tol,
                    albedo_tiny_ms, nt, "numerical: N.H rounded to float before D (cooktorrance.c)");

    /* D3D9Client "white furnace": white diffuse (rho = 1 under unit radiance gives d = 1),
     * unit environment phi, s white; per norm the smallest diffuse weight 1 - |lambda| and
     * the largest channel albedo d w + lambda (1 - R) + R over lambda in [0,1]^3 and N.V. */
    static const char *nname[4] = {"max", "mean", "luminance", "euclid"};
    for (int norm = 0; norm < 4; norm++) {
        char fn[40];
        snprintf(fn, sizeof fn, "albedo d3d9client norm=%s", nname[norm]);
        row = row_begin(s, fn, "lambda in [0,1]^3, N.V 0..1, R0 0.04", STABILITY_PHYSICS, 0);
        material mat;
        material_init(&mat);
        mat.d9.norm = (colour_norm)norm;
        double wmin = 1e30, amax = -1e30;
        char wat[128] = "", aat[128] = "";
        int steps_l = 6;
        for (int a = 0; a <= steps_l; a++)
            for (int b = 0; b <= steps_l; b++)
                for (int c = 0; c <= steps_l; c++)
                    for (int q = 0; q <= 10; q++) {
                        mat.d9.reflect = v3((float)a / steps_l, (float)b / steps_l, (float)c / steps_l);
                        float nv = (float)q / 10.0f;
                        d3d9client_result r;
                        d3d9client_combine(&mat.d9, v3s(1.0f), 1.0f, v3s(1.0f), nv, 0.0f, &r);
                        row->samples++;
                        if (isnan(r.rgb.x) || isnan(r.diffuse_weight))
                            row->nan++;
                        if (r.diffuse_weight < wmin) {
                            wmin = r.diffuse_weight;
                            snprintf(wat, sizeof wat, "lambda=(%.2f,%.2f,%.2f)", mat.d9.reflect.x, mat.d9.reflect.y,
                                     mat.d9.reflect.z);
                        }
                        float cm = v3_max_comp(r.rgb);
                        if (cm > amax) {
                            amax = cm;
                            snprintf(aat, sizeof aat, "lambda=(%.2f,%.2f,%.2f) N.V=%.1f", mat.d9.reflect.x,
                                     mat.d9.reflect.y, mat.d9.reflect.z, nv);
                        }
                    }
        row->value = amax;
        row->aux = wmin;
        row->check_ok = amax <= 1.0 + 1e-6 && wmin >= 0.0; /* 1e-6: float rounding of the sum */
        row->expect_ok = 0;
        snprintf(row->where, sizeof row->where, "albedo at %s; weight at %s", aat, wat);
        snprintf(row->note, sizeof row->note, "albedo max %.4f; min diffuse weight 1-|lambda| = %.4f%s", amax, wmin,
                 wmin < 0 ? " (NEGATIVE: diffuse light subtracted)" : "");
    }
}

/* ------------------------------------------------------------------------- public API */

/* ------------------------------------------------------------ a user's model (user_model.h) */

/* Parameter set k of a sweep: the even ones at a corner of the bounds box (bit i of k / 2 puts
 * parameter i at hi), the odd ones drawn within the bounds (log-uniform where log_scale). */
static void user_params_at(sweep *s, const reflcheck_user_model *um, long k, double *p)
{
    for (int i = 0; i < um->n_params; i++) {
        const reflcheck_user_param *q = &um->params[i];
        if (k % 2 == 0)
            p[i] = ((k / 2) >> i) & 1 ? q->hi : q->lo;
        else
            p[i] = q->log_scale ? rng_log(&s->r, q->lo, q->hi) : rng_range(&s->r, q->lo, q->hi);
    }
}

static dvec3 user_round(vec3 a) { return dv3_norm(dv3_from(a)); }

/* One row: case 0 grazing (N.L and N.V log-uniform down to 1e-7), 1 the peak (L the mirror of V
 * turned by up to 1e-4 rad), 2 any upper-hemisphere pair. */
static void sweep_user_case(sweep *s, const reflcheck_user_model *um, const char *fn, int which)
{
    static const char *const cases[] = {"grazing: N.L, N.V log 1e-7..1", "peak: N.H -> 1 (mirror pair)",
                                        "random pairs, params at bounds"};
    stability_row *row = row_begin(s, fn, cases[which], STABILITY_APPROX, 53);
    snprintf(row->note, sizeof row->note,
             "output at float-rounded directions vs at the exact ones: the model's sensitivity to float "
             "geometry; every parameter set alternates a bounds corner and a random point");
    const dvec3 n = dv3(0, 1, 0), albedo = dv3(1.0, 0.5, 0.0);
    double p[REFLCHECK_USER_PARAMS_MAX];
    for (long i = 0; i < s->n; i++) {
        user_params_at(s, um, i, p);
        double ph = rng_range(&s->r, 0.0, 2.0 * (double)REF_PI);
        double cv = which == 0 ? rng_log(&s->r, 1e-7, 1.0) : rng_range(&s->r, 1e-3, 1.0);
        double cl = which == 0 ? rng_log(&s->r, 1e-7, 1.0) : rng_range(&s->r, 1e-3, 1.0);
        vec3 vf = dir_at(cv, ph), lf = which == 1 ? dir_at(cv, ph + (double)REF_PI + rng_range(&s->r, -1e-4, 1e-4))
                                                  : dir_at(cl, rng_range(&s->r, 0.0, 2.0 * (double)REF_PI));
        /* The exact directions: the float ones' own values in double, renormalised in long
         * double; the tested ones are those rounded back to float, as the rasterizer hands them. */
        ld3 vl = l3_norm(l3_from(vf)), ll = l3_norm(l3_from(lf));
        dvec3 v = dv3((double)vl.x, (double)vl.y, (double)vl.z), l = dv3((double)ll.x, (double)ll.y, (double)ll.z);
        reflcheck_user_output got, ref;
        int a = user_model_eval(um, p, user_round(v3_from_d(n)), user_round(v3_from_d(v)), user_round(v3_from_d(l)),
                                albedo, &got);
        int b = user_model_eval(um, p, n, v, l, albedo, &ref);
        if (!a || !b)
            continue;
        for (int c = 0; c < 3; c++) {
            ADD(row, got.diffuse[c], (ld)ref.diffuse[c], "diffuse N.V=%.3g N.L=%.3g", v.y, l.y);
            ADD(row, got.specular[c], (ld)ref.specular[c], "specular N.V=%.3g N.L=%.3g", v.y, l.y);
        }
    }
    row_end(row);
}

/* Directional albedo of the specular half at view angle theta_o: L sampled by a defensive
 * mixture, a cosine hemisphere and GGX half vectors of widths 1e-3..1 around the mirror
 * direction, so any lobe centred there is sampled whatever its width; f cos / mixture pdf. */
static double user_albedo(const reflcheck_user_model *um, const double *p, double theta_o, int grid)
{
    static const double widths[] = {1e-3, 1e-2, 0.1, 1.0};
    const int k = 1 + (int)(sizeof widths / sizeof widths[0]);
    dvec3 n = dv3(0, 1, 0), v = dv3(sin(theta_o), cos(theta_o), 0.0);
    double sum = 0.0;
    long count = 0;
    for (int i = 0; i < grid; i++)
        for (int j = 0; j < grid; j++) {
            double u1 = (i + 0.5) / grid, u2 = (j + 0.5) / grid, ph = 2.0 * (double)REF_PI * u2;
            int comp = (i * grid + j) % k;
            dvec3 l;
            if (comp == 0) {
                double st = sqrt(u1);
                l = dv3(st * cos(ph), sqrt(1.0 - u1), st * sin(ph));
            } else {
                double a = widths[comp - 1], t2 = a * a * u1 / (1.0 - u1), ch = 1.0 / sqrt(1.0 + t2);
                dvec3 h = dv3(sqrt(1.0 - ch * ch) * cos(ph), ch, sqrt(1.0 - ch * ch) * sin(ph));
                l = dv3_sub(dv3_scale(h, 2.0 * dv3_dot(v, h)), v);
            }
            count++;
            if (l.y <= 0.0)
                continue;
            dvec3 h = dv3_norm(dv3_add(l, v));
            double pdf = l.y / (double)REF_PI, vh = dv3_dot(v, h), c2 = h.y * h.y;
            for (int w = 0; w < k - 1; w++) {
                double a2 = widths[w] * widths[w], t = a2 * c2 + (1.0 - c2);
                pdf += vh > 0.0 ? a2 / ((double)REF_PI * t * t) * h.y / (4.0 * vh) : 0.0;
            }
            pdf /= k;
            reflcheck_user_output o;
            if (user_model_eval(um, p, n, v, l, dv3(0, 0, 0), &o))
                sum += o.specular[0] * l.y / pdf;
        }
    return sum / (double)count;
}

static void check_user_albedo(sweep *s, const reflcheck_user_model *um, const char *fn, int grid)
{
    static const double th[] = {0, 30, 60, 80, 89};
    stability_row *row = row_begin(s, fn, "max directional albedo (specular), bounds corners", STABILITY_PHYSICS, 0);
    double p[REFLCHECK_USER_PARAMS_MAX], worst = -1.0, wt = 0.0;
    long corners = 1L << um->n_params;
    for (long c = 0; c < corners; c++) {
        user_params_at(s, um, 2 * c, p);
        for (size_t b = 0; b < sizeof th / sizeof th[0]; b++) {
            double al = user_albedo(um, p, th[b] * (double)REF_PI / 180.0, grid);
            row->samples++;
            row->nan += isnan(al);
            if (al > worst) {
                worst = al;
                wt = th[b];
                size_t used = (size_t)snprintf(row->where, sizeof row->where, "view=%g deg", wt);
                for (int i = 0; i < um->n_params && used < sizeof row->where; i++)
                    used += (size_t)snprintf(row->where + used, sizeof row->where - used, " %s=%g", um->params[i].name,
                                             p[i]);
            }
        }
    }
    row->value = worst;
    row->check_ok = worst <= 1.0;
    row->expect_ok = 0;
    snprintf(row->note, sizeof row->note, "albedo max %.4f (diffuse albedo 0): %s; reported, not gated", worst,
             row->check_ok ? "energy conserving" : "reflects more than it receives");
}

static void sweep_user(sweep *s, const reflcheck_user_model *um, int grid)
{
    char fn[40];
    snprintf(fn, sizeof fn, "user[%s]", um->name);
    for (int which = 0; which < 3; which++)
        sweep_user_case(s, um, fn, which);
    check_user_albedo(s, um, fn, grid);
}

rc_status stability_run(const stability_options *o, stability_table *out)
{
    stability_options d = {0};
    if (o)
        d = *o;
    if (d.samples == 0)
        d.samples = STABILITY_DEFAULT_SAMPLES;
    if (d.albedo_grid == 0)
        d.albedo_grid = 96;
    if (d.samples < 16 || d.samples > STABILITY_MAX_SAMPLES || d.albedo_grid < 8 || d.albedo_grid > 2048)
        return RC_ERR_RANGE;
    stability_table *t = malloc(sizeof *t);
    if (!t)
        return RC_ERR_NOMEM;
    memset(t, 0, sizeof *t);
    t->samples = d.samples;
    t->ldbl_mant_dig = LDBL_MANT_DIG;
    sweep s = {.t = t, .r = {d.seed ? d.seed : 0x5EED5EEDu}, .n = d.samples};
    sweep_fresnel(&s);
    sweep_microfacet(&s);
    sweep_d3d(&s);
    sweep_d3d9client(&s);
    sweep_cooktorrance(&s);
    sweep_shade(&s);
    sweep_unnormalised(&s);
    check_physics(&s, d.albedo_grid);
    if (d.user != NULL)
        sweep_user(&s, d.user, d.albedo_grid);
    memcpy(out, t, sizeof *t);
    free(t);
    return RC_OK;
}

static int row_fails(const stability_row *r)
{
    if (r->nan || r->inf || r->negative)
        return 1;
    return r->kind == STABILITY_PHYSICS && r->expect_ok && r->check_ok == 0;
}

int stability_failures(const stability_table *t)
{
    int n = 0;
    for (int i = 0; i < t->n_rows; i++)
        n += row_fails(&t->rows[i]);
    return n;
}

const stability_row *stability_find(const stability_table *t, const char *function, const char *case_prefix)
{
    for (int i = 0; i < t->n_rows; i++) {
        const stability_row *r = &t->rows[i];
        if (function && strncmp(r->function, function, strlen(function)) != 0)
            continue;
        if (case_prefix && strncmp(r->case_name, case_prefix, strlen(case_prefix)) != 0)
            continue;
        return r;
    }
    return NULL;
}

static const char *kind_name(stability_kind k)
{
    return k == STABILITY_ROUNDING ? "rounding" : k == STABILITY_APPROX ? "approx" : "physics";
}

/* Figures carry 6 significant digits (the table's own precision; enough to tell 0.5 ulp from
 * 1); a non-finite figure (never expected) is null, as JSON has no Inf/NaN. */
#define STABILITY_JSON_DIGITS 6

static cJSON *stability_json_row(const stability_row *r)
{
    cJSON *o = cJSON_CreateObject();
    if (o == NULL)
        return NULL;
    int ok = cJSON_AddStringToObject(o, "function", r->function) != NULL &&
             cJSON_AddStringToObject(o, "case", r->case_name) != NULL &&
             cJSON_AddStringToObject(o, "kind", kind_name(r->kind)) != NULL &&
             cJSON_AddNumberToObject(o, "precision_bits", r->precision) != NULL &&
             cJSON_AddNumberToObject(o, "samples", (double)r->samples) != NULL &&
             jsonio_add(o, "max_ulp", jsonio_number(r->max_ulp, STABILITY_JSON_DIGITS)) &&
             jsonio_add(o, "max_rel", jsonio_number(r->max_rel, STABILITY_JSON_DIGITS)) &&
             jsonio_add(o, "max_abs", jsonio_number(r->max_abs, STABILITY_JSON_DIGITS)) &&
             cJSON_AddStringToObject(o, "where", r->where) != NULL &&
             cJSON_AddStringToObject(o, "where_abs", r->where_abs) != NULL &&
             cJSON_AddNumberToObject(o, "nan", (double)r->nan) != NULL &&
             cJSON_AddNumberToObject(o, "inf", (double)r->inf) != NULL &&
             cJSON_AddNumberToObject(o, "negative", (double)r->negative) != NULL &&
             cJSON_AddNumberToObject(o, "check_ok", r->check_ok) != NULL &&
             cJSON_AddBoolToObject(o, "gating", r->expect_ok) != NULL &&
             jsonio_add(o, "value", jsonio_number(r->value, STABILITY_JSON_DIGITS)) &&
             jsonio_add(o, "aux", jsonio_number(r->aux, STABILITY_JSON_DIGITS)) &&
             cJSON_AddStringToObject(o, "note", r->note) != NULL &&
             cJSON_AddBoolToObject(o, "fails", row_fails(r)) != NULL;
    if (!ok) {
        cJSON_Delete(o);
        return NULL;
    }
    return o;
}

cJSON *stability_json(const stability_table *t)
{
    cJSON *doc = cJSON_CreateObject(), *rows = NULL;
    int ok = doc != NULL && cJSON_AddNumberToObject(doc, "reference_mantissa_bits", t->ldbl_mant_dig) != NULL &&
             cJSON_AddNumberToObject(doc, "samples", t->samples) != NULL &&
             cJSON_AddNumberToObject(doc, "failures", stability_failures(t)) != NULL &&
             jsonio_add(doc, "rows", rows = cJSON_CreateArray());
    if (!ok) {
        cJSON_Delete(doc);
        return NULL;
    }
    for (int i = 0; i < t->n_rows; i++) {
        cJSON *row = stability_json_row(&t->rows[i]);
        if (row == NULL || !cJSON_AddItemToArray(rows, row)) {
            cJSON_Delete(row);
            cJSON_Delete(doc);
            return NULL;
        }
    }
    return doc;
}

int stability_write_json(FILE *f, const stability_table *t)
{
    cJSON *doc = stability_json(t);
    if (doc == NULL)
        return -1;
    int rc = jsonio_print(f, doc);
    cJSON_Delete(doc);
    return rc;
}

static void csv_str(FILE *f, const char *s)
{
    fputc('"', f);
    for (; *s; s++) {
        if (*s == '"')
            fputc('"', f);
        fputc(*s, f);
    }
    fputc('"', f);
}

int stability_write_csv(FILE *f, const stability_table *t)
{
    fputs("function,case,kind,precision_bits,samples,max_ulp,max_rel,max_abs,where,where_abs,nan,inf,negative,check_ok,"
          "gating,"
          "value,aux,note,fails\n",
          f);
    for (int i = 0; i < t->n_rows; i++) {
        const stability_row *r = &t->rows[i];
        csv_str(f, r->function);
        fputc(',', f);
        csv_str(f, r->case_name);
        fprintf(f, ",%s,%d,%ld,%.6g,%.6g,%.6g,", kind_name(r->kind), r->precision, r->samples, r->max_ulp, r->max_rel,
                r->max_abs);
        csv_str(f, r->where);
        fputc(',', f);
        csv_str(f, r->where_abs);
        fprintf(f, ",%ld,%ld,%ld,%d,%d,%.6g,%.6g,", r->nan, r->inf, r->negative, r->check_ok, r->expect_ok, r->value,
                r->aux);
        csv_str(f, r->note);
        fprintf(f, ",%d\n", row_fails(r));
    }
    return ferror(f) ? -1 : 0;
}

int stability_write_text(FILE *f, const stability_table *t)
{
    fprintf(f,
            "stability: %d samples per case, reference long double (%d-bit significand); ulp in the result's "
            "precision (0.5 = correctly rounded)\n",
            t->samples, t->ldbl_mant_dig);
    fprintf(f, "%-38s %-34s %10s %10s %10s %4s %4s %4s  %s\n", "function", "case", "max_ulp", "max_rel", "max_abs",
            "NaN", "Inf", "neg", "where / check");
    for (int i = 0; i < t->n_rows; i++) {
        const stability_row *r = &t->rows[i];
        if (r->kind == STABILITY_PHYSICS)
            fprintf(f, "%-38s %-34s %10s %10s %10s %4ld %4ld %4s  %s%s [%s]\n", r->function, r->case_name, "-", "-",
                    "-", r->nan, r->inf, "-", row_fails(r) ? "FAIL " : "", r->note, r->where);
        else
            fprintf(f, "%-38s %-34s %10.3g %10.3g %10.3g %4ld %4ld %4ld  %s%s\n", r->function, r->case_name, r->max_ulp,
                    r->max_rel, r->max_abs, r->nan, r->inf, r->negative, row_fails(r) ? "FAIL " : "",
                    r->kind == STABILITY_APPROX ? r->where_abs : r->where);
    }
    int nf = stability_failures(t);
    fprintf(f, "stability: %d rows, %d failing (NaN/Inf/negative for finite input, or a gating physics check)\n",
            t->n_rows, nf);
    return ferror(f) ? -1 : 0;
}
