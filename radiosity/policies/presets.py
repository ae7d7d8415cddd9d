"""Quality presets: one word that sets every speed/accuracy knob of every stage.

``PRESETS[quality]`` is the one table. The solver (photons, gather and light samples,
kernel width, mesh refinement), the direction grid (``grid_factor``), the fitter
(lights, refinement iterations), the demo (the light-count sweep) and the help texts
all read it. Each knob also has its own flag; a flag given explicitly wins over the
preset. Mesh refinement is relative to the scene's size, so a preset means the same
in millimetres and in metres.

Every stage reads it, so it lives in the radiosity stage's shared core (the README's
stage rule).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

from radiosity.files.errors import InputError

__all__ = ["DEFAULT_QUALITY", "MAX_KERNEL_RINGS", "MAX_MIN_PHOTONS", "MAX_SPARSE_RINGS", "MIN_PHOTONS", "PRESETS", "QUALITIES", "Preset", "max_edge", "preset", "preset_table"]


@dataclass(frozen=True, kw_only=True)
class Preset:
    """Every knob of one quality, each given by name.

    photons          : photons emitted in total
    gather_samples   : gather rays per glossy vertex
    light_samples    : light samples (shadow rays) per glossy vertex
    kernel_rings     : density kernel width, in rings of neighbours
    max_edge_divisor : refine to edges no longer than the scene diagonal / this
    grid_factor      : c in the direction grid's n = ceil(c * sqrt(exponent + 1))
    fit_lights       : virtual lights per glossy object
    fit_iterations   : L-BFGS iterations of the fit's refinement
    demo_light_sweep : light counts of the demo's error-against-lights plot
    truth_spp        : path-traced samples per pixel of the ground truth (``vlights truth``,
                       ``compare --truth-spp``, the demo)
    adaptive         : refine the mesh where the light changes (``transport.adaptive``)
    vertex_budget_factor : the refined scene's vertices at most this times the uniform mesh's
    adaptive_passes  : estimate-and-refine rounds before the final solve
    adaptive_tolerance : the refinement's error target, relative to the local light
    extra_gather     : further gather passes, at most this times the glossy vertices, where
                       the gather is noisy (``transport.regather``; 0: none)
    gather_tolerance : the relative standard error those passes aim at
    visibility_samples : shadow rays per glossy vertex and emitter part: how much of each
                       emitter a vertex sees (its highlight's shadow, ``transport.highlights``)
    emitter_nodes    : N of the quadrature of the emitters' highlights (solver and every
                       display: ``physics.emitters``; more is more exact and slower to draw)
    probe_sizes      : the reflection probe's sizes (M x M texels) ``vlights fit --model auto``
                       tries for each glossy object (``fitting.glossy``)
    probe_lights     : virtual lights per glossy object beside a probe (what the emitters and
                       the probe leave: fewer than ``fit_lights`` alone need)
    fit_search_samples : a glossy object's model is searched for on every k-th vertex, at most
                       this many samples (vertex x direction), its per-vertex coefficients then
                       solved on all (``fitting.blocks``): more is slower and holds more memory
                       (about 1.2 kB a sample)
    """

    photons: int
    gather_samples: int
    light_samples: int
    kernel_rings: int
    max_edge_divisor: int
    grid_factor: float
    fit_lights: int
    fit_iterations: int
    demo_light_sweep: tuple[int, ...]
    truth_spp: int
    adaptive: bool = True
    vertex_budget_factor: float = 1.5
    adaptive_passes: int = 1
    adaptive_tolerance: float = 0.005
    extra_gather: float = 0.0
    gather_tolerance: float = 0.02
    visibility_samples: int = 64
    emitter_nodes: int = 8
    probe_sizes: tuple[int, ...] = (16, 32)
    probe_lights: int = 4
    fit_search_samples: int = 1 << 18


# fit_iterations: the refinement's L-BFGS iterations. One evaluation costs about
# V x D x K (teapot, K = 8: 0.1 s at draft's 17 x 17 grid, 1.5 s at high's 44 x 44), and
# the light placement before it runs on about 1000 vertices: 60 iterations keep the
# high teapot near two minutes on 2 cores (measured: 106 s, relative RMS 0.125).
PRESETS = {
    "draft": Preset(
        photons=2_000_000, gather_samples=256, light_samples=32, kernel_rings=1, max_edge_divisor=24, grid_factor=1.5,
        fit_lights=8, fit_iterations=25, demo_light_sweep=(1, 2, 4, 8), truth_spp=64, adaptive=True,
        vertex_budget_factor=1.5, adaptive_passes=1, adaptive_tolerance=0.005, extra_gather=1.0,
        gather_tolerance=0.03, visibility_samples=32, emitter_nodes=8, probe_sizes=(16, 32), probe_lights=4,
        fit_search_samples=1 << 18,
    ),
    "medium": Preset(
        photons=8_000_000, gather_samples=1024, light_samples=64, kernel_rings=1, max_edge_divisor=40,
        grid_factor=2.5, fit_lights=8, fit_iterations=40, demo_light_sweep=(1, 2, 4, 8, 16), truth_spp=256,
        adaptive=True, vertex_budget_factor=1.5, adaptive_passes=2, adaptive_tolerance=0.005, extra_gather=0.5,
        gather_tolerance=0.02, visibility_samples=64, emitter_nodes=8, probe_sizes=(16, 32, 64), probe_lights=4,
        fit_search_samples=1 << 18,
    ),
    "high": Preset(
        photons=32_000_000, gather_samples=4096, light_samples=256, kernel_rings=1, max_edge_divisor=64,
        grid_factor=4.0, fit_lights=8, fit_iterations=60, demo_light_sweep=(1, 2, 4, 8, 16), truth_spp=1024,
        adaptive=True, vertex_budget_factor=1.5, adaptive_passes=2, adaptive_tolerance=0.005, extra_gather=0.25,
        gather_tolerance=0.01, visibility_samples=128, emitter_nodes=12, probe_sizes=(32, 64), probe_lights=8,
        fit_search_samples=1 << 19,
    ),
}
QUALITIES = tuple(PRESETS)

# The widest density kernel a solve may ask for (``--kernel-rings``). A ring widens each
# vertex's kernel by one edge (``transport.density.widen``); the finest preset cuts
# edges to the scene diagonal / 64, so 64 rings already reach across the whole scene,
# and wider only blurs. Each ring also multiplies the kernel's moments by about the
# vertex valence + 1 (about 7), and the fit takes products of them: 7^(2 x 64) = 1e108
# is far below float64's 1.8e308, while 1000 rings overflow to inf and the solve's
# radiance to NaN (measured), and 10^9 rings would run for days.
MAX_KERNEL_RINGS = 64
# A density kernel whose support holds fewer than MIN_PHOTONS photons widens further, ring by
# ring, up to MAX_SPARSE_RINGS more (``transport.density.irradiance``; ``--min-photons``): the
# same at every quality, since it is the photons a kernel holds, not their total, that it asks.
# Its support is also kept within --max-edge, which binds first on all but the finest meshes
# (the living room's cushions, edges of 6 mm, reach 16 photons in 10 to 30 rings at draft).
MIN_PHOTONS = 16
MAX_SPARSE_RINGS = 32
MAX_MIN_PHOTONS = 1_000_000
DEFAULT_QUALITY = "draft"


def preset(quality: str) -> Preset:
    """The preset of ``quality``; InputError naming the choices otherwise."""
    try:
        return PRESETS[quality]
    except (KeyError, TypeError):
        raise InputError(f"unknown quality {quality!r}; choose one of {', '.join(QUALITIES)}") from None


def preset_table() -> str:
    """The table as text, for help texts and ``--help``."""
    rows = [asdict(p) for p in PRESETS.values()]
    keys = list(rows[0])
    width = max(len(k) for k in keys)
    lines = [" " * width + "".join(f"{q:>14}" for q in QUALITIES)]
    for k in keys:
        lines.append(k.ljust(width) + "".join(f"{str(r[k]):>14}" for r in rows))
    return "\n".join(lines)


def max_edge(scene, quality=DEFAULT_QUALITY, explicit=None):
    """The refinement edge length: ``explicit`` if given, else the preset's fraction
    of the scene diagonal. Returns (length, how it was chosen)."""
    if explicit is not None:
        if not explicit > 0:
            raise InputError(f"--max-edge must be positive, got {explicit:g}")
        if not math.isfinite(explicit):
            raise InputError(f"--max-edge must be a finite length, got {explicit:g}")
        return float(explicit), "--max-edge"
    divisor = preset(quality).max_edge_divisor
    return scene.diagonal / divisor, f"{quality} preset: diagonal / {divisor}"
