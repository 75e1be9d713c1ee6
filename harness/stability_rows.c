/* stability_rows.c - the sample points of the stability sweeps and the row accumulator
 * (stability_sweep.h). Sweeps mix log-spaced values of the extreme parameter with seeded random
 * values of the others, so a run is reproducible.
 */
#include <float.h>
#include <stdlib.h>
#include <string.h>

#include "stability_sweep.h"

double stab_rng_u(rng *r)
{
    /* splitmix64: tiny, seedable, good enough to scatter sweep points. */
    uint64_t z = (r->s += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    z ^= z >> 31;
    return (double)(z >> 11) * 0x1p-53;
}

double stab_rng_range(rng *r, double lo, double hi) { return lo + (hi - lo) * stab_rng_u(r); }
double stab_rng_log(rng *r, double lo, double hi) { return lo * pow(hi / lo, stab_rng_u(r)); }

/* i-th of n log-spaced values from lo to hi, both included. */
double stab_lsp(int i, int n, double lo, double hi)
{
    return n < 2 ? lo : lo * pow(hi / lo, (double)i / (double)(n - 1));
}

vec3 stab_rng_dir_upper(rng *r, double cos_lo, double cos_hi)
{
    double c = stab_rng_range(r, cos_lo, cos_hi), ph = stab_rng_range(r, 0.0, 2.0 * (double)REF_PI);
    double s = sqrt(fmax(0.0, 1.0 - c * c));
    return v3((float)(s * cos(ph)), (float)c, (float)(s * sin(ph)));
}

/* Unit vector (in float) at polar cosine c from +Y, azimuth ph. */
vec3 stab_dir_at(double c, double ph)
{
    double s = sqrt(fmax(0.0, (1.0 - c) * (1.0 + c)));
    return v3((float)(s * cos(ph)), (float)c, (float)(s * sin(ph)));
}

stability_row *stab_row_begin(sweep *s, const char *fn, const char *cs, stability_kind kind, int precision)
{
    stability_table *t = s->t;
    if (t->n_rows >= STABILITY_MAX_ROWS)
        abort(); /* a programming error: raise STABILITY_MAX_ROWS with the new rows */
    stability_row *row = &t->rows[t->n_rows++];
    memset(row, 0, sizeof *row);
    snprintf(row->function, sizeof row->function, "%s", fn);
    snprintf(row->case_name, sizeof row->case_name, "%s", cs);
    row->kind = kind;
    row->precision = precision;
    row->max_ulp = -1.0;
    row->max_abs = -1.0;
    row->check_ok = -1;
    row->expect_ok = 1;
    return row;
}

void stab_row_end(stability_row *row)
{
    if (row->max_ulp < 0.0)
        row->max_ulp = 0.0;
    if (row->max_abs < 0.0)
        row->max_abs = 0.0;
}

ld stab_ulp_of(ld ref, int precision)
{
    ld a = fabsl(ref);
    if (precision == 24) {
        if (a < (ld)FLT_MIN)
            return 0x1p-149L;
        if (a > (ld)FLT_MAX)
            a = FLT_MAX;
        return ldexpl(1.0L, ilogbl(a) - 23);
    }
    if (a < (ld)DBL_MIN)
        return 0x1p-1074L;
    if (a > (ld)DBL_MAX)
        a = DBL_MAX;
    return ldexpl(1.0L, ilogbl(a) - 52);
}

/* Adds one result; returns bit 1 for a new worst ulp error, bit 2 for a new worst absolute
 * error (the caller then records the inputs). Sweeps only pass finite inputs, so a NaN or
 * Inf result is always counted. */
int stab_row_add(stability_row *row, double got, ld ref)
{
    row->samples++;
    if (isnan(got)) {
        row->nan++;
        return 0;
    }
    if (isinf(got)) {
        row->inf++;
        return 0;
    }
    if (got < 0.0 && ref >= 0)
        row->negative++;
    ld diff = fabsl((ld)got - ref);
    double u = (double)(diff / stab_ulp_of(ref, row->precision));
    double ab = (double)diff;
    /* Relative error only where the reference is a normal number of the result's type:
     * below that the result is denormal or 0 by design and the ulp figure says it all. */
    if (fabsl(ref) >= (row->precision == 24 ? (ld)FLT_MIN : (ld)DBL_MIN)) {
        double rel = (double)(diff / fabsl(ref));
        if (rel > row->max_rel)
            row->max_rel = rel;
    }
    int worst = 0;
    if (u > row->max_ulp) {
        row->max_ulp = u;
        worst |= 1;
    }
    if (ab > row->max_abs) {
        row->max_abs = ab;
        worst |= 2;
    }
    return worst;
}
