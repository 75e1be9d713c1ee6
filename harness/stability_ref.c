/* stability_ref.c - the long double references of the stability sweeps (stability_sweep.h).
 *
 * Each stab_ref_* function restates one model function's documented formula, guards and caps in
 * long double, from the same float inputs. Where a formula cancels (1 - c, cos_i - eta cos_t)
 * the reference cancels in the same place, so its error grows by the same factor as the
 * function's; the ratio stays 2^-40 (float results) or 2^-11 (double results), which still
 * resolves 0.01 ulp.
 */
#include <string.h>

#include "d3d9client.h"
#include "formula.h"
#include "microfacet.h"
#include "stability_sweep.h"

ld stab_ref_clamp(ld x, ld lo, ld hi) { return x < lo ? lo : (x > hi ? hi : x); }
static ld ref_satf(ld x) { return formula_sat_l(x); }

ld stab_ref_r0(ld n) { return formula_r0_l(n); }

ld stab_ref_schlick(ld f0, ld c) { return ref_satf(formula_schlick_l(f0, c)); }

ld stab_ref_d3d9(ld r0, ld m, ld p, ld c)
{
    return ref_satf(formula_d3d9_fresnel_l(r0, m, powl(formula_one_minus_cos_l(c), formula_d3d9_power_l(p))));
}

ld stab_ref_dielectric(ld cos_i, ld eta)
{
    if (!(eta > 0))
        return 1;
    if (cos_i < 0) {
        cos_i = -cos_i;
        eta = 1 / eta;
    }
    return formula_fresnel_dielectric_l(stab_ref_clamp(cos_i, 0, 1), eta);
}

ld stab_ref_conductor(ld cos_i, ld eta, ld k)
{
    return formula_fresnel_conductor_l(stab_ref_clamp(fabsl(cos_i), 0, 1), fabsl(eta), fabsl(k));
}

ld stab_ref_beckmann(ld c, ld m, ct_normalisation norm)
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

ld stab_ref_vcavity(ld nh, ld nv, ld nl, ld vh) { return formula_vcavity_g_l(nh, nv, nl, vh); }

ld stab_ref_smith_g1_walter(ld c, ld m) { return formula_smith_g1_walter_l(c, m); }

ld stab_ref_smith_g1_exact(ld c, ld m) { return formula_smith_g1_exact_l(c, m); }

ld stab_ref_attenuation(const light *l, ld d)
{
    if (l->kind == LIGHT_SUN)
        return 1;
    return formula_attenuation_l(l->a0, l->a1, l->a2, d, d * d, l->range);
}

ld stab_ref_spot(const light *l, ld3 dir)
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

ld stab_ref_lambert(ld n_l) { return formula_d3d_lambert_l(n_l); }

ld stab_ref_blinn(ld n_h, ld power) { return formula_blinn_l(n_h, power); }

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

ref_d9 stab_ref_d3d9client(const d3d9client_params *p, ld3 d, ld da, ld3 phi, ld n_v, ld n_sun)
{
    ref_d9 r;
    ld R = stab_ref_d3d9(p->r0, p->m, p->p, n_v);
    ld3 lam = l3_from(p->reflect), s = l3_from(p->fresnel_colour);
    r.r_tot = l3(formula_d3d9_r_tot_l(lam.x, s.x, R, phi.x), formula_d3d9_r_tot_l(lam.y, s.y, R, phi.y),
                 formula_d3d9_r_tot_l(lam.z, s.z, R, phi.z));
    r.weight = formula_d3d9_diffuse_weight_l(ref_colour_norm(lam, p->norm));
    ld dw = p->sun_angle ? r.weight * formula_d3d9_sun_factor_l(stab_ref_d3d9(p->r0, p->m, p->p, n_sun)) : r.weight;
    r.rgb = l3(formula_d3d9_colour_l(d.x, dw, r.r_tot.x), formula_d3d9_colour_l(d.y, dw, r.r_tot.y),
               formula_d3d9_colour_l(d.z, dw, r.r_tot.z));
    r.alpha = formula_d3d9_alpha_l(da, ref_colour_norm(r.r_tot, p->norm));
    return r;
}

ld3 stab_ref_ct_fresnel(const ct_params *p, ld c, const material *mat)
{
    if (p->f == F_ONE)
        return l3(1, 1, 1);
    if (p->f == F_EXACT && mat) {
        if (mat->conductor)
            return l3(stab_ref_conductor(c, mat->eta.x, mat->k.x), stab_ref_conductor(c, mat->eta.y, mat->k.y),
                      stab_ref_conductor(c, mat->eta.z, mat->k.z));
        ld f = stab_ref_dielectric(c, mat->ior);
        return l3(f, f, f);
    }
    return l3(stab_ref_schlick(p->f0.x, c), stab_ref_schlick(p->f0.y, c), stab_ref_schlick(p->f0.z, c));
}

static ld ref_ct_g(const ct_params *p, ld nh, ld nv, ld nl, ld vh)
{
    switch (p->g) {
    case G_SMITH_WALTER: return stab_ref_smith_g1_walter(nv, p->m) * stab_ref_smith_g1_walter(nl, p->m);
    case G_SMITH_EXACT: return stab_ref_smith_g1_exact(nv, p->m) * stab_ref_smith_g1_exact(nl, p->m);
    case G_VCAVITY:
    default: return stab_ref_vcavity(nh, nv, nl, vh);
    }
}

ld3 stab_ref_ct_specular(const ct_params *p, ld3 n, ld3 v, ld3 l, const material *mat)
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
    ld n_h = l3_dot(nd, h), v_h = stab_ref_clamp(l3_dot(vd, h), 0, 1);
    ld d = stab_ref_beckmann(n_h, p->m, p->norm);
    ld g = ref_ct_g(p, n_h, n_v, n_l, v_h);
    ld3 r = l3_scale(l3_mul(l3_from(p->ks), stab_ref_ct_fresnel(p, v_h, mat)),
                     formula_ct_lobe_l(d, g, formula_ct_k_l(p->norm != CT_CT1982), n_v));
    ld cap = COOKTORRANCE_MAX;
    return l3(stab_ref_clamp(r.x, -cap, cap), stab_ref_clamp(r.y, -cap, cap), stab_ref_clamp(r.z, -cap, cap));
}
/* ----------------------------------------------------------------------- shade_eval */

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
    ld a = stab_ref_attenuation(l, dist) * stab_ref_spot(l, l3_scale(*to_l, -1));
    *e_perp = l3_scale(l3_from(l->intensity), a);
    return a > 0;
}

void stab_ref_shade(const scene *sc, vec3 env_const, const material *m, vec3 xf, vec3 nf, vec3 vf, ref_terms *o)
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
            spec = l3_add(spec, l3_mul(stab_ref_ct_specular(&m->ct, n, v, to_l, m), e));
        }
        o->diffuse = diffuse;
        o->specular = spec;
        ld3 refl = l3_sub(l3_scale(n, 2 * l3_dot(n, v)), v);
        if (m->ct.reflection && l3_dot(refl, refl) > 0)
            o->reflection =
                l3_mul(l3_from(env_const), stab_ref_ct_fresnel(&m->ct, stab_ref_clamp(l3_dot(n, v), 0, 1), m));
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
        ld atten = l->kind == LIGHT_SUN ? 1
                                        : stab_ref_attenuation(l, l3_len(l3_sub(l3_from(l->position), x))) *
                                              stab_ref_spot(l, l3_scale(to_l, -1));
        diffuse = l3_add(diffuse, l3_scale(l3_mul(l3_from(d->ambient), l3_from(l->ambient)), atten));
        ld n_l = l3_dot(n, to_l);
        if (n_l <= 0)
            continue;
        ld3 colour = l3_scale(e, 1 / REF_PI);
        diffuse = l3_add(diffuse, l3_scale(l3_mul(l3_from(d->diffuse), colour), stab_ref_lambert(n_l)));
        ld3 h = ref_half(to_l, d->local_viewer ? v : e_inf);
        spec = l3_add(spec, l3_scale(l3_mul(l3_from(d->specular), colour), stab_ref_blinn(l3_dot(n, h), d->power)));
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
    ref_d9 r = stab_ref_d3d9client(&m->d9, diffuse, m->d9.alpha, phi, l3_dot(n, v), n_sun);
    o->diffuse = l3_sub(r.rgb, r.r_tot);
    o->reflection = r.r_tot;
    o->alpha = r.alpha;
}
