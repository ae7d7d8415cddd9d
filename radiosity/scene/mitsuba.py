"""Mitsuba XML scenes: the format of the rendering community's test scenes.

``load_mitsuba(path)`` reads a scene written for Mitsuba 0.4-0.6 or 2-3 and returns a
Scene. What it reads, and what it does with it:

Document
    ``<scene version=...>``; ``<default name value>`` and ``$name`` in any attribute;
    ``id`` on any element and ``<ref id>`` to it; ``<include filename>``; property
    names in either spelling (``toWorld`` / ``to_world``, ``intIOR`` / ``int_ior``).
    Values: ``float``, ``integer``, ``boolean``, ``string``, ``rgb``, ``srgb`` (hex or
    numbers, sRGB-decoded), ``spectrum`` (a constant, or wavelength:value pairs
    averaged over three bands, with a warning), ``point`` / ``vector``.
Transforms
    ``matrix`` (16 or 9 numbers, row-major), ``translate``, ``rotate`` (axis and angle
    in degrees), ``scale``, ``lookat``: each applied after the ones before it.
Shapes
    ``obj``, ``ply`` (the file's per-vertex normals kept unless ``face_normals``),
    ``serialized`` (Mitsuba's compressed mesh format, ``shape_index``), and, tessellated
    (``Tessellation`` says how finely): ``rectangle`` ([-1, 1]^2 in z = 0, facing +z),
    ``disk`` (the unit disk, facing +z), ``sphere`` (``center``, ``radius``), ``cube``
    ([-1, 1]^3), ``cylinder`` (``p0``, ``p1``, ``radius``; open ends); ``shapegroup``
    and ``instance``; ``flip_normals``.
Materials (onto Lambert + modified Phong, ``radiosity.scene.microfacet`` measures the
lobes): ``diffuse``; ``twosided`` (the surface gets a back: a second, reversed copy
    a hair behind it, unless the mesh is closed and its inside never seen);
    ``plastic`` / ``roughplastic`` and ``conductor`` / ``roughconductor`` by the rule
    of ``microfacet.phong_lobe_for``; anything else (dielectrics, masks, bump and
    normal maps, blends, principled, ...) approximated with one warning saying how.
    A texture where a colour goes counts with its mean colour (with a warning).
Emitters
    ``area`` (a shape's radiance); ``point`` and ``spot`` as a small sphere lamp of
    the same intensity (a spot's cone is not kept: a warning says so); ``constant``,
    ``envmap`` and ``directional`` are not modelled yet: left out with a warning.
Sensor
    ``perspective`` / ``thinlens`` as the scene's camera: ``fov`` with its
    ``fov_axis`` (x, y, diagonal, smaller, larger) or 0.6's ``focalLength``, the
    transform (``lookat`` or a matrix; a mirroring one is drawn unmirrored, with a
    warning), and the film's width and height.

Integrators, samplers, films' other settings and media are not read (the solver's own
settings apply). Every problem is an InputError naming the file, the line and the
element; every approximation a SceneWarning naming them too.
"""

from __future__ import annotations

import math
import re
import struct
import warnings
import zlib
from dataclasses import dataclass, field
from pathlib import Path
from xml.parsers import expat

import numpy as np
import trimesh

from radiosity.formats.camera import Camera, fov_y_deg, pose_from_matrix
from radiosity.formats.errors import InputError, SceneWarning
from radiosity.formats.inputs import MAX_NESTING, MESH_BYTES, TEXT_BYTES, read_input_bytes
from radiosity.formats.material import fresnel_kd_limit, srgb_to_linear
from radiosity.scene import builtins, microfacet
from radiosity.scene.materials import Material
from radiosity.scene.meshfiles import read_mesh_with_normals
from radiosity.scene.model import DEFAULT_CREASE_ANGLE_DEG, Scene, build_object, with_backs

__all__ = ["Tessellation", "load_mitsuba", "read_serialized"]

MAX_INCLUDES = 16  # nested <include> depth
POINT_LAMP_RADIUS = 2e-3  # a point or spot light's sphere, as a fraction of the scene's diagonal
DEFAULT_FILM = (768, 576)  # Mitsuba's hdrfilm
DEFAULT_FOCAL_LENGTH_MM = 50.0  # Mitsuba 0.6's perspective camera


@dataclass(frozen=True)
class Tessellation:
    """How finely analytic shapes become triangles: ``segments`` around a disk or a
    cylinder, ``sphere_levels`` icosphere subdivisions (level 3: 1,280 triangles)."""

    segments: int = 64
    sphere_levels: int = 3

    def __post_init__(self):
        if not (isinstance(self.segments, int) and 3 <= self.segments <= 4096):
            raise InputError(f"tessellation: segments must be a whole number from 3 to 4096, got {self.segments!r}")
        if not (isinstance(self.sphere_levels, int) and 0 <= self.sphere_levels <= 7):
            raise InputError(
                f"tessellation: sphere levels must be a whole number from 0 to 7, got {self.sphere_levels!r}"
            )


# -- the document ------------------------------------------------------------------------


@dataclass
class Node:
    """One XML element: tag, attributes, children, and where it is (file, line)."""

    tag: str
    attrs: dict
    file: str
    line: int
    children: list = field(default_factory=list)

    @property
    def where(self):
        kind = f" type={self.attrs['type']!r}" if "type" in self.attrs else ""
        name = f" name={self.attrs['name']!r}" if "name" in self.attrs else ""
        return f"{self.file}:{self.line}: <{self.tag}{kind}{name}>"

    def fail(self, problem):
        return InputError(f"{self.where}: {problem}")

    def warn(self, what):
        warnings.warn(f"{self.where}: {what}", SceneWarning, stacklevel=3)


def _parse_xml(path):
    """The root Node of an XML file, with line numbers (expat, which refuses entity
    expansion bombs); InputError naming the file and line of a syntax error."""
    data = read_input_bytes(path, "scene", TEXT_BYTES)
    shown = str(path)
    parser = expat.ParserCreate()
    stack = [Node("#document", {}, shown, 0)]

    def start(tag, attrs):
        node = Node(tag, dict(attrs), shown, parser.CurrentLineNumber)
        if len(stack) > MAX_NESTING:
            raise node.fail(f"elements nested more than {MAX_NESTING} deep")
        stack[-1].children.append(node)
        stack.append(node)

    def end(_tag):
        stack.pop()

    parser.StartElementHandler, parser.EndElementHandler = start, end
    try:
        parser.Parse(data, True)
    except expat.ExpatError as exc:
        raise InputError(f"{shown}:{exc.lineno}: malformed XML: {expat.errors.messages[exc.code]}") from None
    roots = stack[0].children
    if len(roots) != 1 or roots[0].tag != "scene":
        raise InputError(f"{shown}: not a Mitsuba scene (the root element must be <scene>)")
    return roots[0]


def _snake(name):
    """Mitsuba 0.x's camelCase property names in 2-3's spelling: toWorld -> to_world,
    intIOR -> int_ior, fovAxis -> fov_axis."""
    name = re.sub(r"([a-z0-9])([A-Z])", r"\1_\2", name)
    return re.sub(r"([A-Z]+)([A-Z][a-z])", r"\1_\2", name).lower()


_PARAMETER = re.compile(r"\$([A-Za-z_][A-Za-z0-9_]*)")


class _Document:
    """A scene's elements after includes, ``$name`` substitution and ids."""

    def __init__(self, path):
        self.path = Path(path)
        self.base = self.path.parent
        root = _parse_xml(self.path)
        self.version = root.attrs.get("version", "")
        self.major = _major_version(root)
        self.params = {}
        for node in root.children:
            if node.tag == "default":
                name, value = node.attrs.get("name"), node.attrs.get("value")
                if name is None or value is None:
                    raise node.fail("needs 'name' and 'value'")
                self.params.setdefault(name, value)
        self.elements = self._expand(root.children, 0)
        self.ids = {}
        for node in self._walk(self.elements):
            if "id" in node.attrs and node.tag != "ref":
                self.ids.setdefault(node.attrs["id"], node)

    def _walk(self, nodes):
        for node in nodes:
            yield node
            yield from self._walk(node.children)

    def _substitute(self, node):
        for key, value in node.attrs.items():
            if "$" in value:
                def lookup(match, node=node):
                    name = match.group(1)
                    if name not in self.params:
                        raise node.fail(f"unknown parameter ${name} (no <default name={name!r}>)")
                    return self.params[name]

                node.attrs[key] = _PARAMETER.sub(lookup, value)
        for child in node.children:
            self._substitute(child)

    def _expand(self, nodes, depth):
        out = []
        for node in nodes:
            if node.tag == "default":
                continue
            self._substitute(node)
            if node.tag == "include":
                if depth >= MAX_INCLUDES:
                    raise node.fail(f"includes nested more than {MAX_INCLUDES} deep")
                name = node.attrs.get("filename")
                if not name:
                    raise node.fail("needs a 'filename'")
                included = _parse_xml(self.resolve(node, name))
                out += self._expand(included.children, depth + 1)
            else:
                out.append(node)
        return out

    def resolve(self, node, name):
        """A file a scene element names, relative to the scene's directory."""
        path = self.base / name
        if not path.is_file():
            raise node.fail(f"file {str(path)!r} not found")
        return path

    def deref(self, node, tags):
        """``node`` itself, or the element its ``<ref id>`` names (one of ``tags``)."""
        if node.tag != "ref":
            return node
        ident = node.attrs.get("id")
        target = self.ids.get(ident)
        if target is None:
            raise node.fail(f"no element has id {ident!r}")
        if target.tag not in tags:
            raise node.fail(f"id {ident!r} is a <{target.tag}>, not a {' or '.join(f'<{t}>' for t in tags)}")
        return target


def _major_version(root):
    text = root.attrs.get("version", "")
    match = re.match(r"\s*(\d+)\.(\d+)", text)
    if not match:
        if text:
            raise root.fail(f"version {text!r} is not a version number")
        return 3
    major, minor = int(match.group(1)), int(match.group(2))
    if major == 0 and minor < 4 or major > 3:
        raise root.fail(f"version {text} is not one this reader knows (0.4 to 0.6, 2 and 3)")
    return major


# -- properties --------------------------------------------------------------------------


def _numbers(node, text, count=None):
    try:
        values = [float(v) for v in re.split(r"[,\s]+", text.strip()) if v]
    except ValueError:
        raise node.fail(f"expected numbers, got {text!r}") from None
    if not values or not all(math.isfinite(v) for v in values):
        raise node.fail(f"expected finite numbers, got {text!r}")
    if count is not None and len(values) not in count:
        raise node.fail(f"expected {' or '.join(map(str, count))} numbers, got {len(values)}")
    return values


def _colour(node):
    """An RGB triple from ``rgb``, ``srgb`` or ``spectrum`` (linear)."""
    value = node.attrs.get("value")
    if node.tag == "spectrum" and value is None and "filename" in node.attrs:
        raise node.fail("spectra from files are not read; give an <rgb> instead")
    if value is None:
        raise node.fail("needs a 'value'")
    if node.tag == "srgb":
        text = value.strip()
        if text.startswith("#"):
            if not re.fullmatch(r"#[0-9a-fA-F]{6}", text):
                raise node.fail(f"expected #rrggbb, got {text!r}")
            rgb = [int(text[i:i + 2], 16) / 255.0 for i in (1, 3, 5)]
        else:
            rgb = _numbers(node, text, (1, 3))
        return tuple(srgb_to_linear(rgb * 3 if len(rgb) == 1 else rgb))
    if node.tag == "spectrum" and ":" in value:
        return _spectrum_to_rgb(node, value)
    rgb = _numbers(node, value, (1, 3))
    return tuple(rgb * 3 if len(rgb) == 1 else rgb)


def _spectrum_to_rgb(node, value):
    """Wavelength:value pairs as RGB: the mean over 600-700, 500-600 and 400-500 nm
    (linear interpolation), a rough stand-in for spectral rendering."""
    pairs = []
    for item in value.split(","):
        parts = item.split(":")
        if len(parts) != 2:
            raise node.fail(f"expected wavelength:value pairs, got {item.strip()!r}")
        pairs.append(_numbers(node, parts[0], (1,)) + _numbers(node, parts[1], (1,)))
    pairs.sort()
    wavelengths, values = np.array(pairs).T
    bands = [(600, 700), (500, 600), (400, 500)]
    rgb = tuple(float(np.interp(np.linspace(a, b, 21), wavelengths, values).mean()) for a, b in bands)
    node.warn(f"a sampled spectrum taken as RGB {tuple(round(c, 4) for c in rgb)} (band means)")
    return rgb


_COLOURS = {"rgb", "srgb", "spectrum"}
_PROPERTY_TAGS = {"float", "integer", "boolean", "string", "rgb", "srgb", "spectrum", "blackbody", "point", "vector",
                  "transform", "texture"}
_REFERABLE = ("bsdf", "texture", "shape", "emitter", "medium")


class _Props:
    """The properties of one element: ``named`` (``float``, ``rgb``, a named
    ``texture`` or ``ref``, ...: name -> (the element, what it stands for after
    ``<ref>``)) and ``unnamed`` (nested or referenced ``bsdf``, ``shape``, ``emitter``,
    ``film``, ... elements)."""

    def __init__(self, doc, node):
        self.doc, self.node = doc, node
        self.named = {}
        self.unnamed = []
        for child in node.children:
            target = doc.deref(child, _REFERABLE)
            name = child.attrs.get("name")
            if name is not None and child.tag in _PROPERTY_TAGS | {"ref"}:
                self.named[_snake(name)] = (child, target)
            if name is None or target.tag == "bsdf":
                self.unnamed.append(target)

    def _get(self, name):
        return self.named.get(name)

    def float(self, name, default=None):
        item = self._get(name)
        if item is None:
            return default
        child, _ = item
        if child.tag not in ("float", "integer"):
            raise child.fail("expected a <float>")
        return _numbers(child, child.attrs.get("value", ""), (1,))[0]

    def integer(self, name, default=None):
        item = self._get(name)
        if item is None:
            return default
        child, _ = item
        value = child.attrs.get("value", "")
        if child.tag != "integer" or not re.fullmatch(r"\s*[+-]?\d+\s*", value):
            raise child.fail(f"expected a whole number, got {value!r}")
        return int(value)

    def boolean(self, name, default=False):
        item = self._get(name)
        if item is None:
            return default
        child, _ = item
        value = child.attrs.get("value", "").strip().lower()
        if value not in ("true", "false"):
            raise child.fail(f"expected true or false, got {value!r}")
        return value == "true"

    def string(self, name, default=None):
        item = self._get(name)
        if item is None:
            return default
        child, _ = item
        if "value" not in child.attrs:
            raise child.fail("needs a 'value'")
        return child.attrs["value"]

    def vector(self, name, default=None):
        item = self._get(name)
        if item is None:
            return default
        child, _ = item
        if "value" in child.attrs:
            return np.array(_numbers(child, child.attrs["value"], (3,)))
        return np.array([_numbers(child, child.attrs.get(a, "0"), (1,))[0] for a in "xyz"])

    def colour(self, name, default=None):
        """An RGB colour; a texture counts with its mean colour (and a warning)."""
        item = self._get(name)
        if item is None:
            return None if default is None else tuple(np.broadcast_to(default, 3).astype(float))
        child, target = item
        if target.tag == "texture":
            return _texture_mean(self.doc, target)
        if child.tag in ("float", "integer"):
            return (self.float(name),) * 3
        if child.tag == "blackbody":
            raise child.fail("blackbody spectra are not read; give an <rgb> instead")
        if child.tag not in _COLOURS:
            raise child.fail("expected a colour (<rgb>, <srgb>, <spectrum>) or a <texture>")
        return _colour(child)

    def transform(self, name):
        item = self._get(name)
        if item is None:
            return np.eye(4)
        child, _ = item
        if child.tag != "transform":
            raise child.fail("expected a <transform>")
        return _transform(child)


def _texture_mean(doc, node):
    """A texture's mean linear colour: ``bitmap`` from its image, ``checkerboard``
    from its two colours; others refused."""
    kind = node.attrs.get("type")
    props = _Props(doc, node)
    if kind == "bitmap":
        filename = props.string("filename")
        if filename is None:
            raise node.fail("needs a 'filename'")
        path = doc.resolve(node, filename)
        image = _read_image(node, path)
        mean = image.reshape(-1, image.shape[-1])[:, :3].mean(axis=0)
        node.warn(f"texture {filename!r} taken as its mean colour {tuple(round(float(c), 4) for c in mean)}")
        return tuple(float(c) for c in mean)
    if kind == "checkerboard":
        a, b = props.colour("color0", 0.4), props.colour("color1", 0.2)
        mean = tuple((x + y) / 2 for x, y in zip(a, b, strict=True))
        node.warn(f"checkerboard taken as its mean colour {tuple(round(c, 4) for c in mean)}")
        return mean
    raise node.fail(f"texture type {kind!r} is not read (bitmap and checkerboard are)")


def _read_image(node, path):
    """Linear RGB(A) float array of an image file (8-bit images sRGB-decoded)."""
    import imageio.v3 as iio

    try:
        image = np.asarray(iio.imread(path))
    except Exception as exc:  # imageio raises many types for a bad or unknown file
        raise node.fail(f"cannot read image {str(path)!r}: {exc}") from None
    if image.ndim == 2:
        image = image[..., None].repeat(3, axis=2)
    if image.ndim != 3 or image.shape[2] not in (1, 3, 4) or image.size == 0:
        raise node.fail(f"image {str(path)!r} is not an RGB image (shape {image.shape})")
    if image.shape[2] == 1:
        image = image.repeat(3, axis=2)
    if np.issubdtype(image.dtype, np.integer):
        return srgb_to_linear(image[..., :3] / np.iinfo(image.dtype).max)
    return image[..., :3].astype(np.float64)


# -- transforms ---------------------------------------------------------------------------


def _rotation(axis, degrees):
    axis = np.asarray(axis, dtype=np.float64)
    axis = axis / np.linalg.norm(axis)
    x, y, z = axis
    c, s = math.cos(math.radians(degrees)), math.sin(math.radians(degrees))
    t = 1 - c
    return np.array([
        [t * x * x + c, t * x * y - s * z, t * x * z + s * y],
        [t * x * y + s * z, t * y * y + c, t * y * z - s * x],
        [t * x * z - s * y, t * y * z + s * x, t * z * z + c],
    ])


def _xyz(node, default):
    if "value" in node.attrs:
        values = _numbers(node, node.attrs["value"], (1, 3))
        return np.array(values * 3 if len(values) == 1 else values)
    return np.array([_numbers(node, node.attrs[a], (1,))[0] if a in node.attrs else default for a in "xyz"])


def _look_at(node):
    def vec(key, default=None):
        if key not in node.attrs:
            if default is None:
                raise node.fail(f"needs '{key}'")
            return np.array(default, dtype=np.float64)
        return np.array(_numbers(node, node.attrs[key], (3,)))

    origin, target, up = vec("origin"), vec("target"), vec("up", (0.0, 1.0, 0.0))
    forward = target - origin
    if np.linalg.norm(forward) == 0:
        raise node.fail("target equals origin")
    forward /= np.linalg.norm(forward)
    left = np.cross(up, forward)
    if np.linalg.norm(left) < 1e-12:
        raise node.fail("up is zero or parallel to the viewing direction")
    left /= np.linalg.norm(left)
    matrix = np.eye(4)
    matrix[:3, 0], matrix[:3, 1], matrix[:3, 2], matrix[:3, 3] = left, np.cross(forward, left), forward, origin
    return matrix


def _transform(node):
    """The 4x4 matrix of a ``<transform>``: its steps, each applied after the last."""
    matrix = np.eye(4)
    for step in node.children:
        m = np.eye(4)
        if step.tag == "translate":
            m[:3, 3] = _xyz(step, 0.0)
        elif step.tag == "scale":
            m[:3, :3] = np.diag(_xyz(step, 1.0))
        elif step.tag == "rotate":
            axis = _xyz(step, 0.0) if "value" in step.attrs or any(a in step.attrs for a in "xyz") else None
            if axis is None or not np.any(axis):
                raise step.fail("needs a non-zero axis (x, y, z or value)")
            m[:3, :3] = _rotation(axis, _numbers(step, step.attrs.get("angle", "0"), (1,))[0])
        elif step.tag == "matrix":
            values = _numbers(step, step.attrs.get("value", ""), (16, 9))
            if len(values) == 16:
                m = np.array(values).reshape(4, 4)
            else:
                m[:3, :3] = np.array(values).reshape(3, 3)
        elif step.tag == "lookat":
            m = _look_at(step)
        else:
            raise step.fail("not a transform step (matrix, translate, rotate, scale, lookat)")
        matrix = m @ matrix
    if not np.isfinite(matrix).all() or abs(np.linalg.det(matrix[:3, :3])) < 1e-300:
        raise node.fail("the transform is singular or not finite")
    return matrix


# -- meshes -------------------------------------------------------------------------------

_SERIALIZED_MAGIC = 0x041C
_HAS_NORMALS, _HAS_TEXCOORDS, _HAS_COLORS, _DOUBLE = 0x0001, 0x0002, 0x0008, 0x2000


def read_serialized(data, index=0, where="serialized"):
    """Positions (V, 3), faces (F, 3) and normals (V, 3) or None of shape ``index`` of
    a Mitsuba ``.serialized`` file's bytes.

    Layout (Mitsuba's documentation of ``serialized``): a file is a run of shapes, each
    a uint16 format identifier 0x041C, a uint16 version (3 or 4), then a zlib stream
    of: uint32 flags (0x1 normals, 0x2 texture coordinates, 0x8 colours, 0x2000 double
    precision), in version 4 the shape's UTF-8 name ending in NUL, uint64 vertex count,
    uint64 triangle count, positions, normals, texture coordinates (2 per vertex) and
    colours as present, in float32 or float64, then the triangles' vertex indices
    (uint32, or uint64 beyond 2^32 vertices). The file ends in a table of each shape's
    byte offset (uint64 in version 4, uint32 in 3) and a uint32 count of shapes.
    """
    if len(data) < 8:
        raise InputError(f"{where}: too short for a serialized mesh")
    (count,) = struct.unpack_from("<I", data, len(data) - 4)
    magic, version = struct.unpack_from("<HH", data, 0)
    if magic != _SERIALIZED_MAGIC or version not in (3, 4):
        raise InputError(f"{where}: not a Mitsuba serialized mesh (format 0x{magic:04X}, version {version})")
    wide = version == 4
    table_bytes = count * (8 if wide else 4)
    if count == 0 or table_bytes + 4 > len(data):
        raise InputError(f"{where}: its table of shapes is damaged ({count} shapes)")
    if not 0 <= index < count:
        raise InputError(f"{where}: shape_index {index} is not among its {count} shapes")
    offsets = struct.unpack_from(f"<{count}{'Q' if wide else 'I'}", data, len(data) - 4 - table_bytes)
    start = offsets[index]
    end = offsets[index + 1] if index + 1 < count else len(data) - 4 - table_bytes
    if not 0 <= start < end <= len(data):
        raise InputError(f"{where}: shape {index}'s offset is outside the file")
    magic, version = struct.unpack_from("<HH", data, start)
    if magic != _SERIALIZED_MAGIC or version not in (3, 4):
        raise InputError(f"{where}: shape {index} does not start with the serialized mesh header")
    try:
        body = zlib.decompressobj().decompress(data[start + 4:end], MESH_BYTES)
    except zlib.error as exc:
        raise InputError(f"{where}: shape {index}'s compressed data is damaged ({exc})") from None
    return _serialized_body(body, version == 4, where)


def _serialized_body(body, named, where):
    try:
        (flags,) = struct.unpack_from("<I", body, 0)
        at = 4
        if named:
            at = body.index(b"\0", at) + 1
        n_vertices, n_faces = struct.unpack_from("<QQ", body, at)
    except (struct.error, ValueError):
        raise InputError(f"{where}: the shape's header is cut short") from None
    at += 16
    real = np.float64 if flags & _DOUBLE else np.float32
    index = np.uint64 if n_vertices > 2**32 else np.uint32
    sizes = [("positions", 3, real), ("normals", 3 if flags & _HAS_NORMALS else 0, real),
             ("texcoords", 2 if flags & _HAS_TEXCOORDS else 0, real),
             ("colors", 3 if flags & _HAS_COLORS else 0, real)]
    need = sum(n_vertices * k * np.dtype(t).itemsize for _, k, t in sizes) + n_faces * 3 * np.dtype(index).itemsize
    if n_vertices == 0 or n_faces == 0 or at + need > len(body):
        raise InputError(f"{where}: holds {len(body) - at:,} bytes where {n_vertices:,} vertices and "
                         f"{n_faces:,} triangles need {need:,}")
    arrays = {}
    for name, k, dtype in sizes:
        if k:
            n = n_vertices * k
            arrays[name] = np.frombuffer(body, dtype=dtype, count=n, offset=at).reshape(-1, k).astype(np.float64)
            at += n * np.dtype(dtype).itemsize
    faces = np.frombuffer(body, dtype=index, count=n_faces * 3, offset=at).reshape(-1, 3).astype(np.int64)
    if faces.max() >= n_vertices:
        raise InputError(f"{where}: a triangle refers to a vertex that does not exist")
    return arrays["positions"], faces, arrays.get("normals")


def _mesh_file(doc, node, props):
    """Positions, faces, normals (or None) of an obj, ply or serialized shape."""
    filename = props.string("filename")
    if filename is None:
        raise node.fail("needs a 'filename'")
    path = doc.resolve(node, filename)
    kind = node.attrs["type"]
    if kind == "serialized":
        data = read_input_bytes(path, "mesh", MESH_BYTES)
        index = props.integer("shape_index", 0)
        return read_serialized(data, index, where=f"{node.where}: {filename}")
    return read_mesh_with_normals(path, node.where)


def _analytic(node, props, tessellation):
    """Positions, faces and the object-to-world matrix of a tessellated analytic shape."""
    kind = node.attrs["type"]
    to_world = props.transform("to_world")
    if kind == "rectangle":
        positions = np.array([[-1.0, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]])
        return positions, np.array([[0, 1, 2], [0, 2, 3]]), to_world
    if kind == "disk":
        return (*builtins.disk(tessellation.segments), to_world)
    if kind == "cube":  # [-1, 1]^3: the built-in unit cube doubled
        positions, faces = builtins.mesh("cube")
        return 2.0 * positions, faces, to_world
    if kind == "sphere":
        positions, faces = builtins.mesh("sphere", subdivisions=tessellation.sphere_levels)
        radius = props.float("radius", 1.0)
        if not radius > 0:
            raise node.fail(f"radius must be > 0, got {radius}")
        place = np.eye(4)
        place[:3, :3] *= radius
        place[:3, 3] = props.vector("center", np.zeros(3))
        return positions, faces, to_world @ place
    if kind == "cylinder":
        p0, p1 = props.vector("p0", np.zeros(3)), props.vector("p1", np.array([0.0, 0, 1]))
        radius = props.float("radius", 1.0)
        axis = p1 - p0
        length = np.linalg.norm(axis)
        if not radius > 0 or length == 0:
            raise node.fail("needs radius > 0 and p0 != p1")
        z = axis / length
        x = np.cross(z, [1.0, 0, 0] if abs(z[0]) < 0.9 else [0, 1.0, 0])
        x /= np.linalg.norm(x)
        place = np.eye(4)
        place[:3, 0], place[:3, 1], place[:3, 2], place[:3, 3] = radius * x, radius * np.cross(z, x), length * z, p0
        return (*builtins.cylinder(tessellation.segments), to_world @ place)
    raise AssertionError(kind)


# -- materials ----------------------------------------------------------------------------


@dataclass
class _Surface:
    """A shape's material as the project models it, and what the shape needs."""

    diffuse: tuple = (0.5, 0.5, 0.5)
    specular: tuple = (0.0, 0.0, 0.0)
    exponent: float = 0.0
    twosided: bool = False
    visible: bool = True  # False: the shape is left out (a null bsdf, a dielectric)
    fresnel: tuple | None = None  # Schlick's F0 of a mapped plastic or conductor


def _surface(doc, node):
    """The _Surface of a ``<bsdf>`` element (after ``<ref>``)."""
    node = doc.deref(node, ("bsdf",))
    kind = node.attrs.get("type")
    props = _Props(doc, node)
    inner = [c for c in props.unnamed if c.tag == "bsdf"]
    if kind == "twosided":
        if not inner:
            raise node.fail("needs the <bsdf> it makes two-sided")
        if len(inner) > 1:
            node.warn("a different bsdf on each side: the front's is used on both")
        surface = _surface(doc, inner[0])
        surface.twosided = True
        return surface
    if kind == "diffuse":
        return _Surface(diffuse=props.colour("reflectance", 0.5))
    if kind in ("plastic", "roughplastic", "conductor", "roughconductor"):
        return _microfacet_surface(node, props, kind)
    if kind == "null":
        return _Surface(diffuse=(0.0, 0.0, 0.0), visible=False)
    if kind in ("dielectric", "thindielectric", "roughdielectric"):
        node.warn("transmission is not modelled: the shape is left out, so light passes as through clear glass "
                  "(its reflections are lost)")
        return _Surface(visible=False)
    if kind in ("bumpmap", "normalmap"):
        if not inner:
            raise node.fail("needs the <bsdf> it perturbs")
        node.warn(f"the {kind}'s detail is not modelled: the bsdf beneath it is used as it is")
        return _surface(doc, inner[0])
    if kind == "mask":
        if not inner:
            raise node.fail("needs the <bsdf> it masks")
        opacity = float(np.mean(props.colour("opacity", 0.5)))
        if opacity < 0.5:
            node.warn(f"mean opacity {opacity:.2f} < 0.5: the shape is left out")
            return _Surface(visible=False)
        node.warn(f"mean opacity {opacity:.2f} >= 0.5: the shape is taken as opaque")
        return _surface(doc, inner[0])
    if kind == "blendbsdf":
        if len(inner) != 2:
            raise node.fail("needs two <bsdf> to blend")
        weight = float(np.mean(props.colour("weight", 0.5)))
        a, b = _surface(doc, inner[0]), _surface(doc, inner[1])
        node.warn(f"blended as one Phong lobe: colours mixed with weight {weight:.2f}, the exponent of the "
                  "glossier part")
        mix = lambda u, v: tuple((1 - weight) * x + weight * y for x, y in zip(u, v, strict=True))  # noqa: E731
        glossier = a if a.exponent >= b.exponent else b
        diffuse, specular, exponent = mix(a.diffuse, b.diffuse), mix(a.specular, b.specular), glossier.exponent
        if glossier.fresnel is not None and any(specular):  # its Fresnel for the blend, kd within the energy bound
            diffuse = tuple(np.minimum(diffuse, fresnel_kd_limit(specular, glossier.fresnel, exponent)))
        return _Surface(diffuse, specular, exponent, a.twosided or b.twosided, a.visible or b.visible,
                        glossier.fresnel if any(specular) else None)
    colour = props.colour("base_color") or props.colour("reflectance") or props.colour("diffuse_reflectance")
    node.warn(f"bsdf type {kind!r} is not modelled: taken as diffuse"
              + (" with its base colour" if colour is not None else " 0.5"))
    return _Surface(diffuse=colour or (0.5, 0.5, 0.5))


def _microfacet_surface(node, props, kind):
    """plastic, roughplastic, conductor, roughconductor by ``microfacet.phong_lobe_for``'s
    measured rule (the exponent that matches the lobe's half-maximum solid angle, ks
    and kd fitted to the original's albedos over incidence)."""
    alpha, distribution = None, props.string("distribution", "beckmann")
    if kind.startswith("rough"):
        alpha = props.float("alpha")
        if alpha is None and props.float("alpha_u") is not None:
            au, av = props.float("alpha_u"), props.float("alpha_v", props.float("alpha_u"))
            alpha = math.sqrt(au * av)
            if au != av:
                node.warn(f"anisotropic roughness ({au:g}, {av:g}) taken as isotropic {alpha:.4g}")
        alpha = 0.1 if alpha is None else alpha
        if distribution == "phong":  # Mitsuba 0.x's third distribution: close to Beckmann's at the same alpha
            node.warn("the phong distribution is mapped as beckmann of the same alpha")
            distribution = "beckmann"
    params = {"specular_reflectance": props.colour("specular_reflectance", 1.0)}
    if kind.endswith("plastic"):
        params |= {"diffuse_reflectance": props.colour("diffuse_reflectance", 0.5),
                   "int_ior": _ior(props, "int_ior", 1.49), "ext_ior": _ior(props, "ext_ior", 1.000277),
                   "nonlinear": props.boolean("nonlinear")}
    elif "eta" in props.named or "k" in props.named:
        params |= {"eta": props.colour("eta", 0.0), "k": props.colour("k", 1.0)}
    else:
        params["material"] = props.string("material", "none")
    try:
        kd, ks, exponent, fresnel = microfacet.phong_lobe(kind, distribution, alpha if alpha is not None else 0.1,
                                                          **params)
    except InputError as exc:
        raise node.fail(str(exc)) from None
    return _Surface(diffuse=kd, specular=ks, exponent=exponent, fresnel=fresnel)


_NAMED_IOR = {"vacuum": 1.0, "bk7": 1.5046, "glass": 1.5046, "acrylic glass": 1.49, "polypropylene": 1.49,
              "water": 1.333, "air": 1.000277, "diamond": 2.419, "pet": 1.575, "polycarbonate": 1.58}


def _ior(props, name, default):
    text = props.string(name) if name in props.named and props.named[name][0].tag == "string" else None
    if text is not None:
        if text.lower() not in _NAMED_IOR:
            raise props.named[name][0].fail(f"unknown index of refraction {text!r} (known: {', '.join(_NAMED_IOR)})")
        return _NAMED_IOR[text.lower()]
    value = props.float(name, default)
    if not value > 0:
        raise props.node.fail(f"{name} must be > 0, got {value}")
    return value


# -- the scene ------------------------------------------------------------------------------


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


class _Reader:
    def __init__(self, path, tessellation):
        self.doc = _Document(path)
        self.tessellation = tessellation
        self.shapes = []
        self.lamps = []  # (node, position, intensity rgb)
        self.camera = None
        self.names = set()

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

    def _shape(self, node, outer):
        kind = node.attrs.get("type")
        props = _Props(self.doc, node)
        if kind == "shapegroup":
            return  # drawn where an instance places it
        if kind == "instance":
            group = [t for t in props.unnamed if t.tag == "shape" and t.attrs.get("type") == "shapegroup"]
            group += [t for _, t in props.named.values() if t.tag == "shape" and t.attrs.get("type") == "shapegroup"]
            if not group:
                raise node.fail("needs a <ref> to a shapegroup")
            place = outer @ props.transform("to_world")
            for child in group[0].children:
                if child.tag == "shape":
                    self._shape(child, place)
            return
        if kind in ("obj", "ply", "serialized"):
            positions, faces, normals = _mesh_file(self.doc, node, props)
            if props.boolean("face_normals"):
                normals = None
            to_world = outer @ props.transform("to_world")
            fallback = f"{kind}_{len(self.shapes)}_{Path(props.string('filename')).stem}"
            crease = 0.0 if props.boolean("face_normals") else DEFAULT_CREASE_ANGLE_DEG
        elif kind in ("rectangle", "disk", "sphere", "cube", "cylinder"):
            positions, faces, to_world = _analytic(node, props, self.tessellation)
            to_world = outer @ to_world
            normals = None
            fallback = f"{kind}_{len(self.shapes)}"
            crease = 180.0 if kind in ("sphere", "cylinder") else DEFAULT_CREASE_ANGLE_DEG
        else:
            raise node.fail(f"shape type {kind!r} is not read (obj, ply, serialized, rectangle, disk, sphere, cube, "
                            "cylinder, shapegroup, instance are)")
        bsdfs = [t for t in props.unnamed if t.tag == "bsdf"]
        surface = _surface(self.doc, bsdfs[0]) if bsdfs else _Surface()
        emission = (0.0, 0.0, 0.0)
        for child in node.children:
            if child.tag == "emitter":
                if child.attrs.get("type") != "area":
                    raise child.fail("a shape's emitter must be of type 'area'")
                emission = _Props(self.doc, child).colour("radiance", 1.0)
        if not surface.visible and not any(emission):
            return
        if not surface.visible:  # a null bsdf around a lamp: it emits but reflects nothing
            surface = _Surface(diffuse=(0.0, 0.0, 0.0))
        positions = positions @ to_world[:3, :3].T + to_world[:3, 3]
        if normals is not None:
            normals = normals @ np.linalg.inv(to_world[:3, :3])
        if np.linalg.det(to_world[:3, :3]) < 0 and (normals is not None or kind not in ("obj", "ply", "serialized")):
            # a mirroring transform turns the winding around; Mitsuba 3 keeps a mirrored mesh's facing only where
            # its own vertex normals say so (a mesh without them faces as its unturned winding does)
            faces = faces[:, ::-1]
        if props.boolean("flip_normals"):
            faces = faces[:, ::-1]
            normals = None if normals is None else -normals
        self.shapes.append(_Shape(self._name(node, fallback), positions, np.ascontiguousarray(faces), normals,
                                  surface, tuple(emission), node.where, crease))

    def _emitter(self, node):
        kind = node.attrs.get("type")
        props = _Props(self.doc, node)
        if kind in ("point", "spot"):
            position = props.vector("position")
            if position is None:
                position = props.transform("to_world")[:3, 3]
            intensity = props.colour("intensity", 1.0)
            if kind == "spot":
                node.warn("a spot light is taken as a point light: its cone is not kept, light goes every way")
            self.lamps.append((node, position, intensity))
        elif kind in ("constant", "envmap", "directional", "sunsky", "sky", "sun"):
            node.warn(f"{kind} emitters (light from outside the scene) are not modelled yet: left out")
        elif kind == "area":
            raise node.fail("an area emitter must be inside the <shape> that emits")
        else:
            raise node.fail(f"emitter type {kind!r} is not read")

    def scene(self, name):
        if not self.shapes:
            raise InputError(f"{self.doc.path}: no shapes this reader can use")
        everything = np.concatenate([s.positions for s in self.shapes])
        diagonal = float(np.linalg.norm(np.ptp(everything, axis=0)))
        fronts = [build_object(shape.name, _to_material(shape), shape.positions, shape.faces,
                               crease_angle_deg=shape.crease, source=shape.source, normals=shape.normals)
                  for shape in self.shapes]
        objects = list(with_backs(fronts, {shape.name for shape in self.shapes if shape.surface.twosided}))
        for node, position, intensity in self.lamps:
            objects.append(self._lamp(node, position, intensity, diagonal))
        film = None if self.camera is None else (self.camera.width, self.camera.height)
        return Scene(name=name, objects=tuple(objects), camera=self.camera, source=str(self.doc.path), film=film)

    def _lamp(self, node, position, intensity, diagonal):
        radius = POINT_LAMP_RADIUS * diagonal
        sphere = trimesh.creation.icosphere(subdivisions=2, radius=radius)
        # a sphere of radiance L sends pi L area (4 pi I): by the tessellated sphere's area, the power is exact
        radiance = tuple(4.0 * float(i) / sphere.area for i in intensity)
        name = self._name(node, f"{node.attrs['type']}_light_{len(self.names)}")
        node.warn(f"taken as a sphere lamp of radius {radius:.3g} ({POINT_LAMP_RADIUS:g} of the scene's size) and the "
                  "same intensity")
        material = Material(name=name, diffuse=(0.0, 0.0, 0.0), specular=(0.0, 0.0, 0.0), exponent=0.0,
                            emission=radiance)
        return build_object(name, material, np.asarray(sphere.vertices) + position, np.asarray(sphere.faces),
                            crease_angle_deg=180.0, source=node.where)


def _to_material(shape):
    s = shape.surface
    try:
        return Material(name=shape.name, diffuse=s.diffuse, specular=s.specular, exponent=s.exponent,
                        emission=shape.emission, fresnel=s.fresnel)
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
        fov_y = fov_y_deg(fov, axis, width, height)
    except InputError as exc:
        raise node.fail(str(exc).removeprefix("camera: ")) from None
    eye, look_at, up, mirrored = pose_from_matrix(props.transform("to_world"))
    if mirrored:
        node.warn("the sensor's transform mirrors the image (a negative scale): drawn unmirrored")
    try:
        return Camera(eye, look_at, up, fov_y, width, height)
    except InputError as exc:
        raise node.fail(str(exc)) from None


def load_mitsuba(path, tessellation=None):
    """A Scene from a Mitsuba XML file (see the module docstring)."""
    path = Path(path)
    reader = _Reader(path, tessellation or Tessellation())
    reader.read()
    return reader.scene(path.stem)
