/* reflcheck fit: the best each approximation can do on each validate comparison of a scene.
 * For every validate comparison of the model against a reference, the reference comes through
 * the job cache (the same render job as the comparison, so a run's references are reused), and
 * the model's free parameters are fitted to it (harness/fit.h) within the seeds' ranges, or
 * with --bounds wide within wider ones. One record per scene, OUT/<scene>/fit.json (wide:
 * fit-wide.json), with as-authored and best-fit NRMSE and median relative error, the
 * fitted values, evaluations and seconds.
 * Exit status: 0 every fit ran or was skipped (its reference renderer is not installed or cannot
 * represent the scene, or the scene has no free parameter); 1 a reference job failed, a fit
 * failed, or the record could not be written; 2 bad input (command line, a scene file or a file
 * it references). A scene without validate comparisons of the model is reported and skipped. */
#include <errno.h>
#include <getopt.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <cJSON.h>

#include "cli.h"
#include "compare.h"
#include "exr.h"
#include "fileio.h"
#include "fit.h"
#include "frame.h"
#include "jobs.h"
#include "jsonio.h"
#include "scene_file.h"

typedef struct {
    job_variant variant;
    fit_bounds bounds;
    const char *out_dir, *cache_dir;
    fit_options fo;
} cli_fit_opts;

/* A number, or null where it is not one (JSON has no NaN). */
static void cli_fit_num(cJSON *o, const char *key, double v)
{
    if (isfinite(v))
        cJSON_AddNumberToObject(o, key, v);
    else
        cJSON_AddNullToObject(o, key);
}

static cJSON *cli_fit_error_json(const fit_error *e)
{
    cJSON *o = cJSON_CreateObject();
    cli_fit_num(o, "nrmse", e->nrmse);
    cli_fit_num(o, "median_rel", e->median_rel);
    cli_fit_num(o, "nrmse_trim1", e->nrmse_trim1);
    cli_fit_num(o, "worst1_share", e->worst1_share);
    cJSON_AddNumberToObject(o, "n_pixels", (double)e->n_pixels);
    return o;
}

/* The global stage and every local run: budget, screen, starts and where each ended, so the
 * spread across starts shows whether the best point was found more than once. */
static cJSON *cli_fit_global_json(const fit_result *r, const scene *sc, const fit_param *p, int n,
                                  const cli_fit_opts *opt)
{
    cJSON *g = cJSON_CreateObject();
    cJSON_AddNumberToObject(g, "budget", opt->fo.max_evals);
    cJSON_AddNumberToObject(g, "screen_points", r->screen_points);
    cJSON_AddNumberToObject(g, "starts_asked", opt->fo.starts > 0 ? opt->fo.starts : FIT_DEFAULT_STARTS);
    cJSON_AddNumberToObject(g, "best_start", r->best_start);
    cJSON_AddNumberToObject(g, "uncertainty_evaluations", r->uncertainty_evaluations);
    cJSON_AddNumberToObject(g, "uncertainty_tol", FIT_UNCERTAINTY_TOL);
    int within = 0;
    cJSON *runs = cJSON_AddArrayToObject(g, "starts");
    for (int s = 0; s < r->n_starts; s++) {
        const fit_start *st = &r->starts[s];
        cJSON *o = cJSON_CreateObject();
        cJSON *a = cJSON_AddObjectToObject(o, "start"), *e = cJSON_AddObjectToObject(o, "end");
        for (int i = 0; i < n; i++) {
            char key[SCENE_NAME_MAX + 8];
            snprintf(key, sizeof key, "%s.%s", sc->materials[p[i].material].name, fit_param_label(sc, &p[i]));
            cJSON_AddNumberToObject(a, key, st->start[i]);
            cJSON_AddNumberToObject(e, key, st->end[i]);
        }
        cli_fit_num(o, "nrmse", st->nrmse);
        cJSON_AddNumberToObject(o, "evaluations", st->evaluations);
        cJSON_AddStringToObject(o, "stop", st->stop);
        cJSON_AddItemToArray(runs, o);
        within += st->nrmse <= r->best.nrmse * (1.0 + FIT_UNCERTAINTY_TOL);
    }
    cJSON_AddNumberToObject(g, "starts_within_tol", within);
    return g;
}

/* Marks the record o an error with reason why. */
static void cli_fit_error(cJSON *o, const char *why)
{
    cJSON_AddStringToObject(o, "status", "error");
    cJSON_AddStringToObject(o, "reason", why);
}

/* The job whose image the fit reads, as "reference_job": its record (the run's own when the
 * run made it: reused), and from that record its cache key, whether the cache handed the image
 * to that job, its CPU seconds, when it finished and its Slurm job and node (null outside
 * Slurm), so the fit names the render it used even when that render came from the cache. */
static void cli_fit_job_json(cJSON *o, const job_record *rec)
{
    cJSON *r = cJSON_AddObjectToObject(o, "reference_job");
    cJSON_AddStringToObject(r, "record", rec->record);
    cJSON_AddBoolToObject(r, "reused", rec->reused);
    char *text = fileio_read_all(rec->record, NULL);
    cJSON *job = text != NULL ? cJSON_Parse(text) : NULL;
    free(text);
    static const char *const keys[] = {"key", "cached", "cpu_s", "finished_unix", "slurm"};
    for (size_t i = 0; i < sizeof keys / sizeof keys[0]; i++) {
        cJSON *v = cJSON_GetObjectItem(job, keys[i]);
        cJSON_AddItemToObject(r, keys[i], v != NULL ? cJSON_Duplicate(v, 1) : cJSON_CreateNull());
    }
    cJSON_Delete(job);
}

/* The reference image of comparison id: its validate job through the cache, read and passed
 * through compare's value gate. Returns 1 with *img filled (the caller frees it), or 0 with the
 * exit status this comparison earns in *exit_status and the reason in o. */
static int cli_fit_reference(const char *path, const scene *s, int reference, const char *id, const cli_fit_opts *opt,
                             cJSON *o, exr_image *img, job_record *rec, int *exit_status)
{
    job_spec j = {.scene_path = path,
                  .renderer = reference,
                  .role = ROLE_VALIDATE,
                  .variant = opt->variant,
                  .out_dir = opt->out_dir,
                  .cache_dir = opt->cache_dir,
                  .threads = opt->fo.threads,
                  .reuse_record = 1};
    char err[1024];
    rc_status st = job_run(&j, rec, err, sizeof err);
    if (st != RC_OK) {
        fprintf(stderr, "reflcheck: fit: %s\n", err);
        cli_fit_error(o, err);
        return *exit_status = job_exit_status(st, rec), 0;
    }
    cli_fit_job_json(o, rec);
    if (rec->status != RUNNER_OK) {
        int skipped = rec->status == RUNNER_MISSING;
        cJSON_AddStringToObject(o, "status", skipped ? "skipped" : "error");
        char why[700];
        snprintf(why, sizeof why, "%s validate job %s: %s", registry_name(reference), runner_status_name(rec->status),
                 rec->message);
        cJSON_AddStringToObject(o, "reason", why);
        printf("%-20s %-28s %s: %s\n", s->name, id, skipped ? "skipped" : "error", why);
        if (!skipped)
            fprintf(stderr, "reflcheck: fit: %s: %s\n", path, why);
        return *exit_status = skipped ? CLI_OK : CLI_FAILED, 0;
    }
    if (exr_read(rec->exr, img, err, sizeof err) != RC_OK) {
        fprintf(stderr, "reflcheck: fit: %s: the reference image: %s\n", path, err);
        cli_fit_error(o, err);
        return *exit_status = CLI_FAILED, 0;
    }
    /* compare's value gate, the same function: a reference compare would fail for a NaN or Inf
     * (or a negative) value is no reference to fit to, though the fit's sums could skip it. */
    char gate[900];
    if (compare_value_gate(s, img, reference, ROLE_VALIDATE, "ref", gate, sizeof gate)) {
        char why[1100];
        snprintf(why, sizeof why, "values: %s (%s)", gate, rec->exr);
        fprintf(stderr, "reflcheck: fit: %s: %s: %s; the comparison fails on it, so no fit is made\n", path, id, why);
        cli_fit_error(o, why);
        printf("%-20s %-28s error: %s\n", s->name, id, why);
        exr_image_free(img);
        return *exit_status = CLI_FAILED, 0;
    }
    return 1;
}

/* The fitted parameters as the record's "parameters" array, and as " material.name=value" for
 * the summary line in vals. */
static void cli_fit_params_json(cJSON *o, const scene *s, const fit_param *p, int n, char *vals, size_t vals_len)
{
    cJSON *pa = cJSON_AddArrayToObject(o, "parameters");
    size_t used = 0;
    vals[0] = '\0';
    for (int i = 0; i < n; i++) {
        cJSON *q = cJSON_CreateObject();
        cJSON_AddStringToObject(q, "material", s->materials[p[i].material].name);
        cJSON_AddStringToObject(q, "name", fit_param_label(s, &p[i]));
        cJSON_AddNumberToObject(q, "authored", p[i].authored);
        cJSON_AddNumberToObject(q, "fitted", p[i].value);
        cJSON_AddNumberToObject(q, "lo", p[i].lo);
        cJSON_AddNumberToObject(q, "hi", p[i].hi);
        cJSON_AddStringToObject(q, "scale", p[i].log_scale ? "log" : "linear");
        cJSON_AddBoolToObject(q, "at_bound", p[i].at_bound);
        if (p[i].kind == FIT_D9_R0)
            cJSON_AddBoolToObject(q, "m_follows", p[i].tied);
        cli_fit_num(q, "uncertainty", p[i].uncertainty);
        cJSON_AddNumberToObject(q, "spread_lo", p[i].spread_lo);
        cJSON_AddNumberToObject(q, "spread_hi", p[i].spread_hi);
        cJSON_AddItemToArray(pa, q);
        if (used < vals_len)
            used += (size_t)snprintf(vals + used, vals_len - used, " %s.%s=%.4g", s->materials[p[i].material].name,
                                     fit_param_label(s, &p[i]), p[i].value);
    }
}

/* A finished fit into the record o, and its summary line on standard output. */
static void cli_fit_record(cJSON *o, const scene *s, const char *id, const char *exr, const fit_result *r,
                           const fit_param *p, int n, const cli_fit_opts *opt)
{
    char vals[512];
    cJSON_AddStringToObject(o, "status", "ok");
    cJSON_AddStringToObject(o, "reference_exr", exr);
    cJSON_AddItemToObject(o, "authored", cli_fit_error_json(&r->authored));
    cJSON_AddItemToObject(o, "best", cli_fit_error_json(&r->best));
    cli_fit_params_json(o, s, p, n, vals, sizeof vals);
    cJSON_AddNumberToObject(o, "evaluations", r->evaluations);
    cJSON_AddNumberToObject(o, "renders", r->renders);
    cJSON_AddItemToObject(o, "global", cli_fit_global_json(r, s, p, n, opt));
    cJSON_AddNumberToObject(o, "seconds", r->seconds);
    cJSON_AddNumberToObject(o, "cpu_seconds", r->cpu_seconds);
    cJSON_AddStringToObject(o, "stop", r->stop);
    cJSON_AddNumberToObject(o, "width", r->width);
    cJSON_AddNumberToObject(o, "height", r->height);
    cJSON_AddNumberToObject(o, "supersample", r->supersample);
    printf("%-20s %-28s nrmse %.4g -> %.4g, median %.4g -> %.4g (%d evaluations, %d renders, %.1f s)%s\n", s->name, id,
           r->authored.nrmse, r->best.nrmse, r->authored.median_rel, r->best.median_rel, r->evaluations, r->renders,
           r->seconds, vals);
}

/* One validate comparison: its reference through the job cache, then the fit. Returns the exit
 * status this comparison earns; the record goes into fits. */
static int cli_fit_one(const char *path, const scene *s, const mesh *m, const env_map *env, const texture_set *tex,
                       int reference, const cli_fit_opts *opt, cJSON *fits)
{
    char id[128];
    snprintf(id, sizeof id, "%s-vs-%s-validate", registry_name(registry_model()), registry_name(reference));
    cJSON *o = cJSON_CreateObject();
    cJSON_AddItemToArray(fits, o);
    cJSON_AddStringToObject(o, "id", id);
    cJSON_AddStringToObject(o, "reference", registry_name(reference));

    fit_param p[FIT_MAX_PARAMS];
    int n = fit_default_params(s, opt->bounds, p, FIT_MAX_PARAMS);
    if (n == 0) {
        cJSON_AddStringToObject(o, "status", "skipped");
        cJSON_AddStringToObject(o, "reason",
                                "no free parameter: no material has a fresnel power, a Blinn-Phong specular "
                                "colour or a Beckmann m");
        printf("%-20s %-28s skipped: no free parameter\n", s->name, id);
        return CLI_OK;
    }
    exr_image img;
    job_record rec;
    int exit_status;
    if (!cli_fit_reference(path, s, reference, id, opt, o, &img, &rec, &exit_status))
        return exit_status;
    metrics_image ref = {img.width,
                         img.height,
                         {exr_image_channel(&img, "R"), exr_image_channel(&img, "G"), exr_image_channel(&img, "B")}};
    fit_result r;
    fit_options fo = opt->fo;
    fo.textures = tex;
    fo.crease_rules = registry_row(reference)->crease_rules;
    char err[1024];
    rc_status st = fit_run(s, m, env, &ref, p, n, &fo, &r, err, sizeof err);
    exr_image_free(&img);
    if (st != RC_OK) {
        fprintf(stderr, "reflcheck: fit: %s\n", err);
        cli_fit_error(o, err);
        return CLI_FAILED;
    }
    cli_fit_record(o, s, id, rec.exr, &r, p, n, opt);
    return CLI_OK;
}

/* Every validate comparison of one scene; the record is written when the scene has any. */
static int cli_fit_scene(const char *path, const cli_fit_opts *opt)
{
    scene *s = malloc(sizeof *s);
    if (s == NULL) {
        fprintf(stderr, "reflcheck: fit: %s: out of memory for a scene\n", path);
        return CLI_FAILED;
    }
    mesh m = {0};
    env_map env;
    float *env_pixels = NULL;
    texture_set tex = {0};
    char err[1024];
    int rc = CLI_OK;
    rc_status st = scene_file_load(path, s, err, sizeof err);
    if (st == RC_OK) {
        /* The size and samples the validate job renders at, so the images line up. */
        job_apply_variant(s, opt->variant);
        char why[900];
        st = mesh_build(s, &m, why, sizeof why);
        if (st != RC_OK)
            snprintf(err, sizeof err, "%s: objects: %s", path, why);
    }
    /* The frame the raster validate job renders (harness/jobs.c): environment, textures, and
     * the environment's sun moved into a light where the scene asks. */
    if (st == RC_OK)
        st = frame_inputs_load(s, &env, &env_pixels, &tex, err, sizeof err);
    if (st != RC_OK) {
        fprintf(stderr, "reflcheck: %s\n", err);
        rc = st == RC_ERR_NOMEM ? CLI_FAILED : CLI_BAD_INPUT;
    }
    int n_validate = 0;
    for (int i = 0; rc == CLI_OK && i < s->n_comparisons; i++)
        n_validate += s->comparisons[i].role == ROLE_VALIDATE && s->comparisons[i].test == registry_model() &&
                      s->comparisons[i].reference != registry_model();
    if (rc == CLI_OK && n_validate == 0)
        printf("%-20s no validate comparison of the model: nothing to fit\n", s->name);
    if (rc == CLI_OK && n_validate > 0) {
        cJSON *root = cJSON_CreateObject();
        cJSON_AddStringToObject(root, "scene", s->name);
        cJSON_AddStringToObject(root, "scene_path", path);
        cJSON_AddStringToObject(root, "variant", opt->variant == JOB_SMALL ? "small" : "full");
        cJSON_AddStringToObject(root, "bounds", opt->bounds == FIT_BOUNDS_WIDE ? "wide" : "seed");
        cJSON_AddStringToObject(root, "algorithm",
                                "a Halton screen (global), then NLopt LN_BOBYQA from the authored point and the best "
                                "screened points apart from it (local), parameters scaled to [0, 1] over their bounds");
        cJSON_AddNumberToObject(root, "starts", opt->fo.starts > 0 ? opt->fo.starts : FIT_DEFAULT_STARTS);
        cJSON_AddStringToObject(root, "uncertainty",
                                "per parameter: the change raising the best NRMSE by uncertainty_tol of itself, "
                                "from the objective's curvature at the best point");
        cJSON_AddNumberToObject(root, "max_evaluations", opt->fo.max_evals);
        cJSON_AddNumberToObject(root, "xtol_scaled", opt->fo.xtol);
        cJSON_AddStringToObject(root, "objective",
                                "least squares over surface pixels (R, G, B), reported as NRMSE = RMSE / mean "
                                "reference");
        cJSON *fits = cJSON_AddArrayToObject(root, "fits");
        for (int i = 0; i < s->n_comparisons; i++) {
            const comparison *c = &s->comparisons[i];
            if (c->role != ROLE_VALIDATE || c->test != registry_model() || c->reference == registry_model())
                continue;
            int one = cli_fit_one(path, s, &m, &env, &tex, c->reference, opt, fits);
            if (one > rc)
                rc = one;
        }
        /* No reference job made the scene's folder when no comparison had a free parameter. */
        char out[1200];
        snprintf(out, sizeof out, "%s/%s", opt->out_dir, s->name);
        if (job_mkdirs(out) != 0)
            fprintf(stderr, "reflcheck: fit: %s: %s\n", out, strerror(errno));
        snprintf(out, sizeof out, "%s/%s/%s", opt->out_dir, s->name,
                 opt->bounds == FIT_BOUNDS_WIDE ? "fit-wide.json" : "fit.json");
        if (jsonio_write_file(root, out, err, sizeof err) != RC_OK) {
            fprintf(stderr, "reflcheck: fit: %s\n", err);
            rc = CLI_FAILED;
        }
        cJSON_Delete(root);
    }
    mesh_free(&m);
    free(env_pixels);
    texture_set_free(&tex);
    free(s);
    return rc;
}

static const struct option fit_longopts[] = {
    {"out", required_argument, NULL, 'o'},
    {"small", no_argument, NULL, 's'},
    {"cache", required_argument, NULL, 'c'},
    {"no-cache", no_argument, NULL, 'n'},
    {"threads", required_argument, NULL, 't'},
    {"max-evals", required_argument, NULL, 'M'},
    {"xtol", required_argument, NULL, 'x'},
    {"bounds", required_argument, NULL, 'b'},
    {"starts", required_argument, NULL, 'S'},
    {"help", no_argument, NULL, 'h'},
    {NULL, 0, NULL, 0},
};
static const cli_option_help fit_options_help[] = {
    {"out", "DIR",
     "the run folder: the record is DIR/<scene>/fit.json (fit-wide.json with --bounds wide); "
     "default: reports/runs/manual"},
    {"small", NULL, "fit at the small variant's size and samples; default: full size"},
    {"cache", "DIR", "the render cache the reference jobs go through; default: reports/cache"},
    {"no-cache", NULL, "render the references without the cache; default: use the cache"},
    {"threads", "N", "render threads, 1 to 256; default: all cores"},
    {"max-evals", "N", "renders per fit in all (screen and local runs), 2 to 100000; default: 400"},
    {"xtol", "X",
     "the local runs' stopping step, in parameters scaled to [0, 1] over their bounds, 1e-12 to "
     "0.5; default: 1e-4"},
    {"bounds", "seed|wide", "seed: within the seeds' ranges; wide: within wider ones; default: seed"},
    {"starts", "N", "local runs, 1 to 8 (1: from the authored point only, no screen); default: 4"},
    {"help", NULL, "this help, then exit 0"},
    {NULL, NULL, NULL},
};
const cli_command cli_fit_command = {
    .name = "fit",
    .run = cli_fit,
    .operands = "SCENE... [options]",
    .operand_kind = "scene",
    .summary = "the model's free parameters fitted to each validate reference",
    .description = "For every validate comparison of the model against a reference, renders the reference "
                   "through the job cache and fits the model's free parameters (Fresnel power, Blinn-Phong "
                   "specular colour, Beckmann m) to it: a Halton screen, then NLopt BOBYQA runs. Prints the "
                   "as-authored and best-fit NRMSE and median relative error, and writes them with the fitted "
                   "values to the record. A reference renderer that is not installed is skipped.",
    .longopts = fit_longopts,
    .shortopts = "o:h",
    .options = fit_options_help,
    .example = "reflcheck fit scenes/d3d9_glass.yaml --small --out /tmp/run1",
};

int cli_fit(int argc, char **argv)
{
    cli_fit_opts opt = {.variant = JOB_FULL,
                        .out_dir = "reports/runs/manual",
                        .cache_dir = "reports/cache",
                        .fo = {.max_evals = FIT_DEFAULT_EVALS, .xtol = FIT_DEFAULT_XTOL}};
    int c, rc = CLI_OK;
    unsigned char seen[256] = {0};
    optind = 1;
    opterr = 0;
    while (rc == CLI_OK && (c = getopt_long(argc, argv, "o:h", fit_longopts, NULL)) != -1) {
        if (c != '?' && (rc = cli_check_option("fit", c, seen, "o:h", fit_longopts)) != CLI_OK)
            break;
        switch (c) {
        case 'o': opt.out_dir = optarg; break;
        case 's': opt.variant = JOB_SMALL; break;
        case 'c': opt.cache_dir = optarg; break;
        case 'n': opt.cache_dir = NULL; break;
        case 't': rc = cli_parse_int("--threads", optarg, 1, 256, &opt.fo.threads); break;
        case 'M': rc = cli_parse_int("--max-evals", optarg, 2, 100000, &opt.fo.max_evals); break;
        case 'S': rc = cli_parse_int("--starts", optarg, 1, FIT_MAX_STARTS, &opt.fo.starts); break;
        case 'x': rc = cli_parse_double("--xtol", optarg, 1e-12, 0.5, &opt.fo.xtol); break;
        case 'h': return cli_help("fit");
        case 'b':
            if (strcmp(optarg, "seed") == 0 || strcmp(optarg, "wide") == 0) {
                opt.bounds = optarg[0] == 'w' ? FIT_BOUNDS_WIDE : FIT_BOUNDS_SEED;
            } else {
                fprintf(stderr, "reflcheck: fit: --bounds '%s': use seed (the seeds' ranges) or wide\n", optarg);
                rc = CLI_BAD_INPUT;
            }
            break;
        default: rc = cli_bad_option("fit", argc, argv, "o:h", fit_longopts, "see reflcheck fit --help");
        }
    }
    if (rc != CLI_OK)
        return rc;
    if (optind >= argc) {
        fprintf(stderr, "reflcheck: usage: reflcheck fit SCENE... [--out DIR] [--small] [--cache DIR | --no-cache] "
                        "[--threads N] [--max-evals N] [--xtol X] [--bounds seed|wide] [--starts N]\n");
        return CLI_BAD_INPUT;
    }
    /* Every scene is read before any is fitted, so a bad one refuses the command at once. */
    scene *s = malloc(sizeof *s);
    if (s == NULL)
        return CLI_FAILED;
    for (int i = optind; i < argc && rc == CLI_OK; i++) {
        char err[1024];
        rc_status st = scene_file_load(argv[i], s, err, sizeof err);
        if (st != RC_OK) {
            fprintf(stderr, "reflcheck: %s\n", err);
            rc = st == RC_ERR_NOMEM ? CLI_FAILED : CLI_BAD_INPUT;
        }
    }
    free(s);
    for (int i = optind; i < argc && rc != CLI_BAD_INPUT; i++) {
        int one = cli_fit_scene(argv[i], &opt);
        if (one > rc)
            rc = one;
    }
    return rc;
}
