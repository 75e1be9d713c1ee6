/* stability_sweeps.c - the per-model stability sweeps (stability_sweep.h): Fresnel,
 * microfacet, D3D, the D3D9Client combine and the Cook-Torrance specular, each function of the
 * models against its long double reference over extreme and degenerate inputs.
 */
#include <float.h>

#include "cooktorrance.h"
#include "d3d.h"
#include "d3d9client.h"
#include "fresnel.h"
#include "microfacet.h"
#include "stability_sweep.h"

static void fresnel_r0_rows(sweep *s)
{
    int n = s->n;
    stability_row *row;

    row = stab_row_begin(s, "fresnel_r0_from_ior", "n->1 (1 +- 2^-23..0.1)", STABILITY_ROUNDING, 24);
    for (int i = 0; i < n; i++) {
        float ior = (float)(1.0 + (i % 2 ? -1.0 : 1.0) * stab_lsp(i / 2, n / 2, 0x1p-23, 0.1));
        ADD(row, fresnel_r0_from_ior(ior), stab_ref_r0(ior), "n=%.9g", ior);
    }
    stab_row_end(row);
    row = stab_row_begin(s, "fresnel_r0_from_ior", "n->inf (1..FLT_MAX)", STABILITY_ROUNDING, 24);
    for (int i = 0; i < n; i++) {
        float ior = (float)stab_lsp(i, n, 1.0, FLT_MAX);
        ADD(row, fresnel_r0_from_ior(ior), stab_ref_r0(ior), "n=%.9g", ior);
    }
    stab_row_end(row);
    row = stab_row_begin(s, "fresnel_r0_from_ior", "n->0+ (denormal..1)", STABILITY_ROUNDING, 24);
    for (int i = 0; i < n; i++) {
        float ior = (float)stab_lsp(i, n, 1.4e-45, 1.0);
        ADD(row, fresnel_r0_from_ior(ior), stab_ref_r0(ior), "n=%.9g", ior);
    }
    stab_row_end(row);
}

static void fresnel_schlick_rows(sweep *s)
{
    int n = s->n;
    stability_row *row;

    struct {
        const char *name;
        double c_lo, c_hi;
        int near_one;
        double f_lo, f_hi;
        int f_log;
    } sc[] = {
        {"cos->0 (denormal..0.1)", 1.4e-45, 0.1, 0, 0.0, 1.0, 0},
        {"cos->1 (1-2^-24..0.9)", 0x1p-24, 0.1, 1, 0.0, 1.0, 0},
        {"F0->0 (n->1, 1e-38..1e-2)", 1e-3, 1.0, 0, 1e-38, 1e-2, 1},
        {"F0->1 (n->inf)", 1e-3, 1.0, 0, 0.999, 1.0, 0},
        {"bad input F0 in [-10,10]", 1e-3, 1.0, 0, -10.0, 10.0, 0},
    };
    for (size_t k = 0; k < sizeof sc / sizeof sc[0]; k++) {
        row = stab_row_begin(s, "fresnel_schlick", sc[k].name, STABILITY_ROUNDING, 24);
        for (int i = 0; i < n; i++) {
            double cv = k < 2 ? stab_lsp(i, n, sc[k].c_lo, sc[k].c_hi) : stab_rng_range(&s->r, sc[k].c_lo, sc[k].c_hi);
            float c = (float)(sc[k].near_one ? 1.0 - cv : cv);
            float f0 = (float)(sc[k].f_log ? stab_lsp(i, n, sc[k].f_lo, sc[k].f_hi)
                                           : stab_rng_range(&s->r, sc[k].f_lo, sc[k].f_hi));
            ADD(row, fresnel_schlick(f0, c), stab_ref_schlick(f0, c), "F0=%.9g cos=%.9g", f0, c);
        }
        stab_row_end(row);
    }
}

static void fresnel_d3d9_rows(sweep *s)
{
    int n = s->n;
    stability_row *row;

    struct {
        const char *name;
        int mode;
    } dc[] = {
        {"p->0 (1e-6..0.1)", 0},      {"p>=1e4 (1e4..1e7)", 1},   {"cos->0 (denormal..0.1)", 2},
        {"cos->1 (1-2^-24..0.9)", 3}, {"bad input R0>1, m<0", 4}, {"huge R0, m (saturation)", 5},
    };
    for (size_t k = 0; k < sizeof dc / sizeof dc[0]; k++) {
        row = stab_row_begin(s, "fresnel_d3d9", dc[k].name, STABILITY_ROUNDING, 24);
        for (int i = 0; i < n; i++) {
            float r0 = (float)stab_rng_range(&s->r, 0.0, 0.25), m = 1.0f - r0;
            float p = (float)stab_rng_range(&s->r, 0.5, 8.0), c = (float)stab_rng_u(&s->r);
            switch (dc[k].mode) {
            case 0: p = (float)stab_lsp(i, n, 1e-6, 0.1); break;
            case 1:
                p = (float)stab_lsp(i, n, 1e4, 1e7);
                c = (float)stab_rng_log(&s->r, 1e-8, 1e-2);
                break;
            case 2: c = (float)stab_lsp(i, n, 1.4e-45, 0.1); break;
            case 3: c = (float)(1.0 - stab_lsp(i, n, 0x1p-24, 0.1)); break;
            case 4:
                r0 = (float)stab_rng_range(&s->r, 1.0, 100.0);
                m = (float)stab_rng_range(&s->r, -100.0, 0.0);
                break;
            default:
                r0 = (float)((i % 2 ? -1 : 1) * stab_lsp(i, n, 1e30, FLT_MAX));
                m = (float)((i % 3 ? 1 : -1) * stab_lsp(n - 1 - i, n, 1e30, FLT_MAX));
                break;
            }
            ADD(row, fresnel_d3d9(r0, m, p, c), stab_ref_d3d9(r0, m, p, c), "R0=%.9g m=%.9g p=%.9g cos=%.9g", r0, m, p,
                c);
        }
        stab_row_end(row);
    }
}

/* The double exact references, judged in double ulps. */
static void fresnel_exact_rows(sweep *s)
{
    int n = s->n;
    stability_row *row;

    row = stab_row_begin(s, "fresnel_dielectric", "cos->0 (1e-300..0.1)", STABILITY_ROUNDING, 53);
    for (int i = 0; i < n; i++) {
        double c = stab_lsp(i, n, 1e-300, 0.1), eta = stab_rng_range(&s->r, 1.01, 3.0);
        if (i % 2)
            eta = 1.0 / eta;
        ADD(row, fresnel_dielectric(c, eta), stab_ref_dielectric(c, eta), "cos=%.17g eta=%.17g", c, eta);
    }
    stab_row_end(row);
    row = stab_row_begin(s, "fresnel_dielectric", "n->1 (1 +- 1e-15..1e-2)", STABILITY_ROUNDING, 53);
    for (int i = 0; i < n; i++) {
        double eta = 1.0 + (i % 2 ? -1.0 : 1.0) * stab_lsp(i / 2, n / 2, 1e-15, 1e-2), c = stab_rng_u(&s->r);
        ADD(row, fresnel_dielectric(c, eta), stab_ref_dielectric(c, eta), "cos=%.17g eta=%.17g", c, eta);
    }
    stab_row_end(row);
    row = stab_row_begin(s, "fresnel_dielectric", "n->inf (1e3..1e150), n->0", STABILITY_ROUNDING, 53);
    for (int i = 0; i < n; i++) {
        double eta = stab_lsp(i / 2, n / 2, 1e3, 1e150), c = stab_rng_u(&s->r);
        if (i % 2)
            eta = 1.0 / eta;
        ADD(row, fresnel_dielectric(c, eta), stab_ref_dielectric(c, eta), "cos=%.17g eta=%.17g", c, eta);
    }
    stab_row_end(row);
    row = stab_row_begin(s, "fresnel_dielectric", "near total internal reflection", STABILITY_ROUNDING, 53);
    for (int i = 0; i < n; i++) {
        double eta = 1.0 / 1.5, cc = sqrt(1.0 - eta * eta);
        double c = cc + (i % 2 ? -1.0 : 1.0) * stab_lsp(i / 2, n / 2, 1e-16, 1e-2);
        ADD(row, fresnel_dielectric(c, eta), stab_ref_dielectric(c, eta), "cos=%.17g eta=%.17g", c, eta);
    }
    stab_row_end(row);
    row = stab_row_begin(s, "fresnel_conductor", "cos->0, eta/k 1e-3..1e3", STABILITY_ROUNDING, 53);
    for (int i = 0; i < n; i++) {
        double c = i % 2 ? stab_lsp(i / 2, n / 2, 1e-300, 0.1) : stab_rng_u(&s->r);
        double eta = stab_rng_log(&s->r, 1e-3, 1e3), k = stab_rng_log(&s->r, 1e-3, 1e3);
        ADD(row, fresnel_conductor(c, eta, k), stab_ref_conductor(c, eta, k), "cos=%.17g eta=%.9g k=%.9g", c, eta, k);
    }
    stab_row_end(row);
}

/* Approximation error against the exact dielectric (Figure 1's numbers). */
static void fresnel_approx_rows(sweep *s)
{
    int n = s->n;
    stability_row *row;

    struct {
        const char *fn;
        double ior, p;
    } ap[] = {
        {"schlick p=5 vs exact", 1.33, 5.0}, {"schlick p=5 vs exact", 1.5, 5.0}, {"schlick p=5 vs exact", 2.4, 5.0},
        {"d3d9 p=2 vs exact", 1.5, 2.0},     {"d3d9 p=4 vs exact", 1.5, 4.0},
    };
    for (size_t k = 0; k < sizeof ap / sizeof ap[0]; k++) {
        char cs[56];
        snprintf(cs, sizeof cs, "n=%.3g, angle 0..90 deg", ap[k].ior);
        row = stab_row_begin(s, ap[k].fn, cs, STABILITY_APPROX, 24);
        float r0 = fresnel_r0_from_ior((float)ap[k].ior);
        for (int i = 0; i < n; i++) {
            double deg = 90.0 * i / (n - 1);
            float c = (float)cos(deg * (double)REF_PI / 180.0);
            float f = fresnel_d3d9(r0, 1.0f - r0, (float)ap[k].p, c);
            ADD(row, f, stab_ref_dielectric(c, ap[k].ior), "angle=%.4g deg", deg);
        }
        stab_row_end(row);
    }
}

void stab_sweep_fresnel(sweep *s)
{
    fresnel_r0_rows(s);
    fresnel_schlick_rows(s);
    fresnel_d3d9_rows(s);
    fresnel_exact_rows(s);
    fresnel_approx_rows(s);
}

/* -------------------------------------------------------------------- microfacet sweeps */

static void microfacet_beckmann_rows(sweep *s)
{
    int n = s->n;
    stability_row *row;
    static const char *dname[2] = {"microfacet_beckmann_d[walter]", "microfacet_beckmann_d[ct1982]"};
    struct {
        const char *name;
        int mode;
    } bc[] = {
        {"cos_h->0 (denormal..0.1)", 0},
        {"cos_h->1 (1-2^-24..0.9)", 1},
        {"m->0 (1e-6..1e-2)", 2},
        {"m->inf (1..1e3)", 3},
        {"denormal m", 4},
    };
    for (int norm = 0; norm < 2; norm++) {
        ct_normalisation cn = norm ? CT_CT1982 : CT_WALTER;
        for (size_t k = 0; k < sizeof bc / sizeof bc[0]; k++) {
            row = stab_row_begin(s, dname[norm], bc[k].name, STABILITY_ROUNDING, 24);
            for (int i = 0; i < n; i++) {
                float c = (float)stab_rng_u(&s->r), m = (float)stab_rng_log(&s->r, 0.01, 1.0);
                switch (bc[k].mode) {
                case 0:
                    c = (float)stab_lsp(i, n, 1.4e-45, 0.1);
                    m = (float)stab_rng_log(&s->r, 1.0, 1e3);
                    break;
                case 1:
                    c = (float)(1.0 - stab_lsp(i, n, 0x1p-24, 0.1));
                    m = (float)stab_rng_log(&s->r, 1e-6, 1.0);
                    break;
                case 2:
                    m = (float)stab_lsp(i, n, 1e-6, 1e-2);
                    c = (float)cos(stab_rng_range(&s->r, 0.0, 5.0 * m)); /* inside the lobe */
                    break;
                case 3: m = (float)stab_lsp(i, n, 1.0, 1e3); break;
                default:
                    m = (float)stab_lsp(i, n, 1.4e-45, 1e-38);
                    c = (float)(1.0 - stab_rng_log(&s->r, 1e-8, 1.0));
                    break;
                }
                ADD(row, microfacet_beckmann_d(c, m, cn), stab_ref_beckmann(c, m, cn), "cos_h=%.9g m=%.9g", c, m);
            }
            stab_row_end(row);
        }
    }
}

static void microfacet_vcavity_rows(sweep *s)
{
    int n = s->n;
    stability_row *row;

    struct {
        const char *name;
        int mode;
    } vc[] = {
        {"V.H->0 (denormal..1e-3)", 0},
        {"cos->0 (N.V, N.L)", 1},
        {"random unit-vector geometry", 2},
    };
    for (size_t k = 0; k < sizeof vc / sizeof vc[0]; k++) {
        row = stab_row_begin(s, "microfacet_vcavity_g", vc[k].name, STABILITY_ROUNDING, 24);
        for (int i = 0; i < n; i++) {
            float nh = (float)stab_rng_u(&s->r), nv = (float)stab_rng_u(&s->r), nl = (float)stab_rng_u(&s->r),
                  vh = (float)stab_rng_u(&s->r);
            if (vc[k].mode == 0) {
                vh = (float)stab_lsp(i, n, 1.4e-45, 1e-3);
            } else if (vc[k].mode == 1) {
                nv = (float)stab_lsp(i, n, 1.4e-45, 0.1);
                nl = (float)stab_rng_log(&s->r, 1.4e-45, 0.1);
            } else {
                vec3 nn = v3(0, 1, 0), v = stab_rng_dir_upper(&s->r, -0.2, 1.0),
                     l = stab_rng_dir_upper(&s->r, -0.2, 1.0);
                vec3 h = v3_norm(v3_add(v, l));
                nh = v3_dot(nn, h);
                nv = v3_dot(nn, v);
                nl = v3_dot(nn, l);
                vh = v3_dot(v, h);
            }
            ADD(row, microfacet_vcavity_g(nh, nv, nl, vh), stab_ref_vcavity(nh, nv, nl, vh),
                "nh=%.9g nv=%.9g nl=%.9g vh=%.9g", nh, nv, nl, vh);
        }
        stab_row_end(row);
    }
}

static void microfacet_smith_rows(sweep *s)
{
    int n = s->n;
    stability_row *row;

    struct {
        const char *name;
        int mode;
    } sc[] = {
        {"cos->0 (denormal..0.1)", 0}, {"cos->1 (1-2^-24..0.9)", 1}, {"m->0 (1e-6..1e-2)", 2},
        {"m->inf (1..1e3)", 3},        {"a near 1.6 (branch)", 4},
    };
    for (int exact = 0; exact < 2; exact++) {
        for (size_t k = 0; k < sizeof sc / sizeof sc[0]; k++) {
            row = stab_row_begin(s, exact ? "microfacet_smith_g1_exact" : "microfacet_smith_g1_walter", sc[k].name,
                                 STABILITY_ROUNDING, exact ? 53 : 24);
            for (int i = 0; i < n; i++) {
                float c = (float)stab_rng_u(&s->r), m = (float)stab_rng_log(&s->r, 0.01, 1.0);
                switch (sc[k].mode) {
                case 0: c = (float)stab_lsp(i, n, 1.4e-45, 0.1); break;
                case 1: c = (float)(1.0 - stab_lsp(i, n, 0x1p-24, 0.1)); break;
                case 2:
                    m = (float)stab_lsp(i, n, 1e-6, 1e-2);
                    c = (float)stab_rng_log(&s->r, 1e-8, 1.0);
                    break;
                case 3: m = (float)stab_lsp(i, n, 1.0, 1e3); break;
                default: {
                    /* 1/(m tan) = 1.6 +- a little: tan = 1/(1.6 m) */
                    double t = 1.0 / (1.6 * m) * (1.0 + stab_rng_range(&s->r, -1e-6, 1e-6));
                    c = (float)(1.0 / sqrt(1.0 + t * t));
                    break;
                }
                }
                if (exact)
                    ADD(row, microfacet_smith_g1_exact(c, m), stab_ref_smith_g1_exact(c, m), "cos=%.9g m=%.9g", c, m);
                else
                    ADD(row, microfacet_smith_g1_walter(c, m), stab_ref_smith_g1_walter(c, m), "cos=%.9g m=%.9g", c, m);
            }
            stab_row_end(row);
        }
    }
    row = stab_row_begin(s, "smith G1 walter vs exact", "m 0.01..1, all angles", STABILITY_APPROX, 24);
    for (int i = 0; i < n; i++) {
        float c = (float)stab_rng_u(&s->r), m = (float)stab_rng_log(&s->r, 0.01, 1.0);
        ADD(row, microfacet_smith_g1_walter(c, m), stab_ref_smith_g1_exact(c, m), "cos=%.9g m=%.9g", c, m);
    }
    stab_row_end(row);
}

void stab_sweep_microfacet(sweep *s)
{
    microfacet_beckmann_rows(s);
    microfacet_vcavity_rows(s);
    microfacet_smith_rows(s);
}

/* ------------------------------------------------------------------------- D3D sweeps */

static void d3d_blinn_lambert_rows(sweep *s)
{
    int n = s->n;
    stability_row *row;
    struct {
        const char *name;
        int mode;
    } bc[] = {
        {"P->0 (1e-6..0.1)", 0},
        {"P>=1e4 (1e4..1e7)", 1},
        {"N.H->0 (denormal..0.1)", 2},
        {"N.H->1 (1-2^-24..0.9)", 3},
    };
    for (size_t k = 0; k < sizeof bc / sizeof bc[0]; k++) {
        row = stab_row_begin(s, "d3d_blinn", bc[k].name, STABILITY_ROUNDING, 24);
        for (int i = 0; i < n; i++) {
            float nh = (float)stab_rng_u(&s->r), p = (float)stab_rng_log(&s->r, 1.0, 128.0);
            switch (bc[k].mode) {
            case 0: p = (float)stab_lsp(i, n, 1e-6, 0.1); break;
            case 1:
                p = (float)stab_lsp(i, n, 1e4, 1e7);
                nh = (float)(1.0 - stab_rng_log(&s->r, 1e-8, 1e-2));
                break;
            case 2:
                nh = (float)stab_lsp(i, n, 1.4e-45, 0.1);
                p = (float)stab_rng_log(&s->r, 1e-3, 4.0);
                break;
            default:
                nh = (float)(1.0 - stab_lsp(i, n, 0x1p-24, 0.1));
                p = (float)stab_rng_log(&s->r, 1.0, 1e4);
                break;
            }
            ADD(row, d3d_blinn(nh, p), stab_ref_blinn(nh, p), "N.H=%.9g P=%.9g", nh, p);
        }
        stab_row_end(row);
    }

    row = stab_row_begin(s, "d3d_lambert", "N.L over [-1,1], denormal", STABILITY_ROUNDING, 24);
    for (int i = 0; i < n; i++) {
        float nl = i % 2 ? (float)stab_rng_range(&s->r, -1.0, 1.0) : (float)stab_lsp(i, n, 1.4e-45, 1.0);
        ADD(row, d3d_lambert(nl), stab_ref_lambert(nl), "N.L=%.9g", nl);
    }
    stab_row_end(row);
}

static void d3d_attenuation_rows(sweep *s)
{
    int n = s->n;
    stability_row *row;

    struct {
        const char *name;
        int mode;
    } ac[] = {
        {"d->0 (denormal..1e-3)", 0},
        {"d->inf (1e3..FLT_MAX)", 1},
        {"a0=a1=a2=0", 2},
        {"random a, range", 3},
    };
    for (size_t k = 0; k < sizeof ac / sizeof ac[0]; k++) {
        row = stab_row_begin(s, "d3d_attenuation", ac[k].name, STABILITY_ROUNDING, 24);
        for (int i = 0; i < n; i++) {
            light l;
            light_init(&l);
            float d = (float)stab_rng_log(&s->r, 1e-3, 1e3);
            switch (ac[k].mode) {
            case 0:
                d = (float)stab_lsp(i, n, 1.4e-45, 1e-3);
                l.a0 = (float)(i % 3 == 0 ? 0.0 : stab_rng_u(&s->r));
                break;
            case 1:
                d = (float)stab_lsp(i, n, 1e3, FLT_MAX);
                l.a1 = (float)(i % 2 ? stab_rng_u(&s->r) : 0.0);
                break;
            case 2:
                l.a0 = l.a1 = l.a2 = 0.0f;
                d = (float)stab_rng_log(&s->r, 1.4e-45, FLT_MAX);
                break;
            default:
                l.a0 = (float)stab_rng_u(&s->r);
                l.a1 = (float)stab_rng_u(&s->r);
                l.a2 = (float)stab_rng_u(&s->r);
                l.range = (float)stab_rng_log(&s->r, 1e-2, 1e4);
                break;
            }
            ADD(row, d3d_attenuation(&l, d), stab_ref_attenuation(&l, d), "d=%.9g a=(%.3g,%.3g,%.3g)", d, l.a0, l.a1,
                l.a2);
        }
        stab_row_end(row);
    }
}

static void d3d_spot_rows(sweep *s)
{
    int n = s->n;
    stability_row *row;

    struct {
        const char *fn;
        spot_profile prof;
        const char *name;
        int mode;
    } pc[] = {
        {"d3d_spot[d3d]", SPOT_D3D, "rho near outer edge", 0},
        {"d3d_spot[d3d]", SPOT_D3D, "rho near inner edge", 1},
        {"d3d_spot[d3d]", SPOT_D3D, "falloff 0..1e4, random rho", 2},
        {"d3d_spot[smooth]", SPOT_SMOOTH, "rho near outer edge", 0},
        {"d3d_spot[smooth]", SPOT_SMOOTH, "rho near inner edge", 1},
        {"d3d_spot[smooth]", SPOT_SMOOTH, "random cones, rho", 2},
    };
    for (size_t k = 0; k < sizeof pc / sizeof pc[0]; k++) {
        row = stab_row_begin(s, pc[k].fn, pc[k].name, STABILITY_ROUNDING, 24);
        for (int i = 0; i < n; i++) {
            light l;
            light_init(&l);
            l.kind = LIGHT_SPOT;
            l.profile = pc[k].prof;
            l.direction = stab_rng_dir_upper(&s->r, -1.0, 1.0);
            l.inner = (float)stab_rng_range(&s->r, 0.05, 2.0);
            l.outer = l.inner + (float)stab_rng_range(&s->r, 0.01, 1.0);
            l.falloff = (float)stab_rng_range(&s->r, 0.5, 4.0);
            double half;
            if (pc[k].mode == 0)
                half = 0.5 * (double)l.outer * (1.0 - (i % 2 ? -1 : 1) * stab_lsp(i / 2, n / 2, 1e-7, 1e-2));
            else if (pc[k].mode == 1)
                half = 0.5 * (double)l.inner * (1.0 + (i % 2 ? -1 : 1) * stab_lsp(i / 2, n / 2, 1e-7, 1e-2));
            else {
                half = stab_rng_range(&s->r, 0.0, 0.5 * (double)l.outer * 1.1);
                l.falloff = (float)(i % 2 ? stab_lsp(i, n, 1e-6, 1e4) : stab_rng_range(&s->r, 0.0, 8.0));
            }
            /* A unit vector at angle `half` from the axis. */
            ld3 ax = l3_norm(l3_from(l.direction));
            ld3 perp = l3_norm(fabsl(ax.x) < 0.9L ? l3(0, ax.z, -ax.y) : l3(-ax.z, 0, ax.x));
            ld3 dir = l3_add(l3_scale(ax, cosl(half)), l3_scale(perp, sinl(half)));
            vec3 df = v3((float)dir.x, (float)dir.y, (float)dir.z);
            ADD(row, d3d_spot(&l, df), stab_ref_spot(&l, l3_from(df)),
                "half-angle=%.9g inner=%.6g outer=%.6g falloff=%.6g", half, l.inner, l.outer, l.falloff);
        }
        stab_row_end(row);
    }
}

void stab_sweep_d3d(sweep *s)
{
    d3d_blinn_lambert_rows(s);
    d3d_attenuation_rows(s);
    d3d_spot_rows(s);
}

/* ---------------------------------------------------------------- D3D9Client combine */

void stab_sweep_d3d9client(sweep *s)
{
    int n = s->n;
    static const char *nname[4] = {"max", "mean", "luminance", "euclid"};
    struct {
        const char *name;
        int mode;
    } cc[] = {
        {"grazing N.V (denormal..0.1)", 0}, {"HDR phi and d up to 1e6", 1},
        {"sun angle (8), N.L->0", 2},       {"p->0 and p>=1e4", 3},
        {"bright lambda (euclid < 0)", 4},
    };
    for (size_t k = 0; k < sizeof cc / sizeof cc[0]; k++) {
        stability_row *row = stab_row_begin(s, "d3d9client_combine", cc[k].name, STABILITY_ROUNDING, 24);
        for (int i = 0; i < n; i++) {
            material mat;
            material_init(&mat);
            d3d9client_params *p = &mat.d9;
            p->norm = (colour_norm)(i % 4);
            p->r0 = fresnel_r0_from_ior((float)stab_rng_range(&s->r, 1.0, 3.0));
            p->m = 1.0f - p->r0;
            p->p = (float)stab_rng_range(&s->r, 1.0, 5.0);
            p->reflect = v3((float)stab_rng_u(&s->r), (float)stab_rng_u(&s->r), (float)stab_rng_u(&s->r));
            vec3 d = v3((float)stab_rng_u(&s->r), (float)stab_rng_u(&s->r), (float)stab_rng_u(&s->r));
            vec3 phi = v3((float)stab_rng_u(&s->r), (float)stab_rng_u(&s->r), (float)stab_rng_u(&s->r));
            float nv = (float)stab_rng_u(&s->r), nsun = (float)stab_rng_u(&s->r), da = (float)stab_rng_u(&s->r);
            switch (cc[k].mode) {
            case 0: nv = (float)stab_lsp(i, n, 1.4e-45, 0.1); break;
            case 1:
                phi = v3_scale(phi, (float)stab_lsp(i, n, 1.0, 1e6));
                d = v3_scale(d, (float)stab_rng_log(&s->r, 1e-6, 1e6));
                break;
            case 2:
                p->sun_angle = 1;
                nsun = (float)stab_lsp(i, n, 1.4e-45, 0.1);
                break;
            case 3: p->p = (float)(i % 2 ? stab_lsp(i, n, 1e-6, 0.1) : stab_lsp(i, n, 1e4, 1e7)); break;
            default: p->reflect = v3s((float)stab_rng_range(&s->r, 0.8, 1.0)); break;
            }
            d3d9client_result r;
            d3d9client_combine(p, d, da, phi, nv, nsun, &r);
            ref_d9 e = stab_ref_d3d9client(p, l3_from(d), da, l3_from(phi), nv, nsun);
            const float got[4] = {r.rgb.x, r.rgb.y, r.rgb.z, r.alpha};
            const ld want[4] = {e.rgb.x, e.rgb.y, e.rgb.z, e.alpha};
            static const char *what[4] = {"rgb.r", "rgb.g", "rgb.b", "alpha"};
            for (int j = 0; j < 4; j++)
                ADD(row, got[j], want[j], "%s norm=%s N.V=%.9g N.sun=%.9g p=%.6g d=%.6g phi=%.6g", what[j],
                    nname[p->norm], nv, nsun, p->p, d.x, phi.x);
        }
        stab_row_end(row);
    }
}

/* -------------------------------------------------------------- Cook-Torrance specular */

static void ct_variant(int i, ct_params *p, material *mat)
{
    static const ct_geometry gs[3] = {G_VCAVITY, G_SMITH_WALTER, G_SMITH_EXACT};
    static const ct_fresnel fs[3] = {F_SCHLICK, F_EXACT, F_EXACT};
    p->g = gs[i % 3];
    p->f = fs[(i / 3) % 3];
    mat->conductor = (i / 3) % 3 == 2;
    mat->eta = v3(0.18f, 0.42f, 1.37f); /* gold-like complex index, per channel */
    mat->k = v3(3.42f, 2.35f, 1.77f);
    p->ks = v3(1.0f, 0.9f, 0.8f);
}

void stab_sweep_cooktorrance(sweep *s)
{
    int n = s->n;
    static const char *gname[3] = {"vcavity", "smith-walter", "smith-exact"};
    struct {
        const char *name;
        int mode;
    } cc[] = {
        {"grazing view (N.V denormal..0.1)", 0},
        {"grazing light (N.L->0)", 1},
        {"V.H->0 (L ~ -V)", 2},
        {"N.L < 0", 3},
        {"m->0 (1e-6..1e-2)", 4},
        {"m->inf (1..1e3)", 5},
        {"zero-length / denormal normal", 6},
        {"random geometry", 7},
    };
    for (int norm = 0; norm < 2; norm++) {
        for (size_t k = 0; k < sizeof cc / sizeof cc[0]; k++) {
            stability_row *row =
                stab_row_begin(s, norm ? "cooktorrance_specular[ct1982]" : "cooktorrance_specular[walter]", cc[k].name,
                               STABILITY_ROUNDING, 24);
            for (int i = 0; i < n; i++) {
                material mat;
                material_init(&mat);
                ct_params *p = &mat.ct;
                p->norm = norm ? CT_CT1982 : CT_WALTER;
                ct_variant(i, p, &mat);
                p->m = (float)stab_rng_log(&s->r, 0.05, 1.0);
                vec3 nn = v3(0, 1, 0);
                vec3 v = stab_rng_dir_upper(&s->r, 0.0, 1.0), l = stab_rng_dir_upper(&s->r, 0.0, 1.0);
                double ph = stab_rng_range(&s->r, 0.0, 2.0 * (double)REF_PI);
                switch (cc[k].mode) {
                case 0: v = stab_dir_at(stab_lsp(i, n, 1.4e-45, 0.1), ph); break;
                case 1: l = stab_dir_at(stab_lsp(i, n, 1.4e-45, 0.1), ph); break;
                case 2: {
                    /* L close to -V: both graze, |L + V| from 1e-8 to 1e-2 */
                    double e = stab_lsp(i, n, 1e-8, 1e-2);
                    v = stab_dir_at(0.5 * e, ph);
                    l = stab_dir_at(0.5 * e, ph + (double)REF_PI - e);
                    break;
                }
                case 3: l = stab_rng_dir_upper(&s->r, -1.0, 0.0); break;
                case 4: {
                    p->m = (float)stab_lsp(i, n, 1e-6, 1e-2);
                    /* L near the mirror direction of V, within a few m, so D is not 0 */
                    double th = stab_rng_range(&s->r, 0.0, 1.3), dth = stab_rng_range(&s->r, -3.0, 3.0) * p->m;
                    v = stab_dir_at(cos(th), ph);
                    l = stab_dir_at(cos(th + dth), ph + (double)REF_PI + stab_rng_range(&s->r, -3.0, 3.0) * p->m);
                    break;
                }
                case 5: p->m = (float)stab_lsp(i, n, 1.0, 1e3); break;
                case 6: nn = i % 2 ? v3s(0.0f) : v3(0.0f, (float)stab_lsp(i, n, 1.4e-45, 1e-38), 0.0f); break;
                default:
                    v = stab_rng_dir_upper(&s->r, -0.1, 1.0);
                    l = stab_rng_dir_upper(&s->r, -0.1, 1.0);
                    break;
                }
                vec3 got = cooktorrance_specular(p, nn, v, l, &mat);
                ld3 want = stab_ref_ct_specular(p, l3_from(nn), l3_from(v), l3_from(l), &mat);
                const float g3[3] = {got.x, got.y, got.z};
                const ld w3[3] = {want.x, want.y, want.z};
                for (int j = 0; j < 3; j++)
                    ADD(row, g3[j], w3[j], "ch%d G=%s F=%s m=%.6g N.V=%.6g N.L=%.6g", j, gname[p->g],
                        p->f == F_SCHLICK ? "schlick"
                        : mat.conductor   ? "conductor"
                                          : "dielectric",
                        p->m, v3_dot(v3_norm(nn), v), v3_dot(v3_norm(nn), l));
            }
            stab_row_end(row);
        }
    }
    stability_row *row =
        stab_row_begin(s, "cooktorrance_reflection_weight", "N.V denormal..1, all F", STABILITY_ROUNDING, 24);
    for (int i = 0; i < n; i++) {
        material mat;
        material_init(&mat);
        ct_variant(i, &mat.ct, &mat);
        mat.ct.f0 = v3((float)stab_rng_u(&s->r), (float)stab_rng_u(&s->r), (float)stab_rng_u(&s->r));
        float nv = (float)(i % 2 ? stab_lsp(i, n, 1.4e-45, 1.0) : stab_rng_range(&s->r, -1.0, 1.0));
        vec3 got = cooktorrance_reflection_weight(&mat.ct, nv, &mat);
        ld3 want = stab_ref_ct_fresnel(&mat.ct, stab_ref_clamp(nv, 0, 1), &mat);
        ADD(row, got.x, want.x, "N.V=%.9g", nv);
        ADD(row, got.y, want.y, "N.V=%.9g", nv);
        ADD(row, got.z, want.z, "N.V=%.9g", nv);
    }
    stab_row_end(row);
}
