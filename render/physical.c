#include "physical.h"

#include <math.h>
#include <stdio.h>

#include "formula.h"
#include "fresnel.h"
#include "microfacet.h"

int physical_light_incident(const light *l, dvec3 x, dvec3 *to_light, dvec3 *e_perp)
{
    *to_light = dv3(0, 0, 0);
    *e_perp = dv3(0, 0, 0);
    if (l->kind == LIGHT_SUN) {
        *to_light = dv3_scale(dv3_norm(dv3_from(l->direction)), -1.0);
        *e_perp = dv3_from(l->intensity);
        return 1;
    }
    dvec3 d = dv3_sub(dv3_from(l->position), x);
    double dist = dv3_len(d);
    /* A light exactly at the shaded point has no direction; it lights nothing there. */
    if (!(dist > 0.0))
        return 0;
    *to_light = dv3_scale(d, 1.0 / dist);
    double a = formula_attenuation_d(l->a0, l->a1, l->a2, dist, dist * dist, l->range);
    if (l->kind == LIGHT_SPOT) {
        double rho = -dv3_dot(dv3_norm(dv3_from(l->direction)), *to_light);
        double cos_in = cos(0.5 * (double)l->inner), cos_out = cos(0.5 * (double)l->outer);
        double cone = formula_spot_cone_d(cos_in, cos_out);
        a *= l->profile == SPOT_SMOOTH ? formula_spot_smooth_d(rho, cos_in, cos_out, cone)
                                       : formula_spot_d3d_d(rho, cos_in, cos_out, cone, l->falloff);
    }
    *e_perp = dv3_scale(dv3_from(l->intensity), a);
    return a > 0.0;
}

dvec3 physical_fresnel_exact(const material *mat, double c)
{
    if (mat->conductor)
        return dv3(fresnel_conductor(c, mat->eta.x, mat->k.x), fresnel_conductor(c, mat->eta.y, mat->k.y),
                   fresnel_conductor(c, mat->eta.z, mat->k.z));
    double f = fresnel_dielectric(c, mat->ior);
    return dv3(f, f, f);
}

dvec3 physical_fresnel(const material *mat, physics_fresnel f, double c)
{
    switch (f) {
    case PHYS_FRESNEL_ONE: return dv3(1, 1, 1);
    case PHYS_FRESNEL_SCHLICK: {
        /* F0 is the exact reflectance at normal incidence, of the ior or of eta + ik. */
        dvec3 f0 = physical_fresnel_exact(mat, 1.0);
        return dv3(formula_schlick_d(f0.x, c), formula_schlick_d(f0.y, c), formula_schlick_d(f0.z, c));
    }
    case PHYS_FRESNEL_EXACT:
    case PHYS_FRESNEL_NV:
    default: return physical_fresnel_exact(mat, c);
    }
}

dvec3 physical_lobe(const material *mat, physics_fresnel f, dvec3 n, dvec3 v, dvec3 l)
{
    double m = mat->roughness;
    double n_l = dv3_dot(n, l), n_v = dv3_dot(n, v);
    if (!(n_l > 0.0 && n_v > 0.0 && m > 0.0 && mat->lobe))
        return dv3(0, 0, 0);
    dvec3 hs = dv3_add(l, v);
    double hl = dv3_len(hs);
    /* With both cosines > 0, L + V has length > 0 unless both graze: the lobe is 0 there. */
    if (hl < FORMULA_HALF_MIN)
        return dv3(0, 0, 0);
    dvec3 h = dv3_scale(hs, formula_half_scale_d(hl));
    double n_h = dv3_dot(n, h);
    if (!(n_h > 0.0))
        return dv3(0, 0, 0);
    /* sin^2 of N to H from the cross product: 1 - cos^2 cancels at the peak of a sharp lobe. */
    dvec3 nxh = dv3_cross(n, h);
    double d, g;
    if (mat->distribution == DIST_GGX) {
        d = microfacet_ggx_d(dv3_dot(nxh, nxh), n_h * n_h, m);
        g = microfacet_ggx_g(n_v, n_l, m);
    } else {
        d = formula_beckmann_d_d(dv3_dot(nxh, nxh), n_h * n_h, 1.0 / (m * m), formula_beckmann_log_norm_d(m, 1));
        g = microfacet_smith_g_exact(n_v, n_l, m);
    }
    double lobe = formula_ct_lobe_d(d, g, formula_ct_k_d(1), formula_cos_floor_d(n_v));
    /* V.H = |L + V|/2 >= 0 exactly; only rounding can leave [0, 1]. */
    double v_h = dv3_dot(v, h);
    v_h = v_h < 0.0 ? 0.0 : (v_h > 1.0 ? 1.0 : v_h);
    return dv3_scale(physical_fresnel(mat, f, f == PHYS_FRESNEL_NV ? n_v : v_h), lobe);
}

/* The Lambert weight per channel: albedo/pi (0 for a conductor) under the diffuse weight. */
static dvec3 physical_kd(const material *mat, const physics *ph, double n_v)
{
    if (mat->conductor)
        return dv3(0, 0, 0);
    dvec3 kd = dv3(formula_lambert_brdf_d(mat->albedo.x), formula_lambert_brdf_d(mat->albedo.y),
                   formula_lambert_brdf_d(mat->albedo.z));
    if (ph->diffuse_weight == PHYS_DIFFUSE_ONE_MINUS_F)
        kd = dv3_scale(kd, 1.0 - fresnel_dielectric(n_v < 0.0 ? 0.0 : n_v, mat->ior));
    return kd;
}

static vec3 physical_to_float(dvec3 a)
{
    return v3((float)formula_sat_d(a.x), (float)formula_sat_d(a.y), (float)formula_sat_d(a.z));
}

static void physical_shade(const shade_context *c, const shade_plan *p, vec3 x, vec3 n, vec3 v, shade_terms *out)
{
    (void)v; /* the viewer direction is formed again in double from the eye */
    const material *mat = p->mat;
    const physics *ph = p->params;
    dvec3 xd = dv3_from(x), nd = dv3_norm(dv3_from(n));
    dvec3 vd = dv3_norm(dv3_sub(dv3_from(c->eye), xd));
    double n_v = dv3_dot(nd, vd);
    dvec3 kd = physical_kd(mat, ph, n_v);
    dvec3 diffuse = dv3(0, 0, 0), spec = dv3(0, 0, 0), refl = dv3(0, 0, 0);
    int lobe = (p->terms & SHADE_TERM_SPECULAR) != 0;
    for (int i = 0; i < c->s->n_lights; i++) {
        dvec3 to_l, e;
        if (!physical_light_incident(&c->s->lights[i], xd, &to_l, &e))
            continue;
        double n_l = dv3_dot(nd, to_l);
        if (n_l <= 0.0)
            continue;
        if (ph->diffuse_lights & (1u << i))
            diffuse = dv3_add(diffuse, dv3_scale(dv3_mul(kd, e), n_l));
        if (lobe && (ph->specular_lights & (1u << i)))
            spec = dv3_add(spec, dv3_mul(physical_lobe(mat, ph->fresnel_specular, nd, vd, to_l), e));
    }
    if (ph->env_diffuse && c->env != NULL && c->env->kind == ENV_CONSTANT)
        diffuse = dv3_add(diffuse, dv3_scale(dv3_mul(kd, dv3_from(c->env->constant)), FORMULA_PI_D));
    if (p->terms & SHADE_TERM_REFLECTION) {
        /* The mirror direction 2 (N.V) N - V in double; the lookup itself is the float bilinear
         * one every renderer's environment is checked against. */
        dvec3 r = dv3_sub(dv3_scale(nd, 2.0 * n_v), vd);
        dvec3 phi = dv3_from(env_lookup(c->env, v3_from_d(r)));
        refl = dv3_mul(phi, physical_fresnel(mat, ph->fresnel_reflection, n_v < 0.0 ? 0.0 : (n_v > 1.0 ? 1.0 : n_v)));
    }
    out->diffuse = physical_to_float(diffuse);
    out->specular = physical_to_float(spec);
    out->reflection = physical_to_float(refl);
    out->emission = mat->d3d.emissive;
    out->alpha = 1.0f;
}


rc_status physical_plan_make(const shade_context *c, const material *m, const physics *ph, shade_plan *p, char *why,
                             size_t whylen)
{
    int env = c->env != NULL && c->env->kind != ENV_NONE;
    int diffuse = v3_nonzero(m->albedo) && !m->conductor;
    p->mat = m;
    p->params = ph;
    /* Textures scale the physics as they scale the approximations' terms (the albedo). */
    shade_plan_textures(c, m, p);
    p->fn = physical_shade;
    p->fn_uv = NULL;
    p->batch = shade_batch_scalar;
    p->terms = (diffuse ? SHADE_TERM_DIFFUSE : 0u) | (v3_nonzero(m->d3d.emissive) ? SHADE_TERM_EMISSION : 0u);
    p->path = !m->lobe ? "physical-diffuse" : (m->roughness > 0.0f ? "physical-lobe" : "physical-mirror");
    /* A diffuse texture is the albedo varying over the surface (it multiplies the Lambert term,
     * as Cycles' validate colours its Diffuse BSDF); a specular map scales an approximation's
     * lobe and has no physical meaning. */
    if (m->texture[MAT_TEX_SPECULAR][0] != '\0') {
        snprintf(why, whylen,
                 "material '%s': a specular texture scales an approximation's specular term and has no physical "
                 "meaning; the exact reference renders diffuse textures only (remove texture.specular)",
                 m->name);
        return RC_ERR_RANGE;
    }
    if (ph->shadows || ph->interreflection || ph->bounces > 1) {
        snprintf(why, whylen,
                 "physics: %s; the exact reference renders direct light without shadows or inter-reflection "
                 "(bounces 1)",
                 ph->shadows ? "shadows: true" : (ph->interreflection ? "interreflection: true" : "bounces > 1"));
        return RC_ERR_RANGE;
    }
    if (!m->lobe) {
        /* No specular written (material.lobe): neither a highlight nor a reflection. */
    } else if (m->roughness > 0.0f) {
        p->terms |= SHADE_TERM_SPECULAR;
        if (env && ph->env_specular) {
            snprintf(why, whylen,
                     "material '%s': a rough lobe (roughness %g) reflecting the environment needs an integral over "
                     "it; the exact reference renders rough lobes under point, spot and sun lights (or set physics "
                     "env_specular: false)",
                     m->name, (double)m->roughness);
            return RC_ERR_RANGE;
        }
    } else if (env && ph->env_specular) {
        p->terms |= SHADE_TERM_REFLECTION;
    }
    if (diffuse && env && ph->env_diffuse && c->env->kind != ENV_CONSTANT) {
        snprintf(why, whylen,
                 "material '%s': an environment image lighting the diffuse (physics env_diffuse: true) needs an "
                 "integral over it; the exact reference renders a constant environment on the diffuse only",
                 m->name);
        return RC_ERR_RANGE;
    }
    return RC_OK;
}
