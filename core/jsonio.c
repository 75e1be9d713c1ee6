#include "jsonio.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fileio.h"

/* The document's text with a final newline (files and pipes end their last line); NULL when
 * memory runs out. Free with free(). */
static char *jsonio_text(const cJSON *doc)
{
    char *text = cJSON_Print(doc);
    if (text == NULL)
        return NULL;
    size_t n = strlen(text);
    char *line = malloc(n + 2);
    if (line != NULL) {
        memcpy(line, text, n);
        memcpy(line + n, "\n", 2);
    }
    cJSON_free(text);
    return line;
}

rc_status jsonio_write_file(const cJSON *doc, const char *path, char *err, size_t errlen)
{
    char *text = jsonio_text(doc);
    if (text == NULL) {
        status_message(err, errlen, "%s: out of memory for the JSON text", path);
        return RC_ERR_NOMEM;
    }
    rc_status st = fileio_write_atomic(path, text, err, errlen);
    free(text);
    return st;
}

int jsonio_print(FILE *f, const cJSON *doc)
{
    char *text = jsonio_text(doc);
    if (text == NULL)
        return -1;
    int ok = fputs(text, f) >= 0;
    free(text);
    return ok ? 0 : -1;
}

cJSON *jsonio_number(double x, int digits)
{
    if (!isfinite(x))
        return cJSON_CreateNull();
    /* The decimal text and back: the double nearest the rounded decimal, which cJSON's
     * shortest-round-trip printing ("%1.15g", checked) then writes as that decimal. */
    char text[40];
    snprintf(text, sizeof text, "%.*g", digits < 1 ? 1 : digits > 17 ? 17 : digits, x);
    return cJSON_CreateNumber(strtod(text, NULL));
}

int jsonio_add(cJSON *object, const char *key, cJSON *item)
{
    if (item != NULL && cJSON_AddItemToObject(object, key, item))
        return 1;
    cJSON_Delete(item);
    return 0;
}
