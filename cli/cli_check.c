/* cli_check.c - `reflcheck check`: a scene file parsed, its meshes, environment and textures
 * loaded and its references' physics checked, without rendering; --json prints the comparisons
 * and their gates as parsed (tools/gates.py reads them). */
#include "cli.h"

#include <getopt.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fileio.h"
#include "frame.h"
#include "jobs.h"
#include "jsonio.h"
#include "scene_file.h"

/* The scene's own facts beside its comparisons: its full size, supersampling and Cycles samples
 * as parsed (samples 0: `auto`, from the gates' noise), for tools/sweep/. */
static void cli_check_json_image(cJSON *doc, const scene *s)
{
    cJSON *img = cJSON_AddObjectToObject(doc, "image");
    cJSON_AddNumberToObject(img, "width", s->width);
    cJSON_AddNumberToObject(img, "height", s->height);
    cJSON_AddNumberToObject(img, "supersample", s->supersample);
    cJSON_AddNumberToObject(img, "samples", s->samples);
}

/* `check --json SCENE`: the scene file's comparisons and their thresholds as parsed, for
 * tools/gates.py and tools/sweep/, which must not read YAML a second way. Each comparison names
 * its test (the default resolved: `test_is_model` says it computes the model), its reference
 * and its role. Parses the file only. */
static int cli_check_json(const char *path)
{
    static const char *const sizes[] = {"", "small", "full"};
    scene *s = malloc(sizeof *s);
    char err[1024];
    if (s == NULL || scene_file_load(path, s, err, sizeof err) != RC_OK) {
        fprintf(stderr, "reflcheck: %s\n", s ? err : "check: out of memory for a scene");
        free(s);
        return s ? CLI_BAD_INPUT : CLI_FAILED;
    }
    cJSON *doc = cJSON_CreateObject(), *list = cJSON_AddArrayToObject(doc, "comparisons");
    cJSON_AddStringToObject(doc, "scene", s->name);
    cli_check_json_image(doc, s);
    for (int i = 0; list && i < s->n_comparisons; i++) {
        const comparison *c = &s->comparisons[i];
        cJSON *o = cJSON_CreateObject(), *ths = cJSON_AddArrayToObject(o, "thresholds");
        char id[96];
        snprintf(id, sizeof id, "%s-vs-%s-%s", registry_name(c->test), registry_name(c->reference),
                 job_role_names[c->role]);
        cJSON_AddStringToObject(o, "id", id);
        cJSON_AddStringToObject(o, "test", registry_name(c->test));
        cJSON_AddBoolToObject(o, "test_is_model", c->test == registry_model());
        cJSON_AddStringToObject(o, "reference", registry_name(c->reference));
        cJSON_AddStringToObject(o, "role", job_role_names[c->role]);
        cJSON_AddItemToArray(list, o);
        for (int j = 0; ths && j < c->n_thresholds; j++) {
            const threshold *t = &c->thresholds[j];
            cJSON *th = cJSON_CreateObject();
            cJSON_AddStringToObject(th, "metric", t->metric);
            cJSON_AddNumberToObject(th, "warn", t->warn);
            cJSON_AddNumberToObject(th, "fail", t->fail);
            cJSON_AddStringToObject(th, "why", t->why);
            cJSON_AddStringToObject(th, "loose", t->loose);
            if (t->sized_size != SIZED_NONE) {
                cJSON *z = cJSON_AddObjectToObject(th, "sized");
                cJSON_AddNumberToObject(z, "figure", t->sized_figure);
                cJSON_AddStringToObject(z, "size", sizes[t->sized_size]);
                cJSON_AddStringToObject(z, "run", t->sized_run);
            }
            /* The gate each size is judged by, resolved here so gates.py reads one answer. */
            for (int k = 0; k < 2; k++) {
                threshold_gate g;
                threshold_gate_at(t, k, &g);
                cJSON *at = cJSON_AddObjectToObject(th, sizes[1 + k]);
                cJSON_AddNumberToObject(at, "warn", g.warn);
                cJSON_AddNumberToObject(at, "fail", g.fail);
                cJSON_AddStringToObject(at, "loose", g.loose);
                cJSON_AddBoolToObject(at, "own", g.own);
                if (g.sized_size != SIZED_NONE) {
                    cJSON *z = cJSON_AddObjectToObject(at, "sized");
                    cJSON_AddNumberToObject(z, "figure", g.sized_figure);
                    cJSON_AddStringToObject(z, "size", sizes[g.sized_size]);
                    cJSON_AddStringToObject(z, "run", g.sized_run);
                }
            }
            cJSON_AddItemToArray(ths, th);
        }
    }
    int rc = jsonio_print(stdout, doc) == 0 ? CLI_OK : CLI_FAILED;
    cJSON_Delete(doc);
    free(s);
    return rc;
}

static const struct option cli_check_longopts[] = {
    {"json", no_argument, NULL, 'j'}, {"help", no_argument, NULL, 'h'}, {NULL, 0, NULL, 0}};
static const cli_option_help cli_check_options[] = {
    {"json", NULL,
     "print the scene's name, image (width, height, supersample, samples) and comparisons (test, test_is_model, "
     "reference, role, thresholds) as parsed, as JSON, instead of checking it (parses "
     "the file only); give it before SCENE"},
    {"help", NULL, "this help, then exit 0"},
    {NULL, NULL, NULL},
};
const cli_command cli_check_command = {
    .name = "check",
    .run = cli_check,
    .operands = "[--json] SCENE",
    .operand_kind = "scene",
    .summary = "parse and validate a scene, without rendering",
    .description = "Loads everything render loads (the scene file, its meshes, its environment image with its "
                   "texels checked, its textures) and asks render's memory estimate for the scene's own size, so "
                   "a scene that passes check does not fail render on its inputs or its size. Prints one line: "
                   "objects, triangles, lights, materials and the environment.",
    .longopts = cli_check_longopts,
    .shortopts = "h",
    .options = cli_check_options,
    .example = "reflcheck check scenes/d3d9_glass.yaml",
};

/* Loads everything `render` loads (the scene, its meshes, its environment image with its
 * texels checked) and asks render's own memory estimate, without rendering, so a scene that
 * passes check does not fail render on its inputs or its size. Everything here is the
 * user's input: a failure is bad input (2), except running out of memory (1). */
int cli_check(int argc, char **argv)
{
    /* check's options take no value, so a word before "--" that is -h or --help is the option,
     * as getopt_long would read it. */
    for (int i = 1; i < argc && strcmp(argv[i], "--") != 0; i++)
        if (strcmp(argv[i], "-h") == 0 || strcmp(argv[i], "--help") == 0)
            return cli_help("check");
    if (argc == 3 && strcmp(argv[1], "--json") == 0)
        return cli_check_json(argv[2]);
    if (argc != 2) {
        fprintf(stderr, "reflcheck: usage: reflcheck check [--json] SCENE\n");
        return CLI_BAD_INPUT;
    }
    scene *s = malloc(sizeof *s);
    if (s == NULL) {
        fprintf(stderr, "reflcheck: check: out of memory for a scene\n");
        return CLI_FAILED;
    }
    mesh m = {0};
    env_map env;
    float *env_pixels = NULL;
    texture_set tex;
    memset(&tex, 0, sizeof tex);
    int rc = cli_load_scene(argv[1], s, &m);
    if (rc == CLI_OK) {
        char err[1024];
        rc_status st = frame_inputs_load(s, &env, &env_pixels, &tex, err, sizeof err);
        /* A validate or agree whose reference cannot render the physics would only be skipped. */
        if (st == RC_OK)
            st = scene_file_physics_check(s, err, sizeof err);
        if (st != RC_OK) {
            fprintf(stderr, "reflcheck: %s\n", err);
            rc = st == RC_ERR_NOMEM ? CLI_FAILED : CLI_BAD_INPUT;
        }
    }
    if (rc == CLI_OK) {
        /* The scene's own size, as `render SCENE` without options would refuse it. */
        size_t limit = 0;
        double need = 0.0;
        char why[256];
        if (fileio_memory_limit(&limit, why, sizeof why) != RC_OK) {
            fprintf(stderr, "reflcheck: %s: %s\n", argv[1], why);
            rc = CLI_BAD_INPUT;
        } else {
            render_memory_estimate(s, &m, &env, NULL, &need, NULL);
            if (need > (double)limit) {
                fprintf(stderr,
                        "reflcheck: %s: image: a %dx%d render at supersample %d needs about %.2f GiB, over "
                        "the memory limit of %.2f GiB; make image.width, image.height or image.supersample smaller, "
                        "or raise REFLCHECK_MEMORY_LIMIT\n",
                        argv[1], s->width, s->height, s->supersample, need / 1073741824.0,
                        (double)limit / 1073741824.0);
                rc = CLI_BAD_INPUT;
            }
        }
    }
    if (rc == CLI_OK) {
        char envs[64] = "";
        if (s->env.kind == ENV_IMAGE)
            snprintf(envs, sizeof envs, ", environment %dx%d", env.width, env.height);
        else if (s->env.kind == ENV_CUBE)
            snprintf(envs, sizeof envs, ", cube map 6 x %dx%d", env.width, env.height);
        printf("%s: ok: %d objects, %d triangles, %d lights, %d materials%s\n", argv[1], s->n_objects, m.n_tris,
               s->n_lights, s->n_materials, envs);
    }
    free(env_pixels);
    texture_set_free(&tex);
    mesh_free(&m);
    free(s);
    return rc;
}
