#include "fileio.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

void fileio_temp_name(const char *path, char *buf, size_t len)
{
    snprintf(buf, len, "%s.tmp%ld", path, (long)getpid());
}

rc_status fileio_write_atomic(const char *path, const char *text, char *err, size_t errlen)
{
    char tmp[1100];
    fileio_temp_name(path, tmp, sizeof tmp);
    FILE *f = fopen(tmp, "w");
    int ok = f != NULL && fputs(text, f) >= 0;
    if (f != NULL)
        ok &= fclose(f) == 0;
    if (!ok || rename(tmp, path) != 0) {
        snprintf(err, errlen, "%s: cannot write: %s", path, strerror(errno));
        unlink(tmp);
        return RC_ERR_IO;
    }
    return RC_OK;
}

char *fileio_read_all(const char *path, size_t *len)
{
    FILE *f = fopen(path, "rb");
    if (f == NULL)
        return NULL;
    char *buf = NULL;
    size_t used = 0, cap = 0, n;
    char chunk[8192];
    while ((n = fread(chunk, 1, sizeof chunk, f)) > 0) {
        if (used + n + 1 > cap) {
            cap = (used + n + 1) * 2;
            char *nb = realloc(buf, cap);
            if (nb == NULL) {
                free(buf);
                fclose(f);
                return NULL;
            }
            buf = nb;
        }
        memcpy(buf + used, chunk, n);
        used += n;
    }
    int bad = ferror(f);
    fclose(f);
    if (!bad && buf == NULL)
        buf = malloc(1); /* an empty file is an empty string */
    if (bad || buf == NULL) {
        free(buf);
        return NULL;
    }
    buf[used] = '\0';
    if (len != NULL)
        *len = used;
    return buf;
}

int fileio_copy(const char *from, const char *to)
{
    char tmp[1100];
    fileio_temp_name(to, tmp, sizeof tmp);
    FILE *in = fopen(from, "rb");
    if (in == NULL)
        return -1;
    FILE *out = fopen(tmp, "wb");
    if (out == NULL) {
        fclose(in);
        return -1;
    }
    char buf[65536];
    size_t n;
    int ok = 1;
    while ((n = fread(buf, 1, sizeof buf, in)) > 0)
        ok &= fwrite(buf, 1, n, out) == n;
    ok &= !ferror(in);
    fclose(in);
    ok &= fclose(out) == 0;
    if (!ok || rename(tmp, to) != 0) {
        unlink(tmp);
        return -1;
    }
    return 0;
}
