/* shade_batch_d3d.c - the D3D fixed-function kernels (docs/models.md §1): diffuse only, and
 * diffuse + specular + ambient. The lit pass (sb_d3d_lit) is shade_batch_lanes.h's, shared with
 * the D3D9Client kernels; shade_batch.c says how the kernels work and when they fall back. */
#include "shade_batch_lanes.h"

/* shade.c's shade_d3d_impl over a batch: sb_d3d_lit, then no reflection and alpha 1. */
SB_INLINE int sb_d3d(const shade_context *c, const material *m, const shade_batch_in *restrict in,
                     shade_batch_out *restrict out, const int specular, const int ambient)
{
    const int bad = sb_d3d_lit(c, m, in, out, specular, ambient), n = in->n;
    const vec3 emission = sb_d3d_emission(&m->d3d);
#pragma omp simd
    for (int i = 0; i < n; i++) {
        shade_lane_set(&out->reflection, i, v3s(0.0f));
        shade_lane_set(&out->emission, i, emission);
        out->alpha[i] = 1.0f;
    }
    return bad;
}

SMATH_CLONES
void shade_batch_d3d_diffuse(const shade_context *c, const shade_plan *p, const shade_batch_in *in,
                             shade_batch_out *out)
{
    if (sb_d3d(c, p->mat, in, out, 0, 0))
        shade_batch_scalar(c, p, in, out);
}

SMATH_CLONES
void shade_batch_d3d_full(const shade_context *c, const shade_plan *p, const shade_batch_in *in, shade_batch_out *out)
{
    if (sb_d3d(c, p->mat, in, out, 1, 1))
        shade_batch_scalar(c, p, in, out);
}
