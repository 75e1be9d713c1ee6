/* reflcheck run: one scene in one renderer and role, cached and recorded (harness/jobs.h).
 * Exit status 0 when the job is ok or skipped, 1 when it failed, crashed, timed out or hit
 * an error on our side, 2 for bad input (options, scene file, a file it references).
 * --record-status S [--record-message M --record-log F --slurm-job ID] renders nothing and
 * writes the record of a job the scheduler ended (ops/slurm/finish.sh); its exit status is
 * that of a job with status S (1). */
#include <getopt.h>
#include <stdio.h>
#include <string.h>

#include "cli.h"
#include "jobs.h"

static const struct option run_longopts[] = {
    {"renderer", required_argument, NULL, 'r'},
    {"role", required_argument, NULL, 'R'},
    {"small", no_argument, NULL, 's'},
    {"out", required_argument, NULL, 'o'},
    {"cache", required_argument, NULL, 'c'},
    {"no-cache", no_argument, NULL, 'n'},
    {"timeout", required_argument, NULL, 'T'},
    {"threads", required_argument, NULL, 't'},
    {"seeds", required_argument, NULL, 'S'},
    {"supersample", required_argument, NULL, 'k'},
    {"samples", required_argument, NULL, 'N'},
    {"tessellation", required_argument, NULL, 'e'},
    {"per-vertex", no_argument, NULL, 'v'},
    {"tag", required_argument, NULL, 'g'},
    {"seed", required_argument, NULL, 'E'},
    {"slurm-job", required_argument, NULL, 'J'},
    {"record-status", required_argument, NULL, 'X'},
    {"record-message", required_argument, NULL, 'M'},
    {"record-log", required_argument, NULL, 'L'},
    {"help", no_argument, NULL, 'h'},
    {NULL, 0, NULL, 0},
};
static const cli_option_help run_options_help[] = {
    {"renderer", "RENDERER", "the renderer, a name of `reflcheck renderers`; default: raster (the model)"},
    {"role", "twin|validate|agree",
     "twin: the model's own equations in the reference (raster: Smith G and F = 1); validate: the scene's "
     "physics; default: validate"},
    {"small", NULL,
     "the small variant (the scene's image.small: width 96 or less, k 2 or less, samples 32 or "
     "less); default: full size"},
    {"out", "DIR",
     "the run folder: DIR/<scene>/<renderer>-<role>.exr, .json (the record) and .log; default: "
     "reports/runs/manual"},
    {"cache", "DIR", "the render cache, shared safely by concurrent runs; default: reports/cache"},
    {"no-cache", NULL, "render in a private work folder and cache nothing; default: use the cache"},
    {"timeout", "SECONDS",
     "the render's time limit in seconds, 0.1 to 1000000; default: the scene's timeout, "
     "else 600"},
    {"threads", "N", "threads the renderer may use, 1 to 256; default: all cores"},
    {"seeds", "N", "Cycles: renders with different seeds averaged, 1 to 64; default: 2"},
    {"supersample", "K", "K x K samples per pixel, 1 to 16; default: the scene's (or the small variant's)"},
    {"samples", "N", "Cycles samples per pixel per seed, 1 to 1048576; default: the scene's image.samples"},
    {"tessellation", "N", "segments of every object's tessellation, 3 to 4096; default: the scene's"},
    {"per-vertex", NULL, "per-vertex (Gouraud) shading of every D3D material; default: the scene's shading"},
    {"tag", "NAME",
     "a-z, 0-9, _ and -: with a quality override the outputs are <renderer>-<role>-NAME, so "
     "sweeps do not overwrite each other; default: none"},
    {"seed", "N", "Cycles: the first seed, 0 to 1048576; default: 0"},
    {"slurm-job", "ID",
     "the scheduler's id of this job, kept in the record; default: from SLURM_ARRAY_JOB_ID, "
     "SLURM_ARRAY_TASK_ID, SLURM_JOB_ID and SLURM_STEP_ID, none outside Slurm"},
    {"record-status", "failed|crashed|timeout|error",
     "render nothing: write the record of a job the scheduler ended without one, with this status "
     "(ops/slurm/finish.sh); exit 1; default: render the job"},
    {"record-message", "TEXT", "with --record-status: the record's message; default: none"},
    {"record-log", "FILE", "with --record-status: the scheduler's output file, kept as the job's log; default: none"},
    {"help", NULL, "this help, then exit 0"},
    {NULL, NULL, NULL},
};
const cli_command cli_run_command = {
    .name = "run",
    .run = cli_run,
    .operands = "SCENE [--renderer RENDERER] [--role ROLE] [options]",
    .operand_kind = "scene",
    .summary = "one render job: a scene in one renderer and role, cached and recorded",
    .description = "Renders SCENE in the renderer and role (POV-Ray and Blender headless, or in-process), "
                   "through the cache, and writes the image, its record (status, times, renderer version, "
                   "command, cache key) and the renderer's log. Exit 0 when the job is ok or skipped (the "
                   "renderer is not installed or cannot represent the scene: the record says which), 1 when it "
                   "failed, crashed, timed out or hit an error on our side.",
    .longopts = run_longopts,
    .shortopts = "o:h",
    .options = run_options_help,
    .example = "reflcheck run scenes/d3d9_glass.yaml --renderer povray --role validate --small --out /tmp/run1",
};

/* --record-status: only the verdicts a scheduler gives a job that ended without its record. */
static int cli_run_record_status(const char *value, job_spec *j)
{
    j->record_only = 1;
    if (strcmp(value, "failed") == 0)
        j->record_status = RUNNER_FAILED;
    else if (strcmp(value, "crashed") == 0)
        j->record_status = RUNNER_CRASHED;
    else if (strcmp(value, "timeout") == 0)
        j->record_status = RUNNER_TIMEOUT;
    else if (strcmp(value, "error") == 0)
        j->record_status = RUNNER_ERROR;
    else {
        fprintf(stderr, "reflcheck: run: --record-status '%s': use failed, crashed, timeout or error\n", value);
        return CLI_BAD_INPUT;
    }
    return CLI_OK;
}

/* One option c (its value in optarg) into the job. */
static int cli_run_option(int c, job_spec *j, int argc, char **argv)
{
    int rc = CLI_OK, v;
    switch (c) {
    case 'r':
        if ((v = registry_find(optarg)) < 0) {
            char names[200];
            fprintf(stderr, "reflcheck: run: --renderer '%s': use %s\n", optarg, registry_list(names, sizeof names));
            rc = CLI_BAD_INPUT;
        }
        j->renderer = v;
        break;
    case 'R':
        if ((v = job_role_from_name(optarg)) < 0) {
            fprintf(stderr, "reflcheck: run: --role '%s': use twin, validate or agree\n", optarg);
            rc = CLI_BAD_INPUT;
        }
        j->role = (comparison_role)v;
        break;
    case 's': j->variant = JOB_SMALL; break;
    case 'o': j->out_dir = optarg; break;
    case 'c': j->cache_dir = optarg; break;
    case 'n': j->cache_dir = NULL; break;
    case 'T': {
        double t;
        rc = cli_parse_double("--timeout", optarg, 0.1, 1e6, &t);
        j->timeout_s = t;
        break;
    }
    case 't': rc = cli_parse_int("--threads", optarg, 1, 256, &j->threads); break;
    case 'S': rc = cli_parse_int("--seeds", optarg, 1, 64, &j->seeds); break;
    case 'k': rc = cli_parse_int("--supersample", optarg, 1, 16, &j->supersample); break;
    case 'N': rc = cli_parse_int("--samples", optarg, 1, 1 << 20, &j->samples); break;
    case 'e': rc = cli_parse_int("--tessellation", optarg, 3, 4096, &j->tessellation); break;
    case 'v': j->per_vertex = 1; break;
    case 'E': rc = cli_parse_int("--seed", optarg, 0, 1 << 20, &j->seed); break;
    case 'J': j->slurm_job = optarg; break;
    case 'X': rc = cli_run_record_status(optarg, j); break;
    case 'M': j->record_message = optarg; break;
    case 'L': j->record_log = optarg; break;
    case 'g':
        if (optarg[0] == '\0' || strspn(optarg, "abcdefghijklmnopqrstuvwxyz0123456789_-") != strlen(optarg)) {
            fprintf(stderr, "reflcheck: run: --tag '%s': use a-z, 0-9, _ and -\n", optarg);
            rc = CLI_BAD_INPUT;
        }
        j->tag = optarg;
        break;
    default: rc = cli_bad_option("run", argc, argv, "o:h", run_longopts, "see reflcheck run --help");
    }
    return rc;
}

int cli_run(int argc, char **argv)
{
    job_spec j = {.renderer = registry_model(),
                  .role = ROLE_VALIDATE,
                  .variant = JOB_FULL,
                  .out_dir = "reports/runs/manual",
                  .cache_dir = "reports/cache"};
    int c, rc = CLI_OK;
    unsigned char seen[256] = {0};
    optind = 1;
    opterr = 0;
    while (rc == CLI_OK && (c = getopt_long(argc, argv, "o:h", run_longopts, NULL)) != -1) {
        if (c != '?' && (rc = cli_check_option("run", c, seen, "o:h", run_longopts)) != CLI_OK)
            break;
        if (c == 'h')
            return cli_help("run");
        rc = cli_run_option(c, &j, argc, argv);
    }
    if (rc != CLI_OK)
        return rc;
    if (optind != argc - 1) {
        fprintf(stderr, "reflcheck: usage: reflcheck run SCENE --renderer R [--role ROLE] [--small] [--out DIR]\n");
        return CLI_BAD_INPUT;
    }
    j.scene_path = argv[optind];
    job_record r;
    char err[1024];
    rc_status st = job_run(&j, &r, err, sizeof err);
    if (st != RC_OK) {
        fprintf(stderr, "reflcheck: %s\n", err);
        return job_exit_status(st, &r);
    }
    printf("%-28s %-7s %-8s %-8s %8.2f s%s  %s\n", j.scene_path, registry_name(j.renderer), job_role_names[j.role],
           runner_status_name(r.status), r.wall_s, r.cached ? " (cached)" : "",
           r.status == RUNNER_OK ? r.exr : r.message);
    /* A job that is neither done nor skipped fails the run: make -k, the nightly and scripts
     * see it in the exit status, not only in the record. */
    if (r.status != RUNNER_OK && r.status != RUNNER_MISSING)
        fprintf(stderr, "reflcheck: run: %s %s: %s: %s\n", j.scene_path, registry_name(j.renderer),
                runner_status_name(r.status), r.message);
    return job_exit_status(st, &r);
}
