/* cli.h - the reflcheck commands: one function per command, argv[0] is the command name.
 *
 * Usage:
 *   const cli_command *c = cli_find("render");  c->run(argc, argv) returns the exit status:
 *   0 ok, 1 a run failed (I/O, renderer), 2 bad input (command line or scene file).
 * cli_load_scene parses a scene file and tessellates it; errors are printed as one line.
 */
#ifndef REFLCHECK_CLI_H
#define REFLCHECK_CLI_H

#include "mesh.h"
#include "scene.h"

typedef struct {
    const char *name;
    int (*run)(int argc, char **argv);
} cli_command;

enum { CLI_OK = 0, CLI_FAILED = 1, CLI_BAD_INPUT = 2 };

const cli_command *cli_find(const char *name);

/* Exit status for an rc_status: parse and range errors are bad input (2), others failures (1). */
int cli_exit_status(int rc);
/* Loads and validates SCENE, then tessellates it into m (if m is not NULL). Prints the error. */
int cli_load_scene(const char *path, scene *s, mesh *m);
/* Parses a whole positive integer option value; prints an error naming the option. */
int cli_parse_int(const char *opt, const char *text, int lo, int hi, int *out);
int cli_parse_double(const char *opt, const char *text, double lo, double hi, double *out);
/* After getopt_long (opterr = 0) returned '?': prints one line naming the argument it refused
 * as typed (an unknown option, "-r" in "-rf.yaml", or an option without its value), never the
 * command, then usage; returns CLI_BAD_INPUT. */
struct option;
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

#endif
