"""The demo's report leads with a verdict in numbers, and every FLIP error image carries
its scale: no GL, no solve (hand-made summaries and images)."""

import numpy as np
from PIL import Image

from display.compare import BAR_WIDTH, _panel_row, colour_bar, glossy_flip
from display.demo import _report, verdict


def scene_summary(flip_with=0.05, flip_without=0.2):
    objects = {
        "teapot": {"model": "probe+lights", "words": "probe+lights: the emitters' highlights + a 32x32 reflection probe "
                   "+ 4 virtual lights (positional); 19 floats per vertex", "lights": 4, "probe_size": 32,
                   "emitters": True, "floats_per_vertex": 19, "floats": 200000, "shininess": [480.0],
                   "tried": [], "time_s": 12.0, "relative_rms": 0.07, "perceptual": 0.11,
                   "diffuse_only_relative_rms": 0.96},
        "tall_block": {"model": "probe", "words": "probe: the emitters' highlights + a 16x16 reflection probe; 7 floats "
                       "per vertex", "lights": 0, "probe_size": 16, "emitters": True, "floats_per_vertex": 7,
                       "floats": 9000, "shininess": [], "tried": [], "time_s": 1.0, "relative_rms": 0.007,
                       "perceptual": 0.01, "diffuse_only_relative_rms": 0.37},
    }
    figure = {"flip_mean": 0.02, "psnr_db": 40.0, "flip_mean_glossy": 0.1, "psnr_db_glossy": 30.0}
    with_model = figure | {"flip_mean_glossy": flip_with}
    without = figure | {"flip_mean_glossy": flip_without}
    return {
        "scene": "cornell-teapot", "objects": objects, "sizes_bytes": {"solution.npz": 1e7, "fit.npz": 4e5},
        "times_s": {"solve_s": 2.0, "fit_s": 20.0, "compare_s": 10.0, "total_s": 32.0}, "emitter_parts": 1,
        "mesh": None, "truth": None,
        "figures": {"figure5": {f"view{i}": figure for i in (1, 2, 3)},
                    "figure7": {"with_virtual_lights": with_model, "diffuse_only": without},
                    "glossy_flip": glossy_flip(with_model, without)},
    }


def summary(**kw):
    scene = scene_summary(**kw)
    s = {"quality": "draft", "samples": 4, "scenes": {"cornell-teapot": scene}, "times_s": {"total_s": 40.0},
         "meaning": {"diffuse": "a diffuse walkthrough of the solution"}}
    s["verdict"] = verdict("cornell-teapot", scene)
    return s


def test_the_report_leads_with_what_the_model_bought():
    s = summary()
    assert s["verdict"] == ("cornell-teapot (teapot probe+lights, tall_block probe): FLIP on the glossy objects 0.050 "
                            "fitted against 0.200 diffuse (0.25x) against the solution.")
    report = _report(s).splitlines()
    assert report[0].startswith("# ") and report[2] == f"**{s['verdict']}**"
    text = "\n".join(report)
    assert "lower is better" in text and "0 is exact" in text and "0 (identical) to 1" in text
    assert "19 floats per vertex" in text and "a 16x16 reflection probe" in text
    assert "figures with 4 samples per pixel (antialiasing" in text
    assert "cornell-teapot/compare/figure5_view1.png" in text and "models.png" in text


def test_the_verdict_says_what_it_measured_when_nothing_improved():
    scene = scene_summary(flip_with=0.2, flip_without=0.2)
    assert "0.200 fitted against 0.200 diffuse (1.00x)" in verdict("cornell-teapot", scene)


def test_figure7_ratio_against_the_target():
    g = scene_summary(flip_with=0.15, flip_without=0.2)["figures"]["glossy_flip"]
    assert g["ratio"] == 0.15 / 0.2 and g["target_ratio"] == 0.5 and g["meets_target"] is False
    assert glossy_flip({"flip_mean": 0.0}, {"flip_mean": 0.0})["ratio"] == 1.0  # identical: the model changed nothing


def test_every_flip_error_image_has_a_colour_bar(tmp_path):
    h, w = 60, 50
    picture = np.full((h, w, 3), 128, np.uint8)
    error = np.zeros((h, w, 3), np.uint8)
    _panel_row([picture, error, error], ["picture", "error a", "error b"], tmp_path / "row.png", errors=(1, 2))
    row = np.asarray(Image.open(tmp_path / "row.png").convert("RGB"))
    assert row.shape[1] == 3 * w + 2 * BAR_WIDTH  # a bar column beside each error image
    bar = colour_bar(h)
    assert bar.shape == (h, BAR_WIDTH, 3)
    strip = bar[:, 3:13].astype(int).sum(axis=2).mean(axis=1)
    assert strip[6] > strip[h // 2] > strip[h - 7]  # bright (1) at the top, dark (0) at the bottom
    placed = row[-h:, 2 * w:2 * w + BAR_WIDTH]
    assert np.array_equal(placed, bar)
