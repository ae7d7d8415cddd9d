"""The solver on Dask: the same bits as on threads (photons and gather), whatever
happens to a worker; bad schedulers refused in one line, before any work (a malformed
or unsupported address) or within the connect timeout (nothing there, or a server that
is not a Dask scheduler); Ctrl-C cancels the tasks.

One small LocalCluster (2 worker processes, 1 thread each) for the module, used by the
tests marked ``dask``; skipped where Dask is not installed (``pip install ".[dask]"``).
See test_dask_cleanup.py for what a ``--scheduler dask`` run leaves behind (nothing)."""

import asyncio
import dataclasses
import http.server
import os
import signal
import socket
import threading
import time

import numpy as np
import pytest

from display.cli import main
from radiosity.files.errors import InputError
from radiosity.files.solution import load_solution
from radiosity.physics.environment import Environment
from radiosity.policies import cluster as dask_module
from radiosity.scene.loaders import load_scene
from radiosity.transport import solve as solve_module
from radiosity.transport.solve import SolveOptions, solve

distributed = pytest.importorskip("distributed")

KNOBS = dict(photons=200_000, gather_samples=16, light_samples=4, max_edge=150.0, seed=7)  # 4 batches, 2 glossy


@pytest.fixture(scope="module")
def scene():
    return load_scene("cornell-teapot")


@pytest.fixture(scope="module")
def on_threads(scene):
    return solve(scene, SolveOptions(threads=2, **KNOBS))


def assert_same_bits(a, b):
    assert [o.name for o in a.objects] == [o.name for o in b.objects]
    for x, y in zip(a.objects, b.objects):
        assert np.array_equal(x.radiance, y.radiance), x.name
    assert a.stats["energy"] == b.stats["energy"]
    assert (a.stats["photon_rays"], a.stats["gather_rays"]) == (b.stats["photon_rays"], b.stats["gather_rays"])


@pytest.mark.dask
def test_same_seed_same_bits_on_dask_as_on_threads(client, scene, on_threads):
    on_dask = solve(scene, SolveOptions(**KNOBS), client=client)
    assert_same_bits(on_threads, on_dask)
    assert any(o.grid_n > 1 for o in on_dask.objects)  # the gather ran too
    assert on_dask.stats["scheduler"].startswith("dask") and on_dask.stats["threads"] == 2
    other = solve(scene, SolveOptions(**{**KNOBS, "seed": 8}), client=client)
    assert not np.array_equal(other.object("teapot").radiance, on_dask.object("teapot").radiance)


@pytest.mark.dask
def test_a_textured_scene_same_bits_on_dask_as_on_threads(client, tmp_path):
    """The textures travel with the scattered scene: photons and gather read them alike."""
    from PIL import Image

    Image.fromarray(np.random.default_rng(3).integers(0, 256, (4, 6, 3), dtype=np.uint8)).save(tmp_path / "t.png")
    (tmp_path / "s.toml").write_text(
        '[materials.lamp]\nemission = 5.0\n[materials.tex]\ndiffuse = 0.9\ndiffuse_texture = "t.png"\n'
        '[materials.gloss]\ndiffuse = 0.1\nspecular = 0.5\nexponent = 50\n'
        '[[objects]]\nname = "floor"\nbuiltin = "quad"\nscale = 4\nmaterial = "tex"\n'
        '[[objects]]\nname = "wall"\nbuiltin = "cube"\nscale = 0.8\ntranslate = [0, 0.4, 0]\nmaterial = "tex"\n'
        '[[objects]]\nname = "ball"\nbuiltin = "sphere"\nsubdivisions = 2\nscale = 0.3\ntranslate = [1, 0.3, 0]\n'
        'material = "gloss"\n'
        '[[objects]]\nname = "lamp"\nbuiltin = "quad"\nflip = true\ntranslate = [0, 2, 0]\nmaterial = "lamp"\n'
    )
    scene = load_scene(tmp_path / "s.toml")
    knobs = {**KNOBS, "max_edge": 0.5}
    on_threads = solve(scene, SolveOptions(threads=2, **knobs))
    on_dask = solve(scene, SolveOptions(**knobs), client=client)
    assert_same_bits(on_threads, on_dask)
    for x, y in zip(on_threads.objects, on_dask.objects):
        assert (x.textured is None) == (y.textured is None)
        if x.textured is not None:
            assert np.array_equal(x.textured.irradiance, y.textured.irradiance)
    assert on_dask.object("floor").textured is not None


@pytest.mark.dask
def test_an_environment_gives_the_same_bits_on_dask(client, scene, on_threads):
    """The environment's arrays travel with the scene's (``SceneArrays.env``)."""
    sky = np.random.default_rng(3).random((8, 16, 3)).astype(np.float32) * 4
    lit = dataclasses.replace(scene, environment=Environment.from_image(sky))
    knobs = {**KNOBS, "photons": 100_000}
    on_dask = solve(lit, SolveOptions(**knobs), client=client)
    assert_same_bits(solve(lit, SolveOptions(threads=2, **knobs)), on_dask)
    assert on_dask.stats["energy"]["emitted"] != on_threads.stats["energy"]["emitted"]


class _Bar:
    """A progress bar that runs ``action`` at its first update."""

    action = None

    def __init__(self, **kwargs):
        self.total = kwargs.get("total")

    def update(self, n=1):
        action, _Bar.action = _Bar.action, None
        if action is not None:
            action()

    def close(self):
        pass


@pytest.mark.dask
def test_a_worker_lost_mid_run_changes_no_bit(client, scene, on_threads, monkeypatch):
    pids = client.run(os.getpid)
    victim = sorted(pids.values())[0]
    monkeypatch.setattr(solve_module, "_progress_factory", lambda enabled: _Bar)
    monkeypatch.setattr(_Bar, "action", lambda: os.kill(victim, signal.SIGKILL))  # after the first result
    on_dask = solve(scene, SolveOptions(**KNOBS), progress=True, client=client)
    assert _Bar.action is None  # the worker was killed
    assert_same_bits(on_threads, on_dask)
    client.wait_for_workers(2, timeout=60)  # the nanny restarts it
    assert victim not in client.run(os.getpid).values()


async def _tasks_once_none_is_left(dask_scheduler, timeout=30.0):
    """(Run on the scheduler.) The number of tasks it holds, as soon as it holds none
    (checked after every task transition, as the scheduler makes them) or after
    ``timeout`` seconds: the releases of a cancelled run reach it a moment later."""
    from distributed.diagnostics.plugin import SchedulerPlugin

    loop = asyncio.get_running_loop()
    none_left = asyncio.Event()

    def check():
        if not dask_scheduler.tasks:
            none_left.set()

    class Watch(SchedulerPlugin):
        name = "vlights-test-no-task-left"

        def transition(self, *args, **kwargs):
            loop.call_soon(check)  # once the transition is complete (a forgotten task is then gone)

    dask_scheduler.add_plugin(Watch(), name=Watch.name)
    try:
        check()
        await asyncio.wait_for(none_left.wait(), timeout)
    except TimeoutError:
        pass
    finally:
        dask_scheduler.remove_plugin(name=Watch.name)
    return len(dask_scheduler.tasks)


@pytest.mark.dask
def test_ctrl_c_cancels_the_tasks(client, scene, monkeypatch):
    def interrupt():
        raise KeyboardInterrupt

    monkeypatch.setattr(solve_module, "_progress_factory", lambda enabled: _Bar)
    monkeypatch.setattr(_Bar, "action", interrupt)
    with pytest.raises(KeyboardInterrupt):
        solve(scene, SolveOptions(**{**KNOBS, "photons": 2_000_000}), progress=True, client=client)
    assert client.run_on_scheduler(_tasks_once_none_is_left) == 0  # nothing left running, the scene released


@pytest.mark.dask
def test_cli_on_a_scheduler_address(client, scene, on_threads, tmp_path, capsys):
    out = tmp_path / "solution.npz"
    argv = ["solve", "cornell-teapot", "-o", str(out), "--scheduler", client.scheduler.address]
    for key, value in KNOBS.items():
        argv += [f"--{key.replace('_', '-')}", str(value)]
    assert main(argv) == 0
    loaded = load_solution(out)
    for a in on_threads.objects:
        assert np.array_equal(a.radiance, loaded.object(a.name).radiance), a.name
    assert "dask" in loaded.stats["scheduler"]


@pytest.mark.dask
def test_cli_scheduler_dask_starts_a_local_cluster(tmp_path):
    out = tmp_path / "solution.npz"
    argv = ["solve", "cornell", "--photons", "20000", "--max-edge", "400", "--scheduler", "dask", "-o", str(out)]
    assert main(argv) == 0
    assert load_solution(out).stats["scheduler"].startswith("dask")


def _refused_before_any_work(tmp_path, capsys, scheduler, *expected):
    out = tmp_path / "solution.npz"
    t = time.perf_counter()
    assert main(["solve", "cornell", "--scheduler", scheduler, "-o", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "--scheduler must be threads, dask or" in err, err
    for phrase in expected:
        assert phrase in err, err
    assert "Traceback" not in err
    assert not out.exists()
    assert time.perf_counter() - t < 10  # no connection tried (the timeout is 20 s)


@pytest.mark.parametrize("scheduler", ["nonsense", "tcp://host", "tcp://host:99999", "localhost:8786", ""])
def test_a_bad_scheduler_is_one_line_before_any_work(tmp_path, capsys, scheduler):
    _refused_before_any_work(tmp_path, capsys, scheduler)


@pytest.mark.parametrize(
    "scheduler, expected",
    [
        ("tls://127.0.0.1:8786", "tls:// needs certificates"),
        ("ucx://127.0.0.1:8786", "ucx:// needs UCX"),
        ("inproc://192.0.2.2/4242/1", "inproc:// reaches only a scheduler inside the same process"),
        ("ws://127.0.0.1:8786", "ws:// is not supported here"),
        ("http://127.0.0.1:8786", "unknown scheme 'http'"),
    ],
)
def test_an_unsupported_scheme_is_one_line_before_any_work(tmp_path, capsys, scheduler, expected):
    _refused_before_any_work(tmp_path, capsys, scheduler, expected, "only tcp://")


@pytest.mark.parametrize(
    "scheduler, expected",
    [
        ("tcp://[::1", "unbalanced '['"),
        ("tcp://[::1:8786", "unbalanced '['"),
        ("tcp://::1]:8786", "unbalanced ']'"),
        ("tcp://::1:8786", "an IPv6 host is written in brackets"),
        ("tcp://[not-ipv6]:8786", "'not-ipv6' in brackets is not an IPv6 address"),
        ("tcp://[::1]", "no port after the host"),
        ("tcp://[::1]8786", "no port after the host"),
        ("tcp://:8786", "'' is not a host name"),
        ("tcp://bad host:8786", "'bad host' is not a host name"),
        ("tcp://host:0", "the port '0' is not a number from 1 to 65535"),
        ("tcp://host:8786/path", "the port '8786/path'"),
    ],
)
def test_a_malformed_host_or_port_is_one_line_before_any_work(tmp_path, capsys, scheduler, expected):
    _refused_before_any_work(tmp_path, capsys, scheduler, expected)


@pytest.mark.parametrize("address", ["tcp://127.0.0.1:8786", "tcp://[::1]:8786", "tcp://node-7.cluster.example:1"])
def test_a_well_formed_address_is_taken(address):
    assert dask_module.address_problem(address) is None
    dask_module.check_scheduler(address)


@pytest.fixture
def http_server():
    """A tiny HTTP server (not a Dask scheduler) on a free local port, in a thread."""

    class Quiet(http.server.SimpleHTTPRequestHandler):
        def log_message(self, *args):
            pass

    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), Quiet)
    server.daemon_threads = True
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    yield f"tcp://127.0.0.1:{server.server_address[1]}"
    server.shutdown()
    server.server_close()


@pytest.fixture
def silent_server():
    """A port that takes connections and never says a word."""
    with socket.socket() as listening:
        listening.bind(("127.0.0.1", 0))
        listening.listen()
        yield f"tcp://127.0.0.1:{listening.getsockname()[1]}"


@pytest.mark.parametrize("server", ["http_server", "silent_server"])
def test_a_server_that_is_not_a_dask_scheduler_is_one_line_within_the_timeout(
    tmp_path, capsys, monkeypatch, request, server
):
    import distributed  # noqa: F401  (imported before the clock starts, as the command has)

    address = request.getfixturevalue(server)
    monkeypatch.setattr(dask_module, "CONNECT_TIMEOUT", 2.0)
    connecting = []
    real_connect = dask_module.connect

    def timed_connect(scheduler):
        t = time.perf_counter()
        try:
            return real_connect(scheduler)
        finally:
            connecting.append(time.perf_counter() - t)

    monkeypatch.setattr(dask_module, "connect", timed_connect)
    out = tmp_path / "solution.npz"
    assert main(["solve", "cornell", "--scheduler", address, "-o", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1, err
    assert f"{address} took the connection but is not a Dask scheduler (no Dask handshake within 2 s)" in err
    assert not out.exists()
    [elapsed] = connecting
    assert 1.9 < elapsed < 2.5  # the timeout set, not Dask's (none) nor the default 20 s


@pytest.mark.dask
def test_a_dask_worker_is_not_taken_for_the_scheduler(client, tmp_path, capsys):
    worker = sorted(client.nthreads())[0]
    out = tmp_path / "solution.npz"
    assert main(["solve", "cornell", "--scheduler", worker, "-o", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and f"{worker} is a Dask worker, not a Dask scheduler" in err, err
    assert not out.exists()


def test_an_unreachable_scheduler_is_one_line(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(dask_module, "CONNECT_TIMEOUT", 1.0)
    out = tmp_path / "solution.npz"
    assert main(["solve", "cornell", "--scheduler", "tcp://127.0.0.1:1", "-o", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "cannot reach the Dask scheduler at tcp://127.0.0.1:1 within 1 s" in err
    assert "Connection refused" in err and "object at 0x" not in err  # the cause, not Dask's wrapping
    assert not out.exists()


def test_without_dask_the_scheduler_is_refused(monkeypatch):
    monkeypatch.setattr(dask_module, "have_dask", lambda: False)
    with pytest.raises(InputError, match="needs Dask, which is not installed"):
        SolveOptions(scheduler="dask").resolved(load_scene("cornell"))
    SolveOptions(scheduler="threads").resolved(load_scene("cornell"))  # threads never need it


def test_dasks_sync_cancel_race_is_not_printed_but_other_loop_errors_are(caplog):
    # distributed.utils.sync's cancel callback can run before its future exists when a
    # signal interrupts the wait (seen once in 40 SIGTERM runs under load): NameError,
    # logged by tornado with a traceback after our one line. Only that record is dropped.
    import logging

    from radiosity.policies.cluster import _quiet_sync_race

    _quiet_sync_race()
    _quiet_sync_race()  # once is enough: no second filter
    logger = logging.getLogger("tornado.application")
    assert sum(type(f).__name__ == "_SyncCancelRace" for f in logger.filters) == 1

    def outer():
        future: object

        def cancel():
            if future is not None:  # noqa: F821 (unbound on purpose, as in Dask)
                pass

        cancel()

    with caplog.at_level(logging.ERROR, logger="tornado.application"):
        for fail in (outer, lambda: 1 / 0):
            try:
                fail()
            except (NameError, ZeroDivisionError):
                logger.error("Exception in callback", exc_info=True)
    assert [r.exc_info[0] for r in caplog.records] == [ZeroDivisionError]
