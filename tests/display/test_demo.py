"""vlights demo end to end, with the draft preset shrunk so the test is quick."""

import dataclasses
import json

import pytest

from display.cli import main
from radiosity.formats import presets

pytestmark = pytest.mark.gl


def test_demo_writes_everything_and_reports(tmp_path, capsys, monkeypatch, gl_context):
    tiny = dataclasses.replace(
        presets.PRESETS["draft"], photons=30_000, gather_samples=16, light_samples=4, fit_iterations=2, demo_light_sweep=(1, 2)
    )
    monkeypatch.setitem(presets.PRESETS, "draft", tiny)
    out = tmp_path / "demo"
    assert main(["demo", "--out", str(out), "--size", "48x48"]) == 0
    printed = capsys.readouterr().out
    assert f"everything is in {out}" in printed and "teapot" in printed and "FLIP" in printed
    names = {p.name for p in out.iterdir()}
    assert {"solution.npz", "fit.npz", "summary.json", "report.md", "error_vs_lights.png", "compare"} <= names
    summary = json.loads((out / "summary.json").read_text())
    assert set(summary["times_s"]) == {"solve_s", "fit_s", "compare_s", "sweep_s", "total_s"}
    assert set(summary["objects"]) == {"tall_block", "teapot"}
    for o in summary["objects"].values():
        assert o["lights"] == 8 and 0 <= o["relative_rms"] <= o["diffuse_only_relative_rms"] * 1.5
    assert summary["paper_error_vs_lights"]["teapot"].keys() == {"1", "2"}
    report = (out / "report.md").read_text()
    for picture in ("error_vs_lights.png", "compare/figure5_view1.png", "compare/figure6.png", "compare/figure7.png"):
        assert picture in report and (out / picture).exists()


def test_demo_refuses_a_file_as_output_directory(tmp_path, capsys):
    path = tmp_path / "taken"
    path.write_text("x")
    assert main(["demo", "--out", str(path)]) == 2
    assert capsys.readouterr().err.count("\n") == 1
