/* shade_eval_n (render/shade_batch_*.c) against shade_eval lane by lane, and env_lookup_n against
 * env_lookup.
 *
 * Inputs are random but deterministic (a fixed-seed LCG): x in a box around the target, n a
 * random unit normal turned to face v, v the unit direction to the eye; a third of the lanes
 * get a normal near the first light's half vector, so Blinn highlights up to power 1e4 are
 * sampled where they are large, not only in their tails. Cases: the D3D diffuse and full
 * kernels (specular powers, local and infinite viewer, ambient, emissive, clamp), every light
 * kind and its variations (attenuation, range, spot profiles and hard edges), several lights at
 * once, the D3D9Client kernel (whole and non-whole p, sun_angle with a sun or a point main
 * light, every colour norm, constant, no and image environment), Cook-Torrance (the kernels
 * for Beckmann D with V-cavity or Walter's Smith G and Schlick or unit Fresnel, m from 0.001;
 * the exact G and Fresnel and m < 1e-6 on shade_batch_scalar, so bit-identical), partial batches (lanes past n stay
 * untouched), and batches with a light closer than 1e-15 m or farther than 1e15 m (the whole batch must be redone by
 * shade_eval: bit-identical). Every output must be finite.
 *
 * Tolerance: every term component (diffuse, specular, reflection, emission, alpha) must satisfy
 * |batch - scalar| <= REL * max(|scalar|, floor), REL = 2e-5, floor = a fraction of the largest
 * |scalar| of that term over the case. The relative part covers what the kernels do
 * differently per lane: float where shade.c forms sums in double (attenuation, the D3D9Client
 * combination: a few ulp), smath_pow for powf/pow (up to 1.6e-5 relative, test_smath.c) and
 * smath_atan2 in the environment lookup. The floor covers the errors that are absolute rather
 * than relative to the lane's value:
 *   FLOOR_FRACTION 1e-2: D3D9Client's 1 - F(N.L_sun) (equation 8) near a grazing sun, where F
 *     is formed in float instead of double and its last-bit difference (6e-8) is a large
 *     fraction of a small 1 - F: an error of about 6e-8 of the unweighted diffuse, against a
 *     tolerance of 2e-7 of the peak (measured worst 6.4e-8 of the peak).
 *   SPOT_FLOOR_FRACTION 0.2, for scenes with a spot whose factor varies inside the cone: the
 *     kernel forms rho = -axis.L and the cone cosines in float, shade.c in double, so
 *     t = (rho - cos_out)/(cos_in - cos_out) is off by about 1.2e-7 / 0.06 = 2e-6 for these
 *     30/50 degree cones, and near the outer edge (t -> 0) that is an absolute error of up to
 *     2e-6 of the unspotted value, unbounded relative to the spotted one; tolerance 4e-6 of
 *     the peak (measured worst 4.8e-7 of the peak, falloff 1).
 * Specular: shade.c's half vector renormalises L and V (d3d_half_vector), the kernel uses them
 * as they are, so N.H differs by up to ~2 ulp (1.2e-7) and (N.H)^P by about P times that:
 * power 1e4 gets its own tolerance (2e-3; measured 1.19e-3), powers up to 40 stay within REL.
 * Cook-Torrance's lobe: the same half-vector difference moves a Beckmann lobe's log D by about
 * 2 tan(theta) dtheta / m^2, so its specular bound grows as 3e-7/m (test_cook_torrance).
 * The measured worst errors are printed, one "# shade_batch ..." line per case.
 *
 * test_env_lookup_n_pole_negative_zero: the exact poles with a -0 component, where the two
 * lookups once read different columns (see its comment).
 */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <cmocka.h>

#include "check.h"

#include <float.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "env.h"
#include "shade.h"
#include "user_model.h"

#define FLOOR_FRACTION      1e-2
#define SPOT_FLOOR_FRACTION 0.2
#define REL                 2e-5
/* env_lookup_n vs env_lookup: |difference| as a fraction of the channel's full texel spread
 * (measured 9.9e-7; env.h allows a 1e-4 texel position difference). */
#define ENV_SPREAD_TOL      2e-6

/* ---- deterministic random numbers ---- */

static uint64_t rng_state;

static void rng_seed(uint64_t seed) { rng_state = seed * 2862933555777941757ull + 3037000493ull; }

/* Knuth's MMIX LCG; the top 24 bits make a float in [0, 1) without rounding. */
static float rng_unit(void)
{
    rng_state = rng_state * 6364136223846793005ull + 1442695040888963407ull;
    return (float)(rng_state >> 40) * 0x1p-24f;
}

static float rng_range(float lo, float hi) { return lo + (hi - lo) * rng_unit(); }

static vec3 rng_direction(void)
{
    for (;;) {
        vec3 a = v3(rng_range(-1.0f, 1.0f), rng_range(-1.0f, 1.0f), rng_range(-1.0f, 1.0f));
        float l2 = v3_dot(a, a);
        if (l2 > 1e-4f && l2 <= 1.0f)
            return v3_norm(a);
    }
}

/* ---- the environment image: 8 x 4 texels, each channel its own irregular pattern ---- */

enum { ENV_W = 8, ENV_H = 4 };
static float env_rgb[ENV_W * ENV_H * 3];

/* Values in [0.5, 4.1] with irregular steps, asymmetric in u and v (so a wrong, mirrored or
 * swapped texel shows), and no zero (so relative errors stay meaningful). */
static env_map make_env_image(void)
{
    for (int y = 0; y < ENV_H; y++)
        for (int x = 0; x < ENV_W; x++) {
            float *p = env_rgb + 3 * (y * ENV_W + x);
            p[0] = 0.5f + 0.25f * (float)((3 * x + 5 * y) % 11);
            p[1] = 0.7f + 0.4f * (float)((x * x + 2 * y) % 7);
            p[2] = 0.6f + 0.5f * (float)((5 * x + 3 * y * y + 1) % 8);
        }
    env_map e = {.kind = ENV_IMAGE, .scale = {1.0f, 0.5f, 2.0f}, .width = ENV_W, .height = ENV_H, .rgb = env_rgb};
    return e;
}

/* ---- scenes ---- */

static void base_scene(scene *s)
{
    scene_init(s);
    s->camera.eye = v3(0.3f, 2.5f, 3.5f);
    s->camera.target = v3(0.0f, 0.0f, 0.0f);
    s->n_materials = 1;
    s->n_lights = 0;
}

static light *add_light(scene *s, light_kind kind)
{
    light *l = &s->lights[s->n_lights++];
    light_init(l);
    l->kind = kind;
    return l;
}

static light *add_sun(scene *s)
{
    light *l = add_light(s, LIGHT_SUN);
    l->direction = v3(-0.3f, -1.0f, -0.2f); /* not unit: both paths normalise it */
    l->intensity = v3(2.0f, 1.5f, 1.0f);
    return l;
}

static light *add_point(scene *s)
{
    light *l = add_light(s, LIGHT_POINT);
    l->position = v3(0.5f, 2.0f, 0.5f);
    l->intensity = v3(6.0f, 5.0f, 4.0f);
    return l;
}

/* Aimed down from 2.5 m above the box: the edges of the 30 and 50 degree cones cross the box. */
static light *add_spot(scene *s, spot_profile profile)
{
    light *l = add_light(s, LIGHT_SPOT);
    l->position = v3(-0.2f, 2.5f, 0.1f);
    l->direction = v3(0.1f, -2.0f, 0.05f);
    l->intensity = v3(8.0f, 7.0f, 9.0f);
    l->profile = profile;
    l->inner = (float)deg(30.0);
    l->outer = (float)deg(50.0);
    return l;
}

/* A sun, a point light whose range cuts some lanes and a spot: every light kind at once. */
static void add_three_lights(scene *s, spot_profile profile)
{
    add_sun(s);
    add_point(s)->range = 2.5f;
    add_spot(s, profile);
}

/* ---- inputs ---- */

/* Lanes: x in [-1, 1] x [-0.5, 0.5] x [-1, 1]; v the unit vector to the eye; n random, or for a
 * third of the lanes the first light's half vector (for the viewer the material uses) tilted
 * by 10^-3.5 to 10^-1, then turned to face v. */
static void make_inputs(const shade_context *c, const material *m, int n, shade_batch_in *in)
{
    const scene *s = c->s;
    in->n = n;
    for (int i = 0; i < n; i++) {
        vec3 x = v3(rng_range(-1.0f, 1.0f), rng_range(-0.5f, 0.5f), rng_range(-1.0f, 1.0f));
        vec3 v = v3_norm(v3_sub(c->eye, x));
        vec3 nn = rng_direction();
        if (s->n_lights > 0 && rng_unit() < 0.35f) {
            const light *l = &s->lights[0];
            vec3 to_l = l->kind == LIGHT_SUN ? v3_neg(v3_norm(l->direction)) : v3_norm(v3_sub(l->position, x));
            vec3 h = v3_norm(v3_add(to_l, m->d3d.local_viewer ? v : c->e_inf));
            float tilt = powf(10.0f, rng_range(-3.5f, -1.0f));
            nn = v3_norm(v3_add(h, v3_scale(rng_direction(), tilt)));
        }
        if (v3_dot(nn, v) < 0.0f)
            nn = v3_neg(nn);
        shade_batch_set_input(in, i, x, nn, v);
    }
}

/* ---- comparison ---- */

enum { T_DIFFUSE, T_SPECULAR, T_REFLECTION, T_EMISSION, T_ALPHA, T_COUNT };
static const char *const term_names[T_COUNT] = {"diffuse", "specular", "reflection", "emission", "alpha"};

/* Components of term t of a scalar result (alpha fills one). */
static int term_values(const shade_terms *t, int term, float v[3])
{
    const vec3 *src[] = {&t->diffuse, &t->specular, &t->reflection, &t->emission};
    if (term == T_ALPHA) {
        v[0] = t->alpha;
        return 1;
    }
    v[0] = src[term]->x, v[1] = src[term]->y, v[2] = src[term]->z;
    return 3;
}

static int batch_values(const shade_batch_out *o, int i, int term, float v[3])
{
    shade_terms t;
    shade_batch_get_terms(o, i, &t);
    return term_values(&t, term, v);
}

typedef struct {
    double worst[T_COUNT]; /* worst |batch - scalar| / max(|scalar|, floor) */
    long lanes;            /* lanes compared */
    long lit;              /* lanes whose scalar diffuse is non-zero */
    long failures;
} check_stat;

typedef struct {
    const char *name;
    double spec_rel; /* specular tolerance (the others are REL) */
    int exact;       /* bit-identical required (the scalar fallback) */
} check_spec;

static void stat_merge(check_stat *into, const check_stat *s)
{
    for (int t = 0; t < T_COUNT; t++)
        into->worst[t] = fmax(into->worst[t], s->worst[t]);
    into->lanes += s->lanes;
    into->lit += s->lit;
    into->failures += s->failures;
}

static void stat_print(const char *what, const check_stat *s)
{
    print_message("# shade_batch %s: %ld lanes (%ld lit), worst rel err diffuse %.3g specular %.3g reflection %.3g "
                  "emission %.3g alpha %.3g\n",
                  what, s->lanes, s->lit, s->worst[T_DIFFUSE], s->worst[T_SPECULAR], s->worst[T_REFLECTION],
                  s->worst[T_EMISSION], s->worst[T_ALPHA]);
}

static void report_mismatch(check_stat *st, const check_spec *spec, const shade_batch_in *in, int lane, int term,
                            int comp, float got, float want, double err)
{
    st->failures++;
    if (st->failures > 6)
        return;
    vec3 x = shade_lane_get(&in->x, lane), n = shade_lane_get(&in->nrm, lane), v = shade_lane_get(&in->v, lane);
    print_error("%s: lane %d of %d, %s[%d]: batch %.9g (%a), scalar %.9g (%a), error %.3g\n"
                "  x = (%a, %a, %a) n = (%a, %a, %a) v = (%a, %a, %a)\n",
                spec->name, lane, in->n, term_names[term], comp, (double)got, (double)got, (double)want, (double)want,
                err, (double)x.x, (double)x.y, (double)x.z, (double)n.x, (double)n.y, (double)n.z, (double)v.x,
                (double)v.y, (double)v.z);
}

/* Lanes a case checks: fixed, not a multiple of SHADE_BATCH, so that the batch length does
 * not change which random inputs a case draws (the lanes are drawn in order, batch after
 * batch). Over 4096 lanes the power-1e4 case reaches 2.4e-3 (shade.h). */
enum { TEST_LANES = 1024, MAX_BATCHES = TEST_LANES / SHADE_BATCH > 4 ? TEST_LANES / SHADE_BATCH : 4 };
/* Sentinel for lanes past n: the kernels must not write them. */
#define SENTINEL (-7.75e33f)

static struct {
    shade_batch_in in[MAX_BATCHES];
    shade_batch_out out[MAX_BATCHES];
    shade_terms want[MAX_BATCHES][SHADE_BATCH];
} work;

static void fill_sentinel(shade_batch_out *o)
{
    float *f = (float *)(void *)o;
    for (size_t i = 0; i < sizeof *o / sizeof(float); i++)
        f[i] = SENTINEL;
}

/* A spot whose factor varies inside the cone (inner < outer): its lanes near the outer edge
 * carry the absolute spot-factor error that SPOT_FLOOR_FRACTION covers. */
static int has_soft_spot(const scene *s)
{
    for (int i = 0; i < s->n_lights; i++)
        if (s->lights[i].kind == LIGHT_SPOT && s->lights[i].inner < s->lights[i].outer)
            return 1;
    return 0;
}

/* `batches` batches of `lanes` lanes through shade_eval_n, each lane against shade_eval. */
static void run_case(const shade_context *c, const shade_plan *p, const check_spec *spec, int lanes, int batches,
                     check_stat *total)
{
    assert_true(batches <= MAX_BATCHES && lanes >= 0 && lanes <= SHADE_BATCH);
    check_stat st = {{0}, 0, 0, 0};
    double peak[T_COUNT] = {0};
    const double floor_fraction = has_soft_spot(c->s) ? SPOT_FLOOR_FRACTION : FLOOR_FRACTION;
    for (int b = 0; b < batches; b++) {
        make_inputs(c, p->mat, lanes, &work.in[b]);
        for (int i = 0; i < lanes; i++) {
            shade_terms *t = &work.want[b][i];
            shade_eval(c, p, shade_lane_get(&work.in[b].x, i), shade_lane_get(&work.in[b].nrm, i),
                       shade_lane_get(&work.in[b].v, i), t);
            for (int term = 0; term < T_COUNT; term++) {
                float w[3];
                int k = term_values(t, term, w);
                for (int j = 0; j < k; j++)
                    peak[term] = fmax(peak[term], fabs(w[j]));
            }
            st.lit += v3_sum(t->diffuse) != 0.0f;
        }
    }
    for (int b = 0; b < batches; b++) {
        shade_batch_out *o = &work.out[b];
        fill_sentinel(o);
        shade_eval_n(c, p, &work.in[b], o);
        for (int i = 0; i < lanes; i++) {
            st.lanes++;
            for (int term = 0; term < T_COUNT; term++) {
                float got[3], want[3];
                int k = batch_values(o, i, term, got);
                term_values(&work.want[b][i], term, want);
                double rel = term == T_SPECULAR ? spec->spec_rel : REL;
                double floor = floor_fraction * peak[term];
                for (int j = 0; j < k; j++) {
                    double err;
                    int ok;
                    if (spec->exact) {
                        ok = memcmp(&got[j], &want[j], sizeof got[j]) == 0;
                        err = ok ? 0.0 : INFINITY;
                    } else {
                        double scale = fmax(fabs(want[j]), floor);
                        double d = fabs((double)got[j] - want[j]);
                        err = d == 0.0 ? 0.0 : (scale > 0.0 ? d / scale : INFINITY);
                        ok = err <= rel;
                    }
                    ok &= isfinite(got[j]) != 0;
                    st.worst[term] = fmax(st.worst[term], isnan(err) ? INFINITY : err);
                    if (!ok)
                        report_mismatch(&st, spec, &work.in[b], i, term, j, got[j], want[j], err);
                }
            }
        }
        /* Lanes past n are not the kernel's to write. */
        for (int i = lanes; i < SHADE_BATCH; i++)
            for (int term = 0; term < T_COUNT; term++) {
                float got[3];
                int k = batch_values(o, i, term, got);
                for (int j = 0; j < k; j++)
                    if (got[j] != SENTINEL) {
                        st.failures++;
                        print_error("%s: lane %d past n = %d written (%s)\n", spec->name, i, lanes, term_names[term]);
                    }
            }
    }
    stat_merge(total, &st);
}

static void plan_for(const scene *s, const env_map *env, shade_context *c, shade_plan *p, shade_batch_fn want)
{
    shade_context_make(s, env, c);
    shade_plan_make(c, &s->materials[0], p);
    /* The case is only a test of its kernel if the plan picked that kernel. */
    assert_true(p->batch == want);
}

/* run_case from its own seed, its statistics merged into *all; returns its failures. */
static int run_seeded(const shade_context *c, const shade_plan *p, const check_spec *spec, uint64_t seed, int lanes,
                      int batches, check_stat *all)
{
    check_stat st = {{0}, 0, 0, 0};
    rng_seed(seed);
    run_case(c, p, spec, lanes, batches, &st);
    stat_merge(all, &st);
    return (int)st.failures;
}
/* ---- D3D ---- */

static void test_d3d_diffuse(void **state)
{
    (void)state;
    rng_seed(1);
    scene s;
    base_scene(&s);
    add_sun(&s);
    add_point(&s)->a0 = 0.3f;
    add_spot(&s, SPOT_SMOOTH);
    s.materials[0].d3d.diffuse = v3(0.7f, 0.5f, 0.3f);
    env_map env = {.kind = ENV_NONE};
    shade_context c;
    shade_plan p;
    plan_for(&s, &env, &c, &p, shade_batch_d3d_diffuse);
    assert_string_equal(p.path, "d3d-diffuse");
    check_stat st = {{0}, 0, 0, 0};
    const check_spec spec = {"d3d-diffuse", REL, 0};
    run_case(&c, &p, &spec, SHADE_BATCH, MAX_BATCHES, &st);
    stat_print("d3d-diffuse (sun, point, smooth spot)", &st);
    assert_int_equal(st.failures, 0);
}

/* The kernels keep a light's cone set-up from one batch to the next (shade_batch.c,
 * sb_light_make). Editing the same light struct's direction and cone between two batches must
 * show in the second: its lanes equal, bit for bit, a batch shaded on a second scene that had
 * the edited light from the start. The same inputs both times, so only the light differs. */
static void test_light_edit_between_batches(void **state)
{
    (void)state;
    scene *s = malloc(sizeof *s), *t = malloc(sizeof *t);
    assert_non_null(s);
    assert_non_null(t);
    base_scene(s);
    light *l = add_spot(s, SPOT_D3D);
    l->falloff = 2.0f;
    s->materials[0].d3d.diffuse = v3(0.7f, 0.5f, 0.3f);
    env_map env = {.kind = ENV_NONE};
    shade_context c, ct;
    shade_plan p, pt;
    plan_for(s, &env, &c, &p, shade_batch_d3d_diffuse);
    static shade_batch_in in;
    static shade_batch_out before, after, fresh;
    rng_seed(7);
    make_inputs(&c, &s->materials[0], SHADE_BATCH, &in);
    shade_eval_n(&c, &p, &in, &before);
    /* A narrower cone turned a little: some lanes leave it, others change their factor. */
    l->direction = v3(0.3f, -2.0f, 0.1f);
    l->inner = (float)deg(10.0);
    l->outer = (float)deg(25.0);
    l->falloff = 1.5f;
    shade_eval_n(&c, &p, &in, &after);
    *t = *s; /* the edited light from the start, in another struct */
    plan_for(t, &env, &ct, &pt, shade_batch_d3d_diffuse);
    shade_eval_n(&ct, &pt, &in, &fresh);
    assert_memory_equal(&after.diffuse, &fresh.diffuse, sizeof after.diffuse);
    assert_memory_not_equal(&after.diffuse, &before.diffuse, sizeof after.diffuse);
    free(s);
    free(t);
}

/* Blinn powers 0, 1, 40, 1e4 with local and infinite viewer. Measured worst specular errors
 * (relative to max(|scalar|, floor)): 2.7e-7, 1.05e-6, 4.9e-6 (within REL) and 1.19e-3 at 1e4,
 * whose tolerance is 2e-3 (P times N.H's ~2 ulp difference, see the top of the file). */
static void test_d3d_full_specular(void **state)
{
    (void)state;
    const float powers[] = {0.0f, 1.0f, 40.0f, 1e4f};
    const double spec_rel[] = {REL, REL, REL, 2e-3};
    int failures = 0;
    for (int pi = 0; pi < 4; pi++)
        for (int local = 0; local <= 1; local++) {
            rng_seed(100 + (uint64_t)(pi * 2 + local));
            scene s;
            base_scene(&s);
            add_sun(&s);
            add_point(&s)->a1 = 0.2f;
            material *m = &s.materials[0];
            m->d3d.diffuse = v3(0.6f, 0.4f, 0.2f);
            m->d3d.specular = v3(0.6f, 0.5f, 0.4f);
            m->d3d.power = powers[pi];
            m->d3d.local_viewer = local;
            env_map env = {.kind = ENV_NONE};
            shade_context c;
            shade_plan p;
            plan_for(&s, &env, &c, &p, shade_batch_d3d_full);
            char name[96];
            snprintf(name, sizeof name, "d3d-full power %g local_viewer %d", (double)powers[pi], local);
            const check_spec spec = {name, spec_rel[pi], 0};
            check_stat st = {{0}, 0, 0, 0};
            run_case(&c, &p, &spec, SHADE_BATCH, MAX_BATCHES, &st);
            stat_print(name, &st);
            failures += (int)st.failures;
        }
    assert_int_equal(failures, 0);
}

/* Light ambient, global ambient, emissive, and D3D's clamp of Dv (with the emissive colour)
 * and Sv; bright lights make the clamp bind on many lanes, an emissive channel above 1 leaves
 * no room for diffuse at all. */
static void test_d3d_full_ambient_emissive_clamp(void **state)
{
    (void)state;
    int failures = 0;
    for (int clamp = 0; clamp <= 1; clamp++)
        for (int bright = 0; bright <= 1; bright++) {
            rng_seed(200 + (uint64_t)(clamp * 2 + bright));
            scene s;
            base_scene(&s);
            s.global_ambient = v3(0.05f, 0.1f, 0.15f);
            light *sun = add_sun(&s);
            sun->ambient = v3(0.2f, 0.1f, 0.05f);
            light *pt = add_point(&s);
            pt->ambient = v3(0.3f, 0.3f, 0.1f);
            pt->a0 = 0.1f;
            pt->intensity = bright ? v3(40.0f, 20.0f, 10.0f) : v3(4.0f, 2.0f, 1.0f);
            material *m = &s.materials[0];
            m->d3d.diffuse = v3(0.6f, 0.4f, 0.2f);
            m->d3d.ambient = v3(0.3f, 0.2f, 0.1f);
            m->d3d.specular = v3(0.5f, 0.5f, 0.5f);
            m->d3d.power = 12.0f;
            m->d3d.emissive = bright ? v3(0.2f, 1.5f, 0.0f) : v3(0.2f, 0.1f, 0.05f);
            m->d3d.clamp = clamp;
            env_map env = {.kind = ENV_NONE};
            shade_context c;
            shade_plan p;
            plan_for(&s, &env, &c, &p, shade_batch_d3d_full);
            char name[96];
            snprintf(name, sizeof name, "d3d-full ambient+emissive clamp %d bright %d", clamp, bright);
            const check_spec spec = {name, REL, 0};
            check_stat st = {{0}, 0, 0, 0};
            run_case(&c, &p, &spec, SHADE_BATCH, MAX_BATCHES, &st);
            stat_print(name, &st);
            failures += (int)st.failures;
        }
    /* Ambient alone (no specular) also takes the full kernel. */
    rng_seed(210);
    scene s;
    base_scene(&s);
    add_sun(&s)->ambient = v3(0.1f, 0.2f, 0.3f);
    s.materials[0].d3d.ambient = v3(0.5f, 0.5f, 0.5f);
    env_map env = {.kind = ENV_NONE};
    shade_context c;
    shade_plan p;
    plan_for(&s, &env, &c, &p, shade_batch_d3d_full);
    const check_spec spec = {"d3d-full ambient only", REL, 0};
    check_stat st = {{0}, 0, 0, 0};
    run_case(&c, &p, &spec, SHADE_BATCH, MAX_BATCHES, &st);
    stat_print("d3d-full ambient only", &st);
    failures += (int)st.failures;
    assert_int_equal(failures, 0);
}

/* One light per case, every kind, through the full kernel (specular power 40, ambient). lit
 * counts are checked where a case must cut some lanes and light others (range, cones). */
static void light_case(const char *name, const light *l, check_stat *out_stat)
{
    scene s;
    base_scene(&s);
    s.lights[0] = *l;
    s.n_lights = 1;
    material *m = &s.materials[0];
    m->d3d.diffuse = v3(0.6f, 0.5f, 0.4f);
    m->d3d.specular = v3(0.3f, 0.3f, 0.3f);
    m->d3d.power = 40.0f;
    env_map env = {.kind = ENV_NONE};
    shade_context c;
    shade_plan p;
    plan_for(&s, &env, &c, &p, shade_batch_d3d_full);
    const check_spec spec = {name, REL, 0};
    check_stat st = {{0}, 0, 0, 0};
    run_case(&c, &p, &spec, SHADE_BATCH, MAX_BATCHES, &st);
    stat_print(name, &st);
    *out_stat = st;
}

/* The scratch scene a light is built in, emptied first (light_case copies the light out). */
static scene *cleared(scene *s)
{
    s->n_lights = 0;
    return s;
}

static void test_light_kinds(void **state)
{
    (void)state;
    int failures = 0;
    check_stat st;
    scene tmp;
    base_scene(&tmp);

    rng_seed(300);
    light_case("sun", add_sun(cleared(&tmp)), &st);
    failures += (int)st.failures;

    /* Point: attenuation variants; the same seed with and without a range shows the range
     * cutting lanes (distances from the light to the box run from about 1.1 to 3.4 m). */
    const float att[][3] = {{0, 0, 1}, {1, 0, 0}, {0.5f, 0.3f, 0.2f}, {0, 1, 0}, {0.02f, 0, 0.5f}};
    for (int a = 0; a < 5; a++) {
        light *pt = add_point(cleared(&tmp));
        pt->a0 = att[a][0], pt->a1 = att[a][1], pt->a2 = att[a][2];
        char name[64];
        snprintf(name, sizeof name, "point a = (%g, %g, %g)", (double)att[a][0], (double)att[a][1], (double)att[a][2]);
        rng_seed(310 + (uint64_t)a);
        light_case(name, pt, &st);
        failures += (int)st.failures;
        const long lit_all = st.lit;
        pt->range = 2.2f;
        snprintf(name, sizeof name, "point a = (%g, %g, %g) range 2.2", (double)att[a][0], (double)att[a][1],
                 (double)att[a][2]);
        rng_seed(310 + (uint64_t)a);
        light_case(name, pt, &st);
        failures += (int)st.failures;
        assert_true(st.lit > 0 && st.lit < lit_all);
    }

    /* D3D spot: falloff 0, 1, 3.5 between a 30 and a 50 degree cone; then a hard edge. */
    const float falloffs[] = {0.0f, 1.0f, 3.5f};
    for (int f = 0; f < 3; f++) {
        light *sp = add_spot(cleared(&tmp), SPOT_D3D);
        sp->falloff = falloffs[f];
        char name[64];
        snprintf(name, sizeof name, "spot d3d falloff %g", (double)falloffs[f]);
        rng_seed(320 + (uint64_t)f);
        light_case(name, sp, &st);
        failures += (int)st.failures;
        assert_true(st.lit > 0 && st.lit < st.lanes);
    }
    light *sp = add_spot(cleared(&tmp), SPOT_D3D);
    sp->inner = sp->outer = (float)deg(40.0);
    rng_seed(330);
    light_case("spot d3d hard edge (inner == outer)", sp, &st);
    failures += (int)st.failures;
    assert_true(st.lit > 0 && st.lit < st.lanes);

    /* Smooth spot (cos * smoothstep), soft and hard-edged. */
    sp = add_spot(cleared(&tmp), SPOT_SMOOTH);
    rng_seed(340);
    light_case("spot smooth", sp, &st);
    failures += (int)st.failures;
    assert_true(st.lit > 0 && st.lit < st.lanes);
    sp = add_spot(cleared(&tmp), SPOT_SMOOTH);
    sp->inner = sp->outer = (float)deg(40.0);
    rng_seed(341);
    light_case("spot smooth hard edge (inner == outer)", sp, &st);
    failures += (int)st.failures;
    assert_true(st.lit > 0 && st.lit < st.lanes);
    assert_int_equal(failures, 0);
}

/* Eight lights of every kind at once, all features on. */
static void test_multiple_lights(void **state)
{
    (void)state;
    rng_seed(400);
    scene s;
    base_scene(&s);
    add_point(&s)->range = 2.5f;
    add_sun(&s)->ambient = v3(0.05f, 0.05f, 0.1f);
    add_spot(&s, SPOT_D3D)->falloff = 2.0f;
    add_spot(&s, SPOT_SMOOTH)->position = v3(1.0f, 2.0f, -1.0f);
    light *p2 = add_point(&s);
    p2->position = v3(-1.5f, 0.5f, 1.0f);
    p2->a0 = 1.0f, p2->a1 = 0.5f, p2->a2 = 0.0f;
    light *sun2 = add_sun(&s);
    sun2->direction = v3(1.0f, -0.2f, 0.3f);
    sun2->intensity = v3(0.5f, 0.7f, 0.9f);
    light *sp3 = add_spot(&s, SPOT_D3D);
    sp3->position = v3(0.0f, 0.3f, 2.5f);
    sp3->direction = v3(0.0f, -0.1f, -1.0f);
    sp3->falloff = 0.0f;
    add_point(&s)->position = v3(0.2f, -1.5f, 0.3f); /* below the box: lights from behind on many lanes */
    assert_int_equal(s.n_lights, 8);
    s.global_ambient = v3(0.02f, 0.03f, 0.04f);
    material *m = &s.materials[0];
    m->d3d.diffuse = v3(0.5f, 0.6f, 0.7f);
    m->d3d.ambient = v3(0.4f, 0.4f, 0.4f);
    m->d3d.specular = v3(0.4f, 0.3f, 0.2f);
    m->d3d.emissive = v3(0.01f, 0.02f, 0.0f);
    m->d3d.power = 12.0f;
    env_map env = {.kind = ENV_NONE};
    shade_context c;
    shade_plan p;
    plan_for(&s, &env, &c, &p, shade_batch_d3d_full);
    const check_spec spec = {"8 lights", REL, 0};
    check_stat st = {{0}, 0, 0, 0};
    run_case(&c, &p, &spec, SHADE_BATCH, MAX_BATCHES, &st);
    stat_print("8 lights (point, sun, d3d spots, smooth spot)", &st);
    assert_int_equal(st.failures, 0);
}

/* ---- D3D9Client ---- */

static void test_d3d9client(void **state)
{
    (void)state;
    const float ps[] = {3.0f, 5.0f, 2.5f, 0.0f, 12.0f};
    const colour_norm norms[] = {NORM_MAX, NORM_MEAN, NORM_LUMINANCE, NORM_EUCLID};
    const char *const norm_names[] = {"max", "mean", "luminance", "euclid"};
    /* A dim metal (1 - |lambda| > 0) and a bright one (euclid |lambda| > 1: negative weight). */
    const vec3 lambdas[] = {{0.6f, 0.4f, 0.2f}, {0.9f, 0.8f, 0.7f}};
    env_map envs[3] = {{.kind = ENV_CONSTANT, .constant = {0.4f, 0.6f, 0.9f}}, {.kind = ENV_NONE}, make_env_image()};
    const char *const env_names[] = {"constant", "none", "image"};
    int failures = 0;
    check_stat all = {{0}, 0, 0, 0};
    uint64_t seed = 500;
    for (int pi = 0; pi < 5; pi++)
        for (int sun_angle = 0; sun_angle <= 1; sun_angle++)
            for (int main_sun = 0; main_sun <= 1; main_sun++)
                for (int ni = 0; ni < 4; ni++)
                    for (int ei = 0; ei < 3; ei++)
                        for (int li = 0; li < 2; li++) {
                            scene s;
                            base_scene(&s);
                            /* The main light is the first sun, else the first light. */
                            add_point(&s);
                            if (main_sun)
                                add_sun(&s);
                            add_spot(&s, main_sun ? SPOT_D3D : SPOT_SMOOTH);
                            s.global_ambient = v3(0.02f, 0.02f, 0.02f);
                            material *m = &s.materials[0];
                            m->model = MODEL_D3D9CLIENT;
                            m->d3d.diffuse = v3(0.6f, 0.5f, 0.4f);
                            m->d3d.specular = v3(0.3f, 0.3f, 0.3f);
                            m->d3d.ambient = v3(0.2f, 0.2f, 0.2f);
                            m->d3d.power = 20.0f;
                            m->d9.p = ps[pi];
                            m->d9.r0 = 0.04f;
                            m->d9.m = 0.96f;
                            m->d9.reflect = lambdas[li];
                            m->d9.norm = norms[ni];
                            m->d9.sun_angle = sun_angle;
                            m->d9.alpha = 0.5f;
                            shade_context c;
                            shade_plan p;
                            plan_for(&s, &envs[ei], &c, &p, shade_batch_d3d9client);
                            char name[160];
                            snprintf(name, sizeof name,
                                     "d3d9client p %g sun_angle %d main %s norm %s env %s lambda (%g, %g, %g)",
                                     (double)ps[pi], sun_angle, main_sun ? "sun" : "point", norm_names[ni],
                                     env_names[ei], (double)lambdas[li].x, (double)lambdas[li].y,
                                     (double)lambdas[li].z);
                            const check_spec spec = {name, REL, 0};
                            failures += run_seeded(&c, &p, &spec, seed++, SHADE_BATCH, 3, &all);
                        }
    stat_print("d3d9client (all 480 combinations)", &all);
    assert_int_equal(failures, 0);
}

/* The Dissolve kernel against shade_eval_uv lane by lane, at random (tu, tv) in [-2, 2) (the
 * noise wraps), two lights, the image environment and the tolerances above. The plan picks
 * this kernel only for a textured material; the texture multiplies the terms after both paths
 * (shade_texture_apply), so the kernel is installed here by hand on an untextured one. */
static void test_d3d9client_dissolve(void **state)
{
    (void)state;
    const float strengths[] = {0.3f, 1.5f};
    check_stat all = {{0}, 0, 0, 0};
    env_map env = make_env_image();
    rng_seed(900);
    for (int si = 0; si < 2; si++) {
        scene s;
        base_scene(&s);
        add_point(&s);
        add_sun(&s);
        material *m = &s.materials[0];
        m->model = MODEL_D3D9CLIENT;
        m->d3d.diffuse = v3(0.6f, 0.5f, 0.4f);
        m->d3d.specular = v3(0.3f, 0.3f, 0.3f);
        m->d3d.power = 20.0f;
        m->d9.p = 5.0f;
        m->d9.r0 = 0.04f;
        m->d9.m = 0.96f;
        m->d9.reflect = v3(0.6f, 0.4f, 0.2f);
        m->d9.dissolve_scale = 1.25f;
        m->d9.dissolve_strength = strengths[si];
        shade_context c;
        shade_plan p;
        shade_context_make(&s, &env, &c);
        shade_plan_make(&c, m, &p);
        assert_false(p.textured);
        p.batch = shade_batch_d3d9client_dissolve;
        p.fn_uv = shade_d3d9client_dissolve;
        shade_batch_in *in = &work.in[0];
        shade_batch_out *o = &work.out[0];
        make_inputs(&c, m, SHADE_BATCH, in);
        for (int i = 0; i < SHADE_BATCH; i++) {
            in->tu[i] = rng_range(-2.0f, 2.0f);
            in->tv[i] = rng_range(-2.0f, 2.0f);
        }
        fill_sentinel(o);
        shade_eval_n(&c, &p, in, o);
        double peak = 0.0;
        for (int i = 0; i < SHADE_BATCH; i++) {
            shade_eval_uv(&c, &p, shade_lane_get(&in->x, i), shade_lane_get(&in->nrm, i), shade_lane_get(&in->v, i),
                          in->tu[i], in->tv[i], &work.want[0][i]);
            float w[3];
            term_values(&work.want[0][i], T_REFLECTION, w);
            for (int j = 0; j < 3; j++)
                peak = fmax(peak, fabs(w[j]));
        }
        assert_true(peak > 0.0);
        for (int i = 0; i < SHADE_BATCH; i++) {
            all.lanes++;
            float got[3], want[3];
            batch_values(o, i, T_REFLECTION, got);
            term_values(&work.want[0][i], T_REFLECTION, want);
            for (int j = 0; j < 3; j++) {
                double err = fabs((double)got[j] - want[j]) / fmax(fabs(want[j]), FLOOR_FRACTION * peak);
                all.worst[T_REFLECTION] = fmax(all.worst[T_REFLECTION], err);
                if (!(err <= REL) || !isfinite(got[j])) {
                    all.failures++;
                    print_error("dissolve strength %g lane %d (tu %g, tv %g) channel %d: batch %.9g, scalar %.9g\n",
                                (double)strengths[si], i, (double)in->tu[i], (double)in->tv[i], j, (double)got[j],
                                (double)want[j]);
                }
            }
        }
    }
    stat_print("d3d9client dissolve (reflection)", &all);
    assert_int_equal(all.failures, 0);
}

/* ---- Cook-Torrance: the kernels, and shade_eval lane by lane where they do not apply ---- */

/* Every normalisation, G and Fresnel, with and without the reflection term, under the three
 * lights and every environment kind. Beckmann D, V-cavity and Walter's Smith G and Schlick or
 * unit Fresnel run in the kernels (compared with the tolerances above); the exact Smith G, the
 * exact Fresnel and m below 1e-6 stay on shade_eval, and there the batch must be bit-identical. */
static void test_cook_torrance(void **state)
{
    (void)state;
    env_map envs[3] = {{.kind = ENV_CONSTANT, .constant = {0.4f, 0.6f, 0.9f}}, {.kind = ENV_NONE}, make_env_image()};
    const ct_normalisation norms[2] = {CT_WALTER, CT_CT1982};
    const ct_geometry gs[3] = {G_VCAVITY, G_SMITH_WALTER, G_SMITH_EXACT};
    const ct_fresnel fs[3] = {F_SCHLICK, F_ONE, F_EXACT};
    const float ms[5] = {0.001f, 0.05f, 0.2f, 0.6f, 1e-7f};
    int failures = 0;
    uint64_t seed = 600;
    check_stat kernel = {{0}, 0, 0, 0}, scalar = {{0}, 0, 0, 0};
    for (int ni = 0; ni < 2; ni++)
        for (int gi = 0; gi < 3; gi++)
            for (int fi = 0; fi < 3; fi++)
                for (int mi = 0; mi < 5; mi++)
                    for (int refl = 0; refl <= 1; refl++) {
                        int ei = (ni + gi + fi + mi + refl) % 3;
                        scene s;
                        base_scene(&s);
                        add_three_lights(&s, SPOT_SMOOTH);
                        material *m = &s.materials[0];
                        m->model = MODEL_COOK_TORRANCE;
                        m->albedo = v3(0.3f, 0.4f, 0.5f);
                        m->conductor = mi % 2;
                        m->eta = v3(1.66f, 0.88f, 0.52f);
                        m->k = v3(9.22f, 6.27f, 4.84f);
                        m->ct.norm = norms[ni];
                        m->ct.g = gs[gi];
                        m->ct.f = fs[fi];
                        m->ct.m = ms[mi];
                        m->ct.f0 = v3(0.9f, 0.6f, 0.3f);
                        m->ct.ks = v3(1.0f, 0.9f, 0.8f);
                        m->ct.reflection = refl;
                        m->d3d.emissive = v3(0.1f, 0.0f, 0.0f);
                        int kernel_ok = shade_batch_ct_supported(&m->ct);
                        int with_env = refl && envs[ei].kind != ENV_NONE;
                        shade_batch_fn want = !kernel_ok ? shade_batch_scalar
                                              : with_env ? shade_batch_ct_env
                                                         : shade_batch_ct_lights;
                        shade_context c;
                        shade_plan p;
                        plan_for(&s, &envs[ei], &c, &p, want);
                        char name[128];
                        snprintf(name, sizeof name, "cook-torrance norm %d g %d f %d m %g refl %d env %d", ni, gi, fi,
                                 (double)ms[mi], refl, ei);
                        /* D = exp(-tan^2/m^2 ...): both paths keep tan^2's relative precision (the
                         * kernel through |N x H|^2, the scalar path in double), but H's direction
                         * differs by ~1e-8 rad between the kernel's float and the scalar path's double
                         * normalisation, and log D moves by 2 tan(theta) dtheta / m^2 with tan(theta)
                         * up to ~3m on the lobe: a bound of 3e-7/m (3e-4 at m = 0.001, where 1.5e-4 was
                         * measured; REL from m = 0.015). */
                        const check_spec spec = {name, fmax(REL, 3e-7 / (double)ms[mi]), !kernel_ok};
                        failures += run_seeded(&c, &p, &spec, seed++, SHADE_BATCH, 4, kernel_ok ? &kernel : &scalar);
                    }
    stat_print("cook-torrance kernels (walter/ct1982, v-cavity/smith-walter, schlick/one)", &kernel);
    stat_print("cook-torrance on shade_eval (smith exact, F exact, m < 1e-6: bit-identical)", &scalar);
    assert_int_equal(failures, 0);
}

/* ---- partial batches ---- */

static void test_partial_batches(void **state)
{
    (void)state;
    const int ns[] = {0, 1, 7, 16, 63, 64};
    env_map img = make_env_image();
    int failures = 0;
    check_stat all = {{0}, 0, 0, 0};
    for (int k = 0; k < 3; k++) {
        scene s;
        base_scene(&s);
        add_three_lights(&s, SPOT_D3D);
        material *m = &s.materials[0];
        shade_batch_fn want = shade_batch_d3d_diffuse;
        if (k >= 1) {
            m->d3d.specular = v3(0.5f, 0.4f, 0.3f);
            m->d3d.power = 30.0f;
            want = shade_batch_d3d_full;
        }
        if (k == 2) {
            m->model = MODEL_D3D9CLIENT;
            m->d9.reflect = v3(0.3f, 0.2f, 0.1f);
            m->d9.sun_angle = 1;
            m->d9.p = 2.5f;
            want = shade_batch_d3d9client;
        }
        shade_context c;
        shade_plan p;
        plan_for(&s, &img, &c, &p, want);
        for (size_t i = 0; i < sizeof ns / sizeof ns[0]; i++) {
            char name[64];
            snprintf(name, sizeof name, "%s n = %d", p.path, ns[i]);
            const check_spec spec = {name, REL, 0};
            failures += run_seeded(&c, &p, &spec, 700 + (uint64_t)(k * 10) + i, ns[i], 4, &all);
        }
    }
    stat_print("partial batches (n = 0, 1, 7, 16, 63, 64; lanes past n untouched)", &all);
    assert_int_equal(failures, 0);
}

/* ---- a lane's terms do not depend on the batch it is shaded in ---- */

/* Lanes [from, from + n) of src as lanes [0, n) of dst. */
static void copy_lanes(const shade_batch_in *src, int from, int n, shade_batch_in *dst)
{
    dst->n = n;
    for (int i = 0; i < n; i++) {
        const int j = from + i;
        shade_batch_set_input(dst, i, shade_lane_get(&src->x, j), shade_lane_get(&src->nrm, j),
                              shade_lane_get(&src->v, j));
        dst->tu[i] = src->tu[j];
        dst->tv[i] = src->tv[j];
    }
}

/* SHADE_BATCH (how many samples the renderer queues per call) was chosen for speed alone:
 * renders keep every bit whatever it is only because each lane's terms are those of the same
 * lane shaded alone. One full batch against the same lanes cut into runs of 1, 16, 37 and 64
 * (every kernel the renders use, the environment image included), compared bit for bit. */
static void test_batch_length_same_bits(void **state)
{
    (void)state;
    const int runs[] = {1, 16, 37, 64};
    env_map img = make_env_image();
    int failures = 0;
    for (int k = 0; k < 4; k++) {
        scene s;
        base_scene(&s);
        add_sun(&s);
        add_point(&s);
        material *m = &s.materials[0];
        m->d3d.specular = v3(0.5f, 0.4f, 0.3f);
        m->d3d.power = 40.0f;
        m->d3d.local_viewer = 1;
        shade_batch_fn want = shade_batch_d3d_full;
        if (k == 1 || k == 2) {
            m->model = MODEL_D3D9CLIENT;
            m->d9.reflect = v3(0.3f, 0.2f, 0.1f);
            m->d9.sun_angle = k == 2;
            want = shade_batch_d3d9client;
        } else if (k == 3) {
            m->model = MODEL_COOK_TORRANCE;
            m->ct.reflection = 1;
            want = shade_batch_ct_env;
        }
        shade_context c;
        shade_plan p;
        plan_for(&s, &img, &c, &p, want);
        rng_seed(900 + (uint64_t)k);
        shade_batch_in *whole = &work.in[0], *part = &work.in[1];
        shade_batch_out *o_whole = &work.out[0], *o_part = &work.out[1];
        make_inputs(&c, p.mat, SHADE_BATCH, whole);
        shade_eval_n(&c, &p, whole, o_whole);
        for (size_t r = 0; r < sizeof runs / sizeof runs[0]; r++)
            for (int from = 0; from < SHADE_BATCH; from += runs[r]) {
                const int n = SHADE_BATCH - from < runs[r] ? SHADE_BATCH - from : runs[r];
                copy_lanes(whole, from, n, part);
                shade_eval_n(&c, &p, part, o_part);
                for (int i = 0; i < n; i++)
                    for (int term = 0; term < T_COUNT; term++) {
                        float a[3], b[3];
                        int nv = batch_values(o_whole, from + i, term, a);
                        batch_values(o_part, i, term, b);
                        for (int j = 0; j < nv; j++)
                            if (memcmp(&a[j], &b[j], sizeof a[j]) != 0 && failures++ < 5)
                                print_error("%s: lane %d, %s[%d]: %a alone in a run of %d, %a in the full batch\n",
                                            p.path, from + i, term_names[term], j, (double)b[j], runs[r], (double)a[j]);
                    }
            }
    }
    assert_int_equal(failures, 0);
}

/* ---- the user model's batch: shade_user lane by lane, bit for bit ---- */

/* FNV-1a over every byte of a model's input, as one of 4096 levels in [0, 1): a change in any bit
 * of any input (a double's last bit included, which the float terms would round away) moves the
 * level, by about a quarter on average. */
static double probe_hash(const reflcheck_user_input *in)
{
    uint64_t h = 14695981039346656037ull;
    const unsigned char *b = (const unsigned char *)in;
    for (size_t i = 0; i < sizeof *in; i++) {
        h ^= b[i];
        h *= 1099511628211ull;
    }
    return (double)(h >> 52) / 4096.0;
}

/* A model whose output shows every bit of its input (probe_hash), per channel asymmetric. */
static void probe_eval(const reflcheck_user_input *in, const double *p, reflcheck_user_output *out)
{
    const double level = probe_hash(in);
    for (int c = 0; c < 3; c++) {
        out->diffuse[c] = in->albedo[c] * (p[0] + in->n_v);
        out->specular[c] = p[1] * (1.0 + level) * (1.0 + 0.5 * c) * in->n_h;
    }
}

static const reflcheck_user_param probe_params[] = {{"base", 0.0, 2.0, 0.5, 0}, {"gloss", 0.0, 4.0, 1.0, 0}};
static const reflcheck_user_model probe_model = {REFLCHECK_USER_ABI, "probe",   "test: reads every input", 2,
                                                 probe_params,       probe_eval};

/* shade_batch_user (shade_plan.c's kernel for MODEL_USER) against shade_user on the same lanes,
 * every term compared bit for bit: the batch must be a rearrangement of the scalar arithmetic,
 * not an approximation, or a fit's figures would change. Every light kind (the point light's
 * range cuts some lanes), a point light sitting on one lane (the scalar path's double branch)
 * and lanes that face away from the viewer or the lights, at full and partial batch lengths. */
static void test_user_batch_same_bits(void **state)
{
    (void)state;
    scene s;
    base_scene(&s);
    add_three_lights(&s, SPOT_D3D);
    material *m = &s.materials[0];
    m->model = MODEL_USER;
    m->user.model = &probe_model;
    m->user.params[0] = 0.7;
    m->user.params[1] = 1.3;
    m->albedo = v3(0.6f, 0.3f, 0.1f);
    m->d3d.emissive = v3(0.02f, 0.0f, 0.01f);
    env_map none = {.kind = ENV_NONE};
    shade_context c;
    shade_plan p;
    int failures = 0, lit_lanes = 0;
    const int lengths[] = {SHADE_BATCH, 37, 1};
    for (int k = 0; k < 3; k++) {
        rng_seed(1300 + (uint64_t)k);
        shade_batch_in *in = &work.in[0];
        shade_batch_out *out = &work.out[0];
        const int n = lengths[k];
        plan_for(&s, &none, &c, &p, shade_batch_user);
        make_inputs(&c, m, n, in);
        /* Lane 0 faces away from the viewer (user_model_eval's guard), lane 1 is lit from behind,
         * lane 2 sits on a fourth light, a point light (distance 0: shade_light_incident's double
         * branch gives it no light). */
        if (n > 2) {
            shade_lane_set(&in->nrm, 0, v3_neg(shade_lane_get(&in->v, 0)));
            shade_lane_set(&in->nrm, 1, v3(0.0f, -1.0f, 0.0f));
            s.n_lights = 3;
            light *on = add_point(&s);
            on->position = shade_lane_get(&in->x, 2);
        }
        plan_for(&s, &none, &c, &p, shade_batch_user);
        fill_sentinel(out);
        shade_eval_n(&c, &p, in, out);
        for (int i = 0; i < n; i++) {
            shade_terms t;
            shade_user(&c, &p, shade_lane_get(&in->x, i), shade_lane_get(&in->nrm, i), shade_lane_get(&in->v, i), &t);
            lit_lanes += v3_max_comp(t.specular) > 0.0f;
            for (int term = 0; term < T_COUNT; term++) {
                float a[3], b[3];
                int nv = term_values(&t, term, a);
                batch_values(out, i, term, b);
                for (int j = 0; j < nv; j++)
                    if (memcmp(&a[j], &b[j], sizeof a[j]) != 0 && failures++ < 5)
                        print_error("user batch: lane %d of %d, %s[%d]: %a, shade_user %a\n", i, n, term_names[term], j,
                                    (double)b[j], (double)a[j]);
            }
        }
        s.n_lights = 3;
    }
    /* The comparison means something only where the model's lobe was reached. */
    assert_true(lit_lanes > SHADE_BATCH / 4);
    assert_int_equal(failures, 0);
}

/* ---- a lane outside the float-safe band: the whole batch from shade_eval, bit for bit ---- */

static void unsafe_case(const char *name, const scene *s, const env_map *env, shade_batch_fn want, vec3 unsafe_x,
                        int *failures)
{
    shade_context c;
    shade_plan p;
    plan_for(s, env, &c, &p, want);
    check_stat st = {{0}, 0, 0, 0};
    const check_spec spec = {name, 0.0, 1};
    for (int lanes = 1; lanes <= SHADE_BATCH; lanes += 21) {
        shade_batch_in *in = &work.in[0];
        make_inputs(&c, p.mat, lanes, in);
        /* The unsafe lane last, so every earlier lane was already computed by the kernel when
         * the batch is marked bad. */
        int u = lanes - 1;
        shade_batch_set_input(in, u, unsafe_x, v3(0.0f, 1.0f, 0.0f), v3_norm(v3_sub(c.eye, unsafe_x)));
        shade_batch_out *o = &work.out[0];
        fill_sentinel(o);
        shade_eval_n(&c, &p, in, o);
        for (int i = 0; i < lanes; i++) {
            shade_terms t;
            shade_eval(&c, &p, shade_lane_get(&in->x, i), shade_lane_get(&in->nrm, i), shade_lane_get(&in->v, i), &t);
            st.lanes++;
            st.lit += v3_sum(t.diffuse) != 0.0f;
            for (int term = 0; term < T_COUNT; term++) {
                float got[3], wantv[3];
                int k = batch_values(o, i, term, got);
                term_values(&t, term, wantv);
                for (int j = 0; j < k; j++)
                    if (memcmp(&got[j], &wantv[j], sizeof got[j]) != 0 || !isfinite(got[j]))
                        report_mismatch(&st, &spec, in, i, term, j, got[j], wantv[j], INFINITY);
            }
        }
    }
    stat_print(name, &st);
    *failures += (int)st.failures;
}

static void test_unsafe_lane_fallback(void **state)
{
    (void)state;
    rng_seed(800);
    int failures = 0;
    env_map img = make_env_image();
    /* A point light 1e-16 m above the origin (d^2 = 1e-32 < 1e-30), then one 1e16 m away
     * (d^2 = 1e32 > 1e30); the unsafe lane sits at the origin. */
    const vec3 positions[] = {{0.0f, 1e-16f, 0.0f}, {0.0f, 1e16f, 0.0f}};
    const char *const where[] = {"1e-16 m", "1e16 m"};
    for (int w = 0; w < 2; w++) {
        for (int k = 0; k < 4; k++) {
            scene s;
            base_scene(&s);
            /* k = 3: the unsafe light is the D3D9Client main light (first light, no sun);
             * otherwise a sun comes first. */
            if (k != 3)
                add_sun(&s);
            light *pt = add_point(&s);
            pt->position = positions[w];
            pt->intensity = v3(1.0f, 2.0f, 3.0f);
            add_spot(&s, SPOT_SMOOTH);
            material *m = &s.materials[0];
            shade_batch_fn want = shade_batch_d3d_diffuse;
            if (k >= 1) {
                m->d3d.specular = v3(0.5f, 0.4f, 0.3f);
                m->d3d.ambient = v3(0.1f, 0.1f, 0.1f);
                s.global_ambient = v3(0.1f, 0.1f, 0.1f);
                m->d3d.power = 30.0f;
                want = shade_batch_d3d_full;
            }
            if (k >= 2) {
                m->model = MODEL_D3D9CLIENT;
                m->d9.reflect = v3(0.3f, 0.2f, 0.1f);
                m->d9.sun_angle = 1;
                want = shade_batch_d3d9client;
            }
            char name[96];
            snprintf(name, sizeof name, "unsafe lane (light %s) %s%s", where[w],
                     k == 0 ? "d3d-diffuse" : (k == 1 ? "d3d-full" : "d3d9client"),
                     k == 3 ? " (unsafe main light)" : "");
            unsafe_case(name, &s, &img, want, v3(0.0f, 0.0f, 0.0f), &failures);
        }
    }
    assert_int_equal(failures, 0);
}

/* ---- env_lookup_n against env_lookup ---- */

/* |batch - scalar| per channel as a fraction of that channel's largest texel difference (times
 * the scale): the lookups differ by a texel-position error times the local gradient, and the
 * gradient is at most that difference per texel. Channels without texels (constant, none,
 * NULL, an image without rgb) must be bit-identical. */
typedef struct {
    double worst_pos;
    double worst_rel;
    vec3 at;
} env_stat;

static void env_check_dirs(const env_map *e, int n, const float *dx, const float *dy, const float *dz, env_stat *st,
                           int *failures)
{
    enum { CHUNK = 97 };
    float r[CHUNK], g[CHUNK], b[CHUNK];
    /* Spreads of the (scaled) channels, for the position-error measure. */
    float lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    if (e != NULL && e->kind == ENV_IMAGE && e->rgb != NULL)
        for (int i = 0; i < e->width * e->height; i++)
            for (int ch = 0; ch < 3; ch++) {
                lo[ch] = fminf(lo[ch], e->rgb[3 * i + ch]);
                hi[ch] = fmaxf(hi[ch], e->rgb[3 * i + ch]);
            }
    /* Odd chunk sizes, so the lane loop's remainder handling runs too. */
    for (int start = 0; start < n; start += CHUNK) {
        int m = n - start < CHUNK ? n - start : CHUNK;
        env_lookup_n(e, m, dx + start, dy + start, dz + start, r, g, b);
        for (int i = 0; i < m; i++) {
            vec3 d = v3(dx[start + i], dy[start + i], dz[start + i]);
            vec3 want = env_lookup(e, d);
            const float got[3] = {r[i], g[i], b[i]}, wv[3] = {want.x, want.y, want.z};
            const float sc[3] = {e != NULL ? e->scale.x : 0.0f, e != NULL ? e->scale.y : 0.0f,
                                 e != NULL ? e->scale.z : 0.0f};
            for (int ch = 0; ch < 3; ch++) {
                double diff = fabs((double)got[ch] - wv[ch]);
                int ok = isfinite(got[ch]) != 0;
                if (hi[ch] > lo[ch]) {
                    /* Error in texels of a full-spread step; and relative error. */
                    double pos = diff / ((double)(hi[ch] - lo[ch]) * fabs(sc[ch]));
                    double rel = diff / fmax(fabs(wv[ch]), 1e-30);
                    if (pos > st->worst_pos) {
                        st->worst_pos = pos;
                        st->at = d;
                    }
                    st->worst_rel = fmax(st->worst_rel, rel);
                    ok &= pos <= ENV_SPREAD_TOL;
                } else {
                    ok &= memcmp(&got[ch], &wv[ch], sizeof got[ch]) == 0;
                }
                if (!ok) {
                    if (++*failures <= 6)
                        print_error("env_lookup_n (%a, %a, %a) channel %d: batch %.9g, scalar %.9g\n", (double)d.x,
                                    (double)d.y, (double)d.z, ch, (double)got[ch], (double)wv[ch]);
                }
            }
        }
    }
}

enum { ENV_DIRS = 24000 };
static float dir_x[ENV_DIRS], dir_y[ENV_DIRS], dir_z[ENV_DIRS];

static int push_dir(int n, vec3 d)
{
    assert_true(n < ENV_DIRS);
    dir_x[n] = d.x, dir_y[n] = d.y, dir_z[n] = d.z;
    return n + 1;
}

/* Directions: axes (with signed zeros), the poles and near them, the u seam at atan2 = +-pi
 * from both sides, texel centres and edges, random directions scaled by 10^-15..10^15, and
 * zero. */
static int make_env_dirs(void)
{
    int n = 0;
    const float z = 0.0f, nz = -0.0f;
    /* Exact poles with x = -0 are left to test_env_lookup_n_pole_negative_zero. */
    const vec3 axes[] = {{1, z, z},   {-1, z, z},   {z, 1, z},  {z, -1, z},  {z, z, 1},   {z, z, -1}, {-1, nz, z},
                         {-1, z, nz}, {-1, nz, nz}, {z, 1, nz}, {z, -1, nz}, {nz, z, -1}, {1, nz, nz}};
    for (size_t i = 0; i < sizeof axes / sizeof axes[0]; i++)
        n = push_dir(n, axes[i]);
    const float tiny[] = {1e-7f, -1e-7f, 1e-20f, -1e-20f, 3e-4f, -3e-4f};
    for (size_t i = 0; i < sizeof tiny / sizeof tiny[0]; i++) {
        n = push_dir(n, v3(tiny[i], 1.0f, 0.0f));
        n = push_dir(n, v3(0.0f, -1.0f, tiny[i]));
        n = push_dir(n, v3(tiny[i], 1.0f, -tiny[i]));
        for (int k = 0; k < 5; k++) {
            float y = -0.9f + 0.45f * (float)k;
            n = push_dir(n, v3(-1.0f, y, tiny[i])); /* the seam, both sides */
            n = push_dir(n, v3(-1.0f, y, 0.0f));
            n = push_dir(n, v3(-3e5f, y, tiny[i]));
        }
    }
    /* Texel centres and edges: tx, ty on a half-texel grid. */
    for (int j = 0; j <= 2 * ENV_H; j++)
        for (int i = 0; i <= 2 * ENV_W; i++) {
            double phi = ((double)i / (2 * ENV_W) - 0.5) * 2.0 * TEST_PI;
            double lat = (0.5 - (double)j / (2 * ENV_H)) * TEST_PI;
            n = push_dir(n, v3((float)(cos(lat) * cos(phi)), (float)sin(lat), (float)(cos(lat) * sin(phi))));
        }
    n = push_dir(n, v3(0.0f, 0.0f, 0.0f));
    n = push_dir(n, v3(-0.0f, -0.0f, -0.0f));
    /* Random directions, a third unit, the others scaled by 10^-15 .. 10^15. Beyond about
     * 1e-19 and 1e19 the squared length under- or overflows in float and the two lookups
     * both go wrong, differently (1e-25: env_lookup 0, env_lookup_n a pole texel; 1e20: two
     * different wrong texels): not their domain, so not compared. */
    rng_seed(900);
    while (n < ENV_DIRS) {
        vec3 d = rng_direction();
        if (rng_unit() < 0.67f)
            d = v3_scale(d, powf(10.0f, rng_range(-15.0f, 15.0f)));
        n = push_dir(n, d);
    }
    return n;
}

static void test_env_lookup_n(void **state)
{
    (void)state;
    const int n = make_env_dirs();
    int failures = 0;
    env_map img = make_env_image();
    env_stat st = {0.0, 0.0, {0, 0, 0}};
    env_check_dirs(&img, n, dir_x, dir_y, dir_z, &st, &failures);
    print_message("# env_lookup_n vs env_lookup, 8x4 image, %d directions: worst error %.3g of a full texel step "
                  "(at (%a, %a, %a)), worst relative %.3g\n",
                  n, st.worst_pos, (double)st.at.x, (double)st.at.y, (double)st.at.z, st.worst_rel);
    /* A zero direction gives 0 in both. */
    float r, g, b;
    const float zero = 0.0f;
    env_lookup_n(&img, 1, &zero, &zero, &zero, &r, &g, &b);
    assert_true(r == 0.0f && g == 0.0f && b == 0.0f);

    /* Constant, none, NULL and an image without texels: exactly as env_lookup, zero direction
     * included. */
    env_map constant = {.kind = ENV_CONSTANT, .constant = {0.25f, 0.5f, 2.0f}};
    env_map none = {.kind = ENV_NONE, .constant = {1.0f, 1.0f, 1.0f}};
    env_map empty = {.kind = ENV_IMAGE, .scale = {1, 1, 1}, .width = ENV_W, .height = ENV_H, .rgb = NULL};
    const env_map *others[] = {&constant, &none, NULL, &empty};
    for (size_t k = 0; k < sizeof others / sizeof others[0]; k++) {
        env_stat o = {0.0, 0.0, {0, 0, 0}};
        env_check_dirs(others[k], 600, dir_x, dir_y, dir_z, &o, &failures);
    }
    assert_int_equal(failures, 0);
}

/* At an exact pole the longitude is undefined, and which column a lookup reads depends on
 * atan2's signed zeros: env_lookup takes u from atan2f(z, x), +-pi for x = -0 and z = +-0
 * (u = 1 or 0: the seam). smath_atan2 first gave 0 there (u = 0.5, the middle column), and the
 * image's top and bottom rows differ between those columns, so the lookups differed by whole
 * texels, and so did shading: a D3D9Client surface with normal (-0, 1, 0) seen from straight
 * above reflects exactly (-0, 1, 0). smath_atan2 now follows C's signed zeros. */
static void test_env_lookup_n_pole_negative_zero(void **state)
{
    (void)state;
    env_map img = make_env_image();
    const float z = 0.0f, nz = -0.0f;
    const vec3 dirs[] = {{nz, 1, z}, {nz, 1, nz}, {nz, -1, z}, {nz, -1, nz}};
    int failures = 0;
    for (size_t i = 0; i < sizeof dirs / sizeof dirs[0]; i++) {
        float r, g, b;
        env_lookup_n(&img, 1, &dirs[i].x, &dirs[i].y, &dirs[i].z, &r, &g, &b);
        vec3 want = env_lookup(&img, dirs[i]);
        print_message("# env pole (%g, %g, %g): env_lookup_n (%.9g, %.9g, %.9g), env_lookup (%.9g, %.9g, %.9g)\n",
                      (double)dirs[i].x, (double)dirs[i].y, (double)dirs[i].z, (double)r, (double)g, (double)b,
                      (double)want.x, (double)want.y, (double)want.z);
        env_stat st = {0.0, 0.0, {0, 0, 0}};
        env_check_dirs(&img, 1, &dirs[i].x, &dirs[i].y, &dirs[i].z, &st, &failures);
    }

    /* The same through shade_eval_n: one D3D9Client lane looking straight down at a surface
     * whose normal has a -0 x component. */
    scene s;
    base_scene(&s);
    add_sun(&s);
    material *m = &s.materials[0];
    m->model = MODEL_D3D9CLIENT;
    m->d9.reflect = v3(0.5f, 0.5f, 0.5f);
    shade_context c;
    shade_plan p;
    plan_for(&s, &img, &c, &p, shade_batch_d3d9client);
    shade_batch_in *in = &work.in[0];
    in->n = 1;
    shade_batch_set_input(in, 0, v3(0.0f, 0.0f, 0.0f), v3(nz, 1.0f, 0.0f), v3(0.0f, 1.0f, 0.0f));
    shade_batch_out *o = &work.out[0];
    shade_eval_n(&c, &p, in, o);
    shade_terms t;
    shade_eval(&c, &p, v3(0.0f, 0.0f, 0.0f), v3(nz, 1.0f, 0.0f), v3(0.0f, 1.0f, 0.0f), &t);
    print_message(
        "# d3d9client n = (-0, 1, 0), v = (0, 1, 0): reflection batch (%.9g, %.9g, %.9g), scalar (%.9g, %.9g, "
        "%.9g)\n",
        (double)o->reflection.x[0], (double)o->reflection.y[0], (double)o->reflection.z[0], (double)t.reflection.x,
        (double)t.reflection.y, (double)t.reflection.z);
    const float got[3] = {o->reflection.x[0], o->reflection.y[0], o->reflection.z[0]};
    const float want[3] = {t.reflection.x, t.reflection.y, t.reflection.z};
    for (int ch = 0; ch < 3; ch++)
        failures += !(fabs((double)got[ch] - want[ch]) <= REL * fabs(want[ch]));
    assert_int_equal(failures, 0);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_d3d_diffuse),
        cmocka_unit_test(test_d3d_full_specular),
        cmocka_unit_test(test_d3d_full_ambient_emissive_clamp),
        cmocka_unit_test(test_light_kinds),
        cmocka_unit_test(test_multiple_lights),
        cmocka_unit_test(test_d3d9client),
        cmocka_unit_test(test_d3d9client_dissolve),
        cmocka_unit_test(test_cook_torrance),
        cmocka_unit_test(test_partial_batches),
        cmocka_unit_test(test_batch_length_same_bits),
        cmocka_unit_test(test_unsafe_lane_fallback),
        cmocka_unit_test(test_user_batch_same_bits),
        cmocka_unit_test(test_light_edit_between_batches),
        cmocka_unit_test(test_env_lookup_n),
        cmocka_unit_test(test_env_lookup_n_pole_negative_zero),
    };
    return cmocka_run_group_tests_name("shade_batch", tests, NULL, NULL);
}
