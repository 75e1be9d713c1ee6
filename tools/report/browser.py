"""browser - headless Chromium on the pages from disk: screenshots, DOM dumps, load checks."""

import os
import re
import shutil
import subprocess
import tempfile

from .util import CHROMIUM_TIMEOUT_S, load_ids

ATTR = load_ids()['attr']  # report.js's load markers on <body>


def chromium_exe():
    for n in ('chromium', 'chromium-browser', 'google-chrome'):
        p = shutil.which(n)
        if p:
            return p
    return None


def chromium(args, page_path, timeout=CHROMIUM_TIMEOUT_S):
    """Runs headless chromium on a file:// page; returns CompletedProcess (stdout = DOM if asked)."""
    exe = chromium_exe()
    if not exe:
        raise FileNotFoundError('chromium not found; apt-get install chromium')
    with tempfile.TemporaryDirectory(prefix='reflcheck-chromium-') as prof:
        cmd = (
            [
                exe,
                '--headless',
                '--no-sandbox',
                '--disable-gpu',
                '--disable-background-networking',
                '--disable-component-update',
                '--disable-sync',
                '--no-first-run',
                '--hide-scrollbars',
                f'--user-data-dir={prof}',
                '--virtual-time-budget=5000',
            ]
            + args
            + ['file://' + os.path.abspath(page_path)]
        )
        return subprocess.run(cmd, capture_output=True, text=True, timeout=timeout)


def screenshot(page_path, png, size='1400,1000'):
    tmp = f'{png}.tmp{os.getpid()}.png'
    r = chromium([f'--screenshot={tmp}', f'--window-size={size}'], page_path)
    if not os.path.exists(tmp):
        raise RuntimeError(f'chromium wrote no screenshot ({r.returncode}): {r.stderr.strip()[-300:]}')
    os.replace(tmp, png)


def dump_dom(page_path):
    return chromium(['--dump-dom'], page_path).stdout


def check_pages(run, pages):
    """[(page, why)] for every page whose DOM in headless Chromium does not show all of its
    images loaded (data-loaded="n/n", data-failed="0") or, for the index, no table rows."""
    bad = []
    for name in pages:
        dom = dump_dom(os.path.join(run, name))
        m = re.search(ATTR['loaded'] + r'="(\d+)/(\d+)"', dom)
        failed = re.search(ATTR['failed'] + r'="(\d+)"', dom)
        if not m or m.group(1) != m.group(2) or (failed and failed.group(1) != '0'):
            bad.append(
                (
                    name,
                    f'images loaded {m.group(0) if m else "marker missing"}, '
                    f'failed {failed.group(1) if failed else "?"}',
                )
            )
        elif name == 'index.html' and '<tr' not in dom:
            bad.append((name, 'the comparisons table has no rows'))
    return bad
