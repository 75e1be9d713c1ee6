#include "frame.h"

#include <inttypes.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

#include "crease.h"
#include "exr.h"
#include "image_oiio.h"

static rc_status frame_env_cube(const scene *s, env_map *e, float **pixels, char *err, size_t errlen);

rc_status frame_env_load(const scene *s, env_map *e, float **pixels, char *err, size_t errlen)
{
    *pixels = NULL;
    e->kind = s->env.kind;
    e->constant = s->env.radiance;
    e->scale = s->env.radiance;
    e->width = e->height = 0;
    e->rgb = NULL;
    if (s->env.kind == ENV_CUBE)
        return frame_env_cube(s, e, pixels, err, errlen);
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

int frame_sun_split(const scene *s) { return s->env.kind == ENV_IMAGE && s->env.sun_threshold > 0.0f; }

int frame_light_count(const scene *s) { return s->n_lights + (frame_sun_split(s) && s->n_lights < SCENE_MAX_LIGHTS); }

rc_status frame_env_split_sun(scene *s, float *pixels, const env_map *e, env_sun *sun, char *err, size_t errlen)
{
    env_sun local;
    if (sun == NULL)
        sun = &local;
    memset(sun, 0, sizeof *sun);
    if (!frame_sun_split(s) || pixels == NULL)
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

/* A cube map of N x N faces converts to an equirectangular image this many times N wide and half
 * that high: 360 degrees over 4 N cube texels, so FRAME_CUBE_EQUIRECT_PER_FACE / 4 equirectangular
 * texels per cube texel, which keeps the references' bilinear lookup of the conversion within
 * the floor docs/cubemaps.md measures. */
#define FRAME_CUBE_EQUIRECT_PER_FACE 64
rc_status frame_env_cube_write(const char *path, const env_map *cube, char *err, size_t errlen)
{
    int w = FRAME_CUBE_EQUIRECT_PER_FACE * cube->width, h = w / 2;
    float *rgb = malloc((size_t)w * (size_t)h * 3 * sizeof *rgb);
    if (rgb == NULL) {
        snprintf(err, errlen, "%s: out of memory for a %dx%d conversion of the cube map", path, w, h);
        return RC_ERR_NOMEM;
    }
    env_cube_to_equirect(cube, w, h, rgb);
    env_map e = {.kind = ENV_IMAGE, .width = w, .height = h, .rgb = rgb};
    rc_status st = frame_env_write(path, &e, err, errlen);
    free(rgb);
    return st;
}

/* The layers of img, plus the crease layer when asked (frame.h), with the header attributes. */
static rc_status frame_write_layers(const char *path, const scene *s, const mesh *m, const render_image *img,
                                    const char *renderer, int crease, char *err, size_t errlen)
{
    exr_channel ch[RENDER_CHANNELS + 1];
    int n = 0;
    for (int c = 0; c < RENDER_CHANNELS; c++)
        if (img->chan[c] != NULL)
            ch[n++] = (exr_channel){render_channel_names[c], img->chan[c]};
    float *share = NULL;
    if (crease) {
        share = malloc((size_t)img->width * (size_t)img->height * sizeof *share);
        if (share == NULL) {
            status_message(err, errlen, "%s: out of memory for the crease layer of %dx%d", path, img->width,
                           img->height);
            return RC_ERR_NOMEM;
        }
        rc_status st = crease_share(s, m, img->width, img->height, img->supersample, 0, share, err, errlen);
        if (st != RC_OK) {
            free(share);
            return st;
        }
        ch[n++] = (exr_channel){"crease", share};
    }
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
    rc_status st = exr_write(path, img->width, img->height, ch, n, at, (int)(sizeof at / sizeof at[0]), err, errlen);
    free(share);
    return st;
}

rc_status frame_write(const char *path, const scene *s, const mesh *m, const render_image *img, char *err,
                      size_t errlen)
{
    return frame_write_layers(path, s, m, img, "reflcheck-raster", 1, err, errlen);
}

rc_status frame_write_as(const char *path, const scene *s, const mesh *m, const render_image *img, const char *renderer,
                         char *err, size_t errlen)
{
    return frame_write_layers(path, s, m, img, renderer, 0, err, errlen);
}

/* 1 when path ends in ext (".exr", ".dds"), in any case, as the scene file accepts it. */
static int frame_has_ext(const char *p, const char *ext)
{
    size_t n = strlen(p), k = strlen(ext);
    return n >= k && strcasecmp(p + n - k, ext) == 0;
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

int frame_is_dds(const char *path) { return frame_has_ext(path, ".dds"); }

/* Face f of a DDS file as a texture: 8-bit colour decoded as sRGB exactly as PNG/JPEG texels are,
 * float data (BC6H) taken as linear. */
static rc_status frame_dds_face(const image_dds *d, int f, texture *t, char *err, size_t errlen)
{
    size_t at = (size_t)f * (size_t)d->width * (size_t)d->height * 4;
    return d->linear ? texture_from_rgba(d->width, d->height, d->rgbaf + at, t, err, errlen)
                     : texture_from_srgb8(d->width, d->height, d->rgba8 + at, t, err, errlen);
}

/* A DDS file's faces (IMAGE_DDS_CUBE: six, D3DCUBEMAP_FACES order) or its 2D image into t[]. */
static rc_status frame_dds_load(const char *path, image_dds_kind kind, texture *t, char *err, size_t errlen)
{
    image_dds d;
    rc_status st = image_dds_read(path, kind, TEXTURE_MAX_BYTES, TEXTURE_MAX_SIDE, &d, err, errlen);
    for (int f = 0; st == RC_OK && f < d.faces; f++)
        st = frame_dds_face(&d, f, &t[f], err, errlen);
    image_dds_free(&d);
    if (st != RC_OK)
        for (int f = 0; f < (kind == IMAGE_DDS_CUBE ? 6 : 1); f++)
            texture_free(&t[f]);
    return st;
}

/* An image a scene names (texture, cube face, cross) by its extension: linear EXR, a 2D DDS
 * through OpenImageIO, else PNG/JPEG (sRGB). */
static rc_status frame_image_load(const char *path, texture *t, char *err, size_t errlen)
{
    if (frame_has_ext(path, ".exr"))
        return frame_texture_exr(path, t, err, errlen);
    if (frame_is_dds(path))
        return frame_dds_load(path, IMAGE_DDS_2D, t, err, errlen);
    return texture_load(path, t, err, errlen);
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
            rc_status st = frame_image_load(p, t, why, sizeof why);
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

/* The horizontal cross (FORMAT.md): face f's column and row, in faces, of the 4 x 3 grid
 *        +Y
 *    -X  +Z  +X  -Z
 *        -Y
 * each face as it is seen from inside the cube, unrotated. */
static const int frame_cross_cell[6][2] = {{2, 1}, {0, 1}, {1, 0}, {1, 2}, {1, 1}, {3, 1}};

void frame_env_cube_key(const scene *s, int face, char *key, size_t len)
{
    if (s->env.cube[0][0] != '\0')
        snprintf(key, len, "environment.cube.%s", env_cube_face_keys[face]);
    else
        snprintf(key, len, frame_is_dds(s->env.path) ? "environment.cube_dds" : "environment.cube_cross");
}

/* A cube map's faces as one ENV_CUBE map: six files, one cross, or one DDS cube; EXR linear,
 * PNG/JPEG and 8-bit DDS through the textures' sRGB decoding; square faces of one size, finite
 * texels >= 0. */
static rc_status frame_env_cube(const scene *s, env_map *e, float **pixels, char *err, size_t errlen)
{
    int one_file = s->env.cube[0][0] == '\0', dds = one_file && frame_is_dds(s->env.path);
    int cross = one_file && !dds;
    texture img[6] = {{0}};
    char why[1024], key[64];
    rc_status st = RC_OK;
    int n = 0, first = -1;
    /* A DDS cube holds its six faces in D3DCUBEMAP_FACES order, each as D3D addresses it: they
     * come out as six face images would. */
    if (dds && (st = frame_dds_load(s->env.path, IMAGE_DDS_CUBE, img, why, sizeof why)) != RC_OK)
        snprintf(err, errlen, "%s: environment.cube_dds: %s", s->path, why);
    for (int f = 0; st == RC_OK && f < (cross ? 1 : 6); f++) {
        const char *p = one_file ? s->env.path : s->env.cube[f];
        frame_env_cube_key(s, f, key, sizeof key);
        if (!dds)
            st = frame_image_load(p, &img[f], why, sizeof why);
        if (st != RC_OK) {
            snprintf(err, errlen, "%s: %s: %s", s->path, key, why);
            break;
        }
        int w = img[f].width, h = img[f].height;
        if (cross && (w % 4 != 0 || h % 3 != 0 || w / 4 != h / 3)) {
            snprintf(err, errlen,
                     "%s: %s: %s is %dx%d, not a horizontal cross; give a 4N x 3N image (faces N x N: +Y above +Z, "
                     "then -X +Z +X -Z in a row, -Y below +Z) or six faces under environment.cube",
                     s->path, key, p, w, h);
            st = RC_ERR_RANGE;
        } else if (!cross && w != h) {
            snprintf(err, errlen, "%s: %s: the %s face %s is %dx%d; give square faces, all of one size", s->path, key,
                     env_cube_face_names[f], p, w, h);
            st = RC_ERR_RANGE;
        } else if (!cross && first >= 0 && w != n) {
            snprintf(err, errlen,
                     "%s: %s: the %s face %s is %dx%d but the %s face %s is %dx%d; give six faces of one size", s->path,
                     key, env_cube_face_names[f], p, w, h, env_cube_face_names[first], s->env.cube[first], n, n);
            st = RC_ERR_RANGE;
        }
        if (first < 0) {
            first = f;
            n = cross ? w / 4 : w;
        }
    }
    size_t nn = (size_t)n * (size_t)n;
    float *rgb = st == RC_OK ? malloc(6 * nn * 3 * sizeof *rgb) : NULL;
    if (st == RC_OK && rgb == NULL) {
        snprintf(err, errlen, "%s: out of memory for a cube map of 6 x %dx%d", s->path, n, n);
        st = RC_ERR_NOMEM;
    }
    for (int f = 0; st == RC_OK && f < 6; f++) {
        const texture *t = &img[cross ? 0 : f];
        int x0 = cross ? frame_cross_cell[f][0] * n : 0, y0 = cross ? frame_cross_cell[f][1] * n : 0;
        for (int y = 0; y < n; y++)
            for (int x = 0; x < n; x++)
                for (int c = 0; c < 3; c++)
                    rgb[3 * ((size_t)f * nn + (size_t)y * (size_t)n + (size_t)x) + (size_t)c] =
                        t->rgba[4 * ((size_t)(y0 + y) * (size_t)t->width + (size_t)(x0 + x)) + (size_t)c];
    }
    for (int f = 0; f < 6; f++)
        texture_free(&img[f]);
    if (st != RC_OK) {
        free(rgb);
        return st;
    }
    *e = (env_map){.kind = ENV_CUBE, .scale = s->env.radiance, .width = n, .height = n, .rgb = rgb};
    /* As for an equirectangular image: a NaN, Inf or negative texel has no radiance meaning. */
    env_texel_check chk;
    if (env_check(e, &chk) != RC_OK) {
        const env_texel *t = chk.n_nonfinite > 0 ? &chk.first_nonfinite : &chk.first_negative;
        const char *p = one_file ? s->env.path : s->env.cube[t->face];
        frame_env_cube_key(s, t->face, key, sizeof key);
        snprintf(err, errlen,
                 "%s: %s: %s: %ld non-finite and %ld negative texel values, the first on the %s face at texel "
                 "(x %d, y %d) channel %c = %g; give faces whose texels are finite and >= 0",
                 s->path, key, p, chk.n_nonfinite, chk.n_negative, env_cube_face_names[t->face], t->x, t->y,
                 "RGB"[t->channel], (double)t -> value);
        free(rgb);
        *e = (env_map){.kind = ENV_CUBE, .scale = s->env.radiance};
        return RC_ERR_RANGE;
    }
    *pixels = rgb;
    return RC_OK;
}

rc_status frame_inputs_load(scene *s, env_map *e, float **env_pixels, texture_set *ts, char *err, size_t errlen)
{
    rc_status st = frame_env_load(s, e, env_pixels, err, errlen);
    if (st == RC_OK)
        st = frame_textures_load(s, ts, err, errlen);
    /* Every renderer gets the same split sky: the sun moved into a light here, once. */
    if (st == RC_OK)
        st = frame_env_split_sun(s, *env_pixels, e, NULL, err, errlen);
    return st;
}
