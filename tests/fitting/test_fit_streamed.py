"""The fit read an object at a time: the same model as from a loaded
solution, the same bits with any number of worker processes or numba threads, and a
memory estimate that is said before the work and refuses in one line what cannot fit."""

from dataclasses import replace

import numba
import numpy as np
import pytest
from test_fit import synthetic
from test_fit_cli import DIFFUSE_MATERIAL, run

from fitting import lobes, mixed
from fitting.data import fit_data
from fitting.fit import FitOptions, fit, planned_threads, planned_workers
from fitting.memory import PROCESS_BYTES, SAMPLE_BYTES, check_fit_memory, fit_estimate, object_bytes
from fitting.results import Lights
from radiosity.files.errors import InputError
from radiosity.files.solution import ObjectSolution, Solution, SolutionFile, load_solution

OPTIONS = FitOptions.for_quality("draft")


def scene_file(path):
    """Two glossy domes (different lights and lobes: one a probe's, one needing lights)
    and a diffuse floor."""
    objects = []
    for i, (seed, shininess, grid) in enumerate(((1, 30.0, 9), (2, 300.0, 9))):  # alike in cost: two workers
        sol, _ = synthetic(np.random.default_rng(seed), lights=2, shininess=shininess, grid=grid, subdivisions=1)
        objects.append(replace(sol.objects[0], name=f"dome_{i}", positions=sol.objects[0].positions + np.float32(3 * i)))
    objects.append(ObjectSolution(
        name="floor", positions=np.array([[0, 0, 0], [9, 0, 0], [0, 9, 0]], np.float32),
        normals=np.tile(np.float32([0, 0, 1]), (3, 1)), tangents=np.tile(np.float32([1, 0, 0]), (3, 1)),
        faces=np.array([[0, 1, 2]], np.int32), directions=np.float32([[0, 0, 1]]),
        radiance=np.full((3, 1, 3), 0.25, np.float32), material=DIFFUSE_MATERIAL,
    ))
    Solution(objects=tuple(objects), settings={"quality": "draft"}, scene="test").save(path)
    return path


@pytest.fixture(scope="module")
def path(tmp_path_factory):
    return scene_file(tmp_path_factory.mktemp("streamed") / "s.npz")


def arrays(model, tmp_path, name):
    model.save(tmp_path / name)
    with np.load(tmp_path / name) as z:
        return {k: z[k] for k in z.files if k != "meta"}


def same(a, b):
    assert a.keys() == b.keys()
    differ = [k for k in a if not np.array_equal(a[k], b[k])]
    assert not differ, differ


def test_the_file_read_an_object_at_a_time_holds_what_load_solution_reads(path):
    whole = load_solution(path)
    with SolutionFile(path) as f:
        assert f.names == whole.names and f.version == whole.version
        for o in whole.objects:
            one = f.object(o.name)
            for key in ("positions", "normals", "tangents", "faces", "directions", "radiance"):
                assert np.array_equal(getattr(one, key), getattr(o, key))
            positions, faces = f.geometry(o.name)
            assert np.array_equal(positions, o.positions) and np.array_equal(faces, o.faces)
            assert f.n_directions(o.name) == o.directions.shape[0]
            alone = f.alone(o.name)
            assert alone.names == (o.name,) and alone.settings == whole.settings and alone.scene == whole.scene
        assert f.load().names == whole.names
        with pytest.raises(KeyError, match="no object 'nothing'"):
            f.geometry("nothing")


def test_streamed_fit_is_the_loaded_fit_and_workers_change_no_bit(path, tmp_path):
    loaded = arrays(fit(load_solution(path), OPTIONS), tmp_path, "a.npz")
    with SolutionFile(path) as f:
        one = arrays(fit(f, OPTIONS, workers=1), tmp_path, "b.npz")
        two = arrays(fit(f, OPTIONS, workers=2), tmp_path, "c.npz")
    same(loaded, one)
    same(one, two)
    assert any(k.endswith("/light_pos") and len(v) for k, v in one.items()) or any(k.endswith("/probe") for k in one)


def test_workers_need_the_file():
    sol, _ = synthetic(np.random.default_rng(0), lights=1, grid=4, subdivisions=1)
    with pytest.raises(ValueError, match="SolutionFile"):
        fit(sol, OPTIONS, workers=2)


@pytest.mark.skipif(numba.config.NUMBA_NUM_THREADS < 2, reason="one numba thread: nothing to compare")
def test_the_lights_loss_has_the_same_bits_on_any_number_of_threads():
    sol, _ = synthetic(np.random.default_rng(3), lights=3, shininess=80.0, grid=16, subdivisions=3)
    data = fit_data(sol.objects[0])
    problem = mixed.Problem.make(data, np.ones((1, 1, 1)), True, mixed.SceneGeometry.empty(), (1.0, 1e4))
    rng = np.random.default_rng(4)
    pos = np.concatenate([rng.normal(size=(3, 3)), np.zeros((3, 1))], axis=1)
    pos[:, 2] = np.abs(pos[:, 2]) + 0.5
    pos[:, :3] /= np.linalg.norm(pos[:, :3], axis=1, keepdims=True)
    lights = Lights(pos, rng.uniform(0.5, 2, (3, 3)), np.array([20.0, 80.0, 300.0]))
    v = data.n_vertices
    emitted, coefficients = rng.uniform(0, 0.2, (v, 3)), rng.uniform(0, 1, (v, 3, 3))
    before = numba.get_num_threads()
    losses = []
    try:
        for threads in (1, 2, numba.config.NUMBA_NUM_THREADS):
            numba.set_num_threads(threads)
            partial = np.zeros((v, 3, 7))
            losses.append(lobes.mixed_loss_and_gradient(data.normals, data.views, lights, problem.samples, emitted,
                                                        coefficients, partial))
    finally:
        numba.set_num_threads(before)
    assert losses[0] > 0 and len({float(x).hex() for x in losses}) == 1, losses


def test_the_estimate_adds_the_base_the_geometry_and_each_worker_s_largest_object(path):
    with SolutionFile(path) as f:
        geometry = sum(f.geometry(n)[0].nbytes * 4 + f.geometry(n)[1].nbytes for n in f.names)
        shapes = sorted(((len(f.geometry(n)[0]), f.n_directions(n)) for n in f.names if f.n_directions(n) > 1),
                        key=lambda s: -s[0] * s[1])
        work = [object_bytes(v, d) for v, d in shapes]
        one, biggest = fit_estimate(f, 1)
        two, _ = fit_estimate(f, 2)
        assert biggest[0] == "dome_1" and (biggest[1], biggest[2]) == shapes[0]
        assert one == PROCESS_BYTES + 2 * geometry + work[0]
        assert two == PROCESS_BYTES + 2 * geometry + 2 * PROCESS_BYTES + work[0] + work[1]
        said = []
        assert check_fit_memory(f, 2, available=two, out=said.append) == 2
        assert check_fit_memory(f, 2, available=two - 1, out=said.append) == 1
        assert "fewer than the 2 asked" in said[-1] and "'dome_1'" in said[-1]
        with pytest.raises(InputError, match=r"fit needs about .* GB of .* GB available; largest glossy object 'dome_1'"):
            check_fit_memory(f, 1, available=one - 1, out=said.append)


def test_an_object_s_working_set_is_bounded_by_the_search_and_the_block_not_its_samples():
    small, large = object_bytes(2_000, 1_024), object_bytes(100_000, 1_024)
    # the search and a block are capped: beyond them an object adds its float32 radiance and its vertices
    assert large - small == 98_000 * (1_024 * 12 + 1_000)
    assert large < 100_000 * 1_024 * SAMPLE_BYTES / 40  # 2.6 GB where arrays of every sample were 123 GB
    assert object_bytes(100_000, 1_024, search_samples=2**20) > large  # a larger search holds more


def test_the_command_refuses_what_does_not_fit_in_one_line_and_writes_nothing(path, tmp_path, capsys, monkeypatch):
    monkeypatch.setattr("fitting.memory.available_memory", lambda: 10 * 2**20)
    out = tmp_path / "fit.npz"
    code, stdout, err = run(["fit", str(path), "-o", str(out)], capsys)
    assert code == 2 and err.count("\n") == 1 and "fit needs about" in err and "Traceback" not in err, err
    assert not out.exists() and not list(tmp_path.iterdir())


def test_the_command_says_its_estimate_and_takes_workers(path, tmp_path, capsys):
    out = tmp_path / "fit.npz"
    code, stdout, err = run(["fit", str(path), "-o", str(out), "--workers", "2"], capsys)
    assert code == 0, err
    assert "fit: about" in err and "2 workers" in err and "fit: about" not in stdout
    code, _, err = run(["fit", str(path), "-o", str(out), "--workers", "0"], capsys)
    assert code == 2 and "--workers" in err


def test_a_worker_shows_warnings_as_its_parent_does(path):
    # the worker's initializer takes the parent's warnings.showwarning (the command's
    # "vlights: warning: ..." line) and uses it
    import warnings

    from fitting.fit import _WORKER, _worker_start

    before, threads = warnings.showwarning, numba.get_num_threads()
    said = []
    try:
        _worker_start(1, lambda message, *rest, **kw: said.append(str(message)), str(path), "scene", "box")
        assert _WORKER["scene"] == "scene" and _WORKER["source"].names == ("dome_0", "dome_1", "floor")
        assert numba.get_num_threads() == 1
        warnings.warn("a sharp lobe", RuntimeWarning, stacklevel=1)
    finally:
        warnings.showwarning = before
        numba.set_num_threads(threads)
        _WORKER.pop("source").close()
        _WORKER.clear()
    assert said == ["a sharp lobe"]


def test_workers_are_used_only_where_they_pay(path, tmp_path):
    with SolutionFile(path) as f:
        assert planned_workers(f, 2) == 2 and planned_workers(f, 8) == 2  # two glossy objects alike
        assert planned_workers(f, 1) == 1
        assert planned_workers(f, 2, {"a": 600, "b": 400}) == 1  # one object is most of the work
        assert planned_workers(f, 4, {"a": 300, "b": 300, "c": 400}) == 3
        assert planned_workers(f, 4, {}) == 1  # nothing glossy
    one = tmp_path / "one.npz"
    whole = load_solution(path)
    Solution(objects=whole.objects[1:], settings=whole.settings, scene="test").save(one)  # one glossy dome
    with SolutionFile(one) as f:
        assert planned_workers(f, 2) == 1


def test_where_one_object_is_most_of_the_work_threads_fit_the_others_beside_it_bit_for_bit(path, tmp_path, capsys):
    """A dome of 4 x the other's directions: no worker processes (they would wait for it),
    but two threads of this process (the small dome fitted beside the large): the same
    bits as one, and the command says its threads."""
    whole = load_solution(path)
    big, _ = synthetic(np.random.default_rng(3), lights=2, shininess=30.0, grid=18, subdivisions=1)
    objects = (replace(big.objects[0], name="dome_big"), *whole.objects[1:])
    uneven = tmp_path / "uneven.npz"
    Solution(objects=objects, settings=whole.settings, scene="test").save(uneven)
    with SolutionFile(uneven) as f:
        assert planned_workers(f, 2) == 1 and planned_threads(f, 2) == 2 and planned_threads(f, 8) == 2
        one = arrays(fit(f, OPTIONS, workers=1), tmp_path, "one.npz")
        two = arrays(fit(f, OPTIONS, workers=2), tmp_path, "two.npz")
    same(one, two)
    code, _, err = run(["fit", str(uneven), "-o", str(tmp_path / "f.npz"), "--workers", "2"], capsys)
    assert code == 0 and "2 threads" in err, err


def test_a_bad_object_anywhere_is_one_line_before_the_estimate(path, tmp_path, capsys):
    # the file is read an object at a time; a NaN in its last glossy object must still be
    # refused before the estimate is said or any object fitted
    import zipfile

    bad = tmp_path / "bad.npz"
    with zipfile.ZipFile(path) as src, zipfile.ZipFile(bad, "w") as dst:
        for info in src.infolist():
            data = src.read(info.filename)
            if info.filename == "dome_1/radiance.npy":
                import io

                array = np.load(io.BytesIO(data))
                array[3, 2, 1] = np.nan
                buf = io.BytesIO()
                np.save(buf, array)
                data = buf.getvalue()
            dst.writestr(info, data)
    out = tmp_path / "fit.npz"
    code, stdout, err = run(["fit", str(bad), "-o", str(out)], capsys)
    assert code == 2 and err.count("\n") == 1 and "dome_1/radiance" in err and "NaN" in err, err
    assert "fit: about" not in err and not out.exists()
