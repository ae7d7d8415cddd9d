"""Refinement driven by the light: ``solve_adaptive(scene, opts, adaptive) -> Solution``.

A uniform mesh knows the light only at vertices spaced by the preset's maximum edge,
so a shadow edge, a contact shadow or the bright patch under a lamp is blurred by the
density kernel and by the linear interpolation between vertices. Here the solver runs
first on that mesh (a cheaper pass: fewer photons and gather rays), and each edge gets
an indicator of the error linear interpolation makes along it:

    err_e = |(g_b - g_a) . (x_b - x_a)| / 8

with g the gradient of the vertex values fitted over each vertex's ring of neighbours:
for a quadratic along the edge this is the interpolation error at its midpoint
(f'' L^2 / 8), and it vanishes wherever the light varies linearly. The values are the
outgoing radiance without emission (its luminance; for glossy objects averaged over
the direction grid), the quantity the reference display interpolates. An edge is
marked where err_e is above both

  * the noise: the photon count of each vertex's kernel (its mass times the
    irradiance over the power of one photon) gives the relative noise of its value,
    and err_e of pure noise stays below about a third of that noise (``NOISE_SIGMAS``);
  * the error target: ``tolerance`` times sqrt(local level x the scene's typical
    level), as a display's sRGB curve (about a square root) sees an error: relative
    to the light in bright parts, less strict in dark ones (and a floor, a small
    fraction of the typical level, so that black corners do not pull vertices).

The ratio err_e / target is weighted per object by (its median edge / max_edge)^2 in
the uniform mesh, at most 1 (``object_weights``): what a split gains in the image is
the error times the area it changes, so a blurred shadow across the floor comes before
the same error on a finely tessellated small object (the teapot). Marked edges give a
size field (edges per unit length: sqrt(ratio) / length, as the interpolation error
falls with the square of the edge length), dilated by the density kernel's support
(the estimate is blurred by it, so the feature may lie anywhere within it; not into
black vertices), and the meshes are refined conformingly to it
(``geometry.refine_density``: longest-edge bisection, no T-junctions, crease copies
split together, normals interpolated). Where the result would exceed the vertex
budget, the field is scaled down (a larger tolerance, found by bisection) until it
fits. Then the solver runs again on the refined scene, whose edges are already below
``max_edge``, so ``solve``'s own refinement leaves them; with ``passes`` > 1 the
estimate-and-refine step repeats, each pass spending its share of the budget left.
Every pass uses the same seed (photon and gather random numbers are counter-based, so
a pass needs no state from another); the estimate passes trace ``FIRST_PASS_PHOTONS``
of the photons and at most ``FIRST_PASS_GATHER`` gather rays, and gather the emitters'
highlights instead of computing them in closed form (the indicator reads each vertex's
mean over the grid, which is the same either way; the closed form's shadow rays and
grids were 11 s of a 22-33 s estimate pass at 10^6 triangles, whose refined mesh and
solution came out the same, bit for bit).

The final pass runs with the options as given; the returned Solution's stats gain
``adaptive``: vertices before and after, passes, the budget and the time of each pass.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, replace
from typing import NamedTuple

import numpy as np

from radiosity.files.errors import InputError
from radiosity.policies import presets
from radiosity.scene.geometry import unique_edges
from radiosity.transport import density
from radiosity.transport.solve import SolveOptions, solve

LUMINANCE = np.array([0.2126, 0.7152, 0.0722])
GATHER_NOISE = 3.0  # relative noise of one gather ray's estimate (19 % at 256 rays, measured)
# an edge's indicator must exceed this times its ends' noise: on independent unit noise
# the indicator's 99th percentile is 0.29 (measured on uniform meshes), and a local
# linear fit is noisier than the photon count alone says
NOISE_SIGMAS = 0.5
FLOOR_FRACTION = 0.1  # of the scene's typical level: darker light is weighed as this
MIN_EDGE_FRACTION = 1 / 16  # no edge shorter than max_edge times this
FIRST_PASS_PHOTONS = 0.5  # the estimate passes trace this fraction of the photons
FIRST_PASS_GATHER = 64  # ... and at most this many gather rays per glossy vertex


class AdaptiveKnobs(NamedTuple):
    """The refinement's knobs with their values (``AdaptiveOptions.resolved``)."""

    enabled: bool
    passes: int
    tolerance: float
    vertex_budget: int


@dataclass(frozen=True)
class AdaptiveOptions:
    """Knobs of the refinement; None means "as the quality preset says".

    enabled       : refine where the light changes (False: ``solve`` alone)
    vertex_budget : most vertices of the refined scene (default: the preset's
                    ``vertex_budget_factor`` times the uniform mesh's count)
    passes        : estimate-and-refine rounds before the final solve
    tolerance     : the error target: interpolation error relative to the local light
    """

    enabled: bool | None = None
    vertex_budget: int | None = None
    passes: int | None = None
    tolerance: float | None = None

    def resolved(self, quality, uniform_vertices, explicit_max_edge=False):
        """Every knob with its value (an ``AdaptiveKnobs``). ``explicit_max_edge``: the mesh size
        was given (``--max-edge``), which asks for that uniform mesh, so refinement is
        then off unless ``enabled`` says otherwise."""
        preset = presets.preset(quality)
        default = preset.adaptive and not explicit_max_edge
        out = {
            "enabled": default if self.enabled is None else bool(self.enabled),
            "passes": preset.adaptive_passes if self.passes is None else self.passes,
            "tolerance": preset.adaptive_tolerance if self.tolerance is None else self.tolerance,
        }
        budget = self.vertex_budget
        if budget is None:
            budget = int(round(preset.vertex_budget_factor * uniform_vertices))
        if int(budget) != budget or budget < 1:
            raise InputError(f"--vertex-budget must be a whole number >= 1, got {budget}")
        if int(out["passes"]) != out["passes"] or out["passes"] < 0:
            raise InputError(f"adaptive passes must be a whole number >= 0, got {out['passes']}")
        if not out["tolerance"] > 0:
            raise InputError(f"adaptive tolerance must be positive, got {out['tolerance']}")
        return AdaptiveKnobs(enabled=out["enabled"], passes=out["passes"], tolerance=out["tolerance"],
                             vertex_budget=int(budget))


def solve_adaptive(scene, opts=None, adaptive=None, progress=False, client=None):
    """The solution of ``scene`` on a mesh refined where the light changes.

    ``opts`` : ``SolveOptions`` (default: the default preset); ``adaptive`` :
    ``AdaptiveOptions`` (default: as the preset says). Same contract as ``solve`` (a
    ``Solution``); with refinement disabled it is ``solve``'s. ``stats["adaptive"]``
    records the vertices before and after, the passes, the budget and each pass's time.
    """
    opts = SolveOptions() if opts is None else opts
    adaptive = AdaptiveOptions() if adaptive is None else adaptive
    settings = opts.resolved(scene)
    max_edge = settings.max_edge
    coarse = scene.refined(max_edge)
    knobs = adaptive.resolved(opts.quality, coarse.n_vertices, explicit_max_edge=opts.max_edge is not None)
    if not knobs.enabled or knobs.passes == 0:
        solution = solve(scene, opts, progress=progress, client=client)
        return _with_stats(solution, knobs, coarse.n_vertices, coarse.n_vertices, [], max_edge)

    fixed = replace(opts, max_edge=max_edge)  # the same length on every pass, however chosen
    cheap = replace(
        fixed,
        photons=max(1, int(settings.photons * FIRST_PASS_PHOTONS)),
        gather_samples=min(settings.gather_samples, FIRST_PASS_GATHER),
        light_samples=min(settings.light_samples, FIRST_PASS_GATHER // 4),
        extra_gather=0.0,  # the estimate needs no extra gather passes
        emitter_highlights=False,  # nor the highlights' closed form: gathered, their mean is the same
    )
    passes = []
    current = coarse
    budget = knobs.vertex_budget
    weights = object_weights(coarse, max_edge)
    for k in range(knobs.passes):
        if current.n_vertices >= budget:
            break
        t0 = time.perf_counter()
        estimate = solve(current, cheap, progress=progress, client=client)
        marks = mark_edges(current, estimate, knobs.tolerance, max_edge, weights)
        del estimate  # its radiance is the size of the final solve's: not held through it
        # each pass may spend its share of what is left, so later passes (which see the
        # features the earlier ones began to resolve) still have vertices to place
        share = current.n_vertices + (budget - current.n_vertices) // (knobs.passes - k)
        refined = refine_within_budget(current, marks, share)
        passes.append(
            {"vertices": current.n_vertices, "refined_to": refined.n_vertices, "time_s": round(time.perf_counter() - t0, 3)}
        )
        if refined.n_vertices == current.n_vertices:
            break
        current = refined
    solution = solve(current, fixed, progress=progress, client=client)
    return _with_stats(
        solution, knobs, coarse.n_vertices, current.n_vertices, passes, max_edge, settings.max_edge_chosen_by
    )


def _with_stats(solution, knobs, before, after, passes, max_edge, chosen_by=None):
    stats = dict(solution.stats)
    stats["adaptive"] = {
        "enabled": bool(knobs.enabled),
        "vertices_before": int(before),
        "vertices_after": int(after),
        "vertex_budget": knobs.vertex_budget,
        "tolerance": knobs.tolerance,
        "passes": passes,
    }
    settings = dict(solution.settings)
    settings.update({"adaptive": bool(knobs.enabled), "vertex_budget": knobs.vertex_budget, "max_edge": max_edge})
    if chosen_by is not None:
        settings["max_edge_chosen_by"] = chosen_by
    return replace(solution, stats=stats, settings=settings)


# -- the indicator -------------------------------------------------------------------


def vertex_values(obj_solution):
    """(V,) float64: the luminance of the outgoing radiance without emission (averaged
    over the direction grid of a glossy object). A textured object's radiance leaves its
    diffuse term out (``radiosity.physics.textures``): it is added back with the
    texture's mean colour, so that the mesh follows the light as on the same object
    untextured (the texture's own detail is drawn per pixel, not by the mesh)."""
    # the mean in float64 straight from the float32 radiance (no float64 copy of the
    # whole grid), then less the emission: the same bits wherever the emission is 0
    mean = obj_solution.radiance.mean(axis=1, dtype=np.float64) - np.asarray(obj_solution.material_record.emission)
    t = obj_solution.textured
    if t is not None:
        albedo = np.asarray(t.kd) * t.texture.reshape(-1, 3).mean(axis=0, dtype=np.float64)
        mean = mean + albedo / np.pi * t.irradiance.astype(np.float64)
    return np.maximum(mean @ LUMINANCE, 0.0)


def ring_gradients(positions, normals, tangents, edges, values):
    """(V, 2) least-squares gradients of ``values`` in each vertex's tangent plane, from
    the differences to its neighbours (the other ends of its ``edges``, (E, 2))."""
    target = np.concatenate([edges[:, 0], edges[:, 1]])
    source = np.concatenate([edges[:, 1], edges[:, 0]])
    bitangents = np.cross(normals, tangents)
    offset = positions[source] - positions[target]
    d = np.stack([np.einsum("ij,ij->i", offset, tangents[target]), np.einsum("ij,ij->i", offset, bitangents[target])], 1)
    dv = values[source] - values[target]
    n = len(positions)
    ata = np.zeros((n, 2, 2))
    atb = np.zeros((n, 2))
    np.add.at(ata, target, d[:, :, None] * d[:, None, :])
    np.add.at(atb, target, d * dv[:, None])
    scale = np.maximum(np.trace(ata, axis1=1, axis2=2), 1e-300)
    ata += (1e-9 * scale)[:, None, None] * np.eye(2)
    return np.linalg.solve(ata, atb[:, :, None])[:, :, 0]


def edge_errors(positions, normals, tangents, faces, values):
    """Edges (E, 2) of the mesh and the interpolation error (E,) of ``values`` along
    each: |(g_b - g_a) . (x_b - x_a)| / 8, the gradients in world space."""
    edges = unique_edges(faces)
    g = ring_gradients(positions, normals, tangents, edges, values)
    world = g[:, :1] * tangents + g[:, 1:] * np.cross(normals, tangents)
    a, b = edges[:, 0], edges[:, 1]
    err = np.abs(np.einsum("ij,ij->i", world[b] - world[a], positions[b] - positions[a])) / 8
    return edges, err


def value_noise(obj, values, photon_power, gather_samples, rings):
    """(V,) the noise (one standard deviation) of each vertex's value: photon noise of
    its density estimate (the photons in its kernel: irradiance times kernel mass over
    one photon's power), and for a glossy object the gather's."""
    kd = float(np.asarray(obj.material.diffuse) @ LUMINANCE)
    zeros = (np.zeros((obj.n_vertices, 1)), np.zeros((obj.n_vertices, 1, 2)))
    moments = zeros + density.kernel_moments(obj.positions, obj.normals, obj.tangents, obj.faces)
    mass = density.widen(obj.positions, obj.normals, obj.tangents, obj.faces, moments, rings)[2]
    # value = kd / pi * E and E * mass / photon_power photons: sigma = value / sqrt(photons)
    photon = np.sqrt(np.maximum(values, 0.0) * kd / np.pi * photon_power / np.maximum(mass, 1e-300))
    if obj.material.has_grid:
        return np.hypot(photon, GATHER_NOISE / np.sqrt(gather_samples) * values)
    return photon


class Marks(NamedTuple):
    """The edges of one object a pass wants split.

    edges    : (M, 2) int64 vertex pairs
    wanted   : (M,) edges per unit length wanted along each: sqrt(ratio) / length
    ratio    : (M,) the weighted error over the target (> 1)
    into     : (V,) bool, the vertices the field may spread to (not black)
    all_edges: (E, 2) every edge of the mesh (for the dilation)
    rings    : the dilation, in rings (the density kernel's support)
    """

    edges: np.ndarray
    wanted: np.ndarray
    ratio: np.ndarray
    into: np.ndarray
    all_edges: np.ndarray
    rings: int

    def field(self, n_vertices, scale=1.0):
        """(V,) the size field ``wanted`` times ``scale`` (1 / scale^2 multiplies the
        tolerance), dilated."""
        wanted = self.wanted * scale
        rho = np.zeros(n_vertices)
        np.maximum.at(rho, self.edges[:, 0], wanted)
        np.maximum.at(rho, self.edges[:, 1], wanted)
        return dilate(rho, self.all_edges, self.rings, into=self.into)


def object_weights(scene, max_edge):
    """{object name: weight}: (median edge length / max_edge)^2, at most 1, of each
    object of the uniform mesh ``scene``: what a split gains in the image is the error
    times the area it changes, so a blurred shadow across the floor comes before the
    same error on a finely tessellated small object (a teapot's edges are a few
    millimetres where the walls' are centimetres)."""
    out = {}
    for o in scene.objects:
        ends = o.faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
        median = float(np.median(np.linalg.norm(o.positions[ends[:, 0]] - o.positions[ends[:, 1]], axis=1)))
        out[o.name] = min(median / max_edge, 1.0) ** 2
    return out


def mark_edges(scene, solution, tolerance, max_edge, weights=None):
    """Per object of ``scene`` the ``Marks`` from ``solution`` (solved on exactly that
    scene): the edges whose interpolation error, times the object's weight
    (``object_weights``, default 1), exceeds their noise and the target.
    Returns {object name: Marks} (objects with none left out)."""
    settings, stats = solution.settings, solution.stats
    emitted = sum(float(np.asarray(o.emitted_power) @ LUMINANCE) for o in scene.emitters)
    if (scene.environment is not None or scene.lights) and "energy" in stats:  # the environment's and lights' too
        energy = stats["energy"]  # less what no photon carried (a point light's light away from the scene)
        emitted = float((np.asarray(energy["emitted"]) - np.asarray(energy.get("unreached", np.zeros(3)))) @ LUMINANCE)
    photon_power = emitted / max(stats.get("photons", 0), 1)
    values = {o.name: vertex_values(solution.object(o.name)) for o in scene.objects}
    lit = np.concatenate([v for o, v in zip(scene.objects, values.values()) if not o.material.is_emitter] or [np.zeros(1)])
    level = float(np.percentile(lit, 90))
    floor = FLOOR_FRACTION * level
    out = {}
    for o in scene.objects:
        v = values[o.name]
        if len(v) != o.n_vertices:
            raise ValueError(f"object {o.name!r}: the solution has {len(v)} vertices, the scene {o.n_vertices}")
        if o.material.is_emitter or not v.any():
            continue
        edges, err = edge_errors(o.positions, o.normals, o.tangents, o.faces, v)
        sigma = value_noise(o, v, photon_power, settings["gather_samples"], settings["kernel_rings"])
        a, b = edges[:, 0], edges[:, 1]
        noise = NOISE_SIGMAS * 0.5 * (sigma[a] + sigma[b])
        target = tolerance * np.sqrt(np.maximum(0.5 * (v[a] + v[b]), floor) * level)
        length = np.linalg.norm(o.positions[b] - o.positions[a], axis=1)
        ratio = err / np.maximum(target, 1e-300) * (1.0 if weights is None else weights[o.name])
        marked = (err > noise) & (ratio > 1)
        if not marked.any():
            continue
        wanted = np.minimum(np.sqrt(ratio[marked]) / length[marked], 1 / (MIN_EDGE_FRACTION * max_edge))
        out[o.name] = Marks(edges[marked], wanted, ratio[marked], v > floor, edges, settings["kernel_rings"] + 1)
    return out


def dilate(values, edges, rings, into=None):
    """(V,) the largest of ``values`` within ``rings`` rings of each vertex (of the
    vertices ``into`` (V,) bool selects; the others keep their own).

    The estimate a pass sees is the light blurred by the kernel (the hat widened by
    ``kernel_rings``), so a feature's true position is anywhere within that support
    of where the estimate bends: the size field covers it. It does not grow into
    black vertices (the floor under a block), where nothing can be seen to change."""
    out = values.copy()
    for _ in range(rings):
        grown = out.copy()
        np.maximum.at(grown, edges[:, 0], out[edges[:, 1]])
        np.maximum.at(grown, edges[:, 1], out[edges[:, 0]])
        out = grown if into is None else np.where(into, grown, out)
    return out


def refine_within_budget(scene, marks, budget, steps=12):
    """``scene`` refined to the size fields of ``marks`` ({name: Marks}); if that goes
    beyond ``budget`` vertices, to the fields scaled down by the largest factor that
    stays within it (bisection on its logarithm): the same as a larger tolerance, so
    the vertices stay spread over every feature in proportion to its error. Returns
    the refined Scene (the scene itself if nothing fits)."""

    def refined(scale, partial=False):
        objects = []
        for k, o in enumerate(scene.objects):
            rho = marks[o.name].field(o.n_vertices, scale) if o.name in marks else None
            if rho is None or not rho.any():
                objects.append(o)
                continue
            room = budget
            if partial:  # what the others leave; the refinement stops before the round beyond it
                room = budget - sum(x.n_vertices for x in objects) - sum(x.n_vertices for x in scene.objects[k + 1:])
            objects.append(o.refined_to_density(rho, max_vertices=max(room, o.n_vertices)))
        out = replace(scene, objects=tuple(objects))
        return out, out.n_vertices

    full, total = refined(1.0)
    if total <= budget or not marks:
        return full if total <= budget else scene
    lo, hi = -8.0, 0.0  # log2 of the scale: 2^-8 refines (almost) nothing, 1 too much
    best = scene
    for _ in range(steps):
        mid = 0.5 * (lo + hi)
        candidate, total = refined(2.0**mid)
        if total <= budget:
            lo, best = mid, candidate
        else:
            hi = mid
    if best is scene:  # not even the smallest field fits whole: its first rounds
        candidate, total = refined(2.0**lo, partial=True)
        if total <= budget:
            best = candidate
    return best
