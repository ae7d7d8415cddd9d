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

Where it runs
  - ``dask``: a LocalCluster whose scheduler and workers keep their scratch space in a
    private temporary directory, removed when the run ends, however it ends;
  - ``tcp://HOST:PORT`` (HOST a name, an IPv4 address or ``[IPv6]``): checked before any
    work (``address_problem``; tls, ucx, inproc and ws need a ``Client`` configured in
    Python), then reached within CONNECT_TIMEOUT or refused in one line, a server that
    is not a Dask scheduler included (``_identify``).

Dask is optional (``pip install ".[dask]"``); this module imports it only when used.
"""

from __future__ import annotations

import asyncio
import importlib.util
import ipaddress
import logging
import re
import shutil
import signal
import tempfile
import threading
import time

from radiosity.formats.errors import InputError
from radiosity.transport.embree import RayTracer
from radiosity.transport.threads import in_order

CONNECT_TIMEOUT = 20.0  # seconds to reach a scheduler and see at least one worker
SCHEDULERS = ("threads", "dask")
SCHEMES = ("tcp",)  # the addresses ``--scheduler`` takes; others need a configured Client
_USAGE = "--scheduler must be threads, dask or a Dask scheduler address tcp://HOST:PORT"
_OTHER_SCHEMES = {  # why a scheme Dask knows is not taken here
    "tls": "needs certificates and keys this command cannot take",
    "wss": "needs certificates and keys this command cannot take",
    "ws": "is not supported here",
    "ucx": "needs UCX (distributed-ucxx) and is not supported here",
    "inproc": "reaches only a scheduler inside the same process, never one a command can use",
}
_HOST_NAME = re.compile(r"^(?!-)[A-Za-z0-9_-]{1,63}(?<!-)(\.(?!-)[A-Za-z0-9_-]{1,63}(?<!-))*\.?$")
_PORT = re.compile(r"^\d{1,5}$")


def have_dask():
    return importlib.util.find_spec("distributed") is not None


def address_problem(address):
    """What is wrong with a scheduler address (a phrase), or None for a well-formed
    ``tcp://HOST:PORT``: HOST a name, an IPv4 address or an IPv6 one in brackets,
    PORT 1-65535."""
    scheme, sep, location = address.partition("://")
    if not sep:
        return "no scheme: write tcp://HOST:PORT"
    if scheme not in SCHEMES:
        if scheme in _OTHER_SCHEMES:
            return (
                f"{scheme}:// {_OTHER_SCHEMES[scheme]} (only tcp:// is; from Python, pass a configured "
                "distributed.Client: solve(..., client=))"
            )
        return f"unknown scheme {scheme!r} (only tcp:// is supported)"
    if location.startswith("["):
        host, bracket, tail = location[1:].partition("]")
        if not bracket:
            return "unbalanced '[': an IPv6 host is written in brackets, tcp://[::1]:8786"
        try:
            ipaddress.IPv6Address(host)
        except ValueError:
            return f"{host!r} in brackets is not an IPv6 address"
        if not tail.startswith(":"):
            return "no port after the host: tcp://[HOST]:PORT"
        port = tail[1:]
    else:
        if "]" in location:
            return "unbalanced ']': an IPv6 host is written in brackets, tcp://[::1]:8786"
        host, colon, port = location.rpartition(":")
        if not colon:
            return "no port after the host: tcp://HOST:PORT"
        if ":" in host:
            return "an IPv6 host is written in brackets, tcp://[::1]:8786"
        if not _HOST_NAME.match(host):
            return f"{host!r} is not a host name or IPv4 address"
    if not _PORT.match(port) or not 0 < int(port) < 65536:
        return f"the port {port!r} is not a number from 1 to 65535"
    return None


def check_scheduler(scheduler):
    """Refuse (InputError, one line) a ``--scheduler`` that is neither ``threads``,
    ``dask`` nor a well-formed ``tcp://HOST:PORT`` (``address_problem``), or that
    needs Dask where it is not installed."""
    if scheduler == "threads":
        return
    if scheduler != "dask":
        problem = address_problem(str(scheduler))
        if problem is not None:
            raise InputError(f"{_USAGE}; {str(scheduler)!r}: {problem}")
    if not have_dask():
        raise InputError(
            f"--scheduler {scheduler} needs Dask, which is not installed: pip install \"virtual-lights[dask]\" "
            "(or \"dask[distributed]\")"
        )


class _SyncCancelRace(logging.Filter):
    """Drops one record: Dask's ``distributed.utils.sync`` schedules a ``cancel``
    callback when Ctrl-C or SIGTERM interrupts its wait, and if that happens before its
    future exists the callback raises NameError in the event loop (a race inside Dask,
    harmless: there is nothing to cancel yet), which tornado logs with a traceback
    after our one line."""

    def filter(self, record):
        exc = record.exc_info[1] if record.exc_info else None
        return not (isinstance(exc, NameError) and "'future'" in str(exc))


def _quiet_sync_race():
    logger = logging.getLogger("tornado.application")
    if not any(isinstance(f, _SyncCancelRace) for f in logger.filters):
        logger.addFilter(_SyncCancelRace())


def connect(scheduler):
    """(client, cluster): a new LocalCluster sized to the machine for ``dask`` (cluster
    to close at the end), or a client of the scheduler at an address (cluster None).
    InputError (one line) if it cannot be reached, is not a Dask scheduler, or has no
    worker, within CONNECT_TIMEOUT in all."""
    check_scheduler(scheduler)
    _quiet_sync_race()
    if scheduler == "dask":
        return _local_cluster()
    from distributed import Client

    deadline = time.monotonic() + CONNECT_TIMEOUT
    _identify(scheduler, deadline)
    try:
        client = Client(scheduler, timeout=max(deadline - time.monotonic(), 0.1))
    except (OSError, TimeoutError) as exc:
        raise InputError(
            f"cannot reach the Dask scheduler at {scheduler} within {CONNECT_TIMEOUT:g} s: {' '.join(str(exc).split())}"
        ) from None
    try:
        client.wait_for_workers(1, timeout=max(deadline - time.monotonic(), 0.1))
    except (OSError, TimeoutError):
        client.close()
        raise InputError(f"the Dask scheduler at {scheduler} has no worker after {CONNECT_TIMEOUT:g} s") from None
    return client, None


class _Unreachable(Exception):
    """Nothing took the connection (refused, no route, no such host) before the deadline."""


class _NotDask(Exception):
    """Something took the connection but did not answer as a Dask scheduler does."""


def _identify(address, deadline):
    """Make sure a Dask scheduler answers at ``address`` before ``deadline``
    (``time.monotonic``), else InputError: Dask's own connect waits for the handshake
    without a timeout, so a server of another kind (HTTP, ...) would hang ``Client``.
    The connection, Dask's handshake and one ``identity`` request run on an event loop
    of their own, in a thread the caller stops waiting for at the deadline."""
    from distributed.comm.addressing import parse_address
    from distributed.comm.registry import get_backend

    scheme, location = parse_address(address)
    connector = get_backend(scheme).get_connector()
    outcome = {}

    def run():
        try:
            outcome["identity"] = asyncio.run(_ask_identity(connector, location, deadline, outcome))
        except BaseException as exc:  # reported to the caller
            outcome["error"] = exc

    worker = threading.Thread(target=run, name="vlights-dask-probe", daemon=True)
    worker.start()
    worker.join(max(deadline - time.monotonic(), 0))
    error = outcome.get("error")
    if "identity" not in outcome and not outcome.get("connected"):
        reason = error if isinstance(error, _Unreachable) else "timed out"
        raise InputError(f"cannot reach the Dask scheduler at {address} within {CONNECT_TIMEOUT:g} s: {reason}")
    if "identity" not in outcome:
        reason = error if isinstance(error, _NotDask) else "no Dask handshake"
        raise InputError(
            f"{address} took the connection but is not a Dask scheduler ({reason} within {CONNECT_TIMEOUT:g} s)"
        )
    kind = outcome["identity"].get("type") if isinstance(outcome["identity"], dict) else None
    if kind != "Scheduler":
        what = f"a Dask {kind.lower()}" if isinstance(kind, str) and kind.isalpha() else "not a Dask server"
        raise InputError(f"{address} is {what}, not a Dask scheduler")


def _reason(exc):
    """The root of a connection error in a few words (Dask wraps the OSError in text
    naming its connector object)."""
    while exc.__cause__ is not None or (exc.__context__ is not None and not exc.__suppress_context__):
        exc = exc.__cause__ or exc.__context__
    text = getattr(exc, "strerror", None) or " ".join(str(exc).split())
    return text or type(exc).__name__


async def _ask_identity(connector, location, deadline, outcome):
    """The ``identity`` of the Dask server at ``location``: _Unreachable if no
    connection is made before ``deadline`` (retried with a growing pause, as Dask does),
    _NotDask if the handshake or the answer fail, or do not come by then. Sets
    ``outcome["connected"]`` once a connection is made."""
    pause = 0.01
    while True:
        left = deadline - time.monotonic()
        try:
            if left <= 0:
                raise TimeoutError("timed out")
            comm = await asyncio.wait_for(connector.connect(location, deserialize=True), left)
            break
        except (OSError, TimeoutError) as exc:
            if time.monotonic() + pause >= deadline:
                raise _Unreachable(_reason(exc)) from None
            await asyncio.sleep(pause)
            pause = min(2 * pause, 1.0)
    outcome["connected"] = True
    try:
        return await asyncio.wait_for(_handshake_identity(comm), max(deadline - time.monotonic(), 0))
    except TimeoutError:
        raise _NotDask("no Dask handshake") from None
    except Exception as exc:
        raise _NotDask(f"its answer failed: {type(exc).__name__}") from None
    finally:
        comm.abort()


async def _handshake_identity(comm):
    """Dask's handshake (as ``distributed.comm.connect`` makes it) and the answer to
    ``identity`` on a fresh ``comm``."""
    local = comm.handshake_info()
    await comm.write(local)
    remote = await comm.read()
    comm.remote_info, comm.local_info = remote, local
    comm.handshake_options = comm.handshake_configuration(local, remote)
    await comm.write({"op": "identity", "reply": True})
    return await comm.read()


class _LocalCluster:
    """A LocalCluster whose workers keep their scratch files (``dask-scratch-space``
    and its locks) in a directory of their own, removed with the cluster."""

    def __init__(self, cluster, directory):
        self.cluster = cluster
        self.directory = directory

    def close(self):
        try:
            self.cluster.close()
        finally:
            shutil.rmtree(self.directory, ignore_errors=True)


def _local_cluster():
    """(client, cluster) of a new LocalCluster sized to this machine, its workers'
    scratch space in a private temporary directory removed when it closes (or at once
    if starting it fails or is interrupted)."""
    import dask
    from distributed import Client, LocalCluster

    directory = tempfile.mkdtemp(prefix="vlights-dask-")
    cluster = client = None
    # the worker processes start with Ctrl-C ignored (inherited): a terminal's Ctrl-C
    # reaches the whole process group, and this process alone should answer it, by
    # cancelling the tasks and closing the cluster
    main = threading.current_thread() is threading.main_thread()
    try:
        previous = signal.signal(signal.SIGINT, signal.SIG_IGN) if main else None
        try:
            with dask.config.set({"temporary-directory": directory}):  # the scheduler's scratch space too
                cluster = LocalCluster(dashboard_address=None, silence_logs=logging.ERROR, local_directory=directory)
        finally:
            if main:
                signal.signal(signal.SIGINT, previous)
        client = Client(cluster)
    except BaseException:
        try:
            if client is not None:
                client.close()
            if cluster is not None:
                cluster.close()
        finally:
            shutil.rmtree(directory, ignore_errors=True)
        raise
    return client, _LocalCluster(cluster, directory)


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
        self._scene = self._scatter((merged.positions, merged.faces, sa))

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
