/* status.h - the status codes every fallible reflcheck function returns (0 = ok).
 * Functions that fail also write a one-line message into a caller's buffer
 * (char *err, size_t errlen) naming the file, the place and the fix.
 */
#ifndef REFLCHECK_STATUS_H
#define REFLCHECK_STATUS_H

#include <stddef.h>

typedef enum {
    RC_OK = 0,
    RC_ERR_IO,    /* a file could not be opened, read or written */
    RC_ERR_PARSE, /* malformed input: syntax, unknown key, wrong type */
    RC_ERR_RANGE, /* a value outside what is allowed (NaN, negative roughness, ...) */
    RC_ERR_NOMEM,
    RC_ERR_RENDERER /* an external renderer failed */
} rc_status;

/* Formats the one-line message into err (errlen bytes, cut to fit); err NULL or errlen 0:
 * nothing. Every module writes its messages through this one function. */
#if defined(__GNUC__)
__attribute__((format(printf, 3, 4)))
#endif
void status_message(char *err, size_t errlen, const char *fmt, ...);

#endif
