/* image_dds.c - image_oiio.h's functions, through the OpenImageIO plugin loaded at first use.
 *
 * Linking OpenImageIO into the programs made every process start load its 263 shared libraries
 * (0.77 s for `reflcheck renderers` against 0.02 s without), and the tests and the nightly start
 * reflcheck thousands of times. So the C++ shim is a plugin of its own (image_oiio.cpp,
 * reflcheck-oiio.so next to the reflcheck binary, path set at build time; REFLCHECK_OIIO_PLUGIN
 * names another), opened only when a scene reads a DDS. */
#include "image_oiio.h"

#include <dlfcn.h>
#include <pthread.h>
#include <stdlib.h>
#include <string.h>

#include "status.h"

#ifndef REFLCHECK_OIIO_PLUGIN
#define REFLCHECK_OIIO_PLUGIN "reflcheck-oiio.so"
#endif

typedef rc_status (*image_dds_read_fn)(const char *, image_dds_kind, long long, int, image_dds *, char *, size_t);
typedef void (*image_dds_free_fn)(image_dds *);
typedef const char *(*image_oiio_version_fn)(void);

static struct {
    pthread_once_t once;
    image_dds_read_fn read;
    image_dds_free_fn free;
    image_oiio_version_fn version;
    char why[512];
} image_dds_plugin = {.once = PTHREAD_ONCE_INIT};

static void image_dds_open(void)
{
    const char *path = getenv("REFLCHECK_OIIO_PLUGIN");
    if (path == NULL || path[0] == '\0')
        path = REFLCHECK_OIIO_PLUGIN;
    void *h = dlopen(path, RTLD_NOW | RTLD_LOCAL);
    if (h == NULL) {
        const char *e = dlerror();
        status_message(image_dds_plugin.why, sizeof image_dds_plugin.why,
                       "cannot load the DDS reader %s (%s); build it with make, or set REFLCHECK_OIIO_PLUGIN to "
                       "reflcheck-oiio.so",
                       path, e != NULL ? e : "no reason given");
        return;
    }
    /* ISO C has no cast from dlsym's object pointer to a function pointer; POSIX guarantees the
     * representation, so the bytes are copied. */
    void *fn[3] = {dlsym(h, "reflcheck_oiio_read"), dlsym(h, "reflcheck_oiio_free"),
                   dlsym(h, "reflcheck_oiio_version")};
    memcpy(&image_dds_plugin.read, &fn[0], sizeof fn[0]);
    memcpy(&image_dds_plugin.free, &fn[1], sizeof fn[1]);
    memcpy(&image_dds_plugin.version, &fn[2], sizeof fn[2]);
    if (image_dds_plugin.read == NULL || image_dds_plugin.free == NULL || image_dds_plugin.version == NULL) {
        image_dds_plugin.read = NULL;
        status_message(image_dds_plugin.why, sizeof image_dds_plugin.why,
                       "%s is not reflcheck's DDS reader (its entry points are missing); rebuild it with make", path);
    }
}

rc_status image_dds_read(const char *path, image_dds_kind kind, long long max_bytes, int max_side, image_dds *out,
                         char *err, size_t errlen)
{
    *out = (image_dds){0};
    pthread_once(&image_dds_plugin.once, image_dds_open);
    if (image_dds_plugin.read == NULL) {
        status_message(err, errlen, "%s: %s", path, image_dds_plugin.why);
        return RC_ERR_IO;
    }
    return image_dds_plugin.read(path, kind, max_bytes, max_side, out, err, errlen);
}

void image_dds_free(image_dds *d)
{
    /* Only the plugin allocates an image_dds's texels, so without it there is nothing to free. */
    if (image_dds_plugin.free != NULL)
        image_dds_plugin.free(d);
    else
        *d = (image_dds){0};
}

const char *image_oiio_version(void)
{
    pthread_once(&image_dds_plugin.once, image_dds_open);
    return image_dds_plugin.version != NULL ? image_dds_plugin.version() : "(no DDS reader)";
}
