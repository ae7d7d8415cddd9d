"""The demo's verdicts are small tables (each display's FLIP against the solution and the
truth, the truth's noise floor, a one-line verdict), the same in the terminal and in
report.md, which leads with them; every FLIP error image carries its scale: no GL, no
solve (hand-made summaries and images)."""

import numpy as np
import pytest
from PIL import Image

from display.compare import BAR_WIDTH, _panel_row, colour_bar, glossy_flip
from display.demo import _report, key_numbers, verdict, verdict_markdown, verdict_text


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


def truth(noise=0.031):
    def display(image, glossy):
        return {"flip_mean": image, "flip_mean_glossy": glossy, "relative_mse": 0.01, "relative_mse_glossy": 0.02}

    return {"spp": 64, "noise_flip": noise, "reference": display(0.061, 0.145), "fitted": display(0.066, 0.171),
            "diffuse": display(0.121, 0.409)}


def summary(with_truth=False, **kw):
    scene = scene_summary(**kw)
    if with_truth:
        scene["truth"] = truth()
    s = {"quality": "draft", "samples": 4, "scenes": {"cornell-teapot": scene}, "times_s": {"total_s": 40.0},
         "meaning": {"diffuse": "a diffuse walkthrough of the solution"}}
    s["verdict"] = f"cornell-teapot: {verdict(scene)}."
    return s


def test_the_verdict_is_a_table_of_each_display_against_the_solution_and_the_truth():
    scene = summary(with_truth=True)["scenes"]["cornell-teapot"]
    lines = verdict_text("cornell-teapot", scene).splitlines()
    assert lines[0] == "cornell-teapot (teapot probe+lights, tall_block probe)"
    rows = {line.split("  ")[1].strip(): line.split() for line in lines[3:7]}
    assert rows["solution display"][-3:] == ["itself", "0.145", "0.061"]
    assert rows["fitted display"][-3:] == ["0.050", "0.171", "0.066"]
    assert rows["diffuse display"][-3:] == ["0.200", "0.409", "0.121"]
    assert rows["noise floor (64 spp)"][-1] == "0.031"
    assert lines[-1] == ("  verdict: the fit keeps the glossy look (0.25x the diffuse display against the solution, "
                         "target 0.50x); 0.026 behind the solution display against the truth")
    table = lines[1:7]
    assert len({len(line) for line in table[:-1]}) == 1 and max(map(len, table)) <= 80  # aligned, a terminal wide
    for column in ("0.145", "0.171", "0.409"):  # the numbers of a column end where its heading ends
        assert len({line.index(column) + len(column) for line in table if column in line}) == 1
    assert lines[3].index("itself") + len("itself") == lines[4].index("0.050") + len("0.050")


def test_the_report_has_the_terminals_tables():
    s = summary(with_truth=True)
    report = _report(s)
    scene = s["scenes"]["cornell-teapot"]
    assert report.splitlines()[2] == "## Verdict"
    markdown = verdict_markdown("cornell-teapot", scene)
    assert "\n".join(markdown) in report
    assert "| fitted display | 0.050 | 0.171 | 0.066 |" in markdown
    assert "| noise floor (64 spp) |  |  | 0.031 |" in markdown
    assert f"**Verdict**: {verdict(scene)}." in markdown
    printed = key_numbers(s, "out")
    assert verdict_text("cornell-teapot", scene) in printed
    assert printed.index("everything is in out/") < printed.index("verdict:")  # the verdicts end the output
    assert "Older outputs, compare.json and `--mode` call it `reference`" in report


def test_the_verdict_without_a_truth_has_the_solution_column_alone():
    scene = summary()["scenes"]["cornell-teapot"]
    lines = verdict_text("cornell-teapot", scene).splitlines()
    assert [line.split()[-1] for line in lines[3:6]] == ["itself", "0.050", "0.200"]
    assert "truth" not in "\n".join(lines) and "noise floor" not in "\n".join(lines)
    whole = summary()
    assert "noise floor" not in key_numbers(whole, "out") and "noise floor" not in _report(whole).split("## What")[0]
    assert verdict(scene) == "the fit keeps the glossy look (0.25x the diffuse display against the solution, target 0.50x)"


def test_the_report_explains_its_numbers():
    s = summary()
    text = _report(s)
    assert "lower is better" in text and "0 is exact" in text and "0 (identical) to 1" in text
    assert "19 floats per vertex" in text and "a 16x16 reflection probe" in text
    assert "figures with 4 samples per pixel (antialiasing" in text
    assert "cornell-teapot/compare/figure5_view1.png" in text and "models.png" in text


@pytest.mark.parametrize("flip_with, words", [
    (0.2, "the fit changes nothing a viewer sees (1.00x the diffuse display against the solution)"),
    (0.15, "the fit keeps part of the glossy look (0.75x the diffuse display against the solution, target 0.50x)"),
])
def test_the_verdict_says_what_it_measured_when_the_fit_falls_short(flip_with, words):
    assert verdict(scene_summary(flip_with=flip_with, flip_without=0.2)) == words


def test_the_verdict_against_the_truth_either_way():
    scene = scene_summary()
    scene["truth"] = truth()
    scene["truth"]["fitted"] = scene["truth"]["fitted"] | {"flip_mean_glossy": 0.135}
    assert verdict(scene).endswith("; 0.010 ahead of the solution display against the truth")
    scene["truth"]["fitted"] = scene["truth"]["fitted"] | {"flip_mean_glossy": 0.145}
    assert verdict(scene).endswith("; level with the solution display against the truth")
    scene["truth"]["noise_flip"] = 0.065  # between the two displays' FLIP over the image: it tells them apart
    assert "noise" not in verdict(scene)
    scene["truth"]["noise_flip"] = 0.07  # above both: the truth cannot tell them apart
    assert verdict(scene).endswith("; level with the solution display against the truth, within its noise")
    scene["truth"]["noise_flip"] = None  # one sample per pixel: no halves to compare
    assert verdict_text("x", scene).splitlines()[6].split()[-1] == "n/a"


def test_a_scene_without_glossy_objects():
    scene = scene_summary()
    scene["objects"] = {}
    assert verdict(scene) == "no glossy object: the fitted display is the diffuse one"
    assert verdict_text("cornell", scene).splitlines()[0] == "cornell (no glossy object)"


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
