#include "frame.h"

#include <inttypes.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "exr.h"

rc_status frame_env_load(const scene *s, env_map *e, float **pixels, char *err, size_t errlen)
{
    *pixels = NULL;
    e->kind = s->env.kind;
    e->constant = s->env.radiance;
    e->scale = s->env.radiance;
    e->width = e->height = 0;
    e->rgb = NULL;
    if (s->env.kind != ENV_IMAGE)
        return RC_OK;

    exr_image img;
    char why[512];
    rc_status st = exr_read(s->env.path, &img, why, sizeof why);
    if (st != RC_OK) {
        snprintf(err, errlen, "%s: environment.image: %s", s->path, why);
        return st;
    }
    const float *ch[3] = {exr_image_channel(&img, "R"), exr_image_channel(&img, "G"), exr_image_channel(&img, "B")};
    if (ch[0] == NULL || ch[1] == NULL || ch[2] == NULL) {
        snprintf(err, errlen, "%s: environment.image: %s has no R, G, B channels; give an RGB equirectangular EXR",
                 s->path, s->env.path);
        exr_image_free(&img);
        return RC_ERR_PARSE;
    }
    size_t n = (size_t)img.width * (size_t)img.height;
    float *p = malloc(3 * n * sizeof *p);
    if (p == NULL) {
        exr_image_free(&img);
        snprintf(err, errlen, "%s: out of memory for environment %s", s->path, s->env.path);
        return RC_ERR_NOMEM;
    }
    for (size_t i = 0; i < n; i++)
        for (int c = 0; c < 3; c++)
            p[3 * i + (size_t)c] = ch[c][i];
    e->width = img.width;
    e->height = img.height;
    e->rgb = p;
    exr_image_free(&img);
    /* A NaN, Inf or negative texel has no radiance meaning and the bilinear lookup spreads it
     * into every pixel that sees it; none of the canonical environments has one, so refuse
     * them rather than clamp (the fix is one oiiotool call). */
    env_texel_check chk;
    if (env_check(e, &chk) != RC_OK) {
        const env_texel *t = chk.n_nonfinite > 0 ? &chk.first_nonfinite : &chk.first_negative;
        snprintf(err, errlen,
                 "%s: environment.image: %s: %ld non-finite and %ld negative texel values, the first at texel "
                 "(x %d, y %d) channel %c = %g; give an image whose texels are finite and >= 0, e.g. "
                 "oiiotool %s --fixnan black --clamp:min=0 -o fixed.exr",
                 s->path, s->env.path, chk.n_nonfinite, chk.n_negative, t->x, t->y, "RGB"[t->channel],
                 (double)t -> value, s -> env.path);
        free(p);
        e->rgb = NULL;
        e->width = e->height = 0;
        return RC_ERR_RANGE;
    }
    *pixels = p;
    return RC_OK;
}

rc_status frame_env_split_sun(scene *s, float *pixels, const env_map *e, env_sun *sun, char *err, size_t errlen)
{
    env_sun local;
    if (sun == NULL)
        sun = &local;
    memset(sun, 0, sizeof *sun);
    if (s->env.kind != ENV_IMAGE || !(s->env.sun_threshold > 0.0f) || pixels == NULL)
        return RC_OK;
    if (s->n_lights >= SCENE_MAX_LIGHTS) {
        snprintf(err, errlen,
                 "%s: environment.sun_threshold: the extracted sun needs a light and the scene has %d (the most); "
                 "remove a light or the sun_threshold",
                 s->path, s->n_lights);
        return RC_ERR_RANGE;
    }
    rc_status st = env_extract_sun(pixels, e->width, e->height, s->env.radiance, s->env.sun_threshold, sun);
    if (st == RC_ERR_NOMEM) {
        snprintf(err, errlen, "%s: environment.sun_threshold: out of memory for a %dx%d image", s->path, e->width,
                 e->height);
        return st;
    }
    if (st != RC_OK || !(v3_dot(sun->irradiance, sun->irradiance) > 0.0f)) {
        snprintf(err, errlen,
                 "%s: environment.sun_threshold: no texel of %s is brighter than %g (its brightest: luminance %g); "
                 "give a threshold between the sky's and the sun's luminance",
                 s->path, s->env.path, (double)s->env.sun_threshold, (double)sun->peak);
        return RC_ERR_RANGE;
    }
    light *l = &s->lights[s->n_lights++];
    light_init(l);
    l->kind = LIGHT_SUN;
    l->direction = v3_neg(sun->direction);
    l->intensity = sun->irradiance;
    return RC_OK;
}

rc_status frame_env_write(const char *path, const env_map *e, char *err, size_t errlen)
{
    size_t n = (size_t)e->width * (size_t)e->height;
    float *p[3] = {malloc(n * sizeof(float)), malloc(n * sizeof(float)), malloc(n * sizeof(float))};
    rc_status st = RC_ERR_NOMEM;
    if (p[0] && p[1] && p[2]) {
        for (size_t i = 0; i < n; i++)
            for (int c = 0; c < 3; c++)
                p[c][i] = e->rgb[3 * i + (size_t)c];
        exr_channel ch[3] = {{"R", p[0]}, {"G", p[1]}, {"B", p[2]}};
        st = exr_write(path, e->width, e->height, ch, 3, NULL, 0, err, errlen);
    } else
        snprintf(err, errlen, "%s: out of memory for a %dx%d environment", path, e->width, e->height);
    for (int c = 0; c < 3; c++)
        free(p[c]);
    return st;
}

rc_status frame_write(const char *path, const scene *s, const mesh *m, const render_image *img, char *err,
                      size_t errlen)
{
    return frame_write_as(path, s, m, img, "reflcheck-raster", err, errlen);
}

rc_status frame_write_as(const char *path, const scene *s, const mesh *m, const render_image *img, const char *renderer,
                         char *err, size_t errlen)
{
    exr_channel ch[RENDER_CHANNELS];
    int n = 0;
    for (int c = 0; c < RENDER_CHANNELS; c++)
        if (img->chan[c] != NULL)
            ch[n++] = (exr_channel){render_channel_names[c], img->chan[c]};
    char hash[32], ms[32], k[16], tris[32], samples[32];
    snprintf(hash, sizeof hash, "%016" PRIx64, s->hash);
    snprintf(ms, sizeof ms, "%.3f", img->seconds * 1e3);
    snprintf(k, sizeof k, "%d", img->supersample);
    snprintf(tris, sizeof tris, "%d", m->n_tris);
    snprintf(samples, sizeof samples, "%lld", img->shaded_samples);
    exr_attr at[] = {
        {"reflcheck.scene", s->name},          {"reflcheck.scene_hash", hash}, {"reflcheck.renderer", renderer},
        {"reflcheck.render_ms", ms},           {"reflcheck.supersample", k},   {"reflcheck.triangles", tris},
        {"reflcheck.shaded_samples", samples},
    };
    return exr_write(path, img->width, img->height, ch, n, at, (int)(sizeof at / sizeof at[0]), err, errlen);
}

static int frame_is_exr(const char *p)
{
    size_t n = strlen(p);
    return n >= 4 && (strcmp(p + n - 4, ".exr") == 0 || strcmp(p + n - 4, ".EXR") == 0);
}

static rc_status frame_texture_exr(const char *path, texture *t, char *err, size_t errlen)
{
    exr_image img;
    rc_status st = exr_read(path, &img, err, errlen);
    if (st != RC_OK)
        return st;
    const float *r = exr_image_channel(&img, "R"), *g = exr_image_channel(&img, "G"), *b = exr_image_channel(&img, "B");
    if (r == NULL || g == NULL || b == NULL) {
        snprintf(err, errlen, "%s: no R, G, B channels; give a linear RGB(A) EXR texture", path);
        exr_image_free(&img);
        return RC_ERR_PARSE;
    }
    st = texture_from_planes(img.width, img.height, r, g, b, exr_image_channel(&img, "A"), t, err, errlen);
    exr_image_free(&img);
    return st;
}

rc_status frame_textures_load(const scene *s, texture_set *ts, char *err, size_t errlen)
{
    memset(ts, 0, sizeof *ts);
    static const char *const slot[MAT_TEX_SLOTS] = {"diffuse", "specular"};
    for (int i = 0; i < s->n_materials; i++)
        for (int k = 0; k < MAT_TEX_SLOTS; k++) {
            const char *p = s->materials[i].texture[k];
            if (p[0] == '\0')
                continue;
            char why[1024];
            texture *t = &ts->map[i][k];
            rc_status st =
                frame_is_exr(p) ? frame_texture_exr(p, t, why, sizeof why) : texture_load(p, t, why, sizeof why);
            /* A NaN, Inf or negative texel has no colour meaning and bilinear filtering spreads it. */
            size_t n = st == RC_OK ? (size_t)t->width * (size_t)t->height * 4 : 0;
            for (size_t j = 0; j < n && st == RC_OK; j++)
                if (!(isfinite(t->rgba[j]) && t->rgba[j] >= 0.0f)) {
                    snprintf(why, sizeof why,
                             "%s: texel (x %zu, y %zu) channel %c is %g; give texels that are finite and >= 0", p,
                             j / 4 % (size_t)t->width, j / 4 / (size_t)t->width, "RGBA"[j % 4], (double)t -> rgba[j]);
                    st = RC_ERR_RANGE;
                }
            if (st != RC_OK) {
                snprintf(err, errlen, "%s: materials.%s.texture.%s: %s", s->path, s->materials[i].name, slot[k], why);
                texture_set_free(ts);
                return st;
            }
        }
    return RC_OK;
}
