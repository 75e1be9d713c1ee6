#include "env.h"

#include <math.h>
#include <stddef.h>

#include "formula.h"
#include "smath.h"

void env_direction_to_texel(const env_map *e, vec3 dir, float *tx, float *ty)
{
    vec3 d = v3_norm(dir);
    /* asinf is only defined on [-1, 1]; rounding in v3_norm can leave y a few ulp outside. */
    float y = fminf(fmaxf(d.y, -1.0f), 1.0f);
    float u = 0.5f + atan2f(d.z, d.x) / (2.0f * FORMULA_PI_F);
    float v = 0.5f + asinf(y) / FORMULA_PI_F;
    *tx = u * (float)e->width;
    *ty = (1.0f - v) * (float)e->height;
}

rc_status env_check(const env_map *e, env_texel_check *out)
{
    const env_texel none = {-1, -1, -1, 0.0f};
    *out = (env_texel_check){0, 0, none, none};
    if (e == NULL || e->kind != ENV_IMAGE || e->rgb == NULL || e->width <= 0 || e->height <= 0)
        return RC_OK;
    for (int y = 0; y < e->height; y++)
        for (int x = 0; x < e->width; x++)
            for (int c = 0; c < 3; c++) {
                float v = e->rgb[3 * ((size_t)y * (size_t)e->width + (size_t)x) + (size_t)c];
                if (!isfinite(v)) {
                    if (out->n_nonfinite++ == 0)
                        out->first_nonfinite = (env_texel){x, y, c, v};
                } else if (v < 0.0f && out->n_negative++ == 0) {
                    out->first_negative = (env_texel){x, y, c, v};
                }
            }
    return out->n_nonfinite > 0 || out->n_negative > 0 ? RC_ERR_RANGE : RC_OK;
}

static vec3 env_texel_rgb(const env_map *e, int x, int y)
{
    y = y < 0 ? 0 : (y >= e->height ? e->height - 1 : y);
    const float *p = e->rgb + 3 * ((size_t)y * (size_t)e->width + (size_t)x);
    return v3(p[0], p[1], p[2]);
}

vec3 env_lookup(const env_map *e, vec3 dir)
{
    if (e == NULL || e->kind == ENV_NONE || v3_dot(dir, dir) == 0.0f)
        return v3s(0.0f);
    if (e->kind == ENV_CONSTANT || e->rgb == NULL || e->width <= 0 || e->height <= 0)
        return e->kind == ENV_CONSTANT ? e->constant : v3s(0.0f);

    float tx, ty;
    env_direction_to_texel(e, dir, &tx, &ty);
    /* Texel centres sit at +0.5: shift so that floor() finds the left/upper neighbour. */
    float fx = tx - 0.5f, fy = ty - 0.5f;
    float x0f = floorf(fx), y0f = floorf(fy);
    float ax = fx - x0f, ay = fy - y0f;
    int x0 = (int)x0f, y0 = (int)y0f;
    /* tx lies in [0, W], so x0 is in [-1, W]: wrap with compares instead of a division per texel. */
    x0 = x0 < 0 ? x0 + e->width : (x0 >= e->width ? x0 - e->width : x0);
    int x1 = x0 + 1 >= e->width ? x0 + 1 - e->width : x0 + 1;
    if (x0 < 0 || x0 >= e->width)
        x0 = 0, x1 = e->width > 1 ? 1 : 0;
    vec3 top = v3_lerp(env_texel_rgb(e, x0, y0), env_texel_rgb(e, x1, y0), ax);
    vec3 bottom = v3_lerp(env_texel_rgb(e, x0, y0 + 1), env_texel_rgb(e, x1, y0 + 1), ax);
    return v3_mul(v3_lerp(top, bottom, ay), e->scale);
}

/* The same lookup as env_lookup with one lane per direction: asin(y) of the unit direction is
 * taken as atan2(y, sqrt(x^2 + z^2)), which needs no normalisation, and every index is kept
 * inside the image by selects, so no lane can read out of bounds whatever its input. */
SMATH_CLONES
void env_lookup_n(const env_map *e, int n, const float *restrict dx, const float *restrict dy, const float *restrict dz,
                  float *restrict r, float *restrict g, float *restrict b)
{
    if (e == NULL || e->kind == ENV_NONE || e->kind == ENV_CONSTANT || e->rgb == NULL || e->width <= 0 ||
        e->height <= 0) {
        vec3 c = e != NULL && e->kind == ENV_CONSTANT ? e->constant : v3s(0.0f);
        for (int i = 0; i < n; i++) {
            int zero = (dx[i] == 0.0f) & (dy[i] == 0.0f) & (dz[i] == 0.0f);
            r[i] = zero ? 0.0f : c.x;
            g[i] = zero ? 0.0f : c.y;
            b[i] = zero ? 0.0f : c.z;
        }
        return;
    }
    const int w = e->width, h = e->height;
    const float fw = (float)w, fh = (float)h;
    const float *restrict rgb = e->rgb;
    const vec3 scale = e->scale;
#pragma omp simd
    for (int i = 0; i < n; i++) {
        float x = dx[i], y = dy[i], z = dz[i];
        int zero = (x == 0.0f) & (y == 0.0f) & (z == 0.0f);
        float u = 0.5f + smath_atan2(z, x) * (0.5f / FORMULA_PI_F);
        float v = 0.5f + smath_atan2(y, sqrtf(x * x + z * z)) * (1.0f / FORMULA_PI_F);
        float fx = u * fw - 0.5f, fy = (1.0f - v) * fh - 0.5f;
        /* fx, fy >= -0.5: truncating fx + 1 is floor(fx) + 1 without a libm floorf. */
        int x0 = (int)(fx + 1.0f) - 1, y0 = (int)(fy + 1.0f) - 1;
        float ax = fx - (float)x0, ay = fy - (float)y0;
        x0 = x0 < 0 ? x0 + w : (x0 >= w ? x0 - w : x0);
        x0 = ((x0 >= 0) & (x0 < w)) ? x0 : 0;
        int x1 = x0 + 1 >= w ? 0 : x0 + 1;
        int y1 = y0 + 1;
        y0 = y0 < 0 ? 0 : (y0 >= h ? h - 1 : y0);
        y1 = y1 < 0 ? 0 : (y1 >= h ? h - 1 : y1);
        int o00 = 3 * (y0 * w + x0), o01 = 3 * (y0 * w + x1), o10 = 3 * (y1 * w + x0), o11 = 3 * (y1 * w + x1);
        float bx = 1.0f - ax, by = 1.0f - ay;
        float cr = by * (bx * rgb[o00] + ax * rgb[o01]) + ay * (bx * rgb[o10] + ax * rgb[o11]);
        float cg = by * (bx * rgb[o00 + 1] + ax * rgb[o01 + 1]) + ay * (bx * rgb[o10 + 1] + ax * rgb[o11 + 1]);
        float cb = by * (bx * rgb[o00 + 2] + ax * rgb[o01 + 2]) + ay * (bx * rgb[o10 + 2] + ax * rgb[o11 + 2]);
        /* The zero-direction select is on the factor, not the result: a select on the result
         * lets the compiler move the texel loads under it, and masked gathers do not vectorise. */
        vec3 k = zero ? v3s(0.0f) : scale;
        r[i] = cr * k.x;
        g[i] = cg * k.y;
        b[i] = cb * k.z;
    }
}
