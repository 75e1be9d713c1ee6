/* cycles_samples.h - a Cycles job's samples from the noise its comparisons' gates must resolve.
 *
 * Usage (cycles_render_job does this when the scene says `image.samples: auto`):
 *   cycles_noise_need need;
 *   cycles_noise_need_of(&scn, registry_find("cycles"), ROLE_VALIDATE, &need);
 *   need.ztest: a z-test gate judges the render -> refused (its sample count is the gate's)
 *   render CYCLES_PILOT_SPP samples, then cycles_exr_noise("out.exr", &noise, err, sizeof err);
 *   int n = cycles_samples_for(noise, CYCLES_PILOT_SPP, &need);   n > pilot: render n samples
 *
 * The rule. An RMS-error gate (nrmse, nrmse_trim1, rel_rms, of any region) of a comparison
 * whose reference or test is this render: the reference's own noise adds to the figure in
 * quadrature, so a noise of fail / CYCLES_NOISE_MARGIN moves a figure at the gate by at most
 * sqrt(1 + 1/9) - 1 = 5.4 %. The target is the smallest such fail / 3 over the render's gates;
 * the samples follow from a pilot's noise by the Monte Carlo rate (noise ~ samples^-1/2; PMJ's
 * stratification only makes it fall faster, so the count errs high). A job with no RMS gate
 * (test_nonfinite, coverage, crease shares: no noise scale) renders the pilot alone.
 * A z-test gate (z_fail_share, bias.z_*) sets no noise scale: its false alarms stay at alpha
 * whatever the noise, its power (the smallest error it flags, z_crit times the noise) is what
 * the samples buy, so its sample count is part of the gate: a scene keeps image.samples a
 * number there.
 * Noise (cycles_exr_noise): sqrt(mean of var.R/G/B) / mean of R/G/B over the interior pixels
 * (metrics_classify on the image's coverage and object: the surface region, without edges,
 * whose variance is their coverage's, or object boundaries), the noise NRMSE of the seeds'
 * mean, as `nrmse` normalises an error (rel_rms divides by the RMS instead, never below the
 * mean, so the target is conservative there; crease pixels stay in, conservative too).
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
/* The most samples the rule asks (Cycles' own limit is far above; a gate asking more than this
 * at a scene's size is a gate to look at, and the record says the target was not reached). */
#define CYCLES_MAX_SPP      4096

typedef struct {
    double target;  /* the noise NRMSE the render must reach; 0 = no RMS gate asks */
    char gate[128]; /* which gate sets target (or the z-test gate), for the record */
    int ztest;      /* nonzero: a z-test gate judges this render */
} cycles_noise_need;

/* The need of the render of `role` (twin: the twin comparisons; validate and agree: the
 * others) of the renderer-table row `row`, from the scene's comparisons naming that row. */
void cycles_noise_need_of(const scene *s, int row, comparison_role role, cycles_noise_need *out);

/* Samples per seed for a render whose pilot of n_pilot samples measured `noise`: n_pilot when
 * nothing asks for less noise or the pilot reaches it, else n_pilot (noise / target)^2 rounded
 * up, at most CYCLES_MAX_SPP. */
int cycles_samples_for(double noise, int n_pilot, const cycles_noise_need *need);

/* The noise NRMSE of a collected Cycles image (above); RC_ERR_RANGE when it has no var.*
 * channels (one seed) or no interior pixel of non-zero mean. */
rc_status cycles_exr_noise(const char *exr_path, double *noise, char *err, size_t errlen);

#endif
