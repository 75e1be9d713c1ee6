/* user_load.h - loading a user's shading model (model/user_model.h) and evaluating it.
 *
 * Usage:
 *   const reflcheck_user_model *um;
 *   if (user_model_load("build/examples/ggx/ggx.so", &um, err, sizeof err) != RC_OK) ...
 *   int i = user_model_param_index(um, "roughness");          -1 when the model has none
 *   if (user_model_check_value(um, path, i, 0.3, err, sizeof err) != RC_OK) ...   within bounds
 *   if (user_model_probe(um, path, values, err, sizeof err) != RC_OK) ...   NaN, Inf or < 0 anywhere
 *   user_model_eval(um, values, n, v, l, albedo, &out);       BRDF at one (N, V, L)
 *
 * Loading is code execution by design: dlopen runs the object's constructors and reflcheck calls
 * its code. It happens only for a path a scene file or the command line names (never a search
 * path: a name without '/' is taken as ./name). The object stays loaded until the process ends,
 * so the description the entry returns may be kept in scenes. Loading the same file twice gives
 * the same description (dlopen counts references).
 * Every error is one line naming the file and the fix.
 */
#ifndef REFLCHECK_USER_LOAD_H
#define REFLCHECK_USER_LOAD_H

#include <math.h>
#include <stddef.h>

#include "status.h"
#include "user_model.h"
#include "vec.h"

/* dlopen (RTLD_NOW, so a missing symbol fails here and not mid-render), then the entry symbol,
 * the ABI version and the description (names, bounds, defaults, eval). RC_ERR_IO for a file that
 * cannot be loaded, RC_ERR_PARSE for no entry symbol or a bad description, RC_ERR_RANGE for
 * another ABI version. */
rc_status user_model_load(const char *path, const reflcheck_user_model **out, char *err, size_t errlen);

/* The index of the parameter called name, or -1. */
int user_model_param_index(const reflcheck_user_model *m, const char *name);

/* RC_ERR_RANGE unless value is finite and within parameter i's bounds (the message names path,
 * the parameter, its bounds). */
rc_status user_model_check_value(const reflcheck_user_model *m, const char *path, int i, double value, char *err,
                                 size_t errlen);

/* The model's defaults into values[0..n_params-1]. */
void user_model_defaults(const reflcheck_user_model *m, double *values);

/* Calls eval on a grid of directions (N.L and N.V from 1 down to 1e-4, the highlight's peak and
 * its tail, grazing pairs) at the given parameter values and, one parameter at a time, at each
 * of its bounds; RC_ERR_RANGE with the first input that gave NaN, Inf or a negative value. */
rc_status user_model_probe(const reflcheck_user_model *m, const char *path, const double *values, char *err,
                           size_t errlen);

/* The BRDF at unit n, v, l (pointing away from the surface): 0 and out zeroed when N.L <= 0 or
 * N.V <= 0 (eval is not called), else 1 with eval's output. */
int user_model_eval(const reflcheck_user_model *m, const double *values, dvec3 n, dvec3 v, dvec3 l, dvec3 albedo,
                    reflcheck_user_output *out);

/* user_model_eval's two steps on plain numbers, for a caller that takes the geometry over many
 * samples at once (render/shade.c's batch form) and must give eval the same bits. */

/* The unit half vector of unit l and v; with N.L > 0 and N.V > 0, |L + V| > 0 unless both graze
 * exactly, and then H is N's limit. */
static inline dvec3 user_model_half(dvec3 n, dvec3 v, dvec3 l)
{
    dvec3 hs = dv3_add(l, v);
    double hl = dv3_len(hs);
    return hl > 0.0 ? dv3_scale(hs, 1.0 / hl) : n;
}

/* eval's input but the albedo, from the unit vectors, h = user_model_half(n, v, l) and the
 * cosines n_l = N.L > 0, n_v = N.V > 0: clamped to [0, 1] as the header promises (rounding can
 * leave it by an ulp). Element by element: a loop over {n, v, l, h} through a local array
 * stalled on store forwarding in the batch. */
static inline void user_model_input(reflcheck_user_input *in, dvec3 n, dvec3 v, dvec3 l, dvec3 h, double n_l,
                                    double n_v)
{
    in->n_l = fmin(n_l, 1.0);
    in->n_v = fmin(n_v, 1.0);
    in->n_h = fmin(fmax(dv3_dot(n, h), 0.0), 1.0);
    in->v_h = fmin(fmax(dv3_dot(v, h), 0.0), 1.0);
    in->n[0] = n.x, in->n[1] = n.y, in->n[2] = n.z;
    in->v[0] = v.x, in->v[1] = v.y, in->v[2] = v.z;
    in->l[0] = l.x, in->l[1] = l.y, in->l[2] = l.z;
    in->h[0] = h.x, in->h[1] = h.y, in->h[2] = h.z;
}

#endif
