"""The fit's glossy objects on Dask: the same model, bit for bit, as in this
process; the window of objects in flight; the command's scheduler, checked and refused
in one line; its memory statement."""

from dataclasses import replace

import numpy as np
import pytest
from test_fit import synthetic
from test_fit_cli import run
from test_fit_streamed import OPTIONS, arrays, same, scene_file

from fitting import mixed
from fitting.cluster import fit_on_dask
from fitting.fit import fit, fit_object
from fitting.memory import PROCESS_BYTES, check_dask_memory, object_bytes
from radiosity.files.errors import InputError
from radiosity.files.solution import Solution, SolutionFile
from radiosity.policies import cluster

distributed = pytest.importorskip("distributed")


@pytest.fixture(scope="module")
def path(tmp_path_factory):
    return scene_file(tmp_path_factory.mktemp("dask_fit") / "s.npz")


@pytest.mark.dask
def test_the_model_on_dask_is_the_model_here_bit_for_bit(path, client, tmp_path):
    with SolutionFile(path) as f:
        here = fit(f, OPTIONS)
        there = fit(f, OPTIONS, client=client)
    same(arrays(here, tmp_path, "a.npz"), arrays(there, tmp_path, "b.npz"))
    assert [o.name for o in there.objects] == ["dome_0", "dome_1", "floor"]  # the file's order
    for a, b in zip(here.objects, there.objects):
        drop = ("time_s",)
        assert {k: v for k, v in a.info.items() if k not in drop} == {k: v for k, v in b.info.items() if k not in drop}
    assert {o.info["model"] for o in there.objects[:2]} <= {"probe", "probe+lights", "emitters", "lights"}  # fitted there


@pytest.mark.dask
def test_at_most_the_window_of_objects_is_in_flight(client, tmp_path, monkeypatch):
    """The client reads an object only when fewer than 2 x threads + 1 are out: with
    the cluster seen as one thread, at most 3 of 5 glossy objects are in flight."""
    objects = []
    for i in range(5):
        sol, _ = synthetic(np.random.default_rng(10 + i), lights=1, shininess=40.0, grid=5, subdivisions=0)
        objects.append(replace(sol.objects[0], name=f"dome_{i}", positions=sol.objects[0].positions + np.float32(3 * i)))
    path = tmp_path / "five.npz"
    Solution(objects=tuple(objects), settings={"quality": "draft"}, scene="test").save(path)
    first = sorted(client.nthreads())[0]
    monkeypatch.setattr(client, "nthreads", lambda *a, **kw: {first: 1})
    out = []

    class Bar:
        done = 0

        def update(self, n):
            self.done += n

    bar = Bar()
    with SolutionFile(path) as f:
        real = f.alone

        def alone(name):
            out.append(len(out) + 1 - bar.done)  # objects out once this one is sent
            return real(name)

        f.alone = alone
        place = (mixed.SceneGeometry.empty(), np.array([[-9.0] * 3, [99.0] * 3]), fit_object)
        model = fit_on_dask(client, f, OPTIONS, place, bar)
    assert len(out) == 5 and max(out) == 3  # the window filled, never passed
    assert [o.name for o in model] == [f"dome_{i}" for i in range(5)] and bar.done == 5


def test_a_solution_in_memory_is_not_sent_to_dask(path):
    from radiosity.files.solution import load_solution

    with pytest.raises(ValueError, match="needs a SolutionFile"):
        fit(load_solution(path), OPTIONS, client=object())


def test_the_command_refuses_a_bad_scheduler_in_one_line_before_reading(path, tmp_path, capsys):
    out = tmp_path / "f.npz"
    code, _, err = run(["fit", str(tmp_path / "missing.npz"), "-o", str(out), "--scheduler", "http://x:1"], capsys)
    assert code == 2 and len(err.strip().splitlines()) == 1
    assert "--scheduler must be threads, dask or a Dask scheduler address" in err and "unknown scheme 'http'" in err
    assert not out.exists()


def test_workers_do_not_go_with_a_scheduler(path, tmp_path, capsys):
    code, _, err = run(["fit", str(path), "-o", str(tmp_path / "f.npz"), "--scheduler", "dask", "--workers", "2"], capsys)
    assert code == 2 and len(err.strip().splitlines()) == 1 and "--workers" in err and "--scheduler dask" in err
    assert not (tmp_path / "f.npz").exists()


def test_an_unreachable_scheduler_is_one_line_and_no_file(path, tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(cluster, "CONNECT_TIMEOUT", 1.0)
    out = tmp_path / "f.npz"
    code, _, err = run(["fit", str(path), "-o", str(out), "--scheduler", "tcp://127.0.0.1:1"], capsys)
    assert code == 2 and len(err.strip().splitlines()) == 1, err
    assert "cannot reach the Dask scheduler at tcp://127.0.0.1:1 within 1 s" in err
    assert not out.exists() and not list(tmp_path.glob("*.npz*"))


def test_without_dask_the_scheduler_is_refused(path, tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(cluster, "have_dask", lambda: False)
    code, _, err = run(["fit", str(path), "-o", str(tmp_path / "f.npz"), "--scheduler", "dask"], capsys)
    assert code == 2 and "needs Dask, which is not installed" in err


def test_the_dask_estimate_counts_the_objects_in_flight_here_and_one_on_a_worker(path):
    lines = []
    with SolutionFile(path) as f:
        sizes = {n: f.sizes(n) for n in f.names}
        glossy = sorted(((v * d, n) for n, (v, d, _) in sizes.items() if d > 1), reverse=True)
        geometry = sum(mesh + 36 * v for v, d, mesh in sizes.values())
        check_dask_memory(f, 1, available=2**40, out=lines.append)
        [line] = lines
        here = PROCESS_BYTES + 2 * geometry + glossy[0][0] * 12
        assert f"about {here / 2**30:.2f} GB at most here of 1024.0 GB available" in line
        v, d, _ = sizes[glossy[0][1]]
        assert f"each Dask worker about {(PROCESS_BYTES + object_bytes(v, d)) / 2**30:.2f} GB" in line
        assert repr(glossy[0][1]) in line
        lines.clear()
        check_dask_memory(f, 2, available=2**40, out=lines.append)
        two = PROCESS_BYTES + 2 * geometry + (glossy[0][0] + glossy[1][0]) * 12
        assert f"about {two / 2**30:.2f} GB" in lines[0]
        with pytest.raises(InputError, match="fit needs about .* GB here of .* to send its objects to Dask"):
            check_dask_memory(f, 2, available=1000, out=lines.append)


@pytest.mark.dask
def test_the_command_on_a_running_scheduler_writes_the_same_file(path, client, tmp_path, capsys):
    here, there = tmp_path / "here.npz", tmp_path / "there.npz"
    assert run(["fit", str(path), "-o", str(here), "--workers", "1"], capsys)[0] == 0
    code, stdout, err = run(["fit", str(path), "-o", str(there), "--scheduler", client.scheduler.address], capsys)
    assert code == 0, err
    assert f"fit: on dask {client.scheduler.address} (2 threads)" in err and "each Dask worker about" in err
    with np.load(here) as a, np.load(there) as b:
        assert a.files == b.files
        assert all(np.array_equal(a[k], b[k]) for k in a.files if k != "meta")


@pytest.mark.dask
@pytest.mark.subprocess
def test_ctrl_c_during_a_fit_on_dask_is_one_line_and_no_file(path, tmp_path):
    """SIGINT once the tasks are out: the command cancels them, closes its LocalCluster
    and says one line; nothing is written."""
    import signal

    from child_process import Child, vlights

    out = tmp_path / "fit.npz"
    child = Child(vlights("fit", path, "--scheduler", "dask", "--lights", "8", "--iterations", "5000", "-o", out))
    child.wait_for(r"fit: on dask tcp://")  # not the whole line: the line is one write, not split by the signal
    child.send(signal.SIGINT)
    code, _, err = child.finish()
    if code == 0:
        pytest.skip("the fit finished before the signal came")
    assert code == 130, err
    assert err.strip().splitlines()[-1] == "vlights fit: interrupted" and "Traceback" not in err, err
    assert "8787" not in err, err  # the scheduler's HTTP server takes a free port, without a warning
    assert list(tmp_path.iterdir()) == []
