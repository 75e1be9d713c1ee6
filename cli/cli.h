/* cli.h - the reflcheck commands: one function per command, argv[0] is the command name.
 *
 * Usage:
 *   const cli_command *c = cli_find("render");  c->run(argc, argv) returns the exit status:
 *   (every command takes -h/--help: cli_help(name) prints its help, exit 0)
 *   0 ok, 1 a run failed (I/O, renderer), 2 bad input (command line or scene file).
 * cli_load_scene parses a scene file and tessellates it; errors are printed as one line.
 */
#ifndef REFLCHECK_CLI_H
#define REFLCHECK_CLI_H

#include <stdio.h>

#include "mesh.h"
#include "scene.h"

struct option;

/* One option's help, beside the command's getopt_long table: name is the long name as there,
 * value the placeholder of its value (NULL for a flag; "a|b" lists the values it takes, FILE,
 * DIR and RENDERER tell shell completion what to offer), text what it does with its default
 * and unit. */
typedef struct {
    const char *name;
    const char *value;
    const char *text;
} cli_option_help;

/* A command: its function, its option table and its help, defined once in its cli_*.c file and
 * listed in cli.c's command table, which `reflcheck --help`, COMMAND --help, the manual page
 * and the shell completion (tools/gen_man.c) all read. */
typedef struct {
    const char *name;
    int (*run)(int argc, char **argv);
    const char *operands;           /* the usage line after the name, e.g. "SCENE -o OUT.exr [options]" */
    const char *operand_kind;       /* completion of operands: "scene", "exr", "command", words, or "" */
    const char *summary;            /* one line */
    const char *description;        /* a paragraph, unwrapped */
    const struct option *longopts;  /* getopt_long's table, {NULL} ended */
    const char *shortopts;          /* getopt_long's short options */
    const cli_option_help *options; /* one per longopts entry, {NULL} ended */
    const char *example;
} cli_command;

enum { CLI_OK = 0, CLI_FAILED = 1, CLI_BAD_INPUT = 2 };

const cli_command *cli_find(const char *name);
/* The command table, in the order help lists it: i from 0 to cli_command_count() - 1. */
int cli_command_count(void);
const cli_command *cli_command_at(int i);
/* `reflcheck COMMAND --help`: usage, summary, description, every option with its default and
 * unit, an example, on stdout; CLI_OK, or CLI_FAILED when stdout cannot take it. */
int cli_help(const char *command);
/* `reflcheck --help`: the commands with their summaries, the exit status and environment. */
void cli_usage(FILE *f);
/* The text help prints for the exit status and environment, also in the manual page. */
extern const char cli_exit_text[];
extern const char cli_env_text[];

/* Exit status for an rc_status: parse and range errors are bad input (2), others failures (1). */
int cli_exit_status(int rc);
/* Loads and validates SCENE, then tessellates it into m (if m is not NULL). Prints the error. */
int cli_load_scene(const char *path, scene *s, mesh *m);
/* The second half of cli_load_scene: tessellates the loaded scene s (from path) into m. */
int cli_build_mesh(const char *path, scene *s, mesh *m);
/* Parses a whole positive integer option value; prints an error naming the option. */
int cli_parse_int(const char *opt, const char *text, int lo, int hi, int *out);
int cli_parse_double(const char *opt, const char *text, double lo, double hi, double *out);
/* After getopt_long (opterr = 0) returned '?': prints one line naming the argument it refused
 * as typed (an unknown option, "-r" in "-rf.yaml", or an option without its value), never the
 * command, then usage; returns CLI_BAD_INPUT. */
int cli_bad_option(const char *cmd, int argc, char **argv, const char *shortopts, const struct option *longopts,
                   const char *usage);
/* For each option getopt_long returns (c, optarg): an option that takes a value must not be
 * empty nor given twice (the last would win silently). seen: 256 zeroed bytes per command line.
 * Prints one line naming the option; returns CLI_BAD_INPUT, or CLI_OK. */
int cli_check_option(const char *cmd, int c, unsigned char seen[256], const char *shortopts,
                     const struct option *longopts);

int cli_render(int argc, char **argv);
int cli_check(int argc, char **argv);
int cli_eval(int argc, char **argv);
int cli_run(int argc, char **argv);
int cli_compare(int argc, char **argv);
int cli_diff(int argc, char **argv);
int cli_plan(int argc, char **argv);
int cli_stability(int argc, char **argv);
int cli_renderers(int argc, char **argv);
int cli_fit(int argc, char **argv);

extern const cli_command cli_render_command, cli_check_command, cli_eval_command, cli_run_command, cli_compare_command,
    cli_diff_command, cli_plan_command, cli_stability_command, cli_renderers_command, cli_fit_command;

#endif
