"""vlights demo end to end, with the draft preset shrunk so the test is quick."""

import dataclasses
import json
import re

import pytest

from display.cli import main
from display.demo import verdict, verdict_markdown, verdict_text
from display.export_reader import load_export
from fitting import load_fit
from radiosity.policies import presets

pytestmark = pytest.mark.gl


def test_demo_writes_everything_and_reports(tmp_path, capsys, monkeypatch, gl_context):
    tiny = dataclasses.replace(
        presets.PRESETS["draft"], photons=30_000, gather_samples=16, light_samples=4, fit_lights=2, fit_iterations=2,
        truth_spp=4, probe_sizes=(4,), probe_lights=1, visibility_samples=4,
    )
    monkeypatch.setitem(presets.PRESETS, "draft", tiny)
    out = tmp_path / "demo"
    assert main(["demo", "--out", str(out), "--size", "48x48"]) == 0
    printed = capsys.readouterr().out
    assert f"everything is in {out}" in printed and "teapot" in printed and "plate_mirror" in printed
    names = {p.name for p in out.iterdir()}
    assert {"summary.json", "report.md", "models.png", "cornell-teapot", "plates"} <= names
    summary = json.loads((out / "summary.json").read_text())
    assert set(summary["scenes"]) == {"cornell-teapot", "plates"}
    for scene, s in summary["scenes"].items():
        here = out / scene
        assert {"solution.npz", "fit.npz", "compare", "web"} <= {p.name for p in here.iterdir()}
        assert load_export(here / "web" / "scene.glb").names == load_fit(here / "fit.npz").names  # the walkthrough's model
        assert f"vlights serve {out}/{scene}/web" in printed
        assert set(s["times_s"]) == {"solve_s", "fit_s", "truth_s", "compare_s", "total_s"}
        truth = s["truth"]  # the first view, path-traced at the preset's samples
        assert truth["spp"] == 4 and 0 < truth["noise_flip"] < 1
        for mode in ("reference", "fitted", "diffuse"):
            assert 0 < truth[mode]["flip_mean"] < 1 and 0 < truth[mode]["flip_mean_glossy"] < 1
        assert s["emitter_parts"] >= 1
        for o in s["objects"].values():
            assert o["model"] in ("diffuse", "emitters", "probe", "probe+lights") and o["tried"]
            assert 0 <= o["relative_rms"] and o["floats_per_vertex"] >= 3
        glossy = s["figures"]["glossy_flip"]
        assert glossy["ratio"] == pytest.approx(glossy["with_virtual_lights"] / glossy["diffuse_only"])
    assert set(summary["scenes"]["cornell-teapot"]["objects"]) == {"tall_block", "teapot"}
    assert set(summary["scenes"]["plates"]["objects"]) == {"plate_mirror", "plate_polished", "plate_glossy", "plate_rough"}
    mesh = summary["scenes"]["cornell-teapot"]["mesh"]  # the draft preset refines where the light changes
    assert mesh["enabled"] and mesh["vertices_before"] < mesh["vertices_after"] <= mesh["vertex_budget"]
    report = (out / "report.md").read_text()
    assert report.splitlines()[2] == "## Verdict" and "lower is better" in report
    for scene, s in summary["scenes"].items():  # a table per scene, the same in the terminal and the report
        assert verdict_text(scene, s) in printed and "\n".join(verdict_markdown(scene, s)) in report
        assert f"{scene}: {verdict(s)}." in summary["verdict"]
        assert re.search(r"(behind|ahead of|level with) the solution display against the truth", verdict(s))
    assert printed.count("noise floor (4 spp)") == 2
    assert f"{mesh['vertices_before']:,} -> {mesh['vertices_after']:,} vertices" in report
    assert "Against the truth (view 1" in report
    for picture in ("models.png", "cornell-teapot/compare/figure5_view1.png", "plates/compare/figure7.png"):
        assert picture in report and (out / picture).exists()


def test_demo_without_truth(tmp_path, capsys, monkeypatch, gl_context):
    tiny = dataclasses.replace(
        presets.PRESETS["draft"], photons=20_000, gather_samples=4, light_samples=1, fit_lights=1, fit_iterations=1,
        probe_sizes=(4,), probe_lights=1, visibility_samples=2,
    )
    monkeypatch.setitem(presets.PRESETS, "draft", tiny)
    out = tmp_path / "demo"
    assert main(["demo", "--out", str(out), "--size", "32x32", "--truth-spp", "0"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    for s in summary["scenes"].values():
        assert s["truth"] is None and "truth_s" not in s["times_s"]
    printed = capsys.readouterr().out
    assert "noise floor" not in printed and printed.count("verdict: the fit") == 2
    assert main(["demo", "--out", str(out), "--truth-spp", "-1"]) == 2
    assert "--truth-spp must be" in capsys.readouterr().err


def test_demo_refuses_a_file_as_output_directory(tmp_path, capsys):
    path = tmp_path / "taken"
    path.write_text("x")
    assert main(["demo", "--out", str(path)]) == 2
    assert capsys.readouterr().err.count("\n") == 1
