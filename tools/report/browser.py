"""browser - headless Chromium on the pages from disk: screenshots, DOM dumps, load checks.

Usage:
    with Browser() as b:                        one Chromium for any number of pages
        b.screenshot('run/index.html', 'run/screenshot.png', (1400, 1000))
        bad = b.check_pages('run', ['index.html', 'scene-a.html'])   [(page, why)]
        b.check_pages('run', pages, shots={'index.html': ('run/shot.png', (1400, 1000))})
    dom = dump_dom('run/index.html')            one page, one Chromium (the tests' use)

A Chromium start costs about 0.7 s of CPU, more than loading a report page in it (0.1-0.3 s):
Browser starts one and drives it over the DevTools protocol on a pipe (--remote-debugging-pipe:
JSON messages ending in a NUL byte, commands on its fd 3, replies on its fd 4), so a report of
50 pages costs one start, not 50.
"""

import base64
import fcntl
import json
import os
import re
import select
import shutil
import subprocess
import tempfile
import time

from .util import CHROMIUM_TIMEOUT_S, load_ids

ATTR = load_ids()['attr']  # report.js's load markers on <body>
# How long a loaded page's report.js may take to settle its markers (data-ready): the old
# one-shot check gave the page 5 s of virtual time; a page without report.js ends there.
SETTLE_S = 5.0
# Pages the check loads at a time, each in a tab: a page's load is mostly one renderer process,
# so two would keep both cores of the nightly's machine busy if a settled page were seen at
# once; it is seen at the next look (POLL_S), and a third tab loads meanwhile.
TABS = 3
# Between two looks at a loading page: short beside a page's 0.1-0.3 s load, long enough that
# the looks themselves cost nothing.
POLL_S = 0.05
# The window a page loads in (width, height), the index's screenshot's size: a page the check
# loads for a screenshot of another size loads at that size instead.
WINDOW = (1400, 1000)


def chromium_exe():
    for n in ('chromium', 'chromium-browser', 'google-chrome'):
        p = shutil.which(n)
        if p:
            return p
    return None


FLAGS = [
    '--headless',
    '--no-sandbox',
    '--disable-gpu',
    '--disable-background-networking',
    '--disable-component-update',
    '--disable-sync',
    '--no-first-run',
    '--hide-scrollbars',
]


def chromium(args, page_path, timeout=CHROMIUM_TIMEOUT_S):
    """Runs headless chromium on a file:// page; returns CompletedProcess (stdout = DOM if asked)."""
    exe = chromium_exe()
    if not exe:
        raise FileNotFoundError('chromium not found; apt-get install chromium')
    with tempfile.TemporaryDirectory(prefix='reflcheck-chromium-') as prof:
        cmd = [exe] + FLAGS + [f'--user-data-dir={prof}', '--virtual-time-budget=5000'] + args
        cmd.append('file://' + os.path.abspath(page_path))
        return subprocess.run(cmd, capture_output=True, text=True, timeout=timeout)


def dump_dom(page_path):
    return chromium(['--dump-dom'], page_path).stdout


def _high_fd(fd):
    """fd moved to 10 or above, so that the child's dup to 3 and 4 cannot overwrite it."""
    high = fcntl.fcntl(fd, fcntl.F_DUPFD_CLOEXEC, 10)
    os.close(fd)
    return high


class Browser:
    """One headless Chromium, one tab, driven over the DevTools pipe (see the module's usage)."""

    def __init__(self, timeout=CHROMIUM_TIMEOUT_S):
        self.timeout = timeout
        self.proc = None
        self.next_id = 0
        self.buf = b''

    def __enter__(self):
        exe = chromium_exe()
        if not exe:
            raise FileNotFoundError('chromium not found; apt-get install chromium')
        self.prof = tempfile.mkdtemp(prefix='reflcheck-chromium-')
        cmd_r, self.cmd_w = os.pipe()
        self.reply_r, reply_w = os.pipe()
        cmd_r, reply_w = _high_fd(cmd_r), _high_fd(reply_w)
        # Debian's chromium is a shell script that execs the browser: bash (dash knows no fd
        # above 9) puts the pipe ends on 3 and 4, where --remote-debugging-pipe expects them.
        shell = f'exec "$@" 3<&{cmd_r} 4>&{reply_w} {cmd_r}<&- {reply_w}>&-'
        argv = [exe] + FLAGS + [f'--user-data-dir={self.prof}', '--remote-debugging-pipe', 'about:blank']
        try:
            self.proc = subprocess.Popen(
                ['/bin/bash', '-c', shell, 'chromium'] + argv,
                pass_fds=(cmd_r, reply_w),
                stdin=subprocess.DEVNULL,
                stdout=subprocess.DEVNULL,
                stderr=subprocess.DEVNULL,
            )
        finally:
            os.close(cmd_r)
            os.close(reply_w)
        self.session = self.new_tab()
        self.tabs = [self.session]
        return self

    def open_tabs(self, n):
        """The first n tabs, made where missing (the check's; opened ahead, they are ready when
        the pages are)."""
        while len(self.tabs) < n:
            self.tabs.append(self.new_tab())
        return self.tabs[:n]

    def __exit__(self, *exc):
        if self.proc is not None:
            try:
                self.call('Browser.close', timeout=5.0)
            except (OSError, RuntimeError):
                pass
            try:
                self.proc.wait(5.0)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
        for fd in (self.cmd_w, self.reply_r):
            os.close(fd)
        shutil.rmtree(self.prof, ignore_errors=True)
        return False

    def _message(self, deadline):
        while b'\0' not in self.buf:
            left = deadline - time.monotonic()
            if left <= 0 or not select.select([self.reply_r], [], [], left)[0]:
                raise RuntimeError(f'chromium did not answer within {self.timeout:.0f} s')
            chunk = os.read(self.reply_r, 1 << 16)
            if not chunk:
                raise RuntimeError(f'chromium ended (exit {self.proc.poll()}) during the report')
            self.buf += chunk
        msg, self.buf = self.buf.split(b'\0', 1)
        return json.loads(msg)

    def new_tab(self):
        """A tab of its own window (a window, so that Chromium does not throttle it as a
        background tab); its session id."""
        target = self.call('Target.createTarget', {'url': 'about:blank', 'newWindow': True})['targetId']
        session = self.call('Target.attachToTarget', {'targetId': target, 'flatten': True})['sessionId']
        self.call('Emulation.setFocusEmulationEnabled', {'enabled': True}, session)
        return session

    def call(self, method, params=None, session=None, timeout=None):
        """One DevTools command, to a tab's session if given; its result (events that arrive
        meanwhile are dropped)."""
        self.next_id += 1
        msg = {'id': self.next_id, 'method': method, 'params': params or {}}
        if session:
            msg['sessionId'] = session
        try:
            os.write(self.cmd_w, json.dumps(msg).encode() + b'\0')
        except BrokenPipeError:
            raise RuntimeError(f'chromium ended (exit {self.proc.poll()}) during the report') from None
        deadline = time.monotonic() + (timeout or self.timeout)
        while True:
            reply = self._message(deadline)
            if reply.get('id') == self.next_id:
                if 'error' in reply:
                    raise RuntimeError(f'chromium: {method}: {reply["error"].get("message")}')
                return reply.get('result', {})

    def evaluate(self, expression, session=None):
        r = self.call('Runtime.evaluate', {'expression': expression, 'returnByValue': True}, session or self.session)
        return r.get('result', {}).get('value')

    def navigate(self, page_path, size=WINDOW, session=None):
        """Starts loading the page in the tab at a window of size (width, height); settled()
        says when it is done."""
        session = session or self.session
        width, height = size
        self.call(
            'Emulation.setDeviceMetricsOverride',
            {'width': width, 'height': height, 'deviceScaleFactor': 1, 'mobile': False},
            session,
        )
        # The old document answers until the new one commits: it is marked, and not waited for.
        self.evaluate('window.reflcheckLeft = true', session)
        self.call('Page.navigate', {'url': 'file://' + os.path.abspath(page_path)}, session)
        return {'path': page_path, 'session': session, 'start': time.monotonic(), 'loaded': None}

    def settled(self, tab):
        """True once report.js has settled the page's markers, or SETTLE_S after the load for a
        page whose markers never come; RuntimeError past the time limit."""
        ready = (
            "window.reflcheckLeft ? 'left' : "
            f"document.readyState + ' ' + (document.body && document.body.getAttribute('{ATTR['ready']}'))"
        )
        state = str(self.evaluate(ready, tab['session']))
        now = time.monotonic()
        if state == 'complete 1':
            return True
        if state.startswith('complete'):
            tab['loaded'] = tab['loaded'] or now
            if now - tab['loaded'] > SETTLE_S:
                return True
        if now - tab['start'] > self.timeout:
            raise RuntimeError(f'{tab["path"]}: not loaded within {self.timeout:.0f} s')
        return False

    def open(self, page_path, size=WINDOW):
        """Loads the page in the first tab and waits until it has settled."""
        tab = self.navigate(page_path, size)
        while not self.settled(tab):
            time.sleep(POLL_S)

    def dom(self, page_path):
        self.open(page_path)
        return self.evaluate('document.documentElement.outerHTML') or ''

    def screenshot(self, page_path, png, size=WINDOW):
        self.open(page_path, size)
        self._capture(page_path, png, self.session)

    def _capture(self, page_path, png, session):
        data = self.call('Page.captureScreenshot', {'format': 'png'}, session).get('data')
        if not data:
            raise RuntimeError(f'chromium wrote no screenshot of {page_path}')
        tmp = f'{png}.tmp{os.getpid()}.png'
        with open(tmp, 'wb') as f:
            f.write(base64.b64decode(data))
        os.replace(tmp, png)

    def check_pages(self, run, pages, tabs=TABS, shots=None):
        """[(page, why)] for every page whose DOM does not show all of its images loaded
        (data-loaded="n/n", data-failed="0") or, for the index, no table rows; tabs pages load
        at a time, each in a tab of its own. shots {page: (png, (width, height))}: those pages
        load at that window size and are saved as png once settled, from the load the check
        looks at (one load a page, and the screenshots beside the other tabs' loads)."""
        shots = shots or {}
        todo = list(pages)
        idle = self.open_tabs(max(1, min(tabs, len(todo))))[::-1]
        busy, why = [], {}
        while todo or busy:
            while todo and idle:
                name = todo.pop(0)
                size = shots[name][1] if name in shots else WINDOW
                busy.append((name, self.navigate(os.path.join(run, name), size, idle.pop())))
            for name, tab in [b for b in busy if self.settled(b[1])]:
                if name in shots:
                    self._capture(tab['path'], shots[name][0], tab['session'])
                why[name] = page_problem(
                    name, self.evaluate('document.documentElement.outerHTML', tab['session']) or ''
                )
                busy.remove((name, tab))
                idle.append(tab['session'])
            if busy:
                time.sleep(POLL_S)
        return [(name, why[name]) for name in pages if why[name]]


def page_problem(name, dom):
    """Why the page's DOM fails the load check, or None."""
    m = re.search(ATTR['loaded'] + r'="(\d+)/(\d+)"', dom)
    failed = re.search(ATTR['failed'] + r'="(\d+)"', dom)
    if not m or m.group(1) != m.group(2) or (failed and failed.group(1) != '0'):
        return f'images loaded {m.group(0) if m else "marker missing"}, ' f'failed {failed.group(1) if failed else "?"}'
    if name == 'index.html' and '<tr' not in dom:
        return 'the comparisons table has no rows'
    return None


def screenshot(page_path, png, size=f'{WINDOW[0]},{WINDOW[1]}'):
    """One screenshot, one Chromium (size 'W,H')."""
    with Browser() as b:
        b.screenshot(page_path, png, tuple(int(v) for v in size.split(',')))


def check_pages(run, pages):
    with Browser() as b:
        return b.check_pages(run, pages)
