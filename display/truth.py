"""Ground truth: the path tracer's picture of what the display shows, and every
display mode's error against it.

The path tracer (``radiosity.transport.pathtrace``, reached through
``display.pipeline`` as every run of an earlier stage is) renders the solution's own meshes
and materials (or a scene's), from the same camera record, integrating over each
pixel with a box filter as the antialiased display does. What it cannot know is its
own noise; ``ground_truth`` therefore traces two independent halves of the samples
(samples 0 .. N/2 - 1 and N/2 .. N - 1 of each pixel: together exactly the N-sample
image) and reports FLIP between the halves, the noise floor below which no error
against the truth means anything. Each display's error against the truth is
``display.metrics.against_truth``; the command is ``display.commands.truth``.
"""

from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np

from radiosity.files.errors import InputError

__all__ = ["GroundTruth", "ground_truth", "load_truth", "scene_for_truth"]


def scene_for_truth(path):
    """The source to path-trace: a solution.npz (its meshes and materials, what its
    displays show), or a scene (TOML, OBJ, glTF or a built-in name). A fit.npz holds no
    materials and is refused (InputError)."""
    from radiosity.files.sniff import FIT, SOLUTION, input_kind
    from radiosity.files.solution import load_solution

    from . import pipeline

    text = str(path)
    kind = input_kind(text) if os.path.lexists(text) and not os.path.isdir(text) else None
    npz = text.endswith(".npz")
    if kind in ("scene", "mesh") or (kind in (None, "unknown") and not npz):
        return pipeline.load_scene(text)  # a scene file or a built-in; the loader names what is wrong
    if kind is None:
        raise InputError(f"{text!r} not found")
    if kind == FIT:
        raise InputError(f"{text!r} is a fit.npz, which holds no materials to path-trace; give the "
                         "solution.npz it was fitted to, or the scene")
    if kind != SOLUTION:
        raise InputError(f"{text!r} is not a solution.npz (nor a scene)")
    return load_solution(text)


@dataclass(frozen=True)
class GroundTruth:
    """A path-traced image and how much to trust it.

    radiance   : (H, W, 3) float32 linear radiance, the mean of all samples
    spp        : samples per pixel
    noise_flip : FLIP between the two independent halves of the samples (the error the
                 path tracer's own noise would show against the truth), None for 1 spp
    stats      : the path tracer's, both halves together (paths, rays, seconds, rates)
    """

    radiance: np.ndarray
    spp: int
    noise_flip: float | None
    stats: dict


def ground_truth(source, camera, spp, seed=1, threads=None, progress=False):
    """Path-trace ``camera`` (a ``Camera``) of ``source`` (a ``Solution`` or a ``Scene``)
    with ``spp`` samples per pixel, as two independent halves; a ``GroundTruth``."""
    from . import pipeline
    from .metrics import is_black, metrics

    first = spp // 2
    runs = [(n, start) for n, start in ((first, 0), (spp - first, first)) if n > 0]
    halves = pipeline.path_trace(pipeline.scene_of(source), camera, runs, seed, threads, progress)
    total = sum(h.radiance.astype(np.float64) * h.spp for h in halves)
    radiance = (total / spp).astype(np.float32)
    noise = None
    if len(halves) == 2 and not is_black(halves[0].radiance):
        noise = metrics(halves[0].radiance, halves[1].radiance)[0]["flip_mean"]
    seconds = sum(h.stats["seconds"] for h in halves)
    rays = sum(h.stats["rays"] for h in halves)
    stats = halves[0].stats | {
        "spp": spp, "paths": spp * camera.width * camera.height, "rays": rays,
        "shadow_rays": sum(h.stats["shadow_rays"] for h in halves), "seconds": round(seconds, 4),
        "rays_per_s": rays / seconds if seconds > 0 else 0.0,
        "paths_per_s": spp * camera.width * camera.height / seconds if seconds > 0 else 0.0,
    }
    return GroundTruth(radiance, spp, noise, stats)


def load_truth(path, camera):
    """A path-traced image from ``--truth FILE.npy`` for ``camera``: (H, W, 3) float32,
    finite, not negative, of the camera's size; InputError naming the problem."""
    try:
        image = np.load(path, allow_pickle=False)
    except FileNotFoundError:
        raise InputError(f"--truth {str(path)!r} not found") from None
    except (OSError, ValueError) as exc:
        raise InputError(f"--truth {str(path)!r} is not a .npy image: {' '.join(str(exc).split())}") from None
    want = (camera.height, camera.width, 3)
    if image.shape != want:
        raise InputError(f"--truth {str(path)!r} is {image.shape}, but the view is {camera.width}x{camera.height}: "
                         f"give an image of shape {want} (render it with the same --size and camera)")
    if image.dtype.kind != "f" or not np.isfinite(image).all() or (image < 0).any():
        raise InputError(f"--truth {str(path)!r} must hold finite, non-negative linear radiance")
    return image.astype(np.float32)
