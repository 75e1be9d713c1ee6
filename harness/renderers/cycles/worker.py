"""worker.py - one Blender process that renders many reflcheck Cycles jobs in turn.

Usage (worker_pool.py starts it; nothing else should):
    blender -b --factory-startup --python-exit-code 1 -P worker.py -- FD
FD is a listening Unix stream socket the process inherited; several workers may share one
socket, and the kernel hands each connection to one idle worker. Per connection, one job:
    request   one JSON line {"job": JOB.json, "out": OUT.exr, "log": LOG, "threads": N}
    reply     {"started": PID} when the worker takes the job, then, once it is done,
              {"status": 0 | 1, "cpu_s": S, "wall_s": S}
The job runs exactly as `blender ... -P cycles_render.py -- JOB.json OUT.exr` would run it
(cycles_render.render_job, which rebuilds the scene from factory settings): the same files
beside OUT, the same log (stdout and stderr go to LOG while the job runs, and a failure ends
with the same "cycles_render.py: error: ..." line), status 1 where Blender would exit 1.
What gives the same answer as a fresh Blender per job is checked by tests/slurm_worker.sh.

A client that goes away while its job renders (its `reflcheck run` timed out, was killed or
interrupted) ends the render the only way Blender allows: the worker kills itself, and the pool
starts another. The job's files are then the client's to clean up, as with a killed Blender.
"""

import json
import os
import resource
import signal
import socket
import sys
import threading
import time
import traceback

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import cycles_render  # noqa: E402  (needs the path above)


def cpu_seconds():
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def watch(conn, done):
    """Ends this process if the client hangs up before the job is done: a render cannot be
    stopped from Python, and nobody waits for its result any more."""
    while not done.is_set():
        try:
            if conn.recv(1, socket.MSG_PEEK) == b'':
                break
        except OSError:
            break
    if not done.is_set():
        os.kill(os.getpid(), signal.SIGKILL)


def serve_one(conn, render=None, script='cycles_render.py'):
    """One job on conn: render(job, out, threads) (default cycles_render.render_job; EEVEE's
    worker passes its own and its script's name for the log's error line)."""
    render = render or cycles_render.render_job
    f = conn.makefile('rb')
    line = f.readline(1 << 16)
    try:
        req = json.loads(line)
        job, out, log = req['job'], req['out'], req['log']
        threads = int(req.get('threads', 0))
    except (ValueError, KeyError, TypeError):
        conn.sendall(b'{"status": 2}\n')
        return
    conn.sendall(('{"started": %d}\n' % os.getpid()).encode())
    done = threading.Event()
    threading.Thread(target=watch, args=(conn, done), daemon=True).start()
    t0, c0 = time.monotonic(), cpu_seconds()
    sys.stdout.flush()
    sys.stderr.flush()
    saved = os.dup(1), os.dup(2)
    status = 0
    try:
        fd = os.open(log, os.O_WRONLY | os.O_CREAT | os.O_TRUNC | os.O_CLOEXEC, 0o644)
        os.dup2(fd, 1)
        os.dup2(fd, 2)
        os.close(fd)
        try:
            render(job, out, threads)
        except cycles_render.JobError as e:
            print("%s: error: %s" % (script, e), file=sys.stderr)
            status = 1
        except Exception:
            traceback.print_exc()
            print("%s: error: unexpected failure (traceback above)" % script, file=sys.stderr)
            status = 1
    except OSError as e:
        status = 1
        print("worker.py: %s: %s" % (log, e), file=sys.stderr)
    finally:
        sys.stdout.flush()
        sys.stderr.flush()
        os.dup2(saved[0], 1)
        os.dup2(saved[1], 2)
        os.close(saved[0])
        os.close(saved[1])
    done.set()
    reply = {'status': status, 'cpu_s': cpu_seconds() - c0, 'wall_s': time.monotonic() - t0}
    conn.sendall((json.dumps(reply) + '\n').encode())


def main(render=None, script='cycles_render.py'):
    argv = sys.argv[sys.argv.index('--') + 1 :] if '--' in sys.argv else []
    if len(argv) != 1:
        print('worker.py: usage: blender -b --factory-startup -P worker.py -- FD', file=sys.stderr)
        sys.exit(2)
    listener = socket.socket(fileno=int(argv[0]))
    while True:
        conn, _ = listener.accept()
        try:
            serve_one(conn, render, script)
        except OSError:
            pass  # the client went away after its job: nothing to tell it
        finally:
            conn.close()


if __name__ == '__main__':
    main()
