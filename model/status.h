/* status.h - the status codes every fallible reflcheck function returns (0 = ok).
 * Functions that fail also write a one-line message into a caller's buffer
 * (char *err, size_t errlen) naming the file, the place and the fix.
 */
#ifndef REFLCHECK_STATUS_H
#define REFLCHECK_STATUS_H

typedef enum {
    RC_OK = 0,
    RC_ERR_IO,       /* a file could not be opened, read or written */
    RC_ERR_PARSE,    /* malformed input: syntax, unknown key, wrong type */
    RC_ERR_RANGE,    /* a value outside what is allowed (NaN, negative roughness, ...) */
    RC_ERR_NOMEM,
    RC_ERR_RENDERER  /* an external renderer failed */
} rc_status;

#endif
