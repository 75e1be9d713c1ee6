#include "env.h"

#include <math.h>
#include <stddef.h>

#define ENV_PI 3.14159265358979323846f

void env_direction_to_texel(const env_map *e, vec3 dir, float *tx, float *ty)
{
    vec3 d = v3_norm(dir);
    /* asinf is only defined on [-1, 1]; rounding in v3_norm can leave y a few ulp outside. */
    float y = fminf(fmaxf(d.y, -1.0f), 1.0f);
    float u = 0.5f + atan2f(d.z, d.x) / (2.0f * ENV_PI);
    float v = 0.5f + asinf(y) / ENV_PI;
    *tx = u * (float)e->width;
    *ty = (1.0f - v) * (float)e->height;
}

static vec3 env_texel(const env_map *e, int x, int y)
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
    if (x0 < 0 || x0 >= e->width) x0 = 0, x1 = e->width > 1 ? 1 : 0;
    vec3 top = v3_lerp(env_texel(e, x0, y0), env_texel(e, x1, y0), ax);
    vec3 bottom = v3_lerp(env_texel(e, x0, y0 + 1), env_texel(e, x1, y0 + 1), ax);
    return v3_mul(v3_lerp(top, bottom, ay), e->scale);
}
