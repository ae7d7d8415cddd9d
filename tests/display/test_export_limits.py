"""What ``vlights export`` needs, said before it starts (display/export_limits.py): the
sizes come from the fit's headers alone; the memory estimate bounds the export's
measured peak within a stated factor; a large estimate is said on stderr in one line, a
small one not at all; an export that cannot fit is refused in one line, exit 2, nothing
written; the page's textures larger than 4096 texels are warned of in one line.
"""

import dataclasses
import math
import subprocess
import sys

import numpy as np
import pytest
from display_fixtures import assert_refused, listing, lit_model
from test_export import glossy_model
from test_export_textures import textured_model

import display.export_limits as limits
from display.export import FILE
from display.export_limits import FitSizes, ObjectSizes, check_export_memory, check_page_textures, fit_sizes
from display.glsl import FLOAT_TEXTURE_WIDTH
from display.store import SAY_BYTES
from fitting.model import FittedModel, FittedObject
from radiosity.physics.environment import EnvironmentLight

GIB = 2**30


def full_model(rng):
    """Every kind of array a fit holds: per-light coefficients, highlights and probes
    (``glossy_model``), a textured object and an environment."""
    glossy = glossy_model(True, rng)
    textured = textured_model(False, rng).objects[0]
    textured = dataclasses.replace(textured, name="textured")
    env = EnvironmentLight.from_image(rng.uniform(0, 2, (5, 8, 3)).astype(np.float32), 1.0, np.eye(3), source="t")
    return dataclasses.replace(glossy, objects=(*glossy.objects, textured), environment=env)


def test_sizes_are_the_arrays_and_come_from_the_headers_alone(tmp_path, rng, monkeypatch):
    """Every object's V, K, per-light, P, probe M and each array's value count, as the
    arrays have them; no array but the meta is read to find them."""
    model = full_model(rng)
    model.save(tmp_path / "fit.npz")
    read = []
    original = np.lib.npyio.NpzFile.__getitem__

    def getitem(self, key):
        read.append(key)
        return original(self, key)

    monkeypatch.setattr(np.lib.npyio.NpzFile, "__getitem__", getitem)
    sizes = fit_sizes(tmp_path / "fit.npz")
    assert read == ["meta"]
    monkeypatch.undo()
    assert [o.name for o in sizes.objects] == list(model.names)
    with np.load(tmp_path / "fit.npz") as npz:
        for obj, got in zip(model.objects, sizes.objects, strict=True):
            assert got.vertices == len(obj.positions) and got.lights == obj.n_lights
            assert got.per_light == obj.per_light
            assert got.parts == (obj.highlight.visibility.shape[1] if obj.highlight is not None else 0)
            assert got.probe == (obj.probe.size if obj.probe is not None else 0)
            members = {k.split("/", 1)[1]: npz[k].size for k in npz.files if k.startswith(f"{obj.name}/")}
            assert got.values == members and len(members) >= 8
        assert sizes.environment == npz["environment_image"].shape[:2] == (5, 8)
    assert sizes.objects[1].per_light and sizes.objects[1].parts == 4
    assert sizes.objects[2].values["texture"] == 6 * 8 * 3


def test_a_file_that_is_not_a_fit_is_refused(tiny_pair):
    _, solution = tiny_pair
    with pytest.raises(limits.InputError, match="is not a fit file .*: it is a solution file"):
        fit_sizes(solution)


def sizes_of(*objects, environment=None):
    return FitSizes(tuple(objects), environment)


def an_object(name, v, f, k=0, per_light=False, parts=0, probe=0, texture=0):
    """An ``ObjectSizes`` of V vertices, F faces, K lights (a diffuse object stores a zero (V, 3) specular)."""
    values = {"positions": 3 * v, "normals": 3 * v, "faces": 3 * f, "emitted": 3 * v,
              "specular": 3 * v * k if per_light else 3 * v, "light_pos": 4 * k, "light_rgb": 3 * k, "shininess": k}
    if parts:
        values["visibility"] = v * parts
    if probe:
        values.update(probe=3 * probe * probe, probe_weight=3 * v)
    if texture:
        values.update(texture=3 * texture, uvs=2 * v, irradiance=3 * v)
    return ObjectSizes(name, v, k, per_light, parts, probe, values)


def test_the_estimate_counts_each_kind_of_value_at_its_own_cost():
    """Known answers: a diffuse object's zero specular is loaded, not exported; a lit
    object's is exported; visibility is exported three parts to an attribute (4 parts:
    6 values a vertex); probes, textures and the environment at their own costs."""
    L = limits
    estimate = L.export_estimate
    v, f = 1000, 1900
    base = L.PROCESS_BYTES + L.OBJECT_BYTES
    mesh = L.MESH_BYTES * (6 * v + 3 * f)
    assert estimate(sizes_of(an_object("d", v, f))) == base + mesh + L.ATTRIBUTE_BYTES * 3 * v + L.REST_BYTES * 3 * v
    lit = an_object("l", v, f, k=5, per_light=True)
    assert estimate(sizes_of(lit)) == base + mesh + L.ATTRIBUTE_BYTES * (3 * v + 15 * v) + L.REST_BYTES * 40
    glossy = an_object("g", v, f, k=2, parts=4, probe=16, texture=64 * 64)
    attributes = 3 * v + 3 * v + 3 * v + 6 * v + 2 * v + 3 * v  # emitted, specular, probe weight, visibility, uvs, E
    assert estimate(sizes_of(glossy)) == (base + mesh + L.ATTRIBUTE_BYTES * attributes + L.PROBE_BYTES * 3 * 16 * 16
                                          + L.TEXTURE_BYTES * 3 * 64 * 64 + L.REST_BYTES * (8 + 6 + 2))
    both = estimate(sizes_of(lit, glossy, environment=(32, 64)))
    assert both == estimate(sizes_of(lit)) + estimate(sizes_of(glossy)) - L.PROCESS_BYTES \
        + L.ENVIRONMENT_BYTES * 3 * 32 * 64


def test_an_image_that_objects_share_is_counted_once(tmp_path, rng):
    """Objects whose textures are stored alike (one image: staircase's 600 objects of one
    wood) cost the image once; a different image costs its own. From a file: the sizes
    name each object's stored image, equal for the copies of one image."""
    L = limits
    v, f = 100, 150
    one = [an_object(f"o{i}", v, f, texture=64 * 64)._replace(image=(7, 1000)) for i in range(3)]
    other = an_object("x", v, f, texture=32 * 32)._replace(image=(8, 500))
    alone = L.export_estimate(sizes_of(one[0]))
    together = L.export_estimate(sizes_of(*one))
    assert together == 3 * alone - 2 * L.PROCESS_BYTES - 2 * L.TEXTURE_BYTES * 3 * 64 * 64
    assert L.export_estimate(sizes_of(*one, other)) == together + L.export_estimate(sizes_of(other)) - L.PROCESS_BYTES

    model = textured_model(False, rng)
    wall = model.objects[0]
    copy = dataclasses.replace(wall, name="copy", textured=dataclasses.replace(wall.textured))
    dataclasses.replace(model, objects=(*model.objects, copy)).save(tmp_path / "fit.npz")
    sizes = {o.name: o for o in fit_sizes(tmp_path / "fit.npz").objects}
    assert sizes["wall"].image == sizes["copy"].image != sizes["tile"].image
    assert None not in (sizes["wall"].image, sizes["tile"].image)


# ---------------------------------------------------------------------- against the measure

MEASURE = """
import resource, subprocess, sys
code = subprocess.run(sys.argv[1:], capture_output=True).returncode
print(code, resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss * 1024)
"""


def measured_peak(fit, out):
    """(exit status, peak resident bytes) of ``vlights export FIT -o OUT`` in a child of
    a fresh process (so the peak is the export's alone)."""
    result = subprocess.run([sys.executable, "-c", MEASURE, sys.executable, "-m", "display", "export", str(fit), "-o",
                             str(out)], capture_output=True, text=True, check=True)
    code, peak = map(int, result.stdout.split())
    return code, peak


def grid_object(name, n, lights, rng):
    """An n x n grid of vertices, random normals and values, ``lights`` lights with
    per-light coefficients (random: trimesh stores equal buffers once, which would
    hide their cost)."""
    u = np.linspace(0, 1, n, dtype=np.float32)
    x, y = np.meshgrid(u, u)
    positions = np.stack([x.ravel(), y.ravel(), np.zeros(n * n, np.float32)], 1)
    i = np.arange(n * n).reshape(n, n)
    a, b, c, d = i[:-1, :-1].ravel(), i[:-1, 1:].ravel(), i[1:, :-1].ravel(), i[1:, 1:].ravel()
    faces = np.concatenate([np.stack([a, b, d], 1), np.stack([a, d, c], 1)]).astype(np.int32)
    normals = rng.normal(size=positions.shape).astype(np.float32)
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    light_pos = np.zeros((lights, 4), np.float32)
    light_pos[:, 2] = 1
    return FittedObject(name=name, positions=positions, normals=normals, faces=faces,
                        emitted=rng.uniform(0, 1, (n * n, 3)).astype(np.float32),
                        specular=rng.uniform(0, 1, (n * n, lights, 3)).astype(np.float32), light_pos=light_pos,
                        light_rgb=np.ones((lights, 3), np.float32), shininess=np.full(lights, 10, np.float32))


FACTOR = 1.5  # the estimate is at least the measured peak, and at most this many times it


@pytest.mark.subprocess
def test_the_estimate_bounds_the_measured_peak(tmp_path, rng):
    """The export of 90,000 vertices with 16 per-light coefficients each (115 MB more than
    the process's own) and of the tiny scene, each measured (peak resident memory):
    each estimate is at least the peak and at most FACTOR times it, and so is the
    estimate of what the large one adds to the tiny one (the bytes a value, apart from
    the process's)."""
    lit_model(True, rng).save(tmp_path / "tiny.npz")
    FittedModel(objects=(grid_object("grid", 300, 16, rng),), source="test", model="mixed").save(tmp_path / "big.npz")
    peaks, estimates = [], []
    for name in ("tiny", "big"):
        code, peak = measured_peak(tmp_path / f"{name}.npz", tmp_path / name)
        assert code == 0 and (tmp_path / name / FILE).exists()
        peaks.append(peak)
        estimates.append(limits.export_estimate(fit_sizes(tmp_path / f"{name}.npz")))
    for peak, estimate in zip(peaks, estimates, strict=True):
        assert peak <= estimate <= FACTOR * peak, (peak, estimate)
    more, estimated_more = peaks[1] - peaks[0], estimates[1] - estimates[0]
    assert more > 60e6  # not vacuous: the values, not the process, make the difference
    assert more <= estimated_more <= FACTOR * more, (more, estimated_more)


# ---------------------------------------------------------------------------- said, refused

def test_a_large_estimate_is_said_a_small_one_is_not():
    """Said at render's threshold (display.store.SAY_BYTES, a gigabyte) and above, as
    'export: about X GB at most of Y GB available'; below it nothing."""
    lines = []
    per_vertex = 6 * limits.MESH_BYTES + 3 * limits.ATTRIBUTE_BYTES + 3 * limits.REST_BYTES  # a diffuse object's
    v = math.ceil((SAY_BYTES - limits.PROCESS_BYTES - limits.OBJECT_BYTES) / per_vertex)
    large, small = sizes_of(an_object("o", v, 0)), sizes_of(an_object("o", v - 1, 0))
    assert limits.export_estimate(small) < SAY_BYTES <= limits.export_estimate(large)
    assert check_export_memory(small, available=64 * GIB, say=lines.append) == limits.export_estimate(small)
    assert lines == []
    need = check_export_memory(large, available=64 * GIB, say=lines.append)
    assert lines == [f"export: about {need / GIB:.2f} GB at most of 64.0 GB available"]


def test_what_cannot_fit_is_refused():
    sizes = sizes_of(an_object("wall", 10, 10), an_object("teapot", 1_000_000, 2_000_000, k=8, per_light=True))
    need = limits.export_estimate(sizes)
    assert check_export_memory(sizes, available=need, say=lambda _: None) == need
    with pytest.raises(limits.InputError) as refused:
        check_export_memory(sizes, available=need - 1, say=lambda _: None)
    message = str(refused.value)
    assert "\n" not in message and message.startswith(
        f"export needs about {need / GIB:.1f} GB of memory but {(need - 1) / GIB:.1f} GB is available (2 objects; "
        "largest object 'teapot': 1,000,000 vertices x 8 lights)")


def test_the_export_command_refuses_what_cannot_fit_and_writes_nothing(tmp_path, cli, rng, monkeypatch):
    """With less memory free than the estimate: exit 2, one line, no directory left, and
    the fit not even loaded."""
    lit_model(True, rng).save(tmp_path / "fit.npz")
    need = limits.export_estimate(fit_sizes(tmp_path / "fit.npz"))
    monkeypatch.setattr(limits, "available_memory", lambda: need - 1)
    import fitting

    monkeypatch.setattr(fitting, "load_fit", lambda path: pytest.fail("the fit was loaded before the refusal"))
    before = listing(tmp_path)
    assert_refused(cli("export", tmp_path / "fit.npz", "-o", tmp_path / "web"), "export needs about", "GB is available",
                   "largest object", command="export")
    assert listing(tmp_path) == before
    monkeypatch.undo()
    monkeypatch.setattr(limits, "available_memory", lambda: need)  # just enough: written, and nothing said
    code, out, err = cli("export", tmp_path / "fit.npz", "-o", tmp_path / "web")
    assert code == 0 and err == "" and (tmp_path / "web" / FILE).exists()


def test_the_export_command_says_a_large_estimate(tmp_path, cli, rng, monkeypatch):
    lit_model(False, rng).save(tmp_path / "fit.npz")
    monkeypatch.setattr(limits, "SAY_BYTES", 1)
    code, out, err = cli("export", tmp_path / "fit.npz", "-o", tmp_path / "web")
    need = limits.export_estimate(fit_sizes(tmp_path / "fit.npz"))
    assert code == 0 and err.startswith(f"export: about {need / GIB:.2f} GB at most") and err.count("\n") == 1


# ---------------------------------------------------------------------------- page textures

def test_the_page_textures_of_an_object():
    """Known sizes: 2 x K lights, TEXTURE_WIDTH wide coefficient and visibility textures
    of a row per TEXTURE_WIDTH values, M x M probe."""
    w = FLOAT_TEXTURE_WIDTH
    textures = limits.object_textures(an_object("o", 1_000_000, 0, k=20, per_light=True, parts=5, probe=64))
    got = [(t.width, t.height) for t in textures]
    assert got == [(2, 20), (w, math.ceil(20_000_000 / w)), (w, math.ceil(5_000_000 / w)), (64, 64)] == \
        [(2, 20), (4096, 4883), (4096, 1221), (64, 64)]
    assert [(t.width, t.height) for t in limits.object_textures(an_object("d", 10, 0))] == [(2, 1)]
    shared = limits.object_textures(an_object("s", 10**7, 0, k=3))  # shared coefficients are a vertex attribute
    assert [(t.width, t.height) for t in shared] == [(2, 3)]


def test_textures_over_4096_are_warned_of_in_one_line():
    exact = an_object("exact", 4096 * 4096 // 8, 0, k=8, per_light=True)  # 4096 x 4096: what a page may assume
    big = an_object("big", 1_000_000, 0, k=20, per_light=True)
    lines = []
    assert check_page_textures(sizes_of(exact, an_object("d", 10, 0)), say=lines.append) == [] and lines == []
    large = check_page_textures(sizes_of(exact, big, environment=(4096, 8192)), say=lines.append)
    assert [(t.name, t.width, t.height) for t in large] == [(None, 8192, 4096), ("big", 4096, 4883)]
    assert len(lines) == 1 and "\n" not in lines[0]
    assert lines[0].startswith("export: warning: the scene needs a 8192 x 4096 texture on the page for the "
                               "environment's image")
    assert "(1 more texture over 4096)" in lines[0] and "MAX_TEXTURE_SIZE is at least 8192" in lines[0]
    lines.clear()
    check_page_textures(sizes_of(big), say=lines.append)
    assert lines[0].startswith("export: warning: object 'big' needs a 4096 x 4883 texture on the page for its "
                               "per-light coefficients (1,000,000 vertices x 20 lights)")
    assert limits.PAGE_TEXTURE_SIZE == 4096 and limits.page_textures(sizes_of(big), limit=4883) == []


def test_the_export_command_warns_of_a_large_texture_with_the_page(tmp_path, cli, rng):
    """An environment 4097 texels wide (a tiny file: 3 rows): one warning line with the
    page and the files written; without the page, nothing said."""
    env = EnvironmentLight.from_image(rng.uniform(0, 2, (3, 4097, 3)).astype(np.float32), 1.0, np.eye(3), source="t")
    dataclasses.replace(lit_model(False, rng), environment=env).save(tmp_path / "fit.npz")
    code, out, err = cli("export", tmp_path / "fit.npz", "-o", tmp_path / "web")
    assert code == 0 and (tmp_path / "web" / FILE).exists() and "index.html" in out
    assert err.count("\n") == 1 and err.startswith("export: warning: the scene needs a 4097 x 3 texture on the page")
    code, out, err = cli("export", tmp_path / "fit.npz", "-o", tmp_path / "glb", "--no-page")
    assert code == 0 and err == ""
