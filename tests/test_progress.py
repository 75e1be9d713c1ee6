"""test_progress.py - tools/progress.py: done/total, the time left, failures named at once.

A fake clock and a string stream stand in for time and the terminal, so nothing here depends on
how fast the machine is.
Run: /usr/bin/python3 -m pytest -q -p no:cacheprovider tests/test_progress.py
"""

import io
import json
import os
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, 'tools'))
import progress  # noqa: E402


class Clock:
    def __init__(self):
        self.t = 100.0

    def __call__(self):
        return self.t


def make(total, weight=None, every=10.0):
    clock, out = Clock(), io.StringIO()
    return progress.Progress('sweep', total, weight, stream=out, every=every, clock=clock), clock, out


def test_time_left_scales_elapsed_by_the_work_left_in_weights():
    p, clock, _ = make(4, weight=10.0)
    assert p.eta() is None  # nothing done: no estimate
    clock.t += 30.0
    p.done(weight=7.5)  # three quarters of the work in 30 s: 10 s left
    assert abs(p.eta() - 10.0) < 1e-9
    assert 'about 10 s left' in p.line() and '1/4 done' in p.line()


def test_a_log_gets_a_line_at_most_every_period_and_always_the_last():
    p, clock, out = make(5, every=10.0)
    p.done()  # first line at once
    clock.t += 3.0
    p.done()  # within 10 s of the last line: quiet
    clock.t += 3.0
    p.tick()  # still quiet
    clock.t += 5.0
    p.tick()  # 11 s since the last line: a line
    clock.t += 1.0
    p.done()
    p.done()
    p.done()  # the last unit: a line
    lines = out.getvalue().splitlines()
    assert [line.split(' done')[0] for line in lines] == ['sweep: 1/5', 'sweep: 2/5', 'sweep: 5/5']


def test_a_failure_is_named_when_it_happens():
    p, clock, out = make(3)
    p.done()
    clock.t += 1.0
    p.done(failed='d3d_spot/cycles-16: failed: blender exit 1')
    lines = out.getvalue().splitlines()
    assert lines[1] == 'sweep: FAILED d3d_spot/cycles-16: failed: blender exit 1'
    assert '2/3 done, 1 failed' in lines[2]


def test_fmt_s():
    assert progress.fmt_s(7.4) == '7 s'
    assert progress.fmt_s(185) == '3 min 05 s'
    assert progress.fmt_s(3720) == '1 h 02 min'


def test_watch_counts_whole_records_and_names_failed_ones(tmp_path):
    run = tmp_path / 'run'
    (run / 'a').mkdir(parents=True)
    (run / 'a' / 'raster-twin.json').write_text(json.dumps({'renderer': 'raster', 'status': 'ok'}))
    (run / 'a' / 'povray-twin.json').write_text(
        json.dumps({'renderer': 'povray', 'status': 'failed', 'message': 'povray failed (exit status 1)\nmore'})
    )
    (run / 'a' / 'compare.json').write_text('{}')  # not a job record
    (run / 'a' / 'cycles-twin.json').write_text('{"renderer": "cy')  # still being written
    out = io.StringIO()
    # The work has ended (as when the watched make exits): the watch scans once more and stops.
    rc = progress.watch(str(run), 3, 'renders', 10.0, ended=lambda: True, poll=0.0, stream=out)
    text = out.getvalue()
    assert rc == 1
    assert 'renders: FAILED a/povray-twin: failed: povray failed (exit status 1)' in text
    assert text.splitlines()[-1].startswith('renders: 2/3 done, 1 failed')


def test_expected_time_gives_an_estimate_before_the_one_unit_ends():
    clock, out = Clock(), io.StringIO()
    p = progress.Progress('stability', 1, stream=out, clock=clock, expected=30.0)
    clock.t += 12.0
    assert abs(p.eta() - 18.0) < 1e-9
    clock.t += 40.0  # past the expected time: no estimate rather than a wrong one
    assert p.eta() is None


def test_each_runs_every_item_names_a_failure_when_it_ends_and_keeps_the_worst_status(tmp_path):
    log, out = tmp_path / 'fit.txt', io.StringIO()
    # Each item appends its fields to the log; the second one fails with exit 3. The first
    # item's record is written before the second starts, so its line precedes the failure.
    cmd = ['/bin/sh', '-c', 'echo "fit $0 $1"; [ "$1" != b.yaml ] || { echo "b: no reference" >&2; exit 3; }']
    rc = progress.each(
        cmd + ['{1}', '{2}'],
        ['seed\ta.yaml', 'seed\tb.yaml', 'wide\ta.yaml'],
        'fits',
        10.0,
        log=str(log),
        poll=0.01,
        stream=out,
    )
    assert rc == 3
    assert log.read_text().splitlines() == ['fit seed a.yaml', 'fit seed b.yaml', 'b: no reference', 'fit wide a.yaml']
    lines = out.getvalue().splitlines()
    assert 'fits: FAILED seed b.yaml: exit 3: b: no reference' in lines
    assert lines.index('fits: FAILED seed b.yaml: exit 3: b: no reference') < len(lines) - 1
    assert lines[-1].startswith('fits: 3/3 done, 1 failed')


def test_substitute_replaces_once_so_braces_in_an_item_stay():
    assert progress.substitute(['x{}', '{2}', '{1}', '{3}'], 'a{1}\tb') == ['xa{1}\tb', 'b', 'a{1}', '{3}']


def test_follow_shows_failures_and_the_latest_line_of_another_process(tmp_path):
    f = tmp_path / 'sweep.txt'
    f.write_text('sweep: 1/4 done\nnoise\nsweep: FAILED s/cycles-16: failed: exit 1\nsweep: 2/4 done, 1 failed\n')
    out = io.StringIO()
    progress.follow(str(f), 'sweep', 10.0, ended=lambda: True, poll=0.0, stream=out)
    assert out.getvalue().splitlines() == ['sweep: FAILED s/cycles-16: failed: exit 1', 'sweep: 2/4 done, 1 failed']


def test_an_exited_child_not_yet_reaped_is_not_alive():
    pid = os.fork()
    if pid == 0:
        os._exit(0)
    # Wait for its exit without reaping it (WNOWAIT): a zombie, which kill(pid, 0) still finds.
    os.waitid(os.P_PID, pid, os.WEXITED | os.WNOWAIT)
    os.kill(pid, 0)
    assert not progress.alive(pid)
    os.waitpid(pid, 0)
    assert not progress.alive(pid)


def test_watch_leaves_cache_hits_out_of_the_estimate(tmp_path):
    run = tmp_path / 'run'
    (run / 'a').mkdir(parents=True)
    # Two of four jobs came from the cache at once; the estimate counts the work that renders.
    for name, cached in (('raster-twin', True), ('exact-validate', True)):
        (run / 'a' / f'{name}.json').write_text(json.dumps({'renderer': 'x', 'status': 'ok', 'cached': cached}))
    clock, out = Clock(), io.StringIO()
    p = progress.Progress('renders', 4, stream=out, clock=clock)
    for path in sorted((run / 'a').glob('*.json')):
        progress.record_done(p, path.stem, *progress.record_status(str(path)))
    clock.t += 10.0
    assert p.eta() is None  # nothing rendered yet: no estimate from cache hits
    progress.record_done(p, 'a/povray-twin', 'ok', '', False)  # one render took 10 s; one is left
    assert abs(p.eta() - 10.0) < 1e-9
    progress.record_done(p, 'a/cycles-twin', 'ok', '', False)
    assert p.eta() == 0.0 and '4/4 done' in p.line()


# Each rendezvous item writes its first line, marks that it has started and then waits (at most
# about 20 s, a bound no item reaches unless it runs alone) for the other's mark: the two can
# only both succeed when they run at the same time. Item a also waits for b's end, so b ends
# first and the log must still hold a's lines before b's, each item's lines together.
RENDEZVOUS = (
    '[ -d "$2" ] || exit 8; echo "$0 first"; : > "$2/$0.started"; n=0; '
    'until [ -e "$2/$1.started" ]; do n=$((n + 1)); '
    '[ $n -gt 2000 ] && { echo "$0: $1 never started"; exit 9; }; sleep 0.01; done; '
    'echo "$0 second"; [ "$0" = b ] && { : > "$2/b.ended"; exit 0; }; n=0; '
    'until [ -e "$2/b.ended" ]; do n=$((n + 1)); [ $n -gt 2000 ] && exit 9; sleep 0.01; done'
)


def test_each_runs_jobs_at_once_and_keeps_each_items_output_together_in_item_order(tmp_path):
    log, out = tmp_path / 'fit.txt', io.StringIO()
    cmd = ['/bin/sh', '-c', RENDEZVOUS + '; [ "$0" != c ] || { echo "c: no reference"; exit 3; }', '{1}', '{2}', '{3}']
    items = [f'a\tb\t{tmp_path}', f'b\ta\t{tmp_path}', f'c\tc\t{tmp_path}']
    # c waits for its own mark, which it made: it passes the rendezvous and fails after it.
    rc = progress.each(cmd, items, 'fits', 10.0, log=str(log), poll=0.01, stream=out, jobs=2)
    assert rc == 3
    assert log.read_text().splitlines() == [
        'a first',
        'a second',
        'b first',
        'b second',
        'c first',
        'c second',
        'c: no reference',
    ]
    lines = out.getvalue().splitlines()
    assert f'fits: FAILED c c {tmp_path}: exit 3: c: no reference' in lines
    assert lines[-1].startswith('fits: 3/3 done, 1 failed')


def test_each_names_a_command_that_cannot_start_and_goes_on(tmp_path):
    log, out = tmp_path / 'log.txt', io.StringIO()
    rc = progress.each(
        [str(tmp_path / 'no-such-program'), '{}'], ['x', 'y'], 'fits', 10.0, log=str(log), poll=0.01, stream=out, jobs=2
    )
    assert rc == 127
    failed = [x for x in out.getvalue().splitlines() if 'FAILED' in x]
    assert len(failed) == 2 and failed[0].startswith('fits: FAILED x: exit 127: cannot start')


def test_each_starts_the_costliest_items_first_and_logs_in_item_order(tmp_path):
    log, out, started = tmp_path / 'fit.txt', io.StringIO(), tmp_path / 'started'
    cmd = ['/bin/sh', '-c', 'echo "$0" >> "$1"; echo "fit $0"', '{}', str(started)]
    # One at a time, so the start order is the order the marks land in.
    rc = progress.each(cmd, ['a', 'b', 'c', 'd'], 'fits', 10.0, log=str(log), poll=0.01, stream=out, costs=[1, 5, 3, 5])
    assert rc == 0
    assert started.read_text().split() == ['b', 'd', 'c', 'a']
    assert log.read_text().splitlines() == ['fit a', 'fit b', 'fit c', 'fit d']
    assert progress.start_order(3) == [0, 1, 2]


def test_each_holds_a_slot_of_the_shared_fifo_while_an_item_runs(tmp_path):
    fifo = tmp_path / 'slots'
    os.mkfifo(fifo)
    keep = os.open(fifo, os.O_RDWR | os.O_NONBLOCK)
    os.write(keep, b'+')  # one slot for everyone, though each may run 2 items at a time
    # Each item looks into the FIFO: the one token must be out of it (held for this item).
    look = (
        'import os, sys\n'
        'fd = os.open(sys.argv[1], os.O_RDWR | os.O_NONBLOCK)\n'
        'try:\n'
        '    os.write(fd, os.read(fd, 1)); print(sys.argv[2], "saw a free slot")\n'
        'except BlockingIOError:\n'
        '    print(sys.argv[2], "held the slot")\n'
    )
    log, out = tmp_path / 'log.txt', io.StringIO()
    rc = progress.each(
        [sys.executable, '-c', look, str(fifo), '{}'],
        ['a', 'b', 'c'],
        'compare',
        10.0,
        log=str(log),
        poll=0.01,
        stream=out,
        jobs=2,
        slots=str(fifo),
    )
    assert rc == 0
    assert log.read_text().splitlines() == ['a held the slot', 'b held the slot', 'c held the slot']
    assert os.read(keep, 8) == b'+'  # handed back, once
    os.close(keep)
