"""The scene: shapes, shapegroups and instances placed, emitters (area, point, spot,
directional, constant, envmap) and the sensor, into a ``Scene`` (``load_mitsuba``).
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from radiosity.files.camera import Camera, fov_y_deg, pose_from_matrix
from radiosity.files.errors import InputError
from radiosity.physics.environment import Environment, read_environment_image
from radiosity.scene.lights import DEFAULT_CUTOFF_DEG, directional_light, point_light, spot_light
from radiosity.scene.material_kernels import Material
from radiosity.scene.model import DEFAULT_CREASE_ANGLE_DEG, Scene, build_object, with_backs

from .bsdfs import _Surface, _surface
from .document import _Document
from .meshes import Tessellation, _analytic, _mesh_file
from .values import _Props

MAX_SHAPES = 20_000  # shapes placed in all, instances' shapes included (the collection's largest places 655)
DEFAULT_FILM = (768, 576)  # Mitsuba's hdrfilm
DEFAULT_FOCAL_LENGTH_MM = 50.0  # Mitsuba 0.6's perspective camera




@dataclass
class _Shape:
    name: str
    positions: np.ndarray
    faces: np.ndarray
    normals: np.ndarray | None
    surface: _Surface
    emission: tuple
    source: str
    crease: float
    uvs: np.ndarray | None = None
    texture: np.ndarray | None = None
    opacity: np.ndarray | None = None


class _Reader:
    def __init__(self, path, tessellation):
        self.doc = _Document(path)
        self.tessellation = tessellation
        self.shapes = []
        self.lights = []  # delta lights (``radiosity.scene.lights``)
        self.camera = None
        self.names = set()
        self.placed = 0  # shapes placed, instances' shapes counted (``MAX_SHAPES``)
        self.environment = None

    def read(self):
        for node in self.doc.elements:
            if node.tag == "shape":
                self._shape(node, np.eye(4))
            elif node.tag == "emitter":
                self._emitter(node)
            elif node.tag == "sensor":
                if self.camera is None:
                    self.camera = _camera(self.doc, node)
                else:
                    node.warn("a second sensor: the first is the scene's camera")
            elif node.tag in ("bsdf", "texture", "integrator", "sampler", "film", "rfilter", "medium", "phase"):
                if node.tag in ("medium", "phase"):
                    node.warn("participating media are not modelled: left out")
            else:
                raise node.fail(f"<{node.tag}> is not a scene element this reader knows")

    def _name(self, node, fallback):
        base = node.attrs.get("id") or fallback
        base = re.sub(r"[\x00-\x1f\x7f/]", "_", base) or "shape"
        name, n = base, 1
        while name in self.names:
            n += 1
            name = f"{base}#{n}"
        self.names.add(name)
        return name

    def _shape(self, node, outer, groups=()):
        kind = node.attrs.get("type")
        props = _Props(self.doc, node)
        if kind == "shapegroup":
            return  # drawn where an instance places it
        self.placed += 1
        if self.placed > MAX_SHAPES:
            raise node.fail(f"more than {MAX_SHAPES:,} shapes in all, instances' shapes counted (nested instances "
                            "multiply)")
        props.check_refs(("shape:shapegroup",) if kind == "instance" else ("bsdf", "emitter", "medium"))
        if kind == "instance":
            group = [t for t in props.unnamed if t.tag == "shape" and t.attrs.get("type") == "shapegroup"]
            group += [t for _, t in props.named.values() if t.tag == "shape" and t.attrs.get("type") == "shapegroup"]
            if not group:
                raise node.fail("needs a <ref> to a shapegroup")
            if any(group[0] is g for g in groups):
                raise node.fail("instances the shapegroup it is in (a cycle of instances)")
            place = outer @ props.transform("to_world")
            for child in group[0].children:
                if child.tag == "shape":
                    self._shape(child, place, (*groups, group[0]))
            return
        bsdfs = [t for t in props.unnamed if t.tag == "bsdf"]
        surface = _surface(self.doc, bsdfs[0]) if bsdfs else _Surface()
        textured = surface.texture is not None
        if kind in ("obj", "ply", "serialized"):
            positions, faces, normals, uvs = _mesh_file(self.doc, node, props)
            if props.boolean("face_normals"):
                normals = None
            to_world = outer @ props.transform("to_world")
            fallback = f"{kind}_{len(self.shapes)}_{Path(props.string('filename')).stem}"
            crease = 0.0 if props.boolean("face_normals") else DEFAULT_CREASE_ANGLE_DEG
        elif kind in ("rectangle", "disk", "sphere", "cube", "cylinder"):
            positions, faces, uvs, to_world = _analytic(node, props, self.tessellation,
                                                        textured or surface.opacity is not None)
            to_world = outer @ to_world
            normals = None
            fallback = f"{kind}_{len(self.shapes)}"
            crease = 180.0 if kind in ("sphere", "cylinder") else DEFAULT_CREASE_ANGLE_DEG
        else:
            raise node.fail(f"shape type {kind!r} is not read (obj, ply, serialized, rectangle, disk, sphere, cube, "
                            "cylinder, shapegroup, instance are)")
        texture = None
        opacity = self._opacity(node, surface, uvs)
        if textured and uvs is None:
            node.warn(f"the mesh has no texture coordinates: texture {surface.texture.filename!r} taken as its "
                      f"mean colour {tuple(round(float(c), 4) for c in surface.texture.mean)}")
            surface = surface.untextured()
        elif textured:
            texture, uvs = surface.texture.reading(uvs, node.where)
        emission = (0.0, 0.0, 0.0)
        for child in node.children:
            if child.tag == "emitter":
                if child.attrs.get("type") != "area":
                    raise child.fail("a shape's emitter must be of type 'area'")
                emission = _Props(self.doc, child).colour("radiance", 1.0)
                if min(emission) < 0:
                    raise child.fail(f"the radiance must not be negative, got {tuple(float(c) for c in emission)}")
        if not surface.visible and not any(emission):
            return
        if not surface.visible:  # a null bsdf around a lamp: it emits but reflects nothing
            surface = _Surface(diffuse=(0.0, 0.0, 0.0))
        positions = positions @ to_world[:3, :3].T + to_world[:3, 3]
        if normals is not None:
            normals = normals @ np.linalg.inv(to_world[:3, :3])
        if np.linalg.slogdet(to_world[:3, :3])[0] < 0 and (normals is not None or kind not in ("obj", "ply", "serialized")):
            # a mirroring transform turns the winding around; Mitsuba 3 keeps a mirrored mesh's facing only where
            # its own vertex normals say so (a mesh without them faces as its unturned winding does)
            faces = faces[:, ::-1]
        if props.boolean("flip_normals"):
            faces = faces[:, ::-1]
            normals = None if normals is None else -normals
        self.shapes.append(_Shape(self._name(node, fallback), positions, np.ascontiguousarray(faces), normals,
                                  surface, tuple(emission), node.where, crease,
                                  uvs if texture is not None or opacity is not None else None, texture, opacity))

    @staticmethod
    def _opacity(node, surface, uvs):
        """A masked shape's opacity (H, W) through its texture coordinates, or None (opaque,
        with a warning where the mask cannot be read so: no uvs, or a mask or texture
        that maps them (``to_uv``, a wrap mode other than repeat))."""
        mask = surface.opacity
        if mask is None:
            return None
        if uvs is None:
            node.warn(f"the mesh has no texture coordinates: the mask {mask.filename!r} is left out (opaque)")
            return None
        if not mask.reads_as_given or (surface.texture is not None and not surface.texture.reads_as_given):
            node.warn(f"the mask {mask.filename!r} or the texture beneath it maps its texture coordinates "
                      "(to_uv, or a wrap mode other than repeat): the mask is left out (opaque)")
            return None
        return mask.opacity

    def _emitter(self, node):
        kind = node.attrs.get("type")
        props = _Props(self.doc, node)
        if kind in ("point", "spot", "directional"):
            self.lights.append(self._light(node, kind, props))
        elif kind in ("constant", "envmap"):
            if self.environment is not None:
                node.warn("a second environment emitter: left out (the first is the scene's environment)")
            else:
                self.environment = _environment(self.doc, node, props)
        elif kind in ("sunsky", "sky", "sun"):
            node.warn(f"{kind} emitters (light from outside the scene) are not modelled yet: left out")
        elif kind == "area":
            raise node.fail("an area emitter must be inside the <shape> that emits")
        else:
            raise node.fail(f"emitter type {kind!r} is not read")

    def _light(self, node, kind, props):
        """The delta light (``radiosity.scene.lights``) of a point, spot or directional emitter."""
        name = self._name(node, f"{kind}_light_{len(self.lights) + 1}")
        where = node.where
        if kind == "directional":
            direction = props.vector("direction")
            if direction is not None and "to_world" in props.named:
                raise node.fail("give 'direction' or 'to_world', not both")
            if direction is None:
                direction = props.transform("to_world")[:3, :3] @ np.array([0.0, 0.0, 1.0])
            return directional_light(name, direction, props.colour("irradiance", 1.0), where)
        to_world = props.transform("to_world")
        position = props.vector("position") if kind == "point" else None
        if position is not None and "to_world" in props.named:
            raise node.fail("give 'position' or 'to_world', not both")
        if position is None:
            position = to_world[:3, 3]
        intensity = props.colour("intensity", 1.0)
        if kind == "point":
            return point_light(name, position, intensity, where)
        if "texture" in props.named:
            node.warn("a spot light's projected texture is not modelled: left out (the spot is its intensity alone)")
        linear = to_world[:3, :3]
        singular = np.linalg.svd(linear, compute_uv=False)
        if singular.min() > 0 and np.abs(singular / singular.max() - 1).max() > 1e-6:
            node.warn("the spot's to_world scales unevenly or shears (its cone would be elliptical): only the "
                      "direction of its +z is kept, the cone stays round")
        return spot_light(name, position, linear @ np.array([0.0, 0.0, 1.0]), intensity, where,
                          props.float("cutoff_angle", DEFAULT_CUTOFF_DEG), props.float("beam_width"))

    def scene(self, name):
        if not self.shapes:
            raise InputError(f"{self.doc.path}: no shapes this reader can use")
        fronts = [build_object(shape.name, _to_material(shape), shape.positions, shape.faces,
                               crease_angle_deg=shape.crease, source=shape.source, normals=shape.normals,
                               uvs=shape.uvs, texture=shape.texture, opacity=shape.opacity)
                  for shape in self.shapes]
        fronts = [o for o in fronts if o is not None]  # None: every triangle degenerate (warned), as Mitsuba drops it
        if not fronts:
            raise InputError(f"{self.doc.path}: every shape's triangles are degenerate: nothing is left to draw")
        objects = list(with_backs(fronts, {shape.name for shape in self.shapes if shape.surface.twosided}))
        film = None if self.camera is None else (self.camera.width, self.camera.height)
        return Scene(name=name, objects=tuple(objects), camera=self.camera, source=str(self.doc.path), film=film,
                     environment=self.environment, lights=tuple(self.lights))

def _environment(doc, node, props):
    """The ``Environment`` of a ``constant`` or ``envmap`` emitter."""
    to_world = props.transform("to_world")[:3, :3]
    u, singular, vt = np.linalg.svd(to_world)
    if not singular.min() > 0:
        raise node.fail("the environment's to_world is singular")
    rotation = u @ vt
    if np.abs(singular / singular.max() - 1).max() > 1e-6:
        node.warn("the environment's to_world scales or shears: only its rotation is kept")
    scale = props.float("scale", 1.0)
    if node.attrs.get("type") == "constant":
        return Environment.uniform(props.colour("radiance", 1.0), scale, rotation, node.where)
    filename = props.string("filename")
    if filename is None:
        raise node.fail("needs a 'filename'")
    path = doc.resolve(node, filename)
    return Environment.from_image(read_environment_image(path, node.where), scale, rotation, node.where)


def _to_material(shape):
    s = shape.surface
    try:
        return Material(name=shape.name, diffuse=s.diffuse, specular=s.specular, exponent=s.exponent,
                        emission=shape.emission, fresnel=s.fresnel, microfacet=s.microfacet, glass=s.glass)
    except InputError as exc:
        raise InputError(f"{shape.source}: {exc}") from None


def _camera(doc, node):
    kind = node.attrs.get("type")
    if kind not in ("perspective", "thinlens", "perspective_rdist"):
        node.warn(f"sensor type {kind!r} is not a pinhole camera: no default camera")
        return None
    props = _Props(doc, node)
    films = [c for c in node.children if c.tag == "film"]
    width, height = DEFAULT_FILM
    if films:
        film = _Props(doc, films[0])
        width, height = film.integer("width", width), film.integer("height", height)
        if width < 1 or height < 1:
            raise films[0].fail(f"a film of {width} x {height} pixels: its width and height must be at least 1")
    fov = props.float("fov")
    if fov is None:
        focal = props.string("focal_length", f"{DEFAULT_FOCAL_LENGTH_MM}mm")
        match = re.fullmatch(r"\s*([0-9]*\.?[0-9]+)\s*(mm)?\s*", focal)
        if not match or not float(match.group(1)) > 0:
            raise node.fail(f"focal length {focal!r} is not like '50mm'")
        # Mitsuba 0.6 and 3: the diagonal field of view of a 36 x 24 mm film
        fov = math.degrees(2 * math.atan(math.hypot(36.0, 24.0) / (2 * float(match.group(1)))))
        axis = "diagonal"
    else:
        axis = props.string("fov_axis", "x").lower()
    try:
        fov_y_deg(fov, axis, width, height)  # the fov and its axis checked before the transform
    except InputError as exc:
        raise node.fail(str(exc).removeprefix("camera: ")) from None
    eye, look_at, up, mirrored = pose_from_matrix(props.transform("to_world"))
    if mirrored:
        node.warn("the sensor's transform mirrors the image (a negative scale): drawn unmirrored")
    try:  # the fov kept along its axis: at another image size, Mitsuba 3's view of the same sensor
        return Camera(eye, look_at, up, fov, width, height, axis)
    except InputError as exc:
        raise node.fail(str(exc)) from None


def load_mitsuba(path, tessellation=None):
    """A Scene from a Mitsuba XML file (see the module docstring)."""
    path = Path(path)
    reader = _Reader(path, tessellation or Tessellation())
    reader.read()
    return reader.scene(path.stem)
