/* realpath() is an XSI function in glibc's headers. */
#define _XOPEN_SOURCE 700
#include "fileio.h"

#include <limits.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

int fileio_same_file(const char *a, const char *b)
{
    struct stat sa, sb;
    if (a == NULL || b == NULL || stat(a, &sa) != 0 || stat(b, &sb) != 0)
        return 0;
    return sa.st_dev == sb.st_dev && sa.st_ino == sb.st_ino;
}

rc_status fileio_output_target(const char *path, char *target, size_t len, char *err, size_t errlen)
{
    struct stat st;
    if (lstat(path, &st) != 0) {
        if (errno != ENOENT) {
            status_message(err, errlen, "%s: cannot check the output (%s); give a writable path", path,
                           strerror(errno));
            return RC_ERR_IO;
        }
        if (snprintf(target, len, "%s", path) >= (int)len) {
            status_message(err, errlen, "%s: output path is too long; give a shorter one", path);
            return RC_ERR_RANGE;
        }
        return RC_OK;
    }
    if (S_ISLNK(st.st_mode)) {
        /* Write the file the link points to, so the link stays a link. */
        char resolved[PATH_MAX];
        if (realpath(path, resolved) == NULL) {
            status_message(err, errlen,
                           "%s: the output is a symlink that cannot be followed (%s); give a "
                           "regular file or a new name",
                           path, strerror(errno));
            return RC_ERR_RANGE;
        }
        if (stat(resolved, &st) != 0) {
            status_message(err, errlen, "%s: cannot check the output (%s); give a writable path", path,
                           strerror(errno));
            return RC_ERR_IO;
        }
        if (!S_ISREG(st.st_mode)) {
            status_message(err, errlen,
                           "%s: the output is not a regular file (%s); give a regular file or a "
                           "new name",
                           path, fileio_kind(st.st_mode));
            return RC_ERR_RANGE;
        }
        if (snprintf(target, len, "%s", resolved) >= (int)len) {
            status_message(err, errlen, "%s: output path is too long; give a shorter one", path);
            return RC_ERR_RANGE;
        }
        return RC_OK;
    }
    if (!S_ISREG(st.st_mode)) {
        status_message(err, errlen, "%s: the output is not a regular file (%s); give a regular file or a new name",
                       path, fileio_kind(st.st_mode));
        return RC_ERR_RANGE;
    }
    /* An existing file we may not write stays as it is: renaming over it would bypass its mode. */
    if (access(path, W_OK) != 0) {
        status_message(err, errlen,
                       "%s: the output exists and is not writable (%s); make it writable or give "
                       "another path",
                       path, strerror(errno));
        return RC_ERR_IO;
    }
    if (snprintf(target, len, "%s", path) >= (int)len) {
        status_message(err, errlen, "%s: output path is too long; give a shorter one", path);
        return RC_ERR_RANGE;
    }
    return RC_OK;
}

rc_status fileio_temp_open(const char *target, char *tmp, size_t tmplen, int *fd, char *err, size_t errlen)
{
    /* pid keeps processes apart, the counter threads of one process; O_EXCL makes a stale
     * name from a killed run with a recycled pid a retry instead of a shared file. */
    static atomic_uint counter;
    *fd = -1;
    for (int tries = 0; tries < 100; tries++) {
        unsigned n = atomic_fetch_add(&counter, 1u);
        if (snprintf(tmp, tmplen, "%s.tmp%ld.%u", target, (long)getpid(), n) >= (int)tmplen) {
            status_message(err, errlen, "%s: output path is too long; give a shorter one", target);
            return RC_ERR_RANGE;
        }
        *fd = open(tmp, O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0666);
        if (*fd >= 0)
            return RC_OK;
        if (errno != EEXIST)
            break;
    }
    status_message(err, errlen,
                   "%s: cannot create a temporary file next to it (%s); check the folder exists "
                   "and is writable",
                   target, strerror(errno));
    return RC_ERR_IO;
}

rc_status fileio_temp_finish(int fd, const char *tmp, const char *target, int failed, char *err, size_t errlen)
{
    int e = 0;
    if (fd >= 0 && close(fd) != 0 && !failed) {
        e = errno;
        failed = 1;
        status_message(err, errlen, "%s: write failed on close (%s); check free space", target, strerror(e));
    }
    if (!failed && rename(tmp, target) != 0) {
        e = errno;
        failed = 1;
        status_message(err, errlen,
                       "%s: cannot rename the finished temporary file onto it (%s); check the "
                       "folder is writable",
                       target, strerror(e));
    }
    if (failed) {
        unlink(tmp);
        return RC_ERR_IO;
    }
    return RC_OK;
}

/* Writes n bytes in full; 0 on success, else errno is set. */
static int fileio_write_full(int fd, const char *p, size_t n)
{
    while (n > 0) {
        ssize_t w = write(fd, p, n);
        if (w < 0) {
            if (errno == EINTR)
                continue;
            return -1;
        }
        p += w;
        n -= (size_t)w;
    }
    return 0;
}

rc_status fileio_write_atomic(const char *path, const char *text, char *err, size_t errlen)
{
    char target[FILEIO_PATH_MAX], tmp[FILEIO_PATH_MAX];
    int fd;
    rc_status st = fileio_output_target(path, target, sizeof target, err, errlen);
    if (st == RC_OK)
        st = fileio_temp_open(target, tmp, sizeof tmp, &fd, err, errlen);
    if (st != RC_OK)
        return st;
    int failed = fileio_write_full(fd, text, strlen(text)) != 0;
    if (failed)
        status_message(err, errlen, "%s: cannot write: %s", path, strerror(errno));
    return fileio_temp_finish(fd, tmp, target, failed, err, errlen);
}

rc_status fileio_read_input(const char *path, long long max_bytes, const char *what, unsigned char **out, size_t *len,
                            char *err, size_t errlen)
{
    int fd;
    long long size = 0;
    *out = NULL;
    rc_status rc = fileio_open_input(path, max_bytes, what, &fd, &size, err, errlen);
    if (rc != RC_OK)
        return rc;
    unsigned char *buf = malloc((size_t)size + 1);
    if (buf == NULL) {
        close(fd);
        status_message(err, errlen, "%s: out of memory for %lld bytes", path, size);
        return RC_ERR_NOMEM;
    }
    size_t used = 0;
    /* At most the size fstat gave: a file growing meanwhile is cut there, never read without end. */
    while (used < (size_t)size) {
        ssize_t r = read(fd, buf + used, (size_t)size - used);
        if (r < 0 && errno == EINTR)
            continue;
        if (r < 0) {
            status_message(err, errlen, "%s: cannot read it (%s); give a readable file", path, strerror(errno));
            close(fd);
            free(buf);
            return RC_ERR_IO;
        }
        if (r == 0)
            break;
        used += (size_t)r;
    }
    close(fd);
    buf[used] = '\0';
    *out = buf;
    *len = used;
    return RC_OK;
}

char *fileio_read_all(const char *path, size_t *len)
{
    unsigned char *buf;
    size_t n;
    char err[16];
    if (fileio_read_input(path, FILEIO_READ_ALL_MAX_BYTES, "a text file", &buf, &n, err, sizeof err) != RC_OK)
        return NULL;
    if (len != NULL)
        *len = n;
    return (char *)buf;
}

int fileio_copy(const char *from, const char *to)
{
    char target[FILEIO_PATH_MAX], tmp[FILEIO_PATH_MAX], err[16];
    int out;
    FILE *in = fopen(from, "rb");
    if (in == NULL)
        return -1;
    if (fileio_output_target(to, target, sizeof target, err, sizeof err) != RC_OK ||
        fileio_temp_open(target, tmp, sizeof tmp, &out, err, sizeof err) != RC_OK) {
        fclose(in);
        return -1;
    }
    char buf[65536];
    size_t n;
    int failed = 0;
    while (!failed && (n = fread(buf, 1, sizeof buf, in)) > 0)
        failed = fileio_write_full(out, buf, n) != 0;
    failed |= ferror(in) != 0;
    fclose(in);
    return fileio_temp_finish(out, tmp, target, failed, err, sizeof err) == RC_OK ? 0 : -1;
}

const char *fileio_kind(mode_t m)
{
    if (S_ISDIR(m))
        return "a directory";
    if (S_ISFIFO(m))
        return "a FIFO";
    if (S_ISCHR(m))
        return "a character device";
    if (S_ISBLK(m))
        return "a block device";
    if (S_ISSOCK(m))
        return "a socket";
    return "not a regular file";
}

rc_status fileio_open_input(const char *path, long long max_bytes, const char *what, int *fd_out, long long *size_out,
                            char *err, size_t errlen)
{
    *fd_out = -1;
    int fd = open(path, O_RDONLY | O_NONBLOCK | O_CLOEXEC | O_NOCTTY);
    if (fd < 0) {
        status_message(err, errlen, "%s: cannot open (%s); give a path to %s", path, strerror(errno), what);
        return RC_ERR_IO;
    }
    struct stat st;
    if (fstat(fd, &st) != 0) {
        status_message(err, errlen, "%s: cannot stat (%s); give a path to %s", path, strerror(errno), what);
        close(fd);
        return RC_ERR_IO;
    }
    if (!S_ISREG(st.st_mode)) {
        status_message(err, errlen, "%s: not a regular file (%s); give a path to %s", path, fileio_kind(st.st_mode),
                       what);
        close(fd);
        return RC_ERR_RANGE;
    }
    if ((long long)st.st_size > max_bytes) {
        status_message(err, errlen, "%s: %lld bytes is over the limit of %lld bytes; give %s of at most that size",
                       path, (long long)st.st_size, max_bytes, what);
        close(fd);
        return RC_ERR_RANGE;
    }
    /* Reads of a regular file never block; clear the flag so they behave as ordinary reads. */
    int fl = fcntl(fd, F_GETFL);
    if (fl != -1)
        fcntl(fd, F_SETFL, fl & ~O_NONBLOCK);
    *fd_out = fd;
    if (size_out != NULL)
        *size_out = (long long)st.st_size;
    return RC_OK;
}

rc_status fileio_memory_limit(size_t *bytes, char *err, size_t errlen)
{
    const char *v = getenv("REFLCHECK_MEMORY_LIMIT");
    if (v != NULL && v[0] != '\0') {
        char *end;
        errno = 0;
        unsigned long long n = strtoull(v, &end, 10);
        int shift = 0;
        switch (*end) {
        case 'k':
        case 'K':
            shift = 10;
            end++;
            break;
        case 'm':
        case 'M':
            shift = 20;
            end++;
            break;
        case 'g':
        case 'G':
            shift = 30;
            end++;
            break;
        case 't':
        case 'T':
            shift = 40;
            end++;
            break;
        default: break;
        }
        if (errno != 0 || end == v || *end != '\0' || v[0] == '-' || n == 0 || n > (SIZE_MAX >> shift)) {
            status_message(err, errlen,
                           "REFLCHECK_MEMORY_LIMIT='%s': expected a positive number of bytes with an "
                           "optional K, M, G or T suffix, e.g. 8G; fix or unset it",
                           v);
            return RC_ERR_RANGE;
        }
        *bytes = (size_t)n << shift;
        return RC_OK;
    }
    long pages = sysconf(_SC_PHYS_PAGES), page = sysconf(_SC_PAGESIZE);
    /* Half the machine: the other half stays for the system, the page cache and the second
     * job the nightly runs beside this one (make -j2). */
    if (pages <= 0 || page <= 0)
        *bytes = FILEIO_MEMORY_FALLBACK;
    else
        *bytes = (size_t)pages / 2 * (size_t)page;
    return RC_OK;
}

rc_status fileio_image_budget(const char *path, const char *format, long long w, long long h, double min_bytes,
                              long long file_bytes, double alloc, char *err, size_t errlen)
{
    if (min_bytes > (double)file_bytes) {
        status_message(err, errlen,
                       "%s: the %s header says %lld x %lld pixels, which needs at least %.0f bytes of coded data, "
                       "but the file has %lld: it is truncated or its header is corrupt; give the complete file",
                       path, format, w, h, min_bytes, file_bytes);
        return RC_ERR_PARSE;
    }
    size_t limit = 0;
    char why[256];
    if (fileio_memory_limit(&limit, why, sizeof why) != RC_OK) {
        status_message(err, errlen, "%s: %s", path, why);
        return RC_ERR_RANGE;
    }
    if (alloc > (double)limit) {
        status_message(err, errlen,
                       "%s: a %lld x %lld %s needs %.2f GiB decoded, over the memory limit of %.2f GiB; give a "
                       "smaller image or raise REFLCHECK_MEMORY_LIMIT",
                       path, w, h, format, alloc / 1073741824.0, (double)limit / 1073741824.0);
        return RC_ERR_RANGE;
    }
    return RC_OK;
}
