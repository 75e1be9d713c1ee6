/* reflcheck - command line.
 *
 *   reflcheck render SCENE -o OUT.exr [--width W] [--height H] [--supersample K] [--threads N] [--aovs all|none]
 *   reflcheck eval fresnel|beckmann [--ior N] [--p P] [--r0 R0] [--m M] [--steps N]
 *   reflcheck check SCENE                 parse and validate only
 *   reflcheck run | plan | compare | stability | renderers   (see usage below)
 * Exit status: 0 ok, 1 a run failed (a job not ok or skipped, a comparison that fails or errors, a
 * write that failed), 2 bad input (command line, scene file, a file it references, an output onto an input).
 */
#include <math.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli.h"
#include "renderers/registry.h"

static void usage(FILE *f)
{
    char names[200] = "";
    for (int i = 0, used = 0; i < registry_count() && used < (int)sizeof names; i++)
        used += snprintf(names + used, sizeof names - (size_t)used, "%s%s", i ? "|" : "", registry_name(i));
    fprintf(f,
            "usage: reflcheck COMMAND ...\n"
            "  render SCENE -o OUT.exr [--width W] [--height H] [--supersample K] [--threads N] [--aovs all|none]\n"
            "  eval fresnel|beckmann|smith [--ior N] [--p P] [--r0 R0] [--m M] [--steps N]\n"
            "  check SCENE\n"
            "  run SCENE --renderer %s [--role twin|validate|agree] [--small] [--out DIR]\n"
            "      [--supersample K] [--samples N] [--tessellation N] [--per-vertex] [--tag NAME] [--seeds N]\n"
            "  plan SCENE... --out RUNDIR [--small]      the render jobs as a Makefile\n"
            "  compare SCENE... --run RUNDIR             metrics and thresholds -> compare.json\n"
            "  diff TEST.exr REF.exr [--mask GEO.exr]    metrics of one image pair as JSON\n"
            "  stability [--json F] [--csv F]            float models vs long double over extremes\n"
            "  renderers [--json]                        the renderer table\n"
            "  fit SCENE... [--out RUNDIR] [--small] [--bounds seed|wide]   parameters fitted to each validate\n",
            names);
}

int main(int argc, char **argv)
{
    if (argc < 2 || strcmp(argv[1], "-h") == 0 || strcmp(argv[1], "--help") == 0) {
        usage(argc < 2 ? stderr : stdout);
        return argc < 2 ? 2 : 0;
    }
    /* Past a file size limit (ulimit -f) a write must fail with EFBIG and be reported by every
     * command (outputs are temporaries renamed on success), not kill the process with SIGXFSZ
     * and leave a temporary behind. */
    signal(SIGXFSZ, SIG_IGN);
    const cli_command *c = cli_find(argv[1]);
    if (c == NULL) {
        fprintf(stderr, "reflcheck: unknown command '%s'\n", argv[1]);
        usage(stderr);
        return 2;
    }
    return c->run(argc - 1, argv + 1);
}
