/* stability_user.c - the stability rows of a user's shading model (user_model.h,
 * stability_sweep.h): NaN/Inf/negative counts, float-geometry sensitivity, directional albedo.
 */
#include "stability_sweep.h"

/* Parameter set k of a sweep: the even ones at a corner of the bounds box (bit i of k / 2 puts
 * parameter i at hi), the odd ones drawn within the bounds (log-uniform where log_scale). */
static void user_params_at(sweep *s, const reflcheck_user_model *um, long k, double *p)
{
    for (int i = 0; i < um->n_params; i++) {
        const reflcheck_user_param *q = &um->params[i];
        if (k % 2 == 0)
            p[i] = ((k / 2) >> i) & 1 ? q->hi : q->lo;
        else
            p[i] = q->log_scale ? stab_rng_log(&s->r, q->lo, q->hi) : stab_rng_range(&s->r, q->lo, q->hi);
    }
}

static dvec3 user_round(vec3 a) { return dv3_norm(dv3_from(a)); }

/* One row: case 0 grazing (N.L and N.V log-uniform down to 1e-7), 1 the peak (L the mirror of V
 * turned by up to 1e-4 rad), 2 any upper-hemisphere pair. */
static void sweep_user_case(sweep *s, const reflcheck_user_model *um, const char *fn, int which)
{
    static const char *const cases[] = {"grazing: N.L, N.V log 1e-7..1", "peak: N.H -> 1 (mirror pair)",
                                        "random pairs, params at bounds"};
    stability_row *row = stab_row_begin(s, fn, cases[which], STABILITY_APPROX, 53);
    snprintf(row->note, sizeof row->note,
             "output at float-rounded directions vs at the exact ones: the model's sensitivity to float "
             "geometry; every parameter set alternates a bounds corner and a random point");
    const dvec3 n = dv3(0, 1, 0), albedo = dv3(1.0, 0.5, 0.0);
    double p[REFLCHECK_USER_PARAMS_MAX];
    for (long i = 0; i < s->n; i++) {
        user_params_at(s, um, i, p);
        double ph = stab_rng_range(&s->r, 0.0, 2.0 * (double)REF_PI);
        double cv = which == 0 ? stab_rng_log(&s->r, 1e-7, 1.0) : stab_rng_range(&s->r, 1e-3, 1.0);
        double cl = which == 0 ? stab_rng_log(&s->r, 1e-7, 1.0) : stab_rng_range(&s->r, 1e-3, 1.0);
        vec3 vf = stab_dir_at(cv, ph),
             lf = which == 1 ? stab_dir_at(cv, ph + (double)REF_PI + stab_rng_range(&s->r, -1e-4, 1e-4))
                             : stab_dir_at(cl, stab_rng_range(&s->r, 0.0, 2.0 * (double)REF_PI));
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
    stab_row_end(row);
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
    stability_row *row =
        stab_row_begin(s, fn, "max directional albedo (specular), bounds corners", STABILITY_PHYSICS, 0);
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

void stab_sweep_user(sweep *s, const reflcheck_user_model *um, int grid)
{
    char fn[40];
    snprintf(fn, sizeof fn, "user[%s]", um->name);
    for (int which = 0; which < 3; which++)
        sweep_user_case(s, um, fn, which);
    check_user_albedo(s, um, fn, grid);
}
