/* scene.c - the defaults stated in scene.h, in one place.
 *
 * Derived defaults (d3d.diffuse = albedo, d9.r0 from ior, d9.m = 1 - r0, ct.m = roughness,
 * ct.f0 from ior) are filled here for the default material; a scene file that changes albedo,
 * ior or roughness re-derives them after the whole material is read (harness/scene_file.c).
 */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "scene.h"
#include "formula.h"

/* Degrees to radians for the few defaults that are angles. */
const char *const scene_reserved_names[] = {
#include "reserved_names.def"
    NULL};

static int scene_name_char(int ch)
{
    return (ch >= 'a' && ch <= 'z') || (ch >= '0' && ch <= '9') || ch == '_' || ch == '-';
}

int scene_name_check(const char *name, char *why, size_t whylen)
{
    size_t len = name ? strlen(name) : 0;
    if (len == 0 || len >= SCENE_NAME_MAX) {
        snprintf(why, whylen, "name is %zu bytes long", len);
        return 0;
    }
    for (size_t i = 0; i < len; i++)
        if (!scene_name_char((unsigned char)name[i])) {
            snprintf(why, whylen, "character %zu (byte 0x%02x) is not allowed in a name", i + 1,
                     (unsigned char)name[i]);
            return 0;
        }
    if (name[0] == '-') {
        snprintf(why, whylen, "a name starting with '-' reads as a command-line option");
        return 0;
    }
    for (int i = 0; scene_reserved_names[i]; i++)
        if (strcmp(name, scene_reserved_names[i]) == 0) {
            snprintf(why, whylen,
                     "'%s' is reserved: a run folder holds a file or folder of that name itself "
                     "(model/reserved_names.def)",
                     name);
            return 0;
        }
    return 1;
}

void scene_name_sanitise(const char *text, size_t n, char out[SCENE_NAME_MAX])
{
    size_t j = 0;
    for (size_t i = 0; i < n && j + 1 < SCENE_NAME_MAX; i++) {
        int ch = (unsigned char)text[i];
        if (ch >= 'A' && ch <= 'Z')
            ch += 'a' - 'A';
        out[j] = (char)(scene_name_char(ch) && !(j == 0 && ch == '-') ? ch : '_');
        j++;
    }
    out[j] = '\0';
}

static float scene_deg(double d) { return (float)(d * FORMULA_PI_D / 180.0); }

void light_init(light *l)
{
    memset(l, 0, sizeof *l);
    l->kind = LIGHT_POINT;
    l->direction = v3(0.0f, -1.0f, 0.0f);
    l->a0 = 0.0f;
    l->a1 = 0.0f;
    l->a2 = 1.0f;
    l->range = INFINITY;
    l->inner = scene_deg(30.0);
    l->outer = scene_deg(40.0);
    l->falloff = 1.0f;
    /* The references can only reproduce the smooth profile, so it is the default. */
    l->profile = SPOT_SMOOTH;
}

void material_init(material *m)
{
    memset(m, 0, sizeof *m);
    m->albedo = v3s(0.8f);
    m->ior = 1.5f;
    m->roughness = 0.3f;
    m->lobe = 1;
    m->model = MODEL_D3D;

    m->d3d.diffuse = m->albedo;
    m->d3d.local_viewer = 1;
    m->d3d.normalize_normals = 1;
    m->d3d.two_sided = 1;
    m->d3d.diffuse_source = COLOUR_SOURCE_COLOUR1;
    m->d3d.specular_source = COLOUR_SOURCE_COLOUR2;

    float r = (1.0f - m->ior) / (1.0f + m->ior);
    m->d9.p = 3.0f;
    m->d9.r0 = r * r;
    m->d9.m = 1.0f - m->d9.r0;
    m->d9.fresnel_colour = v3s(1.0f);
    m->d9.norm = NORM_MAX;
    m->d9.alpha = 1.0f;

    m->ct.m = m->roughness;
    m->ct.f0 = v3s(r * r);
    m->ct.ks = v3s(1.0f);
    m->ct.norm = CT_WALTER;
    m->ct.g = G_VCAVITY;
    m->ct.f = F_SCHLICK;
    m->ct.reflection = 1;
}

void object_init(object *o)
{
    memset(o, 0, sizeof *o);
    o->shape = SHAPE_SPHERE;
    o->radius = 0.5f;
    o->major = 1.0f;
    o->size = v3s(1.0f);
    o->scale = v3s(1.0f);
    o->tessellation = 32;
}

const char *const physics_fresnel_names[4] = {"exact", "nv", "one", "schlick"};
const char *const physics_diffuse_weight_names[2] = {"plain", "one_minus_f"};

static size_t physics_mask_text(unsigned mask, int n_lights, char *buf, size_t len)
{
    unsigned all = n_lights >= 32 ? ~0u : (1u << n_lights) - 1u;
    mask &= all;
    if (mask == all)
        return (size_t)snprintf(buf, len, "all");
    if (mask == 0)
        return (size_t)snprintf(buf, len, "none");
    size_t used = 0;
    buf[0] = 0;
    for (int i = 0; i < n_lights && used < len; i++)
        if (mask & (1u << i))
            used += (size_t)snprintf(buf + used, len - used, "%s%d", used ? "+" : "", i);
    return used;
}

const char *physics_describe(const physics *p, int n_lights, char *buf, size_t len)
{
    char dl[40], sl[40];
    physics_mask_text(p->diffuse_lights, n_lights, dl, sizeof dl);
    physics_mask_text(p->specular_lights, n_lights, sl, sizeof sl);
    int fs = p->fresnel_specular >= 0 && p->fresnel_specular < 4 ? (int)p->fresnel_specular : 0;
    int fr = p->fresnel_reflection >= 0 && p->fresnel_reflection < 4 ? (int)p->fresnel_reflection : 0;
    int dw = p->diffuse_weight >= 0 && p->diffuse_weight < 2 ? (int)p->diffuse_weight : 0;
    snprintf(buf, len,
             "diffuse_lights=%s specular_lights=%s env_diffuse=%d env_specular=%d bounces=%d shadows=%d "
             "interreflection=%d fresnel_specular=%s fresnel_reflection=%s diffuse_weight=%s",
             dl, sl, p->env_diffuse, p->env_specular, p->bounces, p->shadows, p->interreflection,
             physics_fresnel_names[fs], physics_fresnel_names[fr], physics_diffuse_weight_names[dw]);
    return buf;
}

/* Splits a canonical description into its key=value words (at most 16). */
static int physics_words(char *text, char **words)
{
    int n = 0;
    char *t = text;
    while (*t != '\0' && n < 16) {
        words[n++] = t;
        t += strcspn(t, " ");
        if (*t == ' ')
            *t++ = '\0';
    }
    return n;
}

int physics_diff(const physics *want, const physics *rendered, int n_lights, char *buf, size_t len)
{
    char a[400], b[400];
    char *wa[16], *wb[16];
    physics_describe(want, n_lights, a, sizeof a);
    physics_describe(rendered, n_lights, b, sizeof b);
    int na = physics_words(a, wa), nb = physics_words(b, wb), n = 0;
    size_t used = 0;
    buf[0] = '\0';
    for (int i = 0; i < na && i < nb; i++) {
        if (strcmp(wa[i], wb[i]) == 0)
            continue;
        char *eq_a = strchr(wa[i], '='), *eq_b = strchr(wb[i], '=');
        if (eq_a == NULL || eq_b == NULL)
            continue;
        *eq_a = '\0';
        if (used < len)
            used += (size_t)snprintf(buf + used, len - used, "%s%s: %s wanted, %s rendered", n ? "; " : "", wa[i],
                                     eq_a + 1, eq_b + 1);
        n++;
    }
    return n;
}

void physics_init(physics *p)
{
    memset(p, 0, sizeof *p);
    p->diffuse_lights = PHYSICS_ALL_LIGHTS;
    p->specular_lights = PHYSICS_ALL_LIGHTS;
    p->env_diffuse = 0;
    p->env_specular = 1;
    p->bounces = 1;
    p->fresnel_specular = PHYS_FRESNEL_EXACT;
    p->fresnel_reflection = PHYS_FRESNEL_EXACT;
    p->diffuse_weight = PHYS_DIFFUSE_PLAIN;
}

void scene_init(scene *s)
{
    memset(s, 0, sizeof *s);
    strcpy(s->name, "scene");
    s->width = 64;
    s->height = 64;
    s->supersample = 1;
    s->samples = 64;
    s->camera.eye = v3(0.0f, 0.0f, 4.0f);
    s->camera.target = v3(0.0f, 0.0f, 0.0f);
    s->camera.up = v3(0.0f, 1.0f, 0.0f);
    s->camera.hfov = scene_deg(40.0);
    s->env.kind = ENV_NONE;
    s->env.radiance = v3s(1.0f); /* the image scale default; unused while kind is ENV_NONE */
    physics_init(&s->physics);
    for (int i = 0; i < SCENE_MAX_LIGHTS; i++)
        light_init(&s->lights[i]);
    for (int i = 0; i < SCENE_MAX_MATERIALS; i++)
        material_init(&s->materials[i]);
    for (int i = 0; i < SCENE_MAX_OBJECTS; i++)
        object_init(&s->objects[i]);
    /* Comparisons name renderers only in the file; harness/scene_file.c resolves them. */
    for (int i = 0; i < SCENE_MAX_COMPARISONS; i++)
        s->comparisons[i].role = ROLE_TWIN;
}

const light *scene_main_light(const scene *s)
{
    for (int i = 0; i < s->n_lights; i++)
        if (s->lights[i].kind == LIGHT_SUN)
            return &s->lights[i];
    return s->n_lights > 0 ? &s->lights[0] : NULL;
}

int scene_material_used(const scene *s, int mi)
{
    for (int i = 0; i < s->n_objects; i++)
        if (s->objects[i].material == mi)
            return 1;
    return 0;
}
