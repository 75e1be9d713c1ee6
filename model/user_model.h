/* user_model.h - the interface of a user's own shading model, built as a shared object that a
 * scene names (docs/user_models.md). The only reflcheck header a model includes; it needs no
 * other file of the project and no library.
 *
 * Usage (the whole of a model; examples/ggx/ggx.c is a complete one):
 *   #include "user_model.h"
 *   static const reflcheck_user_param params[] = {
 *       {"roughness", 0.02, 1.0, 0.5, 1},          name, lo, hi, default, log_scale
 *   };
 *   static void eval(const reflcheck_user_input *in, const double *p, reflcheck_user_output *out)
 *   { ... out->diffuse[c] = in->albedo[c] / M_PI; out->specular[c] = ...; }
 *   static const reflcheck_user_model model = {REFLCHECK_USER_ABI, "mine", "what it is", 1, params, eval};
 *   const reflcheck_user_model *reflcheck_user_model_entry(void) { return &model; }
 *   cc -shared -fPIC -O2 -Imodel mine.c -o mine.so
 * and in the scene: materials: {m: {model: user, user: {path: mine.so, params: {roughness: 0.3}}}}.
 *
 * Convention (docs/conventions.md): every direction is a unit vector in the world frame pointing
 * away from the surface: N the shading normal (already turned toward the viewer), V to the
 * viewer, L to the light, H = normalize(L + V). reflcheck calls eval only where N.L > 0 and
 * N.V > 0, once per light and sample, and gives the cosines it computed beside the vectors.
 * eval returns the BRDF f [1/sr] (no cosine, no light): reflcheck multiplies it by the light's
 * irradiance at normal incidence E [W/m^2] (a point light's I/d^2, a sun's E) and by N.L, so
 * the outgoing radiance is f E N.L, in the scene's radiometric units (a Lambert surface of albedo
 * rho is rho/pi). The two halves are reported as the diffuse and the specular terms.
 * albedo is the material's diffuse colour d (the scene's `albedo`, linear RGB).
 * eval must be a pure function of its arguments (it is called from several threads at once) and
 * return finite values >= 0 for every input in the ranges above and parameters within their
 * bounds: reflcheck probes it on load and refuses a model that returns NaN, Inf or < 0.
 * Only lights reach a user model: it has no environment term and no emission of its own (the
 * material's d3d emissive colour is added as for every model).
 */
#ifndef REFLCHECK_USER_MODEL_H
#define REFLCHECK_USER_MODEL_H

/* The interface's version. reflcheck refuses a model built against another one; a change to any
 * struct below raises it. */
#define REFLCHECK_USER_ABI 1

/* The entry symbol reflcheck looks up with dlsym: a function returning the model's description
 * (a pointer to static data, read once per load). */
#define REFLCHECK_USER_ENTRY "reflcheck_user_model_entry"

/* Parameters per model: enough for a roughness, an F0 per channel and a few shape terms. */
#define REFLCHECK_USER_PARAMS_MAX 8

typedef struct {
    /* 1..31 characters of a-z 0-9 _ (the key in the scene's user.params, in fit records and
     * stability rows), unique within the model. */
    const char *name;
    double lo, hi; /* bounds, finite, lo < hi: a scene value outside them is refused, fit searches
                      within them, the stability sweep runs at both */
    double def;    /* the value when the scene gives none; within [lo, hi] */
    int log_scale; /* 1: the parameter acts multiplicatively (a roughness, a power), so fit scales
                      it as log(value); then lo > 0 */
} reflcheck_user_param;

typedef struct {
    double n_l, n_v, n_h, v_h; /* cosines; N.L and N.V in (0, 1], N.H in (0, 1], V.H in [0, 1] */
    double n[3], v[3], l[3], h[3];
    double albedo[3]; /* the material's diffuse colour d, linear RGB */
} reflcheck_user_input;

typedef struct {
    double diffuse[3];  /* BRDF [1/sr] of the part reported as the diffuse term */
    double specular[3]; /* BRDF [1/sr] of the part reported as the specular term */
} reflcheck_user_output;

/* params: the model's n_params values, in the order of its params array. out is zeroed before
 * the call. */
typedef void (*reflcheck_user_eval_fn)(const reflcheck_user_input *in, const double *params,
                                       reflcheck_user_output *out);

typedef struct reflcheck_user_model {
    int abi;                            /* REFLCHECK_USER_ABI as the model was built */
    const char *name;                   /* short, for reports */
    const char *description;            /* one line: the model and its source */
    int n_params;                       /* 0..REFLCHECK_USER_PARAMS_MAX */
    const reflcheck_user_param *params; /* n_params entries */
    reflcheck_user_eval_fn eval;
} reflcheck_user_model;

typedef const reflcheck_user_model *(*reflcheck_user_entry_fn)(void);

#endif
