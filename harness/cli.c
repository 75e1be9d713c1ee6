#include "cli.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fileio.h"
#include "frame.h"
#include "render.h"
#include "scene_file.h"
#include "status.h"

static const cli_command cli_commands[] = {
    {"render", cli_render},       {"check", cli_check}, {"eval", cli_eval}, {"run", cli_run},
    {"compare", cli_compare},     {"diff", cli_diff},   {"plan", cli_plan}, {"stability", cli_stability},
    {"renderers", cli_renderers}, {"fit", cli_fit},
};

const cli_command *cli_find(const char *name)
{
    for (size_t i = 0; i < sizeof cli_commands / sizeof cli_commands[0]; i++)
        if (strcmp(cli_commands[i].name, name) == 0)
            return &cli_commands[i];
    return NULL;
}

int cli_exit_status(int rc)
{
    if (rc == RC_OK)
        return CLI_OK;
    return (rc == RC_ERR_PARSE || rc == RC_ERR_RANGE) ? CLI_BAD_INPUT : CLI_FAILED;
}

int cli_load_scene(const char *path, scene *s, mesh *m)
{
    char err[1024];
    rc_status st = scene_file_load(path, s, err, sizeof err);
    if (st == RC_OK && m != NULL) {
        char why[900];
        st = mesh_build(s, m, why, sizeof why);
        /* The mesh error names the mesh file and line; say which scene asked for it too. */
        if (st != RC_OK)
            snprintf(err, sizeof err, "%s: objects: %s", path, why);
        else if (mesh_repair_note(s, m, why, sizeof why))
            fprintf(stderr, "reflcheck: note: %s: %s\n", path, why);
    }
    if (st != RC_OK) {
        fprintf(stderr, "reflcheck: %s\n", err);
        if (st == RC_ERR_IO)
            return CLI_BAD_INPUT;
        return cli_exit_status(st);
    }
    return CLI_OK;
}

int cli_parse_int(const char *opt, const char *text, int lo, int hi, int *out)
{
    char *end;
    errno = 0;
    long v = strtol(text, &end, 10);
    if (errno != 0 || end == text || *end != '\0' || v < lo || v > hi) {
        fprintf(stderr, "reflcheck: %s '%s': expected a whole number from %d to %d\n", opt, text, lo, hi);
        return CLI_BAD_INPUT;
    }
    *out = (int)v;
    return CLI_OK;
}

int cli_parse_double(const char *opt, const char *text, double lo, double hi, double *out)
{
    char *end;
    errno = 0;
    double v = strtod(text, &end);
    if (errno != 0 || end == text || *end != '\0' || !isfinite(v) || v < lo || v > hi) {
        fprintf(stderr, "reflcheck: %s '%s': expected a number from %g to %g\n", opt, text, lo, hi);
        return CLI_BAD_INPUT;
    }
    *out = v;
    return CLI_OK;
}

/* Loads everything `render` loads (the scene, its meshes, its environment image with its
 * texels checked) and asks render's own memory estimate, without rendering, so a scene that
 * passes check does not fail render on its inputs or its size. Everything here is the
 * user's input: a failure is bad input (2), except running out of memory (1). */
int cli_check(int argc, char **argv)
{
    if (argc != 2) {
        fprintf(stderr, "reflcheck: usage: reflcheck check SCENE\n");
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
        rc_status st = frame_env_load(s, &env, &env_pixels, err, sizeof err);
        if (st == RC_OK)
            st = frame_textures_load(s, &tex, err, sizeof err);
        if (st == RC_OK)
            st = frame_env_split_sun(s, env_pixels, &env, NULL, err, sizeof err);
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
