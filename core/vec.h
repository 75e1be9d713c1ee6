/* vec.h - small inline vector maths for reflcheck.
 *
 * Usage:
 *   vec3 n = v3_norm(v3(0, 1, 1));     float vectors for the shading models (GPU-like)
 *   dvec3 d = dv3_norm(dv3(0, 1, 1));  double vectors for the exact references
 * Every function is pure and returns by value. v3_norm of a zero-length vector
 * returns the zero vector (callers guard degenerate input before normalising).
 * Convention (whole project): directions point away from the surface point.
 */
#ifndef REFLCHECK_VEC_H
#define REFLCHECK_VEC_H

#include <math.h>

typedef struct {
    float x, y, z;
} vec3;
typedef struct {
    double x, y, z;
} dvec3;

static inline vec3 v3(float x, float y, float z)
{
    vec3 r = {x, y, z};
    return r;
}
static inline vec3 v3s(float s) { return v3(s, s, s); }
static inline vec3 v3_add(vec3 a, vec3 b) { return v3(a.x + b.x, a.y + b.y, a.z + b.z); }
static inline vec3 v3_sub(vec3 a, vec3 b) { return v3(a.x - b.x, a.y - b.y, a.z - b.z); }
static inline vec3 v3_mul(vec3 a, vec3 b) { return v3(a.x * b.x, a.y * b.y, a.z * b.z); }
static inline vec3 v3_scale(vec3 a, float s) { return v3(a.x * s, a.y * s, a.z * s); }
static inline vec3 v3_madd(vec3 a, vec3 b, float s) { return v3(a.x + b.x * s, a.y + b.y * s, a.z + b.z * s); }
static inline vec3 v3_neg(vec3 a) { return v3(-a.x, -a.y, -a.z); }
static inline float v3_dot(vec3 a, vec3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
static inline vec3 v3_cross(vec3 a, vec3 b)
{
    return v3(a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x);
}
static inline float v3_len(vec3 a) { return sqrtf(v3_dot(a, a)); }
static inline vec3 v3_norm(vec3 a)
{
    float l = v3_len(a);
    return l > 0.0f ? v3_scale(a, 1.0f / l) : v3s(0.0f);
}
static inline vec3 v3_lerp(vec3 a, vec3 b, float t) { return v3_add(a, v3_scale(v3_sub(b, a), t)); }
static inline float v3_max_comp(vec3 a) { return fmaxf(a.x, fmaxf(a.y, a.z)); }
static inline float v3_sum(vec3 a) { return a.x + a.y + a.z; }
/* Exactly zero in every channel: a colour that switches a term off, as written, not within a tolerance. */
static inline int v3_nonzero(vec3 a) { return a.x != 0.0f || a.y != 0.0f || a.z != 0.0f; }
/* Mirror of d about unit n, with d pointing away from the surface: 2(n.d)n - d. */
static inline vec3 v3_reflect(vec3 d, vec3 n) { return v3_sub(v3_scale(n, 2.0f * v3_dot(n, d)), d); }

static inline dvec3 dv3(double x, double y, double z)
{
    dvec3 r = {x, y, z};
    return r;
}
static inline dvec3 dv3_from(vec3 a) { return dv3(a.x, a.y, a.z); }
static inline vec3 v3_from_d(dvec3 a) { return v3((float)a.x, (float)a.y, (float)a.z); }
static inline dvec3 dv3_add(dvec3 a, dvec3 b) { return dv3(a.x + b.x, a.y + b.y, a.z + b.z); }
static inline dvec3 dv3_sub(dvec3 a, dvec3 b) { return dv3(a.x - b.x, a.y - b.y, a.z - b.z); }
static inline dvec3 dv3_mul(dvec3 a, dvec3 b) { return dv3(a.x * b.x, a.y * b.y, a.z * b.z); }
static inline dvec3 dv3_scale(dvec3 a, double s) { return dv3(a.x * s, a.y * s, a.z * s); }
static inline double dv3_dot(dvec3 a, dvec3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
static inline dvec3 dv3_cross(dvec3 a, dvec3 b)
{
    return dv3(a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x);
}
static inline double dv3_len(dvec3 a) { return sqrt(dv3_dot(a, a)); }
static inline dvec3 dv3_norm(dvec3 a)
{
    double l = dv3_len(a);
    return l > 0.0 ? dv3_scale(a, 1.0 / l) : dv3(0, 0, 0);
}

#endif
