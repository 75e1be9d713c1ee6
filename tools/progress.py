"""progress - done/total, the time left and the failures of a long stage, as it runs.

Usage (Python 3 standard library only):
  from progress import Progress
  p = Progress('sweep', total=367, weights=None, stream=sys.stderr)
  p.done(weight=1.0, failed=None)     # one unit finished; failed='scene/tag: why' names a failure now
  p.close()                           # the last line: done/total, failures, elapsed

  python3 tools/progress.py watch RUN --total N [--label renders] [--every 10] [--pid PID]
      Counts the job records (RUN/<scene>/<renderer>-<role>.json) as they appear until N are
      there or the watched process (--pid) ends; names each record whose status is not ok or
      skipped when it appears.
  python3 tools/progress.py each --label fits [--jobs N] [--log FILE] [--expect S] [--costs FILE]
          [--slots FIFO] -- CMD... ::: ITEM...
      Runs CMD once per ITEM, N at a time (default 1), with {} in CMD replaced by the item and
      {1}, {2}, ... by its tab-separated fields. --costs: one number an item (a line each); the
      items start highest cost first. --slots: a FIFO holding one byte a free slot, shared with
      other processes (bash ops/nightly.sh's compare): an item runs only while it holds one. Each item's output (stdout and stderr) is held
      until it ends and then appended whole to FILE, else to this stderr, in item order: the log
      reads the same whatever order the items end in. A failed item is named when it fails, with
      its exit status and its last line of output. Exit status: the highest of the items' (0
      when all succeeded).
  python3 tools/progress.py follow FILE --label sweep [--pid PID] [--every 10]
      Shows the LABEL progress lines another process writes to FILE (a Slurm job's output) until
      PID ends: FAILED lines as they appear, the latest done/total line at least every EVERY s.

--expect S (seconds, e.g. the same stage in the last run) gives a time left before the first
unit is done, for stages of one unit (stability, the report). REFLCHECK_PROGRESS=tty or log
overrides the terminal test, so a stage whose stderr goes through a pipe (tee) keeps the mode
of the terminal the nightly was started on.

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
import queue
import re
import subprocess
import sys
import tempfile
import threading
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

    def __init__(self, label, total, total_weight=None, stream=None, every=10.0, clock=time.monotonic, expected=None):
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
        self.expected = expected
        mode = os.environ.get('REFLCHECK_PROGRESS', '')
        self.written = None
        self.tty = mode == 'tty' or (mode != 'log' and hasattr(self.stream, 'isatty') and self.stream.isatty())

    def eta(self):
        """Seconds left; before the first unit is done, what is left of EXPECTED, else None."""
        elapsed = self.clock() - self.t0
        if self.total and self.n >= self.total:
            return 0.0
        if self.weight <= 0 or self.total_weight <= 0:
            # Past the expected time the estimate says nothing: unknown, rather than 0 s.
            if self.expected and elapsed < self.expected and self.n < self.total:
                return self.expected - elapsed
            return None
        left = max(0.0, self.total_weight - self.weight)
        return elapsed * left / self.weight

    def line(self):
        eta = self.eta()
        left = 'time left unknown' if eta is None else f'about {fmt_s(eta)} left'
        fails = f', {len(self.failures)} failed' if self.failures else ''
        return f'{self.label}: {self.n}/{self.total} done{fails}, {fmt_s(self.clock() - self.t0)} elapsed, {left}'

    def _write(self, text, final=False):
        self.written = text
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
        text = self.line()
        if self.tty:
            self.stream.write('\n' if text == self.written else '\r\033[K' + text + '\n')
            self.stream.flush()
        elif text != self.written:
            self._write(text, final=True)


def record_status(path):
    """A job record's (status, message, cached), or None while it is being written (not yet whole)."""
    try:
        with open(path, encoding='utf-8') as f:
            r = json.load(f)
    except (OSError, ValueError):
        return None
    if not isinstance(r, dict) or 'renderer' not in r:
        return None
    return r.get('status'), r.get('message', ''), r.get('cached') is True


def record_done(p, name, status, msg, cached):
    """Counts one job record in P: a failure named now; a cache hit, which costs nothing, leaves the
    work to come, and so the estimate, alone."""
    bad = status not in ('ok', 'skipped')
    if cached:
        p.total_weight = max(0.0, p.total_weight - 1.0)
    p.done(
        weight=0.0 if cached else 1.0,
        failed=f'{name}: {status}: {str(msg).splitlines()[0] if msg else ""}' if bad else None,
    )


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
            record_done(p, os.path.relpath(path, run)[: -len('.json')], *st)

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
    """Whether process PID still runs: an exited child its parent has not reaped yet (a zombie)
    has ended, though kill(pid, 0) still finds it."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    try:
        with open(f'/proc/{pid}/stat', encoding='ascii', errors='replace') as f:
            return f.read().rsplit(')', 1)[1].split()[0] != 'Z'
    except (OSError, IndexError):
        return True


def substitute(cmd, item):
    """CMD's words with {} replaced by ITEM and {1}, {2}, ... by its tab-separated fields, in one
    pass, so that an item holding braces is never substituted again."""
    fields = item.split('\t')

    def one(m):
        k = m.group(1)
        if not k:
            return item
        return fields[int(k) - 1] if 0 < int(k) <= len(fields) else m.group(0)

    return [re.sub(r'\{(\d*)\}', one, word) for word in cmd]


def last_line(text):
    """The last non-empty line of TEXT (bytes: what a failed command said last)."""
    lines = [x for x in text.decode('utf-8', 'replace').splitlines() if x.strip()]
    return lines[-1].strip() if lines else ''


def start_one(argv, done, index):
    """Starts ARGV with its output (stdout and stderr) in a private anonymous file, and a thread
    that puts (INDEX, exit status, that file) on the queue DONE when it ends. A command that
    cannot start is put there at once, with status 127 and the reason as its output."""
    out = tempfile.TemporaryFile()
    try:
        proc = subprocess.Popen(argv, stdout=out, stderr=subprocess.STDOUT)
    except OSError as e:
        out.write(f'cannot start {argv[0]}: {e.strerror}\n'.encode())
        done.put((index, 127, out))
        return

    def waiter():
        rc = proc.wait()
        # A signal's death (negative) is told as the shell tells it: 128 + the signal number.
        done.put((index, 128 - rc if rc < 0 else rc, out))

    threading.Thread(target=waiter, daemon=True).start()


class Slots:
    """Tokens of a FIFO that several processes share (one byte a free slot, as make's jobserver):
    ask() requests one, which a thread puts on QUEUE as (None, 0, None) once read; give() hands
    one back. Without a path every ask is granted at once."""

    def __init__(self, path, queue_):
        self.queue = queue_
        self.fd = os.open(path, os.O_RDWR) if path else None
        self.want = threading.Semaphore(0)
        if self.fd is not None:
            threading.Thread(target=self._reader, daemon=True).start()

    def _reader(self):
        while True:
            self.want.acquire()
            if os.read(self.fd, 1):
                self.queue.put((None, 0, None))

    def ask(self):
        if self.fd is None:
            self.queue.put((None, 0, None))
        else:
            self.want.release()

    def give(self):
        if self.fd is not None:
            os.write(self.fd, b'+')


def start_order(n, costs=None):
    """The items' indices in the order they start: by COSTS (one number an item) highest first,
    ties in item order, so the longest items do not end the stage on one core; else item order."""
    if costs is None:
        return list(range(n))
    if len(costs) != n:
        raise ValueError(f'{len(costs)} costs for {n} items')
    return sorted(range(n), key=lambda i: -costs[i])


def each(cmd, items, label, every, log=None, expected=None, poll=1.0, stream=None, jobs=1, costs=None, slots=None):
    """Runs CMD once per item, JOBS at a time, with progress; a failed item is named when it ends.
    Items start in start_order(COSTS); with SLOTS (a FIFO of tokens) each also holds a token
    while it runs, so that processes sharing the FIFO share its slots. Each item's output is held
    in its own file and appended whole to LOG (else this stderr) in item order, so the log reads
    the same whatever order the items start and end in."""
    p = Progress(label, len(items), stream=stream, every=every, expected=expected)
    done = queue.Queue()
    order = start_order(len(items), costs)
    tokens = Slots(slots, done)
    outputs = [None] * len(items)
    started = flushed = running = worst = held = asked = 0
    sink = open(log, 'ab') if log else None
    try:
        while flushed < len(items):
            while asked + held + running < max(1, jobs) and started + held + asked < len(items):
                tokens.ask()
                asked += 1
            while held and started < len(items):
                start_one(substitute(cmd, items[order[started]]), done, order[started])
                started, running, held = started + 1, running + 1, held - 1
            try:
                i, rc, out = done.get(timeout=poll)
            except queue.Empty:
                p.tick()
                continue
            if i is None:  # a slot granted
                asked, held = asked - 1, held + 1
                continue
            running -= 1
            tokens.give()
            out.seek(0)
            outputs[i] = out.read()
            out.close()
            worst = max(worst, rc)
            said = last_line(outputs[i]) if rc else ''
            why = f'exit {rc}' + (f': {said}' if said else '')
            p.done(failed=f"{items[i].replace(chr(9), ' ')}: {why}" if rc else None)
            # Whole items, in item order: those before an unfinished one wait for it.
            while flushed < len(items) and outputs[flushed] is not None:
                if sink:
                    sink.write(outputs[flushed])
                    sink.flush()
                else:
                    sys.stderr.flush()
                    os.write(sys.stderr.fileno(), outputs[flushed])
                outputs[flushed] = b''
                flushed += 1
    finally:
        if sink:
            sink.close()
    p.close()
    return worst


def follow(path, label, every, ended, poll=1.0, stream=None):
    """Echoes the LABEL progress lines a process writes to PATH until ended() says it ended."""
    p = Progress(label, 0, stream=stream, every=every)
    pos, buf, status, shown = 0, b'', None, None
    while True:
        finished = ended()
        try:
            with open(path, 'rb') as f:
                f.seek(pos)
                chunk = f.read()
        except OSError:
            chunk = b''
        pos += len(chunk)
        *whole, buf = (buf + chunk).split(b'\n')
        for raw in whole:
            # A writer's own terminal updates, if any: the text after the last carriage return.
            text = raw.decode('utf-8', 'replace').split('\r')[-1].replace('\033[K', '').strip()
            if text.startswith(f'{label}: FAILED'):
                p.stream.write(('\r\033[K' if p.tty else '') + text + '\n')
            elif text.startswith(f'{label}: '):
                status = text
        line = status or f'{label}: no progress line yet in {path}'
        now = p.clock()
        if finished or p.last is None or now - p.last >= every or (p.tty and line != shown):
            p.last, shown = now, line
            p._write(line, final=finished)
        if finished:
            return 0
        time.sleep(poll)


def main(argv=None):
    argv = sys.argv[1:] if argv is None else argv
    ap = argparse.ArgumentParser(description='progress of a long stage (see the docstring)')
    sub = ap.add_subparsers(dest='cmd', required=True)
    w = sub.add_parser('watch', help="follow a run folder's job records")
    w.add_argument('run')
    w.add_argument('--total', type=int, required=True)
    w.add_argument('--label', default='renders')
    w.add_argument('--every', type=float, default=10.0)
    w.add_argument('--pid', type=int, help='stop when this process ends')
    e = sub.add_parser('each', help='run a command once per item, with progress')
    e.add_argument('--label', required=True)
    e.add_argument('--every', type=float, default=10.0)
    e.add_argument('--log', help="append the commands' output to this file")
    e.add_argument('--expect', type=float, help='seconds the stage is expected to take')
    e.add_argument('--jobs', type=int, default=1, help='items run at a time (default 1)')
    e.add_argument('--costs', help='a file of one number an item: items start highest first')
    e.add_argument('--slots', help='a FIFO of slot tokens shared with other processes')
    f = sub.add_parser('follow', help="show another process's progress lines from its log")
    f.add_argument('file')
    f.add_argument('--label', required=True)
    f.add_argument('--every', type=float, default=10.0)
    f.add_argument('--pid', type=int, required=True, help='stop when this process ends')
    rest = []
    if argv and argv[0] == 'each' and '--' in argv:
        argv, rest = argv[: argv.index('--')], argv[argv.index('--') + 1 :]
    a = ap.parse_args(argv)
    if a.every <= 0 or (a.cmd == 'watch' and a.total < 0) or (a.cmd == 'each' and a.jobs < 1):
        print('progress.py: --total must be >= 0, --every > 0 and --jobs >= 1', file=sys.stderr)
        return 2
    if a.cmd == 'each':
        if ':::' not in rest or rest.index(':::') == 0:
            print('progress.py each: give -- CMD... ::: ITEM... (see the docstring)', file=sys.stderr)
            return 2
        cut = rest.index(':::')
        items = rest[cut + 1 :]
        costs = None
        if a.costs:
            try:
                with open(a.costs, encoding='utf-8') as f:
                    costs = [float(x) for x in f.read().split()]
                start_order(len(items), costs)  # the count checked here, before any item runs
            except (OSError, ValueError) as e:
                print(
                    f'progress.py each: --costs {a.costs}: {e}; give one number a line, one line an item',
                    file=sys.stderr,
                )
                return 2
        return each(rest[:cut], items, a.label, a.every, a.log, a.expect, jobs=a.jobs, costs=costs, slots=a.slots)
    if a.cmd == 'follow':
        return follow(a.file, a.label, a.every, lambda: not alive(a.pid))
    watch(a.run, a.total, a.label, a.every, (lambda: not alive(a.pid)) if a.pid else None)
    return 0


if __name__ == '__main__':
    sys.exit(main())
