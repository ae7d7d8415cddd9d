"""Tests for radiosity.files.solution (the solution file) and radiosity.files.atomic.

A small synthetic solution (one diffuse object, one glossy object on the 4 x 4 grid)
is saved and read back, read with plain numpy, written atomically under an
interrupted writer, and every kind of damaged file is refused with a one-line
InputError.
"""

from __future__ import annotations

import dataclasses
import json
import os
import zipfile

import numpy as np
import pytest
from refusals import input_error

from radiosity.files.atomic import atomic_output
from radiosity.files.camera import Camera
from radiosity.files.errors import InputError
from radiosity.files.solution import (
    ARRAY_KEYS,
    ObjectSolution,
    Solution,
    load_solution,
)
from radiosity.physics.directions import DIFFUSE_DIRECTIONS, grid_directions
from radiosity.physics.materials import Material

DTYPES = {
    "positions": np.float32,
    "normals": np.float32,
    "tangents": np.float32,
    "faces": np.int32,
    "directions": np.float32,
    "radiance": np.float32,
}
DIFFUSE_NAME = "floor:left.0"  # ':' and '.' are allowed in names
GLOSSY_NAME = "teapot"
BLACK = [0.0, 0.0, 0.0]
WHITE = {"diffuse": [0.7, 0.7, 0.7], "specular": BLACK, "exponent": 0.0, "emission": BLACK}
POLISHED = {
    "diffuse": [0.2, 0.05, 0.05], "specular": [0.5, 0.5, 0.5], "exponent": 60.0, "emission": BLACK
}


def make_object(name: str, n_grid: int, material: dict, seed: int) -> ObjectSolution:
    """A 2 x 2 quad grid (V = 9, F = 8) in the plane z = 0, arrays as float64 / int64."""
    rng = np.random.default_rng(seed)
    u, v = np.meshgrid(np.arange(3.0), np.arange(3.0))
    positions = np.stack([u.ravel(), v.ravel(), np.zeros(9)], axis=1)
    faces = []
    for r in range(2):
        for c in range(2):
            k = 3 * r + c
            faces += [[k, k + 1, k + 4], [k, k + 4, k + 3]]
    directions = DIFFUSE_DIRECTIONS if n_grid == 0 else grid_directions(n_grid)
    return ObjectSolution(
        name=name,
        positions=positions,
        normals=np.tile([0.0, 0.0, 1.0], (9, 1)),
        tangents=np.tile([1.0, 0.0, 0.0], (9, 1)),
        faces=np.array(faces, dtype=np.int64),
        directions=directions,
        radiance=rng.random((9, len(directions), 3)) * 10.0,
        material=material,
    )


def make_solution() -> Solution:
    return Solution(
        objects=(make_object(DIFFUSE_NAME, 0, WHITE, 1), make_object(GLOSSY_NAME, 4, POLISHED, 2)),
        settings={"quality": "draft", "grid": {"teapot": 4}},
        stats={
            "photons": 1000, "rays": np.int64(5000), "wall_s": {"trace": np.float64(0.5)}, "seed": 7
        },
        scene="cornell-teapot",
    )


@pytest.fixture
def solution() -> Solution:
    return make_solution()


@pytest.fixture
def saved(tmp_path, solution) -> str:
    path = str(tmp_path / "solution.npz")
    solution.save(path)
    return path


# ---------------------------------------------------------------------------
# Round trip and the file's layout
# ---------------------------------------------------------------------------


def test_round_trip(saved, solution):
    loaded = load_solution(saved)
    assert loaded.names == (DIFFUSE_NAME, GLOSSY_NAME)
    assert loaded.scene == "cornell-teapot"
    assert loaded.settings == {"quality": "draft", "grid": {"teapot": 4}}
    assert loaded.stats == {"photons": 1000, "rays": 5000, "wall_s": {"trace": 0.5}, "seed": 7}
    for before, after in zip(solution.objects, loaded.objects):
        assert after.name == before.name
        assert after.material == before.material
        for key, dtype in DTYPES.items():
            a = getattr(after, key)
            assert a.dtype == dtype, key
            np.testing.assert_array_equal(a, getattr(before, key))
    assert Solution.load(saved).names == loaded.names


def test_object_properties(solution):
    diffuse, glossy = solution.object(DIFFUSE_NAME), solution.object(GLOSSY_NAME)
    assert diffuse.is_diffuse and diffuse.grid_n == 0
    assert not glossy.is_diffuse and glossy.grid_n == 4
    assert glossy.radiance.shape == (9, 16, 3)
    b = glossy.bitangents
    assert b.dtype == np.float32 and b.shape == (9, 3)
    np.testing.assert_array_equal(b, np.tile([0.0, 1.0, 0.0], (9, 1)))  # cross(z, x) = y
    with pytest.raises(KeyError, match="lamp"):
        solution.object("lamp")
    assert "teapot" in repr(solution) and "D=16" in repr(glossy)


def test_constructor_converts_to_the_contract_dtypes(solution):
    for o in solution.objects:
        for key, dtype in DTYPES.items():
            a = getattr(o, key)
            assert a.dtype == dtype and a.flags.c_contiguous, key


def test_file_has_exactly_the_contract_keys_and_plain_numpy_reads_it(saved):
    with np.load(saved, allow_pickle=False) as npz:
        expected = {"meta"} | {f"{n}/{k}" for n in (DIFFUSE_NAME, GLOSSY_NAME) for k in ARRAY_KEYS}
        assert set(npz.files) == expected
        for name, d in ((DIFFUSE_NAME, 1), (GLOSSY_NAME, 16)):
            for key, dtype in DTYPES.items():
                assert npz[f"{name}/{key}"].dtype == dtype
            assert npz[f"{name}/positions"].shape == (9, 3)
            assert npz[f"{name}/faces"].shape == (8, 3)
            assert npz[f"{name}/directions"].shape == (d, 3)
            assert npz[f"{name}/radiance"].shape == (9, d, 3)
        np.testing.assert_allclose(npz[f"{GLOSSY_NAME}/directions"], grid_directions(4), atol=1e-7)
        raw = npz["meta"]
        assert raw.shape == () and raw.dtype.kind == "U"
        meta = json.loads(str(raw))
    assert meta["format"] == "vlights.solution" and meta["version"] == 2
    assert meta["emitters"] == [] and meta["emitter_nodes"] == 8  # version 2: no closed-form highlights here
    assert meta["objects"] == [DIFFUSE_NAME, GLOSSY_NAME]
    assert meta["materials"] == {DIFFUSE_NAME: WHITE, GLOSSY_NAME: POLISHED}
    assert set(meta) >= {"settings", "stats", "scene"}
    assert meta["scene"] == "cornell-teapot"


def test_file_is_compressed(tmp_path):
    o = make_object("flat", 32, POLISHED, 3)
    o = ObjectSolution(**{**{k: getattr(o, k) for k in ("name", "material", *ARRAY_KEYS)},
                          "radiance": np.zeros((9, 1024, 3))})
    path = tmp_path / "zeros.npz"
    Solution((o,)).save(path)
    assert path.stat().st_size < o.radiance.nbytes / 4


def test_material_objects_are_accepted():
    m = Material("polished", **POLISHED)
    o = make_object("teapot", 2, m, 4)
    assert o.material == POLISHED


def test_a_fresnel_material_round_trips_and_files_without_it_have_no_key(tmp_path, saved):
    plastic = {"diffuse": [0.6, 0.5, 0.4], "specular": [1.0, 1.0, 1.0], "exponent": 60.0, "emission": BLACK,
               "fresnel": [0.04, 0.04, 0.04]}  # kd + ks > 1: allowed with Fresnel
    path = tmp_path / "fresnel.npz"
    Solution((make_object("floor", 2, plastic, 5),)).save(path)
    assert load_solution(path).object("floor").material == plastic
    with np.load(saved, allow_pickle=False) as npz:
        meta = json.loads(str(npz["meta"]))
    assert all("fresnel" not in m for m in meta["materials"].values())
    bad = dict(plastic, fresnel=[0.04, 0.04])
    with pytest.raises(ValueError, match="fresnel must be 3 numbers"):
        make_object("floor", 2, bad, 5)


MICROFACET = {"kind": "roughconductor", "distribution": "ggx", "alpha": 0.05, "eta": [1.66, 0.88, 0.52],
              "k": [9.2, 6.3, 4.8], "specular_reflectance": [1.0, 1.0, 1.0], "diffuse_reflectance": [0.0, 0.0, 0.0],
              "nonlinear": False}


def test_a_microfacet_material_is_version_6_round_trips_and_others_stay_as_they_were(tmp_path, saved):
    metal = {"diffuse": [0.0, 0.0, 0.0], "specular": [1.0, 1.0, 1.0], "exponent": 500.0, "emission": BLACK,
             "fresnel": [0.9, 0.9, 0.9], "microfacet": MICROFACET}
    path = tmp_path / "metal.npz"
    Solution((make_object("plate", 2, metal, 5),)).save(path)
    loaded = load_solution(path)
    assert loaded.version == 6 and loaded.object("plate").material == metal
    assert Material("plate", **loaded.object("plate").material).microfacet.k == (9.2, 6.3, 4.8)
    assert load_solution(saved).version < 6


def test_microfacet_highlights_make_version_8_and_older_files_keep_the_stand_in(tmp_path, saved):
    """A solution whose microfacet objects' highlights are their own lobes' is version 8 and
    says so (``lobe_of`` gives the model); without the flag, version 6 as before, its lobe
    the stand-in's (None); a flag that is not a boolean is refused in one line."""
    metal = {"diffuse": [0.0, 0.0, 0.0], "specular": [1.0, 1.0, 1.0], "exponent": 500.0, "emission": BLACK,
             "fresnel": [0.9, 0.9, 0.9], "microfacet": MICROFACET}
    objects = (make_object("plate", 2, metal, 5),)
    Solution(objects, microfacet_highlights=True).save(tmp_path / "new.npz")
    Solution(objects).save(tmp_path / "old.npz")
    new, old = load_solution(tmp_path / "new.npz"), load_solution(tmp_path / "old.npz")
    assert (new.version, new.microfacet_highlights, new.lobe_of("plate")) == (8, True, MICROFACET)
    assert (old.version, old.microfacet_highlights, old.lobe_of("plate")) == (6, False, None)
    assert load_solution(saved).version < 6 and not Solution(load_solution(saved).objects,
                                                             microfacet_highlights=True).version == 8
    meta, arrays = contents(new)
    meta["microfacet_highlights"] = "yes"
    refused(write_npz(tmp_path / "bad.npz", meta, arrays), "'microfacet_highlights' must be true or false")


@pytest.mark.parametrize("change, fragment", [
    ({"kind": "roughglass"}, "microfacet kind 'roughglass'"),
    ({"distribution": "phong"}, "microfacet distribution 'phong'"),
    ({"alpha": 0.0}, "microfacet alpha = 0"),
    ({"alpha": "rough"}, "microfacet alpha must be a number"),
    ({"eta": [0.0, 0.88, 0.52], "k": [0.0, 1.0, 1.0]}, "must not be 0"),
    ({"k": [1.0, float("nan"), 1.0]}, "microfacet k green"),
    ({"diffuse_reflectance": [0.5, 0.5, 0.5]}, "a conductor has no diffuse_reflectance"),
    ({"nonlinear": "yes"}, "'nonlinear' must be true or false"),
    ({"roughness": 1}, "unknown key(s) 'roughness'"),
])
def test_a_bad_microfacet_entry_is_refused_in_one_line(tmp_path, solution, change, fragment):
    meta, arrays = contents(solution)
    name = next(iter(meta["materials"]))
    meta["materials"][name]["microfacet"] = dict(MICROFACET, **change)
    meta["version"] = 6
    refused(write_npz(tmp_path / "s.npz", meta, arrays), fragment)


GLASS = {"kind": "roughdielectric", "eta": 1.5, "distribution": "ggx", "alpha": 0.2,
         "specular_reflectance": [1.0, 1.0, 1.0], "specular_transmittance": [0.9, 0.8, 0.7]}


def test_a_glass_material_is_version_7_round_trips_and_others_stay_as_they_were(tmp_path, saved):
    glass = {"diffuse": BLACK, "specular": BLACK, "exponent": 0.0, "emission": BLACK, "glass": GLASS}
    path = tmp_path / "glass.npz"
    Solution((make_object("ball", 1, glass, 5),)).save(path)
    loaded = load_solution(path)
    assert loaded.version == 7 and loaded.object("ball").material == glass
    assert Material("ball", **loaded.object("ball").material).glass.specular_transmittance == (0.9, 0.8, 0.7)
    assert load_solution(saved).version < 7


@pytest.mark.parametrize("change, fragment", [
    ({"kind": "crystal"}, "glass kind 'crystal'"),
    ({"eta": 1.0}, "glass eta = 1"),
    ({"alpha": 0.0}, "glass alpha = 0"),
    ({"kind": "dielectric"}, "a smooth glass (dielectric) has alpha 0"),
    ({"specular_transmittance": [1.0, 2.0, 1.0]}, "glass specular_transmittance green"),
    ({"tint": 1}, "unknown key(s) 'tint'"),
])
def test_a_bad_glass_entry_is_refused_in_one_line(tmp_path, solution, change, fragment):
    meta, arrays = contents(solution)
    name = next(iter(meta["materials"]))
    meta["materials"][name] = {"diffuse": BLACK, "specular": BLACK, "exponent": 0.0, "emission": BLACK,
                               "glass": dict(GLASS, **change)}
    meta["version"] = 7
    refused(write_npz(tmp_path / "s.npz", meta, arrays), fragment)


def test_a_plastic_microfacet_needs_one_index_other_than_1():
    plastic = dict(MICROFACET, kind="roughplastic", eta=[1.5, 1.5, 1.4], k=[0, 0, 0])
    with pytest.raises(InputError, match="one positive index other than 1"):
        Material("p", (0.3,) * 3, (1.0,) * 3, 50.0, fresnel=(0.04,) * 3, microfacet=plastic)


def test_a_camera_along_x_keeps_its_axis_and_its_film_s_vertical_fov(tmp_path, solution):
    # a Mitsuba sensor's fov 70 along x on a 1280 x 720 film
    camera = Camera((6.9, 1.65, 2.55), (6.0, 1.65, 2.12), (0.0, 1.0, 0.0), 70.0, 1280, 720, "x")
    path = tmp_path / "camera.npz"
    dataclasses.replace(solution, camera=camera).save(path)
    with np.load(path, allow_pickle=False) as npz:
        meta = json.loads(str(npz["meta"]))
    assert meta["version"] == 2  # optional keys: no new version (a version 2 reader reads the file)
    assert meta["camera"]["fov_y_deg"] == pytest.approx(42.99566, abs=1e-5)  # what an older reader draws the film with
    assert (meta["camera"]["fov_deg"], meta["camera"]["fov_axis"], meta["camera"]["film"]) == (70.0, "x", [1280, 720])
    back = load_solution(path).camera
    assert back == camera and back.sized(1024, 1024).fov_y_deg == pytest.approx(70.0, rel=1e-12)
    for key in ("fov_deg", "fov_axis", "film"):  # a file without them reads as before: that vertical fov
        del meta["camera"][key]
    _, arrays = contents(solution)
    old = load_solution(write_npz(tmp_path / "old.npz", meta, arrays)).camera
    assert old.fov_axis == "y" and old.fov_deg == meta["camera"]["fov_y_deg"]
    meta["camera"] |= {"fov_deg": 70.0, "fov_axis": "x", "film": [1280, 721]}
    refused(write_npz(tmp_path / "bad.npz", meta, arrays), "meta 'camera'", "is not the vertical field of view")


def test_names_with_a_slash_are_refused(tmp_path):
    with pytest.raises(ValueError, match="'/'"):
        Solution((make_object("box/top", 0, WHITE, 1),)).save(tmp_path / "s.npz")
    assert not list(tmp_path.iterdir())


def test_duplicate_names_are_refused():
    with pytest.raises(ValueError, match="duplicate"):
        Solution((make_object("a", 0, WHITE, 1), make_object("a", 0, WHITE, 2)))


@pytest.mark.parametrize(
    "change, match",
    [
        ({"radiance": np.zeros((9, 2, 3))}, "radiance"),
        ({"faces": np.array([[0, 1, 9]])}, "faces"),
        ({"faces": np.zeros((1, 3), dtype=np.float32)}, "integers"),
        # indices that an int32 cast would wrap back into range, and an object with no faces
        ({"faces": np.array([[0, 1, 2]], np.int64) + 2**40}, r"from 1099511627776 to 1099511627778, outside \[0, 9\)"),
        ({"faces": np.array([[0, 1, 2]], np.uint64) + np.uint64(2**63)}, "outside"),
        ({"faces": np.zeros((0, 3), np.int64)}, "'x/faces' is empty: object 'x' has no faces"),
        ({"directions": DIFFUSE_DIRECTIONS * 2.0}, "unit"),
        ({"directions": grid_directions(2)[::-1].copy(), "radiance": np.zeros((9, 4, 3))}, "grid"),
        ({"radiance": np.full((9, 1, 3), np.inf)}, "infinite"),
        ({"radiance": np.full((9, 1, 3), -1e-3)}, "27 negative values"),
        ({"material": {"diffuse": [0.7, 0.7, 0.7]}}, "material"),
    ],
)
def test_constructor_refuses_data_that_breaks_the_contract(change, match):
    o = make_object("x", 0, WHITE, 1)
    kwargs = {k: getattr(o, k) for k in ("name", "material", *ARRAY_KEYS)}
    with pytest.raises(ValueError, match=match):
        ObjectSolution(**{**kwargs, **change})


def test_save_replaces_an_existing_file_and_keeps_open_permissions(tmp_path, solution):
    path = tmp_path / "solution.npz"
    path.write_bytes(b"old")
    solution.save(path)
    assert load_solution(path).names == solution.names
    assert os.listdir(tmp_path) == ["solution.npz"]
    reference = tmp_path / "plain"
    reference.write_bytes(b"")
    assert (path.stat().st_mode & 0o777) == (reference.stat().st_mode & 0o777)


# ---------------------------------------------------------------------------
# Atomicity
# ---------------------------------------------------------------------------


def interrupted_savez(file, *args, **kwargs):
    """Stands in for numpy.savez_compressed: writes part of the data, then Ctrl-C."""
    file.write(b"PK\x03\x04 half a zip archive")
    file.flush()
    raise KeyboardInterrupt


def test_interrupted_save_leaves_no_file(tmp_path, solution, monkeypatch):
    monkeypatch.setattr(np, "savez_compressed", interrupted_savez)
    with pytest.raises(KeyboardInterrupt):
        solution.save(tmp_path / "solution.npz")
    assert os.listdir(tmp_path) == []


def test_interrupted_save_keeps_the_older_file(tmp_path, solution, monkeypatch):
    path = tmp_path / "solution.npz"
    solution.save(path)
    old = path.read_bytes()
    monkeypatch.setattr(np, "savez_compressed", interrupted_savez)
    with pytest.raises(KeyboardInterrupt):
        make_solution().save(path)
    assert os.listdir(tmp_path) == ["solution.npz"]
    assert path.read_bytes() == old


def test_unserialisable_stats_fail_before_any_file_is_made(tmp_path):
    s = Solution((make_object("a", 0, WHITE, 1),), stats={"bad": object()})
    with pytest.raises(TypeError):
        s.save(tmp_path / "s.npz")
    assert os.listdir(tmp_path) == []


def test_atomic_output_commits_on_success_and_cleans_up_on_error(tmp_path):
    path = tmp_path / "out.bin"
    with atomic_output(path) as f:
        f.write(b"new")
        assert not path.exists()  # nothing visible until the block ends
    assert path.read_bytes() == b"new"
    with pytest.raises(RuntimeError):
        with atomic_output(path) as f:
            f.write(b"newer, but broken")
            raise RuntimeError("boom")
    assert path.read_bytes() == b"new"
    assert os.listdir(tmp_path) == ["out.bin"]
    (tmp_path / "dir").mkdir()
    with pytest.raises(OSError):  # the rename onto a directory fails
        with atomic_output(tmp_path / "dir") as f:
            f.write(b"x")
    assert sorted(os.listdir(tmp_path)) == ["dir", "out.bin"]


# ---------------------------------------------------------------------------
# Bad files: InputError with a one-line message
# ---------------------------------------------------------------------------


def contents(solution: Solution) -> tuple[dict, dict]:
    """(meta dict, arrays dict) of a good file, to damage before writing it."""
    arrays = {}
    for o in solution.objects:
        arrays.update(o.arrays())
    return json.loads(json.dumps(solution.meta(), default=lambda v: v.item())), arrays


def write_npz(path, meta, arrays) -> str:
    np.savez_compressed(path, meta=np.array(json.dumps(meta)), **arrays)
    return str(path)


def refused(path, *fragments: str) -> str:
    return input_error(lambda: load_solution(path), *fragments)


def test_good_file_written_by_plain_numpy_is_accepted(tmp_path, solution):
    meta, arrays = contents(solution)
    loaded = load_solution(write_npz(tmp_path / "s.npz", meta, arrays))
    assert loaded.names == solution.names


def test_missing_file(tmp_path):
    path = tmp_path / "nothing.npz"
    assert refused(path) == f"solution file '{path}' not found"


def test_not_a_zip(tmp_path):
    path = tmp_path / "s.npz"
    path.write_text("this is not\na zip archive\n")
    refused(path, "is not a solution file", "not a zip archive")
    path.write_bytes(b"")
    refused(path, "is not a solution file", "empty")


def test_truncated_file(tmp_path, saved):
    data = open(saved, "rb").read()
    path = tmp_path / "cut.npz"
    path.write_bytes(data[: len(data) // 2])
    refused(path, "is not a solution file")


def test_corrupted_member(tmp_path, saved):
    data = bytearray(open(saved, "rb").read())
    with zipfile.ZipFile(saved) as z:
        info = z.getinfo(f"{GLOSSY_NAME}/radiance.npy")
    start = info.header_offset + 30 + len(info.filename) + len(info.extra)  # member data
    for k in range(10, min(200, info.compress_size)):
        data[start + k] ^= 0x55
    path = tmp_path / "corrupt.npz"
    path.write_bytes(bytes(data))
    refused(path, "is not a solution file", f"'{GLOSSY_NAME}/radiance'")


def test_directory_and_npy_are_refused(tmp_path):
    refused(tmp_path, "solution file", "is a directory")
    np.save(tmp_path / "a.npy", np.zeros(3))
    refused(tmp_path / "a.npy", "is not a solution file", ".npy")


def test_zip_without_meta(tmp_path, solution):
    _, arrays = contents(solution)
    np.savez_compressed(tmp_path / "s.npz", **arrays)
    refused(tmp_path / "s.npz", "is not a solution file", "'meta'")


def test_meta_not_json(tmp_path, solution):
    _, arrays = contents(solution)
    np.savez_compressed(tmp_path / "s.npz", meta=np.array("{not json"), **arrays)
    refused(tmp_path / "s.npz", "'meta' is not JSON")


def test_wrong_format_string(tmp_path, solution):
    meta, arrays = contents(solution)
    meta["format"] = "vlights.fit"
    refused(write_npz(tmp_path / "s.npz", meta, arrays), "is not a solution file", "'vlights.fit'")


@pytest.mark.parametrize("version", [10, "1", None, True])
def test_wrong_version(tmp_path, solution, version):
    meta, arrays = contents(solution)
    meta["version"] = version
    refused(write_npz(tmp_path / "s.npz", meta, arrays), f"version {version!r}")


@pytest.mark.parametrize("key", ARRAY_KEYS)
def test_missing_key(tmp_path, solution, key):
    meta, arrays = contents(solution)
    del arrays[f"{GLOSSY_NAME}/{key}"]
    path = write_npz(tmp_path / "s.npz", meta, arrays)
    refused(path, f"'{GLOSSY_NAME}'", f"'{GLOSSY_NAME}/{key}'")


def test_missing_material(tmp_path, solution):
    meta, arrays = contents(solution)
    del meta["materials"][DIFFUSE_NAME]
    refused(write_npz(tmp_path / "s.npz", meta, arrays), f"'{DIFFUSE_NAME}'", "materials")


@pytest.mark.parametrize(
    "key, value",
    [
        ("radiance", np.zeros((9, 15, 3), np.float32)),  # D does not match directions
        ("radiance", np.zeros((8, 16, 3), np.float32)),  # V does not match positions
        ("normals", np.zeros((9, 2), np.float32)),
        ("faces", np.zeros((4, 4), np.int32)),
        ("directions", np.zeros((16,), np.float32)),
    ],
)
def test_shape_mismatch(tmp_path, solution, key, value):
    meta, arrays = contents(solution)
    arrays[f"{GLOSSY_NAME}/{key}"] = value
    path = write_npz(tmp_path / "s.npz", meta, arrays)
    message = refused(path, f"'{GLOSSY_NAME}/{key}'", "shape")
    assert str(value.shape).replace(",)", ")") in message


def test_nan_radiance(tmp_path, solution):
    meta, arrays = contents(solution)
    arrays[f"{GLOSSY_NAME}/radiance"] = arrays[f"{GLOSSY_NAME}/radiance"].copy()
    arrays[f"{GLOSSY_NAME}/radiance"][3, 5, 1] = np.nan
    refused(write_npz(tmp_path / "s.npz", meta, arrays), f"'{GLOSSY_NAME}/radiance'", "NaN")


def test_negative_radiance(tmp_path, solution):
    meta, arrays = contents(solution)
    arrays[f"{GLOSSY_NAME}/radiance"][3, 5, 1] = -0.25
    arrays[f"{GLOSSY_NAME}/radiance"][4, 0, 0] = -2.0
    refused(write_npz(tmp_path / "s.npz", meta, arrays), f"'{GLOSSY_NAME}/radiance'", "2 negative values", "-2")
    arrays[f"{GLOSSY_NAME}/radiance"][4, 0, 0] = -0.0  # a negative zero is zero
    arrays[f"{GLOSSY_NAME}/radiance"][3, 5, 1] = 0.0
    assert load_solution(write_npz(tmp_path / "z.npz", meta, arrays)).object(GLOSSY_NAME).radiance[4, 0, 0] == 0


@pytest.mark.parametrize(
    "key, damage, fragment",
    [
        ("directions", lambda d: d * 1.01, "unit"),
        ("directions", lambda d: d[[1, 0, *range(2, 16)]], "grid"),
        ("faces", lambda f: f + 5, "outside"),
        ("positions", lambda p: np.where(p == 0, np.inf, p).astype(np.float32), "infinite"),
        ("radiance", lambda r: r.astype(object), "cannot read"),
    ],
)
def test_other_contract_violations(tmp_path, solution, key, damage, fragment):
    meta, arrays = contents(solution)
    arrays[f"{GLOSSY_NAME}/{key}"] = damage(arrays[f"{GLOSSY_NAME}/{key}"])
    refused(write_npz(tmp_path / "s.npz", meta, arrays), fragment)


def test_float64_file_is_read_as_the_contract_dtypes(tmp_path, solution):
    meta, arrays = contents(solution)
    wide = {np.dtype(np.float32): np.float64, np.dtype(np.int32): np.int64}
    arrays = {k: v.astype(wide[v.dtype]) for k, v in arrays.items()}
    loaded = load_solution(write_npz(tmp_path / "s.npz", meta, arrays))
    for o in loaded.objects:
        for key, dtype in DTYPES.items():
            assert getattr(o, key).dtype == dtype


# ---------------------------------------------------------------------------
# Version 4: delta lights
# ---------------------------------------------------------------------------


def with_delta_lights(solution: Solution) -> Solution:
    """``solution`` lit by a spot and a sun, the spot drawn in closed form (a part)."""
    import dataclasses

    from radiosity.physics.emitters import EmitterPart, SpotProfile

    spot = EmitterPart("point", [[0.5, 2.0, 0.5]], 0.0, [9.0, 8.0, 7.0], "torch", SpotProfile([0, -1, 0], 30, 20))
    sun = EmitterPart("direction", [[0.3, -1.0, 0.2]], 0.0, [2.0, 2.0, 1.5], "sun")
    objects = tuple(o if o.is_diffuse else dataclasses.replace(o, visibility=np.ones((o.num_vertices, 1), np.float32))
                    for o in solution.objects)
    return dataclasses.replace(solution, objects=objects, emitters=(spot,), lights=(spot, sun))


def test_a_solution_with_delta_lights_is_version_4_and_reads_back(tmp_path, solution):
    lit = with_delta_lights(solution)
    assert lit.version == 4 and solution.version == 2  # written with the lowest version that holds it
    lit.save(tmp_path / "s.npz")
    back = load_solution(tmp_path / "s.npz")
    meta = json.loads(str(np.load(tmp_path / "s.npz")["meta"]))
    assert meta["version"] == 4 and meta["emitters"][0]["kind"] == "point" and meta["emitters"][0]["spot"]["cutoff_deg"] == 30
    assert [p.to_dict() for p in back.lights] == [p.to_dict() for p in lit.lights] == meta["lights"]
    assert [p.to_dict() for p in back.emitters] == [lit.lights[0].to_dict()]
    # its highlights on the grid are the closed form's, as any part's
    assert np.array_equal(back.highlights(GLOSSY_NAME), lit.highlights(GLOSSY_NAME))
    solution.save(tmp_path / "plain.npz")
    assert "lights" not in json.loads(str(np.load(tmp_path / "plain.npz")["meta"]))


@pytest.mark.parametrize("version", [2, 3])
def test_an_older_file_holding_a_delta_part_is_refused(tmp_path, solution, version):
    meta, arrays = contents(with_delta_lights(solution))
    meta["version"] = version
    refused(write_npz(tmp_path / "s.npz", meta, arrays), "meta 'emitters' entry 0", "kind 'point' is not one of sphere, polygon")


def test_a_bad_light_is_refused(tmp_path, solution):
    meta, arrays = contents(with_delta_lights(solution))
    meta["lights"][1]["direction"] = [0, 0, 0]
    refused(write_npz(tmp_path / "s.npz", meta, arrays), "meta 'lights' entry 1", "must not be zero")
    meta["lights"] = [meta["lights"][0] | {"kind": "sphere", "centre": [0, 0, 0], "radius": 1.0}]
    refused(write_npz(tmp_path / "t.npz", meta, arrays), "meta 'lights' entry 0: kind 'sphere' is not one of point, direction")


# ---------------------------------------------------------------------------
# Textures that objects share are one array in memory
# ---------------------------------------------------------------------------


def textured_solution(textures):
    """A solution of one diffuse quad grid per texture of ``textures``, each textured."""
    from radiosity.physics.textures import TexturedDiffuse

    objects = []
    for k, texture in enumerate(textures):
        o = make_object(f"wall{k}", 0, WHITE, 10 + k)
        t = TexturedDiffuse(uvs=o.positions[:, :2] / 2, irradiance=np.ones((9, 3)), texture=texture, kd=(0.7, 0.7, 0.7))
        objects.append(dataclasses.replace(o, textured=t))
    return Solution(objects=tuple(objects), settings={"quality": "draft"}, stats={"photons": 1}, scene="walls")


def test_objects_sharing_a_texture_read_it_as_one_array_and_others_apart(tmp_path):
    """A scene's walls that share an image store it once each; read, they hold one
    array (not a copy each: a staircase's textures were 4.9 GB so), equal to what was
    written, read-only; a different image of the same size stays its own."""
    rng = np.random.default_rng(4)
    tiles, wood = rng.random((8, 6, 3)).astype(np.float32), rng.random((8, 6, 3)).astype(np.float32)
    path = tmp_path / "solution.npz"
    textured_solution([tiles, tiles.copy(), wood, tiles]).save(path)
    got = [o.textured.texture for o in load_solution(path).objects]
    assert got[0] is got[1] is got[3] and got[2] is not got[0]
    assert np.array_equal(got[0], tiles) and np.array_equal(got[2], wood)
    assert not got[0].flags.writeable


def test_two_textures_whose_stamps_agree_are_still_compared_whole(tmp_path, monkeypatch):
    """Sharing is decided by the content: members whose CRC-32 and size agree (forced
    here) but whose arrays differ are read apart."""
    from radiosity.files import npz

    rng = np.random.default_rng(5)
    a, b = rng.random((4, 4, 3)).astype(np.float32), rng.random((4, 4, 3)).astype(np.float32)
    path = tmp_path / "solution.npz"
    textured_solution([a, b]).save(path)
    monkeypatch.setattr(npz.Archive, "stored_as", lambda self, key: (0, 0))
    got = [o.textured.texture for o in load_solution(path).objects]
    assert got[0] is not got[1] and np.array_equal(got[0], a) and np.array_equal(got[1], b)


@pytest.mark.parametrize("key, value, length", [("normals", 0.0, "0"), ("tangents", 0.5, "0.866025"),
                                                ("normals", 2.0, "3.4641")])
def test_normals_and_tangents_must_be_unit_vectors(tmp_path, solution, key, value, length):
    """A zero normal (a held-out input that ended in numba's SystemError when drawn) and
    any other length are refused in one line naming the vertex."""
    meta, arrays = contents(solution)
    broken = arrays[f"{GLOSSY_NAME}/{key}"].copy()
    broken[1] = value
    arrays[f"{GLOSSY_NAME}/{key}"] = broken
    refused(write_npz(tmp_path / "s.npz", meta, arrays), f"'{GLOSSY_NAME}/{key}' has a vector of length {length}",
            "at vertex 1", "must be unit vectors")


def test_an_object_s_material_is_read_as_the_validated_record(solution):
    """Every stage reads a solution object's material through its record (``Material``),
    the file's dict kept as it is; the record is made once."""
    from radiosity.physics.materials import Material

    for o in solution.objects:
        record = o.material_record
        assert isinstance(record, Material) and record is o.material_record
        assert record.to_dict() == o.material
        assert record.exponent == o.material["exponent"] and list(record.specular) == list(o.material["specular"])
