"""The solver's batches on Dask (``SolveOptions(scheduler="dask" | "tcp://HOST:PORT")``
or ``solve(..., client=...)``): the same tasks as the threads, the same bits.

What goes where
  - the merged scene (positions, faces and ``kernels.SceneArrays``) is scattered to
    every worker once per solve, and after the density phase the irradiance (N, 3)
    float64 and each glossy object's directions: tasks get futures, never arrays;
  - each worker builds the Embree scene once per scattered scene (``_worker_scene``, a
    cache keyed by the scattered data's key), shared by its threads;
  - a task is a pure function of (scattered inputs, seed, job): a photon batch returns
    its additive ``kernels.PhotonTally`` (9 float64 per vertex + the tally), a gather
    block its radiance (B, D, 3) float64, each with the rays it cast;
  - the client keeps a window of a few tasks in flight, feeds the progress bar as tasks
    complete, and combines results strictly in job order (the float sums are those of
    the threads, so the same seed gives the same bits) as soon as the next one in order
    is there: memory stays bounded whatever the photon count;
  - a worker lost mid-run: Dask reruns its tasks elsewhere; being pure functions of
    their inputs they return the same bits. Ctrl-C cancels the outstanding futures.

Dask is optional (``pip install ".[dask]"``); this module imports it only when used.
"""

from __future__ import annotations

import importlib.util
import logging
import re
import signal
import threading
from collections import deque

from radiosity.formats.errors import InputError
from radiosity.transport.embree import RayTracer

CONNECT_TIMEOUT = 20.0  # seconds to reach a scheduler and see at least one worker
SCHEDULERS = ("threads", "dask")
_ADDRESS = re.compile(r"^[a-z][a-z0-9+.-]*://[^\s/]+:(\d{1,5})$")


def have_dask():
    return importlib.util.find_spec("distributed") is not None


def check_scheduler(scheduler):
    """Refuse (InputError, one line) a ``--scheduler`` that is neither ``threads``,
    ``dask`` nor a scheduler address, or that needs Dask where it is not installed."""
    if scheduler == "threads":
        return
    match = _ADDRESS.match(str(scheduler))
    if scheduler != "dask" and not (match and 0 < int(match.group(1)) < 65536):
        raise InputError(
            f"--scheduler must be threads, dask or a Dask scheduler address such as tcp://HOST:8786, got {scheduler!r}"
        )
    if not have_dask():
        raise InputError(
            f"--scheduler {scheduler} needs Dask, which is not installed: pip install \"virtual-lights[dask]\" "
            "(or \"dask[distributed]\")"
        )


def connect(scheduler):
    """(client, cluster): a new LocalCluster sized to the machine for ``dask`` (cluster
    to close at the end), or a client of the scheduler at an address (cluster None).
    InputError (one line) if it cannot be reached, or has no worker, within
    CONNECT_TIMEOUT."""
    check_scheduler(scheduler)
    from distributed import Client, LocalCluster

    if scheduler == "dask":
        # the worker processes start with Ctrl-C ignored (inherited): a terminal's Ctrl-C
        # reaches the whole process group, and this process alone should answer it, by
        # cancelling the tasks and closing the cluster
        main = threading.current_thread() is threading.main_thread()
        previous = signal.signal(signal.SIGINT, signal.SIG_IGN) if main else None
        try:
            cluster = LocalCluster(dashboard_address=None, silence_logs=logging.ERROR)
        finally:
            if main:
                signal.signal(signal.SIGINT, previous)
        return Client(cluster), cluster
    try:
        client = Client(scheduler, timeout=CONNECT_TIMEOUT)
    except (OSError, TimeoutError) as exc:
        raise InputError(
            f"cannot reach the Dask scheduler at {scheduler} within {CONNECT_TIMEOUT:g} s: {' '.join(str(exc).split())}"
        ) from None
    try:
        client.wait_for_workers(1, timeout=CONNECT_TIMEOUT)
    except (OSError, TimeoutError):
        client.close()
        raise InputError(f"the Dask scheduler at {scheduler} has no worker after {CONNECT_TIMEOUT:g} s") from None
    return client, None


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
    """The worker's Embree scene for the scattered ``scene`` (positions, faces, sa), built
    by the first task that needs it; later tasks (any thread) share it."""
    with _SCENES_LOCK:
        if key not in _SCENES:
            positions, faces, sa = scene
            while len(_SCENES) >= _KEEP_SCENES:
                _SCENES.pop(next(iter(_SCENES)))[0].close()
            _SCENES[key] = (RayTracer(positions, faces, threads=1), sa)
        return _SCENES[key]


async def _drop_scene(key):
    """Forget a finished solve's Embree scene (a coroutine: ``Client.run`` need not wait)."""
    with _SCENES_LOCK:
        entry = _SCENES.pop(key, None)
    if entry is not None:
        entry[0].close()


def _photon_task(key, scene, seed, first_id, count, total):
    from radiosity.transport.solve import trace_photon_batch

    tracer, sa = _worker_scene(key, scene)
    counting = _CountingTracer(tracer)
    return trace_photon_batch(counting, sa, seed, first_id, count, total), counting.rays_cast


def _gather_task(key, scene, irradiance, block, material, dirs):
    from radiosity.transport.solve import gather_block

    tracer, sa = _worker_scene(key, scene)
    counting = _CountingTracer(tracer)
    return (block.vertices, gather_block(counting, sa, irradiance, block, material, dirs)), counting.rays_cast


# -- on the client ---------------------------------------------------------------------------


class DaskRunner:
    """Runs a solve's photon batches and gather blocks on a Dask cluster (the
    counterpart of ``solve._ThreadRunner``): ``start``, ``photon_batches``,
    ``gather_blocks``, ``close``; ``rays_cast`` counts the rays of every task."""

    def __init__(self, client, cluster=None, own_client=False):
        self.client = client
        self._own_client = own_client  # made by ``connect``: close it at the end
        self._cluster = cluster  # ours to close, or None
        self.threads = max(1, sum(client.nthreads().values()))
        workers = len(client.nthreads())
        self.description = f"dask {client.scheduler.address} ({workers} workers, {self.threads} threads)"
        self.rays_cast = 0
        self._scattered = []
        self._scene = None
        self._irradiance = None

    def _scatter(self, data):
        [future] = self.client.scatter([data], broadcast=True, hash=False)  # one future, even for a tuple
        self._scattered.append(future)
        return future

    def start(self, merged, sa, seed):
        self._seed = seed
        self._scene = self._scatter((merged.positions, merged.faces, sa))

    def photon_batches(self, total, combine, bar):
        from radiosity.transport.solve import PHOTON_BATCH

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
        """Submit ``task(job)`` (a function and its arguments) for every job, a window
        of a few at a time, feed ``progress`` as tasks complete and ``combine`` the
        results in job order; on any exception (Ctrl-C too) cancel what is pending."""
        from distributed import wait

        window = 2 * self.threads + 1
        pending = deque()  # [future, weight, counted in progress]
        jobs = iter(zip(jobs, weights))
        more = True
        try:
            while True:
                while more and len(pending) < window:
                    item = next(jobs, None)
                    if item is None:
                        more = False
                        break
                    fn, *args = task(item[0])
                    pending.append([self.client.submit(fn, *args, pure=False), item[1], False])
                if not pending:
                    return
                if not pending[0][0].done():
                    wait([p[0] for p in pending if not p[0].done()], return_when="FIRST_COMPLETED")
                for p in pending:
                    if not p[2] and p[0].done():
                        progress.update(p[1])
                        p[2] = True
                while pending and pending[0][0].done():
                    future = pending.popleft()[0]
                    result, rays = future.result()
                    future.release()
                    self.rays_cast += rays
                    combine(result)
        except BaseException:
            self.client.cancel([p[0] for p in pending], force=True)
            raise

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
