"""Glass at display: what real-time renderers draw for a window or a glass ball, from a
probe of the scene around it.

A glass object (a solution's material with ``glass``, a fitted object's ``glass``) stores
nothing per vertex: what it shows is what is around it, reflected and refracted. The
renderer draws it after every other surface and the background (``glass.glsl``):

- each of its pieces (``components``: the panes of a railing) on its own: a flat piece's
  reflection is the scene drawn from the eye reflected in its plane (``display.mirror``);
- else its probe: the scene without its glass, drawn from the piece's bounding-box centre in
  the mode being drawn, six 90-degree views (``cube_views``) resampled into an octahedral
  map (``octahedral_from_faces``, the fitted probe's parametrisation, ``fitting.probe``),
  mipmapped (a rough glass reads a blurrier level, log2(alpha M));
- the reflection: the probe along the mirror direction from the point, parallax-corrected
  against the scene's box, times the specular reflectance, weighted by Fresnel's
  reflectance F (exact dielectric; a thin sheet's 2F / (1 + F));
- what passes through, weighted by 1 - F and the transmittance: for a sheet or a slab (a
  thin dielectric, or a thin object: ``proxy``) straight through, the framebuffer behind blended ("blend", the default) or the
  probe along the view ("probe"); for a solid, refracted in at the point and out through
  its bounding sphere (the proxy), 1 - F again at the exit, the probe along the ray that
  leaves.

Approximated: one refraction in and one out (the path tracer's internal reflections and
caustics through it left out), a solid's far side as its bounding sphere (exact for a
ball), other glass missing from a probe (glass seen in glass), a sheet's tint blended as
its mean, the probe's parallax by the scene's box. ``APPROACHES``: "blend", "probe", and
"none" (glass left out: the walkthrough before glass existed, to compare).
"""

from __future__ import annotations

import moderngl
import numpy as np

from display.choices import APPROACHES  # noqa: F401 (how a display draws glass)
from fitting.probe import decode
from radiosity.files.camera import Camera
from radiosity.physics.materials import Glass

__all__ = ["APPROACHES", "PROBE_SIZE", "SLAB_RATIO", "components", "cube_views", "glass_of", "octahedral_from_faces",
           "probe_texture", "proxy"]

PROBE_SIZE = 128  # texels of a side of the octahedral map (and pixels of a side of each of the six views)
SLAB_RATIO = 0.15  # an object whose mean thickness is under this of its box's largest side passes light straight
_AXES = np.eye(3)


def glass_of(source) -> Glass | None:
    """The ``Glass`` of a fitted object (``FittedObject.glass``) or a solution's object
    (its material's "glass" entry), else None."""
    glass = getattr(source, "glass", None)
    if glass is not None:
        return glass
    record = getattr(source, "material_record", None)  # a solution object's
    return None if record is None else record.glass


def cube_views(centre, size=PROBE_SIZE):
    """The six 90-degree square views from ``centre`` along +x, -x, +y, -y, +z, -z."""
    views = []
    for k in range(3):
        for sign in (1.0, -1.0):
            forward = sign * _AXES[k]
            up = _AXES[2] if k == 1 else _AXES[1]
            views.append(Camera(tuple(centre), tuple(np.asarray(centre) + forward), tuple(up), 90.0, size, size))
    return views


def octahedral_from_faces(faces, views, m=PROBE_SIZE):
    """(m, m, 3) float32: the octahedral map (texel (i, j) at row j) of the radiance the six
    ``views`` saw (``faces``: their images (S, S, 3), row 0 at the top), bilinear in each."""
    uv = (np.stack(np.meshgrid(np.arange(m), np.arange(m)), axis=-1) + 0.5) / m
    u = decode(uv).reshape(-1, 3)
    major = np.argmax(np.abs(u), axis=1)
    face = 2 * major + (u[np.arange(len(u)), major] < 0)
    out = np.zeros((len(u), 3), np.float32)
    for f, (view, image) in enumerate(zip(views, faces, strict=True)):
        sel = face == f
        right, up, forward = view.basis
        d = u[sel]
        depth = d @ forward
        x, y = (d @ right) / depth, (d @ up) / depth
        size = image.shape[0]
        col = np.clip((x + 1) / 2 * size - 0.5, 0, size - 1)
        row = np.clip((1 - y) / 2 * size - 0.5, 0, size - 1)
        c0, r0 = np.minimum(col.astype(int), size - 2), np.minimum(row.astype(int), size - 2)
        tc, tr = (col - c0)[:, None], (row - r0)[:, None]
        out[sel] = ((1 - tc) * (1 - tr) * image[r0, c0] + tc * (1 - tr) * image[r0, c0 + 1]
                    + (1 - tc) * tr * image[r0 + 1, c0] + tc * tr * image[r0 + 1, c0 + 1])
    return out.reshape(m, m, 3)


def proxy(positions, faces):
    """(slab, (centre, radius)): whether the object passes light straight, and its bounding
    sphere about its box's centre. A slab is thin: its mean thickness 2 V / A (V the volume
    its triangles enclose, A their area; 0 for an open sheet) under ``SLAB_RATIO`` of its
    box's largest side (a pane, a railing of panels, thin-walled glassware; a ball's or a
    cube's is a third of it)."""
    positions = np.asarray(positions, np.float64)
    lo, hi = positions.min(axis=0), positions.max(axis=0)
    centre = 0.5 * (lo + hi)
    radius = float(np.linalg.norm(positions - centre, axis=1).max())
    a, b, c = (positions[np.asarray(faces)[:, k]] - centre for k in range(3))
    cross = np.cross(b - a, c - a)
    area = 0.5 * np.linalg.norm(cross, axis=1).sum()
    volume = abs(np.einsum("ij,ij->i", a, np.cross(b, c)).sum()) / 6.0
    thickness = 2.0 * volume / area if area > 0 else 0.0
    return bool(thickness < SLAB_RATIO * (hi - lo).max()), (centre, radius)


def components(positions, faces):
    """The pieces of a mesh that touch nowhere: [(positions, faces)] of each connected set of
    triangles, corners at the same place joined (a box's faces with their own vertices are one
    piece). A glass object of several panes is drawn pane by pane, each with its own plane or
    probe."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    positions, faces = np.asarray(positions, np.float64), np.asarray(faces)
    size = np.linalg.norm(positions.max(axis=0) - positions.min(axis=0)) or 1.0
    _, place = np.unique(np.round(positions / (1e-6 * size)), axis=0, return_inverse=True)
    corners = place.reshape(-1)[faces]
    edges = np.concatenate([corners[:, [0, 1]], corners[:, [1, 2]]])
    n = int(place.max()) + 1
    graph = coo_matrix((np.ones(len(edges)), (edges[:, 0], edges[:, 1])), shape=(n, n))
    count, label = connected_components(graph, directed=False)
    piece = label[corners[:, 0]]
    out = []
    for k in range(count):
        mine = faces[piece == k]
        if len(mine) == 0:
            continue
        used, local = np.unique(mine, return_inverse=True)
        out.append((used, local.reshape(-1, 3)))
    return out


def probe_texture(ctx, image):
    """A mipmapped RGB float texture of an octahedral map (m, m, 3), linear filtering."""
    m = image.shape[0]
    texture = ctx.texture((m, m), 3, np.ascontiguousarray(image, np.float32).tobytes(), dtype="f4")
    texture.build_mipmaps()
    texture.filter = (moderngl.LINEAR_MIPMAP_LINEAR, moderngl.LINEAR)
    texture.repeat_x = texture.repeat_y = False
    return texture
