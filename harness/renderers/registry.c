/* registry.c - the renderers, one row each. Adding a renderer: its folder, its #include and
 * its row here (README, "Adding a renderer"). */
#include "registry.h"

#include <stdio.h>
#include <string.h>

#include "crease.h"
#include "cycles/cycles.h"
#include "eevee/eevee.h"
#include "exact/exact.h"
#include "povray/povray.h"
#include "raster/raster_render.h"

/* What exact renders neither way (pixel integral or at our own samples): one physics, two rows. */
static const char registry_exact_cannot[] =
    "a twin (it renders the physics), rough lobes lit by an environment and an environment image on the diffuse "
    "(they need an integral), shadows, inter-reflection, textures";

static const renderer_row registry_rows[] = {
    {.name = "raster",
     .title = "reflcheck rasterizer",
     .version = "reflcheck-raster",
     .is_model = 1,
     .render = raster_render_job},
    {.name = "povray",
     .title = "POV-Ray 3.7",
     .program = "povray",
     .package = "povray",
     .partial = {[ROLE_TWIN] = RENDERER_TERM_SPECULAR},
     .cannot = "Cook-Torrance (no Beckmann lobe), conductors (no complex Fresnel), Gouraud, clamping, eq. 8, "
               "the D3D spot profile, distance-attenuated D3D ambient, one-sided (d3d.two_sided false) with a "
               "specular colour",
     .cube_maps = 1,
     .render = povray_render_job,
     .physics = povray_physics},
    {.name = "cycles",
     .title = "Blender 3.4 Cycles",
     .program = "blender",
     .package = "blender",
     .stochastic = 1,
     .partial = {[ROLE_TWIN] = RENDERER_TERM_SPECULAR},
     .cannot = "D3D ambient, Gouraud, clamping, eq. 8 with a point main light, D3D attenuation and spot profile",
     .crease_rules = CREASE_RULE_BACK_FACE | CREASE_RULE_VALID_REFLECTION,
     .render = cycles_render_job,
     .physics = cycles_physics},
    {.name = "exact",
     .title = "reflcheck exact physics (pixel integral)",
     .version = "reflcheck-exact-2",
     .cannot = registry_exact_cannot,
     .render = exact_render_job,
     .physics = exact_physics},
    /* exact at the rasterizer's own k x k sample positions: the shading's error alone (the float
     * floor of a model that is its physics), sampling error cancelled (exact/exact.h). */
    {.name = "exact_point",
     .title = "reflcheck exact physics at the rasterizer's own samples",
     .version = "reflcheck-exact-point-1",
     .cannot = registry_exact_cannot,
     .render = exact_point_render_job,
     .physics = exact_physics},
    /* A real-time engine, judged like our model: validate against Cycles; a twin of the raster
     * where it can (eevee_calibration); never in an agree (two approximations).
     * Deterministic (TAA), so not stochastic: its samples reach the key through the scene. */
    {.name = "eevee",
     .title = "Blender 3.4 EEVEE",
     .program = "blender",
     .package = "blender",
     .partial = {[ROLE_TWIN] = RENDERER_TERM_SPECULAR},
     .cannot = "a Beckmann lobe (GGX only, split-sum with LTC lights), exact mirrors (pre-filtered world probe), "
               "env_diffuse false under a lit world (its probe lights every diffuse), shadows, inter-reflection; "
               "as twin only Lambert under points and suns; plus what Cycles cannot",
     .render = eevee_render_job},
};

#define REGISTRY_N ((int)(sizeof registry_rows / sizeof registry_rows[0]))

int registry_count(void) { return REGISTRY_N; }

const renderer_row *registry_row(int i) { return i >= 0 && i < REGISTRY_N ? &registry_rows[i] : NULL; }

const char *registry_name(int i) { return i >= 0 && i < REGISTRY_N ? registry_rows[i].name : "?"; }

int registry_find(const char *name)
{
    for (int i = 0; name != NULL && i < REGISTRY_N; i++)
        if (strcmp(name, registry_rows[i].name) == 0)
            return i;
    return -1;
}

int registry_model(void)
{
    for (int i = 0; i < REGISTRY_N; i++)
        if (registry_rows[i].is_model)
            return i;
    return -1;
}

const char *registry_list(char *buf, size_t len)
{
    size_t used = 0;
    buf[0] = '\0';
    for (int i = 0; i < REGISTRY_N && used < len; i++)
        used += (size_t)snprintf(buf + used, len - used, "%s%s", i == 0 ? "" : (i == REGISTRY_N - 1 ? " or " : ", "),
                                 registry_rows[i].name);
    return buf;
}
