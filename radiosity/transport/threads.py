"""The thread runner: a solve's photon batches and gather blocks (``batches``) on a
pool of threads of this process, sharing one Embree scene, their results combined in
job order (so the same bits whatever the thread count); the path tracer's tiles run
the same way. The counterpart on a cluster is ``distributed.DaskRunner``.
"""

from __future__ import annotations

from collections import deque
from concurrent.futures import ThreadPoolExecutor
from queue import SimpleQueue
from typing import NamedTuple

from radiosity.transport.batches import PHOTON_BATCH, gather_block, trace_photon_batch
from radiosity.transport.embree import RayTracer
from radiosity.transport.records import SceneArrays
from radiosity.transport.signals import HeldSignals


class _NullProgress:
    """A progress bar that shows nothing."""

    def __init__(self, *args, **kwargs):
        pass

    def update(self, n=1):
        pass

    def close(self):
        pass


def progress_bar(enabled):
    """A tqdm progress-bar factory, or one of bars that show nothing."""
    if not enabled:
        return _NullProgress
    from tqdm import tqdm

    return lambda **kw: tqdm(unit_scale=True, dynamic_ncols=True, leave=True, disable=None, **kw)


def in_order(pool, jobs, combine, progress, weights):
    """The one ordered reduction of every runner: submit ``pool.submit(job)`` for every
    job, at most ``pool.window`` in flight (jobs and weights may be lazy iterables),
    feed ``progress`` each job's weight as it completes, and ``combine`` the results
    (``pool.result(future)``) strictly in job order, so the sums are the same whatever
    finishes first; on any exception (Ctrl-C too) ``pool.cancel`` what is pending.

    ``pool``: ``submit(job)`` -> a future (``done()``), ``wait_first(futures)`` (until
    one is done), ``result(future)``, ``cancel(futures)``, ``window``: the threads'
    ``_ThreadPool`` or the Dask runner's."""
    pending = deque()  # [future, weight, counted in progress]
    items = iter(zip(jobs, weights))
    more = True
    try:
        while True:
            while more and len(pending) < pool.window:
                item = next(items, None)
                if item is None:
                    more = False
                    break
                pending.append([pool.submit(item[0]), item[1], False])
            if not pending:
                return
            if not pending[0][0].done():
                pool.wait_first([p[0] for p in pending if not p[0].done()])
            for p in pending:
                if not p[2] and p[0].done():
                    progress.update(p[1])
                    p[2] = True
            while pending and pending[0][0].done():
                combine(pool.result(pending.popleft()[0]))
    except BaseException:
        pool.cancel([p[0] for p in pending])
        raise


class _ThreadPool:
    """``in_order``'s view of a ``ThreadPoolExecutor`` running ``fn(job)``.

    Its ``held`` signals (``signals.HeldSignals``) raise only in ``wait_first``: a Ctrl-C
    or SIGTERM landing while the main thread holds one of ``concurrent.futures``' locks
    would leave it held, and the pool's shutdown would wait forever for the worker
    blocked on it. It waits on a queue that its futures' done-callbacks feed (and the
    held signal's handler too, so that a signal ends the wait at once)."""

    def __init__(self, executor, fn, threads):
        self.executor, self.fn, self.window = executor, fn, 2 * threads + 1
        self.finished = SimpleQueue()  # a None per future done (put once its state is set), or per signal
        self.held = HeldSignals(wake=lambda: self.finished.put(None))

    def submit(self, job):
        future = self.executor.submit(self.fn, job)
        future.add_done_callback(self._done)
        return future

    def _done(self, _future):  # in the worker thread; not the future itself: the queue would keep its result
        self.finished.put(None)

    def wait_first(self, futures):
        """Until one of ``futures`` is done; at once when one is, or when there are none
        (as ``concurrent.futures.wait``): ``in_order`` lists the unfinished ones after
        seeing the head unfinished, and a job finishing in between leaves the list empty,
        its queue entry maybe consumed already, nothing more to come."""
        self.held.check()
        while futures and not any(f.done() for f in futures):
            self.finished.get()
            self.held.check()

    def result(self, future):
        return future.result()

    def cancel(self, futures):
        for future in futures:
            future.cancel()


def run_ordered(workers, fn, jobs, combine, progress, weights):
    """Run ``fn(job)`` for every job on ``workers.pool`` (``in_order``), and ``combine``
    the results in job order (deterministic sums); stops early and cleanly on
    KeyboardInterrupt or SIGTERM (held until the main thread holds no pool lock)."""
    pool = _ThreadPool(workers.pool, fn, workers.threads)
    with pool.held:
        in_order(pool, jobs, combine, progress, weights)


class Workers(NamedTuple):
    """What every parallel phase of a solve uses: the pool, its size, the tracer, the
    merged scene and the seed."""

    pool: ThreadPoolExecutor
    threads: int
    tracer: RayTracer
    sa: SceneArrays
    seed: int


class ThreadRunner:
    """Runs a solve's photon batches and gather blocks on a pool of threads of this
    process, sharing one Embree scene (the counterpart of ``distributed.DaskRunner``)."""

    def __init__(self, threads):
        self.threads = threads
        self.description = "threads"
        self.workers = None

    def start(self, merged, sa, seed):
        tracer = RayTracer(merged.positions, merged.faces, threads=1, cutout=merged.cutout)
        self.workers = Workers(ThreadPoolExecutor(self.threads), self.threads, tracer, sa, seed)

    @property
    def rays_cast(self):
        return self.workers.tracer.rays_cast

    def photon_batches(self, total, combine, bar):
        tracer, sa, seed = self.workers.tracer, self.workers.sa, self.workers.seed
        starts = range(0, total, PHOTON_BATCH)  # lazily: 2^40 photons are 2^24 batches
        counts = (min(PHOTON_BATCH, total - s) for s in starts)
        run_ordered(
            self.workers,
            lambda job: trace_photon_batch(tracer, sa, seed, job, min(PHOTON_BATCH, total - job), total),
            starts,
            combine,
            bar,
            counts,
        )

    def gather_blocks(self, irradiance, jobs, combine, bar):
        tracer, sa = self.workers.tracer, self.workers.sa

        def run(job):
            block, material, dirs = job
            return block.vertices, gather_block(tracer, sa, irradiance, block, material, dirs)

        run_ordered(self.workers, run, jobs, combine, bar, [len(block.vertices) for block, _, _ in jobs])

    def close(self):
        if self.workers is not None:
            self.workers.pool.shutdown()
            self.workers.tracer.close()
