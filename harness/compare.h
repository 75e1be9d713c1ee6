/* compare.h - every comparison a scene lists, measured on the renders of one run.
 *
 * Usage:
 *   compare_scene("scenes/x.yaml", "reports/runs/r1", &summary, err, sizeof err);
 *   compare_images("t.exr", "r.exr", NULL, stdout, &failed, err, sizeof err);    reflcheck diff
 * Reads RUN/<scene>/<renderer>-<role>.exr and .json (harness/jobs.h), writes
 * RUN/<scene>/compare.json (format: reports/FORMAT.md) and RUN/<scene>/view.js (the
 * linear images for the report's viewer).
 * Status of a comparison: "skipped" only when a side's job record says skipped (renderer not
 * installed, or it cannot represent the scene); "error" when a record is missing or not JSON,
 * says anything but ok or skipped (failed, crashed, timeout, error), or its image cannot be
 * read, lacks R, G, B or differs in size; else "pass", "warn" or "fail" from the thresholds
 * and the value gate, where "pass" needs an accuracy gate: a comparison whose thresholds only
 * guard its inputs (finite and non-negative values, coverage, the crease share) and hold is
 * "not_gated". "reason" says why for skipped, error and a gate failure.
 * Bias: where the reference has var.* layers, each term's mean difference over the surface
 * against its standard error (terms.<t>.bias_z, bias_rel; "bias": the worst term, z_max), a
 * threshold metric (bias.z_max) that sees an offset spread over every pixel, which the
 * per-pixel z-test cannot.
 * Value gate: every comparison counts, over all pixels of both images and every layer it may
 * read (R, G, B; in a twin the diffuse, specular, reflection layers; var.*; coverage, object,
 * ndotv, ndotl), the NaN/Inf values and the negative radiance and variance values, into
 * "values" (per side: channels, values, nonfinite, negative, negative_allowed, the first of
 * each) and test_nonfinite, ref_nonfinite, test_negative, ref_negative. Any non-finite value,
 * and any negative one where the model promises radiance >= 0, fails the comparison by
 * itself. Negative radiance is allowed only in our render and twin references of a scene with
 * a D3D9Client material whose |reflect| > 1 or r0 + m > 1 (the model's weights go below 0).
 * Regions are kept apart: surface (interior pixels), edges (silhouettes: partial coverage or
 * an object boundary, from the rasterizer's coverage and object layers) and background.
 * Every metric says how many pixels it used: n_pixels and n_nonfinite per region, nrmse_mean_n,
 * n and n_nonfinite per angle bin, n_tests and n_nonfinite in the z-test.
 * Against a renderer with crease rules (registry.h) the interior pixels where one departs
 * (harness/crease.h) form a fourth region, "crease", reported with its size and per-rule counts
 * under "crease" and beside the surface's figures (crease_pixels, crease_share), and gated like
 * any region ("crease.rel_rms", "crease.z_fail_share"); a crease region above
 * COMPARE_CREASE_MAX_SHARE of the surface fails the comparison by itself, unless the scene
 * states its own limit, with its reason, as the threshold "crease.share_of_surface".
 * Thresholds (from the scene file) are judged on the surface unless the metric names a
 * region or layer: "rel_rms", "edges.rel_rms", "reflection.rel_rms", "z_fail_share",
 * "coverage_agreement", "test_nonfinite", "ref_nonfinite", "test_negative", "ref_negative".
 * psnr, ssim and coverage_agreement fail below the threshold, every other metric above it; a
 * metric that was not measured or is NaN fails.
 * summary counts verdicts; returns RC_OK unless the scene or our own files cannot be read or
 * written.
 * compare_images prints the metrics of one pair and the same value gate (every image taken
 * as radiance >= 0); *failed = 1 with the reason in err when the gate fails. Returns
 * exr_read's status for an image that cannot be read, RC_ERR_RANGE for sizes or channels that
 * do not match, RC_ERR_NOMEM.
 */
#ifndef REFLCHECK_COMPARE_H
#define REFLCHECK_COMPARE_H

#include <stddef.h>
#include <stdio.h>
#include "exr.h"
#include "scene.h"
#include "status.h"

typedef struct {
    int pass, warn, fail, skipped, error;
    int not_gated;            /* judged by guards alone (finite values, coverage): no accuracy gate */
    char first_failure[1024]; /* "scene: comparison: metric value > threshold (why)" */
} compare_summary;

rc_status compare_scene(const char *scene_path, const char *run_dir, compare_summary *sum, char *err, size_t errlen);

/* Metrics between two EXR images (regions from mask_exr's, else test's, coverage and object
 * layers; z-test where ref has var.* layers) and the value gate, printed as one JSON object
 * to out. */
rc_status compare_images(const char *test_exr, const char *ref_exr, const char *mask_exr, FILE *out, int *failed,
                         char *err, size_t errlen);

/* compare_scene's value gate on one image of a comparison (the side renderer renders in role),
 * for a command that uses such an image without comparing it (reflcheck fit): returns 1 when it
 * fails, with the clause compare.json's reason gives ("ref povray: 1 non-finite (first R at (x
 * 3, y 4) = nan) of N values; its output must be finite and >= 0") in gate, else 0. */
int compare_value_gate(const scene *s, const exr_image *img, int renderer, comparison_role role, const char *side,
                       char *gate, size_t len);

/* Relative error denominators r^2 + COMPARE_REL_EPS: below 1e-4 radiance a pixel is dark
 * enough that half-float and noise floors dominate; above it the error is truly relative. */
#define COMPARE_REL_EPS 1e-8

/* The largest share of the surface's interior pixels a reference's crease rules may set apart
 * (harness/crease.h) before the comparison fails, when the scene states no limit of its own: at
 * 2 % the surface figures still judge 98 % of the object. Measured small under Cycles' rules: 0
 * on every analytic shape, 0.8 % on real_spider, 2.7 % on real_house (which states its own). */
#define COMPARE_CREASE_MAX_SHARE 0.02

#endif
