/* reflcheck plan: the render jobs the scenes' comparisons need, as a Makefile, so that
 * `make -j` runs them in parallel and each scene renders only the renderers and roles its
 * comparisons list. Each role has its own renders: twin switches our Cook-Torrance to Smith
 * G and F = 1, agree sets both references up the one way both can represent.
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

/* Writes s single-quoted for /bin/sh, with make's `$` doubled: a make recipe word that the
 * shell receives as exactly s. */
static void plan_quote(const char *s)
{
    putchar('\'');
    for (; *s; s++) {
        if (*s == '\'')
            fputs("'\\''", stdout);
        else if (*s == '$')
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
        int role = cp->role;
        p->need[cp->test][role] = p->need[cp->reference][role] = 1;
        /* Masks (surface, edges) come from the model renderer's coverage and object layers. */
        if (registry_model() >= 0)
            p->need[registry_model()][role] = 1;
    }
    free(s);
    return rc;
}

int cli_plan(int argc, char **argv)
{
    static const struct option longopts[] = {
        {"out", required_argument, NULL, 'o'},   {"small", no_argument, NULL, 's'},
        {"cache", required_argument, NULL, 'c'}, {"threads", required_argument, NULL, 't'},
        {"bin", required_argument, NULL, 'b'},   {NULL, 0, NULL, 0},
    };
    const char *out = NULL, *cache = "reports/cache", *bin = "build/reflcheck";
    int small = 0, threads = 1, c, rc = CLI_OK;
    optind = 1;
    opterr = 0;
    while (rc == CLI_OK && (c = getopt_long(argc, argv, "", longopts, NULL)) != -1) {
        switch (c) {
        case 'o': out = optarg; break;
        case 's': small = 1; break;
        case 'c': cache = optarg; break;
        case 'b': bin = optarg; break;
        case 't': rc = cli_parse_int("--threads", optarg, 1, 256, &threads); break;
        default: fprintf(stderr, "reflcheck: plan: unknown option '%s'\n", argv[optind - 1]); rc = CLI_BAD_INPUT;
        }
    }
    if (rc != CLI_OK)
        return rc;
    if (out == NULL || optind >= argc) {
        fprintf(stderr, "reflcheck: usage: reflcheck plan SCENE... --out RUNDIR [--small] [--cache DIR]\n");
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
    printf("# generated by reflcheck plan: one target per render job\n.PHONY: all\nall:\n");
    for (int i = optind; i < argc; i++)
        for (int r = 0; r < registry_count() && r < 16; r++)
            for (int role = 0; role < 3; role++) {
                if (!all[i - optind].need[r][role])
                    continue;
                char target[1200];
                job_output_path(out, all[i - optind].name, r, (comparison_role)role, "json", target, sizeof target);
                printf("all: %s\n%s:\n\t@", target, target);
                plan_quote(bin);
                printf(" run --renderer %s --role %s --out ", registry_name(r), job_role_names[role]);
                plan_quote(out);
                fputs(" --cache ", stdout);
                plan_quote(cache);
                printf(" --threads %d%s -- ", threads, small ? " --small" : "");
                plan_quote(argv[i]);
                putchar('\n');
            }
    free(all);
    return CLI_OK;
}
