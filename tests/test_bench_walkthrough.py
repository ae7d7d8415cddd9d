"""benchmarks/bench_walkthrough.py's pure parts: the arithmetic of the totals (break-even
N, ratios), the summary of the ways from their rows, the interior's camera walk, and the
Mitsuba export read back by the project's own Mitsuba loader."""

from __future__ import annotations

import importlib
import warnings
from pathlib import Path

import numpy as np
import pytest

BENCHMARKS = Path(__file__).resolve().parent.parent / "benchmarks"


@pytest.fixture
def bw(monkeypatch):
    """The benchmark module, imported as its scripts import each other (from benchmarks/)."""
    monkeypatch.syspath_prepend(str(BENCHMARKS))
    return importlib.import_module("bench_walkthrough")


def test_break_even_is_where_the_totals_meet(bw):
    fitted = {"fixed_s": 20.0, "per_frame_s": 0.1}
    traced = {"fixed_s": 0.5, "per_frame_s": 4.0}
    n = bw.break_even(fitted, traced)
    assert n == pytest.approx(19.5 / 3.9)  # 5 frames
    assert bw.total(fitted, n) == pytest.approx(bw.total(traced, n))
    assert bw.total(fitted, n + 1) < bw.total(traced, n + 1)


def test_break_even_never_and_always(bw):
    cheap_frames = {"fixed_s": 20.0, "per_frame_s": 0.1}
    assert bw.break_even(cheap_frames, {"fixed_s": 0.0, "per_frame_s": 0.1}) is None  # frames no dearer: never pays
    assert bw.break_even(cheap_frames, {"fixed_s": 0.0, "per_frame_s": 0.05}) is None
    assert bw.break_even(cheap_frames, {"fixed_s": 30.0, "per_frame_s": 1.0}) == 0.0  # cheaper from the start
    assert bw.break_even(cheap_frames, {"fixed_s": 30.0, "per_frame_s": 0.1}) == 0.0


def test_ratios_of_the_totals(bw):
    fitted = {"fixed_s": 20.0, "per_frame_s": 0.1}
    traced = {"fixed_s": 0.0, "per_frame_s": 2.0}
    r = bw.ratios(fitted, traced)
    assert list(r) == ["1", "100", "10000"]
    assert r["1"] == pytest.approx(2.0 / 20.1)
    assert r["100"] == pytest.approx(200.0 / 30.0)
    assert r["10000"] == pytest.approx(20000.0 / 1020.0)


def test_summary_of_the_ways(bw):
    setup = {"solve_s": 10.0, "fit_s": 30.0, "upload_fitted_s": 0.5, "upload_reference_s": 1.0, "tracer_setup_s": 0.2}

    def frame(fitted_s, reference_s, traced_fitted, traced_reference, reached=True):
        return {"fitted": {"flip": 0.1, "frame_s": fitted_s}, "reference": {"flip": 0.08, "frame_s": reference_s},
                "path_tracer": {"fitted": {"spp": 48, "seconds": traced_fitted, "flip": 0.09, "reached": True},
                                "reference": {"spp": 96, "seconds": traced_reference, "flip": 0.07,
                                              "reached": reached}}}

    s = bw.summary("scene", setup, [frame(0.1, 0.2, 3.0, 6.0), frame(0.3, 0.4, 5.0, 10.0, reached=False)])
    ways = s["ways"]
    assert ways["fitted"]["fixed_s"] == pytest.approx(40.5) and ways["fitted"]["per_frame_s"] == pytest.approx(0.2)
    assert ways["reference"]["fixed_s"] == pytest.approx(11.0) and ways["reference"]["per_frame_s"] == pytest.approx(0.3)
    tracer = ways["path tracer at the fitted FLIP"]
    assert tracer["fixed_s"] == pytest.approx(0.2) and tracer["per_frame_s"] == pytest.approx(4.0)
    assert tracer["spp"] == [48, 48] and tracer["reached"] is True
    assert ways["path tracer at the reference FLIP"]["reached"] is False
    assert s["break_even_frames"]["fitted"] == pytest.approx((40.5 - 0.2) / (4.0 - 0.2))
    assert s["break_even_frames"]["reference"] == pytest.approx((11.0 - 0.2) / (8.0 - 0.3))
    assert s["ratio_of_totals"]["fitted"]["100"] == pytest.approx(400.2 / 60.5)
    assert "fitted, Mitsuba" not in s["break_even_frames"]


def test_the_walk_goes_through_the_doorway(bw):
    from bench_scale import DOOR, ROOM

    from radiosity.files.camera import Camera

    keyframes = bw.walk_keyframes()
    camera = Camera((0, 1, 0), (0, 1, 1), (0, 1, 0), 60.0, 32, 24)
    views = bw.walk_views(camera, np.linspace(0, 1, 201), keyframes)
    eyes = np.array([v.eye for v in views])
    assert np.allclose(eyes[:, 1], bw.EYE_HEIGHT)
    assert np.allclose(eyes[0, [0, 2]], keyframes[0]) and np.allclose(eyes[-1, [0, 2]], keyframes[-1])
    # inside the first two rooms, clear of the outer walls, crossing the wall at z = ROOM in its doorway
    assert (eyes[:, 0] > 0.3).all() and (eyes[:, 0] < ROOM - 0.3).all()
    assert (eyes[:, 2] > 0.3).all() and (eyes[:, 2] < 2 * ROOM - 0.3).all()
    near_wall = np.abs(eyes[:, 2] - ROOM) < 0.2
    assert near_wall.any() and (np.abs(eyes[near_wall, 0] - ROOM / 2) < DOOR / 2 - 0.2).all()
    for view in views:  # each looks LOOK_AHEAD ahead along the path, slightly down
        flat = np.subtract(view.look_at, view.eye)[[0, 2]]
        assert np.linalg.norm(flat) == pytest.approx(bw.LOOK_AHEAD, abs=0.6)
        assert view.look_at[1] == pytest.approx(bw.LOOK_HEIGHT)
        assert (view.width, view.height, view.fov_y_deg) == (32, 24, 60.0)


def test_along_continues_straight_past_the_ends(bw):
    points = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 2.0]])
    assert np.allclose(bw.along(points, 0.5), [0.5, 0.0])
    assert np.allclose(bw.along(points, 2.0), [1.0, 1.0])
    assert np.allclose(bw.along(points, 4.0), [1.0, 3.0])
    assert np.allclose(bw.along(points, -1.0), [-1.0, 0.0])


@pytest.mark.parametrize("exponent", [8.0, 20.0, 120.0, 1000.0])
def test_ggx_alpha_inverts_the_rule(bw, exponent):
    from radiosity.scene.microfacet import phong_exponent

    assert phong_exponent("ggx", bw.ggx_alpha(exponent)) == pytest.approx(exponent, rel=1e-4)


def test_mitsuba_export_reads_back(bw, tmp_path):
    """The XML written for Mitsuba, read by the project's Mitsuba loader: the same
    triangles, materials (the blend back as one Phong lobe: kd, ks, the exponent), lamp
    and camera (its first sensor)."""
    from display.compare import orbit
    from radiosity.scene.loaders import load_scene
    from radiosity.scene.mitsuba import load_mitsuba

    scene = load_scene("cornell-teapot")
    view = orbit(scene.camera.sized(40, 30), 20.0)
    path = bw.mitsuba_scene(scene, [view, scene.camera.sized(40, 30)], tmp_path)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the second sensor, the blends as one lobe: named, expected
        back = load_mitsuba(path)
    assert [len(o.faces) for o in back.objects] == [len(o.faces) for o in scene.objects]
    for ours, theirs in zip(scene.objects, back.objects, strict=True):
        assert np.allclose(theirs.positions, ours.positions, atol=1e-3)
        a, b = ours.material, theirs.material
        assert np.allclose(b.diffuse, a.diffuse, atol=1e-5) and np.allclose(b.specular, a.specular, atol=1e-5)
        assert np.allclose(b.emission, a.emission, rtol=1e-5)
        assert b.exponent == pytest.approx(a.exponent, rel=1e-3)
    camera = back.camera
    assert np.allclose(camera.eye, view.eye, atol=1e-3)
    assert np.allclose(camera.basis[2], view.basis[2], atol=1e-6)  # the same viewing direction, not mirrored
    assert np.allclose(camera.basis[0], view.basis[0], atol=1e-6)
    assert camera.fov_y_deg == pytest.approx(view.fov_y_deg) and (camera.width, camera.height) == (40, 30)
