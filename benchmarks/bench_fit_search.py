"""Does a model searched for on a subset of a glossy object's vertices choose as the whole does?

    python benchmarks/bench_fit_search.py SOLUTION.npz [SOLUTION.npz ...] [--fractions 1 0.25 0.0625]
                                          [--quality Q] [--min-samples N] [--max-samples N]

For every glossy object of --min-samples to --max-samples samples (vertex x direction:
the whole object's search holds about 1.2 kB a sample) of each solution, fits ``--model auto`` (the quality's options: the solution's unless
--quality) with the search on the whole object and on every k-th vertex (a fraction
of its samples: ``FitOptions.search_samples``), the per-vertex coefficients always on
every vertex, and records for each the model chosen (model, probe size, lights, loss),
its relative RMS and perceptual error on every vertex, the time, and whether the
choice is that of the whole (results/fit_search.jsonl). Numba's caches are warmed on
the first object before anything is timed.
"""

from __future__ import annotations

import argparse
import sys
import time
from dataclasses import replace
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from _common import Recorder  # noqa: E402


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("solutions", nargs="+")
    parser.add_argument("--fractions", type=float, nargs="+", default=[1.0, 0.25, 1 / 16])
    parser.add_argument("--quality", default=None)
    parser.add_argument("--min-samples", type=int, default=50_000)
    parser.add_argument("--max-samples", type=int, default=6_000_000)
    args = parser.parse_args(argv)

    from fitting import FitOptions
    from fitting.fit import fit_object
    from fitting.glossy import proxy_box_of
    from fitting.mixed import SceneGeometry
    from radiosity.files.solution import SolutionFile

    record = Recorder(benchmark="fit_search")
    warm = True
    for path in args.solutions:
        with SolutionFile(path) as source:
            quality = args.quality or source.settings.get("quality", "draft")
            options = FitOptions.for_quality(quality)
            meshes = [(*source.geometry(n), source.materials[n]) for n in source.names]
            scene = SceneGeometry.of_meshes(meshes)
            box = proxy_box_of(m[0] for m in meshes)
            del meshes
            for name in source.names:
                v, d, _ = source.sizes(name)
                if d == 1 or not args.min_samples <= v * d <= args.max_samples:
                    continue
                obj, alone = source.object(name), source.alone(name)
                if warm:
                    fit_object(obj, replace(options, search_samples=v * d // 16), scene, None, alone, box)
                    warm = False
                whole = None
                for fraction in args.fractions:
                    t0 = time.perf_counter()
                    fitted = fit_object(obj, replace(options, search_samples=max(1, int(v * d * fraction))), scene,
                                        None, alone, box)
                    seconds = time.perf_counter() - t0
                    info = fitted.info
                    size = 0 if fitted.probe is None else int(fitted.probe.size)
                    choice = [info["model"], size, int(len(fitted.shininess)), info["loss"]]
                    whole = whole or choice
                    record({"solution": str(path), "quality": quality, "object": name, "vertices": v, "directions": d,
                            "fraction": fraction, "choice": choice, "same_choice": choice == whole,
                            "relative_rms": info["error"]["relative_rms"], "perceptual": info["error"]["perceptual"],
                            "seconds": round(seconds, 2)})
    record.save("fit_search.jsonl")


if __name__ == "__main__":
    main()
