"""Delta lights as scenes declare them (radiosity.scene.lights): TOML's [[lights]],
their checks (one line, exit 2), what ``vlights scene-info`` says of them, a scene
lit by them alone solved without a word, the limit on emitter parts counting them,
and ``vlights truth`` of a solution seeing them."""

import json
import math
import textwrap
import warnings

import numpy as np
import pytest

from display.cli import main
from radiosity.files.errors import InputError, SceneWarning
from radiosity.scene.emitter_parts import MAX_PARTS, emitter_parts
from radiosity.scene.loaders import load_scene

PLANE = """
[materials.floor]
diffuse = 0.5
specular = 0.3
exponent = 20
[[objects]]
name = "floor"
builtin = "quad"
material = "floor"
scale = 2
"""

LIGHTS = """
[[lights]]
name = "bulb"
kind = "point"
position = [0, 1, 0]
intensity = [3, 2, 1]
[[lights]]
kind = "spot"
position = [0.5, 1.5, 0]
direction = [0, -2, 0]
intensity = 4
cutoff_deg = 30
[[lights]]
kind = "directional"
direction = [0, -1, 1]
irradiance = 0.5
"""


def write(tmp_path, text, name="scene.toml"):
    path = tmp_path / name
    path.write_text(textwrap.dedent(text))
    return path


def test_toml_lights_are_read_with_mitsubas_defaults(tmp_path):
    scene = load_scene(write(tmp_path, PLANE + LIGHTS))
    bulb, spot, sun = scene.lights
    assert (bulb.kind, bulb.source, bulb.spot) == ("point", "bulb", None)
    assert bulb.points.tolist() == [[0, 1, 0]] and bulb.radiance.tolist() == [3, 2, 1]
    assert (spot.kind, spot.source) == ("point", "spot_light_2")
    assert spot.spot.axis.tolist() == [0, -1, 0] and (spot.spot.cutoff_deg, spot.spot.beam_deg) == (30, 22.5)
    assert spot.radiance.tolist() == [4, 4, 4]
    assert (sun.kind, sun.source) == ("direction", "directional_light_3")
    assert sun.points[0] == pytest.approx([0, -math.sqrt(0.5), math.sqrt(0.5)])
    assert sun.radiance.tolist() == [0.5] * 3
    assert [o.name for o in scene.objects] == ["floor"]  # nothing to see of them
    assert load_scene(write(tmp_path, PLANE + '[[lights]]\nkind = "spot"\nposition = [0, 1, 0]\n'
                                              'direction = [0, -1, 0]\nintensity = 1\n')).lights[0].spot.cutoff_deg == 20


@pytest.mark.parametrize("light, fragment", [
    ('kind = "lamp"', "'kind' must be one of point, spot, directional, got 'lamp'"),
    ('kind = "point"\nposition = [0, 1, 0]', "a point light needs 'intensity'"),
    ('kind = "point"\nposition = [0, 1, 0]\nintensity = 1\ndirection = [0, -1, 0]', "unknown key 'direction' for a point"),
    ('kind = "point"\nposition = [0, 1]\nintensity = 1', "'position' must be 3 numbers"),
    ('kind = "point"\nposition = [0, 1, 0]\nintensity = -1', "the intensity must not be negative"),
    ('kind = "point"\nposition = [0, 1, 0]\nintensity = [1, "a", 1]', "'intensity' must be 3 numbers or a number"),
    ('kind = "spot"\nposition = [0, 1, 0]\ndirection = [0, -1, 0]\nintensity = 1\ncutoff_deg = 20\nbeam_deg = 25',
     "the beam width must be in [0, the cutoff angle 20] degrees, got 25"),
    ('kind = "spot"\nposition = [0, 1, 0]\ndirection = [0, 0, 0]\nintensity = 1', "the spot's direction must not be zero"),
    ('kind = "spot"\nposition = [0, 1, 0]\ndirection = [0, -1, 0]\nintensity = 1\ncutoff_deg = 200',
     "the cutoff angle must be in (0, 180] degrees, got 200"),
    ('kind = "directional"\ndirection = [0, -1, 0]\nirradiance = 1e39', "beyond the single-precision range"),
    ('name = "floor"\nkind = "directional"\ndirection = [0, -1, 0]\nirradiance = 1', "the name 'floor' is taken"),
    ('name = "a/b"\nkind = "directional"\ndirection = [0, -1, 0]\nirradiance = 1', "'name' must be a non-empty name"),
])
def test_bad_toml_lights_are_refused_in_one_line(tmp_path, capsys, light, fragment):
    path = write(tmp_path, PLANE + "[[lights]]\n" + light + "\n")
    with pytest.raises(InputError) as info:
        load_scene(path)
    assert fragment in str(info.value) and str(path) in str(info.value)
    code = main(["scene-info", str(path)])
    _, err = capsys.readouterr()
    assert code == 2 and err.count("\n") == 1 and err.startswith("vlights scene-info: error: ") and fragment in err


def test_scene_info_lists_the_lights_and_their_power(tmp_path, capsys):
    path = write(tmp_path, PLANE + LIGHTS)
    assert main(["scene-info", str(path)]) == 0
    out = capsys.readouterr().out
    assert "emitters (3)" in out
    assert "bulb           point light, at (0 1 0)  intensity (3 2 1 W/sr)  power (37.7 25.13 12.57)" in out
    assert "spot_light_2   spot light" in out and "cutoff 30 deg, beam 22.5 deg" in out
    assert "directional_light_3 directional light, direction (0 -0.7071 0.7071)  irradiance (0.5 0.5 0.5)" in out
    assert "nothing emits light" not in out
    assert main(["scene-info", str(path), "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    bulb, spot, sun = info["lights"]
    assert bulb["kind"] == "point" and bulb["power"] == pytest.approx(4 * np.pi * np.array([3, 2, 1]), rel=1e-5)
    assert spot["kind"] == "spot" and spot["spot"] == {"axis": [0, -1, 0], "cutoff_deg": 30.0, "beam_deg": 22.5}
    radius = 0.5 * np.linalg.norm([2, 0, 2]) * (1 + 1e-4)  # the floor's bounding sphere
    assert sun["kind"] == "directional" and sun["power"] == pytest.approx(0.5 * np.pi * radius**2 * np.ones(3), rel=1e-5)
    assert sum(e["power_fraction"] for e in info["lights"]) == pytest.approx(1, abs=1e-3)
    assert info["totals"]["emitted_power"] == pytest.approx(sum(np.array(e["power"]) for e in info["lights"]), rel=1e-5)


def test_a_scene_lit_by_a_delta_light_alone_solves_without_a_word(tmp_path, capsys):
    path = write(tmp_path, PLANE + '[[lights]]\nname = "bulb"\nkind = "point"\nposition = [0, 1, 0]\nintensity = 3\n')
    with warnings.catch_warnings():
        warnings.simplefilter("error", SceneWarning)
        code = main(["solve", str(path), "--quality", "draft", "--no-adaptive", "--photons", "20000", "--max-edge", "0.5",
                     "-o", str(tmp_path / "s.npz")])
    out, err = capsys.readouterr()
    assert code == 0, err
    assert "no emitters" not in err and "highlights 1 emitter part(s) in closed form: bulb (point)" in out
    from radiosity.files.solution import load_solution

    solution = load_solution(tmp_path / "s.npz")
    assert [p.source for p in solution.lights] == ["bulb"] and solution.object("floor").radiance.max() > 0.1


def test_delta_lights_come_first_among_the_parts_and_count_in_their_limit(tmp_path):
    """20 point lights and a lamp: every one a part (MAX_PARTS, 1024: each glossy object
    draws its brightest), the lights first; within a limit of 16, the first 16 lights,
    the lamp and the last 4 lights left to the grid (the lights' highlights still in
    closed form)."""
    def points(k):
        return "".join(f'[[lights]]\nkind = "point"\nposition = [{i * 0.1 - 1}, 1, 0]\nintensity = 1\n' for i in range(k))

    lamp = '[materials.lamp]\nemission = 5\n[[objects]]\nname = "lamp"\nbuiltin = "quad"\nmaterial = "lamp"\n' \
           'scale = 0.2\nrotate_deg = [180, 0, 0]\ntranslate = [0, 2, 0]\n'
    scene = load_scene(write(tmp_path, PLANE + lamp + points(20)))
    parts, analytic = emitter_parts(scene)
    assert MAX_PARTS == 1024 and len(parts) == 21 and analytic == ("lamp",)
    assert [p.source for p in parts[:20]] == [f"point_light_{i + 1}" for i in range(20)] and parts[20].kind == "polygon"
    parts, analytic = emitter_parts(scene, max_parts=16)
    assert len(parts) == 16 and [p.source for p in parts] == [f"point_light_{i + 1}" for i in range(16)]
    assert analytic == ()
    parts, analytic = emitter_parts(load_scene(write(tmp_path, PLANE + lamp + points(2), "few.toml")))
    assert [p.kind for p in parts] == ["point", "point", "polygon"] and analytic == ("lamp",)


@pytest.mark.slow
def test_truth_of_a_solution_sees_its_delta_lights(tmp_path, capsys):
    """``vlights truth solution.npz`` path-traces the solution's scene: its lights (meta
    'lights') light it as the scene's do; the camera sees none of them."""
    from radiosity.files.camera import Camera
    from radiosity.files.solution import load_solution
    from radiosity.transport.pathtrace import PathTracer, scene_of_solution
    from radiosity.transport.solve import SolveOptions, solve

    scene = load_scene(write(tmp_path, PLANE + LIGHTS))
    solution = solve(scene, SolveOptions(quality="draft", photons=20_000, max_edge=0.5, threads=2))
    solution.save(tmp_path / "s.npz")
    again = scene_of_solution(load_solution(tmp_path / "s.npz"))
    assert [p.to_dict() for p in again.lights] == [p.to_dict() for p in scene.lights]
    camera = Camera(eye=(0.3, 2.0, 1.5), look_at=(0, 0, 0), up=(0, 1, 0), fov_deg=50, width=16, height=12)
    images = []
    for s in (scene, again):
        with PathTracer(s, threads=2) as tracer:
            images.append(tracer.render(camera, 16, seed=2).radiance)
    assert np.abs(images[0] - images[1]).max() < 1e-4 * images[0].max() and images[0].max() > 0.05


def test_more_lights_than_a_file_holds_are_refused_in_one_line(tmp_path):
    from radiosity.physics.emitters import MAX_LIGHTS

    many = "".join(f'<emitter type="point"><point name="position" x="{i}" y="1" z="0"/></emitter>\n'
                   for i in range(MAX_LIGHTS + 1))
    path = tmp_path / "many.xml"
    path.write_text(f'<scene version="3.0.0"><shape type="rectangle"><bsdf type="diffuse"/></shape>\n{many}</scene>')
    with pytest.raises(InputError, match=f"1,025 lights; a scene has at most {MAX_LIGHTS:,}"):
        load_scene(path)
    toml = "".join(f'[[lights]]\nkind = "point"\nposition = [{i}, 1, 0]\nintensity = 1\n' for i in range(MAX_LIGHTS + 1))
    with pytest.raises(InputError, match=f"1025 lights; a scene has at most {MAX_LIGHTS}"):
        load_scene(write(tmp_path, PLANE + toml))
