/* stability_output.c - the stability table as JSON, CSV and fixed-width text (stability.h). */
#include "jsonio.h"
#include "stability_sweep.h"

static const char *kind_name(stability_kind k)
{
    return k == STABILITY_ROUNDING ? "rounding" : k == STABILITY_APPROX ? "approx" : "physics";
}

/* Figures carry 6 significant digits (the table's own precision; enough to tell 0.5 ulp from
 * 1); a non-finite figure (never expected) is null, as JSON has no Inf/NaN. */
#define STABILITY_JSON_DIGITS 6

static cJSON *stability_json_row(const stability_row *r)
{
    cJSON *o = cJSON_CreateObject();
    if (o == NULL)
        return NULL;
    int ok = cJSON_AddStringToObject(o, "function", r->function) != NULL &&
             cJSON_AddStringToObject(o, "case", r->case_name) != NULL &&
             cJSON_AddStringToObject(o, "kind", kind_name(r->kind)) != NULL &&
             cJSON_AddNumberToObject(o, "precision_bits", r->precision) != NULL &&
             cJSON_AddNumberToObject(o, "samples", (double)r->samples) != NULL &&
             jsonio_add(o, "max_ulp", jsonio_number(r->max_ulp, STABILITY_JSON_DIGITS)) &&
             jsonio_add(o, "max_rel", jsonio_number(r->max_rel, STABILITY_JSON_DIGITS)) &&
             jsonio_add(o, "max_abs", jsonio_number(r->max_abs, STABILITY_JSON_DIGITS)) &&
             cJSON_AddStringToObject(o, "where", r->where) != NULL &&
             cJSON_AddStringToObject(o, "where_abs", r->where_abs) != NULL &&
             cJSON_AddNumberToObject(o, "nan", (double)r->nan) != NULL &&
             cJSON_AddNumberToObject(o, "inf", (double)r->inf) != NULL &&
             cJSON_AddNumberToObject(o, "negative", (double)r->negative) != NULL &&
             cJSON_AddNumberToObject(o, "check_ok", r->check_ok) != NULL &&
             cJSON_AddBoolToObject(o, "gating", r->expect_ok) != NULL &&
             jsonio_add(o, "value", jsonio_number(r->value, STABILITY_JSON_DIGITS)) &&
             jsonio_add(o, "aux", jsonio_number(r->aux, STABILITY_JSON_DIGITS)) &&
             cJSON_AddStringToObject(o, "note", r->note) != NULL &&
             cJSON_AddBoolToObject(o, "fails", stab_row_fails(r)) != NULL;
    if (!ok) {
        cJSON_Delete(o);
        return NULL;
    }
    return o;
}

cJSON *stability_json(const stability_table *t)
{
    cJSON *doc = cJSON_CreateObject(), *rows = NULL;
    int ok = doc != NULL && cJSON_AddNumberToObject(doc, "reference_mantissa_bits", t->ldbl_mant_dig) != NULL &&
             cJSON_AddNumberToObject(doc, "samples", t->samples) != NULL &&
             cJSON_AddNumberToObject(doc, "failures", stability_failures(t)) != NULL &&
             jsonio_add(doc, "rows", rows = cJSON_CreateArray());
    if (!ok) {
        cJSON_Delete(doc);
        return NULL;
    }
    for (int i = 0; i < t->n_rows; i++) {
        cJSON *row = stability_json_row(&t->rows[i]);
        if (row == NULL || !cJSON_AddItemToArray(rows, row)) {
            cJSON_Delete(row);
            cJSON_Delete(doc);
            return NULL;
        }
    }
    return doc;
}

int stability_write_json(FILE *f, const stability_table *t)
{
    cJSON *doc = stability_json(t);
    if (doc == NULL)
        return -1;
    int rc = jsonio_print(f, doc);
    cJSON_Delete(doc);
    return rc;
}

static void csv_str(FILE *f, const char *s)
{
    fputc('"', f);
    for (; *s; s++) {
        if (*s == '"')
            fputc('"', f);
        fputc(*s, f);
    }
    fputc('"', f);
}

int stability_write_csv(FILE *f, const stability_table *t)
{
    fputs("function,case,kind,precision_bits,samples,max_ulp,max_rel,max_abs,where,where_abs,nan,inf,negative,check_ok,"
          "gating,"
          "value,aux,note,fails\n",
          f);
    for (int i = 0; i < t->n_rows; i++) {
        const stability_row *r = &t->rows[i];
        csv_str(f, r->function);
        fputc(',', f);
        csv_str(f, r->case_name);
        fprintf(f, ",%s,%d,%ld,%.6g,%.6g,%.6g,", kind_name(r->kind), r->precision, r->samples, r->max_ulp, r->max_rel,
                r->max_abs);
        csv_str(f, r->where);
        fputc(',', f);
        csv_str(f, r->where_abs);
        fprintf(f, ",%ld,%ld,%ld,%d,%d,%.6g,%.6g,", r->nan, r->inf, r->negative, r->check_ok, r->expect_ok, r->value,
                r->aux);
        csv_str(f, r->note);
        fprintf(f, ",%d\n", stab_row_fails(r));
    }
    return ferror(f) ? -1 : 0;
}

int stability_write_text(FILE *f, const stability_table *t)
{
    fprintf(f,
            "stability: %d samples per case, reference long double (%d-bit significand); ulp in the result's "
            "precision (0.5 = correctly rounded)\n",
            t->samples, t->ldbl_mant_dig);
    fprintf(f, "%-38s %-34s %10s %10s %10s %4s %4s %4s  %s\n", "function", "case", "max_ulp", "max_rel", "max_abs",
            "NaN", "Inf", "neg", "where / check");
    for (int i = 0; i < t->n_rows; i++) {
        const stability_row *r = &t->rows[i];
        if (r->kind == STABILITY_PHYSICS)
            fprintf(f, "%-38s %-34s %10s %10s %10s %4ld %4ld %4s  %s%s [%s]\n", r->function, r->case_name, "-", "-",
                    "-", r->nan, r->inf, "-", stab_row_fails(r) ? "FAIL " : "", r->note, r->where);
        else
            fprintf(f, "%-38s %-34s %10.3g %10.3g %10.3g %4ld %4ld %4ld  %s%s\n", r->function, r->case_name, r->max_ulp,
                    r->max_rel, r->max_abs, r->nan, r->inf, r->negative, stab_row_fails(r) ? "FAIL " : "",
                    r->kind == STABILITY_APPROX ? r->where_abs : r->where);
    }
    int nf = stability_failures(t);
    fprintf(f, "stability: %d rows, %d failing (NaN/Inf/negative for finite input, or a gating physics check)\n",
            t->n_rows, nf);
    return ferror(f) ? -1 : 0;
}
