"""common.py - the sweep's levels and tolerances, and its atomic JSON writer (every module reads them)."""

import json
import math
import os
import tempfile

# The project root (tools/sweep/ is two folders below it).
ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


FORMAT = 'reflcheck-sweep-1'
CYCLES_SPP = (16, 64, 256, 1024)
REF_SPP = 4096
# Stage one's reference level (--levels staged): 256 spp, with 16 and 64 as points. It measures
# every non-Cycles error (0.005 and up on the canonical scenes, where a 256-spp reference's noise
# is a fraction of it) and Cycles' own slope over 16..64; 1024 and 4096 are rendered only where
# plan.stage_decision finds a figure they can change.
FIRST_REF_SPP = 256
QUICK_SPP, QUICK_REF = (16, 64, 256), 1024
RASTER_K = (1, 2, 4, 8)
RASTER_TESS = (8, 16, 32, 64, 128)
POV_K = (1, 2, 4)
QUICK_K, QUICK_TESS, QUICK_POV = (1, 2, 4), (16, 64), (1, 2)
# EEVEE's TAA samples per pixel: deterministic, so one render per level (no seeds). Its error
# is its approximation's, not sampling's (d3d_blinn_phong: 0.0827 at 1, 0.0824 at 16) and a job
# costs 30-75 s on llvmpipe, so two levels draw its line.
EEVEE_TAA = (1, 16)
QUICK_EEVEE = (1, 16)
SEEDS = 2
# The image terms, in the order of the renderers' layers and of RENDERER_TERM_* (renderer.h).
TERMS = ('diffuse', 'specular', 'reflection', 'emission')
RASTER_REPEATS = 3
JOB_TIMEOUT_S = 3600
# Spp slope within this of -0.5 is "Monte Carlo rate": with 4 levels and 2 seeds, the scatter of
# a fitted slope is a few hundredths; 0.1 flags a real departure, not noise.
SLOPE_TOL = 0.1
# A reported error is decided when its standard error (plan.error_sigma) is at most 10 %: the
# gates sit within about 3x of their figures (tools/gates.py), so 10 % moves no verdict, and it
# is above the few % two seeds resolve on a Cycles point of a few thousand pixels.
SIGMA_DECIDED = 0.1
BUDGETS_S = (1.0, 10.0, 100.0)
# Stage two's rule (plan.stage_decision) asks whether a figure is off by more than 2 standard
# errors: with two seeds a point's uncertainty is itself a rough estimate, and 2 sigma keeps a
# one-in-20 fluke from sending a scene deep while a real floor (many sigma) still does.
CONFIDENCE = 2.0
# A point's ln-error uncertainty without a pixel count (a diff that lacks it): 0.1, the scatter
# SLOPE_TOL above allows for.
SIGMA_NO_PIXELS = 0.1
# E[x^2] / E[x]^2 of a squared zero-mean Gaussian (x = z^2: E z^4 / (E z^2)^2 = 3): the least
# spread a pixel's squared error has; plan.point_sigma widens it where outliers dominate.
GAUSS_RATIO = 3.0


def write_json(path, obj):
    os.makedirs(os.path.dirname(path), exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=os.path.dirname(path), prefix='.sweep', suffix='.tmp')
    with os.fdopen(fd, 'w', encoding='utf-8') as f:
        json.dump(obj, f, indent=1, allow_nan=False, default=lambda o: None)
        f.write('\n')
    os.replace(tmp, path)


def clean_nan(o):
    if isinstance(o, float) and not math.isfinite(o):
        return None
    if isinstance(o, dict):
        return {k: clean_nan(v) for k, v in o.items()}
    if isinstance(o, list):
        return [clean_nan(v) for v in o]
    return o
