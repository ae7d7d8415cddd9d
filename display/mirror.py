"""Perfect mirrors at display, as real-time renderers draw them.

A perfect mirror (a smooth conductor: ``Material.is_mirror``, no diffuse part, a Phong
stand-in of exponent >= ``MIRROR_EXPONENT``) holds nothing a per-vertex model can show:
what it shows is the scene reflected. The renderer draws it after every other surface
(``mirror_fragment.glsl``): ks F(w.n) (Schlick's F0 where the material has one) times

- for a flat mirror (``plane_of``: its points within a hundredth of its size of one plane),
  the scene drawn from the eye reflected in the mirror's plane (``mirrored_view``), what
  lies behind the plane clipped away (``clip.glsl``), looked up where the pixel's point
  projects in that view: exact, up to the reflected view's own sampling;
- for a curved one, the probe of the scene around it (``display.glass``), along the
  mirror direction, parallax-corrected against the scene's box.

Glass and other mirrors are missing from what a mirror shows (one bounce of reflection).

A near mirror (``near_mirror_of``: a flat object of a microfacet material of roughness at
most ``NEAR_MIRROR_ALPHA``, a polished floor), where the renderer is asked to
(``Renderer.near_mirrors``, ``--near-mirrors``), is drawn the same way where the displays
draw reflections (``near_fragment.glsl``): its own part (``radiosity.physics.materials.near_base``,
from the solution's grid or as the fit keeps it: a plastic's diffuse substrate, which leaves
the interface as 1 - F(n . w); a conductor's least radiance over its directions; a textured
object's kd texture(uv) E / pi) plus ks (F0 norm + (1 - F0) schlick)(alpha, n . w), its lobe's
albedo with Fresnel (``radiosity.physics.ltc.lobe_albedo``), times the scene drawn from
the eye reflected in its plane: sharp, as a mirror's (its lobe's blur is left out, which
at this roughness is a few pixels at most of a walkthrough's frame), and with what the
emitters' closed-form highlights gave it drawn from the reflected emitters themselves (a
delta light, which no surface shows, is not reflected).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from radiosity.physics.ltc import highlight_lobe
from radiosity.physics.materials import NEAR_MIRROR_ALPHA

__all__ = ["FLAT_THICKNESS", "NEAR_MIRROR_ALPHA", "mirror_of", "mirrored_view", "near_mirror_of", "plane_of"]

FLAT_THICKNESS = 0.01  # an object whose points lie within this fraction of its size of one plane is flat


def mirror_of(source):
    """(ks (3,), F0 (3,) or None) of a perfect mirror: a fitted object's ``mirror`` or a
    solution object's material; None for anything else."""
    mirror = getattr(source, "mirror", None)
    if mirror is not None:
        return tuple(mirror.specular), mirror.fresnel
    m = getattr(source, "material_record", None)  # a solution object's
    if m is not None and m.is_mirror:
        return m.specular, m.fresnel
    return None


def near_mirror_of(source):
    """The ``HighlightLobe`` (ks, F0, lobe code, alpha) of a near mirror's material, from a
    solution object's material or a fitted object's highlight; None where there is no
    microfacet model of roughness at most ``NEAR_MIRROR_ALPHA`` (flatness is ``plane_of``'s)."""
    record = getattr(source, "material_record", None)  # a solution object's
    model = None if record is None else record.microfacet
    highlight = getattr(source, "highlight", None)
    if model is None and highlight is not None and getattr(highlight, "microfacet", None) is not None:
        model = highlight.microfacet
    if model is None:  # a fitted near mirror keeps its model with its own part (fit.npz version 10)
        model = getattr(source, "near_microfacet", None)
    if model is None or model.alpha > NEAR_MIRROR_ALPHA:
        return None
    return highlight_lobe(model)


def plane_of(positions, faces):
    """(a point, the unit normal) of a flat object, else None: flat where every point lies
    within ``FLAT_THICKNESS`` of its size of the plane of least spread through its points (a
    mirror with a thin back and edges, a pane of glass as a thin closed box). The normal is
    turned to the side its faces face, and the point is its front (its points farthest
    along the normal) where they face one side; a closed slab's faces face both: its middle."""
    positions = np.asarray(positions, np.float64)
    centre = positions.mean(axis=0)
    size = np.linalg.norm(positions.max(axis=0) - positions.min(axis=0))
    if size == 0:
        return None
    spread = positions - centre
    n = np.linalg.eigh(spread.T @ spread)[1][:, 0]
    height = spread @ n
    if np.ptp(height) > FLAT_THICKNESS * size:
        return None
    corners = positions[np.asarray(faces)]
    facing = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]).sum(axis=0)
    if facing @ n < 0:
        n, height = -n, -height
    one_sided = abs(facing @ n) > 0.5 * np.linalg.norm(np.cross(corners[:, 1] - corners[:, 0],
                                                                corners[:, 2] - corners[:, 0]), axis=1).sum()
    return (positions[np.argmax(height)] if one_sided else centre), n


def mirrored_view(view, plane):
    """The camera ``view`` (``Camera``) with its eye, target and up reflected in ``plane``
    (a point, a unit normal): it sees through the mirror what the mirror shows."""
    p, n = (np.asarray(v, np.float64) for v in plane)

    def point(x):
        x = np.asarray(x, np.float64)
        return tuple(x - 2.0 * ((x - p) @ n) * n)

    up = np.asarray(view.up, np.float64)
    return replace(view, eye=point(view.eye), look_at=point(view.look_at), up=tuple(up - 2.0 * (up @ n) * n))
