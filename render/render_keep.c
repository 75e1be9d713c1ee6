/* render_keep.c - the kept frame's storage, its key and the worker pool that replays it
 * (render_keep.h); what is kept and how it is shaded again is render.c's. */
#include "render_keep.h"

#include <pthread.h>
#include <stdatomic.h>
#include <stdbool.h>
#include <stdint.h>
#include <stdlib.h>

#include "shade.h"

rc_status render_keep_make(render_keep **out)
{
    *out = calloc(1, sizeof **out);
    if (*out == NULL)
        return RC_ERR_NOMEM;
    (*out)->stats.why = "";
    return RC_OK;
}

void render_keep_clear(render_keep *k)
{
    for (int t = 0; t < k->n_tiles; t++)
        free(k->tiles[t].buf);
    free(k->tiles);
    k->tiles = NULL;
    k->n_tiles = 0;
    k->valid = 0;
    k->stats.bytes = 0.0;
}

void render_keep_free(render_keep *k)
{
    if (k == NULL)
        return;
    render_keep_clear(k);
    free(k);
}

void render_keep_stats_get(const render_keep *k, render_keep_stats *st) { *st = k->stats; }

void render_keep_key_clear(render_keep_key *key) { memset(key, 0, sizeof *key); }

int render_keep_matches(const render_keep *k, const render_keep_key *key)
{
    return k->valid && memcmp(&k->key, key, sizeof *key) == 0;
}

/* Per kept sample: its slot (uint16), x, n and v (9 floats) and, textured, (u, v). A background
 * sample keeps its slot and radiance (3 floats), less than a surface sample. */
#define RENDER_KEEP_SAMPLE(textured) (2.0 + 9.0 * 4.0 + ((textured) ? 8.0 : 0.0))
/* A record's header: a tag and up to four ints (render.c's SPAN; a batch's tag, object, count
 * and textured flag). */
#define RENDER_KEEP_HEADER           (5.0 * 4.0)

double render_keep_tile_bound(int tw, int th, int k, int spans, int n_objects, int n_blend, int textured)
{
    const double samples = (double)tw * th * k * k;
    /* Every sample is in one opaque batch or the background, and in at most one batch of each
     * blended layer. A queue is flushed when full (SHADE_BATCH) and at each span's end (every
     * object and the background; every layer), so batches number at most these. */
    const double batches = (samples / SHADE_BATCH + spans * (n_objects + 1.0)) * (1.0 + n_blend);
    /* Per span: its header, and the end's 5 figures per pixel (covered, object, 3 angles). */
    return samples * RENDER_KEEP_SAMPLE(textured) * (1.0 + n_blend) + batches * RENDER_KEEP_HEADER +
           spans * 2.0 * RENDER_KEEP_HEADER + (double)tw * th * 5.0 * 4.0;
}

rc_status render_keep_begin(render_keep *k, const render_keep_key *key, int n_tiles,
                            double (*bound)(void *user, int tile), void *user)
{
    render_keep_clear(k);
    k->tiles = calloc((size_t)(n_tiles > 0 ? n_tiles : 1), sizeof *k->tiles);
    if (k->tiles == NULL)
        return RC_ERR_NOMEM;
    k->n_tiles = n_tiles;
    for (int t = 0; t < n_tiles; t++) {
        const size_t cap = (size_t)bound(user, t);
        /* Untouched pages of the bound cost no memory until written; the trim gives back the rest. */
        k->tiles[t].buf = malloc(cap > 0 ? cap : 1);
        k->tiles[t].cap = cap;
        if (k->tiles[t].buf == NULL) {
            render_keep_clear(k);
            return RC_ERR_NOMEM;
        }
    }
    k->key = *key;
    atomic_store(&k->stray, 0);
    return RC_OK;
}

int render_keep_end(render_keep *k)
{
    int whole = 1;
    double bytes = 0.0;
    whole &= !atomic_load(&k->stray);
    for (int t = 0; t < k->n_tiles; t++) {
        render_keep_tile *tl = &k->tiles[t];
        whole &= !tl->failed;
        unsigned char *p = realloc(tl->buf, tl->len > 0 ? tl->len : 1);
        if (p != NULL) {
            tl->buf = p;
            tl->cap = tl->len;
        }
        bytes += (double)tl->cap;
    }
    if (!whole) {
        render_keep_clear(k);
        return 0;
    }
    k->valid = 1;
    k->stats.bytes = bytes;
    return 1;
}

typedef struct {
    void (*fn)(void *user, int tile, int worker);
    void *user;
    int n_tiles;
    atomic_int next;
} render_keep_pool;

typedef struct {
    render_keep_pool *pool;
    int worker;
} render_keep_arg;

static void *render_keep_worker(void *arg)
{
    const render_keep_arg *a = arg;
    render_keep_pool *p = a->pool;
    for (int t; (t = atomic_fetch_add(&p->next, 1)) < p->n_tiles;)
        p->fn(p->user, t, a->worker);
    return NULL;
}

rc_status render_keep_run(int threads, int n_tiles, void (*fn)(void *user, int tile, int worker), void *user)
{
    if (threads < 1)
        threads = 1;
    render_keep_pool pool = {.fn = fn, .user = user, .n_tiles = n_tiles};
    atomic_init(&pool.next, 0);
    pthread_t *th = calloc((size_t)threads, sizeof *th);
    render_keep_arg *args = calloc((size_t)threads, sizeof *args);
    bool *started = calloc((size_t)threads, sizeof *started);
    if (th == NULL || args == NULL || started == NULL) {
        free(th);
        free(args);
        free(started);
        return RC_ERR_NOMEM;
    }
    /* Worker 0 is this thread; a worker that could not be started costs only speed (tiles come
     * from the shared counter). */
    for (int i = 0; i < threads; i++) {
        args[i] = (render_keep_arg){&pool, i};
        started[i] = i > 0 && pthread_create(&th[i], NULL, render_keep_worker, &args[i]) == 0;
    }
    render_keep_worker(&args[0]);
    for (int i = 1; i < threads; i++)
        if (started[i])
            pthread_join(th[i], NULL);
    free(th);
    free(args);
    free(started);
    return RC_OK;
}
