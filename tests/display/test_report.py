"""The demo's report leads with a verdict in numbers, and every FLIP error image carries
its scale: no GL, no solve (hand-made summaries and images)."""

import numpy as np
from PIL import Image

from display.compare import BAR_WIDTH, _panel_row, colour_bar, glossy_flip
from display.demo import _report, sweep_counts, verdict


def summary(flip_with=0.05, flip_without=0.2):
    objects = {
        "teapot": {"lights": 8, "kinds": ["positional"] * 5 + ["directional"] * 3, "coefficients": "per-light",
                   "floats_per_vertex": 27, "model": "8 lights (5 positional and 3 directional), a specular "
                   "coefficient per light at each vertex: 27 floats per vertex", "shininess": [240.0],
                   "relative_rms": 0.19, "worst_vertex": 0.8, "diffuse_only_relative_rms": 1.1,
                   "diffuse_baseline_relative_rms": 0.96},
        "tall_block": {"lights": 8, "kinds": ["positional"] * 8, "coefficients": "per-light", "floats_per_vertex": 27,
                       "model": "8 lights (positional), ...", "shininess": [30.0], "relative_rms": 0.04,
                       "worst_vertex": 0.2, "diffuse_only_relative_rms": 0.5, "diffuse_baseline_relative_rms": 0.37},
    }
    figure = {"flip_mean": 0.02, "psnr_db": 40.0, "flip_mean_glossy": 0.1, "psnr_db_glossy": 30.0}
    with_lights = figure | {"flip_mean_glossy": flip_with}
    without = figure | {"flip_mean_glossy": flip_without}
    s = {
        "quality": "draft", "samples": 4, "objects": objects, "sizes_bytes": {"solution.npz": 1e7, "fit.npz": 1e6},
        "times_s": {"solve_s": 2.0, "fit_s": 20.0, "compare_s": 10.0, "sweep_s": 30.0, "total_s": 62.0},
        "error_vs_lights": {"counts": [1, 2], "preset_counts": [1, 2, 4, 8], "iterations": 25, "models": {"auto/per-light": "the default"},
                            "relative_rms": {"teapot": {"auto/per-light": {"1": 0.3, "2": 0.25, "8": 0.19},
                                                        "auto/shared": {"1": 0.3, "2": 0.3}}}},
        "figures": {"figure5": {f"view{i}": figure for i in (1, 2, 3)},
                    "figure7": {"with_virtual_lights": with_lights, "diffuse_only": without},
                    "glossy_flip": glossy_flip(with_lights, without)},
    }
    s["verdict"] = verdict(s)
    return s


def test_the_report_leads_with_what_the_lights_bought():
    s = summary()
    assert s["verdict"] == (
        "Virtual lights cut the relative RMS error of the teapot from 0.96 (diffuse only) to 0.19 and of the "
        "tall_block from 0.37 to 0.04, and FLIP on the glossy objects from 0.200 (lights off) to 0.050 (0.25x)."
    )
    report = _report(s).splitlines()
    assert report[0].startswith("# ") and report[2] == f"**{s['verdict']}**"
    text = "\n".join(report)
    assert "lower is better" in text and "0 is exact" in text and "0 (identical) to 1" in text
    assert "27 floats per vertex" in text
    assert "figures with 4 samples per pixel (antialiasing" in text
    assert "K = 1, 2 for every model (the `draft` preset's light counts are 1, 2, 4, 8; draft refits only" in text
    assert "ratio 0.25; target <= 0.6: met" in text


def test_the_verdict_does_not_claim_a_cut_that_did_not_happen():
    s = summary(flip_with=0.2, flip_without=0.2)
    s["objects"]["teapot"]["relative_rms"] = 0.99
    assert verdict(s) == (
        "Virtual lights took the relative RMS error of the teapot from 0.96 (diffuse only) to 0.99 and of the "
        "tall_block from 0.37 to 0.04; but FLIP on the glossy objects did not fall: 0.200 with the lights off, "
        "0.200 with them (1.00x)."
    )


def test_figure7_ratio_against_the_target():
    g = summary(flip_with=0.15, flip_without=0.2)["figures"]["glossy_flip"]
    assert g["ratio"] == 0.15 / 0.2 and g["target_ratio"] == 0.6 and g["meets_target"] is False
    assert glossy_flip({"flip_mean": 0.0}, {"flip_mean": 0.0})["ratio"] == 1.0  # identical: the lights changed nothing


def test_draft_sweeps_fewer_light_counts():
    from radiosity.formats.presets import PRESETS

    draft, preset = sweep_counts("draft"), sorted(PRESETS["draft"].demo_light_sweep)
    assert draft == tuple(preset[:2]) and len(draft) < len(preset)
    assert sweep_counts("high") == tuple(sorted(set(PRESETS["high"].demo_light_sweep)))


def test_the_sweep_table_has_every_count_swept():
    text = _report(summary())
    assert "| teapot | auto/per-light | 0.3000 | 0.2500 | 0.1900 |" in text
    assert "| teapot | auto/shared | 0.3000 | 0.3000 |  |" in text


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
