"""schedule.py - the sweep's task queue: slots that each take the most urgent task first, where a
task may queue further tasks (a scene's analysis queues its next stage's reference).

Usage:
  q = TaskQueue({'cpu': 2, 'wait': 2})      # kind -> slots (threads) serving that kind
  q.put('cpu', (2, 0, -7.1), fn)            # lowest priority tuple first, then first put
  while not q.wait_idle(10.0): tick()        # True once nothing is queued or running
  q.close()                                  # stops the slots (drops what is queued); re-raises
                                             # a task's exception

Why two kinds: a POV-Ray job spends about 1 s waiting on POV-Ray's own timers (its front end
sleeps between polls; `strace -c`: 1.8 s of clock_nanosleep, 0.03 CPU-s) and none computing, so
it runs in a slot of its own beside the CPU slots instead of idling one of them."""

import heapq
import itertools
import threading


class TaskQueue:
    def __init__(self, slots):
        self.cond = threading.Condition()
        self.heaps = {kind: [] for kind in slots}
        self.seq = itertools.count()
        self.queued = 0
        self.busy = 0
        self.closed = False
        self.errors = []
        self.threads = [
            threading.Thread(target=self._serve, args=(kind,), daemon=True)
            for kind, n in slots.items()
            for _ in range(n)
        ]
        for t in self.threads:
            t.start()

    def put(self, kind, priority, fn):
        """Queues fn() for a slot of `kind`; the lowest priority tuple runs first."""
        with self.cond:
            heapq.heappush(self.heaps[kind], (priority, next(self.seq), fn))
            self.queued += 1
            self.cond.notify_all()

    def _serve(self, kind):
        heap = self.heaps[kind]
        while True:
            with self.cond:
                self.cond.wait_for(lambda: heap or self.closed)
                if not heap:
                    return
                fn = heapq.heappop(heap)[2]
                self.queued -= 1
                self.busy += 1
            try:
                fn()
            except BaseException as e:  # kept for close(): a slot must not die silently
                with self.cond:
                    self.errors.append(e)
            finally:
                with self.cond:
                    self.busy -= 1
                    self.cond.notify_all()

    def wait_idle(self, timeout):
        """Waits up to timeout s; True when nothing is queued or running (a running task puts
        its follow-up before it ends, so idle means done)."""
        with self.cond:
            return self.cond.wait_for(lambda: not self.queued and not self.busy, timeout)

    def close(self):
        """Stops the slots once their running tasks end; tasks still queued are dropped (after
        wait_idle there are none; on an interrupt the sweep must not go on rendering)."""
        with self.cond:
            self.closed = True
            for heap in self.heaps.values():
                self.queued -= len(heap)
                heap.clear()
            self.cond.notify_all()
        for t in self.threads:
            t.join()
        if self.errors:
            raise self.errors[0]
