"""A Mitsuba sensor's field of view at any image size, against Mitsuba 3 itself.

Mitsuba 3 keeps a perspective sensor's ``fov`` along its ``fov_axis`` and derives the
other extent from the film it renders; our ``Camera`` keeps ``fov_deg`` along
``fov_axis`` and derives the vertical field of view at the size it draws. The scene
file we read has a 96 x 54 film; Mitsuba is given the same sensor with the film of the
size drawn (the film's own, wider, taller, square), and our camera is sized to it. For
every axis (and a focal length, a diagonal field of view):

- rays: Mitsuba's ``sample_ray`` through pixel centres against ``Camera.pixel_rays``
  (what the path tracer traces), to float32 rounding;
- markers: small emitting disks parallel to the image plane (so each is drawn as a
  circle about the projection of its centre) rendered by Mitsuba with a box filter (a
  pixel holds the disk's coverage): each one's centroid in the image against where
  ``Camera.view_matrix`` and ``projection_matrix`` (what the renderer draws with) put
  its centre. A field of view read along the wrong axis moves them by pixels.

Skipped where Mitsuba 3 is not installed (tests/mitsuba_oracle.py).
"""

import json
import warnings

import numpy as np
import pytest
from mitsuba_oracle import run_mitsuba
from scipy import ndimage

from radiosity.files.errors import SceneWarning
from radiosity.files.images import read_hdr_image
from radiosity.scene.mitsuba import load_mitsuba

FILM = (96, 54)
SIZES = {"film": FILM, "wider": (128, 40), "taller": (48, 96), "square": (64, 64)}
FOVS = {axis: f'<float name="fov" value="70"/><string name="fov_axis" value="{axis}"/>'
        for axis in ("x", "y", "diagonal", "smaller", "larger")}
FOVS["focal_length"] = '<string name="focal_length" value="35mm"/>'
ORIGIN, TARGET, UP = np.array([0.3, 0.4, 5.0]), np.array([0.0, 0.1, 0.0]), np.array([0.15, 1.0, 0.0])
# markers: (right, up) offsets per unit of depth in the camera's frame, and the depth
MARKERS = [(-0.45, 0.12, 5.0), (0.38, -0.1, 4.0), (0.2, 0.3, 6.0), (-0.25, -0.28, 4.5), (0.62, 0.03, 5.5),
           (0.05, 0.52, 5.0), (-0.7, -0.05, 5.0), (0.1, -0.6, 4.0), (0.0, 0.0, 5.0), (0.12, -0.2, 5.0),
           (-0.1, 0.25, 4.5)]
RADIUS = 0.2
EDGE = 4.0  # pixels: markers nearer the image's border than this are not compared (they may be clipped)
TOLERANCE = 0.1  # pixels

ORACLE = """
import json, sys, mitsuba as mi
mi.set_variant("scalar_rgb")
cases = json.loads(open(sys.argv[1]).read())
out = {}
for name, case in cases.items():
    scene = mi.load_file(case["xml"])
    sensor = scene.sensors()[0]
    w, h = case["size"]
    rays = []
    for i, j in case["pixels"]:
        ray, _ = sensor.sample_ray(0.0, 0.5, mi.Point2f((i + 0.5) / w, (j + 0.5) / h), mi.Point2f(0.5, 0.5))
        rays.append([float(v) for v in ray.d])
    mi.Bitmap(mi.render(scene)).write(case["image"])
    out[name] = rays
open(sys.argv[2], "w").write(json.dumps(out))
"""


def _frame():
    forward = (TARGET - ORIGIN) / np.linalg.norm(TARGET - ORIGIN)
    right = np.cross(forward, UP)
    right /= np.linalg.norm(right)
    return right, np.cross(right, forward), forward


def marker_points():
    """(M, 3) world positions of the markers' centres (disks of radius RADIUS, facing the camera)."""
    right, up, forward = _frame()
    return np.array([ORIGIN + depth * (forward + a * right + b * up) for a, b, depth in MARKERS])


def scene_xml(fov, size):
    v = lambda p: ", ".join(f"{x:.9g}" for x in p)  # noqa: E731
    right, up, forward = _frame()
    markers = ""
    for p in marker_points():  # a disk parallel to the image plane, facing the camera: drawn as a circle
        m = np.eye(4)
        m[:3, :3], m[:3, 3] = RADIUS * np.stack([right, up, -forward], axis=1), p
        markers += (f'<shape type="disk"><transform name="to_world"><matrix value="{v(m.ravel())}"/></transform>'
                    '<emitter type="area"><rgb name="radiance" value="1"/></emitter></shape>')
    return f"""<scene version="3.0.0">
    <integrator type="direct"/>
    <sensor type="perspective">{fov}
        <transform name="to_world"><lookat origin="{v(ORIGIN)}" target="{v(TARGET)}" up="{v(UP)}"/></transform>
        <sampler type="independent"><integer name="sample_count" value="256"/></sampler>
        <film type="hdrfilm"><integer name="width" value="{size[0]}"/><integer name="height" value="{size[1]}"/>
            <rfilter type="box"/></film>
    </sensor>
    {markers}
</scene>"""


def sample_pixels(size):
    """(i, j) pixel indices: the four corners and a 5 x 5 grid."""
    w, h = size
    grid = [(round(a * (w - 1)), round(b * (h - 1))) for a in np.linspace(0, 1, 5) for b in np.linspace(0, 1, 5)]
    return sorted(set(grid))


@pytest.fixture(scope="module")
def mitsuba(tmp_path_factory):
    """Per case name "fov-size": Mitsuba's rays at ``sample_pixels`` and its image."""
    directory = tmp_path_factory.mktemp("mitsuba_camera")
    cases = {}
    for fov_name, fov in FOVS.items():
        for size_name, size in SIZES.items():
            name = f"{fov_name}-{size_name}"
            xml = directory / f"{name}.xml"
            xml.write_text(scene_xml(fov, size))
            cases[name] = {"xml": str(xml), "size": size, "pixels": sample_pixels(size),
                           "image": str(directory / f"{name}.exr")}
    (directory / "cases.json").write_text(json.dumps(cases))
    run_mitsuba(ORACLE, directory / "cases.json", directory / "rays.json")
    rays = json.loads((directory / "rays.json").read_text())
    return {name: (np.array(rays[name]), read_hdr_image(case["image"], "mitsuba's image")[..., :3])
            for name, case in cases.items()}


def our_camera(tmp_path, fov, size):
    """The scene's camera as we read it from the file with the 96 x 54 film, sized to ``size``."""
    path = tmp_path / "scene.xml"
    path.write_text(scene_xml(fov, FILM))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", SceneWarning)
        scene = load_mitsuba(path)
    assert (scene.camera.width, scene.camera.height) == FILM
    return scene.camera.sized(*size)


@pytest.mark.parametrize("size_name", list(SIZES))
@pytest.mark.parametrize("fov_name", list(FOVS))
def test_rays_are_mitsubas_at_any_size(mitsuba, tmp_path, fov_name, size_name):
    size = SIZES[size_name]
    theirs, _ = mitsuba[f"{fov_name}-{size_name}"]
    camera = our_camera(tmp_path, FOVS[fov_name], size)
    pixels = np.array(sample_pixels(size))
    ours = camera.pixel_rays()[pixels[:, 1], pixels[:, 0]]
    theirs = theirs / np.linalg.norm(theirs, axis=1, keepdims=True)
    angle = np.linalg.norm(ours - theirs, axis=1)  # radians, to first order (arccos near 1 loses them)
    assert angle.max() < 1e-6, (fov_name, size_name, angle.max())


def projected(camera, points):
    """(M, 2) continuous pixel coordinates (x right, y down; pixel (i, j) spans [i, i+1] x
    [j, j+1]) of world ``points`` through the renderer's view and projection matrices."""
    clip = camera.projection_matrix(0.1, 100.0) @ camera.view_matrix() @ np.c_[points, np.ones(len(points))].T
    ndc = clip[:2] / clip[3]
    return np.stack([(ndc[0] + 1) / 2 * camera.width, (1 - ndc[1]) / 2 * camera.height], axis=1)


def blob_centroids(image):
    """(B, 2) coverage-weighted centroids (x, y, continuous pixel coordinates) of the
    bright blobs of ``image``."""
    weight = image.mean(axis=2)
    labels, count = ndimage.label(weight > 1e-3)
    ys, xs = np.indices(weight.shape) + 0.5
    out = []
    for k in range(1, count + 1):
        w = np.where(labels == k, weight, 0.0)
        out.append([(w * xs).sum() / w.sum(), (w * ys).sum() / w.sum()])
    return np.array(out).reshape(-1, 2)


def inside(points, size, margin):
    return ((points >= margin) & (points <= np.array(size) - margin)).all(axis=1)


@pytest.mark.parametrize("size_name", list(SIZES))
@pytest.mark.parametrize("fov_name", list(FOVS))
def test_markers_land_on_mitsubas_pixels_at_any_size(mitsuba, tmp_path, fov_name, size_name):
    size = SIZES[size_name]
    _, image = mitsuba[f"{fov_name}-{size_name}"]
    assert image.shape[:2] == (size[1], size[0])
    ours = projected(our_camera(tmp_path, FOVS[fov_name], size), marker_points())
    blobs = blob_centroids(image)
    expected = ours[inside(ours, size, EDGE)]
    assert len(expected) >= 3, f"only {len(expected)} markers in the frame: the test sees too little"
    for point in expected:  # every marker we draw inside the frame is where Mitsuba draws one
        miss = np.linalg.norm(blobs - point, axis=1).min()
        assert miss < TOLERANCE, (fov_name, size_name, point, miss)
    for blob in blobs[inside(blobs, size, EDGE + 1)]:  # and every marker Mitsuba draws is one of ours
        assert np.linalg.norm(ours - blob, axis=1).min() < TOLERANCE, (fov_name, size_name, blob)
