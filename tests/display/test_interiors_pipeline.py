"""Every step a user types, on a Mitsuba 0.4 scene in the layout of Veach's
multiple-importance-sampling test (tests/data/mitsuba/mis_04.xml: our own geometry, in
the old dialect: <lookAt>, camelCase, a mirroring scale undone, fovAxis smaller on a
wide film) and, where the collection has been fetched (tests/radiosity/scene/
test_collection.py says where), on Veach's own scene: scene-info, solve, fit, render,
export and compare against a reference image, each exiting 0 with its files written."""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
import pytest

DATA = Path(__file__).resolve().parents[1] / "data" / "mitsuba"
COLLECTION = Path(os.environ.get("VLIGHTS_SCENES") or "/work/scenes")
SMALL = ["--photons", "40000", "--gather-samples", "16", "--light-samples", "4", "--grid", "16", "--no-adaptive",
         "--seed", "2"]


def every_step(cli, scene, folder, solve_flags, reference=None, size="96x64", spp=32, fit_flags=()):
    """scene-info, solve, fit, render, export and compare (against ``reference``, or the
    path tracer's own image of the scene's camera): the compare.json written."""
    steps = [("scene-info", scene), ("solve", scene, *solve_flags, "-o", folder / "solution.npz"),
             ("fit", folder / "solution.npz", "--workers", "1", *fit_flags, "-o", folder / "fit.npz"),
             ("render", folder / "fit.npz", "--size", "48x32", "--samples", "1", "-o", folder / "render.png"),
             ("export", folder / "fit.npz", "-o", folder / "web")]
    for argv in steps:
        code, _, err = cli(*argv)
        assert code == 0, f"vlights {argv[0]}: {err}"
    if reference is None:
        reference = folder / "traced.npy"
        code, _, err = cli("truth", folder / "solution.npz", "--size", size, "--spp", 4 * spp, "--hdr", reference)
        assert code == 0, err
    code, out, err = cli("compare", folder / "fit.npz", folder / "solution.npz", "--reference", reference,
                         "--truth-spp", spp, "--samples", "8", "--out", folder / "compare")
    assert code == 0, err
    for name in ("solution.npz", "fit.npz", "render.png", "web/scene.glb", "web/index.html", "compare/compare.json"):
        assert (folder / name).is_file(), name
    with open(folder / "compare" / "compare.json") as f:
        return json.load(f)


@pytest.mark.gl
def test_a_mitsuba_04_scene_goes_through_every_step(tmp_path, cli, gl_context):
    numbers = every_step(cli, DATA / "mis_04.xml", tmp_path, SMALL, fit_flags=["--model", "probe", "--probe-size", "8"])
    displays = numbers["reference_image"]["displays"]
    assert set(displays) >= {"fitted", "diffuse", "path_tracer"}
    for name in ("fitted", "path_tracer"):  # the same scene, the same camera: as much light, within the noise
        assert displays[name]["mean_ratio"] == pytest.approx(1, abs=0.1), name
    # the rough plates' reflections (their lamps' highlights gathered into their grids) turn with
    # the view: the diffuse walkthrough, which has none, is the furthest from the truth
    assert displays["diffuse"]["flip_mean"] > 1.5 * displays["fitted"]["flip_mean"]
    assert numbers["reference_image"]["camera"]["eye"] == [0.0, 2.0, 14.0]


@pytest.mark.gl
@pytest.mark.slow
def test_veach_own_scene_goes_through_every_step(tmp_path, cli, gl_context):
    scene, image = COLLECTION / "veach_mi" / "scene.xml", COLLECTION / "veach_mi" / "mi.exr"
    if not (scene.is_file() and image.is_file()):
        pytest.skip(f"Veach's scene is not at {scene} (fetch jgarciapueyo/mitsuba2-transient-scenes and set "
                    "$VLIGHTS_SCENES)")
    numbers = every_step(cli, scene, tmp_path, ["--quality", "draft", "--seed", "1"], reference=image, spp=128)
    displays = numbers["reference_image"]["displays"]
    assert displays["path_tracer"]["mean_ratio"] == pytest.approx(1, abs=0.05)
    assert np.isfinite([d["flip_mean"] for d in displays.values()]).all()
