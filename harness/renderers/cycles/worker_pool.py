"""worker_pool.py - N Blender processes that render Cycles (or EEVEE) jobs without starting
Blender per job.

Usage (Python 3 standard library; tools/sweep.py and the nightly's make use it):
    with WorkerPool(n=2) as pool:
        env = dict(os.environ, **pool.env())        REFLCHECK_CYCLES_WORKER=<socket>
        subprocess.run([bin, 'run', scene, '--renderer', 'cycles', ...], env=env)
    with WorkerPool(n=2, renderer='eevee', threads=1) as pool:   EEVEE: under the pool's own
        env = dict(os.environ, **pool.env())        Xvfb; REFLCHECK_EEVEE_WORKER(_THREADS)
`reflcheck run` hands its Blender step to an idle worker through the socket (harness/
renderers/cycles/cycles_worker.c) instead of starting Blender; everything else about the job
(cache, key, collection of the seeds, record, log) is the same code as without a pool. The
workers (worker.py) share one listening socket, so a job goes to whichever is idle. A worker
that dies (a client timed out or was killed mid-render, Blender crashed) is started again.
The workers start when the first job connects, so a run whose jobs the cache answers starts
no Blender.
Leaving the `with` block stops every worker; they also die with this process (SIGKILL via
PR_SET_PDEATHSIG), and so does an EEVEE pool's Xvfb: no Blender or Xvfb outlives the run.
"""

import contextlib
import ctypes
import os
import select
import shutil
import signal
import socket
import subprocess
import tempfile
import threading
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ENV_VAR = 'REFLCHECK_CYCLES_WORKER'
# EEVEE's workers: the socket, and the llvmpipe threads every worker draws with (fixed when it
# starts; harness/renderers/eevee/eevee.c hands over only jobs that ask for that many).
EEVEE_ENV_VAR = 'REFLCHECK_EEVEE_WORKER'
EEVEE_THREADS_VAR = 'REFLCHECK_EEVEE_WORKER_THREADS'
EEVEE_SCRIPT = os.path.join(HERE, '..', 'eevee', 'eevee_worker.py')
# Xvfb's screen as eevee.c gives xvfb-run: EEVEE renders off-screen, the size only has to exist.
XVFB_SCREEN = ['-screen', '0', '640x480x24']
PR_SET_PDEATHSIG = 1


def _die_with_parent():
    """In the child before exec: SIGKILL when the pool's process dies, however it dies."""
    libc = ctypes.CDLL(None, use_errno=True)
    libc.prctl(PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0)


class WorkerPool:
    def __init__(self, n, blender='blender', log_dir=None, renderer='cycles', threads=1):
        """renderer 'cycles', or 'eevee': workers under one Xvfb of the pool's own, drawing with
        threads llvmpipe threads."""
        self.n = n
        self.blender = blender
        self.renderer = renderer
        self.threads = threads
        self.xvfb = None
        self.display = None
        self.dir = tempfile.mkdtemp(prefix='reflcheck-workers-')
        self.path = os.path.join(self.dir, 'socket')
        self.log_dir = log_dir or self.dir
        self.sock = None
        self.procs = []
        self.starts = 0
        self.stopping = threading.Event()
        self.lock = threading.Lock()
        self.monitor = None

    def env(self):
        if self.renderer == 'eevee':
            return {EEVEE_ENV_VAR: self.path, EEVEE_THREADS_VAR: str(self.threads)}
        return {ENV_VAR: self.path}

    def _start_xvfb(self):
        """The EEVEE workers' display: Xvfb picks a free one and names it on a pipe when it is
        ready (-displayfd), so two pools never race for a number."""
        r, w = os.pipe()
        try:
            self.xvfb = subprocess.Popen(
                ['Xvfb', '-displayfd', str(w), '-nolisten', 'tcp'] + XVFB_SCREEN,
                stdin=subprocess.DEVNULL,
                stdout=subprocess.DEVNULL,
                stderr=subprocess.DEVNULL,
                pass_fds=(w,),
                preexec_fn=_die_with_parent,
            )
        finally:
            os.close(w)
        with os.fdopen(r, 'rb') as f:
            line = f.readline().strip()
        if not line.isdigit():
            raise OSError('Xvfb did not start (exit %s); install it with: apt-get install xvfb' % self.xvfb.poll())
        self.display = ':' + line.decode()

    def _start_one(self):
        name = 'eevee-worker-%d.log' if self.renderer == 'eevee' else 'worker-%d.log'
        log = open(os.path.join(self.log_dir, name % self.starts), 'ab')
        self.starts += 1
        fd = self.sock.fileno()
        script, env = os.path.join(HERE, 'worker.py'), None
        if self.renderer == 'eevee':
            if self.xvfb is None or self.xvfb.poll() is not None:
                self._start_xvfb()
            script = EEVEE_SCRIPT
            env = dict(os.environ, DISPLAY=self.display, LP_NUM_THREADS=str(self.threads))
        p = subprocess.Popen(
            [self.blender, '-b', '--factory-startup', '--python-exit-code', '1', '-P', script, '--', str(fd)],
            env=env,
            stdin=subprocess.DEVNULL,
            stdout=log,
            stderr=subprocess.STDOUT,
            pass_fds=(fd,),
            preexec_fn=_die_with_parent,
        )
        log.close()
        return p

    def _start_all(self):
        """The n workers; False when they cannot start (Xvfb failed): the socket is closed, so
        that the waiting jobs end (recorded crashed) instead of waiting for their time limit."""
        try:
            self.procs = [self._start_one() for _ in range(self.n)]
            return True
        except OSError as e:
            with open(os.path.join(self.log_dir, 'worker-pool.log'), 'a') as f:
                f.write('worker_pool.py: cannot start the %s workers: %s\n' % (self.renderer, e))
            self.sock.close()
            return False

    def _watch(self):
        # The workers start when the first job knocks (a connection waits on the socket): a run
        # whose jobs all come from the cache starts no Blender (1 s of CPU each).
        while not self.procs and not self.stopping.is_set():
            if select.select([self.sock], [], [], 0.2)[0]:
                with self.lock:
                    if not self.stopping.is_set() and not self._start_all():
                        return
        while not self.stopping.wait(0.2):
            with self.lock:
                for i, p in enumerate(self.procs):
                    if p.poll() is not None and not self.stopping.is_set():
                        try:
                            self.procs[i] = self._start_one()
                        except OSError:  # Xvfb cannot start again: the jobs go without
                            self.sock.close()
                            return

    def __enter__(self):
        if shutil.which(self.blender) is None:
            raise OSError('%s is not installed; install it with: apt-get install blender' % self.blender)
        self.sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        self.sock.bind(self.path)
        # Every job of the sweep may wait in the backlog at once; the kernel caps it anyway.
        self.sock.listen(4096)
        self.monitor = threading.Thread(target=self._watch, daemon=True)
        self.monitor.start()
        return self

    def __exit__(self, *exc):
        self.stopping.set()
        if self.monitor:
            self.monitor.join()
        with self.lock:
            for p in self.procs:
                if p.poll() is None:
                    p.terminate()
            deadline = time.monotonic() + 5.0
            for p in self.procs:
                try:
                    p.wait(max(0.1, deadline - time.monotonic()))
                except subprocess.TimeoutExpired:
                    p.kill()
                    p.wait()
            if self.xvfb is not None:
                self.xvfb.terminate()
                self.xvfb.wait()
        if self.sock:
            self.sock.close()
        shutil.rmtree(self.dir, ignore_errors=True)
        return False


def main(argv):
    """`python3 worker_pool.py --workers N [--log-dir DIR] [--eevee-threads T] -- COMMAND ...`:
    COMMAND runs with REFLCHECK_CYCLES_WORKER set, so every `reflcheck run` it starts (the
    nightly's make) hands its Cycles render to one of N Blender workers, and with --eevee-threads
    (and Xvfb installed) its EEVEE render to one of N more; the workers stop when COMMAND ends. Exit
    status: COMMAND's (SIGTERM, SIGINT, SIGHUP end COMMAND first, then the workers)."""
    import argparse

    ap = argparse.ArgumentParser(description=main.__doc__.split('\n')[0])
    ap.add_argument('--workers', type=int, default=2, help='Blender workers (default 2)')
    ap.add_argument('--log-dir', help="the workers' logs (worker-N.log; default a temporary folder)")
    ap.add_argument(
        '--eevee-threads',
        type=int,
        metavar='T',
        help='also N EEVEE workers under an Xvfb of their own, llvmpipe drawing with T threads, for the '
        'EEVEE jobs that ask for T threads (eevee-worker-N.log)',
    )
    ap.add_argument('command', nargs=argparse.REMAINDER, help='-- COMMAND ...')
    args = ap.parse_args(argv)
    cmd = args.command[1:] if args.command[:1] == ['--'] else args.command
    if not cmd or args.workers < 1:
        ap.error('give --workers N (1 or more) and a command after --')
    eevee = contextlib.nullcontext()
    if args.eevee_threads and shutil.which('Xvfb'):
        eevee = WorkerPool(args.workers, log_dir=args.log_dir, renderer='eevee', threads=args.eevee_threads)
    with WorkerPool(args.workers, log_dir=args.log_dir) as pool, eevee as eevee_pool:
        env = dict(os.environ, **pool.env())
        if eevee_pool is not None:
            env.update(eevee_pool.env())
        child = subprocess.Popen(cmd, env=env)

        def stop(signum, _frame):
            child.send_signal(signum)

        for s in (signal.SIGTERM, signal.SIGINT, signal.SIGHUP):
            signal.signal(s, stop)
        rc = child.wait()
        return rc if rc >= 0 else 128 - rc  # a signal's death as a shell reports it


if __name__ == '__main__':
    import sys

    sys.exit(main(sys.argv[1:]))
