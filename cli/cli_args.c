/* cli_args.c - what every command shares: exit statuses, loading a scene, parsing numbers and
 * refusing options with one line (cli.h declares them). The command table (cli.c) calls the
 * commands; the commands call these; nothing here calls back. */
#include "cli.h"

#include <ctype.h>
#include <errno.h>
#include <getopt.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "scene_file.h"

int cli_exit_status(int rc)
{
    if (rc == RC_OK)
        return CLI_OK;
    return (rc == RC_ERR_PARSE || rc == RC_ERR_RANGE) ? CLI_BAD_INPUT : CLI_FAILED;
}

/* The error of a failed load or build, one line; the exit status it means. */
static int cli_load_failed(rc_status st, const char *err)
{
    fprintf(stderr, "reflcheck: %s\n", err);
    if (st == RC_ERR_IO)
        return CLI_BAD_INPUT;
    return cli_exit_status(st);
}

int cli_build_mesh(const char *path, scene *s, mesh *m)
{
    char err[1024], why[900];
    rc_status st = mesh_build(s, m, why, sizeof why);
    /* The mesh error names the mesh file and line; say which scene asked for it too. */
    if (st != RC_OK) {
        snprintf(err, sizeof err, "%s: objects: %s", path, why);
        return cli_load_failed(st, err);
    }
    if (mesh_repair_note(s, m, why, sizeof why))
        fprintf(stderr, "reflcheck: note: %s: %s\n", path, why);
    return CLI_OK;
}

int cli_load_scene(const char *path, scene *s, mesh *m)
{
    char err[1024];
    rc_status st = scene_file_load(path, s, err, sizeof err);
    if (st != RC_OK)
        return cli_load_failed(st, err);
    return m != NULL ? cli_build_mesh(path, s, m) : CLI_OK;
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
