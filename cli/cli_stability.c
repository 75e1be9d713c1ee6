/* reflcheck stability: the numerical stability table (harness/stability.h) on the terminal,
 * optionally as JSON and CSV. Exit 1 when any gate fails (NaN, Inf or a negative value for
 * finite input, or a gating physics check) or an output cannot be written (the files are
 * written to a temporary name and renamed, so a failed write leaves the old file), 2 for bad
 * options or an output that is not a regular file (a device, FIFO or directory). */
#include <errno.h>
#include <getopt.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli.h"
#include "fileio.h"
#include "jsonio.h"
#include "stability.h"
#include "user_load.h"

static int cli_stability_write(const char *path, const stability_table *t, int json)
{
    char *text = NULL, err[1200];
    rc_status st;
    if (json) {
        cJSON *doc = stability_json(t);
        if (doc == NULL) {
            fprintf(stderr, "reflcheck: stability: out of memory for '%s'\n", path);
            return CLI_FAILED;
        }
        st = jsonio_write_file(doc, path, err, sizeof err);
        cJSON_Delete(doc);
    } else {
        size_t len = 0;
        FILE *f = open_memstream(&text, &len);
        if (!f) {
            fprintf(stderr, "reflcheck: stability: out of memory for '%s'\n", path);
            return CLI_FAILED;
        }
        int bad = stability_write_csv(f, t);
        if (fclose(f) != 0 || bad || text == NULL) {
            free(text);
            fprintf(stderr, "reflcheck: stability: cannot format '%s'; out of memory\n", path);
            return CLI_FAILED;
        }
        st = fileio_write_atomic(path, text, err, sizeof err);
        free(text);
    }
    if (st != RC_OK) {
        fprintf(stderr, "reflcheck: stability: %s\n", err);
        return st == RC_ERR_RANGE ? CLI_BAD_INPUT : CLI_FAILED;
    }
    return CLI_OK;
}

static const struct option stability_longopts[] = {
    {"json", required_argument, NULL, 'j'},    {"csv", required_argument, NULL, 'c'},
    {"samples", required_argument, NULL, 's'}, {"seed", required_argument, NULL, 'r'},
    {"quiet", no_argument, NULL, 'q'},         {"user-model", required_argument, NULL, 'u'},
    {"help", no_argument, NULL, 'h'},          {NULL, 0, NULL, 0},
};
static const cli_option_help stability_options_help[] = {
    {"json", "FILE", "also write the table as JSON to FILE; default: none"},
    {"csv", "FILE", "also write the table as CSV to FILE; default: none"},
    {"samples", "N", "evaluations per sweep case, 16 to 10000000; default: 4000"},
    {"seed", "N",
     "the seed of each sweep's random part, 1 to 2147483647; default: a fixed seed (the same "
     "table every run)"},
    {"quiet", NULL, "print no table on standard output; default: the table"},
    {"user-model", "FILE",
     "also sweep a user's shading model, the shared object FILE (loading it runs its code: "
     "docs/user_models.md); default: none"},
    {"help", NULL, "this help, then exit 0"},
    {NULL, NULL, NULL},
};
const cli_command cli_stability_command = {
    .name = "stability",
    .run = cli_stability,
    .operands = "[options]",
    .operand_kind = "",
    .summary = "the float models against long double over extreme inputs",
    .description = "Runs every model function in float and in long double over sweeps of extreme and "
                   "degenerate inputs, with the physics checks of harness/stability.h, and prints the table. "
                   "Exit 1 when a row fails a gate: NaN, Inf or a negative value for finite input, or a gating "
                   "physics check.",
    .longopts = stability_longopts,
    .shortopts = "h",
    .options = stability_options_help,
    .example = "reflcheck stability --json stability.json --quiet",
};

int cli_stability(int argc, char **argv)
{
    const char *json = NULL, *csv = NULL;
    stability_options o = {0};
    int c, rc = CLI_OK, quiet = 0;
    unsigned char seen[256] = {0};
    optind = 1;
    opterr = 0;
    while (rc == CLI_OK && (c = getopt_long(argc, argv, "h", stability_longopts, NULL)) != -1) {
        if (c != '?' && (rc = cli_check_option("stability", c, seen, "h", stability_longopts)) != CLI_OK)
            break;
        switch (c) {
        case 'j': json = optarg; break;
        case 'c': csv = optarg; break;
        case 's': rc = cli_parse_int("--samples", optarg, 16, STABILITY_MAX_SAMPLES, &o.samples); break;
        case 'r': {
            int seed = 0;
            rc = cli_parse_int("--seed", optarg, 1, 2147483647, &seed);
            o.seed = (unsigned)seed;
            break;
        }
        case 'q': quiet = 1; break;
        case 'u': {
            char why[1024];
            if (user_model_load(optarg, &o.user, why, sizeof why) != RC_OK) {
                fprintf(stderr, "reflcheck: stability: --user-model: %s\n", why);
                rc = CLI_BAD_INPUT;
            }
            break;
        }
        case 'h': return cli_help("stability");
        default:
            rc = cli_bad_option("stability", argc, argv, "h", stability_longopts, "see reflcheck stability --help");
        }
    }
    if (rc != CLI_OK)
        return rc;
    if (optind != argc) {
        fprintf(stderr,
                "reflcheck: stability: unexpected argument '%s'; usage: reflcheck stability "
                "[--json FILE] [--csv FILE] [--samples N] [--user-model FILE]\n",
                argv[optind]);
        return CLI_BAD_INPUT;
    }
    stability_table *t = malloc(sizeof *t);
    if (!t) {
        fprintf(stderr, "reflcheck: stability: out of memory for the table\n");
        return CLI_FAILED;
    }
    rc_status st = stability_run(&o, t);
    if (st != RC_OK) {
        fprintf(stderr, "reflcheck: stability: the run failed (status %d); check --samples\n", (int)st);
        free(t);
        return cli_exit_status(st);
    }
    if (!quiet && (stability_write_text(stdout, t) != 0 || fflush(stdout) != 0 || ferror(stdout))) {
        fprintf(stderr,
                "reflcheck: stability: cannot write the table to standard output (%s); check where it "
                "goes\n",
                strerror(errno));
        rc = CLI_FAILED;
    }
    if (json && rc == CLI_OK)
        rc = cli_stability_write(json, t, 1);
    if (csv && rc == CLI_OK)
        rc = cli_stability_write(csv, t, 0);
    int fails = stability_failures(t);
    if (fails)
        fprintf(stderr,
                "reflcheck: stability: %d rows fail a gate (NaN, Inf or negative output for finite input, "
                "or a gating physics check); see the FAIL rows\n",
                fails);
    free(t);
    return rc != CLI_OK ? rc : (fails ? CLI_FAILED : CLI_OK);
}
