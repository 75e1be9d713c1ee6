/* diff_terms.h - an image without some of its terms, for `reflcheck diff --leave-out`.
 *
 * Usage:
 *   unsigned bits;
 *   if (diff_terms_parse("specular,emission", &bits, err, sizeof err) != RC_OK) ...
 *   diff_terms_strip("in.exr", bits, "out.exr", err, sizeof err);
 * A partial twin (compare.json `terms_left_out`) compares the terms both sides render: its
 * reference left a term out, so the test's layer of that term is taken off its RGB (as
 * harness/compare.c does for the twin itself). diff_terms_strip writes `in` again with each
 * left-out term's layer (TERM.R, .G, .B) subtracted from R, G, B; every other channel as read
 * (string attributes are dropped: no metric reads them).
 * A side that left the term out itself has a zero layer (every renderer writes all four), so
 * subtracting it changes nothing; an image without the layer is refused, naming file and layer.
 */
#ifndef REFLCHECK_DIFF_TERMS_H
#define REFLCHECK_DIFF_TERMS_H

#include <stddef.h>

#include "status.h"

/* A comma-separated list of term names (diffuse, specular, reflection, emission) as
 * RENDERER_TERM_* bits; RC_ERR_PARSE naming the word and the allowed ones. */
rc_status diff_terms_parse(const char *list, unsigned *bits, char *err, size_t errlen);

/* Writes `in` minus the layers of the terms in bits to `out`. */
rc_status diff_terms_strip(const char *in, unsigned bits, const char *out, char *err, size_t errlen);

/* Strips test and ref into a new private folder (mkdtemp under $TMPDIR, else /tmp), written to
 * dir (at least 256 bytes) as DIR/test.exr and DIR/ref.exr. diff_terms_cleanup removes them. */
rc_status diff_terms_pair(const char *test, const char *ref, unsigned bits, char *dir, size_t dirlen, char *err,
                          size_t errlen);
void diff_terms_cleanup(const char *dir);
/* Puts the user's file names back into a message about the stripped copies in dir. */
void diff_terms_names(char *msg, size_t len, const char *dir, const char *test, const char *ref);

#endif
