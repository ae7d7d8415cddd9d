"""Glass at display (``display.glass``, glass.glsl) against its numpy statement.

Under a constant environment of radiance 1 the probe of a glass object is 1 in every
direction, so what the shader draws is its weights alone: a thin pane shows F + (1 - F)
= 1 drawn either way ("blend" over the background, "probe"), and a solid ball F + (1 - F)
(1 - F_exit) T^2 at each pixel, computed here from the ray's hit on the true sphere. The
octahedral resampling of the six views is held to the directions it encodes, the fit
file keeps an object's glass (version 7), and the export leaves glass out saying so.
"""

from dataclasses import replace

import numpy as np
import pytest

from display.glass import cube_views, octahedral_from_faces, proxy
from display.renderer import Renderer
from fitting import FitOptions, fit
from fitting.model import load_fit
from fitting.probe import decode
from radiosity.files.camera import Camera
from radiosity.files.solution import ObjectSolution, Solution
from radiosity.physics.directions import grid_directions
from radiosity.physics.environment import EnvironmentLight
from radiosity.scene import builtins
from radiosity.scene.microfacet import fresnel_dielectric

BLACK = [0.0, 0.0, 0.0]


def _glass_object(name, positions, normals, faces, glass):
    material = {"diffuse": BLACK, "specular": BLACK, "exponent": 0.0, "emission": BLACK, "glass": glass}
    tangents = np.cross(normals, [0.3, 0.5, 0.8])
    tangents /= np.linalg.norm(tangents, axis=1, keepdims=True)
    return ObjectSolution(name=name, positions=positions, normals=normals, tangents=tangents, faces=faces,
                          directions=np.array([[0.0, 0.0, 1.0]]), radiance=np.zeros((len(positions), 1, 3)),
                          material=material)


def _ball(eta=1.5, transmittance=(1.0, 1.0, 1.0)):
    positions, faces = builtins.mesh("sphere", subdivisions=5)[:2]
    positions = np.asarray(positions, np.float64)
    normals = positions / np.linalg.norm(positions, axis=1, keepdims=True)
    return _glass_object("ball", normals.copy(), normals, np.asarray(faces), {
        "kind": "dielectric", "eta": eta, "specular_transmittance": list(transmittance)})


def _pane():
    positions = np.array([[-2.0, -0.8, 1.5], [-1.2, -0.8, 1.5], [-1.2, 0.8, 1.5], [-2.0, 0.8, 1.5]])
    return _glass_object("pane", positions, np.tile([0.0, 0.0, 1.0], (4, 1)), np.array([[0, 1, 2], [0, 2, 3]]),
                         {"kind": "thindielectric", "eta": 1.5})


def _furnace(*objects):
    return Solution(objects=objects, scene="glass", environment=EnvironmentLight(np.ones((4, 8, 3), np.float32), 1.0,
                                                                                 np.eye(3)))


CAMERA = Camera((0.0, 0.0, 4.0), (0.0, 0.0, 0.0), fov_deg=40, width=64, height=48)


def _expected_ball(camera, eta, transmittance):
    """Per pixel centre: F + (1 - F)(1 - F_exit) T^2 where the ray meets the unit sphere, NaN elsewhere."""
    d = camera.pixel_rays()
    eye = np.asarray(camera.eye)
    b = d @ eye
    disc = b**2 - (eye @ eye - 1.0)
    s = -b - np.sqrt(np.maximum(disc, 0))
    n = eye + s[..., None] * d
    c = np.sum(-d * n, axis=-1)
    f = fresnel_dielectric(c, eta)
    sin_t = np.sqrt(np.clip(1 - c**2, 0, 1)) / eta
    f_exit = fresnel_dielectric(np.sqrt(1 - sin_t**2), 1 / eta)
    value = f[..., None] + ((1 - f) * (1 - f_exit))[..., None] * np.asarray(transmittance) ** 2
    return np.where((disc > 0)[..., None], value, np.nan), c


@pytest.mark.gl
@pytest.mark.parametrize("approach", ["blend", "probe"])
@pytest.mark.parametrize("eta, transmittance", [(1.5, (1.0, 1.0, 1.0)), (2.4, (0.9, 0.6, 0.3))])
def test_glass_in_a_constant_environment_shows_its_weights(gl_context, approach, eta, transmittance):
    solution = _furnace(_ball(eta, transmittance), _pane())
    renderer = Renderer(gl_context, solution=solution, samples=1)
    renderer.glass_approach = approach
    image = renderer.render(CAMERA, "reference").astype(np.float64)
    expected, cos = _expected_ball(CAMERA, eta, transmittance)
    inside = np.isfinite(expected[..., 0]) & (cos > 0.3)  # off the tessellated silhouette
    assert inside.sum() > 500
    np.testing.assert_allclose(image[inside], expected[inside], atol=0.02)
    pane = np.zeros(image.shape[:2], bool)
    pane[18:30, 3:8] = True  # well inside the pane's image (x -2 .. -1.2 at z 1.5 seen from z 4)
    np.testing.assert_allclose(image[pane], 1.0, atol=0.01)
    renderer.glass_approach = "none"  # left out: the environment behind
    np.testing.assert_allclose(renderer.render(CAMERA, "reference")[inside], 1.0, atol=1e-6)
    renderer.release()


@pytest.mark.gl
def test_a_fitted_glass_object_or_mirror_draws_as_the_solution_s(gl_context, tmp_path):
    mirror = _quad("mirror", [[1.2, -1, -1], [2, -1, -1], [2, 1, -1], [1.2, 1, -1]], [0.0, 0.0, 1.0], 0.0,
                   _mirror_material())
    solution = _furnace(_ball(), _pane(), mirror)
    model = fit(solution, FitOptions.for_quality("draft"))
    path = tmp_path / "fit.npz"
    model.save(path)
    loaded = load_fit(path)
    assert loaded.version == 7 and loaded.object("ball").glass.kind == "dielectric"
    assert loaded.object("ball").n_lights == 0 and not loaded.object("ball").emitted.any()
    assert loaded.object("mirror").mirror.specular == KS and loaded.object("mirror").mirror.fresnel == F0
    assert loaded.object("mirror").n_lights == 0 and loaded.object("mirror").info["model"] == "mirror"
    fitted = Renderer(gl_context, fit=loaded, samples=1)
    reference = Renderer(gl_context, solution=solution, samples=1)
    np.testing.assert_allclose(fitted.render(CAMERA, "fitted"), reference.render(CAMERA, "reference"), atol=1e-5)
    fitted.release()
    reference.release()


def test_the_octahedral_map_holds_the_directions_the_six_views_saw():
    views = cube_views((0.5, -1.0, 2.0), 64)
    faces = []
    for view in views:
        d = view.pixel_rays()
        faces.append((0.5 + 0.5 * d).astype(np.float32))  # each pixel's colour: its direction
    m = 48
    image = octahedral_from_faces(faces, views, m)
    uv = (np.stack(np.meshgrid(np.arange(m), np.arange(m)), axis=-1) + 0.5) / m
    np.testing.assert_allclose(image, 0.5 + 0.5 * decode(uv), atol=0.02)


def test_a_sheet_or_a_slab_passes_light_straight_and_a_ball_or_a_cube_refracts():
    ball = _ball()
    assert not proxy(ball.positions, ball.faces)[0]
    centre, radius = proxy(ball.positions, ball.faces)[1]
    assert np.allclose(centre, 0, atol=1e-9) and radius == pytest.approx(1.0)
    cube, cube_faces = builtins.mesh("cube")[:2]
    assert not proxy(cube, cube_faces)[0]
    for thickness in (0.05, 0.0):  # a closed slab, and an open sheet
        slab = np.asarray(cube, float) * [1.0, 1.0, thickness]
        assert proxy(slab, cube_faces)[0]
    # two thin panels at a right angle (a railing): a box far from thin, yet a slab
    panels = np.concatenate([np.asarray(cube, float) * [1.0, 1.0, 0.02], np.asarray(cube, float)[:, [2, 1, 0]] * [0.02, 1.0, 1.0]])
    faces = np.concatenate([np.asarray(cube_faces), np.asarray(cube_faces) + len(cube)])
    assert proxy(panels, faces)[0]


def test_the_export_leaves_glass_out_saying_so(tmp_path, cli):
    model = fit(_furnace(_ball(), _pane(), *_opaque()), FitOptions.for_quality("draft"))
    model.save(tmp_path / "fit.npz")
    code, out, err = cli("export", tmp_path / "fit.npz", "-o", tmp_path / "page", "--no-page")
    assert code == 0, err
    assert "left out 2 glass object(s) and mirror(s) (ball, pane)" in out
    assert "1 objects" in out


def _opaque():
    positions = np.array([[-3.0, -1.5, -1.0], [3.0, -1.5, -1.0], [3.0, -1.5, 1.0]])
    material = {"diffuse": [0.5, 0.5, 0.5], "specular": BLACK, "exponent": 0.0, "emission": BLACK}
    return (ObjectSolution(name="floor", positions=positions, normals=np.tile([0.0, 1, 0], (3, 1)),
                           tangents=np.tile([1.0, 0, 0], (3, 1)), faces=np.array([[0, 2, 1]]),
                           directions=np.array([[0.0, 0.0, 1.0]]), radiance=np.full((3, 1, 3), 0.3), material=material),)


# -- perfect mirrors ----------------------------------------------------------------------

KS, F0 = (0.9, 0.8, 0.7), (0.6, 0.7, 0.8)


def _mirror_material():
    return {"diffuse": BLACK, "specular": list(KS), "exponent": 1e6, "emission": BLACK, "fresnel": list(F0)}


def _quad(name, corners, normal, radiance, material=None):
    positions = np.asarray(corners, float)
    material = material or {"diffuse": [0.5, 0.5, 0.5], "specular": BLACK, "exponent": 0.0, "emission": BLACK}
    directions, values = np.array([[0.0, 0.0, 1.0]]), np.tile(radiance, (4, 1, 1)).astype(float)
    if material["exponent"] > 0:  # a glossy object's 2 x 2 grid (a mirror's values are not drawn)
        directions, values = grid_directions(2).astype(np.float32), np.zeros((4, 4, 3))
    tangent = np.cross(normal, [0.3, 0.5, 0.8])
    return ObjectSolution(name=name, positions=positions, normals=np.tile(normal, (4, 1)),
                          tangents=np.tile(tangent / np.linalg.norm(tangent), (4, 1)),
                          faces=np.array([[0, 1, 2], [0, 2, 3]]), directions=directions, radiance=values,
                          material=material)


def _reflected_panel(camera):
    """Per pixel of ``camera``: (its ray's direction d; whether it meets the square |x|, |y|
    < 0.95 of the plane z = 0; whether its reflection there meets the panel at z = 2.5, x
    in (-2.95, -1.25), |y| < 1.95; whether that is within 0.1 of the panel's edges)."""
    d = camera.pixel_rays()
    eye = np.asarray(camera.eye)
    s = -eye[2] / d[..., 2]
    hit = eye + s[..., None] * d
    on_plane = (np.abs(hit[..., 0]) < 0.95) & (np.abs(hit[..., 1]) < 0.95) & (s > 0)
    r = d * np.array([1.0, 1.0, -1.0])  # reflected in z = 0
    at = hit + ((2.5 - hit[..., 2]) / r[..., 2])[..., None] * r
    sees_panel = (at[..., 0] > -2.95) & (at[..., 0] < -1.25) & (np.abs(at[..., 1]) < 1.95)
    near_edge = (np.abs(at[..., 0] + 1.2) < 0.1) | (np.abs(at[..., 0] + 3) < 0.1)
    return d, on_plane, sees_panel, near_edge


def _schlick(c):
    return np.asarray(F0) + (1 - np.asarray(F0)) * (1 - c[..., None]) ** 5


@pytest.mark.gl
def test_a_flat_mirror_shows_the_scene_reflected_in_its_plane_and_not_what_is_behind_it(gl_context):
    mirror = _quad("mirror", [[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], [0.0, 0.0, 1.0], 0.0, _mirror_material())
    # a green panel in front of the mirror, off the camera's line of sight, facing the mirror
    panel = _quad("panel", [[-3, -2, 2.5], [-3, 2, 2.5], [-1.2, 2, 2.5], [-1.2, -2, 2.5]], [0.0, 0.0, -1.0],
                  [0.1, 0.8, 0.2])
    # a wall just behind the mirror, facing the room: hidden by the mirror, and clipped from its reflected view
    wall = _quad("wall", [[-4, -3, -0.01], [4, -3, -0.01], [4, 3, -0.01], [-4, 3, -0.01]], [0.0, 0.0, 1.0],
                 [0.3, 0.3, 0.3])
    solution = Solution(objects=(mirror, panel, wall), scene="mirror",
                        environment=EnvironmentLight(np.full((4, 8, 3), 2.0, np.float32), 1.0, np.eye(3)))
    camera = Camera((1.0, 0.2, 3.0), (0.0, 0.0, 0.0), fov_deg=45, width=64, height=48)
    renderer = Renderer(gl_context, solution=solution, samples=1)
    image = renderer.render(camera, "reference").astype(np.float64)
    d, on_mirror, sees_panel, near_edge = _reflected_panel(camera)
    c = d[..., 2] * -1.0
    seen = np.where(sees_panel[..., None], [0.1, 0.8, 0.2], 2.0)
    expected = np.asarray(KS) * _schlick(c) * seen
    check = on_mirror & ~near_edge
    assert (check & sees_panel).sum() > 50 and (check & ~sees_panel).sum() > 50
    np.testing.assert_allclose(image[check], expected[check], rtol=0.02, atol=0.01)
    renderer.release()


@pytest.mark.gl
def test_a_curved_mirror_in_a_constant_environment_shows_ks_times_fresnel(gl_context):
    ball = _ball()
    positions = ball.positions
    material = _mirror_material()
    chrome = ObjectSolution(name="chrome", positions=positions, normals=ball.normals, tangents=ball.tangents,
                            faces=ball.faces, directions=grid_directions(1).astype(np.float32),
                            radiance=np.zeros((len(positions), 1, 3)), material=material)
    solution = _furnace(chrome)
    renderer = Renderer(gl_context, solution=solution, samples=1)
    image = renderer.render(CAMERA, "reference").astype(np.float64)
    _, cos = _expected_ball(CAMERA, 1.5, (1, 1, 1))
    inside = np.isfinite(cos) & (cos > 0.3)
    np.testing.assert_allclose(image[inside], (np.asarray(KS) * _schlick(cos))[inside], rtol=0.02)
    renderer.release()


def test_a_glass_object_is_drawn_piece_by_piece():
    from display.glass import components

    cube, faces = builtins.mesh("cube")[:2]
    cube, faces = np.asarray(cube, float), np.asarray(faces)
    two = np.concatenate([cube * [1, 1, 0.01], cube * [1, 1, 0.01] + [3.0, 0, 0]])
    pieces = components(two, np.concatenate([faces, faces + len(cube)]))
    assert len(pieces) == 2 and all(len(f) == len(faces) for _, f in pieces)
    assert sorted(len(used) for used, _ in pieces) == [len(cube), len(cube)]


def test_a_mirror_with_a_thin_back_is_flat_and_its_plane_is_its_front():
    from display.mirror import mirrored_view, plane_of

    # a 2 x 1 mirror 0.01 thick: a closed box whose front faces +z at z = 0
    x, y, z = np.meshgrid([0.0, 2.0], [0.0, 1.0], [-0.01, 0.0], indexing="ij")
    corners = np.stack([x.ravel(), y.ravel(), z.ravel()], axis=1)  # index 4i + 2j + k
    front = [[1, 5, 7], [1, 7, 3]]  # z = 0, counter-clockwise seen from +z
    point, normal = plane_of(corners, np.array(front))
    assert np.allclose(normal, [0, 0, 1]) and point[2] == 0.0
    ball = _ball()
    assert plane_of(ball.positions, ball.faces) is None
    view = mirrored_view(Camera((0.5, 0.2, 3.0), (0.0, 0.0, 0.0)), (point, normal))
    assert np.allclose(view.eye, (0.5, 0.2, -3.0)) and np.allclose(view.look_at, (0.0, 0.0, 0.0))


@pytest.mark.parametrize("key, entry, fragment", [
    ("glass", {"kind": "crystal", "eta": 1.5}, "glass kind 'crystal'"),
    ("glass", {"kind": "dielectric", "eta": 1.0}, "glass eta = 1"),
    ("mirror", {"specular": [1, 1]}, "mirror specular must be 3 numbers"),
    ("mirror", {"specular": [1, 1, 1], "fresnel": [0.5, 2.0, 0.5]}, "mirror fresnel must be 3 numbers in [0, 1]"),
    ("mirror", {"shine": 1}, "mirror must be"),
])
def test_a_bad_glass_or_mirror_entry_in_a_fit_is_refused_in_one_line(tmp_path, key, entry, fragment):
    import json

    from radiosity.files.errors import InputError
    from radiosity.files.npz import write_archive

    model = fit(_furnace(_ball(), *_opaque()), FitOptions.for_quality("draft"))
    model.save(tmp_path / "fit.npz")
    with np.load(tmp_path / "fit.npz", allow_pickle=False) as f:
        arrays = {k: f[k] for k in f.files if k != "meta"}
        meta = json.loads(str(f["meta"]))
    meta["objects"]["ball"].pop("glass")
    meta["objects"]["ball"][key] = entry
    write_archive(tmp_path / "bad.npz", meta, arrays)
    with pytest.raises(InputError) as refused:
        load_fit(tmp_path / "bad.npz")
    message = str(refused.value)
    assert fragment in message and "\n" not in message and "bad.npz" in message


# -- near mirrors -------------------------------------------------------------------------


def _near_material(alpha, kind="roughplastic"):
    from radiosity.physics.materials import Microfacet

    eta, k = ((1.5,) * 3, (0.0,) * 3) if kind == "roughplastic" else ((0.2, 0.9, 1.1), (3.9, 2.4, 2.2))
    mf = Microfacet(kind, "ggx", alpha, eta, k, specular_reflectance=(0.9, 0.8, 0.7),
                    diffuse_reflectance=(0.5, 0.5, 0.5) if kind == "roughplastic" else (0.0, 0.0, 0.0))
    return {"diffuse": [0.4, 0.4, 0.4], "specular": [0.05, 0.05, 0.05], "exponent": 5000.0, "emission": BLACK,
            "microfacet": mf.to_dict()}


def test_a_flat_sharp_microfacet_object_is_a_near_mirror_and_a_rough_or_phong_one_is_not():
    from display.mirror import NEAR_MIRROR_ALPHA, near_mirror_of

    floor = _quad("floor", [[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], [0.0, 0.0, 1.0], 0.0, _near_material(0.01))
    lobe = near_mirror_of(floor)
    assert lobe.alpha == 0.01 and lobe.code == 1 and np.allclose(lobe.ks, (0.9, 0.8, 0.7))
    assert np.allclose(lobe.f0, 0.04)
    assert near_mirror_of(_quad("f", floor.positions, [0.0, 0.0, 1.0], 0.0, _near_material(2 * NEAR_MIRROR_ALPHA))) is None
    assert near_mirror_of(_quad("f", floor.positions, [0.0, 0.0, 1.0], [0.1, 0.1, 0.1])) is None  # a Phong material
    assert near_mirror_of(_quad("f", floor.positions, [0.0, 0.0, 1.0], 0.0, _near_material(0.02, "roughconductor")))


@pytest.mark.gl
@pytest.mark.parametrize("kind", ["roughplastic", "roughconductor"])
def test_a_near_mirror_shows_its_base_and_the_scene_in_its_plane_weighed_by_its_lobe_s_albedo(gl_context, kind):
    """Its own part plus ks (F0 norm + (1 - F0) schlick)(alpha, n . w) times what the plane
    reflects (a green panel, else the environment); its grid is not drawn. Its own part: a
    conductor's least radiance per vertex; a plastic's substrate, the least of radiance /
    (1 - F) over the grid's directions at least 0.3 from grazing, times 1 - F(n . w) (the
    exact Fresnel of the oracle, radiosity.scene.microfacet). The fitted display draws the
    same from the part fit.npz keeps (version 10). Drawn from the grid (near mirrors off),
    it is not that."""
    from radiosity.physics.ltc import lobe_albedo
    from radiosity.physics.materials import Microfacet
    from radiosity.scene.microfacet import fresnel_dielectric

    material = _near_material(0.01, kind)
    floor = _quad("floor", [[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], [0.0, 0.0, 1.0], 0.0, material)
    grid = np.array([0.3, 0.05, 0.2, 0.1])[None, :, None] * np.array([1.0, 0.8, 0.6])  # least: 0.05 (0.8, 0.6)
    floor = replace(floor, radiance=np.tile(grid, (4, 1, 1)))
    panel = _quad("panel", [[-3, -2, 2.5], [-3, 2, 2.5], [-1.2, 2, 2.5], [-1.2, -2, 2.5]], [0.0, 0.0, -1.0],
                  [0.1, 0.8, 0.2])
    solution = Solution(objects=(floor, panel), scene="near",
                        environment=EnvironmentLight(np.full((4, 8, 3), 2.0, np.float32), 1.0, np.eye(3)))
    camera = Camera((1.0, 0.2, 3.0), (0.0, 0.0, 0.0), fov_deg=45, width=64, height=48)
    renderer = Renderer(gl_context, solution=solution, samples=1)
    renderer.near_mirrors = True
    assert renderer.objects[0].near is not None and renderer.objects[1].near is None
    image = renderer.render(camera, "reference").astype(np.float64)
    d, on_floor, sees_panel, near_edge = _reflected_panel(camera)
    c = np.clip(-d[..., 2], 0.0, 1.0)
    albedo = lobe_albedo(Microfacet.from_dict(material["microfacet"]), c.ravel()).reshape(*c.shape, 3)
    seen = np.where(sees_panel[..., None], [0.1, 0.8, 0.2], 2.0)
    base = 0.05 * np.array([1.0, 0.8, 0.6]) * np.ones(c.shape)[..., None]
    if kind == "roughplastic":
        cos = grid_directions(2)[:, 2].astype(np.float64)
        ok = cos >= 0.3
        substrate = np.min(grid[0, ok] / (1.0 - fresnel_dielectric(cos[ok], 1.5))[:, None], axis=0)
        base = substrate * (1.0 - fresnel_dielectric(c, 1.5))[..., None]
    expected = base + np.array([0.9, 0.8, 0.7]) * albedo * seen
    check = on_floor & ~near_edge
    assert (check & sees_panel).sum() > 50 and (check & ~sees_panel).sum() > 50
    np.testing.assert_allclose(image[check], expected[check], rtol=0.02, atol=0.01)
    renderer.near_mirrors = False
    grid_drawn = renderer.render(camera, "reference").astype(np.float64)
    assert np.abs(grid_drawn[check] - expected[check]).max() > 0.1
    renderer.release()
    model = fit(solution, FitOptions.for_quality("draft"))
    assert model.version == 10 and model.object("floor").near_base is not None
    assert model.object("floor").near_eta == (1.5 if kind == "roughplastic" else 0.0)
    fitted = Renderer(gl_context, fit=model, samples=1)
    assert fitted.near_mirrors  # on by default
    np.testing.assert_allclose(fitted.render(camera, "fitted")[check], expected[check], rtol=0.02, atol=0.01)
    fitted.release()


def test_a_fit_keeps_a_near_mirror_s_own_part_and_reads_it_back(tmp_path):
    """fit.npz version 10: the part ``radiosity.physics.materials.near_base`` takes from the
    solution's grid, with the object's microfacet model; read back the same. A rough one
    (above NEAR_MIRROR_ALPHA) keeps none, and its fit is version 8 or lower."""
    from display.mirror import NEAR_MIRROR_ALPHA
    from radiosity.physics.materials import near_base

    floor = _quad("floor", [[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], [0.0, 0.0, 1.0], 0.0, _near_material(0.01))
    grid = np.array([0.3, 0.05, 0.2, 0.1])[None, :, None] * np.array([1.0, 0.8, 0.6])
    floor = replace(floor, radiance=np.tile(grid, (4, 1, 1)))
    model = fit(Solution(objects=(floor,), scene="near"), FitOptions.for_quality("draft"))
    want, eta = near_base(floor.material["microfacet"], floor.directions, lambda f: f(np.asarray(floor.radiance, float)))
    got = model.object("floor")
    assert eta == 1.5 and got.near_eta == 1.5
    np.testing.assert_allclose(got.near_base, want, rtol=1e-6)
    model.save(tmp_path / "fit.npz")
    back = load_fit(tmp_path / "fit.npz")
    assert back.version == 10 and np.array_equal(back.object("floor").near_base, got.near_base)
    assert back.object("floor").near_microfacet == got.near_microfacet
    rough = replace(floor, material=_near_material(2 * NEAR_MIRROR_ALPHA))
    assert fit(Solution(objects=(rough,), scene="near"), FitOptions.for_quality("draft")).version <= 8


@pytest.mark.parametrize("change, words", [
    (lambda meta, arrays: meta["objects"]["floor"].pop("near"), "'near': {\"microfacet\""),
    (lambda meta, arrays: arrays.pop("floor/near_base"), "has no 'floor/near_base'"),
    (lambda meta, arrays: meta["objects"]["floor"]["near"].update(microfacet={"kind": "felt"}), "a near mirror needs"),
    (lambda meta, arrays: arrays.update({"floor/near_base": -np.ones((4, 3), np.float32)}), "'near_base' must be"),
])
def test_a_fit_with_a_broken_near_mirror_is_refused_in_one_line(tmp_path, change, words):
    import json

    from radiosity.files.errors import InputError
    from radiosity.files.npz import write_archive

    floor = _quad("floor", [[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], [0.0, 0.0, 1.0], 0.0, _near_material(0.01))
    floor = replace(floor, radiance=np.tile(np.array([0.3, 0.05, 0.2, 0.1])[None, :, None] * np.ones(3), (4, 1, 1)))
    fit(Solution(objects=(floor,), scene="near"), FitOptions.for_quality("draft")).save(tmp_path / "fit.npz")
    with np.load(tmp_path / "fit.npz", allow_pickle=False) as f:
        arrays = {k: f[k] for k in f.files if k != "meta"}
        meta = json.loads(str(f["meta"]))
    change(meta, arrays)
    write_archive(tmp_path / "bad.npz", meta, arrays)
    with pytest.raises(InputError) as refused:
        load_fit(tmp_path / "bad.npz")
    message = str(refused.value)
    assert words in message and "\n" not in message, message
