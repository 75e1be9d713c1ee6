#include "cli.h"

#include <errno.h>
#include <getopt.h>
#include <stdio.h>
#include <string.h>

#include "renderers/registry.h"
#include "scene_file.h"

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
