"""util - the bottom of the report package: constants of the run format, number formatting,
strict JSON, JSON for inline scripts, atomic writes and the list of input problems.
Imports nothing from the package, so every other module can import it.
"""

import json
import math
import os
import re
import sys

TOOLS = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
ASSETS = os.path.join(TOOLS, 'report_assets')
PLOTS = os.path.join(TOOLS, 'plots')
# Element ids, data attributes and page-data names shared by the templates and report.js.
IDS_FILE = os.path.join(ASSETS, 'ids.json')

# not_gated: a comparison whose thresholds only guard its inputs (finite values, coverage) and
# hold: measured, shown, never called pass (harness/compare.h).
VERDICTS = ('fail', 'error', 'warn', 'skipped', 'not_gated', 'pass')
VERDICT_ORDER = {v: i for i, v in enumerate(VERDICTS)}
JOB_ORDER = {'crashed': 0, 'failed': 1, 'timeout': 2, 'error': 3, 'skipped': 4, 'ok': 5}
HIGHER_BETTER = ('psnr', 'ssim', 'coverage_agreement')
# Error-like figures spanning decades: always shown as 1.23e-4 so columns compare at a glance.
REL_METRICS = (
    'mae',
    'rmse',
    'rel_mse',
    'rel_rms',
    'max_abs',
    'share_over',
    'max_rel',
    'mean_rel',
    'error',
    'ref_rel_rms',
    'share_fail_pixels',
    'z_fail_share',
    'rel',
)
# Trend plots show at most this many runs: older points crowd the axis without changing the story.
TREND_RUNS = 60
GNUPLOT_TIMEOUT_S = 60
CHROMIUM_TIMEOUT_S = 90


class Problems:
    """Missing or corrupt inputs: listed on the page and echoed to stderr as they are found."""

    def __init__(self):
        self.items = []

    def add(self, path, message, scene=None):
        self.items.append({'file': path, 'message': message, 'scene': scene})
        print(f'report: {path}: {message}', file=sys.stderr)


def is_num(v):
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def finite(v):
    return is_num(v) and math.isfinite(v)


def clean(o):
    """Strict JSON: NaN/Inf become null so every consumer can parse summary.json."""
    if isinstance(o, float) and not math.isfinite(o):
        return None
    if isinstance(o, dict):
        return {str(k): clean(v) for k, v in o.items()}
    if isinstance(o, (list, tuple)):
        return [clean(v) for v in o]
    return o


def fexp(v, digits=2):
    """1.23e-4 style (short exponent), for the relative metrics spanning many decades."""
    if not is_num(v):
        return '—'
    if not math.isfinite(v):
        return str(v)
    if v == 0:
        return '0'
    s = f'{v:.{digits}e}'
    m, e = s.split('e')
    return f'{m}e{int(e)}'


def fmt_metric(name, v):
    base = name.split('.')[-1]
    if not is_num(v):
        return '—' if v is None else str(v)
    if not math.isfinite(v):
        return str(v)
    if base in ('n_pixels', 'n_tests', 'n_fail', 'n_fail_pixels', 'max_x', 'max_y', 'samples'):
        return str(int(v))
    if base == 'psnr':
        return f'{v:.2f}'
    if base in ('ssim', 'coverage_agreement'):
        return f'{v:.6f}'
    if base in ('z_crit', 'max_abs_z'):
        return f'{v:.3g}'
    if base in REL_METRICS:
        return fexp(v)
    return f'{v:.4g}' if 1e-2 <= abs(v) < 1e5 else fexp(v)


def fthr(name, v):
    """A threshold limit as written in a scene file: 5e-3, not 5.00e-3."""
    if not finite(v) or name.split('.')[-1] in ('psnr', 'ssim', 'coverage_agreement'):
        return fmt_metric(name, v)
    return yaml_num(float(f'{v:.3g}'))


def chan_name(c):
    if is_num(c) and int(c) in (0, 1, 2, 3):
        return 'RGBA'[int(c)]
    return '' if c is None else str(c)


def safe_name(name):
    return re.sub(r'[^A-Za-z0-9_.-]', '_', name)


def json_script(o):
    """JSON for an inline <script>. No '<', '>' or '&' may appear raw: '</script' ends the element
    early and '<!--' followed by '<script' makes the parser swallow the closing tag (a scene
    named after a file such as '<!--<script>.yaml'), so all three become JSON \\u escapes."""
    text = json.dumps(clean(o), separators=(',', ':'))
    return text.replace('<', '\\u003c').replace('>', '\\u003e').replace('&', '\\u0026')


def write_atomic(path, data):
    """Readers never see a half-written file: write a temporary sibling, fsync, rename."""
    if isinstance(data, str):
        data = data.encode('utf-8')
    os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
    tmp = f'{path}.tmp{os.getpid()}'
    with open(tmp, 'wb') as f:
        f.write(data)
        f.flush()
        os.fsync(f.fileno())
    os.replace(tmp, path)


def read_json(path, problems, what, scene=None):
    try:
        with open(path, 'rb') as f:
            raw = f.read()
    except FileNotFoundError:
        problems.add(path, f'{what} missing; run the harness step that writes it', scene)
        return None
    except OSError as e:
        problems.add(path, f'{what} unreadable: {e.strerror}', scene)
        return None
    try:
        return json.loads(raw.decode('utf-8'))
    except (UnicodeDecodeError, ValueError) as e:
        problems.add(path, f'{what} corrupt: {e}; re-run the step that writes it', scene)
        return None


def yaml_num(v):
    if not is_num(v):
        return str(v)
    if v == 0:
        return '0'
    if 0.1 <= abs(v) < 1e4:
        return f'{v:.6g}'
    s = f'{v:.6e}'
    m, e = s.split('e')
    m = m.rstrip('0').rstrip('.')
    return f'{m}e{int(e)}'


def fsec(v):
    """Seconds: 3 significant digits, '—' when absent."""
    return '—' if not finite(v) else (f'{v:.3g}' if v >= 1e-3 else fexp(v))


def load_ids():
    """The names shared with report.js (report_assets/ids.json), as a plain dict."""
    with open(IDS_FILE, encoding='utf-8') as f:
        return json.load(f)
