#include "user_load.h"

#include <dlfcn.h>
#include <math.h>
#include <stdio.h>
#include <string.h>

/* The fix every load error ends with: what the object must export. */
#define UL_FIX_ENTRY                                                                                                   \
    "export 'const reflcheck_user_model *" REFLCHECK_USER_ENTRY "(void)' (model/user_model.h, docs/user_models.md)"

static int ul_name_ok(const char *s)
{
    size_t n = s != NULL ? strlen(s) : 0;
    if (n == 0 || n > 31)
        return 0;
    for (size_t i = 0; i < n; i++)
        if (!((s[i] >= 'a' && s[i] <= 'z') || (s[i] >= '0' && s[i] <= '9') || s[i] == '_'))
            return 0;
    return 1;
}

/* The description's own checks: what fit, the sweep and the scene parser rely on. */
static rc_status ul_check_description(const reflcheck_user_model *m, const char *path, char *err, size_t errlen)
{
    if (m->n_params < 0 || m->n_params > REFLCHECK_USER_PARAMS_MAX || (m->n_params > 0 && m->params == NULL) ||
        m->eval == NULL || m->name == NULL) {
        status_message(err, errlen,
                       "%s: the model description has %s; give a name, an eval function and 0..%d parameters "
                       "(model/user_model.h)",
                       path,
                       m->eval == NULL   ? "no eval function"
                       : m->name == NULL ? "no name"
                                         : "a bad n_params",
                       REFLCHECK_USER_PARAMS_MAX);
        return RC_ERR_PARSE;
    }
    for (int i = 0; i < m->n_params; i++) {
        const reflcheck_user_param *p = &m->params[i];
        if (!ul_name_ok(p->name)) {
            status_message(err, errlen, "%s: params[%d]: name '%s' is not 1..31 characters of a-z 0-9 _; rename it",
                           path, i, p->name != NULL ? p->name : "(null)");
            return RC_ERR_PARSE;
        }
        for (int j = 0; j < i; j++)
            if (strcmp(m->params[j].name, p->name) == 0) {
                status_message(err, errlen, "%s: params[%d]: name '%s' is given twice; give each parameter its own",
                               path, i, p->name);
                return RC_ERR_PARSE;
            }
        if (!(isfinite(p->lo) && isfinite(p->hi) && p->lo < p->hi && p->def >= p->lo && p->def <= p->hi) ||
            (p->log_scale && !(p->lo > 0.0))) {
            status_message(err, errlen,
                           "%s: params[%d] '%s': bounds [%g, %g], default %g%s; give finite lo < hi with the default "
                           "between them (lo > 0 for log_scale)",
                           path, i, p->name, p->lo, p->hi, p->def, p->log_scale ? ", log_scale" : "");
            return RC_ERR_PARSE;
        }
    }
    return RC_OK;
}

rc_status user_model_load(const char *path, const reflcheck_user_model **out, char *err, size_t errlen)
{
    char local[4096];
    *out = NULL;
    /* A name without '/' would make dlopen search the library path: only the named file loads. */
    snprintf(local, sizeof local, "%s%s", strchr(path, '/') != NULL ? "" : "./", path);
    dlerror();
    void *h = dlopen(local, RTLD_NOW | RTLD_LOCAL);
    if (h == NULL) {
        const char *why = dlerror();
        status_message(err, errlen,
                       "%s: cannot load the user model: %s; build it as a shared object (cc -shared -fPIC)", path,
                       why != NULL ? why : "dlopen failed");
        return RC_ERR_IO;
    }
    /* ISO C has no conversion from an object pointer to a function pointer; POSIX guarantees
     * dlsym's result converts, and copying the bytes is the form it recommends. */
    void *sym = dlsym(h, REFLCHECK_USER_ENTRY);
    if (sym == NULL) {
        status_message(err, errlen, "%s: no symbol '%s'; %s", path, REFLCHECK_USER_ENTRY, UL_FIX_ENTRY);
        return RC_ERR_PARSE;
    }
    reflcheck_user_entry_fn entry;
    memcpy(&entry, &sym, sizeof entry);
    const reflcheck_user_model *m = entry();
    if (m == NULL) {
        status_message(err, errlen, "%s: %s() returned NULL; return a pointer to the model's static description", path,
                       REFLCHECK_USER_ENTRY);
        return RC_ERR_PARSE;
    }
    if (m->abi != REFLCHECK_USER_ABI) {
        status_message(err, errlen,
                       "%s: built for user-model ABI %d, this reflcheck has ABI %d; rebuild it against this "
                       "reflcheck's model/user_model.h",
                       path, m->abi, REFLCHECK_USER_ABI);
        return RC_ERR_RANGE;
    }
    rc_status rc = ul_check_description(m, path, err, errlen);
    if (rc == RC_OK)
        *out = m;
    return rc;
}

int user_model_param_index(const reflcheck_user_model *m, const char *name)
{
    for (int i = 0; i < m->n_params; i++)
        if (strcmp(m->params[i].name, name) == 0)
            return i;
    return -1;
}

rc_status user_model_check_value(const reflcheck_user_model *m, const char *path, int i, double value, char *err,
                                 size_t errlen)
{
    const reflcheck_user_param *p = &m->params[i];
    if (isfinite(value) && value >= p->lo && value <= p->hi)
        return RC_OK;
    status_message(err, errlen, "%s: parameter '%s' = %g is outside the model's bounds; give a value in [%g, %g]", path,
                   p->name, value, p->lo, p->hi);
    return RC_ERR_RANGE;
}

void user_model_defaults(const reflcheck_user_model *m, double *values)
{
    for (int i = 0; i < m->n_params; i++)
        values[i] = m->params[i].def;
}

int user_model_eval(const reflcheck_user_model *m, const double *values, dvec3 n, dvec3 v, dvec3 l, dvec3 albedo,
                    reflcheck_user_output *out)
{
    memset(out, 0, sizeof *out);
    const double n_l = dv3_dot(n, l), n_v = dv3_dot(n, v);
    if (!(n_l > 0.0 && n_v > 0.0))
        return 0;
    reflcheck_user_input in;
    user_model_input(&in, n, v, l, user_model_half(n, v, l), n_l, n_v);
    in.albedo[0] = albedo.x;
    in.albedo[1] = albedo.y;
    in.albedo[2] = albedo.z;
    m->eval(&in, values, out);
    return 1;
}

/* The first output that is not finite and >= 0: its name in what, or 0 when all are. */
static int ul_bad_output(const reflcheck_user_output *o, char *what, size_t len)
{
    for (int c = 0; c < 3; c++) {
        const double *d[2] = {o->diffuse, o->specular};
        for (int k = 0; k < 2; k++)
            if (!(isfinite(d[k][c]) && d[k][c] >= 0.0)) {
                snprintf(what, len, "%s %s[%d]",
                         isnan(d[k][c])   ? "NaN"
                         : isinf(d[k][c]) ? "Inf"
                                          : "a negative value",
                         k ? "specular" : "diffuse", c);
                return 1;
            }
    }
    return 0;
}

/* The probe's cosines: normal incidence down to grazing (1e-4: N.L at 89.994 degrees). */
static const double ul_cosines[] = {1.0, 0.9, 0.5, 0.1, 1e-2, 1e-4};
#define UL_NCOS ((int)(sizeof ul_cosines / sizeof ul_cosines[0]))

static rc_status ul_probe_at(const reflcheck_user_model *m, const char *path, const double *values, char *err,
                             size_t errlen)
{
    /* Azimuth 0 puts L on V's side (back-scatter), pi opposite (the mirror pair at equal
     * cosines: N.H = 1, the highlight's peak). */
    static const double phis[] = {0.0, 1.5707963267948966, 3.141592653589793};
    const dvec3 n = dv3(0, 0, 1), albedo = dv3(1.0, 0.5, 0.0);
    for (int iv = 0; iv < UL_NCOS; iv++)
        for (int il = 0; il < UL_NCOS; il++)
            for (int ip = 0; ip < 3; ip++) {
                double cv = ul_cosines[iv], cl = ul_cosines[il];
                dvec3 v = dv3(sqrt(fmax(0.0, 1.0 - cv * cv)), 0.0, cv);
                double sl = sqrt(fmax(0.0, 1.0 - cl * cl));
                dvec3 l = dv3(sl * cos(phis[ip]), sl * sin(phis[ip]), cl);
                reflcheck_user_output o;
                char what[64];
                if (!user_model_eval(m, values, n, v, l, albedo, &o) || !ul_bad_output(&o, what, sizeof what))
                    continue;
                char pv[256] = "";
                size_t used = 0;
                for (int i = 0; i < m->n_params && used < sizeof pv; i++)
                    used += (size_t)snprintf(pv + used, sizeof pv - used, " %s=%g", m->params[i].name, values[i]);
                status_message(err, errlen,
                               "%s: eval returned %s at N.L %g, N.V %g, azimuth %g deg,%s; fix the model to return "
                               "finite values >= 0 for N.L, N.V in (0, 1] and parameters within their bounds",
                               path, what, cl, cv, phis[ip] * 57.29577951308232, pv);
                return RC_ERR_RANGE;
            }
    return RC_OK;
}

rc_status user_model_probe(const reflcheck_user_model *m, const char *path, const double *values, char *err,
                           size_t errlen)
{
    rc_status rc = ul_probe_at(m, path, values, err, errlen);
    double at[REFLCHECK_USER_PARAMS_MAX];
    for (int i = 0; rc == RC_OK && i < m->n_params; i++)
        for (int b = 0; rc == RC_OK && b < 2; b++) {
            memcpy(at, values, sizeof(double) * (size_t)m->n_params);
            at[i] = b ? m->params[i].hi : m->params[i].lo;
            rc = ul_probe_at(m, path, at, err, errlen);
        }
    return rc;
}
