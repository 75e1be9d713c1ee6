/* jsonio.h - JSON documents out of the harness, written one way (cJSON).
 *
 * Usage:
 *   cJSON *doc = cJSON_CreateObject(); ...
 *   jsonio_write_file(doc, "run/x/compare.json", err, sizeof err);  text and a newline, written
 *                                                                    to a temporary and renamed
 *   jsonio_print(stdout, doc);                                       text and a newline
 *   jsonio_add(doc, "rms", jsonio_number(x, 6));                     x to 6 significant digits,
 *                                                                    null when not finite
 * The document stays the caller's. jsonio_write_file returns RC_OK, RC_ERR_NOMEM, or the
 * error of fileio_write_atomic (path and reason in err); jsonio_print returns 0, or -1 when the
 * text could not be made or written.
 */
#ifndef REFLCHECK_JSONIO_H
#define REFLCHECK_JSONIO_H

#include <stddef.h>
#include <stdio.h>

#include <cJSON.h>

#include "status.h"

rc_status jsonio_write_file(const cJSON *doc, const char *path, char *err, size_t errlen);
int jsonio_print(FILE *f, const cJSON *doc);

/* x rounded to `digits` significant decimal digits (1..17), so that cJSON prints the short
 * form ("%.{digits}g"'s value); Inf and NaN, which JSON cannot hold, give null. NULL when
 * memory runs out. */
cJSON *jsonio_number(double x, int digits);

/* Adds item under key and returns 1; on failure (item NULL, or no memory for the key) frees
 * item and returns 0, so a chain of additions needs no cleanup but the document's. */
int jsonio_add(cJSON *object, const char *key, cJSON *item);

#endif
