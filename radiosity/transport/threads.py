"""The thread runner: a solve's photon batches and gather blocks (``batches``) on a
pool of threads of this process, sharing one Embree scene, their results combined in
job order (so the same bits whatever the thread count); the path tracer's tiles run
the same way. The counterpart on a cluster is ``distributed.DaskRunner``.
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from typing import NamedTuple

from radiosity.transport.batches import PHOTON_BATCH, gather_block, trace_photon_batch
from radiosity.transport.embree import RayTracer
from radiosity.transport.records import SceneArrays


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


def run_ordered(workers, fn, jobs, combine, progress, weights):
    """Run ``fn(job)`` for every job on ``workers.pool``, a few at a time (jobs and
    weights may be lazy iterables), and ``combine`` the results in job order
    (deterministic sums); stops early and cleanly on KeyboardInterrupt."""
    pending = []
    try:
        for job, weight in zip(jobs, weights):
            pending.append((workers.pool.submit(fn, job), weight))
            if len(pending) > 2 * workers.threads:
                future, w = pending.pop(0)
                combine(future.result())
                progress.update(w)
        for future, w in pending:
            combine(future.result())
            progress.update(w)
    except BaseException:
        for future, _ in pending:
            future.cancel()
        raise


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
        tracer = RayTracer(merged.positions, merged.faces, threads=1)
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
