/* stability.c - the stability driver (see stability.h): runs the sweeps of stability_sweeps.c,
 * stability_shade.c, stability_physics.c and stability_user.c in their fixed order (the rows'
 * order and each sweep's random stream depend on it) and counts and finds the failing rows. The
 * references are in stability_ref.c, the writers in stability_output.c.
 */
#include "stability.h"

#include <float.h>
#include <stdlib.h>
#include <string.h>

#include "stability_sweep.h"

rc_status stability_run(const stability_options *o, stability_table *out)
{
    stability_options d = {0};
    if (o)
        d = *o;
    if (d.samples == 0)
        d.samples = STABILITY_DEFAULT_SAMPLES;
    if (d.albedo_grid == 0)
        d.albedo_grid = 96;
    if (d.samples < 16 || d.samples > STABILITY_MAX_SAMPLES || d.albedo_grid < 8 || d.albedo_grid > 2048)
        return RC_ERR_RANGE;
    stability_table *t = malloc(sizeof *t);
    if (!t)
        return RC_ERR_NOMEM;
    memset(t, 0, sizeof *t);
    t->samples = d.samples;
    t->ldbl_mant_dig = LDBL_MANT_DIG;
    sweep s = {.t = t, .r = {d.seed ? d.seed : 0x5EED5EEDu}, .n = d.samples};
    stab_sweep_fresnel(&s);
    stab_sweep_microfacet(&s);
    stab_sweep_d3d(&s);
    stab_sweep_d3d9client(&s);
    stab_sweep_cooktorrance(&s);
    stab_sweep_shade(&s);
    stab_sweep_unnormalised(&s);
    stab_check_physics(&s, d.albedo_grid);
    if (d.user != NULL)
        stab_sweep_user(&s, d.user, d.albedo_grid);
    memcpy(out, t, sizeof *t);
    free(t);
    return RC_OK;
}

int stab_row_fails(const stability_row *r)
{
    if (r->nan || r->inf || r->negative)
        return 1;
    return r->kind == STABILITY_PHYSICS && r->expect_ok && r->check_ok == 0;
}

int stability_failures(const stability_table *t)
{
    int n = 0;
    for (int i = 0; i < t->n_rows; i++)
        n += stab_row_fails(&t->rows[i]);
    return n;
}

const stability_row *stability_find(const stability_table *t, const char *function, const char *case_prefix)
{
    for (int i = 0; i < t->n_rows; i++) {
        const stability_row *r = &t->rows[i];
        if (function && strncmp(r->function, function, strlen(function)) != 0)
            continue;
        if (case_prefix && strncmp(r->case_name, case_prefix, strlen(case_prefix)) != 0)
            continue;
        return r;
    }
    return NULL;
}
