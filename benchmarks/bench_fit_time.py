"""Does the fit take no longer than the solve of the same scene at the same quality?

    python benchmarks/bench_fit_time.py [--cases teapot-draft teapot-medium ...] [--repeats 3]
                                        [--scenes DIR] [--keep DIR]

Each case is solved and then fitted as the commands a user types (``vlights solve``,
``vlights fit`` with no flag but the output: the quality the solve recorded), each in a
process of its own, timed (wall clock) with its peak resident memory (the kernel's
rusage of the process, its workers' included in ``tree_mb``). Solve and fit alternate,
``--repeats`` times, so that both see the same machine; the medians and their ratio
are recorded (results/fit_time.jsonl), with every run. A solve and a fit of the small
teapot scene first load or compile numba's kernels (not timed).

Cases (``CASES``): the demo scene at draft, medium and high; the plates scene at
draft; the million-triangle interior of ``bench_scale.py`` at draft; Bitterli's living
room at draft (``--scenes``: a directory holding ``living-room/scene.xml``, as
``bench_interiors.py`` reads it; the case is skipped, saying so, where it is missing).
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from _common import Recorder, git_commit, run_vlights  # noqa: E402

# name -> (scene: a built-in name, "interior:TRIANGLES" or "xml:NAME", solve flags)
CASES = {
    "teapot-draft": ("cornell-teapot", ["--quality", "draft"]),
    "teapot-medium": ("cornell-teapot", ["--quality", "medium"]),
    "teapot-high": ("cornell-teapot", ["--quality", "high"]),
    "plates-draft": ("plates", ["--quality", "draft"]),
    "interior-1e6-draft": ("interior:1000000", ["--quality", "draft"]),
    "living-room-draft": ("xml:living-room", ["--quality", "draft"]),
}


def scene_path(scene, work, scenes):
    """What ``vlights solve`` reads for ``scene`` (None: not on this machine)."""
    kind, _, name = scene.partition(":")
    if kind == "interior":
        from bench_scale import write_scene

        path = work / f"interior_{name}.toml"
        if not path.exists():
            write_scene(path, int(name))
        return path
    if kind == "xml":
        path = Path(scenes) / name / "scene.xml"
        return path if path.exists() else None
    return scene


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", nargs="+", default=list(CASES), choices=list(CASES))
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--scenes", default="/work/scenes", help="Bitterli's scenes (see bench_interiors.py)")
    parser.add_argument("--keep", type=Path, help="keep the solutions and fits in this directory")
    args = parser.parse_args(argv)

    work = args.keep or Path(tempfile.mkdtemp(prefix="vlights-fit-time-"))
    work.mkdir(parents=True, exist_ok=True)
    record = Recorder(benchmark="fit_time", commit=git_commit())
    warm = [run_vlights(["solve", "cornell-teapot", "-o", "warm.npz", "--seed", "5"], work),
            run_vlights(["fit", "warm.npz", "-o", "warm.fit.npz"], work)]
    if any(r.exit_code for r in warm):
        sys.exit("the warm-up failed:\n" + "".join(r.stderr for r in warm))
    for case in args.cases:
        scene, flags = CASES[case]
        source = scene_path(scene, work, args.scenes)
        if source is None:
            print(f"{case}: skipped, {scene} is not under {args.scenes}", file=sys.stderr)
            continue
        solution, fitted = work / f"{case}.npz", work / f"{case}.fit.npz"
        runs = []
        for i in range(args.repeats):
            solve = run_vlights(["solve", source, "-o", solution, "--seed", "5", *flags], work)
            fit = run_vlights(["fit", solution, "-o", fitted], work)
            for step, r in (("solve", solve), ("fit", fit)):
                if r.exit_code:
                    sys.exit(f"{case}: {step} failed ({r.exit_code}):\n{r.stderr[-2000:]}")
            runs.append({"solve_s": round(solve.seconds, 2), "fit_s": round(fit.seconds, 2),
                         "solve_mb": round(solve.peak_mb), "fit_mb": round(fit.peak_mb),
                         "fit_tree_mb": round(fit.tree_mb), "ratio": round(fit.seconds / solve.seconds, 3)})
            print(f"{case} run {i + 1}: {runs[-1]}", file=sys.stderr, flush=True)
        solve_s = statistics.median(r["solve_s"] for r in runs)
        fit_s = statistics.median(r["fit_s"] for r in runs)
        record({"case": case, "scene": scene, "flags": flags, "solve_s": solve_s, "fit_s": fit_s,
                "ratio_medians": round(fit_s / solve_s, 3), "ratio_per_run": [r["ratio"] for r in runs],
                "fit_peak_mb": max(r["fit_mb"] for r in runs), "fit_tree_mb": max(r["fit_tree_mb"] for r in runs),
                "runs": runs, "target": "fit <= solve"})
    record.save("fit_time.jsonl")


if __name__ == "__main__":
    main()
