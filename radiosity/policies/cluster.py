"""Reaching Dask, for every stage that runs work on it (``--scheduler dask |
tcp://HOST:PORT``: the solve's batches, the fit's objects).

  - ``dask``: a LocalCluster sized to this machine, whose scheduler and workers keep
    their scratch space in a private temporary directory, removed when the run ends,
    however it ends;
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

from radiosity.files.errors import InputError

__all__ = ["CONNECT_TIMEOUT", "SCHEDULERS", "address_problem", "check_scheduler", "connect", "have_dask"]

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
                "distributed.Client: solve(..., client=), fit(..., client=))"
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
                # no dashboard, and the scheduler's own HTTP server (health, metrics) on a
                # free local port, not 8787 with a warning when that is taken; the
                # workers' logs silenced below CRITICAL: a failed task reaches this
                # process as an exception, and what they log as errors is a heartbeat
                # that fails while the cluster closes under Ctrl-C or SIGTERM
                cluster = LocalCluster(dashboard_address=None, silence_logs=logging.CRITICAL, local_directory=directory,
                                       scheduler_kwargs={"dashboard_address": "127.0.0.1:0"})
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
