"""The solver on Dask: the same bits as on threads (photons and gather), whatever
happens to a worker; bad schedulers refused in one line; Ctrl-C cancels the tasks.

One small LocalCluster (2 worker processes, 1 thread each) for the module; skipped
where Dask is not installed (``pip install ".[dask]"``)."""

import os
import signal
import time

import numpy as np
import pytest

from display.cli import main
from radiosity.formats import load_solution
from radiosity.formats.errors import InputError
from radiosity.scene.loaders import load_scene
from radiosity.transport import distributed as dask_module
from radiosity.transport import solve as solve_module
from radiosity.transport.solve import SolveOptions, solve

distributed = pytest.importorskip("distributed")

KNOBS = dict(photons=200_000, gather_samples=16, light_samples=4, max_edge=150.0, seed=7)  # 4 batches, 2 glossy


@pytest.fixture(scope="module")
def client():
    cluster = distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None)
    client = distributed.Client(cluster)
    yield client
    client.close()
    cluster.close()


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


def test_same_seed_same_bits_on_dask_as_on_threads(client, scene, on_threads):
    on_dask = solve(scene, SolveOptions(**KNOBS), client=client)
    assert_same_bits(on_threads, on_dask)
    assert any(o.grid_n > 1 for o in on_dask.objects)  # the gather ran too
    assert on_dask.stats["scheduler"].startswith("dask") and on_dask.stats["threads"] == 2
    other = solve(scene, SolveOptions(**{**KNOBS, "seed": 8}), client=client)
    assert not np.array_equal(other.object("teapot").radiance, on_dask.object("teapot").radiance)


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


def test_ctrl_c_cancels_the_tasks(client, scene, monkeypatch):
    def interrupt():
        raise KeyboardInterrupt

    monkeypatch.setattr(solve_module, "_progress_factory", lambda enabled: _Bar)
    monkeypatch.setattr(_Bar, "action", interrupt)
    with pytest.raises(KeyboardInterrupt):
        solve(scene, SolveOptions(**{**KNOBS, "photons": 2_000_000}), progress=True, client=client)

    def tasks(dask_scheduler):
        return len(dask_scheduler.tasks)

    deadline = time.time() + 30
    while client.run_on_scheduler(tasks) and time.time() < deadline:
        time.sleep(0.1)
    assert client.run_on_scheduler(tasks) == 0  # nothing left running, the scattered scene released


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


def test_cli_scheduler_dask_starts_a_local_cluster(tmp_path):
    out = tmp_path / "solution.npz"
    argv = ["solve", "cornell", "--photons", "20000", "--max-edge", "400", "--scheduler", "dask", "-o", str(out)]
    assert main(argv) == 0
    assert load_solution(out).stats["scheduler"].startswith("dask")


@pytest.mark.parametrize("scheduler", ["nonsense", "tcp://host", "tcp://host:99999", "localhost:8786", ""])
def test_a_bad_scheduler_is_one_line_before_any_work(tmp_path, capsys, scheduler):
    out = tmp_path / "solution.npz"
    assert main(["solve", "cornell", "--scheduler", scheduler, "-o", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "--scheduler must be threads, dask or" in err
    assert not out.exists()


def test_an_unreachable_scheduler_is_one_line(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(dask_module, "CONNECT_TIMEOUT", 1.0)
    out = tmp_path / "solution.npz"
    assert main(["solve", "cornell", "--scheduler", "tcp://127.0.0.1:1", "-o", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "cannot reach the Dask scheduler at tcp://127.0.0.1:1" in err
    assert not out.exists()


def test_without_dask_the_scheduler_is_refused(monkeypatch):
    monkeypatch.setattr(dask_module, "have_dask", lambda: False)
    with pytest.raises(InputError, match="needs Dask, which is not installed"):
        SolveOptions(scheduler="dask").resolved(load_scene("cornell"))
    SolveOptions(scheduler="threads").resolved(load_scene("cornell"))  # threads never need it
