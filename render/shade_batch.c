/* shade_batch.c - the batch kernels' scalar fallback and per-light set-up.
 *
 * The kernels (shade.c's D3D, D3D9Client and Cook-Torrance paths over structure-of-arrays
 * batches) are in shade_batch_d3d.c, shade_batch_d3d9.c and shade_batch_ct.c, one file per
 * model family so that they compile in parallel; the lane helpers they share are in
 * shade_batch_lanes.h. Each kernel runs the light loop outside and the lanes inside, so a lane
 * loop has no branch that depends on the light or the material (those are chosen before it
 * starts) and compiles to straight SIMD code: one sample per lane, selects for the per-sample
 * conditions that shade.c writes as `if`/`continue`, smath for pow, log, exp and atan2. Every
 * formula is formula.h's lane instance (suffix _v), the very code the scalar models run in
 * double (_d) and the stability check in long double (_l), with the scalar models' order of
 * guards; what differs is float where the scalar path sums in double, and smath's
 * approximations, which is why lanes match shade_eval within the bounds shade.h states rather
 * than bit for bit (tests/test_shade_batch.c measures them).
 *
 * A lane outside the float-safe range of the point-light distance (the scalar path switches
 * to double there) marks the batch, and the whole batch is redone by shade_batch_scalar;
 * grazing or non-unit Cook-Torrance lanes are redone one by one (sb_scalar_lane). */
#include "shade_batch_lanes.h"

#include <math.h>
#include <stdint.h>

/* Lane i from shade_eval. */
void sb_scalar_lane(const shade_context *c, const shade_plan *p, const shade_batch_in *in, shade_batch_out *out, int i)
{
    shade_terms t;
    vec3 x = shade_lane_get(&in->x, i), n = shade_lane_get(&in->nrm, i), v = shade_lane_get(&in->v, i);
    if (p->fn_uv != NULL)
        p->fn_uv(c, p, x, n, v, in->tu[i], in->tv[i], &t);
    else
        p->fn(c, p, x, n, v, &t);
    shade_batch_set_terms(out, i, &t);
}

void shade_batch_scalar(const shade_context *c, const shade_plan *p, const shade_batch_in *in, shade_batch_out *out)
{
    for (int i = 0; i < in->n; i++)
        sb_scalar_lane(c, p, in, out, i);
}

static sb_light sb_light_compute(const light *l)
{
    sb_light b = {v3s(0.0f), v3s(0.0f), 0.0f, 0.0f, 0.0f, 1.0f};
    b.to_sun = v3_neg(v3_norm(l->direction));
    b.axis = v3_from_d(dv3_norm(dv3_from(l->direction)));
    b.cos_in = (float)cos(0.5 * (double)l->inner);
    b.cos_out = (float)cos(0.5 * (double)l->outer);
    b.falloff = l->falloff;
    b.cone = formula_spot_cone_f(b.cos_in, b.cos_out);
    return b;
}

/* sb_light_compute depends on the light's direction, cone angles and falloff alone; a batch of
 * 64 lanes recomputed its two double cosines per light (2 % of a frame), so the last few
 * lights' results are kept per thread and reused while those fields are unchanged (compared
 * by value, so an edited or reused light struct is never served a stale entry). */
#define SB_LIGHT_CACHE 4
typedef struct {
    vec3 direction;
    float inner, outer, falloff;
    sb_light b;
    int used;
} sb_light_entry;

/* Bit equality (a NaN equals itself, -0 differs from +0): the entry is reused only where
 * sb_light_compute would see the very same input bits. */
static int sb_same_bits(float a, float b)
{
    union {
        float f;
        uint32_t u;
    } x = {a}, y = {b};
    return x.u == y.u;
}

static int sb_light_same(const sb_light_entry *e, const light *l)
{
    return e->used && sb_same_bits(e->direction.x, l->direction.x) && sb_same_bits(e->direction.y, l->direction.y) &&
           sb_same_bits(e->direction.z, l->direction.z) && sb_same_bits(e->inner, l->inner) &&
           sb_same_bits(e->outer, l->outer) && sb_same_bits(e->falloff, l->falloff);
}

sb_light sb_light_make(const light *l)
{
    static _Thread_local sb_light_entry cache[SB_LIGHT_CACHE];
    static _Thread_local int next;
    for (int i = 0; i < SB_LIGHT_CACHE; i++)
        if (sb_light_same(&cache[i], l))
            return cache[i].b;
    sb_light_entry *e = &cache[next];
    next = (next + 1) % SB_LIGHT_CACHE;
    *e = (sb_light_entry){l->direction, l->inner, l->outer, l->falloff, sb_light_compute(l), 1};
    return e->b;
}
