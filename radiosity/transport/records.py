"""The records the transport kernels take: named tuples of arrays, never long lists
of them (a kernel unpacks the fields it loops over into locals once).

    SceneArrays   the merged scene (vertex and triangle indices of ``Scene.merged()``)
    LightArrays   its delta lights (points, spots, directions)
    Rays          a batch of rays with an RGB value each: photons or gather paths
    embree.Hits   where each ray of a batch landed (triangle, t, u, v)
    PhotonBatch   which photons a call traces (seed, ids, total, depth, wave size)
    PhotonTally   a photon batch's additive accumulators (density moments, energy tally)
    GatherBlock   a block of glossy vertices and how they are sampled (seed, counts)
    LightSamples  the light samples (shadow rays) of a gather block
    GatherSamples the gather rays of a gather block and the radiance they bring back
    PathBuffers   the buffers a gather block's paths swap between, depth by depth
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from radiosity.physics.environment import EnvArrays
from radiosity.transport.embree import Hits, empty_hits

# tally slots of a photon batch (RGB triples, then counts)
T_ESCAPED, T_ABSORBED, T_INCIDENT, T_BACKFACE, T_TERMINATED = 0, 3, 6, 9, 12
T_HITS, T_LENGTH = 15, 16
PHOTON_WAVE = 1024  # photons traced together by trace_photons: a wave's rays, then its hits


class LightArrays(NamedTuple):
    """A scene's delta lights as the kernels read them (``radiosity.transport.lights``).

    kinds       : (L,) int64          ``physics.emitters`` POINT or DIRECTION
    points      : (L, 3, 3) float64   rows 0-2 of ``PackedParts.points``: the position (a
                                      point) or unit direction of travel (a direction); a
                                      spot's axis; (cutoff, beam width (radians), 1 for a spot)
    values      : (L, 3) float64      intensity (W/sr; a spot's peak) or irradiance
    cones       : (L, 4) float64      a point's photons' cone (axis, cos of its half-angle:
                                      -1 every direction; ``lights.reach``)
    cdf         : (L,) float64        cumulative probability of choosing each, by the
                                      power it sends into the scene
    pick        : (L,) float64        the probability of each
    photon_share: float               probability that a photon is a delta light's
    light_share : float               probability that a path tracer's light sample picks one
    only        : bool                no emitting triangle: a photon that is not the
                                      environment's is a delta light's
    center      : (3,) float64        the scene's bounding sphere: a direction's photons
    radius      : float               start on the disk of this sphere facing it
    """

    kinds: np.ndarray
    points: np.ndarray
    values: np.ndarray
    cones: np.ndarray
    cdf: np.ndarray
    pick: np.ndarray
    photon_share: float
    light_share: float
    only: bool
    center: np.ndarray
    radius: float


class SceneArrays(NamedTuple):
    """The merged scene as the kernels read it.

    positions      : (N, 3) float64   vertex positions
    normals        : (N, 3) float64   unit shading normals
    tangents       : (N, 3) float64   unit tangents (the frames of the density moments)
    faces          : (T, 3) int64
    face_normals   : (T, 3) float64   unit geometric normals (the front side)
    face_material  : (T,) int64       row of ``materials``
    materials      : (M, NCOL) float64, see ``materials.pack_materials``
    albedo_table   : (M, A, 3) float64 true directional albedo at cos theta = k / (A - 1)
    emit_cdf       : (E,) float64     cumulative probability over emitting triangles
    emit_triangles : (E,) int64
    emit_area_pdf  : (T,) float64     density per unit area of choosing a point on a triangle
    epsilon        : float            ray-origin offset, scene units
    uvs            : (N, 2) float64   texture coordinates (0 on untextured objects)
    face_texture   : (T,) int64       the texture of each triangle in the atlas, -1 for none
    texture_pixels, texture_offsets, texture_sizes : every texture in one flat atlas
                     ((X,) float32, (K,) int64, (K, 2) int64: ``textures.atlas``)
    direct_cdf, direct_triangles, direct_area_pdf : the same over the emitters whose direct
                     glossy highlight the gather estimates (its vertices' light samples and
                     the emission its rays find on their first segment); the others'
                     (analytic emitter parts, ``radiosity.scene.emitter_parts``) the solver adds
                     in closed form. The same arrays as emit_* when every emitter is gathered.
                     emit_area_pdf and direct_area_pdf count the triangles alone: a photon
                     or light sample picks the environment first, with ``env``'s shares
    env            : ``environment.EnvArrays``, the light from outside the scene
                     (``environment.no_environment()`` where there is none)
    lights         : ``LightArrays``, the delta lights (``lights.no_lights()`` where there
                     are none): a photon picks the environment first (``env``'s share),
                     then the delta lights (their share), then a triangle
    """

    positions: np.ndarray
    normals: np.ndarray
    tangents: np.ndarray
    faces: np.ndarray
    face_normals: np.ndarray
    face_material: np.ndarray
    materials: np.ndarray
    albedo_table: np.ndarray
    emit_cdf: np.ndarray
    emit_triangles: np.ndarray
    emit_area_pdf: np.ndarray
    epsilon: float
    direct_cdf: np.ndarray
    direct_triangles: np.ndarray
    direct_area_pdf: np.ndarray
    uvs: np.ndarray
    face_texture: np.ndarray
    texture_pixels: np.ndarray
    texture_offsets: np.ndarray
    texture_sizes: np.ndarray
    env: EnvArrays
    lights: LightArrays


class Rays(NamedTuple):
    """A batch of rays, each carrying an RGB value: photons (power) or gather paths
    (throughput). Kernels write the rays that go on into another ``Rays``.

    ids        : (R,) int64      photon id, or gather sample index within its block
    values     : (R, 3) float64  power (photons) or throughput (gather paths)
    origins    : (R, 3) float32  already offset off the surface they leave
    directions : (R, 3) float32  unit
    """

    ids: np.ndarray
    values: np.ndarray
    origins: np.ndarray
    directions: np.ndarray


def empty_rays(count):
    """Uninitialised ``Rays`` for ``count`` rays."""
    return Rays(
        ids=np.empty(count, dtype=np.int64),
        values=np.empty((count, 3)),
        origins=np.empty((count, 3), dtype=np.float32),
        directions=np.empty((count, 3), dtype=np.float32),
    )


class PhotonTally(NamedTuple):
    """What a photon batch accumulates; every field is additive over batches.

    moment0 : (N, 3) float64     sum of power * lambda_j per vertex j (density moments)
    moment1 : (N, 3, 2) float64  sum of power * lambda_j * (x - p_j) in vertex j's tangent frame
    tally   : (T_LENGTH,) float64 energy bookkeeping, slots T_*
    """

    moment0: np.ndarray
    moment1: np.ndarray
    tally: np.ndarray



class PhotonBatch(NamedTuple):
    """Photons first_id .. first_id + count - 1 of a pass of ``total``, emitted and
    scattered with the numbers of ``seed``, for at most ``max_depth`` segments each;
    traced ``wave`` at a time (``photons.trace_photons``)."""

    seed: int
    first_id: int
    count: int
    total: int
    max_depth: int
    wave: int = PHOTON_WAVE

def empty_tally(n_vertices):
    """A zeroed ``PhotonTally`` for a scene of ``n_vertices`` vertices."""
    return PhotonTally(np.zeros((n_vertices, 3)), np.zeros((n_vertices, 3, 2)), np.zeros(T_LENGTH))


class GatherBlock(NamedTuple):
    """A block of glossy vertices and how each is sampled.

    seed      : int           the solve's seed
    vertices  : (B,) int64    merged-scene vertex indices
    n_light   : int           light samples (shadow rays) per vertex
    strata    : int           gather rays per vertex: strata^2, stratified
    max_depth : int           segments of a gather path at most
    lobe_light: bool          sample the light at the glossy hits of gather paths
                              (``shade_paths``); False finds it by the lobe alone,
                              as before: the same expected value, more noise (for tests)
    measure_noise: bool       also measure each vertex's variance (``gather_outputs``);
                              the extra passes of ``regather`` need none
    """

    seed: int
    vertices: np.ndarray
    n_light: int
    strata: int
    max_depth: int
    lobe_light: bool = True
    measure_noise: bool = True


class LightSamples(NamedTuple):
    """The light samples of a gather block, ``n_light`` per vertex, vertex-major.

    origins, directions : (L, 3) float32  shadow rays (direction: the vertex normal where unused)
    distances           : (L,) float32    to the sampled light point (0 where unused)
    wi                  : (L, 3) float64  direction to the light in the vertex's local frame
    radiance            : (L, 3) float64  emitted radiance of the sampled light
    pdf                 : (L,) float64    solid-angle density, 0 for a sample that cannot contribute
    visible             : (L,) bool       the shadow ray reaches the light (filled in by the tracer)
    """

    origins: np.ndarray
    directions: np.ndarray
    distances: np.ndarray
    wi: np.ndarray
    radiance: np.ndarray
    pdf: np.ndarray
    visible: np.ndarray


def empty_light_samples(count):
    """``LightSamples`` for ``count`` samples: pdf, wi and radiance zero, none visible."""
    return LightSamples(
        origins=np.empty((count, 3), np.float32),
        directions=np.empty((count, 3), np.float32),
        distances=np.empty(count, np.float32),
        wi=np.zeros((count, 3)),
        radiance=np.zeros((count, 3)),
        pdf=np.zeros(count),
        visible=np.zeros(count, dtype=bool),
    )


class GatherSamples(NamedTuple):
    """The gather rays of a block, strata^2 per vertex, vertex-major.

    origins, directions : (G, 3) float32  the first segment of each gather path
    wi                  : (G, 3) float64  its direction in the vertex's local frame
    incoming            : (G, 3) float64  radiance arriving along it (accumulated by ``shade_paths``)
    """

    origins: np.ndarray
    directions: np.ndarray
    wi: np.ndarray
    incoming: np.ndarray


def empty_gather_samples(count):
    """``GatherSamples`` for ``count`` rays, nothing arrived yet (incoming zero)."""
    return GatherSamples(
        origins=np.empty((count, 3), np.float32),
        directions=np.empty((count, 3), np.float32),
        wi=np.empty((count, 3)),
        incoming=np.zeros((count, 3)),
    )


# -- random numbers -------------------------------------------------------------------


class PathBuffers(NamedTuple):
    """The buffers a gather block's paths swap between, one row per gather ray: the
    paths in flight and those going on (``Rays``, values: throughput), the density with
    which the previous vertex's lobe sampled each path's direction (2, count) (the
    two rows swap too), and where the paths in flight landed (``embree.Hits``)."""

    paths: Rays
    spare: Rays
    pdfs: np.ndarray
    hits: Hits


def empty_path_buffers(count):
    """``PathBuffers`` for ``count`` gather rays."""
    return PathBuffers(empty_rays(count), empty_rays(count), np.zeros((2, count)), empty_hits(count))
