"""The field's interiors as users bring them: Bitterli's scenes and Mitsuba's Cornell boxes
from their own XML, unchanged (the public repository jgarciapueyo/mitsuba2-transient-scenes,
checked out at $VLIGHTS_SCENES or /work/scenes; not part of this repository). Each test
skips, saying so, where the collection or its scene has not been fetched.

Every complete scene loads; the ones whose copy lacks files are refused in one line naming
the missing file, and load once the elements naming those files are left out (as
``benchmarks/bench_interiors.py`` does); staircase, whose one object has only degenerate
triangles and whose textured plastics are shared by hundreds of shapes, loads within a
bounded memory.
"""

from __future__ import annotations

import importlib
import os
import subprocess
import sys
import warnings
from pathlib import Path

import pytest

from radiosity.files.errors import InputError, SceneWarning
from radiosity.scene.loaders import load_scene

ROOT = Path(os.environ.get("VLIGHTS_SCENES") or "/work/scenes")
BENCHMARKS = Path(__file__).resolve().parents[3] / "benchmarks"


def bench_interiors():
    """The benchmark module (its lists of scenes and its XML pruning), imported as its scripts import each other."""
    if str(BENCHMARKS) not in sys.path:
        sys.path.insert(0, str(BENCHMARKS))
    return importlib.import_module("bench_interiors")


def scene_file(name):
    path = ROOT / name / "scene.xml"
    if not path.is_file():
        pytest.skip(f"the scene collection's {name!r} is not at {path} (fetch jgarciapueyo/mitsuba2-transient-scenes "
                    "and set $VLIGHTS_SCENES)")
    return path


def loaded(path):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        scene = load_scene(path)
    return scene, [str(w.message) for w in caught if issubclass(w.category, SceneWarning)]


@pytest.mark.parametrize("name", ["cbox", "cbox-spheres", "cbox-point-light", "veach_mi", "staircase2",
                                  pytest.param("living-room", marks=pytest.mark.slow)])
def test_every_complete_scene_loads(name):
    scene, _ = loaded(scene_file(name))
    assert scene.n_triangles > 0 and scene.camera is not None
    assert scene.is_lit  # an area light, an environment or a delta light (cbox-point-light: a point light)


@pytest.mark.slow
def test_staircase_leaves_out_its_degenerate_object_and_loads_in_bounded_memory():
    path = scene_file("staircase")
    # a process of its own, so that its peak is its own: 8.4 GB when every shape copied its plastic's image
    script = ("import resource, warnings; warnings.simplefilter('ignore')\n"
              "from radiosity.scene.loaders import load_scene\n"
              f"scene = load_scene({str(path)!r})\n"
              "print(len(scene.objects), resource.getrusage(resource.RUSAGE_SELF).ru_maxrss)")
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, check=True)
    objects, peak_kb = map(int, done.stdout.split())
    assert objects > 1000
    assert peak_kb < 3 * 2**20, f"loading staircase peaked at {peak_kb / 2**20:.2f} GB"
    _, messages = loaded(path)
    left_out = [m for m in messages if "the object is left out" in m]  # 19 objects of collinear points
    assert left_out and all("are degenerate (zero area)" in m for m in left_out)
    assert any("obj_36_Mesh432" in m for m in left_out)  # the one the whole scene was once refused for


@pytest.mark.parametrize("name", ["bathroom", "bathroom2", pytest.param("kitchen", marks=pytest.mark.slow),
                                  "dining-room"])
def test_an_incomplete_copy_is_refused_naming_its_missing_files_and_the_rest_loads(name, tmp_path):
    path = scene_file(name)
    bench = bench_interiors()
    missing = bench.missing_files(path)
    if not missing:
        pytest.skip(f"this copy of {name!r} has every file it names")
    with pytest.raises(InputError) as refused, warnings.catch_warnings():
        warnings.simplefilter("ignore", SceneWarning)  # what it read before the missing file: not this test's
        load_scene(path)
    message = str(refused.value)
    assert "\n" not in message and all(m.split("/")[-1] in message for m in missing)
    pruned = path.with_name(f"scene.test-{os.getpid()}.xml")  # beside the original: its paths are relative
    try:
        assert bench.without_missing(path, set(missing), pruned) == len(missing)
        scene, _ = loaded(pruned)
    finally:
        pruned.unlink(missing_ok=True)
    assert scene.n_triangles > 0
