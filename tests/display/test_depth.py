"""Sides and depth in the renderer, against a numpy ray caster of the same scenes.

The scenes (``depth_scenes``): a 10 m room with a panel hung 1 mm in front of its back
wall, a rug 1 mm above its floor, and a two-sided partition built by
``radiosity.scene.model.with_backs`` (the front and a reversed copy 1e-4 of the
diagonal behind it), scaled by 1e-3, 1 and 1e4, seen from inside and from outside, with
and without an environment. Each pixel's answer: the radiance of the nearest triangle
its centre's ray meets if it meets its front, 0 if its back (surfaces are one-sided), the
environment if none. Every display mode and shading draws it, one sample per pixel; a
pixel whose 3 x 3 neighbourhood sees more than one surface (an edge) is not checked.
Wrong pixels on these scenes before sides and depth were drawn as now: 321,036 of
1,774,200 checked (double-sided with the front's shading, a 24-bit depth buffer and a
near plane 1e-5 of the far one); now none, with reversed Z and with the fallback.
"""

import numpy as np
import pytest
from depth_scenes import SKY, VIEWS, casting, expected, interior, solution, view, wrong_pixels
from renderer_probes import ProbedRenderer

import display.renderer
from display.gl import depth_control
from display.renderer import NEAR_FRACTION, Depth, depth_range
from radiosity.files.camera import Camera

pytestmark = pytest.mark.gl

SCALES = (1e-3, 1.0, 1e4)
MODES = [(mode, shading) for mode in ("reference", "fitted", "diffuse") for shading in ("pixel", "gouraud")]


def check_views(renderer, model, scale, background, views=VIEWS, modes=MODES, samples=1, rtol=1e-3):
    """Every view of ``views`` in every mode of ``modes``: no wrong pixel (beyond
    ``rtol``); returns {view: (image of the first mode, expected, what, front)}. With
    several samples a pixel, a pixel is checked where the 5 x 5 pixels around it see one
    surface: all its samples then do."""
    seen = {}
    for name in views:
        camera = view(name, scale)
        want, what, front = expected(casting(model), camera, background)
        checked = interior(what, front, 1 if samples == 1 else 2)
        assert checked.mean() > 0.7, name  # edges are few: what is checked is most of the picture
        for mode, shading in modes:
            image = renderer.render(camera, mode, shading, samples=samples)
            bad = wrong_pixels(image, want, checked, rtol=rtol)
            assert not bad.any(), (name, mode, shading, int(bad.sum()), image[bad][:3], want[bad][:3])
            seen.setdefault(name, (image, want, what, front))
    return seen


def test_the_context_has_reversed_depth(gl_context):
    """llvmpipe has OpenGL 4.5: the tests below draw with reversed Z into float depth
    (the fallback is tested by its own test, with clip control hidden)."""
    assert depth_control(gl_context) is not None
    assert ProbedRenderer(gl_context, solution=solution()[0], samples=1).depth.reversed


@pytest.mark.parametrize("scale", SCALES)
@pytest.mark.parametrize("environment", [False, True], ids=["black", "environment"])
def test_every_mode_draws_the_nearest_front_at_any_scale(gl_context, scale, environment):
    sol, fit = solution(scale, environment)
    renderer = ProbedRenderer(gl_context, fit=fit, solution=sol, samples=1)
    seen = check_views(renderer, sol, scale, SKY if environment else (0.0, 0.0, 0.0))
    renderer.release()
    # not vacuous: the 1 mm gaps show what is in front, not what is 1 mm behind
    names = [o.name for o in sol.objects]
    for name, part in (("inside, the panel's gap", "panel"), ("inside, the rug on the floor", "rug"),
                       ("inside, grazing along the back wall", "panel")):
        _, _, what, front = seen[name]
        assert ((what == names.index(part)) & front).mean() > 0.05, name


@pytest.mark.parametrize("scale", [1e-3, 1e4])
def test_a_two_sided_wall_shows_the_side_the_eye_is_on(gl_context, scale):
    """The partition (front and back copy, ``with_backs``) from either side and along it:
    every pixel on it the radiance of the side facing the eye, none of the other, none
    black."""
    sol, fit = solution(scale)
    renderer = ProbedRenderer(gl_context, fit=fit, solution=sol, samples=1)
    names = [o.name for o in sol.objects]
    rgb = {o.name: o.radiance[0, 0] for o in sol.objects}
    for name, side, other in (("inside, the partition's front", "partition", "partition (back)"),
                              ("inside, the partition's back", "partition (back)", "partition"),
                              ("inside, along the partition", "partition", "partition (back)")):
        camera = view(name, scale)
        _, what, front = expected(casting(sol), camera)
        on = interior(what, front) & ((what == names.index(side)) | (what == names.index(other)))
        assert on.sum() > 300, name
        assert (front[on] & (what[on] == names.index(side))).all()  # the ray caster agrees
        for mode, shading in MODES:
            image = renderer.render(camera, mode, shading)
            assert np.allclose(image[on], rgb[side], rtol=1e-3), (name, mode, shading)
            assert not np.isclose(image[on], rgb[other], rtol=1e-2).all(axis=1).any()
            assert (image[on].max(axis=1) > 0).all()
    renderer.release()


def test_a_one_sided_wall_from_behind_is_black_and_hides_what_is_behind(gl_context):
    """Behind the back wall, looking in: the room's walls seen from behind are black,
    in every mode, and hide the partition's back copy, which faces this eye, and the
    environment, which shows around them."""
    sol, fit = solution(environment=True)
    renderer = ProbedRenderer(gl_context, fit=fit, solution=sol, samples=1)
    camera = view("outside, behind the back wall")
    _, what, front = expected(casting(sol), camera, SKY)
    names = [o.name for o in sol.objects]
    wall = interior(what, front) & (what == names.index("back"))
    assert wall.mean() > 0.3 and not front[wall].any()
    # without the wall, the partition's back copy would show through it
    without = [c for c in casting(sol) if c[0] != "back"]
    _, behind, behind_front = expected(without, camera, SKY)
    hidden = wall & (behind == [c[0] for c in without].index("partition (back)")) & behind_front
    assert hidden.sum() > 300
    sky = interior(what, front) & (what < 0)
    assert sky.sum() > 300
    for mode, shading in MODES:
        image = renderer.render(camera, mode, shading)
        assert (image[wall] == 0).all(), (mode, shading)
        assert np.allclose(image[sky], SKY, rtol=1e-3)
    renderer.release()


def test_masks_and_attributes_see_fronts_alone(gl_context):
    """The draws figures and tests use: an object's mask holds the pixels where its
    front is the nearest surface (not where its back is); the attribute targets cover
    the fronts alone (a back: no triangle, coverage 0)."""
    sol, fit = solution()
    renderer = ProbedRenderer(gl_context, fit=fit, solution=sol, samples=1)
    names = [o.name for o in sol.objects]
    for name in ("inside, the partition's back", "outside, behind the back wall", "inside, the panel's gap"):
        camera = view(name)
        _, what, front = expected(casting(sol), camera)
        checked = interior(what, front)
        for objects in (("partition", "panel"), ("partition (back)", "back"), tuple(names)):
            mask = renderer.object_mask(camera, objects)
            want = front & np.isin(what, [names.index(o) for o in objects])
            assert np.array_equal(mask[checked], want[checked]), (name, objects)
        which, _, _ = renderer.render_triangles(camera)
        *_, covered = renderer.render_attributes(camera)
        assert np.array_equal(covered[checked], (front & (what >= 0))[checked]), name
        assert np.array_equal(which[checked], np.where(front & (what >= 0), what, -1)[checked]), name
    renderer.release()


@pytest.mark.parametrize("samples, rtol", [(4, 0.03), (16, 0.015)])
def test_antialiased_pictures_are_right_inside_each_surface(gl_context, samples, rtol):
    """With MSAA (4) and supersampling (16), float depth in multisampled buffers: a pixel
    inside one surface averages samples that all see it, so it is that surface's
    radiance within ``rtol``: seen from the side, a wall's triangles are slivers thinner
    than a pixel, and llvmpipe extrapolates their attributes to the pixel's centre (2.1 %
    off at most here with 4 samples, 0.8 % with 16), while one sample of another surface
    would be 7.5 % and 1.9 % off at least (the surfaces differ by 30 % or more)."""
    sol, fit = solution()
    renderer = ProbedRenderer(gl_context, fit=fit, solution=sol, samples=samples)
    check_views(renderer, sol, 1.0, (0.0, 0.0, 0.0), modes=[("reference", "pixel"), ("fitted", "gouraud")],
                samples=samples, rtol=rtol)
    renderer.release()


@pytest.mark.parametrize("scale", SCALES)
def test_without_clip_control_the_conventional_range_draws_the_scenes_too(gl_context, monkeypatch, scale):
    """A context without clip control (OpenGL below 4.5, macOS): the conventional depth
    range into 24 bits, its near plane 1e-3 of the far one and the backs pushed back by
    a polygon offset, draws these scenes right too (a near plane of 1e-4 does not: the
    1 mm gaps from inside)."""
    monkeypatch.setattr(display.renderer, "depth_control", lambda ctx: None)
    sol, fit = solution(scale, environment=True)
    renderer = ProbedRenderer(gl_context, fit=fit, solution=sol, samples=1)
    assert not renderer.depth.reversed
    check_views(renderer, sol, scale, SKY, modes=[("reference", "pixel"), ("fitted", "gouraud")])
    renderer.release()


def test_depth_range_from_the_box_and_the_eye():
    bounds = np.array([[0.0, 0.0, 0.0], [10.0, 10.0, 10.0]])
    near, far = depth_range(bounds, (5.0, 5.0, -20.0))  # outside: half the way to the box
    assert near == pytest.approx(10.0) and far == pytest.approx(np.linalg.norm([5.0, 5.0, 30.0]))
    near, far = depth_range(bounds, (1.0, 2.0, 3.0), 1e-5)  # inside: a fraction of the far corner
    assert far == pytest.approx(np.linalg.norm([9.0, 8.0, 7.0])) and near == pytest.approx(1e-5 * far)
    for scale in (1e-3, 1e4):  # scale-free
        n, f = depth_range(bounds * scale, np.multiply((1.0, 2.0, 3.0), scale), 1e-5)
        assert (n, f) == pytest.approx((near * scale, far * scale))
    assert NEAR_FRACTION[True] < NEAR_FRACTION[False]


def test_reversed_projection_maps_near_to_one_and_infinity_to_zero():
    """Depth = near / distance along the view: 1 at the near plane, 0 only at infinity;
    the conventional projection maps near to -1 and far to 1. Both keep the camera's own
    field of view and aspect (``Camera.projection_matrix``'s x and y rows)."""
    camera = Camera((1.0, 2.0, 3.0), (1.0, 2.0, 10.0), (0.0, 1.0, 0.0), 50.0, 64, 48)
    near, far = 0.01, 100.0
    reversed_, conventional = Depth(True).projection(camera, near, far), Depth(False).projection(camera, near, far)
    assert np.array_equal(reversed_[[0, 1, 3]], camera.projection_matrix(near, far)[[0, 1, 3]])
    assert np.array_equal(conventional, camera.projection_matrix(near, far))
    for distance in (near, 1.0, far, 1e12):
        point = np.array([1.0, 2.0, 3.0 + distance, 1.0])
        clip = reversed_ @ camera.view_matrix() @ point
        assert clip[2] / clip[3] == pytest.approx(near / distance, rel=1e-12)
    clip = conventional @ camera.view_matrix() @ np.array([1.0, 2.0, 3.0 + far, 1.0])
    assert clip[2] / clip[3] == pytest.approx(1.0)
