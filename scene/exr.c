/* exr.c - OpenEXR reading and writing through the OpenEXRCore C API (see exr.h).
 *
 * Write: one scanline part, ZIP (zlib level 1), 32-bit float channels, string attributes; the
 * chunks compressed on every core and written in order.
 * Read: part 0 of any scanline or tiled file (level 0 only), half/float/uint channels
 * converted to float, the data window as the image, every string attribute.
 * OpenEXRCore before 3.1.10 cannot decompress DWAA/DWAB (openexr issue #1384; Debian 12 ships
 * 3.1.5), so such files are first converted to float ZIP by OpenImageIO's oiiotool (a project
 * dependency) in a private temporary directory; the attributes still come from the original.
 * The library reports details through an error callback; we keep its last message and
 * fold it into our one-line error so a corrupt file says what the library found. The callback
 * finds that message through a thread-local pointer, never through exr_get_user_data: the
 * library calls it while holding the context's lock (e.g. inside exr_write_header on a full
 * disk), and exr_get_user_data takes the same lock, which hung `render -o /dev/full` forever.
 * Files go through our own descriptors (custom read and write streams): inputs are opened by
 * fileio_open_input (regular files only, so a FIFO never blocks), outputs are a temporary file
 * next to the destination, renamed over it only when complete.
 */
#define _POSIX_C_SOURCE 200809L
#include "exr.h"

#include <errno.h>
#include <fcntl.h>
#include <inttypes.h>
#include <limits.h>
#include <pthread.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include <openexr.h>

#include "fileio.h"
#include "runner.h"

extern char **environ;

/* Guard against a corrupt header asking for an absurd allocation: 1 << 15 per side is
 * larger than any render this project makes (and than 8K video), and the product cap
 * keeps one channel under 1 GiB of floats. */
#define EXR_MAX_SIDE    (1 << 15)
#define EXR_MAX_PIXELS  ((size_t)1 << 28)
/* zlib's fastest level for the ZIP chunks. Float renders hardly compress past 2:1 at any level;
 * on a 1024^2 render's 25 layers (104.9 MB) level 1 took 1.23 s of CPU against 1.63 s at zlib's
 * default level 6, for 52.3 MB against 51.5 MB (1.5 % larger). Same format, same pixels. */
#define EXR_ZIP_LEVEL   1
/* Compression threads of one write, at most: past the cores of a workstation the writer's
 * one pwrite per chunk, not compression, is the limit. */
#define EXR_MAX_THREADS 32

typedef struct {
    char msg[256];
} exr_errctx;

/* The message buffer of the exr_read or exr_write running on this thread (NULL outside). */
static _Thread_local exr_errctx *exr_sink;

static void exr_on_error(exr_const_context_t ctxt, exr_result_t code, const char *msg)
{
    (void)ctxt;
    (void)code;
    if (exr_sink != NULL)
        snprintf(exr_sink->msg, sizeof exr_sink->msg, "%s", msg ? msg : "");
}

/* The open file behind a custom stream. */
typedef struct {
    int fd;
    int64_t size;
} exr_stream;

static int64_t exr_stream_read(exr_const_context_t ctxt, void *ud, void *buffer, uint64_t sz, uint64_t offset,
                               exr_stream_error_func_ptr_t error_cb)
{
    const exr_stream *f = ud;
    uint64_t done = 0;
    while (done < sz) {
        ssize_t n = pread(f->fd, (char *)buffer + done, (size_t)(sz - done), (off_t)(offset + done));
        if (n < 0 && errno == EINTR)
            continue;
        if (n < 0) {
            error_cb(ctxt, EXR_ERR_READ_IO, "read of %" PRIu64 " bytes at %" PRIu64 " failed: %s", sz, offset,
                     strerror(errno));
            return -1;
        }
        if (n == 0)
            break;
        done += (uint64_t)n;
    }
    return (int64_t)done;
}

static int64_t exr_stream_size(exr_const_context_t ctxt, void *ud)
{
    (void)ctxt;
    return ((const exr_stream *)ud)->size;
}

static int64_t exr_stream_write(exr_const_context_t ctxt, void *ud, const void *buffer, uint64_t sz, uint64_t offset,
                                exr_stream_error_func_ptr_t error_cb)
{
    const exr_stream *f = ud;
    uint64_t done = 0;
    while (done < sz) {
        ssize_t n = pwrite(f->fd, (const char *)buffer + done, (size_t)(sz - done), (off_t)(offset + done));
        if (n < 0 && errno == EINTR)
            continue;
        if (n <= 0) {
            error_cb(ctxt, EXR_ERR_WRITE_IO, "write of %" PRIu64 " bytes failed: %s", sz,
                     n < 0 ? strerror(errno) : "nothing written");
            return -1;
        }
        done += (uint64_t)n;
    }
    return (int64_t)done;
}

/* The library's own message when it gave one, else its generic text for the code. */
static const char *lib_msg(const exr_errctx *e, exr_result_t rv)
{
    return e->msg[0] ? e->msg : exr_get_default_error_message(rv);
}

/* exr_read has already opened the file, so a short read there means a truncated file:
 * a parse error, not an I/O one. */
static rc_status status_of(exr_result_t rv)
{
    switch (rv) {
    case EXR_ERR_OUT_OF_MEMORY: return RC_ERR_NOMEM;
    case EXR_ERR_FILE_ACCESS:
    case EXR_ERR_WRITE_IO: return RC_ERR_IO;
    default: return RC_ERR_PARSE;
    }
}

/* ---------------------------------------------------------------- write */

static int cmp_channel_name(const void *a, const void *b)
{
    return strcmp(((const exr_channel *)a)->name, ((const exr_channel *)b)->name);
}

/* The arguments of a write: the size, each channel's name and data, the attribute list. */
static rc_status exr_write_check(const char *path, int width, int height, const exr_channel *ch, int n_channels,
                                 const exr_attr *attrs, int n_attrs, char *err, size_t errlen)
{
    if (width <= 0 || height <= 0 || width > EXR_MAX_SIDE || height > EXR_MAX_SIDE) {
        status_message(err, errlen, "%s: cannot write a %dx%d EXR; give a size between 1 and %d per side", path, width,
                       height, EXR_MAX_SIDE);
        return RC_ERR_RANGE;
    }
    if (n_channels <= 0 || !ch) {
        status_message(err, errlen, "%s: no channels to write; pass at least one exr_channel", path);
        return RC_ERR_RANGE;
    }
    if (n_attrs < 0 || (n_attrs > 0 && !attrs)) {
        status_message(err, errlen, "%s: attribute list is NULL but n_attrs = %d", path, n_attrs);
        return RC_ERR_RANGE;
    }
    for (int i = 0; i < n_channels; i++) {
        if (!ch[i].name || !ch[i].name[0] || !ch[i].data) {
            status_message(err, errlen, "%s: channel %d has no name or no data; fill both", path, i);
            return RC_ERR_RANGE;
        }
        if (strlen(ch[i].name) >= EXR_NAME_MAX) {
            status_message(err, errlen, "%s: channel name '%s' is longer than %d characters; shorten it", path,
                           ch[i].name, EXR_NAME_MAX - 1);
            return RC_ERR_RANGE;
        }
    }
    return RC_OK;
}

/* EXR needs the channel list sorted by name: a sorted copy in *out (the caller frees it),
 * refusing duplicates, which the format cannot store. */
static rc_status exr_write_sorted(const char *path, const exr_channel *ch, int n_channels, exr_channel **out, char *err,
                                  size_t errlen)
{
    exr_channel *sorted = malloc((size_t)n_channels * sizeof *sorted);
    if (!sorted) {
        status_message(err, errlen, "%s: out of memory", path);
        return RC_ERR_NOMEM;
    }
    memcpy(sorted, ch, (size_t)n_channels * sizeof *sorted);
    qsort(sorted, (size_t)n_channels, sizeof *sorted, cmp_channel_name);
    for (int i = 1; i < n_channels; i++)
        if (strcmp(sorted[i - 1].name, sorted[i].name) == 0) {
            status_message(err, errlen, "%s: channel '%s' given twice; channel names must be unique", path,
                           sorted[i].name);
            free(sorted);
            return RC_ERR_RANGE;
        }
    *out = sorted;
    return RC_OK;
}

/* The header: one scanline part (ZIP), the channels as float, the string attributes. A bad
 * attribute is refused here with its own message (*st); a library failure is returned with the
 * step in *stage. */
static exr_result_t exr_write_head(exr_context_t ctxt, exr_errctx *ec, const char *path, int width, int height,
                                   const exr_channel *sorted, int n_channels, const exr_attr *attrs, int n_attrs,
                                   int zip_level, const char **stage, rc_status *st, char *err, size_t errlen)
{
    int part = 0;
    *stage = "add part";
    exr_result_t rv = exr_add_part(ctxt, NULL, EXR_STORAGE_SCANLINE, &part);
    if (rv == EXR_ERR_SUCCESS) {
        *stage = "required attributes";
        rv = exr_initialize_required_attr_simple(ctxt, part, width, height, EXR_COMPRESSION_ZIP);
    }
    if (rv == EXR_ERR_SUCCESS) {
        *stage = "zip level";
        rv = exr_set_zip_compression_level(ctxt, part, zip_level != 0 ? zip_level : EXR_ZIP_LEVEL);
    }
    for (int i = 0; rv == EXR_ERR_SUCCESS && i < n_channels; i++) {
        *stage = "add channel";
        rv = exr_add_channel(ctxt, part, sorted[i].name, EXR_PIXEL_FLOAT, EXR_PERCEPTUALLY_LINEAR, 1, 1);
    }
    for (int i = 0; rv == EXR_ERR_SUCCESS && i < n_attrs; i++) {
        *stage = "string attribute";
        if (!attrs[i].name || !attrs[i].name[0] || !attrs[i].value) {
            status_message(err, errlen, "%s: attribute %d has no name or value; fill both", path, i);
            *st = RC_ERR_RANGE;
            return rv;
        }
        rv = exr_attr_set_string(ctxt, part, attrs[i].name, attrs[i].value);
        if (rv != EXR_ERR_SUCCESS) {
            status_message(err, errlen,
                           "%s: cannot set string attribute '%s' (%s); use a name that is not a "
                           "standard EXR attribute",
                           path, attrs[i].name, lib_msg(ec, rv));
            *st = RC_ERR_RANGE;
            return rv;
        }
    }
    if (rv == EXR_ERR_SUCCESS) {
        *stage = "write header";
        rv = exr_write_header(ctxt);
    }
    return rv;
}

/* The pixels. ZIP (zlib) compression is most of a write's time (half of a 1024^2 render's
 * CPU time, measured), and OpenEXRCore compresses each chunk on its own, outside the context's
 * lock, so chunks are compressed on several threads; the file is still written one chunk after
 * another in increasing y, as the part's line order requires, so its bytes are those of a
 * one-thread write. Each pipeline's write step only keeps a copy of its chunk; the calling
 * thread writes the kept chunks in order, and compresses chunks itself while it waits. Workers
 * stay within a window of chunks ahead of the writer, so memory stays a few chunks whatever
 * the image size. */
typedef struct {
    unsigned char *bytes; /* the chunk as it goes into the file */
    size_t size;
    int done;
} exr_chunk_out;

typedef struct {
    exr_context_t ctxt;
    int width, lines, n_chunks, window;
    const exr_channel *sorted;
    int n_channels;
    pthread_mutex_t mu;
    pthread_cond_t cv;
    int next;           /* the next chunk to compress */
    int written;        /* chunks in the file */
    exr_chunk_out *out; /* one per chunk */
    exr_result_t rv;    /* the first failure */
    const char *stage;  /* its step */
    char msg[256];      /* the library's message for it, if any */
} exr_chunk_pool;

/* The pipeline's last step: keeps a copy of the chunk (compressed, or packed when compression
 * would not shrink it: the bytes the library's own write step would write). */
static exr_result_t exr_chunk_keep(exr_encode_pipeline_t *enc)
{
    exr_chunk_out *o = enc->encoding_user_data;
    o->bytes = malloc(enc->compressed_bytes > 0 ? enc->compressed_bytes : 1);
    if (o->bytes == NULL)
        return EXR_ERR_OUT_OF_MEMORY;
    memcpy(o->bytes, enc->compressed_buffer, enc->compressed_bytes);
    o->size = enc->compressed_bytes;
    return EXR_ERR_SUCCESS;
}

/* Packs and compresses chunk i into pool->out[i]. enc is this thread's pipeline, reused from
 * chunk to chunk (*init says whether it is set up). */
static exr_result_t exr_chunk_encode(exr_chunk_pool *pool, int i, exr_encode_pipeline_t *enc, int *init,
                                     const char **stage)
{
    const int part = 0; /* the one part exr_write_head added */
    exr_chunk_info_t cinfo;
    *stage = "chunk info";
    exr_result_t rv = exr_write_scanline_chunk_info(pool->ctxt, part, i * pool->lines, &cinfo);
    if (rv != EXR_ERR_SUCCESS)
        return rv;
    *stage = "encode chunk";
    rv = *init ? exr_encoding_update(pool->ctxt, part, &cinfo, enc)
               : exr_encoding_initialize(pool->ctxt, part, &cinfo, enc);
    if (rv != EXR_ERR_SUCCESS)
        return rv;
    for (int c = 0; c < enc->channel_count; c++) {
        /* The pipeline lists channels in the file's order: matched by name. */
        exr_coding_channel_info_t *ci = &enc->channels[c];
        int k = 0;
        while (k < pool->n_channels - 1 && strcmp(pool->sorted[k].name, ci->channel_name) != 0)
            k++;
        ci->user_pixel_stride = (int32_t)sizeof(float);
        ci->user_line_stride = (int32_t)(sizeof(float) * (size_t)pool->width);
        ci->user_bytes_per_element = (int16_t)sizeof(float);
        ci->user_data_type = EXR_PIXEL_FLOAT;
        ci->encode_from_ptr = (const uint8_t *)(pool->sorted[k].data + (size_t)cinfo.start_y * (size_t)pool->width);
    }
    if (!*init) {
        rv = exr_encoding_choose_default_routines(pool->ctxt, part, enc);
        if (rv != EXR_ERR_SUCCESS)
            return rv;
        *init = 1;
    }
    /* The order check and the write are the writer's (exr_chunk_write_all). */
    enc->yield_until_ready_fn = NULL;
    enc->write_fn = exr_chunk_keep;
    enc->encoding_user_data = &pool->out[i];
    return exr_encoding_run(pool->ctxt, part, enc);
}

/* Takes the next chunk within the window and compresses it; with pool->mu held on entry and
 * on return. 0 when there was none to take. */
static int exr_chunk_take(exr_chunk_pool *pool, exr_encode_pipeline_t *enc, int *init, exr_errctx *ec)
{
    if (pool->rv != EXR_ERR_SUCCESS || pool->next >= pool->n_chunks || pool->next >= pool->written + pool->window)
        return 0;
    int i = pool->next++;
    pthread_mutex_unlock(&pool->mu);
    const char *stage = "encode chunk";
    ec->msg[0] = '\0';
    exr_result_t rv = exr_chunk_encode(pool, i, enc, init, &stage);
    pthread_mutex_lock(&pool->mu);
    if (rv != EXR_ERR_SUCCESS && pool->rv == EXR_ERR_SUCCESS) {
        pool->rv = rv;
        pool->stage = stage;
        snprintf(pool->msg, sizeof pool->msg, "%s", ec->msg);
    }
    pool->out[i].done = 1;
    pthread_cond_broadcast(&pool->cv);
    return 1;
}

static void *exr_chunk_worker(void *arg)
{
    exr_chunk_pool *pool = arg;
    exr_encode_pipeline_t enc = EXR_ENCODE_PIPELINE_INITIALIZER;
    int init = 0;
    exr_errctx ec = {{0}};
    exr_sink = &ec; /* this thread's library messages */
    pthread_mutex_lock(&pool->mu);
    while (pool->rv == EXR_ERR_SUCCESS && pool->next < pool->n_chunks)
        if (!exr_chunk_take(pool, &enc, &init, &ec))
            pthread_cond_wait(&pool->cv, &pool->mu);
    pthread_mutex_unlock(&pool->mu);
    if (init)
        exr_encoding_destroy(pool->ctxt, &enc);
    return NULL;
}

/* The writer: chunk after chunk in increasing y, compressing while the next is not ready. */
static exr_result_t exr_chunk_write_all(exr_chunk_pool *pool, exr_errctx *ec, const char **stage)
{
    exr_encode_pipeline_t enc = EXR_ENCODE_PIPELINE_INITIALIZER;
    int init = 0;
    exr_result_t rv = EXR_ERR_SUCCESS;
    for (int i = 0; i < pool->n_chunks && rv == EXR_ERR_SUCCESS; i++) {
        pthread_mutex_lock(&pool->mu);
        while (!pool->out[i].done && pool->rv == EXR_ERR_SUCCESS)
            if (!exr_chunk_take(pool, &enc, &init, ec))
                pthread_cond_wait(&pool->cv, &pool->mu);
        rv = pool->rv;
        pthread_mutex_unlock(&pool->mu);
        if (rv != EXR_ERR_SUCCESS)
            break;
        *stage = "write chunk";
        rv = exr_write_scanline_chunk(pool->ctxt, 0, i * pool->lines, pool->out[i].bytes, pool->out[i].size);
        free(pool->out[i].bytes);
        pool->out[i].bytes = NULL;
        pthread_mutex_lock(&pool->mu);
        if (rv != EXR_ERR_SUCCESS && pool->rv == EXR_ERR_SUCCESS)
            pool->rv = rv;
        pool->written = i + 1;
        pthread_cond_broadcast(&pool->cv);
        pthread_mutex_unlock(&pool->mu);
    }
    if (init)
        exr_encoding_destroy(pool->ctxt, &enc);
    if (rv == EXR_ERR_SUCCESS && pool->rv != EXR_ERR_SUCCESS) {
        /* A worker's failure: its step and message. */
        rv = pool->rv;
        *stage = pool->stage;
        snprintf(ec->msg, sizeof ec->msg, "%s", pool->msg);
    }
    return rv;
}

/* Chunks compressed on up to `threads` threads (0 = one per online core; the calling thread is
 * one of them), written in order. */
static exr_result_t exr_write_chunks(exr_context_t ctxt, exr_errctx *ec, int width, int height,
                                     const exr_channel *sorted, int n_channels, int threads, const char **stage)
{
    int lines = 1;
    *stage = "scanlines per chunk";
    exr_result_t rv = exr_get_scanlines_per_chunk(ctxt, 0, &lines);
    if (rv != EXR_ERR_SUCCESS)
        return rv;
    exr_chunk_pool pool = {.ctxt = ctxt,
                           .width = width,
                           .lines = lines,
                           .n_chunks = (height + lines - 1) / lines,
                           .sorted = sorted,
                           .n_channels = n_channels};
    if (threads <= 0) {
        long n = sysconf(_SC_NPROCESSORS_ONLN);
        threads = n < 1 ? 1 : n > EXR_MAX_THREADS ? EXR_MAX_THREADS : (int)n;
    }
    if (threads > pool.n_chunks)
        threads = pool.n_chunks;
    /* Two chunks in flight per thread: one being compressed, one done and waiting for the
     * writer, so a thread seldom waits for the writer. */
    pool.window = 2 * threads;
    pool.out = calloc((size_t)pool.n_chunks, sizeof *pool.out);
    if (pool.out == NULL)
        return EXR_ERR_OUT_OF_MEMORY;
    pthread_mutex_init(&pool.mu, NULL);
    pthread_cond_init(&pool.cv, NULL);
    pthread_t tid[EXR_MAX_THREADS];
    int started = 0;
    /* A thread that cannot start leaves its chunks to the others (the writer compresses too). */
    while (started < threads - 1 && pthread_create(&tid[started], NULL, exr_chunk_worker, &pool) == 0)
        started++;
    rv = exr_chunk_write_all(&pool, ec, stage);
    pthread_mutex_lock(&pool.mu);
    if (pool.rv == EXR_ERR_SUCCESS && rv != EXR_ERR_SUCCESS)
        pool.rv = rv; /* stops the workers */
    pthread_cond_broadcast(&pool.cv);
    pthread_mutex_unlock(&pool.mu);
    for (int t = 0; t < started; t++)
        pthread_join(tid[t], NULL);
    for (int i = 0; i < pool.n_chunks; i++)
        free(pool.out[i].bytes);
    free(pool.out);
    pthread_cond_destroy(&pool.cv);
    pthread_mutex_destroy(&pool.mu);
    return rv;
}

/* Writes the image into the open stream out; path names it in messages. */
static rc_status exr_write_stream(const char *path, exr_stream *out, exr_errctx *ec, int width, int height,
                                  const exr_channel *ch, int n_channels, const exr_attr *attrs, int n_attrs,
                                  const exr_write_options *opt, char *err, size_t errlen)
{
    exr_channel *sorted = NULL;
    rc_status st = exr_write_check(path, width, height, ch, n_channels, attrs, n_attrs, err, errlen);
    if (st == RC_OK)
        st = exr_write_sorted(path, ch, n_channels, &sorted, err, errlen);
    if (st != RC_OK)
        return st;

    exr_context_initializer_t init = EXR_DEFAULT_CONTEXT_INITIALIZER;
    init.error_handler_fn = exr_on_error;
    init.user_data = out;
    init.write_fn = exr_stream_write;
    exr_context_t ctxt = NULL;
    exr_result_t rv = exr_start_write(&ctxt, path, EXR_WRITE_FILE_DIRECTLY, &init);
    if (rv != EXR_ERR_SUCCESS) {
        status_message(err, errlen, "%s: cannot start the EXR (%s); check free memory", path, lib_msg(ec, rv));
        free(sorted);
        if (ctxt)
            exr_finish(&ctxt);
        return RC_ERR_IO;
    }

    const char *stage = "add part";
    rv = exr_write_head(ctxt, ec, path, width, height, sorted, n_channels, attrs, n_attrs, opt->zip_level, &stage, &st,
                        err, errlen);
    if (st == RC_OK && rv == EXR_ERR_SUCCESS)
        rv = exr_write_chunks(ctxt, ec, width, height, sorted, n_channels, opt->threads, &stage);
    if (rv != EXR_ERR_SUCCESS && st == RC_OK) {
        status_message(err, errlen, "%s: EXR write failed at %s (%s); check disk space and permissions", path, stage,
                       lib_msg(ec, rv));
        st = rv == EXR_ERR_OUT_OF_MEMORY ? RC_ERR_NOMEM : RC_ERR_IO;
    }
    free(sorted);
    exr_result_t frv = exr_finish(&ctxt);
    if (st == RC_OK && frv != EXR_ERR_SUCCESS) {
        status_message(err, errlen, "%s: EXR write failed while closing (%s); check disk space", path,
                       lib_msg(ec, frv));
        st = RC_ERR_IO;
    }
    return st;
}

rc_status exr_write(const char *path, int width, int height, const exr_channel *ch, int n_channels,
                    const exr_attr *attrs, int n_attrs, char *err, size_t errlen)
{
    const exr_write_options none = {0};
    return exr_write_opt(path, width, height, ch, n_channels, attrs, n_attrs, &none, err, errlen);
}

rc_status exr_write_opt(const char *path, int width, int height, const exr_channel *ch, int n_channels,
                        const exr_attr *attrs, int n_attrs, const exr_write_options *opt, char *err, size_t errlen)
{
    if (!path) {
        status_message(err, errlen, "(null): no file name given to exr_write");
        return RC_ERR_RANGE;
    }
    char target[FILEIO_PATH_MAX], tmp[FILEIO_PATH_MAX];
    int fd = -1;
    rc_status st = fileio_output_target(path, target, sizeof target, err, errlen);
    if (st == RC_OK)
        st = fileio_temp_open(target, tmp, sizeof tmp, &fd, err, errlen);
    if (st != RC_OK)
        return st;
    exr_errctx ec = {{0}};
    exr_errctx *outer = exr_sink;
    exr_sink = &ec;
    exr_stream out = {fd, 0};
    st = exr_write_stream(path, &out, &ec, width, height, ch, n_channels, attrs, n_attrs, opt, err, errlen);
    exr_sink = outer;
    char why[512];
    rc_status fst = fileio_temp_finish(fd, tmp, target, st != RC_OK, why, sizeof why);
    if (st == RC_OK && fst != RC_OK) {
        status_message(err, errlen, "%s", why);
        st = fst;
    }
    return st;
}

/* ---------------------------------------------------------------- read */

void exr_image_free(exr_image *img)
{
    if (!img)
        return;
    if (img->data)
        for (int c = 0; c < img->n_channels; c++)
            free(img->data[c]);
    free(img->data);
    free(img->names);
    free(img->attr_names);
    free(img->attr_values);
    memset(img, 0, sizeof *img);
}

const float *exr_image_channel(const exr_image *img, const char *name)
{
    if (!img || !name)
        return NULL;
    for (int c = 0; c < img->n_channels; c++)
        if (strcmp(img->names[c], name) == 0)
            return img->data[c];
    return NULL;
}

const char *exr_image_attr(const exr_image *img, const char *name)
{
    if (!img || !name)
        return NULL;
    for (int a = 0; a < img->n_attrs; a++)
        if (strcmp(img->attr_names[a], name) == 0)
            return img->attr_values[a];
    return NULL;
}

/* Decode one chunk (scanline block or tile) whose top-left pixel is (x0, y0) in image
 * coordinates into the per-channel float planes. */
static exr_result_t decode_chunk(exr_const_context_t ctxt, int part, const exr_chunk_info_t *cinfo, int x0, int y0,
                                 exr_image *img)
{
    exr_decode_pipeline_t dec = EXR_DECODE_PIPELINE_INITIALIZER;
    exr_result_t rv = exr_decoding_initialize(ctxt, part, cinfo, &dec);
    if (rv != EXR_ERR_SUCCESS) {
        exr_decoding_destroy(ctxt, &dec);
        return rv;
    }
    /* The chunk must lie inside the image or the writes below would overrun the planes. */
    if (x0 < 0 || y0 < 0 || cinfo->width < 0 || cinfo->height < 0 || x0 + cinfo->width > img->width ||
        y0 + cinfo->height > img->height || dec.channel_count != img->n_channels) {
        exr_decoding_destroy(ctxt, &dec);
        return EXR_ERR_CORRUPT_CHUNK;
    }
    for (int c = 0; c < dec.channel_count; c++) {
        exr_coding_channel_info_t *ci = &dec.channels[c];
        if (ci->width != cinfo->width || ci->height != cinfo->height) {
            exr_decoding_destroy(ctxt, &dec);
            return EXR_ERR_CORRUPT_CHUNK;
        }
        ci->user_pixel_stride = (int32_t)sizeof(float);
        ci->user_line_stride = (int32_t)(sizeof(float) * (size_t)img->width);
        ci->user_bytes_per_element = (int16_t)sizeof(float);
        ci->user_data_type = EXR_PIXEL_FLOAT;
        ci->decode_to_ptr = (uint8_t *)(img->data[c] + (size_t)y0 * (size_t)img->width + (size_t)x0);
    }
    rv = exr_decoding_choose_default_routines(ctxt, part, &dec);
    if (rv == EXR_ERR_SUCCESS)
        rv = exr_decoding_run(ctxt, part, &dec);
    exr_decoding_destroy(ctxt, &dec);
    return rv;
}

static rc_status read_pixels(exr_context_t ctxt, int part, exr_storage_t storage, exr_attr_box2i_t dw, exr_image *img,
                             const char **stage, exr_result_t *rvout)
{
    exr_result_t rv = EXR_ERR_SUCCESS;
    if (storage == EXR_STORAGE_SCANLINE) {
        int lines = 0;
        *stage = "scanlines per chunk";
        rv = exr_get_scanlines_per_chunk(ctxt, part, &lines);
        if (rv == EXR_ERR_SUCCESS && lines <= 0)
            rv = EXR_ERR_INVALID_ATTR;
        /* Chunk y positions are in data-window coordinates and start at its top. */
        for (int y = dw.min.y; rv == EXR_ERR_SUCCESS && y <= dw.max.y; y += lines) {
            exr_chunk_info_t cinfo;
            *stage = "scanline chunk";
            rv = exr_read_scanline_chunk_info(ctxt, part, y, &cinfo);
            if (rv == EXR_ERR_SUCCESS)
                rv = decode_chunk(ctxt, part, &cinfo, 0, cinfo.start_y - dw.min.y, img);
        }
    } else {
        uint32_t tw = 0, th = 0;
        exr_tile_level_mode_t lm;
        exr_tile_round_mode_t rm;
        *stage = "tile description";
        rv = exr_get_tile_descriptor(ctxt, part, &tw, &th, &lm, &rm);
        if (rv == EXR_ERR_SUCCESS && (tw == 0 || th == 0))
            rv = EXR_ERR_INVALID_ATTR;
        int ntx = rv == EXR_ERR_SUCCESS ? (int)(((uint32_t)img->width + tw - 1) / tw) : 0;
        int nty = rv == EXR_ERR_SUCCESS ? (int)(((uint32_t)img->height + th - 1) / th) : 0;
        for (int ty = 0; rv == EXR_ERR_SUCCESS && ty < nty; ty++)
            for (int tx = 0; rv == EXR_ERR_SUCCESS && tx < ntx; tx++) {
                exr_chunk_info_t cinfo;
                *stage = "tile chunk";
                rv = exr_read_tile_chunk_info(ctxt, part, tx, ty, 0, 0, &cinfo);
                if (rv == EXR_ERR_SUCCESS)
                    rv = decode_chunk(ctxt, part, &cinfo, tx * (int)tw, ty * (int)th, img);
            }
    }
    *rvout = rv;
    return rv == EXR_ERR_SUCCESS ? RC_OK : status_of(rv);
}

static rc_status read_attrs(exr_context_t ctxt, int part, exr_image *img)
{
    int32_t count = 0;
    if (exr_get_attribute_count(ctxt, part, &count) != EXR_ERR_SUCCESS || count <= 0)
        return RC_OK;
    img->attr_names = calloc((size_t)count, sizeof *img->attr_names);
    img->attr_values = calloc((size_t)count, sizeof *img->attr_values);
    if (!img->attr_names || !img->attr_values)
        return RC_ERR_NOMEM;
    for (int32_t i = 0; i < count; i++) {
        const exr_attribute_t *a = NULL;
        if (exr_get_attribute_by_index(ctxt, part, EXR_ATTR_LIST_FILE_ORDER, i, &a) != EXR_ERR_SUCCESS || !a ||
            a->type != EXR_ATTR_STRING || !a->string || !a->name)
            continue;
        /* Names that do not fit the fixed slot are skipped rather than truncated, so a
         * lookup can never match the wrong attribute; long values are truncated. */
        if (strlen(a->name) >= EXR_NAME_MAX)
            continue;
        snprintf(img->attr_names[img->n_attrs], EXR_NAME_MAX, "%s", a->name);
        int len = a->string->length;
        if (len < 0)
            len = 0;
        if (len > (int)sizeof img->attr_values[0] - 1)
            len = (int)sizeof img->attr_values[0] - 1;
        if (a->string->str)
            memcpy(img->attr_values[img->n_attrs], a->string->str, (size_t)len);
        img->attr_values[img->n_attrs][len] = '\0';
        img->n_attrs++;
    }
    return RC_OK;
}

/* Converts through oiiotool, run as its own process with a time limit (core/runner.h). */
static int run_oiiotool_convert(const char *in, const char *out)
{
    const char *argv[] = {"oiiotool", in, "-d", "float", "--compression", "zip", "-o", out, NULL};
    runner_result r;
    return runner_exec(argv, 120.0, NULL, &r) == RUNNER_OK ? 0 : -1;
}

/* Read a DWA-compressed file through an oiiotool conversion; attributes are taken from the
 * original header (ctxt) so oiiotool's own additions do not leak into the image. */
static rc_status read_via_oiiotool(const char *path, exr_context_t ctxt, exr_image *img, char *err, size_t errlen)
{
    char dir[] = "/tmp/reflcheck_exr_XXXXXX";
    if (!mkdtemp(dir)) {
        status_message(err, errlen, "%s: DWA-compressed EXR needs a temporary directory (%s); check /tmp", path,
                       strerror(errno));
        return RC_ERR_IO;
    }
    char tmp[sizeof dir + 16];
    snprintf(tmp, sizeof tmp, "%s/conv.exr", dir);
    rc_status st;
    if (run_oiiotool_convert(path, tmp) != 0) {
        status_message(err, errlen,
                       "%s: DWA-compressed EXR could not be converted by oiiotool; install "
                       "openimageio-tools or re-save the file with ZIP compression",
                       path);
        st = RC_ERR_PARSE;
    } else {
        char sub[256];
        st = exr_read(tmp, img, sub, sizeof sub);
        if (st != RC_OK) {
            status_message(err, errlen,
                           "%s: DWA-compressed EXR unreadable after conversion (%s); re-save it "
                           "with ZIP compression",
                           path, sub);
        } else {
            free(img->attr_names);
            free(img->attr_values);
            img->attr_names = NULL;
            img->attr_values = NULL;
            img->n_attrs = 0;
            st = read_attrs(ctxt, 0, img);
            if (st != RC_OK) {
                status_message(err, errlen, "%s: out of memory reading EXR attributes", path);
                exr_image_free(img);
            }
        }
    }
    remove(tmp);
    rmdir(dir);
    return st;
}

/* The most decoded bytes one byte of a compressed chunk can give, per compression: RLE codes a
 * run of at most 128 bytes in 2; ZIP is deflate (a 258-byte match in 2 bits: 1032); PIZ's
 * Huffman run code gives 256 16-bit values in 10 bits (410), under deflate's bound, which is used;
 * PXR24 deflates floats cut to 24 bits (1032 x 4/3); B44A codes a flat 4x4 block of halves (32
 * bytes) in 3. DWAA/DWAB are lossy and their AC data run-length coded with no such bound: 0, and
 * only the offset table and the memory limit bound them. */
static double exr_max_ratio(exr_compression_t comp)
{
    switch (comp) {
    case EXR_COMPRESSION_NONE: return 1.0;
    case EXR_COMPRESSION_RLE: return 64.0;
    case EXR_COMPRESSION_ZIPS:
    case EXR_COMPRESSION_ZIP:
    case EXR_COMPRESSION_PIZ: return 1032.0;
    case EXR_COMPRESSION_PXR24: return 1032.0 * 4.0 / 3.0;
    case EXR_COMPRESSION_B44:
    case EXR_COMPRESSION_B44A: return 32.0 / 3.0;
    default: return 0.0;
    }
}

/* Before any plane is allocated (or oiiotool started): the file must hold the offset table (8
 * bytes a chunk) and, within the compression's largest ratio, the samples the data window
 * needs (half 2 bytes, float and uint 4), and the float planes must fit the memory limit. */
static rc_status exr_check_budget(const char *path, exr_const_context_t ctxt, int part, const exr_attr_chlist_t *chl,
                                  int64_t file_bytes, const exr_image *img, char *err, size_t errlen)
{
    double px = (double)img->width * (double)img->height, coded = 0.0;
    for (int c = 0; c < chl->num_channels; c++)
        coded += px * (chl->entries[c].pixel_type == EXR_PIXEL_HALF ? 2.0 : 4.0);
    exr_compression_t comp = EXR_COMPRESSION_NONE;
    int32_t chunks = 0;
    exr_get_compression(ctxt, part, &comp);
    exr_get_chunk_count(ctxt, part, &chunks);
    double ratio = exr_max_ratio(comp), min_bytes = 8.0 * chunks;
    if (ratio > 0.0 && coded / ratio > min_bytes)
        min_bytes = coded / ratio;
    return fileio_image_budget(path, "OpenEXR", img->width, img->height, min_bytes, (long long)file_bytes,
                               px * chl->num_channels * sizeof(float), err, errlen);
}

/* Opens the EXR on in for reading, sides bounded by EXR_MAX_SIDE before anything is allocated. */
static rc_status exr_read_open(const char *path, exr_stream *in, exr_errctx *ec, exr_context_t *ctxt, char *err,
                               size_t errlen)
{
    exr_context_initializer_t init = EXR_DEFAULT_CONTEXT_INITIALIZER;
    init.error_handler_fn = exr_on_error;
    init.user_data = in;
    init.read_fn = exr_stream_read;
    init.size_fn = exr_stream_size;
    init.max_image_width = EXR_MAX_SIDE;
    init.max_image_height = EXR_MAX_SIDE;
    init.max_tile_width = EXR_MAX_SIDE;
    init.max_tile_height = EXR_MAX_SIDE;
    *ctxt = NULL;
    exr_result_t rv = exr_start_read(ctxt, path, &init);
    if (rv != EXR_ERR_SUCCESS) {
        rc_status st = status_of(rv);
        status_message(err, errlen,
                       "%s: not an OpenEXR file, or its header is truncated or damaged (%s); "
                       "re-render or re-export it",
                       path, lib_msg(ec, rv));
        if (*ctxt)
            exr_finish(ctxt);
        return st;
    }
    return RC_OK;
}

/* Each channel full resolution, with a name that fits EXR_NAME_MAX. */
static rc_status exr_read_check_channels(const char *path, const exr_attr_chlist_t *chl, char *err, size_t errlen)
{
    if (chl->num_channels <= 0) {
        status_message(err, errlen, "%s: EXR has no channels; write at least R, G, B", path);
        return RC_ERR_PARSE;
    }
    for (int c = 0; c < chl->num_channels; c++) {
        const exr_attr_chlist_entry_t *e = &chl->entries[c];
        if (e->x_sampling != 1 || e->y_sampling != 1) {
            status_message(err, errlen,
                           "%s: channel '%s' is subsampled (%dx%d); only full-resolution channels "
                           "are supported",
                           path, e->name.str, e->x_sampling, e->y_sampling);
            return RC_ERR_PARSE;
        }
        if (e->name.length >= EXR_NAME_MAX) {
            status_message(err, errlen, "%s: channel name '%s' is longer than %d characters; rename the layer", path,
                           e->name.str, EXR_NAME_MAX - 1);
            return RC_ERR_PARSE;
        }
    }
    return RC_OK;
}

/* The header of part 0: a flat (not deep) image, its data window (img's size) and its channels. */
static rc_status exr_read_head(const char *path, exr_context_t ctxt, exr_errctx *ec, exr_storage_t *storage,
                               exr_attr_box2i_t *dw, const exr_attr_chlist_t **chl, exr_image *img, char *err,
                               size_t errlen)
{
    const int part = 0;
    *chl = NULL;
    exr_result_t rv = exr_get_storage(ctxt, part, storage);
    if (rv == EXR_ERR_SUCCESS && *storage != EXR_STORAGE_SCANLINE && *storage != EXR_STORAGE_TILED) {
        status_message(err, errlen, "%s: deep EXR images are not supported; write a flat scanline or tiled image",
                       path);
        return RC_ERR_PARSE;
    }
    if (rv == EXR_ERR_SUCCESS)
        rv = exr_get_data_window(ctxt, part, dw);
    if (rv == EXR_ERR_SUCCESS)
        rv = exr_get_channels(ctxt, part, chl);
    if (rv != EXR_ERR_SUCCESS || !*chl) {
        status_message(err, errlen, "%s: EXR header lacks data window or channel list (%s); re-export the file", path,
                       lib_msg(ec, rv));
        return RC_ERR_PARSE;
    }
    int64_t w = (int64_t)dw->max.x - dw->min.x + 1, h = (int64_t)dw->max.y - dw->min.y + 1;
    if (w <= 0 || h <= 0 || w > EXR_MAX_SIDE || h > EXR_MAX_SIDE || (size_t)(w * h) > EXR_MAX_PIXELS) {
        status_message(err, errlen, "%s: EXR data window (%d,%d)-(%d,%d) is empty or too large; the file is corrupt",
                       path, dw->min.x, dw->min.y, dw->max.x, dw->max.y);
        return RC_ERR_PARSE;
    }
    img->width = (int)w;
    img->height = (int)h;
    return exr_read_check_channels(path, *chl, err, errlen);
}

/* Whether part 0 is DWAA or DWAB compressed (read through oiiotool). */
static int exr_read_is_dwa(exr_const_context_t ctxt)
{
    exr_compression_t comp;
    return exr_get_compression(ctxt, 0, &comp) == EXR_ERR_SUCCESS &&
           (comp == EXR_COMPRESSION_DWAA || comp == EXR_COMPRESSION_DWAB);
}

/* img's channel names and zeroed float planes. */
static rc_status exr_read_planes(const char *path, const exr_attr_chlist_t *chl, exr_image *img, char *err,
                                 size_t errlen)
{
    img->n_channels = chl->num_channels;
    img->names = calloc((size_t)img->n_channels, sizeof *img->names);
    img->data = calloc((size_t)img->n_channels, sizeof *img->data);
    if (!img->names || !img->data) {
        status_message(err, errlen, "%s: out of memory reading EXR", path);
        return RC_ERR_NOMEM;
    }
    for (int c = 0; c < img->n_channels; c++) {
        snprintf(img->names[c], EXR_NAME_MAX, "%s", chl->entries[c].name.str);
        img->data[c] = calloc((size_t)img->width * (size_t)img->height, sizeof(float));
        if (!img->data[c]) {
            status_message(err, errlen, "%s: out of memory for a %dx%d channel", path, img->width, img->height);
            return RC_ERR_NOMEM;
        }
    }
    return RC_OK;
}

/* Reads the EXR open on in (path names it in messages) into img: the header, the budget check,
 * the planes, the pixels, the string attributes. */
static rc_status exr_read_stream(const char *path, exr_stream *in, exr_errctx *ec, exr_image *img, char *err,
                                 size_t errlen)
{
    exr_context_t ctxt;
    rc_status st = exr_read_open(path, in, ec, &ctxt, err, errlen);
    if (st != RC_OK)
        return st;
    const int part = 0;
    exr_storage_t storage;
    exr_attr_box2i_t dw;
    const exr_attr_chlist_t *chl;
    st = exr_read_head(path, ctxt, ec, &storage, &dw, &chl, img, err, errlen);
    if (st == RC_OK)
        st = exr_check_budget(path, ctxt, part, chl, in->size, img, err, errlen);
    if (st == RC_OK && exr_read_is_dwa(ctxt)) {
        img->width = img->height = 0;
        st = read_via_oiiotool(path, ctxt, img, err, errlen);
        exr_finish(&ctxt);
        return st;
    }
    if (st == RC_OK)
        st = exr_read_planes(path, chl, img, err, errlen);
    if (st == RC_OK) {
        const char *stage = "header";
        exr_result_t rv;
        st = read_pixels(ctxt, part, storage, dw, img, &stage, &rv);
        if (st != RC_OK)
            status_message(err, errlen,
                           "%s: EXR pixel data unreadable at %s (%s); the file is truncated or corrupt, "
                           "re-render it",
                           path, stage, lib_msg(ec, rv));
    }
    if (st == RC_OK && (st = read_attrs(ctxt, part, img)) != RC_OK)
        status_message(err, errlen, "%s: out of memory reading EXR attributes", path);
    exr_finish(&ctxt);
    if (st != RC_OK)
        exr_image_free(img);
    return st;
}

rc_status exr_read(const char *path, exr_image *img, char *err, size_t errlen)
{
    if (!img) {
        status_message(err, errlen, "%s: exr_read needs an exr_image to fill", path ? path : "(null)");
        return RC_ERR_RANGE;
    }
    memset(img, 0, sizeof *img);
    if (!path) {
        status_message(err, errlen, "(null): no file name given to exr_read");
        return RC_ERR_IO;
    }
    /* No byte limit on the file: chunks are read by offset, never the whole file, and what
     * is allocated is bounded by the header (EXR_MAX_SIDE, EXR_MAX_PIXELS, memory limit). */
    exr_stream in;
    long long size = 0;
    rc_status st = fileio_open_input(path, LLONG_MAX, "an OpenEXR image", &in.fd, &size, err, errlen);
    if (st != RC_OK)
        return st;
    in.size = (int64_t)size;
    exr_errctx ec = {{0}};
    exr_errctx *outer = exr_sink;
    exr_sink = &ec;
    st = exr_read_stream(path, &in, &ec, img, err, errlen);
    exr_sink = outer;
    close(in.fd);
    return st;
}
