/* reflcheck renderers [--json]: the renderer table (harness/renderers/registry.h) as text, or
 * as JSON for scripts (harness/sweep.py, harness/deps.sh), so that none of them keeps a list. */
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

int cli_renderers(int argc, char **argv)
{
    int json = argc == 2 && strcmp(argv[1], "--json") == 0;
    if (argc > 2 || (argc == 2 && !json)) {
        fprintf(stderr, "reflcheck: renderers: unexpected argument '%s'; usage: reflcheck renderers [--json]\n",
                argv[json ? 2 : 1]);
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
