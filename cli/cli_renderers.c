/* reflcheck renderers [--json]: the renderer table (harness/renderers/registry.h) as text, or
 * as JSON for scripts (tools/sweep.py, ops/deps.sh), so that none of them keeps a list. */
#include <getopt.h>
#include <stdio.h>
#include <string.h>

#include <cJSON.h>

#include "cli.h"
#include "jobs.h"
#include "jsonio.h"
#include "renderers/registry.h"

static cJSON *cli_renderers_terms(unsigned bits)
{
    cJSON *a = cJSON_CreateArray();
    for (int t = 0; t < RENDERER_N_TERMS; t++)
        if (bits & (1u << t))
            cJSON_AddItemToArray(a, cJSON_CreateString(renderer_term_name(t)));
    return a;
}

static const struct option renderers_longopts[] = {
    {"json", no_argument, NULL, 'j'}, {"help", no_argument, NULL, 'h'}, {NULL, 0, NULL, 0}};
static const cli_option_help renderers_options_help[] = {
    {"json", NULL,
     "the table as JSON, with each renderer's package, the terms it may leave out per role and "
     "what it cannot render; default: one line per renderer"},
    {"help", NULL, "this help, then exit 0"},
    {NULL, NULL, NULL},
};
const cli_command cli_renderers_command = {
    .name = "renderers",
    .run = cli_renderers,
    .operands = "[--json]",
    .operand_kind = "",
    .summary = "the renderer table: name, title, program, model or reference",
    .description = "Prints the renderers reflcheck knows (harness/renderers/registry.c), the names --renderer "
                   "takes: its own rasterizer (the model), the exact references and the external programs "
                   "(POV-Ray, Blender Cycles and EEVEE).",
    .longopts = renderers_longopts,
    .shortopts = "h",
    .options = renderers_options_help,
    .example = "reflcheck renderers --json",
};

int cli_renderers(int argc, char **argv)
{
    int json = 0, c;
    optind = 1;
    opterr = 0;
    while ((c = getopt_long(argc, argv, "h", renderers_longopts, NULL)) != -1) {
        if (c == 'h')
            return cli_help("renderers");
        if (c != 'j')
            return cli_bad_option("renderers", argc, argv, "h", renderers_longopts,
                                  "usage: reflcheck renderers [--json]");
        json = 1;
    }
    if (optind != argc) {
        fprintf(stderr, "reflcheck: renderers: unexpected argument '%s'; usage: reflcheck renderers [--json]\n",
                argv[optind]);
        return CLI_BAD_INPUT;
    }
    if (!json) {
        for (int i = 0; i < registry_count(); i++) {
            const renderer_row *r = registry_row(i);
            printf("%-8s %-22s %-8s %s%s\n", r->name, r->title, r->program ? r->program : "-",
                   r->is_model ? "model" : "reference", r->stochastic ? ", stochastic" : "");
        }
        return CLI_OK;
    }
    cJSON *arr = cJSON_CreateArray();
    for (int i = 0; i < registry_count(); i++) {
        const renderer_row *r = registry_row(i);
        cJSON *o = cJSON_CreateObject();
        cJSON_AddStringToObject(o, "name", r->name);
        cJSON_AddStringToObject(o, "title", r->title);
        if (r->program)
            cJSON_AddStringToObject(o, "program", r->program);
        else
            cJSON_AddNullToObject(o, "program");
        if (r->package)
            cJSON_AddStringToObject(o, "package", r->package);
        else
            cJSON_AddNullToObject(o, "package");
        cJSON_AddBoolToObject(o, "model", r->is_model);
        cJSON_AddBoolToObject(o, "stochastic", r->stochastic);
        cJSON *partial = cJSON_AddObjectToObject(o, "may_leave_out");
        for (int role = 0; role < 3; role++)
            cJSON_AddItemToObject(partial, job_role_names[role], cli_renderers_terms(r->partial[role]));
        cJSON_AddStringToObject(o, "cannot", r->cannot ? r->cannot : "");
        cJSON_AddItemToArray(arr, o);
    }
    int bad = jsonio_print(stdout, arr);
    cJSON_Delete(arr);
    return bad == 0 && fflush(stdout) == 0 ? CLI_OK : CLI_FAILED;
}
