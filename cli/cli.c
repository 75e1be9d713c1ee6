#include "cli.h"

#include <ctype.h>
#include <errno.h>
#include <getopt.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fileio.h"
#include "frame.h"
#include "jobs.h"
#include "jsonio.h"
#include "render.h"
#include "renderers/registry.h"
#include "scene_file.h"
#include "status.h"

static int cli_help_run(int argc, char **argv);
static const struct option cli_help_longopts[] = {{"help", no_argument, NULL, 'h'}, {NULL, 0, NULL, 0}};
static const cli_option_help cli_help_options[] = {{"help", NULL, "this help, then exit 0"}, {NULL, NULL, NULL}};
static const cli_command cli_help_command = {
    .name = "help",
    .run = cli_help_run,
    .operands = "[COMMAND]",
    .operand_kind = "command",
    .summary = "the commands, or one command's help (as COMMAND --help)",
    .description = "Without a command, lists the commands, the exit status and the environment variables "
                   "(as reflcheck --help). With one, prints that command's help: its options with their "
                   "defaults and units, and an example.",
    .longopts = cli_help_longopts,
    .shortopts = "h",
    .options = cli_help_options,
    .example = "reflcheck help run",
};

/* The one command table: main.c dispatches through it, help and tools/gen_man.c read it. */
static const cli_command *const cli_commands[] = {
    &cli_render_command,    &cli_check_command,   &cli_eval_command, &cli_run_command,
    &cli_plan_command,      &cli_compare_command, &cli_diff_command, &cli_stability_command,
    &cli_renderers_command, &cli_fit_command,     &cli_help_command,
};

int cli_command_count(void) { return (int)(sizeof cli_commands / sizeof cli_commands[0]); }

const cli_command *cli_command_at(int i) { return i >= 0 && i < cli_command_count() ? cli_commands[i] : NULL; }

const cli_command *cli_find(const char *name)
{
    for (int i = 0; i < cli_command_count(); i++)
        if (strcmp(cli_commands[i]->name, name) == 0)
            return cli_commands[i];
    return NULL;
}

const char cli_exit_text[] =
    "0 ok; 1 a run failed: a job that is not ok or skipped, a comparison that fails or errors, a write "
    "that failed (full disk, ulimit -f); 2 bad input: the command line, a scene file, a mesh or image it "
    "references, an output path that is an input or a device.";
const char cli_env_text[] =
    "REFLCHECK_DATA_DIR: the folder holding reflcheck's own files (the scripts Blender runs, the "
    "sources its cache keys cover); default: the tree it was built from, or PREFIX/share/reflcheck "
    "for an installed copy. REFLCHECK_KEY_SOURCES: the folder of the cache keys' source lists; "
    "default: BUILD/key-sources, or PREFIX/share/reflcheck/key-sources. REFLCHECK_MEMORY_LIMIT: the "
    "most memory a render may take, bytes with K, M, G or T; default: the machine's available memory. "
    "REFLCHECK_OIIO_PLUGIN: the DDS plugin (reflcheck-oiio.so); default: the build's, or "
    "PREFIX/lib/reflcheck. PATH: where povray and blender are found.";

/* Writes text word-wrapped to width columns, every line indented by indent columns; col is the
 * column the cursor is at (the first line continues from there). */
static void cli_wrap(FILE *f, const char *text, int col, int indent, int width)
{
    while (*text != '\0') {
        size_t word = strcspn(text, " ");
        if (col > indent && col + 1 + (int)word > width) {
            fprintf(f, "\n%*s", indent, "");
            col = indent;
        } else if (col > indent) {
            fputc(' ', f);
            col++;
        } else if (col < indent) {
            fprintf(f, "%*s", indent - col, "");
            col = indent;
        }
        fwrite(text, 1, word, f);
        col += (int)word;
        text += word;
        text += strspn(text, " ");
    }
    fputc('\n', f);
}

/* The help text of the option named name, or NULL when the command's help lacks it. */
static const cli_option_help *cli_option_text(const cli_command *c, const char *name)
{
    for (const cli_option_help *h = c->options; h != NULL && h->name != NULL; h++)
        if (strcmp(h->name, name) == 0)
            return h;
    return NULL;
}

/* "  -o, --output FILE" for an option, into buf. */
static void cli_option_head(const cli_command *c, const struct option *o, const cli_option_help *h, char *buf,
                            size_t len)
{
    char alias[8] = "";
    if (o->flag == NULL && o->val > 0 && o->val < 128 && strchr(c->shortopts, o->val) != NULL)
        snprintf(alias, sizeof alias, "-%c, ", o->val);
    snprintf(buf, len, "  %s--%s%s%s", alias, o->name, h != NULL && h->value != NULL ? " " : "",
             h != NULL && h->value != NULL ? h->value : "");
}

static void cli_print_help(FILE *f, const cli_command *c)
{
    fprintf(f, "usage: reflcheck %s %s\n", c->name, c->operands);
    cli_wrap(f, c->summary, 0, 0, 79);
    fputc('\n', f);
    cli_wrap(f, c->description, 0, 0, 79);
    fprintf(f, "\noptions:\n");
    /* From the option table, so every option the parser takes shows; its text from the help
     * table (a missing one shows as such, and tests/test_cli.c fails on it). */
    for (const struct option *o = c->longopts; o->name != NULL; o++) {
        const cli_option_help *h = cli_option_text(c, o->name);
        char head[96];
        cli_option_head(c, o, h, head, sizeof head);
        fputs(head, f);
        /* A head reaching the text column puts the text on the next line, as GNU tools do. */
        int col = (int)strlen(head);
        if (col > 26) {
            fputc('\n', f);
            col = 0;
        }
        cli_wrap(f, h != NULL ? h->text : "(no help: add it to the command's cli_option_help table)", col, 28, 79);
    }
    fprintf(f, "\nexample:\n  %s\n\nexit status:", c->example);
    cli_wrap(f, cli_exit_text, 12, 2, 79);
}

int cli_help(const char *command)
{
    const cli_command *c = cli_find(command);
    if (c == NULL) {
        fprintf(stderr, "reflcheck: help: unknown command '%s'; see reflcheck --help for the commands\n", command);
        return CLI_BAD_INPUT;
    }
    cli_print_help(stdout, c);
    if (fflush(stdout) != 0 || ferror(stdout)) {
        fprintf(stderr, "reflcheck: %s --help: cannot write to standard output: %s\n", command, strerror(errno));
        return CLI_FAILED;
    }
    return CLI_OK;
}

void cli_usage(FILE *f)
{
    fprintf(f, "usage: reflcheck COMMAND [OPTION...] [ARGUMENT...]\n"
               "       reflcheck --help | --version\n"
               "Real-time reflection models against POV-Ray and Blender, per pixel.\n\ncommands:\n");
    for (int i = 0; i < cli_command_count(); i++) {
        fprintf(f, "  %-11s", cli_commands[i]->name);
        cli_wrap(f, cli_commands[i]->summary, 13, 13, 79);
    }
    /* The renderer names come from the table, so a renderer added there is named here too. */
    char names[512], line[600];
    snprintf(line, sizeof line, "%s (run --renderer, scene files; reflcheck renderers for more)",
             registry_list(names, sizeof names));
    fprintf(f, "\nrenderers:");
    cli_wrap(f, line, 11, 2, 79);
    fprintf(f, "\nreflcheck COMMAND --help (or -h) shows a command's options, defaults and an example.\n\n"
               "exit status:");
    cli_wrap(f, cli_exit_text, 12, 2, 79);
    fprintf(f, "\nenvironment:");
    cli_wrap(f, cli_env_text, 12, 2, 79);
}

static int cli_help_run(int argc, char **argv)
{
    int c;
    optind = 1;
    opterr = 0;
    while ((c = getopt_long(argc, argv, "h", cli_help_longopts, NULL)) != -1) {
        if (c == 'h')
            return cli_help("help");
        return cli_bad_option("help", argc, argv, "h", cli_help_longopts, "usage: reflcheck help [COMMAND]");
    }
    if (optind < argc - 1) {
        fprintf(stderr, "reflcheck: help: unexpected argument '%s'; usage: reflcheck help [COMMAND]\n",
                argv[optind + 1]);
        return CLI_BAD_INPUT;
    }
    if (optind == argc - 1)
        return cli_help(argv[optind]);
    cli_usage(stdout);
    if (fflush(stdout) != 0 || ferror(stdout)) {
        fprintf(stderr, "reflcheck: help: cannot write to standard output: %s\n", strerror(errno));
        return CLI_FAILED;
    }
    return CLI_OK;
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
    /* strtol skips leading blanks, so " 7" passed where "7 " did not: a value is the number alone */
    if (errno != 0 || end == text || *end != '\0' || isspace((unsigned char)text[0]) || v < lo || v > hi) {
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
    if (errno != 0 || end == text || *end != '\0' || isspace((unsigned char)text[0]) || !isfinite(v) || v < lo ||
        v > hi) {
        fprintf(stderr, "reflcheck: %s '%s': expected a number from %g to %g\n", opt, text, lo, hi);
        return CLI_BAD_INPUT;
    }
    *out = v;
    return CLI_OK;
}

/* `check --json SCENE`: the scene file's comparisons and their thresholds as parsed, for
 * tools/gates.py, which must not read YAML a second way. Parses the file only. */
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
    for (int i = 0; list && i < s->n_comparisons; i++) {
        const comparison *c = &s->comparisons[i];
        cJSON *o = cJSON_CreateObject(), *ths = cJSON_AddArrayToObject(o, "thresholds");
        char id[96];
        snprintf(id, sizeof id, "%s-vs-%s-%s", registry_name(c->test), registry_name(c->reference),
                 job_role_names[c->role]);
        cJSON_AddStringToObject(o, "id", id);
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
     "print the scene's comparisons and their thresholds as parsed, as JSON, instead of checking it (parses "
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
        rc_status st = frame_env_load(s, &env, &env_pixels, err, sizeof err);
        if (st == RC_OK)
            st = frame_textures_load(s, &tex, err, sizeof err);
        if (st == RC_OK)
            st = frame_env_split_sun(s, env_pixels, &env, NULL, err, sizeof err);
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

/* The argument getopt_long was reading when it refused a short option: a group such as
 * "-rf.yaml" stays at argv[optind] until its last letter, after which optind moves past it. */
static const char *cli_refused_arg(int argc, char **argv)
{
    if (optopt != 0 && optind < argc && argv[optind][0] == '-' && argv[optind][1] != '-' &&
        strchr(argv[optind] + 1, optopt) != NULL)
        return argv[optind];
    return argv[optind - 1];
}

/* 1 when getopt_long knows the option it refused: it then lacked its value (or, given as
 * --name=VALUE, had one it does not take). */
static int cli_known_option(const char *arg, const char *shortopts, const struct option *longopts)
{
    if (optopt == 0)
        return 0;
    if (strncmp(arg, "--", 2) != 0)
        return strchr(shortopts, optopt) != NULL;
    size_t len = strcspn(arg + 2, "=");
    for (const struct option *o = longopts; o->name != NULL; o++)
        if (strlen(o->name) == len && strncmp(o->name, arg + 2, len) == 0)
            return 1;
    return 0;
}

int cli_bad_option(const char *cmd, int argc, char **argv, const char *shortopts, const struct option *longopts,
                   const char *usage)
{
    const char *arg = cli_refused_arg(argc, argv);
    if (!cli_known_option(arg, shortopts, longopts)) {
        if (optopt != 0 && strncmp(arg, "--", 2) != 0 && strlen(arg) > 2)
            fprintf(stderr, "reflcheck: %s: unknown option '-%c' in argument '%s'; %s\n", cmd, optopt, arg, usage);
        else
            fprintf(stderr, "reflcheck: %s: unknown option '%s'; %s\n", cmd, arg, usage);
    } else if (strchr(arg, '=') != NULL && strncmp(arg, "--", 2) == 0) {
        fprintf(stderr, "reflcheck: %s: option '%.*s' takes no value (argument '%s'); %s\n", cmd,
                (int)strcspn(arg, "="), arg, arg, usage);
    } else {
        fprintf(stderr, "reflcheck: %s: option '%s' needs a value after it; %s\n", cmd, arg, usage);
    }
    return CLI_BAD_INPUT;
}

int cli_check_option(const char *cmd, int c, unsigned char seen[256], const char *shortopts,
                     const struct option *longopts)
{
    const struct option *o = longopts;
    while (o->name != NULL && (o->flag != NULL || o->val != c))
        o++;
    if (o->name == NULL || c < 0 || c > 255 || o->has_arg != required_argument)
        return CLI_OK;
    char alias[8] = "";
    if (strchr(shortopts, c) != NULL)
        snprintf(alias, sizeof alias, " (-%c)", c);
    if (optarg == NULL || optarg[0] == '\0') {
        /* An empty path is no path: "--out ''" made "/<scene>" at the file system's root. */
        fprintf(stderr, "reflcheck: %s: option '--%s'%s has an empty value; give it a value\n", cmd, o->name, alias);
        return CLI_BAD_INPUT;
    }
    if (seen[c]) {
        fprintf(stderr,
                "reflcheck: %s: option '--%s'%s given twice (the last, '%s', would win silently); give it once\n", cmd,
                o->name, alias, optarg);
        return CLI_BAD_INPUT;
    }
    seen[c] = 1;
    return CLI_OK;
}
