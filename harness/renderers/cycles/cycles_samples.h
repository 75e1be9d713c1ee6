/* cycles_samples.h - a Cycles job's samples from the noise its comparisons' gates must resolve.
 *
 * Usage (cycles_render_job does this when the scene says `image.samples: auto`):
 *   cycles_noise_need need;
 *   cycles_noise_need_of(&scn, registry_find("cycles"), ROLE_VALIDATE, 1, &need);   1: full size
 *   need.refuse: the rule cannot decide (need.why says which gate and the fix) -> refused
 *   render p = cycles_pilot_samples(k^2) samples, cycles_exr_noise("out.exr", &noise, err, sizeof err);
 *   int n = cycles_samples_need(&noise, p, k^2, &need);   while n > the last count: render
 *   cycles_samples_step(last, n), measure its noise, n = cycles_samples_need(that noise, ...)
 *
 * The rule (docs/samples.md derives it), over the gates of the comparisons whose
 * reference or test is this render, at the size rendered (threshold_gate_at):
 * - An RMS-error gate (nrmse, nrmse_trim1, rel_rms, of any region): the reference's own noise
 *   adds to the figure in quadrature, so a noise of fail / CYCLES_NOISE_MARGIN moves a figure
 *   at the gate by at most sqrt(1 + 1/9) - 1 = 5.4 %. Target: fail / 3, for nrmse_trim1 on the
 *   noise without the 1 % of pixels of largest variance, as that metric drops its worst 1 %.
 * - A per-pixel z-test gate (z_fail_share, of any region): its false alarms stay at alpha
 *   whatever the noise; its power is what the samples buy. A value off by b (a fraction of the
 *   surface's mean radiance) with standard error sigma is flagged with probability 1 - beta
 *   when b / sigma >= z_crit + z_beta, z_crit = Phi^-1(1 - alpha / 2m) the first Holm step over
 *   the m tested values (Bonferroni; Holm's later steps only flag more), z_beta =
 *   Phi^-1(1 - beta). Target for pixel_q: b / (z_crit + z_beta), so that the quietest
 *   CYCLES_ZTEST_COVER of the values have that power. b is the scene's image.samples {auto:
 *   true, bias: b}, else the comparison's own smallest RMS fail (an error that fails it spread
 *   evenly must also show per pixel); neither: refused.
 * - A bias gate in standard errors (bias.z_max, bias.z_trim1_max): a real residual bias's
 *   figure grows as sqrt(samples), so its fail level was set at its sample count: refused.
 * Each noise against its smallest target, the samples follow from a pilot's noise by the Monte
 * Carlo rate (noise ~ samples^-1/2; PMJ's stratification only makes it fall faster, so the
 * count errs high); the larger count wins. A job with no such gate (test_nonfinite, coverage,
 * crease shares: no noise scale) renders the pilot alone.
 * Noise (cycles_exr_noise), over the interior pixels' R, G, B values (metrics_classify on the
 * image's coverage and object: the surface region, without edges, whose variance is their
 * coverage's, or object boundaries): nrmse = sqrt(mean of var) / mean of the values, the noise
 * NRMSE of the seeds' mean, as `nrmse` normalises an error (rel_rms divides by the RMS instead,
 * never below the mean, so the target is conservative there; crease pixels stay in,
 * conservative too); trim1 = the same without the CYCLES_TRIM share of pixels of largest summed
 * variance; pixel_q = the CYCLES_ZTEST_COVER quantile of sqrt(var) over the same
 * values / the same mean (a glossy scene's RMS is ruled by a few fireflies, which a per-value
 * test meets only where they are).
 */
#ifndef REFLCHECK_CYCLES_SAMPLES_H
#define REFLCHECK_CYCLES_SAMPLES_H

#include <stddef.h>
#include "scene.h"
#include "status.h"

/* The pilot's samples per seed: the levels the sweep measures fall at the Monte Carlo rate from
 * 16 spp up (docs/results.md), so a noise measured there scales. */
#define CYCLES_PILOT_SPP    16
/* fail / 3: the noise moves a figure at the gate by at most 5.4 % (above). */
#define CYCLES_NOISE_MARGIN 3.0
/* The z-test's family-wise false-alarm rate: compare.c's (Holm, alpha 0.01). */
#define CYCLES_ZTEST_ALPHA  0.01
/* The z-test's miss rate at the stated bias: 1 in 10 nightlies, the usual design power of 90 %;
 * a bias at b is seen in 99.9 % of three nightlies running. */
#define CYCLES_ZTEST_BETA   0.10
/* The share of pixels nrmse_trim1 drops (metrics.c's METRICS_TRIM). */
#define CYCLES_TRIM         0.01
/* The share of the surface values a z-test's power holds for: the noisiest tenth (highlights,
 * fireflies) may have less. */
#define CYCLES_ZTEST_COVER  0.9
/* The largest step from one render to the next: measured, the Monte Carlo rate from a 16-spp
 * pilot over-asks up to 16 x (grazing_plane's validate, full size: 512 spp asked, the noise at
 * 512 4.6 x under its target), as PMJ's noise falls faster than it; renders of at most 4 x
 * each, each predicted from the last, cost at most 4/3 of the last one besides the pilot. */
#define CYCLES_STEP         4
/* The most samples the rule asks (Cycles' own limit is far above; a gate asking more than this
 * at a scene's size is a gate to look at, and the record says the target was not reached). */
#define CYCLES_MAX_SPP      4096

typedef struct {
    double target;        /* the nrmse the RMS gates (nrmse, rel_rms) ask; 0 = none asks */
    double target_trim1;  /* the trim1 the nrmse_trim1 gates ask; 0 = none asks */
    char gate[128];       /* which gate sets target, for the record */
    char gate_trim1[128]; /* which gate sets target_trim1 */
    double bias;          /* the smallest z-test's bias b; 0 = no z-test gate */
    char zgate[160];      /* which z-test gate, and where its b comes from */
    int refuse;           /* nonzero: auto cannot decide this render; why says which gate and the fix */
    char why[256];
} cycles_noise_need;

/* The noise of a collected Cycles image. */
typedef struct {
    double nrmse;   /* the noise NRMSE of the seeds' mean (above) */
    double trim1;   /* the same without the 1 % of pixels of largest variance */
    double pixel_q; /* the CYCLES_ZTEST_COVER quantile of a value's standard error / mean */
    long n_values;  /* interior pixels times 3: the values a surface z-test tests */
} cycles_noise;

/* The need of the render of `role` (twin: the twin comparisons; validate and agree: the
 * others) of the renderer-table row `row`, from the scene's comparisons naming that row, at the
 * small (full 0) or full size's gates. */
void cycles_noise_need_of(const scene *s, int row, comparison_role role, int full, cycles_noise_need *out);

/* z_crit + z_beta: the standard errors between no bias and the bias a z-test over n_values
 * values catches with probability 1 - CYCLES_ZTEST_BETA (n_values < 1 counts as 1). */
double cycles_ztest_span(long n_values);

/* The pixel_q a z-test asks: need->bias / cycles_ztest_span(n_values); 0 = no z-test. */
double cycles_ztest_target(const cycles_noise_need *need, long n_values);

/* Samples per seed for a render whose pilot of n_pilot samples measured `noise`: n_pilot when
 * nothing asks (target 0) or the pilot reaches target, else n_pilot (noise / target)^2 rounded
 * up, at most CYCLES_MAX_SPP. */
int cycles_samples_for(double noise, int n_pilot, double target);

/* The samples of a pilot that measures what more samples do: two per sample position (positions:
 * k^2 for a twin's k x k model positions, 1 for a pixel integral), at least CYCLES_PILOT_SPP.
 * One sample per position has no strata: its noise falls far faster than the Monte Carlo rate
 * from there (real_spider's twin, k = 4: pixel_q 0.12 at 16 spp, 9e-4 at 32). */
int cycles_pilot_samples(int positions);

/* The count to render after a pilot of n_pilot: the largest of cycles_samples_for's counts for
 * its nrmse against need->target, its trim1 against need->target_trim1 and its pixel_q against
 * cycles_ztest_target; n_pilot when none is larger, else rounded up to a power of two per
 * position (Cycles' PMJ samples are stratified whole there, and not between: real_house's
 * validate has nrmse 0.0022 at 32 spp and 0.0073 at 85), at most CYCLES_MAX_SPP. */
int cycles_samples_need(const cycles_noise *pilot, int n_pilot, int positions, const cycles_noise_need *need);

/* The next render after one of `current` samples when `wanted` (cycles_samples_need) asks more:
 * wanted, or CYCLES_STEP x current if that is less (a power of two per position stays one). */
int cycles_samples_step(int current, int wanted);

/* The noise of a collected Cycles image (above); RC_ERR_RANGE when it has no var.* channels (one
 * seed) or no interior pixel of non-zero mean. */
rc_status cycles_exr_noise(const char *exr_path, cycles_noise *out, char *err, size_t errlen);

#endif
