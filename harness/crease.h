/* crease.h - the samples where a renderer's shading-normal rules depart from the model's.
 *
 * Usage:
 *   float *rules = malloc((size_t)w * (size_t)h * sizeof *rules);
 *   crease_share(&scn, &msh, w, h, k, threads, rules, err, sizeof err);   per pixel: rule bits
 *   unsigned d = crease_departs(n, ng, v);                                   one sample's rule bits
 *   crease_classify_rules(cls, rules, np, registry_row(r)->crease_rules, &interior);
 *
 * The model shades with the interpolated vertex normal N alone, turned toward the viewer. A
 * renderer that also reads the triangle's own normal Ng changes a sample whose N and Ng
 * disagree, which happens along the creases of a low-poly mesh whose vertex normals are smoothed
 * across them. Each rule is one bit; a renderer's registry row (crease_rules) names the bits it
 * has, and a rule stays here only while a render of the real program shows it and a control
 * shows none (tests/crease_renderers.sh: tests/crease_blender.py, tests/crease_povray.py):
 *   CREASE_RULE_BACK_FACE (Cycles 3.4, kernel/geom/shader_data.h): a back face flips N and Ng
 *     together, so an N that leans away from the viewer while Ng faces it stays away (the model
 *     turns it round);
 *   CREASE_RULE_VALID_REFLECTION (Cycles 3.4, kernel/closure/bsdf_util.h, for every BSDF):
 *     ensure_valid_reflection bends N toward Ng when the mirror direction R = 2 (N.V) N - V has
 *     R.Ng below min(0.9 Ng.V, 0.01).
 * Not rules: a light below the triangle (L.Ng < 0) with L.N > 0. Cycles 3.4 calls it
 * transmission by the shading normal (integrator/shade_surface.h: dot(ls.D, sd->N) < 0) and its
 * diffuse BSDF reads N alone, so it lights the sample by N.L as the model does (measured:
 * tests/crease_blender.py). POV-Ray 3.7 has none either: it flips the interpolated normal toward
 * the ray by that normal itself (render/trace.cpp, ComputeTextureColour), cuts a light off by
 * the same normal (N.L < EPSILON) and mirrors about it; its reflection fix-up reads the same
 * raw normal, so without a normal pattern it never fires (tests/crease_povray.py renders the
 * diffuse under a light; no mirror lobe). crease_departs gives the rule bits that apply to one
 * sample (unit n, ng, v pointing away from the surface; ng of either orientation). crease_share
 * rasterizes the mesh at the render's samples (render/raster.h, render/render.h's camera) and writes each pixel's rule
 * bits, the OR over its covered samples, as a float (0 where none departs or none is covered), so compare can leave
 * those pixels out of a comparison with a renderer that has those rules and report them per rule (harness/compare.c),
 * plus CREASE_TIE where a sample lies within crease_tie_band of an open edge.
 * Returns RC_OK, RC_ERR_NOMEM, or RC_ERR_RANGE with one line in err.
 */
#ifndef REFLCHECK_CREASE_H
#define REFLCHECK_CREASE_H

#include <stddef.h>
#include "mesh.h"
#include "scene.h"
#include "status.h"
#include "vec.h"

enum {
    CREASE_RULE_BACK_FACE = 1u,
    CREASE_RULE_VALID_REFLECTION = 2u,
};
#define CREASE_RULE_COUNT 2
/* The rule bits, in bit order, for reports: "back_face", "valid_reflection". */
extern const char *const crease_rule_names[CREASE_RULE_COUNT];
#define CREASE_RULES_ALL (CREASE_RULE_BACK_FACE | CREASE_RULE_VALID_REFLECTION)
/* Not a rule: the layer bit of a pixel with a sample closer to an open edge (below) than the
 * float clip-space inputs resolve, crease_tie_band: which side it falls on is rounding, ours or
 * a ray tracer's, so a twin sets such pixels apart with the edges (harness/compare.c). An open
 * edge is one where the surface seen changes: a triangle's edge that no other triangle shares by
 * vertex index from the other side on screen (a silhouette, a crack between unwelded parts, a
 * fold at an occluding contour, a hard edge whose vertices are split for their normals). */
#define CREASE_TIE       4u
#define CREASE_LAYER_MAX (CREASE_RULES_ALL | CREASE_TIE)

unsigned crease_departs(vec3 n, vec3 ng, vec3 v);
rc_status crease_share(const scene *s, const mesh *m, int width, int height, int k, int threads, float *share,
                       char *err, size_t errlen);
/* The one rule compare and fit share: each METRICS_PX_INTERIOR pixel of cls (harness/metrics.h)
 * whose layer value has a bit of rules becomes METRICS_PX_CREASE. Returns the pixels moved;
 * *interior (may be NULL) gets the interior pixels there were; per_rule (may be NULL,
 * CREASE_RULE_COUNT entries) gets, per rule of rules, the moved pixels it departs at. */
long crease_classify_rules(unsigned char *cls, const float *layer, size_t np, unsigned rules, long *interior,
                           long *per_rule);
/* The tie band in samples for a width x height image at k x k samples through s's camera:
 * 8 roundings of 2^-24 (the float chain of render_camera_clip and the perspective divide, each
 * relative to the view distance) over the half-width in samples, per unit of tan(hfov / 2). */
double crease_tie_band(const scene *s, int width, int k);
/* Each METRICS_PX_INTERIOR pixel of cls whose layer value has CREASE_TIE becomes METRICS_PX_EDGE;
 * returns the pixels moved, *interior (may be NULL) the interior pixels there were. */
long crease_classify_ties(unsigned char *cls, const float *layer, size_t np, long *interior);
/* crease_classify_rules with every rule (fit's reference has a row with some rule). */
long crease_classify(unsigned char *cls, const float *layer, size_t np, long *interior);

#endif
