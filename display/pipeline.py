"""The display's one door to the earlier stages' work.

The rule: display/ reads what the earlier stages wrote (solution.npz, fit.npz) through
the radiosity stage's shared core (``radiosity.files``, ``.physics``, ``.policies``)
and ``fitting``'s public API, and imports nothing else of them;
the two pipeline commands, which run earlier stages themselves (``vlights demo``:
solve and fit; ``vlights truth``: path-trace), reach ``radiosity.scene`` and
``radiosity.transport`` through this module alone. ``tests/test_imports.py`` checks
it. (The dispatcher, ``display.cli``, imports each stage's ``cli`` to register its
commands; that is its only other contact.)

Every import of the earlier stages is inside a function: importing this module loads
neither the light transport nor numba.
"""

from __future__ import annotations

__all__ = ["check_spp", "fit_options", "load_scene", "path_trace", "scene_of", "solve"]


def load_scene(source):
    """A ``Scene`` from a scene file (TOML, OBJ, glTF, ...) or a built-in scene's name;
    InputError (one line) naming what is wrong."""
    from radiosity.scene.loaders import load_scene as load

    return load(source)


def solve(scene, quality, seed=1, progress=False):
    """The solution of ``scene`` as ``vlights solve`` makes it at ``quality`` (the mesh
    refined where the light changes)."""
    from radiosity.transport.adaptive import solve_adaptive
    from radiosity.transport.solve import SolveOptions

    return solve_adaptive(scene, SolveOptions(quality=quality, seed=seed), progress=progress)


def fit_options(quality):
    """The ``fitting.FitOptions`` ``vlights fit`` uses at ``quality`` with no other flag."""
    from fitting import FitOptions

    return FitOptions.for_quality(quality)


def scene_of(source):
    """The ``Scene`` to path-trace: ``source`` itself, or a ``Solution``'s meshes and
    materials."""
    from radiosity.files.solution import Solution
    from radiosity.transport.pathtrace import scene_of_solution

    return scene_of_solution(source) if isinstance(source, Solution) else source


def path_trace(scene, camera, runs, seed=1, threads=None, progress=False):
    """Path-trace ``camera`` of ``scene`` once per (spp, first_sample) of ``runs``: a
    ``radiosity.transport.pathtrace.PathTraced`` each (disjoint sample ranges are
    independent images)."""
    from radiosity.transport.pathtrace import PathTracer

    with PathTracer(scene, threads=threads) as tracer:
        return [tracer.render(camera, spp, seed, progress, first_sample=first) for spp, first in runs]


def check_spp(value, flag="--spp", low=1):
    """Refuse (InputError) a sample count outside ``low`` .. the path tracer's maximum."""
    from radiosity.transport.pathtrace import check_samples

    check_samples(value, flag, low)
