"""How fast is the path tracer, against Embree itself, and how fast does it converge?

Usage:
    python benchmarks/bench_pathtrace.py [--scene cornell-teapot] [--size 256] [--repeats 3] [--quick]

Measures, in one run, with the same thread count throughout:
  1. bare Embree: closest-hit rays per second of incoherent rays (origins on the
     surfaces, directions over the hemisphere) through the same ``RayTracer`` with a
     thread per core, and occlusion rays per second of the same rays cut just short of
     their hit (an unoccluded shadow ray's whole segment);
  2. the path tracer on the scene's camera: rays per second (camera, bounce and shadow
     rays / wall time, every kernel included) as a ratio to (1)'s closest-hit rate;
     paths per second; and, measured directly, the share of the worker threads' time
     spent inside Embree's calls (the rest is the numba kernels, Python between
     wavefronts and the arrays: what jitted tracing loops would save). Its rays are
     cheaper than (1)'s (one in five is a coherent camera ray, the shadow rays aim at
     one lamp), so the ratio to (1) flatters it; the share does not. Repeats are
     interleaved (bare, tracer, bare, tracer, ...) and medians reported;
  3. convergence: FLIP (HDR) and relative MSE against a long render (``--reference-spp``,
     another seed) after each progressive pass, against wall time; the time to reach
     FLIP 0.2, 0.1 and 0.05.
Results: JSON lines in benchmarks/results/pathtrace.jsonl, a plot in results/pathtrace.png.
"""

from __future__ import annotations

import argparse
import os
import threading
import time

import numpy as np
from _common import RESULTS, Recorder, incoherent_rays


def bare_embree_rates(scene, threads, n_rays):
    """(closest-hit, occlusion) rays per second of the same incoherent rays."""
    from radiosity.transport.embree import RayTracer

    merged = scene.merged()
    with RayTracer(merged.positions, merged.faces, threads=threads) as tracer:
        origins, d = incoherent_rays(merged, n_rays, tracer.epsilon)
        t = time.perf_counter()
        hits = tracer.intersect(origins, d)
        closest = n_rays / (time.perf_counter() - t)
        hit = hits.triangle >= 0
        t = time.perf_counter()
        tracer.occluded(origins[hit], d[hit], hits.t[hit] * np.float32(0.999))
        occlusion = int(hit.sum()) / (time.perf_counter() - t)
    return closest, occlusion


FLIP_TARGETS = (0.2, 0.1, 0.05)


def timed_queries(tracer):
    """Wrap ``tracer``'s queries so that their wall time, summed over threads,
    accumulates in the returned one-element list."""
    spent, lock = [0.0], threading.Lock()
    for name in ("intersect", "occluded"):
        query = getattr(tracer, name)

        def timed(*args, query=query):
            start = time.perf_counter()
            try:
                return query(*args)
            finally:
                with lock:
                    spent[0] += time.perf_counter() - start

        setattr(tracer, name, timed)
    return spent


def convergence(tracer, camera, reference, spp, seed):
    """[(spp, seconds, flip, relative MSE)] after each progressive pass."""
    from display.compare import metrics

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
    args = parser.parse_args()
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
        bare, occlusion, rays, paths, shares = [], [], [], [], []
        in_embree = timed_queries(tracer.tracer)
        for _ in range(args.repeats):
            closest, occluded = bare_embree_rates(scene, threads, 1 << 20)
            bare.append(closest)
            occlusion.append(occluded)
            in_embree[0] = 0.0
            stats = tracer.render(camera, args.spp, seed=7).stats
            rays.append(stats["rays_per_s"])
            paths.append(stats["paths_per_s"])
            shares.append(in_embree[0] / (threads * stats["seconds"]))
            record({"what": "repeat", "bare_rays_per_s": closest, "bare_occlusion_rays_per_s": occluded,
                    "rays_per_s": rays[-1], "paths_per_s": paths[-1], "rays_per_path": stats["rays"] / stats["paths"],
                    "shadow_rays_per_path": stats["shadow_rays"] / stats["paths"], "embree_share": shares[-1]})
        ratio = float(np.median(np.divide(rays, bare)))
        record({"what": "speed", "size": args.size, "spp": args.spp,
                "bare_rays_per_s": float(np.median(bare)), "bare_occlusion_rays_per_s": float(np.median(occlusion)),
                "rays_per_s": float(np.median(rays)), "paths_per_s": float(np.median(paths)),
                "ratio_to_bare": ratio, "embree_share_of_thread_time": float(np.median(shares)), "target_ratio": 0.6,
                "meets_target": ratio >= 0.6})

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
