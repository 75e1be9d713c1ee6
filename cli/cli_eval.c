/* reflcheck eval: a model's values over an angle sweep, as CSV, float approximation beside
 * the double-precision exact reference. Exit 0, 1 when standard output cannot take the table
 * (e.g. a full disk), 2 for bad options. */
#include <errno.h>
#include <getopt.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include <cJSON.h>

#include "cli.h"
#include "formula.h"
#include "fresnel.h"
#include "jsonio.h"
#include "microfacet.h"
#include "physical.h"
#include "scene_file.h"

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

static double eval_mean(dvec3 v) { return (v.x + v.y + v.z) / 3.0; }

/* One material's reflectance at cos theta = N.V under its model: the factor its reflection (D3D9Client,
 * eq. 3) or its lobe (Cook-Torrance's F, eq. 4.9) takes from the angle; Direct3D's Blinn-Phong has
 * none, so its specular colour Vs, flat. The mean of R, G and B, so one curve per material. */
static double eval_model_reflectance(const material *m, double c)
{
    switch (m->model) {
    case MODEL_D3D9CLIENT: return fresnel_d3d9(m->d9.r0, m->d9.m, m->d9.p, (float)c);
    case MODEL_COOK_TORRANCE:
        if (m->ct.f == F_ONE)
            return 1.0;
        if (m->ct.f == F_EXACT)
            return eval_mean(physical_fresnel_exact(m, c));
        return eval_mean(dv3_from(fresnel_schlick_rgb(m->ct.f0, (float)c)));
    case MODEL_D3D:
    default: return eval_mean(dv3_from(m->d3d.specular));
    }
}

/* The words for the curve eval_model_reflectance draws, and for the physics' curve. */
static void eval_model_words(const material *m, char *buf, size_t len)
{
    static const char *const ct_f[] = {"Schlick", "F = 1", "exact Fresnel"};
    switch (m->model) {
    case MODEL_D3D9CLIENT:
        snprintf(buf, len, "D3D9Client eq. 3: R0 + m(1 - cos)^p, R0 = %.4g, m = %.4g, p = %.4g", m->d9.r0, m->d9.m,
                 m->d9.p);
        break;
    case MODEL_COOK_TORRANCE:
        snprintf(buf, len, "Cook-Torrance F: %s, F0 = (%.4g, %.4g, %.4g)", ct_f[m->ct.f], m->ct.f0.x, m->ct.f0.y,
                 m->ct.f0.z);
        break;
    case MODEL_D3D:
    default:
        snprintf(buf, len, "Direct3D Blinn-Phong: no Fresnel term, the specular colour Vs = (%.4g, %.4g, %.4g)",
                 m->d3d.specular.x, m->d3d.specular.y, m->d3d.specular.z);
    }
}

/* `eval materials SCENE`: each material of the scene, its model's reflectance against the angle
 * of incidence beside the scene's physics' (physics.fresnel_reflection for a D3D9Client
 * material, whose Fresnel weighs the environment reflection; fresnel_specular for the lobes of
 * the others; 0 for a material with no lobe), as JSON: Figure 1 for the scene's own materials. */
static int eval_materials(const char *path, int steps, const char *out)
{
    scene *s = malloc(sizeof *s);
    char err[1024];
    if (s == NULL || scene_file_load(path, s, err, sizeof err) != RC_OK) {
        fprintf(stderr, "reflcheck: %s\n", s ? err : "eval: out of memory for a scene");
        free(s);
        return s ? CLI_BAD_INPUT : CLI_FAILED;
    }
    cJSON *doc = cJSON_CreateObject(), *angles = cJSON_AddArrayToObject(doc, "angle_deg");
    cJSON_AddStringToObject(doc, "scene", s->name);
    cJSON_AddStringToObject(doc, "value", "reflectance against the angle of incidence, the mean of R, G and B");
    for (int i = 0; i <= steps; i++)
        cJSON_AddItemToArray(angles, cJSON_CreateNumber(90.0 * i / steps));
    cJSON *list = cJSON_AddArrayToObject(doc, "materials");
    for (int k = 0; k < s->n_materials; k++) {
        const material *m = &s->materials[k];
        physics_fresnel pf = m->model == MODEL_D3D9CLIENT ? s->physics.fresnel_reflection : s->physics.fresnel_specular;
        char words[200];
        cJSON *o = cJSON_CreateObject();
        cJSON_AddItemToArray(list, o);
        cJSON_AddStringToObject(o, "name", m->name);
        cJSON_AddStringToObject(o, "kind",
                                m->model == MODEL_D3D9CLIENT      ? "d3d9client"
                                : m->model == MODEL_COOK_TORRANCE ? "cooktorrance"
                                                                  : "d3d");
        eval_model_words(m, words, sizeof words);
        cJSON_AddStringToObject(o, "model_curve", words);
        if (!m->lobe)
            snprintf(words, sizeof words, "no specular lobe: the material reflects nothing in its physics");
        else if (m->conductor)
            snprintf(words, sizeof words,
                     "fresnel %s (the scene's physics), conductor eta (%.4g, %.4g, %.4g), k (%.4g, %.4g, %.4g)",
                     physics_fresnel_names[pf], m->eta.x, m->eta.y, m->eta.z, m->k.x, m->k.y, m->k.z);
        else
            snprintf(words, sizeof words, "fresnel %s (the scene's physics), dielectric n = %.4g",
                     physics_fresnel_names[pf], m->ior);
        cJSON_AddStringToObject(o, "physics_curve", words);
        cJSON *mv = cJSON_AddArrayToObject(o, "model"), *pv = cJSON_AddArrayToObject(o, "physics");
        for (int i = 0; i <= steps; i++) {
            double c = cos(90.0 * i / steps * FORMULA_PI_D / 180.0);
            /* 7 digits: the float model's own precision, and a plot's */
            cJSON_AddItemToArray(mv, jsonio_number(eval_model_reflectance(m, c), 7));
            cJSON_AddItemToArray(pv, jsonio_number(m->lobe ? eval_mean(physical_fresnel(m, pf, c)) : 0.0, 7));
        }
    }
    int rc = CLI_OK;
    if (out == NULL) {
        rc = jsonio_print(stdout, doc) == 0 ? CLI_OK : CLI_FAILED;
    } else {
        char dir[1200], file[1300];
        snprintf(dir, sizeof dir, "%s/%s", out, s->name);
        snprintf(file, sizeof file, "%s/figure1.json", dir);
        err[0] = '\0';
        if (mkdir(dir, 0777) != 0 && errno != EEXIST)
            snprintf(err, sizeof err, "%s", strerror(errno));
        else if (jsonio_write_file(doc, file, err, sizeof err) != RC_OK && err[0] == '\0')
            snprintf(err, sizeof err, "out of memory");
        if (err[0] != '\0') {
            fprintf(stderr, "reflcheck: eval: cannot write %s (%s); give --out an existing, writable run folder\n",
                    file, err);
            rc = CLI_FAILED;
        }
    }
    cJSON_Delete(doc);
    free(s);
    return rc;
}

static const struct option eval_longopts[] = {
    {"ior", required_argument, NULL, 'n'},   {"p", required_argument, NULL, 'p'},
    {"r0", required_argument, NULL, 'r'},    {"m", required_argument, NULL, 'm'},
    {"steps", required_argument, NULL, 's'}, {"out", required_argument, NULL, 'o'},
    {"help", no_argument, NULL, 'h'},        {NULL, 0, NULL, 0},
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
    {"out", "RUN",
     "materials: write RUN/<scene name>/figure1.json (the folder made if missing) instead of standard output; "
     "default: standard output"},
    {"help", NULL, "this help, then exit 0"},
    {NULL, NULL, NULL},
};
const cli_command cli_eval_command = {
    .name = "eval",
    .run = cli_eval,
    .operands = "fresnel|beckmann|smith [options] | materials SCENE [--steps N] [--out RUN]",
    .operand_kind = "fresnel beckmann smith materials",
    .summary = "a model's values over an angle sweep, as CSV (a scene's materials as JSON)",
    .description = "Prints a CSV table over angles from 0 to 90 degrees: fresnel, the D3D9Client Fresnel and "
                   "Schlick's beside the exact dielectric; beckmann, the Beckmann distribution as Walter et al. "
                   "and as Cook-Torrance 1982 write it; smith, Walter's Smith G1 approximation beside the exact "
                   "G1. Float approximations, double-precision references. materials SCENE prints JSON: each "
                   "material's reflectance against angle under its model (D3D9Client eq. 3, Cook-Torrance's F, "
                   "Blinn-Phong's flat Vs) beside the scene physics' Fresnel, the mean of R, G and B (the "
                   "report's Figure 1 of the scene).",
    .longopts = eval_longopts,
    .shortopts = "h",
    .options = eval_options_help,
    .example = "reflcheck eval fresnel --ior 1.33 --steps 18",
};

int cli_eval(int argc, char **argv)
{
    eval_args a = {.ior = 1.5, .p = 5.0, .m = 0.3, .steps = 90};
    int c, rc = CLI_OK;
    const char *out = NULL;
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
        case 'o': out = optarg; break;
        case 'h': return cli_help("eval");
        default: rc = cli_bad_option("eval", argc, argv, "h", eval_longopts, "see reflcheck eval --help");
        }
    }
    if (rc != CLI_OK)
        return rc;
    if (optind == argc - 2 && strcmp(argv[optind], "materials") == 0)
        return eval_materials(argv[optind + 1], a.steps, out);
    if (out != NULL) {
        fprintf(stderr, "reflcheck: eval: --out is for materials SCENE only; the tables go to standard output\n");
        return CLI_BAD_INPUT;
    }
    if (optind != argc - 1) {
        fprintf(stderr, "reflcheck: usage: reflcheck eval fresnel|beckmann|smith [options], or reflcheck eval "
                        "materials SCENE [--steps N]\n");
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
        fprintf(stderr, "reflcheck: eval: unknown model '%s'; use fresnel, beckmann, smith or materials SCENE\n", what);
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
