"""vlights demo end to end, with the draft preset shrunk so the test is quick."""

import dataclasses
import json

import pytest

from display.cli import main
from display.export import load_export
from fitting import load_fit
from radiosity.formats import presets

pytestmark = pytest.mark.gl


def test_demo_writes_everything_and_reports(tmp_path, capsys, monkeypatch, gl_context):
    tiny = dataclasses.replace(
        presets.PRESETS["draft"], photons=30_000, gather_samples=16, light_samples=4, fit_lights=2, fit_iterations=2,
        demo_light_sweep=(1, 2), truth_spp=4,
    )
    monkeypatch.setitem(presets.PRESETS, "draft", tiny)
    out = tmp_path / "demo"
    assert main(["demo", "--out", str(out), "--size", "48x48"]) == 0
    printed = capsys.readouterr().out
    assert f"everything is in {out}" in printed and "teapot" in printed and "FLIP" in printed
    assert printed.count("Virtual lights cut the relative RMS error of the") == 1
    names = {p.name for p in out.iterdir()}
    assert {"solution.npz", "fit.npz", "summary.json", "report.md", "error_vs_lights.png", "compare", "web"} <= names
    assert load_export(out / "web" / "scene.glb").names == load_fit(out / "fit.npz").names  # the walkthrough's model
    assert (out / "web" / "index.html").exists() and f"vlights serve {out}/web" in printed
    summary = json.loads((out / "summary.json").read_text())
    assert set(summary["times_s"]) == {"solve_s", "fit_s", "truth_s", "compare_s", "sweep_s", "total_s"}
    truth = summary["truth"]  # the first view, path-traced at the preset's samples
    assert truth["spp"] == 4 and 0 < truth["noise_flip"] < 1
    for mode in ("reference", "fitted", "diffuse"):
        assert 0 < truth[mode]["flip_mean"] < 1 and 0 < truth[mode]["flip_mean_glossy"] < 1
    assert "Against a path tracer (4 spp)" in summary["verdict"] and "Against a path tracer" in printed
    assert summary["samples"] == 4 and summary["figures"]["samples"] == 4  # antialiasing, the default
    assert set(summary["objects"]) == {"tall_block", "teapot"}
    mesh = summary["mesh"]  # the draft preset refines where the light changes
    assert mesh["enabled"] and mesh["vertices_before"] < mesh["vertices_after"] <= mesh["vertex_budget"]
    assert f"{mesh['vertices_before']:,} -> {mesh['vertices_after']:,} vertices" in (out / "report.md").read_text()
    assert summary["fit_settings"]["coefficients"] == "per-light" and summary["fit_settings"]["light_kind"] == "auto"
    for o in summary["objects"].values():
        assert 1 <= o["lights"] <= 2 and 0 <= o["relative_rms"] <= o["diffuse_only_relative_rms"] * 1.5
        assert o["floats_per_vertex"] == 3 + 3 * o["lights"] and o["relative_rms"] <= o["diffuse_baseline_relative_rms"] * 1.5
    sweep = summary["error_vs_lights"]
    assert sweep["counts"] == [1, 2]
    for curves in sweep["relative_rms"].values():
        assert set(curves) == {"directional/shared", "auto/shared", "auto/per-light"}
        assert all(curve.keys() == {"1", "2"} for curve in curves.values())
    glossy = summary["figures"]["glossy_flip"]
    assert glossy["ratio"] == pytest.approx(glossy["with_virtual_lights"] / glossy["diffuse_only"])
    report = (out / "report.md").read_text()
    assert report.splitlines()[2] == f"**{summary['verdict']}**" and "lower is better" in report
    assert "## Against the truth (view 1, path-traced)" in report
    for picture in ("error_vs_lights.png", "compare/figure5_view1.png", "compare/figure6.png", "compare/figure7.png"):
        assert picture in report and (out / picture).exists()


def test_demo_without_truth(tmp_path, capsys, monkeypatch, gl_context):
    tiny = dataclasses.replace(
        presets.PRESETS["draft"], photons=20_000, gather_samples=4, light_samples=1, fit_lights=1, fit_iterations=1,
        demo_light_sweep=(1,),
    )
    monkeypatch.setitem(presets.PRESETS, "draft", tiny)
    out = tmp_path / "demo"
    assert main(["demo", "--out", str(out), "--size", "32x32", "--truth-spp", "0"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["truth"] is None and "truth_s" not in summary["times_s"]
    assert "Against a path tracer" not in capsys.readouterr().out
    assert main(["demo", "--out", str(out), "--truth-spp", "-1"]) == 2
    assert "--truth-spp must be" in capsys.readouterr().err


def test_demo_refuses_a_file_as_output_directory(tmp_path, capsys):
    path = tmp_path / "taken"
    path.write_text("x")
    assert main(["demo", "--out", str(path)]) == 2
    assert capsys.readouterr().err.count("\n") == 1
