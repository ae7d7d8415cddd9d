"""How fast is the path tracer, against Embree itself, and how fast does it converge?

Usage:
    python benchmarks/bench_pathtrace.py [--scene cornell-teapot] [--size 256] [--repeats 3] [--quick]
                                         [--parts speed,convergence]

Measures, in one run, with the same thread count throughout:
  1. the limit: the fastest this machine traces incoherent rays (origins on the
     surfaces, directions over the hemisphere) through Embree on all cores, jitted
     loops of single-ray queries (a nogil loop per thread, or numba prange, whichever
     is faster: ``_common.Limit``, the same limit ``bench_solver`` uses); and the
     occlusion rays per second of the same rays cut just short of their hit (an
     unoccluded shadow ray's whole segment);
  2. the path tracer on the scene's camera: rays per second (camera, bounce and shadow
     rays / wall time, every kernel included) as a ratio to (1)'s limit; paths per
     second. Its rays are cheaper than (1)'s (one in five is a coherent camera ray,
     the shadow rays aim at one lamp and stop at it), so the ratio flatters it a
     little. Repeats are interleaved (limit, tracer, limit, tracer, ...) and medians
     reported;
  3. convergence: FLIP (HDR) and relative MSE against a long render (``--reference-spp``,
     another seed) after each progressive pass, against wall time; the time to reach
     FLIP 0.2, 0.1 and 0.05.
Results: JSON lines in benchmarks/results/pathtrace.jsonl, a plot in results/pathtrace.png.
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np
from _common import RESULTS, Limit, Recorder


def occlusion_rate(limit):
    """Occlusion rays per second of the limit's rays, cut just short of their hits."""
    tracer = limit.tracer
    hits = tracer.intersect(limit.origins, limit.directions)
    hit = hits.triangle >= 0
    t = time.perf_counter()
    tracer.occluded(limit.origins[hit], limit.directions[hit], hits.t[hit] * np.float32(0.999))
    return int(hit.sum()) / (time.perf_counter() - t)


FLIP_TARGETS = (0.2, 0.1, 0.05)
TARGET_RATIO = 0.7  # the path tracer's rays/s as a fraction of the limit


def speed(record, scene, tracer, camera, threads, args):
    limit = Limit(scene, 1 << 20, threads)
    limits, occlusion, rays, paths, ratios = [], [], [], [], []
    try:
        for _ in range(args.repeats):
            rates = limit.rates()
            limits.append(rates["limit"])
            occlusion.append(occlusion_rate(limit))
            stats = tracer.render(camera, args.spp, seed=7).stats
            rays.append(stats["rays_per_s"])
            paths.append(stats["paths_per_s"])
            ratios.append(rays[-1] / limits[-1])
            record({"what": "repeat", "limit_rays_per_s": limits[-1], "limit_threads_rays_per_s": rates["threads"],
                    "limit_prange_rays_per_s": rates["prange"], "occlusion_rays_per_s": occlusion[-1],
                    "rays_per_s": rays[-1], "paths_per_s": paths[-1], "rays_per_path": stats["rays"] / stats["paths"],
                    "shadow_rays_per_path": stats["shadow_rays"] / stats["paths"]})
    finally:
        limit.close()
    ratio = float(np.median(rays)) / float(np.median(limits))
    record({"what": "speed", "size": args.size, "spp": args.spp,
            "limit_rays_per_s": float(np.median(limits)), "occlusion_rays_per_s": float(np.median(occlusion)),
            "rays_per_s": float(np.median(rays)), "paths_per_s": float(np.median(paths)),
            "ratio_to_limit": ratio, "ratio_median_of_repeats": float(np.median(ratios)),
            "target_ratio": TARGET_RATIO, "meets_target": ratio >= TARGET_RATIO})


def convergence(tracer, camera, reference, spp, seed):
    """[(spp, seconds, flip, relative MSE)] after each progressive pass."""
    from display.metrics import metrics

    rows = []

    def seen(done, image):  # the tracer's seconds leave out the time spent here
        numbers, _ = metrics(reference, image.radiance)
        rows.append((done, image.stats["seconds"], numbers["flip_mean"], numbers["relative_mse"]))

    tracer.render(camera, spp, seed=seed, callback=seen)
    return rows


def time_to(rows, target):
    for spp, seconds, flip, _ in rows:
        if flip <= target:
            return spp, seconds
    return None, None


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--scene", default="cornell-teapot")
    parser.add_argument("--size", type=int, default=256)
    parser.add_argument("--spp", type=int, default=32, help="samples per pixel of each timed render")
    parser.add_argument("--reference-spp", type=int, default=4096)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--quick", action="store_true", help="small sizes, for a smoke run")
    parser.add_argument("--parts", default="speed,convergence", help="which measurements, comma-separated")
    args = parser.parse_args()
    parts = set(args.parts.split(","))
    if args.quick:
        args.size, args.spp, args.reference_spp, args.repeats = 64, 8, 256, 1

    from radiosity.scene.loaders import load_scene
    from radiosity.transport.embree import default_threads
    from radiosity.transport.pathtrace import PathTracer

    threads = default_threads()
    record = Recorder(benchmark="pathtrace", scene=args.scene, threads=threads, cores=os.cpu_count())
    scene = load_scene(args.scene)
    camera = scene.camera.sized(args.size, args.size)
    with PathTracer(scene, threads=threads) as tracer:
        t = time.perf_counter()
        tracer.render(camera.sized(8, 8), 1)
        record({"what": "first render (numba compile or cache load)", "seconds": time.perf_counter() - t})
        if "speed" in parts:
            speed(record, scene, tracer, camera, threads, args)
        if "convergence" not in parts:
            record.save("pathtrace.jsonl")
            return
        t = time.perf_counter()
        reference = tracer.render(camera, args.reference_spp, seed=1, progress=True).radiance
        record({"what": "reference", "spp": args.reference_spp, "seconds": time.perf_counter() - t})
        rows = convergence(tracer, camera, reference, args.reference_spp // 4, seed=2)
        for spp, seconds, flip, rel in rows:
            record({"what": "convergence", "spp": spp, "seconds": seconds, "flip": flip, "relative_mse": rel})
        for target in FLIP_TARGETS:
            spp, seconds = time_to(rows, target)
            record({"what": "time to FLIP", "flip": target, "spp": spp, "seconds": seconds})
    record.save("pathtrace.jsonl")
    plot(rows, args)


def plot(rows, args):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    spp, seconds, flip, rel = (np.array(c) for c in zip(*rows))
    fig, ax = plt.subplots(1, 2, figsize=(10, 4))
    ax[0].loglog(seconds, flip, "o-", label="path tracer")
    for target in FLIP_TARGETS:
        ax[0].axhline(target, color="grey", lw=0.5, ls="--")
    ax[0].set_xlabel("wall time (s)")
    ax[0].set_ylabel(f"FLIP against {args.reference_spp} spp")
    ax[0].set_title(f"{args.scene}, {args.size}x{args.size}")
    ax[1].loglog(spp, rel, "o-")
    ax[1].loglog(spp, rel[0] * spp[0] / spp, "k:", label="1 / spp")
    ax[1].set_xlabel("samples per pixel")
    ax[1].set_ylabel("relative MSE")
    ax[1].legend()
    fig.tight_layout()
    RESULTS.mkdir(exist_ok=True)
    fig.savefig(RESULTS / "pathtrace.png", dpi=100)


if __name__ == "__main__":
    main()
