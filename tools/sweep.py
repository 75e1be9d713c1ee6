#!/usr/bin/python3
"""sweep.py - error against render time: every renderer's quality knobs, per canonical scene.

Usage (Python 3 standard library only; run from the project root after `make build/reflcheck`):
  /usr/bin/python3 tools/sweep.py --run reports/runs/<id> --cache reports/cache/sweep
                                    [--scenes scenes/a.yaml ...] [--quick] [--full-size]
                                    [--jobs 2] [--threads 1] [--clock wall|cpu] [--bin build/reflcheck]
                                    [--scheduler local|slurm] [--no-worker]

What it renders (in the scene's sweep role, below, through `reflcheck run --small --tag T
--threads 1`, two jobs at a time; outputs in RUN/timing/renders/<scene>/<tag>/):
  reference  Cycles at REF spp (4096; --quick 1024), 2 seeds: the best reference the scene has,
             as the pixel integral (--supersample 1) in every role.
  cycles     Cycles at 16, 64, 256, 1024 spp (--quick 16, 64, 256), 2 seeds each.
  Levels (--levels staged, the default; docs/sweep.md states the rule): stage one renders 16
  and 64 spp against 256 spp (seeds 0..1) as the reference; while plan.stage_decision finds a
  figure a deeper level can change (a crossover whose 2-sigma range reaches 1024 spp, the
  highest level the ladder makes a point; a top slope slower than -0.5 beyond 2 sigma; a
  decision error the reference's noise leaves more than 10 % uncertain), the reference becomes
  a point and the next level (1024, then REF spp) the reference, at fresh seeds (4..5, 6..7
  with `run --seed`). --levels all: every level and the REF-spp reference everywhere. Each
  scene's timing JSON (sweep.stage, deep_reference_why, not_deep), sweep.json and a line in the
  output say why it went deeper or what it left open.
  Order (tools/sweep/schedule.py, main.Pipeline): one queue for every stage; a scene is
  analysed the moment its last job lands and its next reference goes first in line, so deeper
  stages overlap other scenes' stage one (twins queued first); POV-Ray jobs, which wait on
  POV-Ray's own timers rather than compute, take --jobs slots of their own beside the CPU slots.
  Second runs: a raster job's repeats (CACHE/repeats/<key>.json) and the diffs of cached renders
  (CACHE/diffs/) are kept in the cache, so a run over a warm cache renders and diffs nothing new.
  raster     as-is (the scene's small-variant supersampling and tessellation, per-pixel),
             k = 1, 2, 4, 8; tessellation 8, 16, 32, 64, 128 (every object); per-vertex shading.
             Raster jobs take milliseconds, so each is rendered RASTER_REPEATS times without the
             cache and the fastest time is kept (the usual benchmark minimum: noise only adds).
  povray     k = 1, 2, 4 where POV-Ray can express the validate scene (a skipped job is listed).
  eevee      TAA samples 1, 16, on scenes whose comparisons name eevee (it is judged there):
             Blender's real-time engine on the same Blender scene as Cycles.
Scenes: those of --scenes (default scenes/*.yaml). The role is `validate` where the comparisons
list `reference: cycles, role: validate` (the physical reference: raster error is the
approximation's), else `twin` where they list Cycles twin (the converged render of our own
model: raster error is sampling and harness error); scenes with neither are left out.
Size: the scene's small variant (`reflcheck run --small`; 96 pixels wide unless the scene says
otherwise), or the full size with --full-size (`reflcheck run` has no width/height option).
Errors: `reflcheck diff POINT.exr REFERENCE.exr --mask RASTER-AS-IS.exr`, surface region (a
scene analysis sends all its pairs to one `reflcheck diff --pairs -` process). A
partial twin (the reference's record lists `terms_left_out`: Cycles has no Blinn-Phong lobe, so
its twin leaves the specular out) is compared as compare.json compares it: on the terms both
sides render (`diff --leave-out TERMS` takes those layers off every image), so the error is the
sampling and harness error of the terms compared, not the size of the missing term.
Blender: Cycles jobs render in a pool of --jobs Blender workers (harness/renderers/cycles/
worker_pool.py), so Blender starts once per worker, not per job, and a Cycles job's time is its
scene build and render without Blender's start-up (--no-worker: one Blender per job, as before;
the images are the same bit for bit). Worker logs go to RUN/worker-N.log.
Slurm (--scheduler slurm, inside the allocation the nightly submits): every job is an srun step
of its own (its id, JOB.STEP, in its record); the workers run in the allocation's batch step.

Writes RUN/timing/<scene>.json (read by tools/report.py; format below), RUN/sweep.json (the
sweep's own cost: wall time, job count, cached jobs) and prints one line per scene.

timing/<scene>.json:
  {"format": "reflcheck-sweep-1", "scene": NAME, "size": [W, H], "error_key": "error",
   "clock": "wall_s"|"cpu_s" (what time_s holds),
   "error_doc": what "error" means (below),
   "reference": {"renderer": "cycles", "role": "validate"|"twin", "samples": N, "seeds": [0, 1],
                 "terms_left_out": [TERM, ...] (what the reference's record says it left out; every
                 diff leaves them out too), "terms_compared": [TERM, ...],
                 "noise_nrmse": its own noise (from its var.* layers), "nested": true|false,
                 "note": how the sweep's seeds relate to the reference's},
   "series": [{"label": "cycles spp", "renderer": "cycles", "knob": "samples",
               "fit": FIT, "fit_spp": FIT (cycles only), "time_model": {"t0_s", "s_per_spp"}
               (cycles only), "slope_note": text (cycles only),
               "points": [POINT, ...]}, ...],
   "as_is": POINT (the raster as-is),
   "pareto": [{"label", "renderer", "time_s", "error"}, ...]   (ascending time),
   "equal_time": [{"budget_s", "budget": "raster as-is"|"1 s"|..., "best": {renderer: {"label",
                   "time_s", "error"} | null}, "cycles_fit_error": number | null}, ...],
   "crossover": {"raster_error", "spp", "time_s", "render_s", "loglog_time_s", "extrapolated":
                 null|"below"|"above", "upper_bound_s" (with "below": the lowest level's time),
                 "note"} | null,
   "crossover_best_raster": same, against the raster's best point,
   "sweep": {"jobs", "cached", "wall_s", "job_time_sum_s"},
   "skipped": [{"label", "message"}, ...]}
  POINT: {"label", "renderer", "tag", "time_s" (the job's wall time, or with --clock cpu its CPU
          time; --threads 1), "wall_s", "cpu_s",
          "render_s" (Cycles: build + render inside Blender, without its start-up), "samples",
          "seeds", "supersample", "tessellation", "per_vertex", "cached",
          "rmse", "nrmse", "rel_rms", "psnr", "ssim" (raw, against the reference, surface),
          "error" (estimated NRMSE against the noise-free image; plotted and fitted),
          "noise_nrmse" (Cycles: the point's own noise from its var.* layers),
          "is_reference" (the reference itself; error = its noise estimate, never fitted)}
  FIT: {"slope", "intercept", "r2", "n", "x": "time_s"|"samples", "local": [{"from", "to",
        "slope"}]} - least squares of ln(error) on ln(x).

"error" and the reference's seeds: `reflcheck run` renders Cycles seeds 0..n-1 and PMJ sampling
is nested (the first n samples of a seed at 4096 spp are the n-spp render), so a sweep point is
part of the reference: measured MSE = var_n (1 - n/N) for independent samples. error =
nrmse / sqrt(1 - n/N) undoes it. With disjoint seeds (`run --seed`, when the CLI has it) the
reference noise adds instead, and error = sqrt(nrmse^2 - noise_ref^2). Non-Cycles points
subtract the reference noise the same way (negligible beside a model error).
Crossover: Cycles' spp at which its fitted error (ln error on ln spp) equals the raster as-is
error, turned into seconds by linear interpolation of the measured (spp, time) levels (below
the fewest samples: that level's time, an upper bound), and, for comparison, by the ln error on
ln time fit. The least-squares time model time = t0 + c * spp (t0: Blender's start-up and the
scene build) gives the fitted Cycles error at each equal-time budget.

Exit status: 0 every scene written (failed jobs are listed in the file), 1 a scene could not be
swept (reference or raster as-is missing), 2 bad usage.

The command line only: the work is done by the package tools/sweep/ beside this file (common:
levels and tolerances; fitmath: the fits; scenes: the scene facts `reflcheck check --json` gives;
runner: one job and one diff; plan: the jobs and stages; analysis: a scene's timing JSON; main:
the command line). This file re-exports the package's names (tests/test_sweep.py reads them here).
"""

import os
import sys

# The package tools/sweep/ sits beside this file; its compiled files stay out of the tree.
sys.dont_write_bytecode = True
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

from sweep import *  # noqa: E402,F401,F403  (the package's names, for its tests)
from sweep.main import main  # noqa: E402

if __name__ == '__main__':
    sys.exit(main())
