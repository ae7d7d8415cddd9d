"""The emitters' direct glossy highlights in closed form (``radiosity.physics.emitters``):
what fraction of each emitter part every glossy vertex sees, by shadow rays, and the
highlights' radiance on each glossy object's direction grid.

The solver leaves these highlights out of the gather (``solve.scene_arrays``'s
``analytic``) and adds them here, so the solution's radiance is the same quantity as
before (emission included, every light) while the part the displays recompute per
pixel is exactly the part they can subtract.

Visibility: from each vertex (offset along its normal, as the gather's rays), shadow
rays to ``samples`` fixed points of each part, the same points for every vertex so
that visibility is a smooth function of position, not noise: a polygon's points
spread over its area by the plastic-number (R2) sequence; a sphere's over the cap the
vertex sees, by the same sequence in the cap's solid angle. A point behind the
vertex's tangent plane or behind the part's front does not count; the vertex's value
is the fraction of the counted points that are unoccluded (1 where none counts: the
part's highlight is 0 there anyway). The part's own object does not shadow it. A delta
part (a point, a direction) has no extent: one shadow ray, to the point (1e-4 of its
length short of it) or along -the direction to infinity, and the value is 0 or 1.

Parts per object (``object_parts``): where the scene has more parts than one object's
highlight draws (``MAX_RECEIVER_PARTS``), each glossy object keeps the parts brightest
for it: a coarse visibility (``COARSE_SAMPLES`` rays a part from at most
``COARSE_VERTICES`` of its vertices) and an estimate of the light each part sends
(``incident``) rank them; the dimmest whose light adds up to less than ``LEFT_OUT`` of
the object's are left out, the others' full visibility and closed-form highlights go
into the grid (the gather leaves every analytic part out), and the
``MAX_RECEIVER_PARTS`` brightest are the ones its file names and its displays draw per
pixel; the others stay in its grid, drawn by its fit. What is left out is lost to both
the grid and the gather: at most ``LEFT_OUT`` of the object's direct highlights, and a
part the coarse rays find hidden from every vertex they leave from.
"""

from __future__ import annotations

import numpy as np

from radiosity.physics.emitters import emitter_grid
from radiosity.scene.geometry import face_normals

__all__ = ["COARSE_SAMPLES", "MAX_RECEIVER_PARTS", "grid_highlights", "object_parts", "r2_points", "visibility"]

MAX_RECEIVER_PARTS = 16  # the emitter parts one glossy object's displays draw per pixel, the brightest for it
COARSE_SAMPLES = 4  # shadow rays a vertex and part that say whether a part reaches an object at all ...
COARSE_VERTICES = 64  # ... from every k-th vertex, at most this many
LEFT_OUT = 0.01  # the dimmest parts whose light adds up to less than this share of an object's are left out
LUMINANCE = np.array([0.2126, 0.7152, 0.0722])  # Rec. 709: how the parts are ranked for an object

PLASTIC = 1.324717957244746  # the plastic number: the R2 sequence's generator
SPHERE_MARGIN = 1.05  # shadow rays to a sphere lamp stop at this times its radius (its mesh lies within)
RELATIVE_SHORTEN = 1e-4  # ... to a polygon, this fraction of their length short of it


def r2_points(count):
    """(count, 2) float64 in [0, 1)^2: the R2 low-discrepancy sequence (Roberts 2018)."""
    i = np.arange(count, dtype=np.float64)[:, None]
    alpha = np.array([1.0 / PLASTIC, 1.0 / PLASTIC**2])
    return np.mod(0.5 + alpha * (i + 1), 1.0)


def polygon_points(vertices, count):
    """(count, 3) points spread over a convex polygon's area (a fan of triangles, each
    getting its share of the R2 sequence by area)."""
    q = np.asarray(vertices, np.float64)
    a, b, c = q[0], q[1:-1], q[2:]
    area = 0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1)
    cdf = np.cumsum(area) / area.sum()
    uv = r2_points(count)
    tri = np.minimum(np.searchsorted(cdf, uv[:, 0], side="right"), len(area) - 1)
    low = np.concatenate([[0.0], cdf[:-1]])[tri]
    x = np.clip((uv[:, 0] - low) / (cdf[tri] - low), 0.0, 1.0)
    s = np.sqrt(x)[:, None]
    y = uv[:, 1:2]
    return a * (1 - s) + s * ((1 - y) * b[tri] + y * c[tri])


def _frame(c):
    """Unit vectors (..., 3) t, b perpendicular to unit c (..., 3)."""
    helper = np.where(np.abs(c[..., :1]) < 0.9, [1.0, 0.0, 0.0], [0.0, 1.0, 0.0])
    t = np.cross(c, helper)
    t /= np.linalg.norm(t, axis=-1, keepdims=True)
    return t, np.cross(c, t)


def _rays_to_part(part, origins, normals, count):
    """Shadow rays from ``origins`` (V, 3) to ``count`` points of ``part`` (one for a
    delta part): (directions (V, S, 3), lengths (V, S), counted (V, S) bool)."""
    if part.kind == "direction":
        directions = np.broadcast_to(-part.points[0], origins.shape)[:, None, :]
        counted = (normals @ -part.points[0] > 0)[:, None]
        return directions, np.full(counted.shape, np.inf), counted
    if part.kind == "point":
        to = (part.points[0] - origins)[:, None, :]
        length = np.linalg.norm(to, axis=2)
        directions = to / np.maximum(length, 1e-300)[..., None]
        counted = (np.einsum("vsi,vi->vs", directions, normals) > 0) & (length > 0)
        return directions, length * (1 - RELATIVE_SHORTEN), counted
    if part.kind == "polygon":
        points = polygon_points(part.points, count)
        to = points[None, :, :] - origins[:, None, :]
        length = np.linalg.norm(to, axis=2)
        directions = to / np.maximum(length, 1e-300)[..., None]
        front = (origins - part.points[0]) @ part.normal > 0
        counted = front[:, None] & (np.einsum("vsi,vi->vs", directions, normals) > 0) & (length > 0)
        return directions, length * (1 - RELATIVE_SHORTEN), counted
    centre, radius = part.points[0], part.radius
    to = centre[None, :] - origins
    dist = np.linalg.norm(to, axis=1)
    c = to / np.maximum(dist, 1e-300)[:, None]
    sin_beta = np.minimum(radius / np.maximum(dist, 1e-300), 1.0)
    cos_beta = np.sqrt(1 - sin_beta**2)
    uv = r2_points(count)
    cos_t = 1 - uv[None, :, 0] * (1 - cos_beta[:, None])
    sin_t = np.sqrt(np.maximum(0.0, 1 - cos_t**2))
    phi = 2 * np.pi * uv[None, :, 1]
    t, b = _frame(c)
    directions = (
        cos_t[..., None] * c[:, None, :]
        + (sin_t * np.cos(phi))[..., None] * t[:, None, :]
        + (sin_t * np.sin(phi))[..., None] * b[:, None, :]
    )
    # stop where the ray enters the sphere that holds the lamp's mesh
    outer = SPHERE_MARGIN * radius
    along = np.einsum("vsi,vi->vs", directions, to)
    disc = along**2 - (dist**2 - outer**2)[:, None]
    length = np.where(disc > 0, along - np.sqrt(np.maximum(disc, 0.0)), 0.0)
    counted = (np.einsum("vsi,vi->vs", directions, normals) > 0) & (dist[:, None] > radius) & (length > 0)
    return directions, np.maximum(length, 0.0), counted


def visibility(tracer, parts, positions, normals, samples, epsilon, source=None, chunk=1 << 18):
    """(V, P) float32: the fraction of each part that each vertex (positions, unit
    normals (V, 3)) sees, from ``samples`` shadow rays per part (one per delta part) traced on ``tracer``
    (a ``embree.RayTracer`` of the whole scene); ``source`` the vertices' own object
    (its own parts: 0)."""
    positions = np.asarray(positions, np.float64)
    normals = np.asarray(normals, np.float64)
    origins = positions + epsilon * normals
    out = np.ones((len(positions), len(parts)), np.float32)
    for i, part in enumerate(parts):
        samples_i = 1 if part.is_delta else samples
        per_chunk = max(1, chunk // max(samples_i, 1))
        if source is not None and part.source == source:
            out[:, i] = 0.0
            continue
        for start in range(0, len(positions), per_chunk):
            sl = slice(start, start + per_chunk)
            directions, length, counted = _rays_to_part(part, origins[sl], normals[sl], samples_i)
            o = np.broadcast_to(origins[sl, None, :], directions.shape)[counted]
            blocked = np.zeros(counted.shape, dtype=bool)
            if counted.any():
                blocked[counted] = tracer.occluded(o, directions[counted], length[counted])
            n_counted = counted.sum(axis=1)
            seen = (counted & ~blocked).sum(axis=1)
            out[sl, i] = np.where(n_counted > 0, seen / np.maximum(n_counted, 1), 1.0)
    return out


def grid_highlights(parts, obj, directions, visible, nodes):
    """E (V, D, 3) float64 of the glossy object ``obj`` (a ``SceneObject``) on its grid
    ``directions`` (D, 3), with its vertices' visibility ``visible`` (V, P)."""
    material = obj.material
    return emitter_grid(
        parts, obj.positions, obj.normals, obj.tangents, directions, material.specular, material.exponent,
        visibility=visible, nodes=nodes, source=obj.name, fresnel=material.fresnel, microfacet=material.microfacet,
    )


def incident(parts, positions, normals):
    """(V, P) float64: an estimate of the light each part sends to each point (V, 3) with
    its unit normal, unshadowed, in luminance: a sphere's or a polygon's radiance times
    its solid angle seen from the point (its area, foreshortened, over the squared
    distance to its centre, the distance at least its size), times the cosine at the
    point; a point's intensity over the squared distance times the cosine; a
    direction's irradiance times the cosine. What ``object_parts`` ranks the parts by
    (a glossy lobe's light over all views is about ks times it)."""
    x = np.asarray(positions, np.float64)
    n = np.asarray(normals, np.float64)
    out = np.zeros((len(x), len(parts)))
    for i, part in enumerate(parts):
        value = float(part.radiance @ LUMINANCE)
        if part.kind == "direction":
            out[:, i] = value * np.maximum(n @ -part.points[0], 0.0)
            continue
        to = part.centre[None, :] - x
        d2 = np.maximum(np.einsum("vi,vi->v", to, to), 1e-300)
        cos = np.maximum(np.einsum("vi,vi->v", n, to), 0.0) / np.sqrt(d2)
        if part.kind == "point":
            out[:, i] = value * cos / d2
        elif part.kind == "sphere":
            out[:, i] = value * np.pi * part.radius**2 / np.maximum(d2, part.radius**2) * cos
        else:
            facing = np.maximum(-(to @ part.normal), 0.0) / np.sqrt(d2)
            out[:, i] = value * part.area * facing / np.maximum(d2, part.area) * cos
    return out


def object_parts(tracer, parts, obj, directions, samples, epsilon, nodes, *, cap=MAX_RECEIVER_PARTS, drawn=None):
    """The emitter parts of the glossy object ``obj`` (a ``SceneObject``) when the scene
    has more than ``cap``: (E (V, D, 3) float64, the highlights on its grid
    ``directions`` of the parts that reach it; kept (P_o,) int32, the indices of the
    ``cap`` at most, among the first ``drawn`` of ``parts`` (default: all; the rest are
    drawn by no display), that send it the most light, ascending; their visibility
    (V, P_o) float32).

    Which parts reach it and how much: on every k-th vertex (at most
    ``COARSE_VERTICES``), ``COARSE_SAMPLES`` shadow rays a part and the light it
    sends (``incident``), summed over the vertices' areas. The dimmest parts whose
    light adds up to less than ``LEFT_OUT`` of the object's are left out (their light,
    at most that share, is lost: the gather leaves every analytic part out); every
    other one's highlight goes into the grid with its full visibility (``samples``
    rays a vertex)."""
    drawn = len(parts) if drawn is None else drawn
    v = len(obj.positions)
    _, areas = face_normals(obj.positions, obj.faces)
    area = np.zeros(v)
    np.add.at(area, np.asarray(obj.faces).ravel(), np.repeat(areas / 3.0, 3))
    sub = np.arange(0, v, max(1, -(-v // COARSE_VERTICES)))
    coarse = visibility(tracer, parts, obj.positions[sub], obj.normals[sub], min(COARSE_SAMPLES, samples), epsilon,
                        source=obj.name)
    light = area[sub] @ (coarse * incident(parts, obj.positions[sub], obj.normals[sub]))
    order = np.argsort(light, kind="stable")  # dimmest first
    total = float(light.sum())
    dropped = np.cumsum(light[order]) <= LEFT_OUT * total
    reaching = np.sort(order[~dropped & (light[order] > 0)])
    seen = visibility(tracer, [parts[i] for i in reaching], obj.positions, obj.normals, samples, epsilon,
                      source=obj.name)
    lit = seen.any(axis=0)
    reaching, seen = reaching[lit], seen[:, lit]
    grid = (grid_highlights([parts[i] for i in reaching], obj, directions, seen, nodes) if len(reaching)
            else np.zeros((v, len(directions), 3)))
    rank = [j for j in np.argsort(-light[reaching], kind="stable") if reaching[j] < drawn][:cap]
    rank = sorted(rank, key=lambda j: reaching[j])
    return grid, reaching[rank].astype(np.int32), np.ascontiguousarray(seen[:, rank], np.float32)
