/* scene_file.h - read a YAML scene file (format: scenes/FORMAT.md) into a scene.
 *
 * Usage:
 *   scene s; char err[512];
 *   if (scene_file_load("scenes/lambert.yaml", &s, err, sizeof err) != RC_OK) { puts(err); ... }
 *
 * Both functions fill *out completely (scene_init defaults, then the file) and only on RC_OK;
 * on failure *out is left untouched and err holds one line
 *   "FILE:LINE:COL: key.path: problem; allowed: ..."
 * Returns RC_ERR_IO (file unreadable, or a referenced mesh/environment file missing),
 * RC_ERR_PARSE (YAML syntax, unknown or duplicate key, wrong type, missing required key),
 * RC_ERR_RANGE (NaN/Inf, a value outside its allowed range, unknown material name, file > 1 MiB,
 * a scene, mesh or environment path that is not a regular file, a mesh > 1 GiB), RC_ERR_NOMEM.
 * Files are checked by kind and size before a byte is read (core/fileio.h), so /dev/zero or
 * a FIFO is refused at once instead of read without end or waited on.
 * Units in the file: degrees for angles (stored as radians), metres, W/sr, W/m^2.
 * Relative paths inside the file (environment image, mesh) are resolved against the directory
 * of `path` (scene_file_load) or `path_for_messages` (scene_file_parse; NULL means "<string>"
 * and the current directory). out->hash is FNV-1a 64 of the bytes read.
 * A threshold's gate at the size a run rendered (small: or full: block, else its own levels):
 *   threshold_gate g; threshold_gate_at(&s.comparisons[0].thresholds[0], 1, &g);  full size
 */
#ifndef REFLCHECK_SCENE_FILE_H
#define REFLCHECK_SCENE_FILE_H

#include <stddef.h>
#include <stdint.h>
#include "renderers/registry.h" /* comparisons hold rows of the renderer table */
#include "scene.h"
#include "status.h"

/* Scene files are hand-written and small; anything larger is refused before parsing. */
#define SCENE_FILE_MAX_BYTES (1u << 20)

rc_status scene_file_load(const char *path, scene *out, char *err, size_t errlen);
rc_status scene_file_parse(const char *text, size_t len, const char *path_for_messages, scene *out, char *err,
                           size_t errlen);
/* RC_OK when every physical reference a validate or agree comparison of s names renders s's
 * physics manifest exactly (each renderer row's physics function); else RC_ERR_RANGE with one
 * line naming the file, the comparison and the physics keys to set (physics: {key: value}) or
 * the renderer's own reason. Call after the environment's sun is split off (frame.h): light
 * masks count it. `reflcheck check` refuses such a scene; a run skips the comparison. */
rc_status scene_file_physics_check(const scene *s, char *err, size_t errlen);
/* One threshold's gate at one image size (full 0: the small variant `make test` renders; 1: the
 * full size): warn and fail from that size's block (scene-file key small: or full:) where it
 * gives them, else the threshold's own; loose likewise ("" = none). own = 1 when the size has a
 * block of its own. sized_size, sized_figure, sized_run: the figure the gate was set on (that
 * size's sized:, else the threshold's own, whichever size it names; SIZED_NONE = not stated). */
typedef struct {
    double warn, fail;
    const char *loose;
    int own;
    int sized_size;
    double sized_figure;
    const char *sized_run;
} threshold_gate;
void threshold_gate_at(const threshold *t, int full, threshold_gate *out);

/* FNV-1a 64-bit hash of len bytes (the scene hash). */
uint64_t scene_file_hash(const void *bytes, size_t len);

#endif
