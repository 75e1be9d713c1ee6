/* user_model_fixture.c - broken user models for tests/test_user_model.c, one per -D:
 * FIXTURE_NO_ENTRY (no entry symbol), FIXTURE_ABI_2 (built for another ABI), FIXTURE_NAN (eval
 * returns NaN at grazing light), FIXTURE_BAD_BOUNDS (a default outside its bounds),
 * FIXTURE_NULL_EVAL (no eval function). Otherwise a valid one-parameter Lambert model. */
#include <math.h>

#include "user_model.h"

static const reflcheck_user_param fx_params[] = {
#ifdef FIXTURE_BAD_BOUNDS
    {"gain", 0.0, 1.0, 2.0, 0},
#else
    {"gain", 0.0, 2.0, 1.0, 0},
#endif
};

#ifndef FIXTURE_NULL_EVAL
static void fx_eval(const reflcheck_user_input *in, const double *p, reflcheck_user_output *out)
{
    for (int c = 0; c < 3; c++)
        out->diffuse[c] = p[0] * in->albedo[c] / 3.14159265358979323846;
#ifdef FIXTURE_NAN
    /* 0/0 where the light grazes: the probe must find it. */
    if (in->n_l < 1e-3)
        out->specular[0] = (in->n_l - in->n_l) / (in->n_l - in->n_l);
#endif
}
#endif

#ifdef FIXTURE_ABI_2
#define FX_ABI 2
#else
#define FX_ABI REFLCHECK_USER_ABI
#endif
#ifdef FIXTURE_NULL_EVAL
#define FX_EVAL 0
#else
#define FX_EVAL fx_eval
#endif

static const reflcheck_user_model fx_model = {FX_ABI, "fixture", "a test fixture", 1, fx_params, FX_EVAL};

#ifndef FIXTURE_NO_ENTRY
const reflcheck_user_model *reflcheck_user_model_entry(void);
const reflcheck_user_model *reflcheck_user_model_entry(void) { return &fx_model; }
#else
const reflcheck_user_model *other_name(void);
const reflcheck_user_model *other_name(void) { return &fx_model; }
#endif
