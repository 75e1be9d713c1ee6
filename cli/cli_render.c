/* reflcheck render: one scene through the rasterizer into a layered EXR.
 * Exit 2 before any rendering when the output could not be a result file: a device, FIFO or
 * directory, or the scene file or a file it references (compared by device and inode, so a
 * symlink or a second name is caught too). Exit 1 when the image cannot be written; the
 * destination is then as it was (exr_write writes a temporary file and renames it). */
#include <getopt.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli.h"
#include "exr.h"
#include "fileio.h"
#include "frame.h"
#include "render.h"

/* Refuses an output that names one of the scene's inputs; prints the error. */
static int cli_render_check_inputs(const char *out, const scene *s)
{
    const char *what = NULL, *input = NULL;
    if (fileio_same_file(out, s->path)) {
        what = "the scene file";
        input = s->path;
    } else if ((s->env.kind == ENV_IMAGE || s->env.kind == ENV_CUBE) && s->env.path[0] != '\0' &&
               fileio_same_file(out, s->env.path)) {
        what = "the environment image";
        input = s->env.path;
    }
    for (int f = 0; what == NULL && s->env.kind == ENV_CUBE && f < 6; f++)
        if (s->env.cube[f][0] != '\0' && fileio_same_file(out, s->env.cube[f])) {
            what = "a cube-map face of the scene";
            input = s->env.cube[f];
        }
    for (int i = 0; what == NULL && i < s->n_objects; i++)
        if (s->objects[i].shape == SHAPE_MESH && fileio_same_file(out, s->objects[i].path)) {
            what = "a mesh of the scene";
            input = s->objects[i].path;
        }
    for (int i = 0; what == NULL && i < s->n_materials; i++)
        for (int k = 0; what == NULL && k < MAT_TEX_SLOTS; k++)
            if (s->materials[i].texture[k][0] != '\0' && fileio_same_file(out, s->materials[i].texture[k])) {
                what = "a texture of the scene";
                input = s->materials[i].texture[k];
            }
    if (what == NULL)
        return CLI_OK;
    fprintf(stderr, "reflcheck: %s: the output is %s %s, which would be overwritten; give another -o path\n", out, what,
            input);
    return CLI_BAD_INPUT;
}

static const struct option render_longopts[] = {
    {"output", required_argument, NULL, 'o'},
    {"width", required_argument, NULL, 'W'},
    {"height", required_argument, NULL, 'H'},
    {"supersample", required_argument, NULL, 'k'},
    {"threads", required_argument, NULL, 't'},
    {"aovs", required_argument, NULL, 'a'},
    {"quiet", no_argument, NULL, 'q'},
    {"help", no_argument, NULL, 'h'},
    {NULL, 0, NULL, 0},
};
#define RENDER_SHORTOPTS "o:W:H:k:t:a:qh"
static const cli_option_help render_options_help[] = {
    {"output", "FILE", "the layered EXR to write (required); written under a temporary name and renamed"},
    {"width", "PIXELS", "image width in pixels, 1 to 16384; default: the scene's image.width"},
    {"height", "PIXELS", "image height in pixels, 1 to 16384; default: the scene's image.height"},
    {"supersample", "K", "K x K box-filtered samples per pixel, 1 to 16; default: the scene's image.supersample"},
    {"threads", "N", "rendering threads, 1 to 256; default: all cores"},
    {"aovs", "all|none",
     "all: the diffuse, specular, reflection and emission layers too; none: R, G, B, A, "
     "coverage and object only; default: all"},
    {"quiet", NULL, "print no summary line; default: one line (size, triangles, milliseconds, samples)"},
    {"help", NULL, "this help, then exit 0"},
    {NULL, NULL, NULL},
};
const cli_command cli_render_command = {
    .name = "render",
    .run = cli_render,
    .operands = "SCENE -o OUT.exr [options]",
    .operand_kind = "scene",
    .summary = "render one scene through reflcheck's rasterizer into a layered EXR",
    .description = "Renders SCENE (scenes/FORMAT.md) with the real-time models in reflcheck's own rasterizer. "
                   "Refuses (exit 2, before rendering) an output that is a device, FIFO or directory, or the "
                   "scene file or a file it references; a failed write leaves the destination as it was.",
    .longopts = render_longopts,
    .shortopts = RENDER_SHORTOPTS,
    .options = render_options_help,
    .example = "reflcheck render scenes/d3d9_glass.yaml -o glass.exr --width 320 --height 240",
};

int cli_render(int argc, char **argv)
{
    const char *out = NULL;
    render_options ro = {0};
    int quiet = 0, c, rc = CLI_OK;
    unsigned char seen[256] = {0};
    optind = 1;
    opterr = 0;
    while (rc == CLI_OK && (c = getopt_long(argc, argv, RENDER_SHORTOPTS, render_longopts, NULL)) != -1) {
        if (c != '?' && (rc = cli_check_option("render", c, seen, RENDER_SHORTOPTS, render_longopts)) != CLI_OK)
            break;
        switch (c) {
        case 'o': out = optarg; break;
        case 'W': rc = cli_parse_int("--width", optarg, 1, 16384, &ro.width); break;
        case 'H': rc = cli_parse_int("--height", optarg, 1, 16384, &ro.height); break;
        case 'k': rc = cli_parse_int("--supersample", optarg, 1, 16, &ro.supersample); break;
        case 't': rc = cli_parse_int("--threads", optarg, 1, 256, &ro.threads); break;
        case 'q': quiet = 1; break;
        case 'h': return cli_help("render");
        case 'a':
            if (strcmp(optarg, "all") == 0)
                ro.aovs = RENDER_AOV_ALL;
            else if (strcmp(optarg, "none") == 0)
                ro.aovs = RENDER_AOV_NONE;
            else {
                fprintf(stderr, "reflcheck: render: --aovs '%s': use all or none\n", optarg);
                rc = CLI_BAD_INPUT;
            }
            break;
        default:
            rc = cli_bad_option("render", argc, argv, RENDER_SHORTOPTS, render_longopts, "see reflcheck render --help");
        }
    }
    if (rc != CLI_OK)
        return rc;
    if (optind != argc - 1 || out == NULL) {
        fprintf(stderr, "reflcheck: usage: reflcheck render SCENE -o OUT.exr [options]\n");
        return CLI_BAD_INPUT;
    }

    char target[FILEIO_PATH_MAX], err[1024];
    rc_status ost = fileio_output_target(out, target, sizeof target, err, sizeof err);
    if (ost != RC_OK) {
        fprintf(stderr, "reflcheck: %s\n", err);
        return cli_exit_status(ost);
    }
    scene *s = malloc(sizeof *s);
    mesh m = {0};
    env_map env;
    float *env_pixels = NULL;
    texture_set tex;
    memset(&tex, 0, sizeof tex);
    ro.textures = &tex;
    render_image img = {0};
    if (s == NULL)
        return CLI_FAILED;
    rc = cli_load_scene(argv[optind], s, &m);
    if (rc == CLI_OK)
        rc = cli_render_check_inputs(out, s);
    if (rc == CLI_OK) {
        rc_status st = frame_inputs_load(s, &env, &env_pixels, &tex, err, sizeof err);
        if (st != RC_OK) {
            /* The environment image is the user's input: missing, unreadable or with bad texels
             * is bad input (exit 2), as `check` says for the same file; only memory is ours. */
            fprintf(stderr, "reflcheck: %s\n", err);
            rc = st == RC_ERR_NOMEM ? CLI_FAILED : CLI_BAD_INPUT;
        } else if ((st = render_scene(s, &m, &env, &ro, &img, err, sizeof err)) != RC_OK) {
            fprintf(stderr, "reflcheck: %s\n", err);
            rc = cli_exit_status(st);
        }
    }
    if (rc == CLI_OK) {
        if (frame_write(out, s, &m, &img, err, sizeof err) != RC_OK) {
            fprintf(stderr, "reflcheck: %s\n", err);
            rc = CLI_FAILED;
        }
        if (rc == CLI_OK && !quiet &&
            (printf("%s: %dx%d k=%d, %d triangles, %.3f ms, %lld shaded samples -> %s\n", s->name, img.width,
                    img.height, img.supersample, m.n_tris, img.seconds * 1e3, img.shaded_samples, out) < 0 ||
             fflush(stdout) != 0)) {
            fprintf(stderr,
                    "reflcheck: render: %s was written, but the summary could not be printed; check "
                    "where standard output goes\n",
                    out);
            rc = CLI_FAILED;
        }
    }
    render_image_free(&img);
    free(env_pixels);
    texture_set_free(&tex);
    mesh_free(&m);
    free(s);
    return rc;
}
