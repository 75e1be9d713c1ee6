"""progress - done/total, the time left and the failures of a long stage, as it runs.

Usage (Python 3 standard library only):
  from progress import Progress
  p = Progress('sweep', total=367, weights=None, stream=sys.stderr)
  p.done(weight=1.0, failed=None)     # one unit finished; failed='scene/tag: why' names a failure now
  p.close()                           # the last line: done/total, failures, elapsed

  python3 harness/progress.py watch RUN --total N [--label renders] [--every 10]
      Counts the job records (RUN/<scene>/<renderer>-<role>.json) as they appear until N are
      there or the watched process (--pid) ends; names each record whose status is not ok or
      skipped when it appears.

On a terminal the line is rewritten in place (one line that updates); in a log (not a tty) a
plain line is written at most every EVERY seconds (default 10) and at every failure, so a log
grows by a few lines a minute and never goes silent for longer than EVERY seconds while units
finish. The time left is the elapsed time scaled by the share of the work left, with work
counted in the caller's weights (a job's expected cost) when it gives them, else in units:
a linear estimate, said as such ("about"), that improves as the stage goes on.
"""

import argparse
import glob
import json
import os
import sys
import time


def fmt_s(s):
    """Seconds as '7 s', '3 min 05 s' or '1 h 02 min'."""
    s = int(round(max(0.0, s)))
    if s < 60:
        return f'{s} s'
    if s < 3600:
        return f'{s // 60} min {s % 60:02d} s'
    return f'{s // 3600} h {(s % 3600) // 60:02d} min'


class Progress:
    """done/total and an estimate of the time left for one stage of work."""

    def __init__(self, label, total, total_weight=None, stream=None, every=10.0, clock=time.monotonic):
        self.label = label
        self.total = max(0, int(total))
        self.total_weight = float(total_weight) if total_weight else float(self.total)
        self.stream = stream if stream is not None else sys.stderr
        self.every = every
        self.clock = clock
        self.t0 = clock()
        self.last = None
        self.n = 0
        self.weight = 0.0
        self.failures = []
        self.tty = hasattr(self.stream, 'isatty') and self.stream.isatty()

    def eta(self):
        """Seconds left, or None before the first unit is done."""
        if self.weight <= 0 or self.total_weight <= 0:
            return None
        elapsed = self.clock() - self.t0
        left = max(0.0, self.total_weight - self.weight)
        return elapsed * left / self.weight

    def line(self):
        eta = self.eta()
        left = 'time left unknown' if eta is None else f'about {fmt_s(eta)} left'
        fails = f', {len(self.failures)} failed' if self.failures else ''
        return (
            f'{self.label}: {self.n}/{self.total} done{fails}, {fmt_s(self.clock() - self.t0)} elapsed, {left}'
        )

    def _write(self, text, final=False):
        if self.tty:
            self.stream.write('\r\033[K' + text + ('\n' if final else ''))
        else:
            self.stream.write(text + '\n')
        self.stream.flush()

    def done(self, weight=1.0, failed=None):
        """One unit finished (its share of the work in the caller's weights); failed names it."""
        self.n += 1
        self.weight += weight
        now = self.clock()
        if failed:
            self.failures.append(failed)
            if self.tty:
                self.stream.write('\r\033[K')
            self.stream.write(f'{self.label}: FAILED {failed}\n')
        if self.tty or failed or self.last is None or now - self.last >= self.every or self.n == self.total:
            self.last = now
            self._write(self.line())

    def tick(self):
        """Called while nothing finishes: keeps a log from going silent longer than EVERY."""
        now = self.clock()
        if self.last is None or now - self.last >= self.every:
            self.last = now
            self._write(self.line())

    def close(self):
        self._write(self.line(), final=True)


def record_status(path):
    """A job record's (status, message), or None while it is being written (not yet whole)."""
    try:
        with open(path, encoding='utf-8') as f:
            r = json.load(f)
    except (OSError, ValueError):
        return None
    if not isinstance(r, dict) or 'renderer' not in r:
        return None
    return r.get('status'), r.get('message', '')


def watch(run, total, label, every, ended=None, poll=1.0, stream=None):
    """Follows a run folder's job records until TOTAL are whole or ended() says the work ended."""
    p = Progress(label, total, stream=stream, every=every)
    seen = set()

    def scan():
        for path in sorted(glob.glob(os.path.join(glob.escape(run), '*', '*-*.json'))):
            if path in seen:
                continue
            st = record_status(path)
            if st is None:
                continue
            seen.add(path)
            status, msg = st
            name = os.path.relpath(path, run)[: -len('.json')]
            bad = status not in ('ok', 'skipped')
            p.done(failed=f'{name}: {status}: {str(msg).splitlines()[0] if msg else ""}' if bad else None)

    while len(seen) < total:
        scan()
        if ended is not None and ended():
            scan()
            break
        p.tick()
        time.sleep(poll)
    p.close()
    return 1 if p.failures else 0


def alive(pid):
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def main(argv=None):
    ap = argparse.ArgumentParser(description='progress of a long stage (see the docstring)')
    sub = ap.add_subparsers(dest='cmd', required=True)
    w = sub.add_parser('watch', help="follow a run folder's job records")
    w.add_argument('run')
    w.add_argument('--total', type=int, required=True)
    w.add_argument('--label', default='renders')
    w.add_argument('--every', type=float, default=10.0)
    w.add_argument('--pid', type=int, help='stop when this process ends')
    a = ap.parse_args(argv)
    if a.total < 0 or a.every <= 0:
        print('progress.py: --total must be >= 0 and --every > 0', file=sys.stderr)
        return 2
    watch(a.run, a.total, a.label, a.every, (lambda: not alive(a.pid)) if a.pid else None)
    return 0


if __name__ == '__main__':
    sys.exit(main())
