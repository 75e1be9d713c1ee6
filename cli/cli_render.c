/* reflcheck render: one scene through the rasterizer into a layered EXR.
 * Exit 2 before any rendering when the output could not be a result file: a device, FIFO or
 * directory, or the scene file or a file it references (compared by device and inode, so a
 * symlink or a second name is caught too). Exit 1 when the image cannot be written; the
 * destination is then as it was (exr_write writes a temporary file and renames it).
 * --stats FILE writes where the command's time went (cli_render_stats_write): a user's answer to
 * "why did one frame take this long", and what `make bench` reads for its CLI ratios. */
#include <getopt.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <time.h>

#include "cli.h"
#include "exr.h"
#include "fileio.h"
#include "frame.h"
#include "jsonio.h"
#include "render.h"

/* The command's phases in the order it runs them; --stats reports each. */
typedef enum {
    CLI_PHASE_SCENE,  /* parse and validate the scene file */
    CLI_PHASE_MESH,   /* tessellate the shapes, read the mesh files */
    CLI_PHASE_INPUTS, /* read and decode the environment and the textures */
    CLI_PHASE_RENDER, /* render_scene, call to return: its layers allocated fresh */
    CLI_PHASE_WRITE,  /* the crease layer and the EXR file */
    CLI_PHASE_FREE,   /* the layers, mesh and inputs released */
    CLI_PHASE_COUNT
} cli_phase;

static const char *const cli_phase_names[CLI_PHASE_COUNT] = {"scene", "mesh", "inputs", "render", "write", "free"};

/* Wall time, CPU time (user + system, all threads) and minor page faults of each phase: on a
 * shared machine the CPU time is the figure that load does not inflate; the faults show what
 * touching fresh memory costs. */
typedef struct {
    double wall[CLI_PHASE_COUNT], cpu[CLI_PHASE_COUNT];
    long faults[CLI_PHASE_COUNT];
    double t_wall, t_cpu; /* at the last mark */
    long t_faults;
} cli_phase_clock;

static void cli_phase_now(double *wall, double *cpu, long *faults)
{
    struct timespec ts;
    struct rusage ru;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    getrusage(RUSAGE_SELF, &ru);
    *wall = (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
    *cpu =
        (double)(ru.ru_utime.tv_sec + ru.ru_stime.tv_sec) + 1e-6 * (double)(ru.ru_utime.tv_usec + ru.ru_stime.tv_usec);
    *faults = ru.ru_minflt;
}

/* Charges the time since the last mark to phase p. */
static void cli_phase_mark(cli_phase_clock *c, cli_phase p)
{
    double w, u;
    long f;
    cli_phase_now(&w, &u, &f);
    c->wall[p] += w - c->t_wall;
    c->cpu[p] += u - c->t_cpu;
    c->faults[p] += f - c->t_faults;
    c->t_wall = w, c->t_cpu = u, c->t_faults = f;
}

/* Refuses an output (given by option opt) that names one of the scene's inputs; prints the error. */
static int cli_render_check_inputs(const char *out, const char *opt, const scene *s)
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
    fprintf(stderr, "reflcheck: %s: the output is %s %s, which would be overwritten; give another %s path\n", out, what,
            input, opt);
    return CLI_BAD_INPUT;
}

static const struct option render_longopts[] = {
    {"output", required_argument, NULL, 'o'},  {"width", required_argument, NULL, 'W'},
    {"height", required_argument, NULL, 'H'},  {"supersample", required_argument, NULL, 'k'},
    {"threads", required_argument, NULL, 't'}, {"aovs", required_argument, NULL, 'a'},
    {"stats", required_argument, NULL, 's'},   {"quiet", no_argument, NULL, 'q'},
    {"help", no_argument, NULL, 'h'},          {NULL, 0, NULL, 0},
};
#define RENDER_SHORTOPTS "o:W:H:k:t:a:s:qh"
static const cli_option_help render_options_help[] = {
    {"output", "FILE", "the layered EXR to write (required); written under a temporary name and renamed"},
    {"width", "PIXELS", "image width in pixels, 1 to 16384; default: the scene's image.width"},
    {"height", "PIXELS", "image height in pixels, 1 to 16384; default: the scene's image.height"},
    {"supersample", "K", "K x K box-filtered samples per pixel, 1 to 16; default: the scene's image.supersample"},
    {"threads", "N", "rendering threads, 1 to 256; default: all cores"},
    {"aovs", "all|none",
     "all: the diffuse, specular, reflection and emission layers too; none: R, G, B, A, "
     "coverage and object only; default: all"},
    {"stats", "FILE",
     "write where the time went as JSON: wall ms, CPU ms (user + system) and minor page faults of each "
     "phase (scene, mesh, inputs, render, write, free); default: none"},
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

/* The --stats document: the frame's size and work, then each phase's wall ms, CPU ms and minor
 * page faults. render.wall_ms is render_scene from call to return, the frame as this command
 * renders it; render_ms is render_scene's own clock (the summary line's figure). */
static int cli_render_stats_write(const char *path, const scene *s, int n_tris, const render_image *img,
                                  const render_options *ro, const cli_phase_clock *c)
{
    cJSON *doc = cJSON_CreateObject(), *ph = cJSON_CreateObject();
    int ok = doc != NULL && jsonio_add(doc, "scene", cJSON_CreateString(s->name)) &&
             jsonio_add(doc, "width", cJSON_CreateNumber(img->width)) &&
             jsonio_add(doc, "height", cJSON_CreateNumber(img->height)) &&
             jsonio_add(doc, "supersample", cJSON_CreateNumber(img->supersample)) &&
             jsonio_add(doc, "threads", cJSON_CreateNumber(ro->threads)) &&
             jsonio_add(doc, "triangles", cJSON_CreateNumber(n_tris)) &&
             jsonio_add(doc, "shaded_samples", cJSON_CreateNumber((double)img->shaded_samples)) &&
             jsonio_add(doc, "render_ms", jsonio_number(img->seconds * 1e3, 6));
    double wall = 0.0, cpu = 0.0;
    for (int p = 0; ok && p < CLI_PHASE_COUNT; p++) {
        cJSON *o = cJSON_CreateObject();
        ok = jsonio_add(ph, cli_phase_names[p], o) && jsonio_add(o, "wall_ms", jsonio_number(c->wall[p] * 1e3, 6)) &&
             jsonio_add(o, "cpu_ms", jsonio_number(c->cpu[p] * 1e3, 6)) &&
             jsonio_add(o, "minor_faults", cJSON_CreateNumber((double)c->faults[p]));
        wall += c->wall[p], cpu += c->cpu[p];
    }
    if (ok) {
        ok = jsonio_add(doc, "phases", ph);
        ph = NULL; /* the document owns it now, or jsonio_add freed it */
    }
    ok = ok && jsonio_add(doc, "phases_wall_ms", jsonio_number(wall * 1e3, 6)) &&
         jsonio_add(doc, "phases_cpu_ms", jsonio_number(cpu * 1e3, 6));
    char err[1024] = "out of memory";
    if (ok && jsonio_write_file(doc, path, err, sizeof err) == RC_OK) {
        cJSON_Delete(doc);
        return CLI_OK;
    }
    cJSON_Delete(ph);
    cJSON_Delete(doc);
    fprintf(stderr, "reflcheck: render: --stats %s: %s; give a writable path\n", path, err);
    return CLI_FAILED;
}

/* Parses render's options into ro, out, stats and quiet; CLI_OK, or the refusal printed. */
static int cli_render_options(int argc, char **argv, render_options *ro, const char **out, const char **stats,
                              int *quiet)
{
    int c, rc = CLI_OK;
    unsigned char seen[256] = {0};
    optind = 1;
    opterr = 0;
    while (rc == CLI_OK && (c = getopt_long(argc, argv, RENDER_SHORTOPTS, render_longopts, NULL)) != -1) {
        if (c != '?' && (rc = cli_check_option("render", c, seen, RENDER_SHORTOPTS, render_longopts)) != CLI_OK)
            break;
        switch (c) {
        case 'o': *out = optarg; break;
        case 's': *stats = optarg; break;
        case 'W': rc = cli_parse_int("--width", optarg, 1, 16384, &ro->width); break;
        case 'H': rc = cli_parse_int("--height", optarg, 1, 16384, &ro->height); break;
        case 'k': rc = cli_parse_int("--supersample", optarg, 1, 16, &ro->supersample); break;
        case 't': rc = cli_parse_int("--threads", optarg, 1, 256, &ro->threads); break;
        case 'q': *quiet = 1; break;
        case 'h': return -1;
        case 'a':
            if (strcmp(optarg, "all") == 0)
                ro->aovs = RENDER_AOV_ALL;
            else if (strcmp(optarg, "none") == 0)
                ro->aovs = RENDER_AOV_NONE;
            else {
                fprintf(stderr, "reflcheck: render: --aovs '%s': use all or none\n", optarg);
                rc = CLI_BAD_INPUT;
            }
            break;
        default:
            rc = cli_bad_option("render", argc, argv, RENDER_SHORTOPTS, render_longopts, "see reflcheck render --help");
        }
    }
    if (rc == CLI_OK && (optind != argc - 1 || *out == NULL)) {
        fprintf(stderr, "reflcheck: usage: reflcheck render SCENE -o OUT.exr [options]\n");
        rc = CLI_BAD_INPUT;
    }
    if (rc == CLI_OK && *stats != NULL && (strcmp(*stats, *out) == 0 || fileio_same_file(*stats, *out))) {
        fprintf(stderr, "reflcheck: render: --stats %s names the image -o writes; give another --stats path\n", *stats);
        rc = CLI_BAD_INPUT;
    }
    return rc;
}

/* Everything the command holds; zeroed, then filled phase by phase. */
typedef struct {
    scene s;
    mesh m;
    env_map env;
    float *env_pixels;
    texture_set tex;
    render_image img;
} cli_render_state;

/* Scene, mesh, inputs, frame and file, each charged to its phase on clk. */
static int cli_render_run(const char *path, const char *out, const char *stats, render_options *ro,
                          cli_render_state *st, cli_phase_clock *clk)
{
    char err[1024];
    int rc = cli_load_scene(path, &st->s, NULL);
    cli_phase_mark(clk, CLI_PHASE_SCENE);
    if (rc == CLI_OK)
        rc = cli_render_check_inputs(out, "-o", &st->s);
    if (rc == CLI_OK && stats != NULL)
        rc = cli_render_check_inputs(stats, "--stats", &st->s);
    if (rc == CLI_OK)
        rc = cli_build_mesh(path, &st->s, &st->m);
    cli_phase_mark(clk, CLI_PHASE_MESH);
    if (rc != CLI_OK)
        return rc;
    ro->textures = &st->tex;
    rc_status sts = frame_inputs_load(&st->s, &st->env, &st->env_pixels, &st->tex, err, sizeof err);
    cli_phase_mark(clk, CLI_PHASE_INPUTS);
    if (sts != RC_OK) {
        /* The environment image is the user's input: missing, unreadable or with bad texels
         * is bad input (exit 2), as `check` says for the same file; only memory is ours. */
        fprintf(stderr, "reflcheck: %s\n", err);
        return sts == RC_ERR_NOMEM ? CLI_FAILED : CLI_BAD_INPUT;
    }
    sts = render_scene(&st->s, &st->m, &st->env, ro, &st->img, err, sizeof err);
    cli_phase_mark(clk, CLI_PHASE_RENDER);
    if (sts != RC_OK) {
        fprintf(stderr, "reflcheck: %s\n", err);
        return cli_exit_status(sts);
    }
    sts = frame_write(out, &st->s, &st->m, &st->img, err, sizeof err);
    cli_phase_mark(clk, CLI_PHASE_WRITE);
    if (sts != RC_OK) {
        fprintf(stderr, "reflcheck: %s\n", err);
        return CLI_FAILED;
    }
    return CLI_OK;
}

int cli_render(int argc, char **argv)
{
    const char *out = NULL, *stats = NULL;
    render_options ro = {0};
    int quiet = 0;
    cli_phase_clock clk;
    memset(&clk, 0, sizeof clk);
    cli_phase_now(&clk.t_wall, &clk.t_cpu, &clk.t_faults);
    int rc = cli_render_options(argc, argv, &ro, &out, &stats, &quiet);
    if (rc < 0)
        return cli_help("render");
    if (rc != CLI_OK)
        return rc;

    char target[FILEIO_PATH_MAX], err[1024];
    rc_status ost = fileio_output_target(out, target, sizeof target, err, sizeof err);
    if (ost != RC_OK) {
        fprintf(stderr, "reflcheck: %s\n", err);
        return cli_exit_status(ost);
    }
    cli_render_state *st = calloc(1, sizeof *st);
    if (st == NULL)
        return CLI_FAILED;
    rc = cli_render_run(argv[optind], out, stats, &ro, st, &clk);
    if (rc == CLI_OK && !quiet &&
        (printf("%s: %dx%d k=%d, %d triangles, %.3f ms, %lld shaded samples -> %s\n", st->s.name, st->img.width,
                st->img.height, st->img.supersample, st->m.n_tris, st->img.seconds * 1e3, st->img.shaded_samples,
                out) < 0 ||
         fflush(stdout) != 0)) {
        fprintf(stderr,
                "reflcheck: render: %s was written, but the summary could not be printed; check "
                "where standard output goes\n",
                out);
        rc = CLI_FAILED;
    }
    /* Released before --stats is written, so that its free phase is measured; the image keeps its
     * size and counts. */
    int n_tris = st->m.n_tris;
    render_image_free(&st->img);
    free(st->env_pixels);
    texture_set_free(&st->tex);
    mesh_free(&st->m);
    cli_phase_mark(&clk, CLI_PHASE_FREE);
    if (rc == CLI_OK && stats != NULL)
        rc = cli_render_stats_write(stats, &st->s, n_tris, &st->img, &ro, &clk);
    free(st);
    return rc;
}
