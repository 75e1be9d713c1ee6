/* render_keep.h - a frame's shading inputs, kept per tile so that render.c can shade the frame
 * again with other material parameters without rasterizing it (render.h: render_options.keep).
 * Internal to render/: render.c records and replays; callers see only render.h's render_keep.
 *
 * Usage (render.c):
 *   render_keep_key key; ... filled from the frame;  render_keep_matches(k, &key)
 *   render_keep_begin(k, &key, n_tiles, bound_of_tile, user)   record: every tile's buffer sized
 *   render_keep_put(&k->tiles[t], &x, sizeof x)                  from the tile's own worker
 *   render_keep_end(k)                                           1: the frame is kept
 *   render_keep_reader r = {&k->tiles[t]}; render_keep_get(&r, &x, sizeof x)   replay, in order
 *   render_keep_run(threads, n_tiles, fn, user)                  fn(user, tile, worker) per tile
 * A tile's buffer is allocated once at its bound (render_keep_tile_bound) before the frame, so the
 * memory render.h's estimate counts is what the keep can hold; it is trimmed to its use after.
 */
#ifndef REFLCHECK_RENDER_KEEP_H
#define REFLCHECK_RENDER_KEEP_H

#include <stdatomic.h>
#include <stddef.h>
#include <string.h>

#include "mesh.h"
#include "render.h"
#include "scene.h"

/* Everything a kept frame's shading inputs depend on besides the materials' parameters: a frame
 * whose key differs in any byte is rendered in full (and kept anew). The mesh and environment
 * are compared by address and size: the caller keeps them unchanged between frames (render.h). */
typedef struct {
    const mesh *m;
    const vec3 *pos, *nrm;
    int n_verts, n_tris;
    const env_map *env;
    const texture_set *tex;
    int width, height, k, tile;
    unsigned term_layers;
    vec3 eye, target, up;
    float hfov;
    int n_lights, n_objects;
    light lights[SCENE_MAX_LIGHTS];
    unsigned char two_sided[SCENE_MAX_OBJECTS], textured[SCENE_MAX_OBJECTS], blend[SCENE_MAX_OBJECTS];
    unsigned char has_length[SCENE_MAX_OBJECTS];
    mesh_normal_length length[SCENE_MAX_OBJECTS];
} render_keep_key;

typedef struct {
    unsigned char *buf;
    size_t len, cap;
    int failed; /* a put went past cap: the frame is not kept */
} render_keep_tile;

struct render_keep {
    int valid; /* the tiles hold a whole frame of key */
    render_keep_key key;
    int n_tiles;
    render_keep_tile *tiles;
    render_keep_stats stats;
    /* Set by a worker given a tile other than the keep's tile at its place (the rasterizer cut the
     * frame otherwise than render.c assumed): that tile is not kept, nor is the frame. */
    atomic_int stray;
};

/* What a tile's buffer holds, in the order the frame made it: per span a SPAN record, then its
 * background and object batches (BLEND: a blended object's, composited over what is there) in
 * flush order, then END with the span's per-pixel figures. */
enum { RENDER_KEEP_SPAN = 1, RENDER_KEEP_BG, RENDER_KEEP_BATCH, RENDER_KEEP_BLEND, RENDER_KEEP_END };

typedef struct {
    const render_keep_tile *t;
    size_t at;
} render_keep_reader;

/* Everything kept freed: nothing to shade again. */
void render_keep_clear(render_keep *k);
/* The key's bytes zeroed before filling, so that padding compares equal. */
void render_keep_key_clear(render_keep_key *key);
int render_keep_matches(const render_keep *k, const render_keep_key *key);
/* Bytes a tile of tw x th pixels at k x k samples, cut into spans, can need (n_objects objects,
 * n_blend of them blended, textured: texture coordinates kept). */
double render_keep_tile_bound(int tw, int th, int k, int spans, int n_objects, int n_blend, int textured);
/* Starts recording a frame of key over n_tiles tiles, each tile's buffer sized by bound(user,
 * tile); RC_ERR_NOMEM (nothing kept) when a buffer cannot be had. */
rc_status render_keep_begin(render_keep *k, const render_keep_key *key, int n_tiles,
                            double (*bound)(void *user, int tile), void *user);
/* The frame's recording done: trimmed; returns 1 when every tile was kept whole. */
int render_keep_end(render_keep *k);
static inline void render_keep_put(render_keep_tile *t, const void *p, size_t n)
{
    if (t->failed || t->len + n > t->cap) {
        t->failed = 1;
        return;
    }
    memcpy(t->buf + t->len, p, n);
    t->len += n;
}
/* The next n bytes into p; 0 at the end of the tile's record. */
static inline int render_keep_get(render_keep_reader *r, void *p, size_t n)
{
    if (r->at + n > r->t->len)
        return 0;
    memcpy(p, r->t->buf + r->at, n);
    r->at += n;
    return 1;
}
/* fn(user, tile, worker) for every tile in [0, n_tiles), on threads workers (tiles taken from a
 * shared counter; a tile's result does not depend on which worker runs it). */
rc_status render_keep_run(int threads, int n_tiles, void (*fn)(void *user, int tile, int worker), void *user);

#endif
