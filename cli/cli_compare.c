/* reflcheck compare: measure each listed comparison of the scenes on one run's renders.
 * reflcheck diff: the metrics of one image pair.
 * Exit status (README): 0 every comparison passed, warned or was skipped; 1 a comparison
 * failed or is an error, or our own output cannot be written; 2 bad input (command line, a
 * scene file, two scenes with one name, a run folder that does not exist, an image given to
 * diff that cannot be read or does not match). */
#include <errno.h>
#include <getopt.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include <cJSON.h>

#include "cli.h"
#include "exr.h"
#include "compare.h"
#include "diff_terms.h"
#include "scene_file.h"

/* Reads every scene before any is compared: a bad scene file or two scenes with one name
 * (their jobs share RUN/<name>/, so one would be judged on the other's images) refuse the
 * whole command, and nothing is written. */
static int cli_compare_scenes_ok(char **paths, int n)
{
    char(*names)[SCENE_NAME_MAX] = calloc((size_t)n, sizeof *names);
    scene *s = malloc(sizeof *s);
    int rc = names != NULL && s != NULL ? CLI_OK : CLI_FAILED;
    for (int i = 0; i < n && rc == CLI_OK; i++) {
        char err[1024];
        rc_status st = scene_file_load(paths[i], s, err, sizeof err);
        if (st != RC_OK) {
            fprintf(stderr, "reflcheck: %s\n", err);
            rc = st == RC_ERR_NOMEM ? CLI_FAILED : CLI_BAD_INPUT;
            break;
        }
        snprintf(names[i], sizeof names[i], "%s", s->name);
        for (int k = 0; k < i; k++)
            if (strcmp(names[k], names[i]) == 0) {
                fprintf(stderr,
                        "reflcheck: compare: %s and %s both have the scene name '%s', so their renders would share "
                        "RUN/%s/; give each scene a distinct name: key (or compare them in separate runs)\n",
                        paths[k], paths[i], names[i], names[i]);
                rc = CLI_BAD_INPUT;
                break;
            }
    }
    free(s);
    free(names);
    return rc;
}

static const struct option compare_longopts[] = {
    {"run", required_argument, NULL, 'r'}, {"help", no_argument, NULL, 'h'}, {NULL, 0, NULL, 0}};
static const cli_option_help compare_options_help[] = {
    {"run", "DIR", "the run folder the renders are in, as reflcheck plan --out or run --out wrote it (required)"},
    {"help", NULL, "this help, then exit 0"},
    {NULL, NULL, NULL},
};
const cli_command cli_compare_command = {
    .name = "compare",
    .run = cli_compare,
    .operands = "SCENE... --run RUNDIR",
    .operand_kind = "scene",
    .summary = "measure each comparison of the scenes on a run's renders -> RUN/<scene>/compare.json",
    .description = "For every comparison a scene lists, computes the metrics of its two renders from the run "
                   "folder, applies the scene's thresholds and the built-in gates, and writes "
                   "RUNDIR/<scene>/compare.json; prints one line per scene (pass, not gated, warn, fail, skipped, "
                   "error). Exit 1 when a comparison fails or is an error.",
    .longopts = compare_longopts,
    .shortopts = "h",
    .options = compare_options_help,
    .example = "reflcheck compare scenes/d3d9_glass.yaml --run /tmp/run1",
};

int cli_compare(int argc, char **argv)
{
    const char *run = NULL;
    int c;
    unsigned char seen[256] = {0};
    optind = 1;
    opterr = 0;
    while ((c = getopt_long(argc, argv, "h", compare_longopts, NULL)) != -1) {
        if (c != '?' && cli_check_option("compare", c, seen, "h", compare_longopts) != CLI_OK)
            return CLI_BAD_INPUT;
        if (c == 'h')
            return cli_help("compare");
        if (c != 'r') {
            return cli_bad_option("compare", argc, argv, "h", compare_longopts,
                                  "usage: reflcheck compare SCENE... --run DIR");
        }
        run = optarg;
    }
    if (run == NULL || optind >= argc) {
        fprintf(stderr, "reflcheck: usage: reflcheck compare SCENE... --run DIR\n");
        return CLI_BAD_INPUT;
    }
    struct stat st_run;
    int stat_rc = stat(run, &st_run);
    if (stat_rc != 0 || !S_ISDIR(st_run.st_mode)) {
        fprintf(stderr,
                "reflcheck: compare: --run %s: %s; give the run folder that reflcheck plan --out or "
                "reflcheck run --out wrote\n",
                run, stat_rc != 0 ? strerror(errno) : "not a directory");
        return CLI_BAD_INPUT;
    }
    int rc = cli_compare_scenes_ok(&argv[optind], argc - optind);
    if (rc != CLI_OK)
        return rc;
    int failed = 0, worst = CLI_OK;
    for (int i = optind; i < argc; i++) {
        compare_summary sum;
        char err[1024];
        rc_status st = compare_scene(argv[i], run, &sum, err, sizeof err);
        if (st != RC_OK) {
            /* The scenes were read above, so this is our own output (compare.json, view.js). */
            fprintf(stderr, "reflcheck: %s\n", err);
            worst = CLI_FAILED;
            continue;
        }
        printf("%-40s pass %d  not gated %d  warn %d  fail %d  skipped %d  error %d\n", argv[i], sum.pass,
               sum.not_gated, sum.warn, sum.fail, sum.skipped, sum.error);
        if (sum.fail > 0 || sum.error > 0) {
            failed = 1;
            if (sum.first_failure[0])
                fprintf(stderr, "FAIL %s\n", sum.first_failure);
        }
    }
    if (fflush(stdout) != 0 || ferror(stdout)) {
        fprintf(stderr, "reflcheck: compare: cannot write the summary to standard output: %s\n", strerror(errno));
        return CLI_FAILED;
    }
    return worst != CLI_OK ? worst : (failed ? CLI_FAILED : CLI_OK);
}

/* A mask of another size than the test image is the mask's fault, not the pair's: name it, its
 * size and the size it must have (in msg). Images that cannot be read are left to
 * compare_images, which names them. */
static int cli_diff_mask_size(const char *test, const char *mask, char *msg, size_t msglen)
{
    exr_image t, g;
    char err[1024];
    if (exr_read(test, &t, err, sizeof err) != RC_OK)
        return CLI_OK;
    int rc = CLI_OK;
    if (exr_read(mask, &g, err, sizeof err) == RC_OK) {
        if (g.width != t.width || g.height != t.height) {
            snprintf(msg, msglen,
                     "diff: --mask %s is %dx%d, the test image %s is %dx%d; give a geometry render "
                     "(coverage, object) of the same %dx%d",
                     mask, g.width, g.height, test, t.width, t.height, t.width, t.height);
            rc = CLI_BAD_INPUT;
        }
        exr_image_free(&g);
    }
    exr_image_free(&t);
    return rc;
}

/* One pair's metrics written to out; returns the exit status diff gives for it, with the
 * line it prints on stderr in msg (empty when none). */
static int cli_diff_one(const char *test, const char *ref, const char *mask, const char *leave_out, FILE *out,
                        char *msg, size_t msglen)
{
    char err[1024];
    int gate_failed = 0;
    msg[0] = '\0';
    if (mask != NULL && cli_diff_mask_size(test, mask, msg, msglen) != CLI_OK)
        return CLI_BAD_INPUT;
    unsigned bits = 0;
    char dir[256] = "", tpath[300], rpath[300];
    rc_status st = leave_out != NULL ? diff_terms_parse(leave_out, &bits, err, sizeof err) : RC_OK;
    if (st == RC_OK && bits != 0)
        st = diff_terms_pair(test, ref, bits, dir, sizeof dir, err, sizeof err);
    snprintf(tpath, sizeof tpath, "%s/test.exr", dir);
    snprintf(rpath, sizeof rpath, "%s/ref.exr", dir);
    if (st == RC_OK)
        st = compare_images(bits ? tpath : test, bits ? rpath : ref, mask, out, &gate_failed, err, sizeof err);
    diff_terms_names(err, sizeof err, dir, test, ref);
    diff_terms_cleanup(dir);
    if (st != RC_OK) {
        /* Every image here is the user's input: one that cannot be read or does not match is
         * bad input; only running out of memory is ours. */
        snprintf(msg, msglen, "%s", err);
        return st == RC_ERR_NOMEM ? CLI_FAILED : CLI_BAD_INPUT;
    }
    if (gate_failed) {
        snprintf(msg, msglen, "diff %s %s: %s", test, ref, err);
        return CLI_FAILED;
    }
    return CLI_OK;
}

/* A line of --pairs: TEST, REF, MASK and TERMS separated by tabs (MASK and TERMS may be empty or
 * left off). 0 when the line has no TEST and REF. */
static int cli_diff_split(char *line, char *field[4])
{
    line[strcspn(line, "\r\n")] = '\0';
    for (int i = 0; i < 4; i++) {
        field[i] = line;
        line = line != NULL ? strchr(line, '\t') : NULL;
        if (line != NULL)
            *line++ = '\0';
    }
    for (int i = 2; i < 4; i++)
        if (field[i] != NULL && field[i][0] == '\0')
            field[i] = NULL;
    return field[0] != NULL && field[0][0] != '\0' && field[1] != NULL && field[1][0] != '\0';
}

/* reflcheck diff --pairs FILE: every pair of FILE ("-": standard input) in one process, one
 * answer each on standard output, in order: the metrics object diff prints for the pair, or
 * {"error": LINE, "exit": N} with the line and exit status diff gives for it alone. A sweep
 * diffs hundreds of small pairs; a process each cost more than the comparisons. Exit 0 once
 * every answer is written (each pair's own status is in its answer), 2 when FILE cannot be
 * read or a line has no TEST and REF. */
static int cli_diff_pairs(const char *file)
{
    FILE *in = strcmp(file, "-") == 0 ? stdin : fopen(file, "r");
    if (in == NULL) {
        fprintf(stderr,
                "reflcheck: diff: --pairs %s: %s; give a readable file of TEST<tab>REF<tab>MASK<tab>TERMS lines\n",
                file, strerror(errno));
        return CLI_BAD_INPUT;
    }
    char *line = NULL, *field[4];
    size_t cap = 0;
    int rc = CLI_OK;
    for (long n = 1; rc == CLI_OK && getline(&line, &cap, in) != -1; n++) {
        if (!cli_diff_split(line, field)) {
            fprintf(stderr,
                    "reflcheck: diff: --pairs %s: line %ld: no TEST and REF; give TEST<tab>REF<tab>MASK<tab>TERMS\n",
                    file, n);
            rc = CLI_BAD_INPUT;
            break;
        }
        char *text = NULL, msg[2048];
        size_t len = 0;
        FILE *mem = open_memstream(&text, &len);
        int st = mem != NULL ? cli_diff_one(field[0], field[1], field[2], field[3], mem, msg, sizeof msg) : CLI_FAILED;
        if (mem != NULL)
            fclose(mem);
        if (st == CLI_OK) {
            fwrite(text, 1, len, stdout);
        } else {
            cJSON *o = cJSON_CreateObject();
            cJSON_AddStringToObject(o, "error", mem != NULL ? msg : "out of memory for the metrics");
            cJSON_AddNumberToObject(o, "exit", st);
            char *e = cJSON_PrintUnformatted(o);
            printf("%s\n", e != NULL ? e : "{\"error\": \"out of memory\", \"exit\": 1}");
            cJSON_free(e);
            cJSON_Delete(o);
        }
        free(text);
    }
    free(line);
    if (in != stdin)
        fclose(in);
    if (rc == CLI_OK && (fflush(stdout) != 0 || ferror(stdout))) {
        fprintf(stderr, "reflcheck: diff: cannot write the metrics to standard output: %s\n", strerror(errno));
        rc = CLI_FAILED;
    }
    return rc;
}

/* reflcheck diff TEST.exr REF.exr [--mask GEO.exr] [--leave-out TERMS]: the metrics of one image
 * pair as JSON; --leave-out compares the terms a partial twin's sides both render
 * (harness/diff_terms.h). */
static const struct option diff_longopts[] = {{"mask", required_argument, NULL, 'm'},
                                              {"leave-out", required_argument, NULL, 'l'},
                                              {"pairs", required_argument, NULL, 'p'},
                                              {"help", no_argument, NULL, 'h'},
                                              {NULL, 0, NULL, 0}};
static const cli_option_help diff_options_help[] = {
    {"mask", "FILE",
     "a geometry render (its coverage and object layers) of the same size: the metrics over "
     "its surface pixels; default: every pixel"},
    {"leave-out", "TERMS",
     "comma-separated terms (diffuse, specular, reflection, emission) taken off both "
     "images' RGB before comparing, as for a partial twin; default: none"},
    {"pairs", "FILE",
     "many pairs in one process, no operands: a line each of TEST, REF, MASK, TERMS separated by tabs "
     "(MASK, TERMS may be empty) from FILE ('-': standard input); one answer a pair, in order: its "
     "metrics or {\"error\": message, \"exit\": status}; default: the one pair of the operands"},
    {"help", NULL, "this help, then exit 0"},
    {NULL, NULL, NULL},
};
const cli_command cli_diff_command = {
    .name = "diff",
    .run = cli_diff,
    .operands = "TEST.exr REF.exr [--mask GEO.exr] [--leave-out TERMS]",
    .operand_kind = "exr",
    .summary = "the metrics of one image pair, as JSON",
    .description = "Compares TEST.exr against REF.exr pixel by pixel and prints the metrics compare uses "
                   "(RMSE, NRMSE, relative errors, bias ...) as JSON on standard output. Exit 1 when a built-in "
                   "gate fails; 2 when an image cannot be read or the two do not match.",
    .longopts = diff_longopts,
    .shortopts = "h",
    .options = diff_options_help,
    .example = "reflcheck diff run1/glass/raster-validate.exr run1/glass/povray-validate.exr",
};

int cli_diff(int argc, char **argv)
{
    const char *mask = NULL, *leave_out = NULL, *pairs = NULL;
    int c;
    unsigned char seen[256] = {0};
    optind = 1;
    opterr = 0;
    while ((c = getopt_long(argc, argv, "h", diff_longopts, NULL)) != -1) {
        if (c != '?' && cli_check_option("diff", c, seen, "h", diff_longopts) != CLI_OK)
            return CLI_BAD_INPUT;
        if (c == 'h')
            return cli_help("diff");
        if (c != 'm' && c != 'l' && c != 'p') {
            return cli_bad_option("diff", argc, argv, "h", diff_longopts,
                                  "usage: reflcheck diff TEST.exr REF.exr [--mask GEO.exr] [--leave-out TERMS]");
        }
        *(c == 'm' ? &mask : c == 'l' ? &leave_out : &pairs) = optarg;
    }
    if (pairs != NULL && (optind != argc || mask != NULL || leave_out != NULL)) {
        fprintf(stderr, "reflcheck: diff: --pairs takes each pair's images, mask and terms from its lines; give no "
                        "operands, --mask or --leave-out with it\n");
        return CLI_BAD_INPUT;
    }
    if (pairs != NULL)
        return cli_diff_pairs(pairs);
    if (optind != argc - 2) {
        fprintf(stderr, "reflcheck: usage: reflcheck diff TEST.exr REF.exr [--mask GEO.exr] [--leave-out TERMS]\n");
        return CLI_BAD_INPUT;
    }
    char msg[2048];
    int rc = cli_diff_one(argv[optind], argv[optind + 1], mask, leave_out, stdout, msg, sizeof msg);
    if (msg[0] != '\0')
        fprintf(stderr, "reflcheck: %s\n", msg);
    if (rc == CLI_OK && (fflush(stdout) != 0 || ferror(stdout))) {
        fprintf(stderr, "reflcheck: diff: cannot write the metrics to standard output: %s\n", strerror(errno));
        return CLI_FAILED;
    }
    return rc;
}
