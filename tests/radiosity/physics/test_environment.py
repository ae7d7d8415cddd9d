"""The environment light (``radiosity.physics.environment``): Mitsuba 3's latitude-longitude
convention (values Mitsuba 3.9.1 returned, and Mitsuba itself where it is installed),
the numba lookup and sampler against their numpy references, the sampler's
chi-square test against its pdf, the pdf and the radiance integral, storage, and the
loaders (TOML [environment], Mitsuba constant and envmap) with their errors.
"""

import json
import textwrap

import numba
import numpy as np
import pytest
from mitsuba_oracle import run_mitsuba
from scipy import stats
from scipy.spatial.transform import Rotation

from radiosity.files.errors import InputError
from radiosity.physics import environment as envmod
from radiosity.physics.environment import Environment, env_lookup, env_pdf, env_sample
from radiosity.scene.loaders import load_scene


def ramp_image(h=5, w=8):
    """Pixel (row j, column i) = (i + 1, j + 1, 1): where each value sits shows at once."""
    image = np.ones((h, w, 3), np.float32)
    image[..., 0] = np.arange(1, w + 1)[None, :]
    image[..., 1] = np.arange(1, h + 1)[:, None]
    return image


def uv_dir(u, v):
    return envmod.uv_to_direction(np.atleast_1d(u), np.atleast_1d(v))


def sunny_image(seed=3, h=32, w=64):
    """A smooth sky with a small sun two pixels wide, 2000 times brighter."""
    rng = np.random.default_rng(seed)
    image = (0.2 + rng.random((h, w, 3))).astype(np.float32)
    image[10:12, 40:42] = 2000.0
    return image


def rotation_xyz(ax, ay, az):
    """Rotation about x by ax, then y by ay, then z by az (radians)."""
    return Rotation.from_euler("xyz", [ax, ay, az]).as_matrix()


# -- the convention ----------------------------------------------------------------------


def test_lookup_matches_the_values_mitsuba_returned():
    """Mitsuba 3.9.1's envmap.eval of the 8 x 5 ramp (scalar_rgb), at these (u, v):
    column i sits at u = (i + 0.5) / W, row j at v = j / (H - 1), u = 0 halfway
    between the last column and the first."""
    env = Environment.from_image(ramp_image())
    cases = [
        ((0.5 / 8, 0.5), (1.0, 3.0, 1.0)),
        ((1.5 / 8, 0.5), (2.0, 3.0, 1.0)),
        ((0.0, 0.5), (4.5, 3.0, 1.0)),
        ((1 / 8, 0.5), (1.5, 3.0, 1.0)),
        ((1.5 / 8, 0.25), (2.0, 2.0, 1.0)),
        ((1.5 / 8, 0.1), (2.0, 1.4, 1.0)),
        ((3.5 / 8, 0.5), (4.0, 3.0, 1.0)),
    ]
    for (u, v), expected in cases:
        assert np.allclose(env.radiance(uv_dir(u, v)), expected, atol=1e-5), (u, v)


def test_zenith_and_nadir_are_the_first_and_last_rows():
    image = ramp_image()
    env = Environment.from_image(image, scale=2.0)
    assert np.allclose(env.radiance([[0, 1, 0]])[0, 1], 2.0 * 1)  # row 0 (green = 1) straight up
    assert np.allclose(env.radiance([[0, -1, 0]])[0, 1], 2.0 * 5)


def test_rotation_turns_the_map_world_from_environment():
    rotation = rotation_xyz(0.3, -1.1, 0.7)
    env = Environment.from_image(ramp_image(), rotation=rotation)
    plain = Environment.from_image(ramp_image())
    local = np.random.default_rng(0).normal(size=(50, 3))
    local /= np.linalg.norm(local, axis=1)[:, None]
    assert np.allclose(env.radiance(local @ rotation.T), plain.radiance(local))


def test_lookup_matches_mitsuba_itself(tmp_path):
    """Random directions, a random image and a to_world rotation: Mitsuba's envmap.eval
    and ours agree to float32 rounding."""
    rng = np.random.default_rng(7)
    image = rng.random((6, 10, 3)).astype(np.float32)
    rotation = rotation_xyz(0.4, 1.3, -0.2)
    dirs = rng.normal(size=(64, 3))
    dirs /= np.linalg.norm(dirs, axis=1)[:, None]
    np.save(tmp_path / "image.npy", image)
    script = textwrap.dedent(f"""
        import json, numpy as np, mitsuba as mi, drjit as dr
        mi.set_variant("scalar_rgb")
        m = np.eye(4); m[:3, :3] = np.array({rotation.tolist()})
        em = mi.load_dict({{"type": "envmap", "bitmap": mi.Bitmap(np.load({str(tmp_path / 'image.npy')!r})),
                           "to_world": mi.ScalarTransform4f(m.tolist())}})
        out = []
        for d in {dirs.tolist()}:
            si = dr.zeros(mi.SurfaceInteraction3f)
            si.wi = -mi.Vector3f(*d)
            out.append(list(map(float, em.eval(si))))
        print(json.dumps(out))
    """)
    theirs = np.array(json.loads(run_mitsuba(script, timeout=120).strip().splitlines()[-1]))
    ours = Environment.from_image(image, rotation=rotation).radiance(dirs)
    assert np.allclose(ours, theirs, rtol=1e-4, atol=1e-5)


# -- numba against numpy ---------------------------------------------------------------------


@numba.njit(cache=True)
def _lookups(env, dirs):
    out = np.empty((len(dirs), 3))
    for k in range(len(dirs)):
        out[k] = env_lookup(env.pixels, env.rotation, dirs[k, 0], dirs[k, 1], dirs[k, 2])
    return out


@numba.njit(cache=True)
def _samples(env, u):
    dirs = np.empty((len(u), 3))
    pdfs = np.empty(len(u))
    again = np.empty(len(u))
    for k in range(len(u)):
        d, p = env_sample(env.rotation, env.row_cdf, env.column_cdf, env.cell_pdf, u[k, 0], u[k, 1])
        dirs[k, 0], dirs[k, 1], dirs[k, 2] = d
        pdfs[k] = p
        again[k] = env_pdf(env.rotation, env.cell_pdf, d[0], d[1], d[2])
    return dirs, pdfs, again


@numba.njit(cache=True)
def _pdfs(env, dirs):
    out = np.empty(len(dirs))
    for k in range(len(dirs)):
        out[k] = env_pdf(env.rotation, env.cell_pdf, dirs[k, 0], dirs[k, 1], dirs[k, 2])
    return out


def test_numba_lookup_and_sampler_match_the_numpy_references():
    rng = np.random.default_rng(1)
    env = Environment.from_image(sunny_image(), scale=0.5, rotation=rotation_xyz(0.2, 0.5, 0.9))
    arrays = env.kernel_arrays((0, 0, 0), 1.0)
    dirs = rng.normal(size=(2000, 3))
    dirs /= np.linalg.norm(dirs, axis=1)[:, None]
    assert np.allclose(_lookups(arrays, dirs), env.radiance(dirs), rtol=1e-12, atol=1e-12)
    u = rng.random((2000, 2))
    sampled, pdf, again = _samples(arrays, u)
    ref_dirs, ref_pdf = env.sample(u)
    assert np.allclose(sampled, ref_dirs, atol=1e-12) and np.allclose(pdf, ref_pdf, rtol=1e-9)
    assert np.allclose(again, pdf, rtol=1e-6)  # env_pdf of a sample is the density it was drawn with
    assert np.allclose(_pdfs(arrays, dirs), env.pdf(dirs), rtol=1e-9)


# -- the sampler ---------------------------------------------------------------------------


def test_pdf_integrates_to_one_and_the_estimator_to_the_integral():
    env = Environment.from_image(sunny_image(), rotation=rotation_xyz(0.3, 0.1, -0.4))
    # equal-area quadrature of the sphere: (phi, cos theta) on a fine grid
    n = 1024
    phi = (np.arange(2 * n) + 0.5) / (2 * n) * 2 * np.pi
    z = 1 - 2 * (np.arange(n) + 0.5) / n
    pp, zz = np.meshgrid(phi, z)
    r = np.sqrt(1 - zz**2)
    dirs = np.stack([r * np.cos(pp), zz, r * np.sin(pp)], axis=-1).reshape(-1, 3)
    weight = 4 * np.pi / len(dirs)
    assert env.pdf(dirs).sum() * weight == pytest.approx(1.0, abs=2e-3)
    assert np.allclose(env.radiance(dirs).sum(axis=0) * weight, env.integral(), rtol=2e-3)
    # importance sampling: L / pdf averages to the integral, with little spread (the sun is sampled)
    world, pdf = env.sample(np.random.default_rng(5).random((200_000, 2)))
    estimate = env.radiance(world) / pdf[:, None]
    assert np.allclose(estimate.mean(axis=0), env.integral(), rtol=0.01)
    assert (estimate.std(axis=0) / estimate.mean(axis=0)).max() < 1.0


def test_sampler_passes_a_chi_square_test_against_its_pdf():
    """200k samples of the numba sampler in bins of the environment's (u, v) (each
    sampling cell split 2 x 2), against the probability its pdf gives each bin; a
    sampler drawing the wrong cell or the wrong place in a cell fails."""
    env = Environment.from_image(sunny_image(h=9, w=12))
    arrays = env.kernel_arrays((0, 0, 0), 1.0)
    rows, columns = arrays.cell_pdf.shape
    dirs, _, _ = _samples(arrays, np.random.default_rng(11).random((200_000, 2)))
    u, v = envmod.direction_to_uv(dirs)
    bu = np.floor(np.mod(u * columns - 0.5, columns) * 2).astype(int)
    bv = np.minimum(np.floor(v * rows * 2).astype(int), 2 * rows - 1)
    observed = np.bincount(bv * 2 * columns + bu, minlength=4 * rows * columns).astype(float)
    # the density is constant in (u, v) within a cell: each quarter holds a quarter of its probability
    expected = np.repeat(np.repeat(arrays.cell_pdf / (rows * columns) / 4, 2, axis=0), 2, axis=1).ravel() * len(dirs)
    keep = expected >= 5
    assert expected.sum() == pytest.approx(len(dirs))
    chi2 = (((observed - expected) ** 2 / np.maximum(expected, 1e-300))[keep]).sum()
    pooled = observed[~keep].sum()
    p = stats.chi2.sf(chi2, keep.sum() - 1)
    assert p > 1e-3, (chi2, keep.sum(), p)
    assert pooled <= expected[~keep].sum() + 5 * np.sqrt(expected[~keep].sum() + 1)


def test_a_constant_environment_samples_nearly_uniformly():
    env = Environment.uniform([1.0, 2.0, 3.0])
    assert np.allclose(env.integral(), 4 * np.pi * np.array([1.0, 2.0, 3.0]))
    world, pdf = env.sample(np.random.default_rng(2).random((10000, 2)))
    assert np.allclose(env.radiance(world), [1.0, 2.0, 3.0])
    # piecewise constant over rows 1/32 of pi high: within 12 % of uniform away from the poles
    middle = np.abs(world[:, 1]) < 0.9
    assert np.allclose(pdf[middle], 1 / (4 * np.pi), rtol=0.12)


def test_black_environment_is_never_sampled():
    arrays = Environment.uniform(0.0).kernel_arrays((0, 0, 0), 1.0, other_power=3.0)
    assert arrays.active and arrays.photon_share == 0 and arrays.light_share == 0


def test_shares_follow_power():
    env = Environment.uniform(1.0)
    assert env.power(2.0) == pytest.approx(np.pi * 4 * 4 * np.pi * np.ones(3))
    power = float(env.power(2.0).sum())
    arrays = env.kernel_arrays((0, 0, 0), 2.0, other_power=power)
    assert arrays.photon_share == pytest.approx(0.5) and arrays.light_share == 0.5
    alone = env.kernel_arrays((0, 0, 0), 2.0)
    assert alone.photon_share == 1.0 and alone.light_share == 1.0


# -- storage ---------------------------------------------------------------------------------


@pytest.mark.parametrize("make", [lambda: Environment.uniform([0.5, 1, 2], 3.0),
                                  lambda: Environment.from_image(sunny_image(), 0.25, rotation_xyz(1, 2, 3))])
def test_arrays_round_trip_through_an_npz(tmp_path, make):
    env = make()
    np.savez(tmp_path / "e.npz", **env.to_arrays())
    with np.load(tmp_path / "e.npz", allow_pickle=False) as data:
        back = Environment.from_arrays(dict(data))
    dirs = np.random.default_rng(0).normal(size=(100, 3))
    dirs /= np.linalg.norm(dirs, axis=1)[:, None]
    assert back.constant == env.constant and back.scale == env.scale
    assert np.array_equal(back.radiance(dirs), env.radiance(dirs))
    json.dumps(env.info())


def test_bad_environments_are_refused():
    with pytest.raises(InputError, match="at least 2 x 3"):
        Environment.from_image(np.ones((2, 8, 3)))
    with pytest.raises(InputError, match="finite and >= 0"):
        Environment.uniform([1, -1, 1])
    with pytest.raises(InputError, match="orthonormal"):
        Environment.uniform(1.0, rotation=np.diag([2.0, 1, 1]))
    with pytest.raises(InputError, match="scale"):
        Environment.uniform(1.0, scale=float("nan"))
    with pytest.raises(InputError, match="missing"):
        Environment.from_arrays({"image": np.ones((1, 1, 3))})


# -- loaders ---------------------------------------------------------------------------------

OBJECT = """
[materials.grey]
diffuse = 0.5
[[objects]]
name = "quad"
builtin = "quad"
material = "grey"
"""


def toml_scene(tmp_path, environment):
    path = tmp_path / "scene.toml"
    path.write_text(OBJECT + textwrap.dedent(environment))
    return path


def test_toml_constant_and_image_environments(tmp_path):
    scene = load_scene(toml_scene(tmp_path, "[environment]\nradiance = [1, 2, 3]\nscale = 2\n"))
    assert scene.environment.constant and np.allclose(scene.environment.radiance([[0, 0, 1]]), [2, 4, 6])
    np.save(tmp_path / "sky.npy", ramp_image())
    scene = load_scene(toml_scene(tmp_path, '[environment]\nimage = "sky.npy"\nrotate_deg = [0, 90, 0]\n'))
    turned = rotation_xyz(0, np.pi / 2, 0)
    assert np.allclose(scene.environment.rotation, turned)
    assert np.allclose(scene.environment.radiance(uv_dir(0.3, 0.4) @ turned.T), Environment.from_image(
        ramp_image()).radiance(uv_dir(0.3, 0.4)))
    rows = "[[1, 0, 0], [0, 0, -1], [0, 1, 0]]"
    scene = load_scene(toml_scene(tmp_path, f'[environment]\nimage = "sky.npy"\nrotation = {rows}\n'))
    assert np.allclose(scene.environment.rotation, [[1, 0, 0], [0, 0, -1], [0, 1, 0]])


@pytest.mark.parametrize("table, message", [
    ("radiance = 1\nimage = 'sky.npy'", "give 'radiance'"),
    ("scale = 2", "give 'radiance'"),
    ("radiance = 1\nbrightness = 2", "unknown key 'brightness'"),
    ("image = 'nowhere.exr'", "not found"),
    ("radiance = 1\nrotation = [[2, 0, 0], [0, 1, 0], [0, 0, 1]]", "orthonormal"),
    ("radiance = 1\nrotation = [1, 2, 3]", "3 rows of 3"),
    ("radiance = 1\nrotation = [[1, 0, 0], [0, 1, 0], [0, 0, 1]]\nrotate_deg = [0, 0, 0]", "one of"),
    ("radiance = -1", "finite and >= 0"),
])
def test_toml_environment_errors(tmp_path, table, message):
    np.save(tmp_path / "sky.npy", ramp_image())
    with pytest.raises(InputError, match=message) as info:
        load_scene(toml_scene(tmp_path, "[environment]\n" + table + "\n"))
    assert "[environment]" in str(info.value) and "\n" not in str(info.value)


MITSUBA = """<scene version="3.0.0">
    <shape type="rectangle"><bsdf type="diffuse"/></shape>
    {emitter}
</scene>
"""


def test_mitsuba_envmap_and_constant(tmp_path):
    np.save(tmp_path / "sky.npy", ramp_image())  # read as linear radiance, as .exr would be
    emitter = """<emitter type="envmap"><string name="filename" value="sky.npy"/><float name="scale" value="3"/>
        <transform name="to_world"><rotate y="1" angle="90"/></transform></emitter>"""
    path = tmp_path / "scene.xml"
    path.write_text(MITSUBA.format(emitter=emitter))
    env = load_scene(path).environment
    assert not env.constant and env.scale == 3.0
    assert np.allclose(env.rotation, rotation_xyz(0, np.pi / 2, 0), atol=1e-12)
    path.write_text(MITSUBA.format(emitter='<emitter type="constant"><rgb name="radiance" value="0.5, 1, 2"/></emitter>'))
    env = load_scene(path).environment
    assert env.constant and np.allclose(env.radiance([[1, 0, 0]]), [0.5, 1, 2])
    path.write_text(MITSUBA.format(emitter='<emitter type="envmap"/>'))
    with pytest.raises(InputError, match="needs a 'filename'"):
        load_scene(path)
