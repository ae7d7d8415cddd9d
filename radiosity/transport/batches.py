"""The solver's units of work, pure functions of their arguments: a photon batch
(``trace_photon_batch``) and a gather block (``gather_block``), over the merged scene
as the kernels read it (``scene_arrays``). Both runners, the threads of ``solve`` and
the Dask tasks of ``distributed``, import them from here, so that neither runner
imports the other.
"""

from __future__ import annotations

import numpy as np

from radiosity.physics.environment import no_environment
from radiosity.physics.textures import atlas
from radiosity.scene.material_kernels import KD, albedo_table, pack_materials
from radiosity.transport import lights as delta
from radiosity.transport.gather import gather_outputs, trace_gather
from radiosity.transport.photons import trace_photons
from radiosity.transport.records import (
    PhotonBatch,
    SceneArrays,
    empty_gather_samples,
    empty_light_samples,
    empty_path_buffers,
    empty_tally,
)

MAX_PHOTON_DEPTH = 64
MAX_GATHER_DEPTH = 8
PHOTON_BATCH = 1 << 16
ALBEDO_TABLE_SIZE = 129


def _emitter_table(power, faces_area2, chosen):
    """(cdf, triangles, area pdf (T,)) of choosing a point on the ``chosen`` triangles
    in proportion to their power (a cdf of one 1 and no area pdf where none emits)."""
    emit_area_pdf = np.zeros(len(power))
    emitting = np.nonzero((power > 0) & chosen)[0]
    if len(emitting):
        probability = power[emitting] / power[emitting].sum()
        emit_area_pdf[emitting] = probability / (0.5 * faces_area2[emitting])
        cdf = np.cumsum(probability)
        cdf[-1] = 1.0
    else:
        cdf = np.ones(1)
        emitting = np.zeros(1, dtype=np.int64)
    return cdf, emitting.astype(np.int64), emit_area_pdf


def scene_arrays(scene, merged, epsilon, analytic=(), microfacet_models=True):
    """The merged scene as the kernels read it (``SceneArrays``); ``analytic``
    names the emitting objects whose direct glossy highlights the solver adds in closed
    form (the gather leaves them out); ``microfacet_models`` False packs every
    material's Phong model (``pack_materials``), what the solver evaluates."""
    material_names = list(scene.materials)
    table = pack_materials([scene.materials[n] for n in material_names], microfacet_models)
    albedos = np.stack([albedo_table(scene.materials[n], ALBEDO_TABLE_SIZE, microfacet_models) for n in material_names])
    object_material = np.array([material_names.index(o.material.name) for o in scene.objects])
    face_material = object_material[merged.triangle_object].astype(np.int64)

    positions = np.concatenate([o.positions for o in scene.objects])
    faces = merged.faces.astype(np.int64)
    tri = positions[faces]
    cross = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    twice_area = np.linalg.norm(cross, axis=1)
    face_normals = cross / np.maximum(twice_area, 1e-300)[:, None]
    power = np.pi * table[face_material, 7:10].sum(axis=1) * 0.5 * twice_area
    cdf, emitting, emit_area_pdf = _emitter_table(power, twice_area, np.ones(len(faces), dtype=bool))
    gathered = ~np.isin(merged.triangle_object, [i for i, o in enumerate(scene.objects) if o.name in set(analytic)])
    direct = (cdf, emitting, emit_area_pdf) if gathered.all() else _emitter_table(power, twice_area, gathered)
    return SceneArrays(
        positions=positions,
        normals=np.concatenate([o.normals for o in scene.objects]),
        tangents=np.concatenate([o.tangents for o in scene.objects]),
        faces=faces,
        face_normals=face_normals,
        face_material=face_material,
        materials=table,
        albedo_table=albedos,
        emit_cdf=cdf,
        emit_triangles=emitting,
        emit_area_pdf=emit_area_pdf,
        epsilon=float(epsilon),
        direct_cdf=direct[0],
        direct_triangles=direct[1],
        direct_area_pdf=direct[2],
        **_texture_arrays(scene, merged),
        **_light_arrays(scene, positions, float(power.sum()), epsilon),
    )


def _light_arrays(scene, positions, triangle_power, epsilon):
    """The ``SceneArrays`` fields ``env`` and ``lights``: the scene's environment
    (``no_environment()`` without one) and delta lights (``no_lights()`` without any).
    The environment's photons and a direction's come from a disk on the bounding
    sphere of the vertices ``positions``, a little larger than the bounding box's (by
    1e-4 of it and 4 ray offsets). Photons are shared by power among the environment,
    the delta lights and the emitting triangles; the path tracer's light samples
    equally among those of the three that the scene has."""
    lo, hi = positions.min(axis=0), positions.max(axis=0)
    center = 0.5 * (lo + hi)
    radius = 0.5 * float(np.linalg.norm(hi - lo)) * (1 + 1e-4) + 4 * epsilon
    if not scene.lights:
        env = no_environment() if scene.environment is None else scene.environment.kernel_arrays(
            center, radius, triangle_power)
        return {"env": env, "lights": delta.no_lights()}
    light_power = float(sum(delta.photon_power(light, center, radius).sum() for light in scene.lights))
    env = no_environment()
    env_power = 0.0
    if scene.environment is not None:
        env = scene.environment.kernel_arrays(center, radius, triangle_power + light_power)
        env_power = float(scene.environment.power(radius).sum()) if env.photon_share > 0 else 0.0
    total = env_power + light_power + triangle_power
    kinds = 1 + (env.light_share > 0) + (triangle_power > 0)
    if env.light_share > 0:
        env = env._replace(light_share=1.0 / kinds)
    photon_share = light_power / total if total > 0 else 0.0
    lights = delta.light_arrays(scene.lights, center, radius, photon_share, 1.0 / kinds, not triangle_power > 0)
    return {"env": env, "lights": lights}


def _texture_arrays(scene, merged):
    """The ``SceneArrays`` fields of a scene's textures: uvs (N, 2) (zero where an
    object has none), face_texture (T,) (-1 where untextured) and the atlas, each
    image once however many objects share it."""
    images, index = [], {}
    object_texture = np.full(len(scene.objects), -1, dtype=np.int64)
    for i, o in enumerate(scene.objects):
        if o.texture is not None:
            object_texture[i] = index.setdefault(id(o.texture), len(images))
            if object_texture[i] == len(images):
                images.append(o.texture)
    pixels, offsets, sizes = atlas(images)
    uvs = np.concatenate([o.uvs if o.uvs is not None else np.zeros((o.n_vertices, 2)) for o in scene.objects])
    return {
        "uvs": uvs,
        "face_texture": object_texture[merged.triangle_object],
        "texture_pixels": pixels,
        "texture_offsets": offsets,
        "texture_sizes": sizes,
    }


def trace_photon_batch(tracer, sa, seed, first_id, count, total):
    """Trace photons first_id .. first_id + count - 1 of ``total`` (one jitted call,
    ``photons.trace_photons``, which releases the GIL), counting their rays on
    ``tracer`` (a ``RayTracer``, or anything with its ``embree`` and ``count``).

    Returns their ``PhotonTally``: moment0 (N, 3), moment1 (N, 3, 2), tally
    (T_LENGTH,), float64, all additive.
    """
    acc = empty_tally(len(sa.positions))
    rays = trace_photons(tracer.embree, sa, PhotonBatch(seed, first_id, count, total, MAX_PHOTON_DEPTH), acc)
    tracer.count(rays)
    return acc


def gather_block(tracer, sa, irradiance, block, material, dirs):
    """Outgoing radiance (B, D, 3) float64 of a ``GatherBlock`` of vertices of one
    glossy object of ``material``, in the local directions ``dirs`` (D, 3) float64, and
    the variance of each vertex's estimate (B,) (its luminance's, summed over the
    directions; see ``gather.gather_outputs``; empty unless ``block.measure_noise``).
    Its rays are traced in one jitted call (``gather.trace_gather``) and counted on
    ``tracer`` (see ``trace_photon_batch``)."""
    b = len(block.vertices)
    n_gather = block.strata * block.strata
    light = empty_light_samples(b * block.n_light)
    samples = empty_gather_samples(b * n_gather)
    buffers = empty_path_buffers(b * n_gather)
    rays, shadow = trace_gather(tracer.embree, sa, irradiance, block, light, samples, buffers)
    tracer.count(rays, shadow)

    values = np.empty((b, len(dirs), 3))
    mat = pack_materials([material])[0]
    emission = np.asarray(material.emission, dtype=np.float64)
    diffuse = (mat[KD : KD + 3] / np.pi)[None, :] * irradiance[block.vertices]  # a rough plastic: its substrate's kd
    variance = np.empty(b if block.measure_noise else 0)
    gather_outputs(mat, emission, diffuse, light, samples, dirs, values, variance)
    return values, variance
