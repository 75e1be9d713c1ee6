#!/usr/bin/python3
"""report.py - the reflcheck report: HTML pages, summary.json/csv, JUnit XML and history of one run.

Usage (Python 3 with Debian's python3-jinja2; plots need the `gnuplot` program, screenshots `chromium`):
  python3 tools/report.py --run reports/runs/<id> [--history reports/local/history.jsonl]
                            [--reference-history reports/history.jsonl]
                            [--commit SHA] [--latest reports/latest] [--screenshot]
                            [--cache reports/cache/report]
  python3 tools/report.py --run reports/runs/<id> --history FILE --failed REASON
  python3 tools/report.py --propose-thresholds --run reports/runs/<id>

The command line only: the work is done by the package tools/report/ beside this file (load,
outputs, history, plots, pages with their Jinja2 templates, proposal, browser; reports/README.md).
Reads what the C harness wrote into the run folder (format: reports/FORMAT.md):
<scene>/compare.json, <scene>/<renderer>-<role>.json job records, <scene>/view.js, and the
optional stability.json, timing/*.json, figure1.svg and <scene>/figure1.json (the scene's
materials' reflectance against angle, `reflcheck eval materials`). It never renders or measures.
Writes into the run folder (each file through a temporary name, then rename): index.html,
scene-<name>.html, figure1-<name>.html (where <scene>/figure1.json is), report.css, report.js,
plots/*.svg, summary.json, summary.csv, junit.xml,
figures.md (the README's tables of this run),
and appends one line to the history file (one write() plus fsync, never truncating). The trend
plots show --reference-history's runs (read only, labelled ref-) and then --history's.
--cache DIR keeps each plot under the hash of its inputs (script, parameters, data) and copies
an unchanged one back; the others are drawn in batches, one gnuplot a batch, while the pages
are written. The one Chromium of --screenshot starts as the report begins and opens every page,
three at a time (reports/README.md, "Where its time goes"). --failed REASON writes no page: it records a run that ended before it could be reported.
A missing or corrupt input file is listed on the page and on stderr with its name; it is never
a crash. Exit status: 0 report written (whatever the verdicts), 1 an output could not be
written, 2 bad usage (run folder missing).
"""

import argparse
import json
import os
import subprocess
import sys
import tempfile
from concurrent.futures import ThreadPoolExecutor

# The package tools/report/ sits beside this file; its compiled files stay out of the tree.
sys.dont_write_bytecode = True
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

try:
    from report import pages
    from report.browser import TABS, WINDOW, Browser
    from report.figures import figures_md
    from report.history import append_history, failed_record, history_record, read_history, trend_history
    from report.load import load_run, verdict_counts
    from report.outputs import junit_xml, summary_csv, summary_object
    from report.plots import CACHE as PLOT_CACHE
    from report.plots import (
        draw_queued,
        plot_angles,
        plot_figure1,
        plot_timing,
        plot_trends,
        queue_plots,
        set_cache,
    )
    from report.proposal import proposal
    from report.util import ASSETS, VERDICTS, write_atomic
except ImportError as e:  # the one library outside the standard library: Jinja2, for the pages
    sys.exit(f'report: {e}; apt-get install python3-jinja2 (ops/deps.sh installs it)')

# ---------------------------------------------------------------------------------------------


def copy_assets(run):
    for f in ('report.css', 'report.js'):
        with open(os.path.join(ASSETS, f), 'rb') as src:
            write_atomic(os.path.join(run, f), src.read())


def make_report(args):
    # The one Chromium starts first, beside the loading and the plots: its start (1-2 s, mostly
    # waiting) then costs the report no wall time (browser.py).
    with ThreadPoolExecutor(1) as starter:
        browser = starter.submit(open_browser) if args.screenshot else None
        try:
            return write_report(args, browser)
        finally:
            if browser is not None and browser.exception() is None:
                browser.result().__exit__(None, None, None)


def open_browser():
    b = Browser()
    try:
        b.__enter__()
        b.open_tabs(TABS)
    except (OSError, RuntimeError, subprocess.TimeoutExpired):
        if b.proc is not None:  # started, then did not answer: not left running
            b.proc.kill()
            b.proc.wait()
        raise
    return b


def write_report(args, browser):
    R = load_run(args.run, args.commit)
    problems = R['problems']
    copy_assets(args.run)
    os.makedirs(os.path.join(args.run, 'plots'), exist_ok=True)
    history, local = [], []
    if args.history:
        rec = history_record(R)
        try:
            if not append_history(args.history, rec, problems):
                print(
                    f'report: {args.history}: run {R["run_id"]} already recorded with the same figures; '
                    'not appended again',
                    file=sys.stderr,
                )
        except OSError as e:
            problems.add(args.history, f'cannot append to history: {e.strerror}')
        local = read_history(args.history, problems)
    reference = read_history(args.reference_history, problems) if args.reference_history else []
    history = trend_history(reference, local)
    parts = []
    if args.reference_history:
        parts.append(f'{len(reference)} reference run{plural(reference)} from {args.reference_history} (labels ref-…)')
    if args.history:
        parts.append(f'{len(local)} run{plural(local)} of this history, {args.history}')
    note = 'trends: ' + ', then '.join(parts) if parts else 'no --history or --reference-history given: no trends'
    if args.cache:
        set_cache(os.path.join(args.cache, 'plots'))
    with tempfile.TemporaryDirectory(prefix='reflcheck-report-') as tmp, ThreadPoolExecutor(1) as drawer:
        # Each plot's data is written and its SVG named first; gnuplot then draws those the
        # cache does not hold in a few batches, one gnuplot a core, while the pages are written
        # with every plot named. A plot that could not be drawn (rare: its page would name a
        # missing file) has the pages written again without it, as when plots were drawn first.
        queue_plots()
        plots = {
            'angles': {s['name']: plot_angles(R, s, tmp, problems) for s in R['scenes']},
            'figure1': {s['name']: plot_figure1(R, s, tmp, problems) for s in R['scenes'] if s.get('figure1')},
            'trends': plot_trends(R, history, tmp, problems) if history else {},
            'timing': plot_timing(R, tmp, problems),
        }
        drawn = drawer.submit(draw_queued, problems, os.cpu_count() or 2)
        extra = write_pages(args, R, plots, note)
        failed = drawn.result()
    if failed:
        extra = write_pages(args, R, drop_plots(plots, args.run, failed), note)
    if args.cache:
        # The nightly's second run is checked by this line (tests/nightly_cache.sh).
        print(
            f'report: plots: {len(PLOT_CACHE.drawn)} drawn by gnuplot '
            f'({", ".join(plot_kinds(PLOT_CACHE.drawn)) or "none"}), {len(PLOT_CACHE.kept)} from {args.cache}'
        )
    if args.latest:
        point_latest(args.run, args.latest, problems)
    if browser is not None and check_in_browser(args.run, R, browser, extra):
        return 1
    n = verdict_counts(R)
    print(
        f'report: {os.path.join(args.run, "index.html")}: '
        + ', '.join(f'{n[v]} {v}' for v in VERDICTS)
        + f'; {len(problems.items)} input problems'
    )
    return 0


def drop_plots(plots, run, failed):
    """plots without the SVGs in failed (paths under run)."""
    gone = {os.path.relpath(f, run) for f in failed}
    out = {}
    for kind, per in plots.items():
        out[kind] = {}
        for k, v in per.items():
            if isinstance(v, dict):
                out[kind][k] = {a: p for a, p in v.items() if p not in gone}
            elif v not in gone:
                out[kind][k] = v
            elif kind == 'figure1':
                out[kind][k] = None
    return out


def write_pages(args, R, plots, note):
    """Every page and summary file of the run; the names of the pages beside the index and the
    scene pages."""
    angles, trends, figure1 = plots['angles'], plots['trends'], plots['figure1']
    for s in R['scenes']:
        write_atomic(
            os.path.join(args.run, s['page']), pages.scene_html(R, s, angles[s['name']], trends.get(s['name']))
        )
    summary = summary_object(R)
    write_atomic(os.path.join(args.run, 'summary.json'), json.dumps(summary, indent=1, allow_nan=False) + '\n')
    write_atomic(os.path.join(args.run, 'figures.md'), figures_md(summary))
    write_atomic(os.path.join(args.run, 'summary.csv'), summary_csv(R))
    write_atomic(os.path.join(args.run, 'junit.xml'), junit_xml(R))
    write_atomic(os.path.join(args.run, 'index.html'), pages.index_html(R, trends, plots['timing'], note))
    extra = []
    if R['optional']['stability'] is not None:
        write_atomic(os.path.join(args.run, 'stability.html'), pages.stability_html(R))
        extra.append('stability.html')
    if R['optional']['figure1']:
        write_atomic(os.path.join(args.run, 'figure1.html'), pages.figure1_html(R))
        extra.append('figure1.html')
    for s in R['scenes']:
        if s['name'] in figure1:
            write_atomic(os.path.join(args.run, s['figure1_page']), pages.figure1_scene_html(R, s, figure1[s['name']]))
            extra.append(s['figure1_page'])
    return extra


def check_in_browser(run, R, browser, extra):
    """The screenshots and the load check of every page in the one Chromium; True if a page
    failed the check."""
    try:
        b = browser.result()  # the start's error, if it failed, is raised here
        # The report as a person opens it: every page in headless Chromium, every table row
        # and image loaded (report.js's markers); a page that fails is named. The index and
        # the first scene page are saved as screenshots from the check's own load of them.
        opened = ['index.html'] + extra + [sc['page'] for sc in R['scenes']]
        shots = {'index.html': (os.path.join(run, 'screenshot.png'), WINDOW)}
        if R['scenes']:
            shots[R['scenes'][0]['page']] = (os.path.join(run, 'screenshot-scene.png'), (1400, 1400))
        bad = b.check_pages(run, opened, shots=shots)
    except (OSError, RuntimeError, subprocess.TimeoutExpired) as e:
        print(f'report: screenshot failed: {e}', file=sys.stderr)
        return False
    for page_name, why in bad:
        print(f'report: {page_name}: {why}', file=sys.stderr)
    print(
        f'report: opened {len(opened) - len(bad)} of {len(opened)} pages in headless Chromium with every image loaded'
    )
    return bool(bad)


def plot_kinds(svgs):
    """['3 trend', '1 angle']: the drawn plots counted by the first word of their name."""
    n = {}
    for p in svgs:
        kind = os.path.basename(p).split('-')[0]
        n[kind] = n.get(kind, 0) + 1
    return [f'{v} {k}' for k, v in sorted(n.items())]


def plural(items):
    return '' if len(items) == 1 else 's'


def record_failed(args):
    """--failed REASON: the run ended before its report; one history line says so."""
    if not args.history:
        print('report: --failed needs --history FILE (the history to record the failed run in)', file=sys.stderr)
        return 2
    rec = failed_record(os.path.basename(os.path.normpath(args.run)), args.commit, args.failed)
    try:
        append_history(args.history, rec, None)
    except OSError as e:
        print(f'report: {args.history}: cannot append the failed run: {e.strerror}', file=sys.stderr)
        return 1
    print(f'report: {args.history}: run {rec["run_id"]} recorded as failed: {args.failed}', file=sys.stderr)
    return 0


def point_latest(run, latest, problems):
    """Symlink to a temporary name, then rename over the old link: readers see old or new."""
    target = os.path.relpath(os.path.abspath(run), os.path.dirname(os.path.abspath(latest)))
    tmp = f'{latest}.tmp{os.getpid()}'
    try:
        if os.path.lexists(tmp):
            os.unlink(tmp)
        os.symlink(target, tmp)
        if os.path.isdir(latest) and not os.path.islink(latest):
            os.unlink(tmp)
            problems.add(latest, 'is a real folder, not a symlink; remove it so --latest can point it at the run')
            return
        os.replace(tmp, latest)
    except OSError as e:
        problems.add(latest, f'cannot point at the run: {e.strerror}')


def propose_main(args):
    R = load_run(args.run, args.commit)
    text, rows = proposal(R)
    sys.stdout.write(text)
    copy_assets(args.run)
    write_atomic(os.path.join(args.run, 'thresholds-proposal.html'), pages.proposal_html(R, text, rows))
    print(
        f'report: wrote {os.path.join(args.run, "thresholds-proposal.html")} (scene files unchanged)', file=sys.stderr
    )
    return 0


def main(argv=None):
    ap = argparse.ArgumentParser(description='Write the reflcheck report of one run folder.')
    ap.add_argument('--run', required=True, help='run folder, e.g. reports/runs/20250101-120000-abc1234')
    ap.add_argument('--history', help='append-only JSON-lines history, e.g. reports/history.jsonl')
    ap.add_argument(
        '--reference-history',
        help="the project's reference history, read only: trends show its runs (labelled ref) before --history's",
    )
    ap.add_argument(
        '--failed',
        metavar='REASON',
        help='the run ended before it could be reported: append a status "failed" line with REASON to --history',
    )
    ap.add_argument('--commit', help='commit of the run (default: from the run id, else "unknown")')
    ap.add_argument('--latest', help='symlink to point at this run, e.g. reports/latest')
    ap.add_argument(
        '--cache',
        help='keep the plots here (CACHE/plots/) and copy back those whose inputs did not change, '
        'e.g. reports/cache/report',
    )
    ap.add_argument(
        '--screenshot',
        action='store_true',
        help='after writing, save screenshot.png (index) and screenshot-scene.png with headless chromium',
    )
    ap.add_argument(
        '--propose-thresholds',
        action='store_true',
        help='print current and proposed thresholds, write thresholds-proposal.html, nothing else',
    )
    args = ap.parse_args(argv)
    if args.failed is not None:
        return record_failed(args)
    if not os.path.isdir(args.run):
        print(f'report: {args.run}: no such run folder; pass --run reports/runs/<id>', file=sys.stderr)
        return 2
    try:
        return propose_main(args) if args.propose_thresholds else make_report(args)
    except OSError as e:
        print(f'report: {getattr(e, "filename", "") or args.run}: cannot write: {e.strerror or e}', file=sys.stderr)
        return 1


if __name__ == '__main__':
    sys.exit(main())
