/* reflcheck eval: a model's values over an angle sweep, as CSV, float approximation beside
 * the double-precision exact reference. Exit 0, 1 when standard output cannot take the table
 * (e.g. a full disk), 2 for bad options. */
#include <errno.h>
#include <getopt.h>
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "cli.h"
#include "formula.h"
#include "fresnel.h"
#include "microfacet.h"

typedef struct {
    double ior, p, r0, m;
    int r0_given, m_given, steps;
} eval_args;

static void eval_fresnel(const eval_args *a)
{
    double r0 = a->r0_given ? a->r0 : fresnel_r0_from_ior((float)a->ior);
    double mult = a->m_given ? a->m : 1.0 - r0;
    printf("angle_deg,cos_theta,d3d9_R,schlick5,exact_dielectric,d3d9_minus_exact,schlick5_minus_exact\n");
    for (int i = 0; i <= a->steps; i++) {
        double deg = 90.0 * i / a->steps;
        double c = cos(deg * FORMULA_PI_D / 180.0);
        float d9 = fresnel_d3d9((float)r0, (float)mult, (float)a->p, (float)c);
        float s5 = fresnel_schlick((float)r0, (float)c);
        double ex = fresnel_dielectric(c, a->ior);
        printf("%.6g,%.9g,%.9g,%.9g,%.9g,%.9g,%.9g\n", deg, c, d9, s5, ex, d9 - ex, s5 - ex);
    }
}

static void eval_beckmann(const eval_args *a)
{
    printf("angle_deg,cos_h,D_walter,D_ct1982\n");
    for (int i = 0; i <= a->steps; i++) {
        double deg = 90.0 * i / a->steps;
        double c = cos(deg * FORMULA_PI_D / 180.0);
        printf("%.6g,%.9g,%.9g,%.9g\n", deg, c, microfacet_beckmann_d((float)c, (float)a->m, CT_WALTER),
               microfacet_beckmann_d((float)c, (float)a->m, CT_CT1982));
    }
}

static void eval_smith(const eval_args *a)
{
    printf("angle_deg,cos_theta,G1_walter,G1_exact,walter_minus_exact\n");
    for (int i = 0; i <= a->steps; i++) {
        double deg = 90.0 * i / a->steps;
        double c = cos(deg * FORMULA_PI_D / 180.0);
        float w = microfacet_smith_g1_walter((float)c, (float)a->m);
        double e = microfacet_smith_g1_exact(c, a->m);
        printf("%.6g,%.9g,%.9g,%.9g,%.9g\n", deg, c, w, e, w - e);
    }
}

static const struct option eval_longopts[] = {
    {"ior", required_argument, NULL, 'n'},
    {"p", required_argument, NULL, 'p'},
    {"r0", required_argument, NULL, 'r'},
    {"m", required_argument, NULL, 'm'},
    {"steps", required_argument, NULL, 's'},
    {"help", no_argument, NULL, 'h'},
    {NULL, 0, NULL, 0},
};
static const cli_option_help eval_options_help[] = {
    {"ior", "N",
     "index of refraction of the dielectric, 1 to 100; default: 1.5 (fresnel: the exact curve, "
     "and R0 = ((N - 1) / (N + 1))^2 unless --r0)"},
    {"p", "P", "fresnel: the D3D9Client Fresnel power, 0 to 10000; default: 5"},
    {"r0", "R0", "fresnel: the reflectance at normal incidence, 0 to 1; default: from --ior"},
    {"m", "M",
     "fresnel: the D3D9Client multiplier, default 1 - R0; beckmann, smith: the RMS microfacet slope "
     "(roughness), default 0.3; 0 to 1000"},
    {"steps", "N", "angle steps from 0 to 90 degrees, 1 to 1000000; default: 90 (one degree apart)"},
    {"help", NULL, "this help, then exit 0"},
    {NULL, NULL, NULL},
};
const cli_command cli_eval_command = {
    .name = "eval",
    .run = cli_eval,
    .operands = "fresnel|beckmann|smith [options]",
    .operand_kind = "fresnel beckmann smith",
    .summary = "a model's values over an angle sweep, as CSV",
    .description = "Prints a CSV table over angles from 0 to 90 degrees: fresnel, the D3D9Client Fresnel and "
                   "Schlick's beside the exact dielectric; beckmann, the Beckmann distribution as Walter et al. "
                   "and as Cook-Torrance 1982 write it; smith, Walter's Smith G1 approximation beside the exact "
                   "G1. Float approximations, double-precision references.",
    .longopts = eval_longopts,
    .shortopts = "h",
    .options = eval_options_help,
    .example = "reflcheck eval fresnel --ior 1.33 --steps 18",
};

int cli_eval(int argc, char **argv)
{
    eval_args a = {.ior = 1.5, .p = 5.0, .m = 0.3, .steps = 90};
    int c, rc = CLI_OK;
    unsigned char seen[256] = {0};
    optind = 1;
    opterr = 0;
    while (rc == CLI_OK && (c = getopt_long(argc, argv, "h", eval_longopts, NULL)) != -1) {
        if (c != '?' && (rc = cli_check_option("eval", c, seen, "h", eval_longopts)) != CLI_OK)
            break;
        switch (c) {
        case 'n': rc = cli_parse_double("--ior", optarg, 1.0, 100.0, &a.ior); break;
        case 'p': rc = cli_parse_double("--p", optarg, 0.0, 1e4, &a.p); break;
        case 'r':
            rc = cli_parse_double("--r0", optarg, 0.0, 1.0, &a.r0);
            a.r0_given = 1;
            break;
        case 'm':
            rc = cli_parse_double("--m", optarg, 0.0, 1e3, &a.m);
            a.m_given = 1;
            break;
        case 's': rc = cli_parse_int("--steps", optarg, 1, 1000000, &a.steps); break;
        case 'h': return cli_help("eval");
        default: rc = cli_bad_option("eval", argc, argv, "h", eval_longopts, "see reflcheck eval --help");
        }
    }
    if (rc != CLI_OK)
        return rc;
    if (optind != argc - 1) {
        fprintf(stderr, "reflcheck: usage: reflcheck eval fresnel|beckmann|smith [options]\n");
        return CLI_BAD_INPUT;
    }
    const char *what = argv[optind];
    if (strcmp(what, "fresnel") == 0)
        eval_fresnel(&a);
    else if (strcmp(what, "beckmann") == 0)
        eval_beckmann(&a);
    else if (strcmp(what, "smith") == 0)
        eval_smith(&a);
    else {
        fprintf(stderr, "reflcheck: eval: unknown model '%s'; use fresnel, beckmann or smith\n", what);
        return CLI_BAD_INPUT;
    }
    /* printf reports nothing; a table cut short by a full disk must not look complete. */
    if (fflush(stdout) != 0 || ferror(stdout)) {
        fprintf(stderr, "reflcheck: eval: cannot write the table to standard output (%s); check where it goes\n",
                strerror(errno));
        return CLI_FAILED;
    }
    return CLI_OK;
}
