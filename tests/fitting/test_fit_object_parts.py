"""The fit of a solution whose glossy objects name their own emitter parts (solution
version 5): each object's highlight draws those parts, with their visibility, and the
fit file (version 6) says which; its displays' colours equal the solution's highlights
on the grid plus the fitted rest."""

import numpy as np
import pytest
from many_lights import solved, two_plates

from display.cli import main
from fitting import load_fit


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    base = tmp_path_factory.mktemp("object-parts")
    solution = solved(two_plates(base))
    solution.save(base / "s.npz")
    assert main(["fit", str(base / "s.npz"), "-o", str(base / "f.npz"), "--model", "emitters"]) == 0
    return solution, load_fit(base / "f.npz")


def test_each_object_s_highlight_draws_its_own_parts(files):
    solution, model = files
    assert model.version == 6 and len(model.emitters) == len(solution.emitters) == 24
    for side in ("left", "right"):
        o, f = solution.object(side), model.object(side)
        assert f.highlight.indices == tuple(int(i) for i in o.emitter_parts)
        assert [p.to_dict() for p in f.highlight.parts] == [p.to_dict() for p in solution.parts_of(side)]
        assert np.array_equal(f.highlight.visibility, o.visibility)


def test_the_fitted_highlight_is_the_solution_s_on_the_grid(files):
    """Shaded at the solution's grid directions, the fit's emitter term is the
    solution's closed form of the object's own parts (``Solution.highlights``)."""
    solution, model = files
    for side in ("left", "right"):
        o, f = solution.object(side), model.object(side)
        tangents = o.tangents.astype(np.float64)
        normals = o.normals.astype(np.float64)
        local = o.directions.astype(np.float64)
        views = (local[None, :, :1] * tangents[:, None] + local[None, :, 1:2] * np.cross(normals, tangents)[:, None]
                 + local[None, :, 2:] * normals[:, None])
        views /= np.linalg.norm(views, axis=2, keepdims=True)
        drawn = f.highlight.radiance(o.positions[:, None, :], normals[:, None, :], views, side)
        assert np.allclose(drawn, solution.highlights(side), rtol=1e-6, atol=1e-9)


def test_a_file_naming_parts_it_does_not_have_is_refused_in_one_line(files, tmp_path):
    """fit.npz version 6 whose object names a part past the scene's, or one twice."""
    import json

    from radiosity.files.errors import InputError

    _, model = files
    model.save(tmp_path / "f.npz")
    with np.load(tmp_path / "f.npz") as z:
        arrays = {k: z[k] for k in z.files}
    for bad, why in (([0, 99], "distinct parts of the 24"), ([3, 3], "distinct parts of the 24")):
        damaged = dict(arrays)
        damaged["left/emitter_parts"] = np.asarray(bad + list(arrays["left/emitter_parts"][2:]), np.int32)
        np.savez(tmp_path / "bad.npz", **damaged)
        with pytest.raises(InputError, match=why) as info:
            load_fit(tmp_path / "bad.npz")
        assert "\n" not in str(info.value) and "left/emitter_parts" in str(info.value)
    assert json.loads(str(arrays["meta"]))["version"] == 6
