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

int cli_stability(int argc, char **argv)
{
    static const struct option longopts[] = {
        {"json", required_argument, NULL, 'j'},    {"csv", required_argument, NULL, 'c'},
        {"samples", required_argument, NULL, 's'}, {"seed", required_argument, NULL, 'r'},
        {"quiet", no_argument, NULL, 'q'},         {NULL, 0, NULL, 0},
    };
    const char *json = NULL, *csv = NULL;
    stability_options o = {0};
    int c, rc = CLI_OK, quiet = 0;
    unsigned char seen[256] = {0};
    optind = 1;
    opterr = 0;
    while (rc == CLI_OK && (c = getopt_long(argc, argv, "", longopts, NULL)) != -1) {
        if (c != '?' && (rc = cli_check_option("stability", c, seen, "", longopts)) != CLI_OK)
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
        default:
            rc = cli_bad_option("stability", argc, argv, "", longopts,
                                "options: --json FILE --csv FILE --samples N --seed N --quiet");
        }
    }
    if (rc != CLI_OK)
        return rc;
    if (optind != argc) {
        fprintf(stderr,
                "reflcheck: stability: unexpected argument '%s'; usage: reflcheck stability "
                "[--json FILE] [--csv FILE] [--samples N]\n",
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
