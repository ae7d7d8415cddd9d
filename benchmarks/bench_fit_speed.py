"""How long does fitting the demo teapot take, against its targets?

    python benchmarks/bench_fit_speed.py [--solution S.npz] [--repeats 3]

Solves the demo scene at draft with seed 5 (unless --solution is given), warms numba's
caches on a small fit, then times ``fitting.fit.fit_object`` on the teapot for the
default model (8 lights, auto kinds, per-light coefficients, the preset's iterations),
the paper's method and the shared-coefficient model, ``--repeats`` times each, and
records the median with every run, the error reached, V, D and the core count
(results/fit_speed.jsonl). Targets on 2 cores: default <= 10 s at draft, paper <= 5 s.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from _common import Recorder  # noqa: E402


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--solution", help="a solution.npz (default: solve the demo scene, draft, seed 5)")
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args(argv)

    from fitting import FitOptions
    from fitting.data import fit_data
    from fitting.fit import fit_object
    from fitting.mixed import SceneGeometry
    from radiosity.files.solution import load_solution
    from radiosity.policies.presets import preset

    if args.solution is None:
        from radiosity.scene.loaders import load_scene
        from radiosity.transport.solve import SolveOptions, solve

        path = Path(tempfile.mkdtemp()) / "solution.npz"
        solve(load_scene("cornell-teapot"), SolveOptions(quality="draft", seed=5)).save(path)
        args.solution = path
    solution = load_solution(args.solution)
    quality = solution.settings.get("quality", "draft")
    knobs = preset(quality)
    scene = SceneGeometry.of_solution(solution)
    teapot = solution.object("teapot")
    data = fit_data(teapot)
    fit_object(solution.object("tall_block"), FitOptions(lights=2, iterations=2), scene)  # numba caches
    record = Recorder(benchmark="fit_speed", quality=quality, vertices=data.n_vertices, directions=data.n_directions)
    models = {
        "default (auto kinds, per-light coefficients)": FitOptions(lights=knobs.fit_lights, iterations=knobs.fit_iterations),
        "paper's method": FitOptions(lights=knobs.fit_lights, method="paper"),
        "auto kinds, shared coefficients": FitOptions(lights=knobs.fit_lights, iterations=knobs.fit_iterations,
                                                      coefficients="shared"),
    }
    for label, options in models.items():
        times = []
        for _ in range(args.repeats):
            t0 = time.perf_counter()
            fitted = fit_object(teapot, options, scene)
            times.append(time.perf_counter() - t0)
        record({"model": label, "lights": knobs.fit_lights, "median_s": round(statistics.median(times), 3),
                "runs_s": [round(t, 3) for t in times], "relative_rms": fitted.info["error"]["relative_rms"]})
    record.save("fit_speed.jsonl")


if __name__ == "__main__":
    main()
