/* reflcheck run: one scene in one renderer and role, cached and recorded (harness/jobs.h).
 * Exit status 0 when the job is ok or skipped, 1 when it failed, crashed, timed out or hit
 * an error on our side, 2 for bad input (options, scene file, a file it references).
 * --record-status S [--record-message M --record-log F --slurm-job ID] renders nothing and
 * writes the record of a job the scheduler ended (harness/slurm/finish.sh); its exit status is
 * that of a job with status S (1). */
#include <getopt.h>
#include <stdio.h>
#include <string.h>

#include "cli.h"
#include "jobs.h"

int cli_run(int argc, char **argv)
{
    static const struct option longopts[] = {
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
        {NULL, 0, NULL, 0},
    };
    job_spec j = {.renderer = registry_model(),
                  .role = ROLE_VALIDATE,
                  .variant = JOB_FULL,
                  .out_dir = "reports/runs/manual",
                  .cache_dir = "reports/cache"};
    int c, rc = CLI_OK, v;
    unsigned char seen[256] = {0};
    optind = 1;
    opterr = 0;
    while (rc == CLI_OK && (c = getopt_long(argc, argv, "o:", longopts, NULL)) != -1) {
        if (c != '?' && (rc = cli_check_option("run", c, seen, "o:", longopts)) != CLI_OK)
            break;
        switch (c) {
        case 'r':
            if ((v = registry_find(optarg)) < 0) {
                char names[200];
                fprintf(stderr, "reflcheck: run: --renderer '%s': use %s\n", optarg,
                        registry_list(names, sizeof names));
                rc = CLI_BAD_INPUT;
            }
            j.renderer = v;
            break;
        case 'R':
            if ((v = job_role_from_name(optarg)) < 0) {
                fprintf(stderr, "reflcheck: run: --role '%s': use twin, validate or agree\n", optarg);
                rc = CLI_BAD_INPUT;
            }
            j.role = (comparison_role)v;
            break;
        case 's': j.variant = JOB_SMALL; break;
        case 'o': j.out_dir = optarg; break;
        case 'c': j.cache_dir = optarg; break;
        case 'n': j.cache_dir = NULL; break;
        case 'T': {
            double t;
            rc = cli_parse_double("--timeout", optarg, 0.1, 1e6, &t);
            j.timeout_s = t;
            break;
        }
        case 't': rc = cli_parse_int("--threads", optarg, 1, 256, &j.threads); break;
        case 'S': rc = cli_parse_int("--seeds", optarg, 1, 64, &j.seeds); break;
        case 'k': rc = cli_parse_int("--supersample", optarg, 1, 16, &j.supersample); break;
        case 'N': rc = cli_parse_int("--samples", optarg, 1, 1 << 20, &j.samples); break;
        case 'e': rc = cli_parse_int("--tessellation", optarg, 3, 4096, &j.tessellation); break;
        case 'v': j.per_vertex = 1; break;
        case 'E': rc = cli_parse_int("--seed", optarg, 0, 1 << 20, &j.seed); break;
        case 'J': j.slurm_job = optarg; break;
        case 'X':
            /* Only the verdicts a scheduler gives a job that ended without its record. */
            j.record_only = 1;
            if (strcmp(optarg, "failed") == 0)
                j.record_status = RUNNER_FAILED;
            else if (strcmp(optarg, "crashed") == 0)
                j.record_status = RUNNER_CRASHED;
            else if (strcmp(optarg, "timeout") == 0)
                j.record_status = RUNNER_TIMEOUT;
            else if (strcmp(optarg, "error") == 0)
                j.record_status = RUNNER_ERROR;
            else {
                fprintf(stderr, "reflcheck: run: --record-status '%s': use failed, crashed, timeout or error\n",
                        optarg);
                rc = CLI_BAD_INPUT;
            }
            break;
        case 'M': j.record_message = optarg; break;
        case 'L': j.record_log = optarg; break;
        case 'g':
            if (optarg[0] == '\0' || strspn(optarg, "abcdefghijklmnopqrstuvwxyz0123456789_-") != strlen(optarg)) {
                fprintf(stderr, "reflcheck: run: --tag '%s': use a-z, 0-9, _ and -\n", optarg);
                rc = CLI_BAD_INPUT;
            }
            j.tag = optarg;
            break;
        default: rc = cli_bad_option("run", argc, argv, "o:", longopts, "see reflcheck --help");
        }
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
