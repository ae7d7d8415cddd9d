"""Does a glossy object of 10^8 radiance samples fit within 4 GB?

    python benchmarks/bench_fit_memory.py [--samples 100000000] [--grid 64] [--solution S.npz ...]
                                          [--keep DIR]

Writes a solution of one glossy object, a square plate of about ``--samples`` / D
vertices on a ``--grid`` x ``--grid`` direction grid (D = 4,096: 24,649 vertices for
10^8 samples, 1.2 GB of float32 radiance), whose radiance is a dim diffuse colour, a
sharp highlight and a broad one (two distant Phong lights, their strength varying
over the plate), and fits it with ``vlights fit`` (its quality's defaults), in a
process of its own: the wall time and the peak resident memory of its process tree
(results/fit_memory.jsonl; the target: 4 GB). ``--solution`` fits those files too (the
Veach scene solved at medium with ``--max-edge 0.25 --adaptive``, for one).
"""

from __future__ import annotations

import argparse
import math
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from _common import Recorder, git_commit, run_vlights  # noqa: E402

TARGET_GB = 4.0
LIGHTS = (((0.3, 0.2, 1.0), 400.0, 3.0), ((-0.6, 0.1, 0.8), 20.0, 0.4))  # (direction, exponent, strength)
MATERIAL = {"diffuse": [0.2, 0.2, 0.2], "specular": [0.6, 0.6, 0.6], "exponent": 400.0, "emission": [0.0, 0.0, 0.0]}


def plate_solution(path, samples, grid):
    """A one-plate ``Solution`` of about ``samples`` samples, saved to ``path``."""
    from radiosity.files.solution import ObjectSolution, Solution
    from radiosity.physics.directions import grid_directions

    local = grid_directions(grid).astype(np.float32)
    n = max(2, math.ceil(math.sqrt(samples / len(local))))
    u = np.linspace(0.0, 4.0, n, dtype=np.float32)
    x, y = np.meshgrid(u, u, indexing="ij")
    positions = np.stack([x.ravel(), y.ravel(), np.zeros(n * n, np.float32)], axis=1)
    i = np.arange(n - 1)
    a = (i[:, None] * n + i[None, :]).ravel()
    faces = np.concatenate([np.stack([a, a + n, a + 1], 1), np.stack([a + 1, a + n, a + n + 1], 1)]).astype(np.int32)
    # the plate's frame is the world's: local directions are world directions
    radiance = np.empty((n * n, len(local), 3), np.float32)
    vary = 0.5 + 0.5 * np.sin(positions[:, 0:1]) * np.cos(positions[:, 1:2])
    for start in range(0, n * n, 4096):
        sl = slice(start, start + 4096)
        colour = np.float32(0.05) + np.zeros((len(vary[sl]), len(local), 3), np.float32)
        for direction, exponent, strength in LIGHTS:
            light = np.asarray(direction, np.float32) / np.linalg.norm(direction)
            half = local + light
            half /= np.linalg.norm(half, axis=1, keepdims=True)
            lobe = np.maximum(half[:, 2], 0.0) ** np.float32(exponent)
            colour += strength * vary[sl, :, None] * lobe[None, :, None]
        radiance[sl] = colour
    obj = ObjectSolution(name="plate", positions=positions, normals=np.tile(np.float32([0, 0, 1]), (n * n, 1)),
                         tangents=np.tile(np.float32([1, 0, 0]), (n * n, 1)), faces=faces, directions=local,
                         radiance=radiance, material=MATERIAL)
    Solution(objects=(obj,), settings={"quality": "draft"}, scene="bench_fit_memory").save(path)
    return n * n, len(local)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--samples", type=float, default=1e8)
    parser.add_argument("--grid", type=int, default=64)
    parser.add_argument("--solution", nargs="*", default=[], help="other solution files to fit")
    parser.add_argument("--keep", type=Path, help="keep the files in this directory")
    args = parser.parse_args(argv)

    work = args.keep or Path(tempfile.mkdtemp(prefix="vlights-fit-memory-"))
    work.mkdir(parents=True, exist_ok=True)
    record = Recorder(benchmark="fit_memory", commit=git_commit())
    cases = []
    if args.samples > 0:
        path = work / "plate.npz"
        v, d = plate_solution(path, int(args.samples), args.grid)
        cases.append((path, f"plate {v:,} x {d:,}"))
    cases += [(Path(p).resolve(), Path(p).name) for p in args.solution]
    for path, name in cases:
        r = run_vlights(["fit", path, "-o", work / (path.stem + ".fit.npz")], work)
        if r.exit_code:
            sys.exit(f"{name}: fit failed ({r.exit_code}): {r.last_line}")
        peak_gb = max(r.peak_mb, r.tree_mb) / 1024
        record({"case": name, "seconds": round(r.seconds, 1), "peak_mb": round(r.peak_mb), "tree_mb": round(r.tree_mb),
                "peak_gb": round(peak_gb, 2), "target_gb": TARGET_GB, "within": peak_gb <= TARGET_GB})
    record.save("fit_memory.jsonl")


if __name__ == "__main__":
    main()
