"""The solver's batches on Dask (``SolveOptions(scheduler="dask" | "tcp://HOST:PORT")``
or ``solve(..., client=...)``): the same tasks as the threads (``batches``), the same bits.

What goes where
  - the merged scene (positions, faces and ``records.SceneArrays``) is scattered to
    every worker once per solve, and after the density phase the irradiance (N, 3)
    float64 and each glossy object's directions: tasks get futures, never arrays;
  - each worker builds the Embree scene once per scattered scene (``_worker_scene``, a
    cache keyed by the scattered data's key), shared by its threads;
  - a task is a pure function of (scattered inputs, seed, job): a photon batch returns
    its additive ``records.PhotonTally`` (9 float64 per vertex + the tally), a gather
    block its radiance (B, D, 3) float64, each with the rays it cast;
  - the client keeps a window of a few tasks in flight, feeds the progress bar as tasks
    complete, and combines results strictly in job order (the float sums are those of
    the threads, so the same seed gives the same bits) as soon as the next one in order
    is there: memory stays bounded whatever the photon count;
  - a worker lost mid-run: Dask reruns its tasks elsewhere; being pure functions of
    their inputs they return the same bits. Ctrl-C cancels the outstanding futures.

Where it runs: ``radiosity.policies.cluster`` (shared with the fit) reaches the scheduler.

Dask is optional (``pip install ".[dask]"``); this module imports it only when used.
"""

from __future__ import annotations

import threading

from radiosity.transport.embree import RayTracer
from radiosity.transport.threads import in_order

# -- on the workers ------------------------------------------------------------------------

_SCENES = {}  # scattered scene key -> (RayTracer, SceneArrays); this worker process's cache
_SCENES_LOCK = threading.Lock()
_KEEP_SCENES = 2  # Embree scenes a worker keeps (a client may run solves one after another)


class _CountingTracer:
    """A task's view of the worker's shared tracer: the same Embree scene, its own ray count."""

    def __init__(self, tracer):
        self._tracer = tracer  # keeps the Embree scene alive while the task traces
        self.embree = tracer.embree
        self.epsilon = tracer.epsilon
        self.rays_cast = 0

    def count(self, rays, shadow_rays=0):
        self.rays_cast += int(rays)


def _worker_scene(key, scene):
    """The worker's Embree scene for the scattered ``scene`` (positions, faces, sa, cutout), built
    by the first task that needs it; later tasks (any thread) share it."""
    with _SCENES_LOCK:
        if key not in _SCENES:
            positions, faces, sa, cutout = scene
            while len(_SCENES) >= _KEEP_SCENES:
                _SCENES.pop(next(iter(_SCENES)))[0].close()
            _SCENES[key] = (RayTracer(positions, faces, threads=1, cutout=cutout), sa)
        return _SCENES[key]


async def _drop_scene(key):
    """Forget a finished solve's Embree scene (a coroutine: ``Client.run`` need not wait)."""
    with _SCENES_LOCK:
        entry = _SCENES.pop(key, None)
    if entry is not None:
        entry[0].close()


def _photon_task(key, scene, seed, first_id, count, total):
    from radiosity.transport.batches import trace_photon_batch

    tracer, sa = _worker_scene(key, scene)
    counting = _CountingTracer(tracer)
    return trace_photon_batch(counting, sa, seed, first_id, count, total), counting.rays_cast


def _gather_task(key, scene, irradiance, block, material, dirs):
    from radiosity.transport.batches import gather_block

    tracer, sa = _worker_scene(key, scene)
    counting = _CountingTracer(tracer)
    return (block.vertices, gather_block(counting, sa, irradiance, block, material, dirs)), counting.rays_cast


# -- on the client ---------------------------------------------------------------------------


class _DaskPool:
    """``threads.in_order``'s view of a Dask client running ``task(job)`` (a function
    and its arguments); each result is (what to combine, the rays it cast)."""

    def __init__(self, runner, task):
        self.runner, self.task, self.window = runner, task, 2 * runner.threads + 1

    def submit(self, job):
        fn, *args = self.task(job)
        return self.runner.client.submit(fn, *args, pure=False)

    def wait_first(self, futures):
        from distributed import wait

        wait(futures, return_when="FIRST_COMPLETED")

    def result(self, future):
        result, rays = future.result()
        future.release()
        self.runner.rays_cast += rays
        return result

    def cancel(self, futures):
        self.runner.client.cancel(futures, force=True)


class DaskRunner:
    """Runs a solve's photon batches and gather blocks on a Dask cluster (the
    counterpart of ``threads.ThreadRunner``): ``start``, ``photon_batches``,
    ``gather_blocks``, ``close``; ``rays_cast`` counts the rays of every task."""

    def __init__(self, client, cluster=None, own_client=False):
        self.client = client
        self._own_client = own_client  # made by ``connect``: close it at the end
        self._cluster = cluster  # ours to close (``close``), or None
        self.rays_cast = 0
        self._scattered = []
        self._scene = None
        self._irradiance = None
        try:
            nthreads = client.nthreads()
        except BaseException:  # a signal or a lost scheduler: close what ``connect`` made
            self.close()
            raise
        self.threads = max(1, sum(nthreads.values()))
        self.description = f"dask {client.scheduler.address} ({len(nthreads)} workers, {self.threads} threads)"

    def _scatter(self, data):
        [future] = self.client.scatter([data], broadcast=True, hash=False)  # one future, even for a tuple
        self._scattered.append(future)
        return future

    def start(self, merged, sa, seed):
        self._seed = seed
        self._scene = self._scatter((merged.positions, merged.faces, sa, merged.cutout))

    def photon_batches(self, total, combine, bar):
        from radiosity.transport.batches import PHOTON_BATCH

        starts = range(0, total, PHOTON_BATCH)  # lazily: 2^40 photons are 2^24 batches
        counts = (min(PHOTON_BATCH, total - s) for s in starts)
        jobs = ((s, min(PHOTON_BATCH, total - s), total) for s in starts)
        scene = self._scene
        self._run_ordered(
            lambda job: (_photon_task, scene.key, scene, self._seed, *job), jobs, combine, bar, counts
        )

    def gather_blocks(self, irradiance, jobs, combine, bar):
        """Gather ``jobs``, (block, material, directions) each, and ``combine`` their
        results in job order."""
        if self._irradiance is None or self._irradiance[0] is not irradiance:
            self._irradiance = (irradiance, self._scatter(irradiance))
        irradiance_future, scene = self._irradiance[1], self._scene
        dirs_futures = {}  # one copy on the workers of each object's directions
        for _, _, dirs in jobs:
            if id(dirs) not in dirs_futures:
                dirs_futures[id(dirs)] = self._scatter(dirs)
        self._run_ordered(
            lambda job: (
                _gather_task, scene.key, scene, irradiance_future, job[0], job[1], dirs_futures[id(job[2])]
            ),
            jobs,
            combine,
            bar,
            (len(block.vertices) for block, _, _ in jobs),
        )

    def _run_ordered(self, task, jobs, combine, progress, weights):
        """Submit ``task(job)`` (a function and its arguments) for every job and
        ``combine`` the results in job order (``threads.in_order``, the one ordered
        reduction); on any exception (Ctrl-C too) cancel what is pending."""
        in_order(_DaskPool(self, task), jobs, combine, progress, weights)

    def close(self):
        """Release the scattered data and the workers' Embree scenes; close the client
        and the cluster if they are ours."""
        try:
            if self._scattered:
                self.client.cancel(self._scattered, force=True)
            if self._scene is not None and self._cluster is None:
                self.client.run(_drop_scene, self._scene.key, wait=False)
        except Exception:  # a cluster already gone: nothing left to release
            pass
        finally:
            self._scattered = []
            if self._own_client:
                self.client.close()
            if self._cluster is not None:
                self._cluster.close()
