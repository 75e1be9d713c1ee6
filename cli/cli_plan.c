/* reflcheck plan: the render jobs the scenes' comparisons need, as a Makefile, so that
 * `make -j` runs them in parallel and each scene renders only the renderers and roles its
 * comparisons list; with --scheduler slurm, the same jobs as a script that submits each one
 * as a Slurm array task (docs/slurm.md). Twin and validate have their own renders (twin
 * switches our Cook-Torrance to Smith G and F = 1; validate renders the scene's physics);
 * agree compares exactly the two validate renders, so it adds no render of its own.
 * The Makefile's target all holds every job; cpu and wait split them in two (plan_job_class), so
 * that the nightly runs the POV-Ray jobs, which mostly wait, in slots of their own.
 *
 * Paths reach /bin/sh through make: every path in a recipe is single-quoted for the shell
 * and its `$` doubled for make, and comes after `--` so a name starting with `-` is not an
 * option. Targets cannot be quoted in make, so a target (OUT/<scene name>/...) must use only
 * letters, digits and _ . / + , @ -; other paths must not hold a newline. Two scenes with one
 * name would write the same files and are refused. Every refusal is exit status 2 and
 * nothing is printed. */
#include <getopt.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli.h"
#include "jobs.h"
#include "scene_file.h"

/* What make takes literally in a target or prerequisite: no space, `:`, `;`, `=`, `$`, `%`,
 * `#`, wildcard or tilde, all of which make would read as syntax. */
static int plan_target_safe(const char *s)
{
    static const char ok[] = "abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789_./+,@-";
    return s[0] != '\0' && strspn(s, ok) == strlen(s);
}

/* Writes s single-quoted for /bin/sh, with make's `$` doubled unless for_shell: a make recipe
 * word (or, for_shell, a shell word) that the shell receives as exactly s. */
static void plan_quote_as(const char *s, int for_shell)
{
    putchar('\'');
    for (; *s; s++) {
        if (*s == '\'')
            fputs("'\\''", stdout);
        else if (*s == '$' && !for_shell)
            fputs("$$", stdout);
        else
            putchar(*s);
    }
    putchar('\'');
}

/* A path for a recipe line: refused if it holds a newline (it would end the recipe line). */
static int plan_check_path(const char *what, const char *path)
{
    if (strpbrk(path, "\n\r") == NULL)
        return CLI_OK;
    fprintf(stderr, "reflcheck: plan: %s '%s' holds a line break, which a make recipe cannot carry; rename it\n", what,
            path);
    return CLI_BAD_INPUT;
}

typedef struct {
    char name[SCENE_NAME_MAX];
    unsigned char need[16][3]; /* [renderer row][role]; the table has fewer rows */
    double timeout;            /* seconds one render may take (the scene's, else 600, as jobs.c) */
} plan_scene;

/* Loads one scene and works out its jobs; refuses names make cannot carry and names an
 * earlier scene already has. */
static int plan_load(char **paths, int i, int first, const char *out, plan_scene *all)
{
    scene *s = malloc(sizeof *s);
    char err[1024];
    if (s == NULL) {
        fprintf(stderr, "reflcheck: plan: %s: out of memory for the scene\n", paths[i]);
        return CLI_FAILED;
    }
    rc_status st = scene_file_load(paths[i], s, err, sizeof err);
    if (st != RC_OK) {
        fprintf(stderr, "reflcheck: %s\n", err);
        free(s);
        return st == RC_ERR_NOMEM ? CLI_FAILED : CLI_BAD_INPUT;
    }
    plan_scene *p = &all[i - first];
    snprintf(p->name, sizeof p->name, "%s", s->name);
    p->timeout = s->timeout > 0 ? s->timeout : 600.0;
    char target[1200];
    job_output_path(out, s->name, registry_model(), ROLE_TWIN, "json", target, sizeof target);
    int rc = CLI_OK;
    if (!plan_target_safe(s->name) || !plan_target_safe(target)) {
        fprintf(stderr,
                "reflcheck: plan: %s: the scene name '%s'%s makes the make target '%s', which make cannot carry; "
                "allowed in names: letters, digits, _ - . (set name: in the scene), in --out also / + , @\n",
                paths[i], s->name, plan_target_safe(s->name) ? "" : " (from the file name)", target);
        rc = CLI_BAD_INPUT;
    }
    for (int k = 0; rc == CLI_OK && k < i - first; k++)
        if (strcmp(all[k].name, p->name) == 0) {
            fprintf(stderr,
                    "reflcheck: plan: %s and %s both have the scene name '%s', so their jobs would write the same "
                    "files; give one of them another name: (scene key name)\n",
                    paths[first + k], paths[i], p->name);
            rc = CLI_BAD_INPUT;
        }
    memset(p->need, 0, sizeof p->need);
    for (int k = 0; rc == CLI_OK && k < s->n_comparisons; k++) {
        const comparison *cp = &s->comparisons[k];
        int role = cp->role == ROLE_AGREE ? ROLE_VALIDATE : cp->role;
        p->need[cp->test][role] = p->need[cp->reference][role] = 1;
        /* Masks (surface, edges) come from the model renderer's coverage and object layers. */
        if (registry_model() >= 0)
            p->need[registry_model()][role] = 1;
    }
    free(s);
    return rc;
}

/* The words of one render job's `reflcheck run` command; for_shell: quoted for the shell
 * alone, else for a make recipe. */
static void plan_job_words(const char *bin, const char *out, const char *cache, int threads, int small, int r, int role,
                           const char *scene_path, int for_shell)
{
    plan_quote_as(bin, for_shell);
    printf(" run --renderer %s --role %s --out ", registry_name(r), job_role_names[role]);
    plan_quote_as(out, for_shell);
    fputs(" --cache ", stdout);
    plan_quote_as(cache, for_shell);
    printf(" --threads %d%s -- ", threads, small ? " --small" : "");
    plan_quote_as(scene_path, for_shell);
}

/* The make group of renderer r's jobs: "wait" for POV-Ray, whose 3.7 process spends about 1 s
 * of a job in its own timed waits for 0.03-0.8 CPU-s (docs/nightly_time.md), so that a second
 * make gives those jobs slots of their own instead of holding a CPU slot while a core idles
 * (the sweep does the same, docs/sweep.md); "cpu" for every other renderer. */
static const char *plan_job_class(int r) { return strcmp(registry_name(r), "povray") == 0 ? "wait" : "cpu"; }

/* Slurm's array size limit (MaxArraySize) is 1001 by default: bigger groups are split. */
#define PLAN_ARRAY_MAX 1000

/* The Slurm limit of a job: its render timeout plus a minute for start-up, the cache and
 * writing the image and record, so the job's own timeout fires first and records "timeout"
 * as it does locally; Slurm's limit is the backstop. Whole minutes, as --time takes them. */
static int plan_minutes(double timeout) { return (int)((timeout + 60.0 + 59.0) / 60.0); }

/* The submit script: one Slurm array task per render job, grouped into arrays by time limit
 * (CPUs are --threads for all). Each array's list file holds one job per line as shell words:
 * its record's path, then its `reflcheck run` command; ops/slurm/task.sh runs line
 * SLURM_ARRAY_TASK_ID, ops/slurm/finish.py reads OUT/slurm/arrays to find each job's task. */
static void plan_print_sbatch(int group, int n, int threads, int minutes)
{
    printf("id=$(sbatch --parsable --array=0-%d --cpus-per-task=%d --time=%d --job-name=reflcheck-render "
           "--output=\"$slurm/%%A_%%a.out\" \"$@\" ops/slurm/task.sh \"$slurm/renders-%d.jobs\")\n"
           "id=${id%%%%;*}\n"
           "echo \"$id $slurm/renders-%d.jobs\" >> \"$slurm/arrays\"\n"
           "ids=$ids${ids:+:}$id\n",
           n - 1, threads, minutes, group, group);
}

static void plan_print_slurm(char **argv, int first, int argc, const plan_scene *all, const char *out,
                             const char *cache, const char *bin, int threads, int small)
{
    printf("#!/usr/bin/env bash\n"
           "# generated by reflcheck plan --scheduler slurm: every render job as a Slurm array task.\n"
           "# From the project root: bash THIS [SBATCH-OPTION...]; prints the array job ids joined by ':'\n"
           "# (for --dependency=afterany:IDS). SBATCH_PARTITION, SBATCH_ACCOUNT etc. apply as usual.\n"
           "set -euo pipefail\nslurm=");
    plan_quote_as(out, 1);
    printf("/slurm\nmkdir -p \"$slurm\"\n: > \"$slurm/arrays\"\nids=\n");
    /* Arrays by time limit, shortest first. */
    int group = 0;
    for (int prev = 0;;) {
        int m = 0;
        for (int i = first; i < argc; i++) {
            int mi = plan_minutes(all[i - first].timeout);
            if (mi > prev && (m == 0 || mi < m))
                m = mi;
        }
        if (m == 0)
            break;
        prev = m;
        int count = 0;
        for (int i = first; i < argc; i++) {
            if (plan_minutes(all[i - first].timeout) != m)
                continue;
            for (int r = 0; r < registry_count() && r < 16; r++)
                for (int role = 0; role < 3; role++) {
                    if (!all[i - first].need[r][role])
                        continue;
                    if (count % PLAN_ARRAY_MAX == 0)
                        printf("cat > \"$slurm/renders-%d.jobs\" <<'REFLCHECK_JOBS'\n", group);
                    char record[1200];
                    job_output_path(out, all[i - first].name, r, (comparison_role)role, "json", record, sizeof record);
                    plan_quote_as(record, 1);
                    putchar(' ');
                    plan_job_words(bin, out, cache, threads, small, r, role, argv[i], 1);
                    putchar('\n');
                    count++;
                    if (count % PLAN_ARRAY_MAX == 0) {
                        printf("REFLCHECK_JOBS\n");
                        plan_print_sbatch(group++, PLAN_ARRAY_MAX, threads, m);
                    }
                }
        }
        if (count % PLAN_ARRAY_MAX != 0) {
            printf("REFLCHECK_JOBS\n");
            plan_print_sbatch(group++, count % PLAN_ARRAY_MAX, threads, m);
        }
    }
    printf("echo \"$ids\"\n");
}

static const struct option plan_longopts[] = {
    {"out", required_argument, NULL, 'o'},   {"small", no_argument, NULL, 's'},
    {"cache", required_argument, NULL, 'c'}, {"threads", required_argument, NULL, 't'},
    {"bin", required_argument, NULL, 'b'},   {"scheduler", required_argument, NULL, 'S'},
    {"help", no_argument, NULL, 'h'},        {NULL, 0, NULL, 0},
};
static const cli_option_help plan_options_help[] = {
    {"out", "DIR",
     "the run folder the jobs write (required); letters, digits and _ . / + , @ - only, as make "
     "targets carry them"},
    {"small", NULL, "every job renders the small variant; default: full size"},
    {"cache", "DIR", "the render cache the jobs share; default: reports/cache"},
    {"threads", "N", "threads per job, 1 to 256; default: 1 (make -j runs the jobs in parallel)"},
    {"bin", "FILE", "the reflcheck program the jobs run; default: build/reflcheck"},
    {"scheduler", "make|slurm",
     "make: a Makefile, one target per job; slurm: a bash script that submits "
     "the jobs as Slurm array tasks (docs/slurm.md); default: make"},
    {"help", NULL, "this help, then exit 0"},
    {NULL, NULL, NULL},
};
const cli_command cli_plan_command = {
    .name = "plan",
    .run = cli_plan,
    .operands = "SCENE... --out RUNDIR [options]",
    .operand_kind = "scene",
    .summary = "the render jobs the scenes' comparisons need, as a Makefile or a Slurm script",
    .description = "Prints, on standard output, one `reflcheck run` job per renderer and role that the "
                   "comparisons of the scenes list, so that make -j (or Slurm) runs them in parallel and "
                   "compare then measures them. Every scene is read first: a refused plan prints nothing.",
    .longopts = plan_longopts,
    .shortopts = "h",
    .options = plan_options_help,
    .example = "reflcheck plan scenes/d3d9_glass.yaml --out runs/r1 --small > r1.mk && make -f r1.mk -j2",
};

int cli_plan(int argc, char **argv)
{
    const char *out = NULL, *cache = "reports/cache", *bin = "build/reflcheck";
    int small = 0, threads = 1, c, rc = CLI_OK, slurm = 0;
    unsigned char seen[256] = {0};
    optind = 1;
    opterr = 0;
    while (rc == CLI_OK && (c = getopt_long(argc, argv, "h", plan_longopts, NULL)) != -1) {
        if (c != '?' && (rc = cli_check_option("plan", c, seen, "h", plan_longopts)) != CLI_OK)
            break;
        switch (c) {
        case 'o': out = optarg; break;
        case 's': small = 1; break;
        case 'c': cache = optarg; break;
        case 'b': bin = optarg; break;
        case 't': rc = cli_parse_int("--threads", optarg, 1, 256, &threads); break;
        case 'h': return cli_help("plan");
        case 'S':
            if (strcmp(optarg, "slurm") == 0)
                slurm = 1;
            else if (strcmp(optarg, "make") != 0) {
                fprintf(stderr, "reflcheck: plan: --scheduler '%s': use make (the default) or slurm\n", optarg);
                rc = CLI_BAD_INPUT;
            }
            break;
        default: rc = cli_bad_option("plan", argc, argv, "h", plan_longopts, "see reflcheck plan --help");
        }
    }
    if (rc != CLI_OK)
        return rc;
    if (out == NULL || optind >= argc) {
        fprintf(stderr, "reflcheck: usage: reflcheck plan SCENE... --out RUNDIR [--small] [--cache DIR] "
                        "[--scheduler make|slurm]\n");
        return CLI_BAD_INPUT;
    }
    if (!plan_target_safe(out)) {
        fprintf(stderr,
                "reflcheck: plan: --out '%s': make cannot carry this path in a target; allowed: letters, "
                "digits, _ . / + , @ -\n",
                out);
        return CLI_BAD_INPUT;
    }
    rc = plan_check_path("--cache", cache);
    if (rc == CLI_OK)
        rc = plan_check_path("--bin", bin);
    for (int i = optind; rc == CLI_OK && i < argc; i++)
        rc = plan_check_path("scene file", argv[i]);
    plan_scene *all = rc == CLI_OK ? calloc((size_t)(argc - optind), sizeof *all) : NULL;
    if (rc == CLI_OK && all == NULL) {
        fprintf(stderr, "reflcheck: plan: out of memory for %d scenes\n", argc - optind);
        rc = CLI_FAILED;
    }
    /* Every scene is checked before anything is printed: a refused plan is no plan. */
    for (int i = optind; rc == CLI_OK && i < argc; i++)
        rc = plan_load(argv, i, optind, out, all);
    if (rc != CLI_OK) {
        free(all);
        return rc;
    }
    if (slurm) {
        plan_print_slurm(argv, optind, argc, all, out, cache, bin, threads, small);
        free(all);
        return CLI_OK;
    }
    printf("# generated by reflcheck plan: one target per render job; all: every job, cpu: the jobs\n"
           "# that keep a core busy, wait: the jobs that mostly wait (make -j N cpu & make -j M wait)\n"
           ".PHONY: all cpu wait\nall:\ncpu:\nwait:\n");
    for (int i = optind; i < argc; i++)
        for (int r = 0; r < registry_count() && r < 16; r++)
            for (int role = 0; role < 3; role++) {
                if (!all[i - optind].need[r][role])
                    continue;
                char target[1200];
                job_output_path(out, all[i - optind].name, r, (comparison_role)role, "json", target, sizeof target);
                printf("all: %s\n%s: %s\n%s:\n\t@", target, plan_job_class(r), target, target);
                plan_job_words(bin, out, cache, threads, small, r, role, argv[i], 0);
                putchar('\n');
            }
    free(all);
    return CLI_OK;
}
