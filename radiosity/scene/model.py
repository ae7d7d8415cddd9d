"""The scene model: objects with shading frames and materials, refinement, and the
merged triangle array the ray tracer wants.

    Scene
      objects : tuple[SceneObject, ...]   one material each, world space
      camera  : Camera | None             the scene's default viewpoint
      environment : Environment | None    light from outside the scene, seen by rays that leave it
      lights  : tuple[EmitterPart, ...]   delta lights: points (spots) and directions, never seen

A SceneObject's arrays are float64 in the scene's units; ``Scene.merged()`` packs
all triangles into one float32 array with a triangle-to-object table.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, replace
from typing import NamedTuple

import numpy as np

from radiosity.files.camera import Camera
from radiosity.files.errors import InputError, SceneWarning
from radiosity.files.npz import check_member_name
from radiosity.physics.emitters import MAX_LIGHTS, EmitterPart
from radiosity.physics.environment import Environment
from radiosity.physics.textures import Cutout, check_opacity, check_texture, cutout_of
from radiosity.scene import geometry
from radiosity.scene.material_kernels import Material

DEFAULT_CREASE_ANGLE_DEG = 40.0
# The ray tracer (Embree) works in single precision. Beyond about 1e12 its intersection
# arithmetic overflows and every ray misses; below about 1e-13 its hit distances are
# noise; and where float32 coordinates are coarse against the scene's size (a small
# scene far from the origin) surfaces are quantised and rays re-hit the surface they
# leave. Scenes outside these limits are refused rather than solved wrongly.
MAX_COORDINATE = 1e10
MIN_SCENE_SIZE = 1e-9
MAX_RELATIVE_SPACING = 1e-4  # float32 spacing at the farthest coordinate / the scene's diagonal


@dataclass(frozen=True, eq=False)
class SceneObject:
    """One object: a triangle mesh with one material.

    positions : (V, 3) float64, world space
    normals   : (V, 3) float64, unit shading normals (split at creases)
    tangents  : (V, 3) float64, unit, orthogonal to the normals
    faces     : (F, 3) int64, counter-clockwise seen from the front
    uvs       : (V, 2) float64 texture coordinates, or None (``radiosity.physics.textures``
                states their convention: v up, repeating)
    texture   : (H, W, 3) float32 linear RGB in [0, 1], row 0 the top, or None: the
                diffuse reflectance is then kd * texture(uv) (``textures.lookup``)
    opacity   : (H, W) float32 in [0, 1], row 0 the top, or None: a mask; the surface
                is there only where opacity(uv) >= ``textures.OPACITY_CUTOFF`` (needs uvs; an
                untextured object given one is textured white, as the files carry a
                mask with the textured term)

    The texture lives on the object, not on its ``Material``: a material is a small
    validated record of numbers (solution.npz's ``meta.materials``, compared by value,
    packed into the kernels' table by name), shared by objects that may each map it
    differently; the image belongs beside the uvs that read it. Objects given the
    same image share the array, and the kernels' atlas holds it once.
    """

    name: str
    material: Material
    positions: np.ndarray
    normals: np.ndarray
    tangents: np.ndarray
    faces: np.ndarray
    source: str = ""
    uvs: np.ndarray | None = None
    texture: np.ndarray | None = None
    opacity: np.ndarray | None = None

    def __post_init__(self):
        if self.opacity is not None and self.texture is None:
            # a mask is carried by the textured diffuse term (the files keep it there): a white texture
            object.__setattr__(self, "texture", np.ones((1, 1, 3), np.float32))
        if self.uvs is not None or self.texture is not None:
            texture, uvs = check_texture(self.texture, self.uvs, len(self.positions), f"object {self.name!r}")
            object.__setattr__(self, "texture", texture)
            object.__setattr__(self, "uvs", uvs)
        object.__setattr__(self, "opacity", check_opacity(self.opacity, self.uvs, f"object {self.name!r}"))

    @property
    def textured(self):
        """Whether a texture modulates the diffuse colour."""
        return self.texture is not None

    @property
    def n_vertices(self):
        return len(self.positions)

    @property
    def n_triangles(self):
        return len(self.faces)

    @property
    def face_areas(self):
        return geometry.face_normals(self.positions, self.faces)[1]

    @property
    def area(self):
        return float(self.face_areas.sum())

    @property
    def emitted_power(self):
        """Power leaving the front faces, (3,) float64: pi * Le * area (Lambertian emitter)."""
        return np.pi * np.asarray(self.material.emission) * self.area

    @property
    def bitangents(self):
        return np.cross(self.normals, self.tangents)

    def refined(self, max_edge):
        """This object refined so that no edge is longer than ``max_edge``."""
        if self.uvs is not None:
            p, f, n, uv = geometry.refine(self.positions, self.faces, max_edge, normals=self.normals, uvs=self.uvs)
            return replace(self, positions=p, faces=f, normals=n, tangents=geometry.tangents(n), uvs=uv)
        p, f, n = geometry.refine(self.positions, self.faces, max_edge, normals=self.normals)
        return replace(self, positions=p, faces=f, normals=n, tangents=geometry.tangents(n))

    def refined_to_density(self, density, max_vertices=None):
        """This object refined conformingly to the size field ``density`` (V,): edges
        per unit length wanted at each vertex (``geometry.refine_density``)."""
        out = geometry.refine_density(
            self.positions, self.faces, density, normals=self.normals, max_vertices=max_vertices, uvs=self.uvs
        )
        p, f, n = out[:3]
        if len(f) == len(self.faces):
            return self
        uv = out[3] if self.uvs is not None else None
        return replace(self, positions=p, faces=f, normals=n, tangents=geometry.tangents(n), uvs=uv)


class MergedMesh(NamedTuple):
    """All triangles of a scene in one array, as the ray tracer takes them.

    positions       : (N, 3) float32
    faces           : (T, 3) int32, into positions
    triangle_object : (T,) int32, index of the object each triangle belongs to
    triangle_face   : (T,) int32, index of the triangle within its object
    vertex_offset   : (O + 1,) int64, object o owns positions[vertex_offset[o]:vertex_offset[o+1]]
    cutout          : ``textures.Cutout`` of the objects' opacity masks, or None without any
    """

    positions: np.ndarray
    faces: np.ndarray
    triangle_object: np.ndarray
    triangle_face: np.ndarray
    vertex_offset: np.ndarray
    cutout: Cutout | None = None

    def triangles(self):
        """(T, 3, 3) float32 vertex positions per triangle."""
        return self.positions[self.faces]


@dataclass(frozen=True, eq=False)
class Scene:
    name: str
    objects: tuple[SceneObject, ...]
    camera: Camera | None = None
    source: str = ""
    film: tuple[int, int] | None = None  # the image size the scene asks for (a Mitsuba sensor's film), if any
    environment: Environment | None = None  # light from outside the scene (``radiosity.physics.environment``)
    # delta lights (``radiosity.physics.emitters`` parts of kind "point", with an optional
    # spot profile, and "direction"), each named by its ``source``: they light the scene
    # and its glossy objects reflect them, but nothing sees them
    lights: tuple[EmitterPart, ...] = ()

    def __post_init__(self):
        if not self.objects:
            raise InputError(f"scene {self.name!r} has no objects")
        object.__setattr__(self, "lights", tuple(self.lights))
        if len(self.lights) > MAX_LIGHTS:
            raise InputError(f"scene {self.name!r} has {len(self.lights):,} lights; a scene has at most {MAX_LIGHTS:,}")
        for light in self.lights:
            if not (isinstance(light, EmitterPart) and light.is_delta):
                raise TypeError(f"scene {self.name!r}: a light must be a point or direction EmitterPart, got {light!r}")
        light_names = [light.source for light in self.lights]
        clash = sorted({n for n in light_names if light_names.count(n) > 1} | ({o.name for o in self.objects} & set(light_names)))
        if clash:
            raise InputError(f"scene {self.name!r}: a light's name must be unique among the lights and objects: "
                             f"{clash[0]!r} repeats")
        names = [o.name for o in self.objects]
        duplicate = sorted({n for n in names if names.count(n) > 1})
        if duplicate:
            raise InputError(f"scene {self.name!r}: object names must be unique: {duplicate[0]!r} repeats")
        for name in names:  # each becomes the prefix of npz member names in the solution file
            try:
                check_member_name(name)
            except ValueError as exc:
                raise InputError(f"scene {self.name!r}: object {name!r}: {exc}") from None
        self._check_precision()

    def _check_precision(self):
        """Refuse a scene the single-precision ray tracer cannot resolve (InputError)."""
        far = max(self.objects, key=lambda o: np.abs(o.positions).max())
        reach = float(np.abs(far.positions).max())
        if not reach <= MAX_COORDINATE:
            raise InputError(
                f"scene {self.name!r}: object {far.name!r} reaches {reach:.3g} from the origin, beyond the "
                f"+-{MAX_COORDINATE:g} the single-precision ray tracer handles"
            )
        size = self.diagonal
        if size < MIN_SCENE_SIZE:
            raise InputError(
                f"scene {self.name!r} is {size:.3g} units across, below the {MIN_SCENE_SIZE:g} the "
                "single-precision ray tracer resolves; scale it up ('scale')"
            )
        spacing = float(np.spacing(np.float32(reach)))
        if spacing > MAX_RELATIVE_SPACING * size:
            raise InputError(
                f"scene {self.name!r} is {size:.3g} units across but reaches {reach:.3g} from the origin, where "
                f"single-precision coordinates are {spacing:.3g} apart (more than {MAX_RELATIVE_SPACING:g} of its "
                "size); move it nearer the origin ('translate')"
            )

    @property
    def materials(self):
        """Materials in first-use order, by name."""
        out = {}
        for o in self.objects:
            out.setdefault(o.material.name, o.material)
        return out

    @property
    def emitters(self):
        """The emitting objects (the delta lights are ``lights``)."""
        return [o for o in self.objects if o.material.is_emitter]

    @property
    def is_lit(self):
        """Whether anything emits light: an object, the environment or a delta light."""
        return bool(self.emitters or self.lights or self.environment is not None)

    @property
    def bounding_sphere(self):
        """(centre (3,), radius) of the ball around the scene's bounding box, a little
        larger (by 1e-4): where a directional light's (and the environment's) photons
        start from."""
        lo, hi = self.bounds
        return 0.5 * (lo + hi), 0.5 * float(np.linalg.norm(hi - lo)) * (1 + 1e-4)

    @property
    def bounds(self):
        """(2, 3) float64: min and max corner."""
        p = np.concatenate([o.positions for o in self.objects])
        return np.stack([p.min(axis=0), p.max(axis=0)])

    @property
    def diagonal(self):
        lo, hi = self.bounds
        return float(np.linalg.norm(hi - lo))

    @property
    def n_triangles(self):
        return sum(o.n_triangles for o in self.objects)

    @property
    def n_vertices(self):
        return sum(o.n_vertices for o in self.objects)

    def object(self, name):
        for o in self.objects:
            if o.name == name:
                return o
        raise KeyError(name)

    def refined(self, max_edge):
        """The scene with every object refined to edges no longer than ``max_edge``."""
        return replace(self, objects=tuple(o.refined(max_edge) for o in self.objects))

    def merged(self):
        """One triangle array for the ray tracer, with a triangle-to-object table."""
        offsets = np.cumsum([0] + [o.n_vertices for o in self.objects])
        faces = np.concatenate([o.faces + off for o, off in zip(self.objects, offsets)])
        triangle_object = np.concatenate([np.full(o.n_triangles, i, dtype=np.int32) for i, o in enumerate(self.objects)])
        cutout = None
        if any(o.opacity is not None for o in self.objects):
            uvs = np.concatenate([o.uvs if o.uvs is not None else np.zeros((o.n_vertices, 2)) for o in self.objects])
            cutout = cutout_of(self.objects, triangle_object, faces, uvs)
        return MergedMesh(
            positions=np.concatenate([o.positions for o in self.objects]).astype(np.float32),
            faces=faces.astype(np.int32),
            triangle_object=triangle_object,
            triangle_face=np.concatenate(
                [np.arange(o.n_triangles, dtype=np.int32) for o in self.objects]
            ),
            vertex_offset=offsets.astype(np.int64),
            cutout=cutout,
        )


def build_object(
    name,
    material,
    positions,
    faces,
    *,
    crease_angle_deg=DEFAULT_CREASE_ANGLE_DEG,
    source="",
    warn_degenerate=True,
    normals=None,
    uvs=None,
    texture=None,
    opacity=None,
):
    """A SceneObject from a raw triangle soup in world space, or None when every
    triangle is degenerate (the object is left out, as Mitsuba leaves it out, with one
    SceneWarning saying so).

    Checks coordinates, welds coincident vertices, drops degenerate triangles (with a
    SceneWarning counting them), and computes crease-split normals and tangents.
    ``normals`` (V, 3), a mesh file's own per-vertex normals, are kept instead (the
    vertices are then not welded: a seam's copies keep their own normals); where one
    is zero or not finite, or points away from every triangle using the vertex, the
    computed one is used. ``uvs`` (V, 2) texture coordinates, a ``texture`` (H, W,
    3) and an ``opacity`` mask (H, W) (``SceneObject``) are kept: vertices at one point with other uvs (a texture's
    seam) are not welded, and the normals are smooth across the seam.
    """
    where = f"object {name!r}" + (f" ({source})" if source else "")
    positions = np.asarray(positions, dtype=np.float64)
    faces = np.asarray(faces)
    if positions.ndim != 2 or positions.shape[1] != 3:
        raise InputError(f"{where}: positions must be (V, 3), got shape {positions.shape}")
    if faces.ndim != 2 or faces.shape[1] != 3 or len(faces) == 0:
        raise InputError(f"{where}: has no triangles")
    bad = ~np.isfinite(positions).all(axis=1)
    if bad.any():
        raise InputError(
            f"{where}: {int(bad.sum())} of {len(positions)} vertices have NaN or infinite coordinates"
        )
    if len(positions) and np.abs(positions).max() > MAX_COORDINATE:
        raise InputError(
            f"{where}: coordinates reach {np.abs(positions).max():.3g}, beyond the +-{MAX_COORDINATE:g} "
            "the single-precision ray tracer handles; scale the mesh down"
        )
    faces = faces.astype(np.int64)
    if faces.min() < 0 or faces.max() >= len(positions):
        raise InputError(f"{where}: a triangle refers to a vertex that does not exist")
    texture, uvs = check_texture(texture, uvs, len(positions), where)
    opacity = check_opacity(opacity, uvs, where)
    if normals is not None:
        return _with_normals(name, material, positions, faces, normals, where=where, source=source,
                             warn_degenerate=warn_degenerate, uvs=uvs, texture=texture, opacity=opacity)
    extent = float(np.ptp(positions[faces.ravel()], axis=0).max())
    tol = 1e-9 * max(extent, np.finfo(float).tiny)
    if uvs is None:
        positions, faces = geometry.weld(positions, faces, tol)
        positions, faces, dropped = geometry.remove_degenerate(positions, faces)
    else:
        positions, faces, uvs = geometry.weld(positions, faces, tol, uvs=uvs)
        keep = _not_degenerate(positions, faces)
        dropped = int(len(faces) - keep.sum())
        positions, faces, uvs = geometry.compact(positions, faces[keep], uvs)
    if len(faces) == 0:
        return _left_out(where, dropped)
    if dropped and warn_degenerate:
        warnings.warn(f"{where}: dropped {dropped} degenerate triangle(s)", SceneWarning, stacklevel=2)
    if uvs is None:
        positions, faces, normals = geometry.crease_normals(positions, faces, crease_angle_deg)
    else:
        positions, faces, normals, uvs = geometry.crease_normals(positions, faces, crease_angle_deg, uvs=uvs)
    return SceneObject(
        name=name,
        material=material,
        positions=positions,
        normals=normals,
        tangents=geometry.tangents(normals),
        faces=faces,
        source=source,
        uvs=uvs,
        texture=texture,
        opacity=opacity,
    )


def _left_out(where, dropped):
    """None, after the one warning for an object whose ``dropped`` triangles were all degenerate."""
    warnings.warn(f"{where}: all {dropped} triangle(s) are degenerate (zero area): the object is left out",
                  SceneWarning, stacklevel=3)
    return None


def _not_degenerate(positions, faces):
    """(F,) bool: the triangles ``geometry.remove_degenerate`` keeps (no repeated
    vertex, an area above 1e-14 of the squared diagonal of the used vertices' box)."""
    repeated = (faces[:, 0] == faces[:, 1]) | (faces[:, 1] == faces[:, 2]) | (faces[:, 2] == faces[:, 0])
    diag2 = float(np.sum(np.ptp(positions[faces.ravel()], axis=0) ** 2)) if len(faces) else 0.0
    _, area = geometry.face_normals(positions, faces)
    return ~repeated & (area > 1e-14 * diag2)


def _with_normals(name, material, positions, faces, normals, *, where, source, warn_degenerate, uvs=None,
                  texture=None, opacity=None):
    """``build_object``'s path for a mesh with its own per-vertex normals."""
    normals = np.asarray(normals, dtype=np.float64)
    if normals.shape != positions.shape:
        raise InputError(f"{where}: {len(normals)} normals for {len(positions)} vertices")
    keep = _not_degenerate(positions, faces)  # as geometry.remove_degenerate
    dropped = int(len(faces) - keep.sum())
    if not keep.any():
        return _left_out(where, dropped)
    if dropped and warn_degenerate:
        warnings.warn(f"{where}: dropped {dropped} degenerate triangle(s)", SceneWarning, stacklevel=3)
    if uvs is None:
        positions, faces, normals = geometry.compact(positions, faces[keep], normals)
    else:
        positions, faces, normals, uvs = geometry.compact(positions, faces[keep], normals, uvs)
    face_n, area = geometry.face_normals(positions, faces)
    length = np.linalg.norm(normals, axis=1)
    unit = normals / np.where(length > 0, length, 1.0)[:, None]
    average = np.zeros_like(positions)
    agrees = np.full(len(positions), -np.inf)
    for corner in range(3):
        np.add.at(average, faces[:, corner], face_n * area[:, None])
        np.maximum.at(agrees, faces[:, corner], np.einsum("ij,ij->i", unit[faces[:, corner]], face_n))
    bad = ~np.isfinite(length) | (length < 1e-12) | ~(agrees > 0)  # none given, or facing away from its triangles
    unit[bad] = average[bad] / np.linalg.norm(average[bad], axis=1, keepdims=True)
    return SceneObject(name=name, material=material, positions=positions, normals=unit,
                       tangents=geometry.tangents(unit), faces=faces, source=source, uvs=uvs, texture=texture,
                       opacity=opacity)


BACK_OFFSET = 1e-4  # a two-sided surface's back lies behind its front by this fraction of the scene's diagonal


def is_closed(obj):
    """Whether a surface is closed (every edge shared by exactly two triangles): its
    back faces inwards and is never seen, so a two-sided material needs no back."""
    faces = geometry.position_labels(obj.positions)[obj.faces]  # the copies split at a crease are one point
    edges = np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), axis=1)
    _, counts = np.unique(edges, axis=0, return_counts=True)
    return bool(np.all(counts == 2))


def back_of(front, name, offset):
    """The back of a two-sided surface (surfaces are one-sided: the back absorbs): a
    reversed copy ``offset`` behind the front, along its normals, so that light from
    behind meets it first; the ray tracer's offset (1e-5 of the diagonal) stays below.
    The back reflects as the front does but emits nothing: a two-sided material makes
    a surface reflect on both sides, not a lamp shine backwards (Mitsuba's area lights
    emit from the front alone, whatever their bsdf); its material is then the front's
    without emission, named "<material> (back)"."""
    material = front.material
    if material.is_emitter:
        material = replace(material, name=f"{material.name} (back)", emission=(0.0, 0.0, 0.0))
    return SceneObject(name=name, material=material, positions=front.positions - offset * front.normals,
                       normals=-front.normals, tangents=-front.tangents, faces=front.faces[:, ::-1].copy(),
                       source=front.source, uvs=front.uvs, texture=front.texture, opacity=front.opacity)


def with_backs(objects, two_sided):
    """``objects`` with a back (``back_of``) after each open surface whose name is in
    ``two_sided``, named "<name> (back)"."""
    everything = np.concatenate([o.positions for o in objects])
    offset = BACK_OFFSET * float(np.linalg.norm(np.ptp(everything, axis=0)))
    names = {o.name for o in objects}
    out = []
    for obj in objects:
        out.append(obj)
        if obj.name in two_sided and not is_closed(obj):
            name = f"{obj.name} (back)"
            while name in names:
                name += "'"
            names.add(name)
            out.append(back_of(obj, name, offset))
    return tuple(out)
