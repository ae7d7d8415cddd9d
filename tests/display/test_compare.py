"""compare's numbers where they are undefined or infinite: a black reference is refused
in one sentence (exit 2, not FLIP's own message and exit 255); compare.json is strict
JSON, with null and a note where a number is not finite."""

import json
import subprocess
import sys

import numpy as np
import pytest
from display_fixtures import assert_refused, listing, tiny_fit, tiny_solution

from display.compare import json_text
from display.metrics import metrics
from radiosity.files.errors import InputError


def strict_json(text):
    """Parse ``text`` refusing NaN and Infinity, which json.loads accepts by default."""

    def refuse(constant):
        raise ValueError(f"{constant} is not JSON")

    return json.loads(text, parse_constant=refuse)


def test_json_text_is_strict_and_says_why():
    results = {"figure7": {"same": {"psnr_db": float("inf"), "flip_mean": 0.0}}, "x": [np.float32(np.nan), 1.5]}
    parsed = strict_json(json_text(results))
    assert parsed["figure7"]["same"] == {"psnr_db": None, "flip_mean": 0.0} and parsed["x"] == [None, 1.5]
    assert parsed["notes"] == [
        "figure7.same.psnr_db is null: the two pictures are identical, so the PSNR is infinite",
        "x[0] is null: the value is nan, not a finite number",
    ]
    assert "notes" not in strict_json(json_text({"a": 1.0}))


def test_metrics_refuse_a_black_reference_before_flip(monkeypatch):
    import flip_evaluator

    def flip(*_args, **_kwargs):
        raise AssertionError("FLIP was called: on a black reference it ends the process")

    monkeypatch.setattr(flip_evaluator, "evaluate", flip)
    black = np.zeros((8, 8, 3), np.float32)
    with pytest.raises(InputError, match="reference image is black, so errors relative to it .* are undefined"):
        metrics(black, black + 1)


def run_isolated(code):
    """Run ``code`` in a new interpreter: FLIP ends the process on inputs it cannot take."""
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)


def test_a_dim_reference_is_measured_like_a_bright_one():
    # FLIP's exposure range breaks down for radiance around 1e-8 (scene units are the
    # user's): metrics scale both pictures so that the reference peaks at 1
    run = run_isolated(
        "import numpy as np\n"
        "from display.metrics import metrics\n"
        "rng = np.random.default_rng(3)\n"
        "ref = rng.uniform(0, 2, (24, 24, 3)).astype(np.float32)\n"
        "test = (ref * rng.uniform(0.7, 1.3, ref.shape)).astype(np.float32)\n"
        "bright, _ = metrics(ref, test)\n"
        "dim, _ = metrics(ref * np.float32(1e-9), test * np.float32(1e-9))\n"
        "print(bright['flip_mean'], dim['flip_mean'])\n"
    )
    assert run.returncode == 0, run.stderr
    bright, dim = map(float, run.stdout.split())
    assert bright > 0.01 and dim == pytest.approx(bright, rel=1e-3)


@pytest.mark.gl
@pytest.mark.subprocess
def test_compare_of_a_scene_with_no_light_says_the_reference_is_black(black_pair, tmp_path, gl_context):
    # a separate process: the exit status is the point (FLIP's own failure exits 255)
    fit, solution = black_pair
    run = subprocess.run([sys.executable, "-m", "display", "compare", str(fit), str(solution), "--size", "16x12",
                          "--out", str(tmp_path / "cmp")], capture_output=True, text=True, timeout=120)
    assert_refused((run.returncode, run.stdout, run.stderr), "reference image", "is black",
                   "relative to it (FLIP, relative MSE) are undefined", command="compare")
    assert listing(tmp_path) == []


@pytest.mark.gl
def test_identical_pictures_give_null_psnr_with_a_note(flat_pair, tmp_path, cli, gl_context):
    fit, solution = flat_pair
    code, out, err = cli("compare", fit, solution, "--size", "16x12", "--out", tmp_path / "cmp")
    assert code == 0, err
    results = strict_json((tmp_path / "cmp" / "compare.json").read_text())
    assert results["figure5"]["view1"]["psnr_db"] is None
    assert "figure5.view1.psnr_db is null: the two pictures are identical, so the PSNR is infinite" in results["notes"]
    assert "PSNR inf" in out and "null" in out


@pytest.mark.gl
def test_a_fit_with_no_light_of_its_own_compares(tmp_path, cli, gl_context):
    # all-zero emitted and no virtual lights: the fitted pictures are black, the reference is not
    from fitting import FittedModel, FittedObject

    solution = tiny_solution()
    lit = tiny_fit(solution, lights=0)
    dark = FittedModel(objects=tuple(
        FittedObject(name=o.name, positions=o.positions, normals=o.normals, faces=o.faces,
                     emitted=np.zeros_like(o.emitted), specular=o.specular, light_pos=o.light_pos,
                     light_rgb=o.light_rgb, shininess=o.shininess)
        for o in lit.objects))
    solution.save(tmp_path / "solution.npz")
    dark.save(tmp_path / "fit.npz")
    code, _, err = cli("compare", tmp_path / "fit.npz", tmp_path / "solution.npz", "--size", "16x12",
                       "--out", tmp_path / "cmp")
    assert code == 0, err
    results = strict_json((tmp_path / "cmp" / "compare.json").read_text())
    numbers = results["figure5"]["view1"]  # the fitted display, black, against the reference
    assert numbers["flip_mean"] > 0.1 and numbers["psnr_db"] > 0 and numbers["relative_mse"] > 0.1
    # figure 7's diffuse walkthrough is the solution's own mean: close to the reference
    assert results["figure7"]["diffuse_only"]["flip_mean"] < numbers["flip_mean"]
