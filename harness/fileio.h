/* fileio.h - whole-file reads and crash-safe writes for the harness's own outputs.
 *
 * Usage:
 *   fileio_write_atomic("run/x/compare.json", text, err, sizeof err);  temp file, then rename
 *   char *text = fileio_read_all("record.json", &len);                 NUL-terminated; free()
 *   fileio_copy("cache/k/out.exr", "run/x/raster-twin.exr");           temp file, then rename
 * A reader of the destination never sees a half-written file, and a killed run leaves the old
 * file (or none) in place. Errors: RC_ERR_IO with the path and the system's reason in err;
 * fileio_read_all returns NULL, fileio_copy -1.
 */
#ifndef REFLCHECK_FILEIO_H
#define REFLCHECK_FILEIO_H

#include <stddef.h>
#include "status.h"

rc_status fileio_write_atomic(const char *path, const char *text, char *err, size_t errlen);
char *fileio_read_all(const char *path, size_t *len);
int fileio_copy(const char *from, const char *to);
/* The temporary name used for path (path + ".tmp" + pid), for writers that stream. */
void fileio_temp_name(const char *path, char *buf, size_t len);

#endif
