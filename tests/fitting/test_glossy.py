"""``--model auto`` against synthetic objects whose answer is known: a floor under
every fit (no kept model worse than the diffuse walkthrough, in the perceptual error
auto compares), lights kept where the radiance is lights, diffuse kept where it is
diffuse plus noise."""

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from fitting import FitOptions, fit
from fitting.data import fit_data, perceptual_error
from fitting.fit import fit_object
from fitting.model import directional, shade_arrays
from radiosity.files.solution import ObjectSolution, Solution
from radiosity.physics import directions
from radiosity.scene import geometry

MATERIAL = {"diffuse": [0.3, 0.3, 0.3], "specular": [0.5, 0.5, 0.5], "exponent": 40.0, "emission": [0.0, 0.0, 0.0]}
# small and quick: one probe size, two lights beside it, a short refinement
OPTIONS = FitOptions(probe_sizes=(8,), probe_lights=2, iterations=15)


def plane(n=9, size=2.0):
    """An n x n vertex square in z = 0 facing +z, two triangles a cell."""
    x, y = np.meshgrid(np.linspace(-size / 2, size / 2, n), np.linspace(-size / 2, size / 2, n))
    positions = np.stack([x.ravel(), y.ravel(), np.zeros(n * n)], axis=1)
    i = np.arange(n - 1)
    a = (i[:, None] * n + i[None, :]).ravel()
    faces = np.concatenate([np.stack([a, a + 1, a + n + 1], 1), np.stack([a, a + n + 1, a + n], 1)])
    normals = np.tile([0.0, 0.0, 1.0], (n * n, 1))
    return positions, faces, normals


def solution_of(positions, faces, normals, radiance_of, grid=8):
    """A one-object solution whose radiance is ``radiance_of(views (V, D, 3), normals,
    positions)`` (V, D, 3) on a grid x grid equal-area direction grid."""
    tangents = geometry.tangents(normals)
    local = directions.grid_directions(grid)
    bitangents = np.cross(normals, tangents)
    views = (local[None, :, :1] * tangents[:, None] + local[None, :, 1:2] * bitangents[:, None]
             + local[None, :, 2:] * normals[:, None])
    radiance = np.maximum(radiance_of(views, normals, positions), 0.0)
    obj = ObjectSolution(name="thing", positions=positions.astype(np.float32), normals=normals.astype(np.float32),
                         tangents=tangents.astype(np.float32), faces=faces.astype(np.int32),
                         directions=local.astype(np.float32), radiance=radiance.astype(np.float32), material=MATERIAL)
    return Solution(objects=(obj,), scene="synthetic")


def fitted(solution, options=OPTIONS):
    """(the fitted object's meta, the perceptual error of its tried "diffuse" row)."""
    o = fit(solution, options).objects[0]
    floor = next(t for t in o.info["tried"] if t["model"] == "diffuse")
    return o, floor


def assert_floor_holds(o, floor):
    """The kept model is no worse than the diffuse walkthrough, and every tried row
    worse than it says so."""
    assert o.info["error"]["perceptual"] <= floor["perceptual"] + 1e-5  # the row is rounded to 5 digits
    for t in o.info["tried"]:
        if abs(t["perceptual"] - floor["perceptual"]) > 1e-5:
            assert bool(t.get("above_floor")) == (t["perceptual"] > floor["perceptual"]), t


def test_the_diffuse_candidate_is_the_diffuse_walkthrough(rng):
    positions, faces, normals = plane()
    colour = rng.uniform(0.2, 1.0, (len(positions), 1, 3))
    solution = solution_of(positions, faces, normals,
                           lambda v, n, p: colour * (1 + 0.3 * v[..., 2:]) ** 2)
    o = fit(solution, FitOptions(model="diffuse")).objects[0]
    mean = np.asarray(solution.objects[0].radiance, np.float64).mean(axis=1)
    np.testing.assert_allclose(o.emitted, mean, rtol=1e-6)  # what display.renderer's diffuse display draws
    data = fit_data(solution.objects[0])
    assert o.info["error"]["perceptual"] == pytest.approx(
        perceptual_error(data, np.broadcast_to(mean[:, None], data.radiance.shape)), rel=1e-5)
    assert o.info["error"]["diffuse_only_relative_rms"] == pytest.approx(o.info["error"]["relative_rms"], rel=1e-6)


def test_diffuse_plus_noise_keeps_diffuse(rng):
    """A diffuse colour per vertex times noise of a gather's kind (heavy-tailed: a gamma
    of shape 1/2, relative standard deviation 1.4, mean 1): nothing but the colour is
    there to draw, and the noise's spikes look like highlights."""
    positions, faces, normals = plane()
    colour = rng.uniform(0.2, 1.0, (len(positions), 1, 3))
    noise = rng.gamma(0.5, 2.0, (len(positions), 64, 1))
    o, floor = fitted(solution_of(positions, faces, normals, lambda v, n, p: colour * noise))
    assert o.info["model"] == "diffuse", o.info
    assert_floor_holds(o, floor)
    np.testing.assert_allclose(o.emitted, (colour * noise).mean(axis=1), rtol=1e-5)


def test_mild_noise_keeps_diffuse(rng):
    positions, faces, normals = plane()
    colour = rng.uniform(0.2, 1.0, (len(positions), 1, 3))
    noise = 1 + 0.1 * rng.normal(size=(len(positions), 64, 1))
    o, floor = fitted(solution_of(positions, faces, normals, lambda v, n, p: colour * noise))
    assert o.info["model"] == "diffuse"
    assert_floor_holds(o, floor)


def distant_lights(rng, count=2, shininess=60.0):
    """``radiance_of`` of exactly ``count`` distant Blinn-Phong lights over an emitted
    colour, each vertex its own coefficients (the model "probe+lights" holds)."""
    dirs = np.array([[0.6, 0.2, 0.77], [-0.5, -0.4, 0.77], [0.1, -0.7, 0.71]])[:count]
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    lights = (directional(dirs), np.ones((count, 3)), np.full(count, shininess))

    def radiance_of(views, normals, positions):
        v = len(positions)
        emitted = rng.uniform(0.05, 0.15, (v, 1, 3))
        specular = rng.uniform(1.0, 3.0, (v, 1, count, 3))
        return shade_arrays(emitted, specular, normals[:, None], positions[:, None], lights, views)

    return radiance_of


def test_a_few_distant_lights_keep_lights(rng):
    positions, faces, normals = plane()
    solution = solution_of(positions, faces, normals, distant_lights(rng), grid=12)
    o, floor = fitted(solution)
    assert o.info["model"] == "lights" and o.n_lights == 2, o.info  # what the radiance is made of
    assert_floor_holds(o, floor)
    assert o.info["error"]["perceptual"] < 0.01 * floor["perceptual"]
    assert o.info["why_kept"].startswith("lights alone"), o.info["why_kept"]
    beside = fit(solution, replace(OPTIONS, model="probe+lights")).objects[0]  # lights beside a probe, asked for
    assert beside.info["model"] == "probe+lights" and beside.n_lights >= 1
    assert beside.info["error"]["perceptual"] < 0.5 * floor["perceptual"]


def noisy_highlight(rng):
    """``radiance_of`` of a diffuse colour and one distant light's highlight, both times
    a gather's heavy-tailed noise (a gamma of shape 1/2: relative standard deviation
    1.4, many samples near 0)."""
    light = distant_lights(rng, count=1)

    def radiance_of(views, normals, positions):
        shape = (len(positions), views.shape[1], 1)
        colour = rng.uniform(0.2, 1.0, (len(positions), 1, 3))
        return colour * rng.gamma(0.5, 2.0, shape) + light(views, normals, positions) * rng.gamma(0.5, 2.0, shape)

    return radiance_of


def test_lights_worse_than_diffuse_are_not_kept(rng):
    """The relative loss on such data (as --loss auto fitted every probe before): it
    weighs the near-zero samples hundreds of times the others, so every colour, probe and
    light it fits sits far below the data. The rest shows a highlight, so lights are
    fitted, and they were kept whatever their error; now they are tried, worse than
    the diffuse walkthrough, and not kept."""
    positions, faces, normals = plane()
    solution = solution_of(positions, faces, normals, noisy_highlight(rng))
    o, floor = fitted(solution, replace(OPTIONS, loss="relative"))
    lights = [t for t in o.info["tried"] if t["lights"] and t.get("kept", True)]
    assert lights and all(t.get("above_floor") for t in lights), o.info["tried"]  # tried, worse, not kept
    assert o.info["model"] == "diffuse" and o.n_lights == 0
    assert o.info["why_kept"].startswith("kept diffuse: every other model was worse"), o.info["why_kept"]
    assert_floor_holds(o, floor)


def test_auto_compares_the_losses_and_keeps_no_worse_than_diffuse(rng):
    """The same object with --loss auto: the linear loss's fits are tried beside the
    relative loss's, the kept one is no worse than the diffuse walkthrough, and it is
    far better than anything the relative loss gave."""
    positions, faces, normals = plane()
    solution = solution_of(positions, faces, normals, noisy_highlight(rng))
    o, floor = fitted(solution)
    assert {t.get("loss") for t in o.info["tried"]} == {None, "relative", "linear"}
    assert_floor_holds(o, floor)
    relative = min(t["perceptual"] for t in o.info["tried"] if t.get("loss") == "relative")
    assert o.info["error"]["perceptual"] < 0.8 * relative


def test_the_report_says_when_diffuse_was_kept_for_the_floor(rng, tmp_path):
    from fitting.cli import format_report

    positions, faces, normals = plane()
    model = fit(solution_of(positions, faces, normals, noisy_highlight(rng)), replace(OPTIONS, loss="relative"))
    model.save(tmp_path / "fit.npz")
    report = format_report(model, tmp_path / "fit.npz")
    assert "kept diffuse: every other model was worse (perceptual" in report
    assert "kept diffuse: every other model was worse than the diffuse walkthrough on 1 of 1 glossy objects (thing)" in report


LIVING_ROOM = Path(__file__).resolve().parent.parent / "data" / "living_room"


def living_room_cut(name):
    """(object of solve 1, object of solve 2, the scene's probe box) of a cut of the
    living room's solution (tests/data/living_room/README.md)."""
    d = np.load(LIVING_ROOM / f"{name}.npz")
    material = json.loads(str(d["meta"]))["material"]

    def obj(radiance):
        return ObjectSolution(name=name, positions=d["positions"], normals=d["normals"], tangents=d["tangents"],
                              faces=d["faces"], directions=d["directions"], radiance=radiance.astype(np.float32),
                              material=material)

    return obj(d["radiance"]), obj(d["radiance_seed2"]), d["box"]


@pytest.mark.parametrize("name", ["floor", "panel_back"])
def test_the_living_rooms_noisy_objects_get_a_model_nearer_an_independent_solve(name):
    """The living room's floor and a window panel's back, as the draft solve left them:
    the gather's noise is most of their radiance (two solves differing only in their
    seed differ by a relative RMS of 0.5 to 0.8). The relative loss, which every probe
    and light was fitted with, weighs their near-zero samples hundreds of times the
    others: its colour per vertex comes out nearly black (relative RMS above 0.98), its
    probes and lights far below the data.
    What "auto" keeps now is nearer the other solve (independent noise, the same
    expected radiance) than both the diffuse walkthrough and the relative loss's probe
    and lights. (Lights alone, which "auto" weighs too, fitted with the relative loss
    are nearer still on the panel: 0.60 against the kept probe's 0.66; "auto" fits them
    with the linear loss, 0.70 there, and keeps the probe.)"""
    a, b, box = living_room_cut(name)
    solution = Solution(objects=(a,), scene="living room (cut)")
    kept = fit_object(a, FitOptions.for_quality("draft"), None, None, solution, box)
    relative = fit_object(a, replace(FitOptions.for_quality("draft"), loss="relative"), None, None, solution, box)
    beside = fit_object(a, replace(FitOptions.for_quality("draft"), loss="relative", model="probe+lights"), None, None,
                        solution, box)
    da, db = fit_data(a), fit_data(b)
    noise = np.sqrt(np.sum(da.weights[..., None] * (da.radiance - db.radiance) ** 2)
                    / np.sum(da.weights[..., None] * db.radiance**2))
    assert noise > 0.5
    colour = next(t for t in relative.info["tried"] if t["model"] == "emitters")  # a colour per vertex, relative loss
    assert colour["relative_rms"] > 0.98, relative.info["tried"]  # nearly black: the relative RMS of zero is 1
    mean = np.broadcast_to(da.radiance.mean(axis=1, keepdims=True), da.radiance.shape)

    def held_out(model):
        return perceptual_error(db, model.shade(db.views))

    assert held_out(kept) < 0.9 * perceptual_error(db, mean)
    assert held_out(kept) < 0.95 * held_out(beside)
    assert kept.info["error"]["perceptual"] <= next(t for t in kept.info["tried"] if t["model"] == "diffuse")["perceptual"]


def stub(model, perceptual, floats, n_lights=0):
    """A ``glossy.Components`` of one vertex with this error and size (for ``_choose``)."""
    from fitting.glossy import Components

    lights = (np.zeros((n_lights, 4)), np.ones((n_lights, 3)), np.ones(n_lights))
    return Components(model=model, emitters=False, emitted=np.zeros((1, 3)), lights=lights,
                      specular=np.zeros((1, n_lights, 3)), probe=None, probe_weight=None, error=perceptual,
                      floats=floats, perceptual=perceptual)


def test_choose_keeps_no_model_above_the_floor_and_says_why():
    from fitting import glossy

    full = fit_data(solution_of(*plane(3), lambda v, n, p: np.ones(v.shape)).objects[0])
    floor = stub("diffuse", 0.50, 10)
    worse = [stub("probe", 0.52, 20), stub("probe+lights", 0.51, 30, n_lights=2)]
    tried = [{"model": "diffuse", "perceptual": 0.50}] + [
        {"model": f.model, "perceptual": f.perceptual, "above_floor": True} for f in worse]
    kept = glossy._choose([floor, *worse], 0.03, tried, full, floor)
    assert kept.model == "diffuse" and kept.why.startswith("kept diffuse: every other model was worse")
    # a highlight's lights, when one is no worse than the walkthrough: lights are kept, even
    # with the walkthrough within reach (it is not among the candidates of that branch)
    lights = [stub("probe+lights", 0.495, 30, n_lights=2), stub("probe+lights", 0.60, 40, n_lights=4)]
    kept = glossy._choose(lights, 0.03, tried, full, floor, reason="a highlight")
    assert kept.n_lights == 2 and kept.why.startswith("a highlight")
    # the floor turns down what would have been kept, and says which
    kept = glossy._choose([floor, stub("emitters", 0.505, 10), stub("probe", 0.40, 20)], 0.45, tried, full, floor)
    assert kept.model == "probe" and "not emitters" not in kept.why
    fits = [stub("emitters", 0.504, 5), floor, stub("probe", 0.49, 20)]
    tried = [{"model": "diffuse", "perceptual": 0.50}, {"model": "emitters", "perceptual": 0.504, "above_floor": True},
             {"model": "probe", "perceptual": 0.49}]
    kept = glossy._choose(fits, 0.03, tried, full, floor)
    assert kept.model == "diffuse"
    assert kept.why == ("the cheapest within 3% of the best (0.49); not emitters (perceptual 0.504): worse than the "
                        "diffuse walkthrough (0.5)")


def shared_lights(rng, shininess=60.0):
    """``radiance_of`` of two distant lights of different colours with one coefficient a
    vertex (the paper's model: ``--coefficients shared``) over an emitted colour."""
    dirs = np.array([[0.6, 0.2, 0.77], [-0.5, -0.4, 0.77]])
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    lights = (directional(dirs), np.array([[1.0, 0.5, 0.2], [0.2, 0.6, 1.0]]), np.full(2, shininess))

    def radiance_of(views, normals, positions):
        v = len(positions)
        emitted = rng.uniform(0.05, 0.15, (v, 1, 3))
        specular = rng.uniform(1.0, 3.0, (v, 1, 3))
        return shade_arrays(emitted, specular, normals[:, None], positions[:, None], lights, views)

    return radiance_of


@pytest.mark.parametrize("search_samples", [1 << 20, 3000])
def test_shared_coefficients_are_honoured_beside_a_probe(rng, search_samples):
    """--coefficients shared with a probe: the file holds one coefficient a vertex (V, 3),
    its meta says so, the tried rows count three floats a vertex for the lights, and the
    model draws the shared lights it was made of (found on every vertex, or on a subset
    and then solved on all)."""
    positions, faces, normals = plane()
    solution = solution_of(positions, faces, normals, shared_lights(rng), grid=12)
    options = replace(OPTIONS, model="probe+lights", coefficients="shared", search_samples=search_samples)
    o = fit(solution, options).objects[0]
    assert o.n_lights >= 1 and o.specular.shape == (len(positions), 3), o.specular.shape
    assert o.info["coefficients"] == "shared" and not o.per_light
    kept = [t for t in o.info["tried"] if t["model"] == "probe+lights" and t.get("kept", True)][-1]
    assert kept["floats"] == (3 + 3 + 3) * len(positions) + 3 * 8 * 8 + 8 * kept["lights"]
    assert o.info["error"]["relative_rms"] < 0.1, o.info["error"]
    per_light = fit(solution, replace(options, coefficients="per-light")).objects[0]
    assert per_light.specular.ndim == 3 and per_light.info["coefficients"] == "per-light"


def test_auto_weighs_lights_alone_and_keeps_them_where_they_are_the_radiance(rng):
    """Radiance that is exactly three distant lights over an emitted colour, each vertex
    its own coefficients: with --lights 3, "auto" tries lights alone beside the probe
    models, lists the row, and keeps them (fewer floats than a probe beside them, and
    an error the probe models do not reach)."""
    positions, faces, normals = plane()
    solution = solution_of(positions, faces, normals, distant_lights(rng, count=3), grid=12)
    o, floor = fitted(solution, replace(OPTIONS, lights=3, iterations=40))
    rows = {t["model"]: t for t in o.info["tried"] if t.get("kept", True)}
    assert "lights" in rows and rows["lights"]["lights"] == 3 and rows["lights"]["floats"] == 12 * len(positions) + 24
    assert o.info["model"] == "lights" and o.n_lights == 3 and o.highlight is None and o.probe is None, o.info
    assert o.info["error"]["relative_rms"] < 0.02, o.info["error"]
    assert rows["lights"]["perceptual"] < min(t["perceptual"] for t in o.info["tried"] if t["model"] != "lights")
    assert_floor_holds(o, floor)
