"""Mitsuba XML scenes: the format of the rendering community's test scenes.

``load_mitsuba(path)`` reads a scene written for Mitsuba 0.4-0.6 or 2-3 and returns a
Scene. What it reads, and what it does with it:

Document
    ``<scene version=...>``; ``<default name value>`` and ``$name`` in any attribute;
    ``id`` on any element and ``<ref id>`` to it; ``<include filename>``; property
    names in either spelling (``toWorld`` / ``to_world``, ``intIOR`` / ``int_ior``).
    Values: ``float``, ``integer``, ``boolean``, ``string``, ``rgb``, ``srgb`` (hex or
    numbers, sRGB-decoded), ``spectrum`` (a constant, or wavelength:value pairs turned
    to RGB as Mitsuba 3's RGB modes do: ``spectra``, with a warning), ``point`` /
    ``vector``.
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
    of ``microfacet.phong_lobe_for`` (the rough ones keep their own model beside it);
    ``dielectric``, ``thindielectric`` and ``roughdielectric`` as ``Glass`` (int_ior
    over ext_ior, named indices as Mitsuba's); anything else (masks, bump and normal
    maps, blends, principled, ...) approximated with one warning saying how.
Textures
    A ``bitmap`` as a ``diffuse`` bsdf's ``reflectance`` (also inside ``twosided``,
    ``bumpmap``, ``normalmap`` and ``mask``) or a plastic's ``diffuse_reflectance``
    is the object's diffuse texture, read through the shape's texture coordinates as
    Mitsuba 3 defines them (``_analytic``; obj ``vt``, which Mitsuba flips to its
    top-down v; ply ``u v`` and serialized texcoords as stored, top-down), each turned
    to ours (``textures``: v up, (u, v) -> (u, 1 - v)). Its ``to_uv`` (scale,
    translate, rotate about z, matrix) applies; ``wrap_mode`` repeat as it is,
    mirror and clamp through ``textures.as_repeating``; ``filter_type`` nearest is
    read bilinear (a warning); ``raw`` skips the sRGB decoding of 8- and 16-bit
    images; OpenEXR images are linear. A plastic's textured diffuse reflectance maps
    its brightest texel by the rule below and scales the others with it (exact where
    the rule's kd is linear in it, as for ``nonlinear`` false; ``nonlinear`` true by
    Mitsuba's kd / (1 - kd R_int) per texel). A texture anywhere else (a specular
    reflectance, a roughness, a blend's weight), a ``checkerboard``, or a bitmap on a
    shape without texture coordinates counts with its mean colour (with a warning).
Emitters
    ``area`` (a shape's radiance); ``point`` (``intensity``; ``position`` or
    ``to_world``'s translation), ``spot`` (``intensity``, ``cutoff_angle`` default 20
    degrees, ``beam_width`` default 3/4 of it, ``to_world``: at its translation,
    pointing along its +z; a projected ``texture`` is left out with a warning) and
    ``directional`` (``irradiance``; ``direction``, the way the light travels, or
    ``to_world``'s +z) as the scene's delta lights (``radiosity.scene.lights``);
    ``constant`` (radiance) and ``envmap`` (filename: .exr, .hdr, .pfm or an 8-bit
    image, sRGB-decoded; scale; to_world, its rotation) become the scene's environment
    (``radiosity.physics.environment``; one per scene: a second is left out with a
    warning); the sun and sky models are not modelled yet: left out with a warning.
Sensor
    ``perspective`` / ``thinlens`` as the scene's camera: ``fov`` with its
    ``fov_axis`` (x, y, diagonal, smaller, larger; kept along that axis at any image
    size, as Mitsuba 3 keeps it) or 0.6's ``focalLength`` (a diagonal fov), the
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
from dataclasses import dataclass, field, replace
from pathlib import Path
from xml.parsers import expat

import numpy as np

from radiosity.files.camera import Camera, fov_y_deg, pose_from_matrix
from radiosity.files.errors import InputError, SceneWarning
from radiosity.files.images import read_image
from radiosity.files.inputs import MAX_NESTING, MESH_BYTES, TEXT_BYTES, check_input_file, read_input_bytes
from radiosity.physics.environment import Environment, read_environment_image
from radiosity.physics.materials import MAX_ALPHA, MIN_ALPHA, Glass, Microfacet, fresnel_kd_limit, srgb_to_linear
from radiosity.physics.textures import WRAP_MODES, as_repeating
from radiosity.scene import builtins, microfacet
from radiosity.scene.lights import DEFAULT_CUTOFF_DEG, directional_light, point_light, spot_light
from radiosity.scene.material_kernels import Material
from radiosity.scene.meshfiles import read_mesh_parts
from radiosity.scene.model import DEFAULT_CREASE_ANGLE_DEG, Scene, build_object, with_backs
from radiosity.scene.spectra import spectrum_to_rgb

__all__ = ["Tessellation", "load_mitsuba", "read_serialized"]

MAX_INCLUDES = 16  # nested <include> depth
MAX_INCLUDED = 256  # <include>s read in all (each including the next ten times, eight deep, is 10^8 of them)
MAX_SERIALIZED_VERTICES = 1 << 25  # a serialized shape claiming more (33.5 M) is refused before it is inflated
MAX_SHAPES = 20_000  # shapes placed in all, instances' shapes included (the collection's largest places 655)
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
        self.included = 0
        self.elements = self._expand(root.children, 0)
        if self.major < 2:
            _upgrade(self.elements)
        self.bitmaps = {}  # id(<texture> element) -> its _Bitmap, each file read once
        self.surfaces = {}  # id(<bsdf> element) -> its _Surface, made once for every shape that refers to it
        self.ids = {}
        for node in self._walk(self.elements):
            if "id" in node.attrs and node.tag != "ref":
                first = self.ids.setdefault(node.attrs["id"], node)
                if first is not node:  # Mitsuba refuses a second element of one id too
                    raise node.fail(f"id {node.attrs['id']!r} is given twice (first at {first.where})")
        self.building = set()  # the <bsdf> elements whose surfaces are being made (a cycle of refs meets one)

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
                self.included += 1
                if self.included > MAX_INCLUDED:
                    raise node.fail(f"more than {MAX_INCLUDED} <include>s in all (a scene including files over and over)")
                included = _parse_xml(self.resolve(node, name))
                out += self._expand(included.children, depth + 1)
            else:
                out.append(node)
        return out

    def resolve(self, node, name):
        """A file a scene element names, relative to the scene's directory; InputError
        naming it, and every other file the scene names that is missing too."""
        path = self.base / name
        if path.exists() or path.is_symlink():  # there, but maybe not a file one can read (the input check says)
            try:
                check_input_file(path, "file")
            except InputError as exc:
                raise node.fail(str(exc)) from None
            return path
        if not path.is_file():
            others = [n for n in self._missing_files() if n != name]
            n = len(others)
            more = f" ({n} more file{'s' * (n > 1)} it names {'are' if n > 1 else 'is'} missing too: " \
                   f"{', '.join(others)})" if others else ""
            raise node.fail(f"file {str(path)!r} not found{more}")
        return path

    def _missing_files(self):
        """The ``filename`` properties of every element that name no file, in document order."""
        seen = []
        for node in self._walk(getattr(self, "elements", [])):  # none yet while includes are read
            name = node.attrs.get("value")
            if node.tag == "string" and node.attrs.get("name") == "filename" and name and name not in seen \
                    and not (self.base / name).is_file():
                seen.append(name)
        return seen

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


_OLD_TAGS = {"lookAt": "lookat"}  # Mitsuba 0.x's scene handler read both spellings as one tag


def _upgrade(nodes):
    """Mitsuba 0.x's spellings of tags in 2-3's, in place (as Mitsuba 3's own
    ``upgrade_tree`` does for property names)."""
    for node in nodes:
        node.tag = _OLD_TAGS.get(node.tag, node.tag)
        _upgrade(node.children)


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


def _colour(node, kind="reflectance"):
    """An RGB triple from ``rgb``, ``srgb`` or ``spectrum`` (linear); ``kind``: what a
    sampled spectrum is (``radiosity.scene.spectra.spectrum_to_rgb``)."""
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
        return _spectrum_to_rgb(node, value, kind)
    rgb = _numbers(node, value, (1, 3))
    return tuple(rgb * 3 if len(rgb) == 1 else rgb)


def _spectrum_to_rgb(node, value, kind):
    """Wavelength:value pairs as linear sRGB, as Mitsuba 3's RGB modes read them
    (``radiosity.scene.spectra``; ``kind``: "reflectance", "emitted" or "unbounded")."""
    pairs = []
    for item in value.split(","):
        parts = item.split(":")
        if len(parts) != 2:
            raise node.fail(f"expected wavelength:value pairs, got {item.strip()!r}")
        pairs.append(_numbers(node, parts[0], (1,)) + _numbers(node, parts[1], (1,)))
    pairs.sort()
    wavelengths, values = np.array(pairs).T
    if len(pairs) < 2 or np.any(np.diff(wavelengths) <= 0):
        raise node.fail("a sampled spectrum needs two or more distinct wavelengths")
    rgb = tuple(float(c) for c in spectrum_to_rgb(wavelengths, values, kind))
    node.warn(f"a sampled spectrum taken as RGB {tuple(round(c, 4) for c in rgb)} (CIE 1931 under "
              f"{'equal-energy light' if kind == 'emitted' else 'daylight'}, as Mitsuba 3's RGB modes)")
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
        kind = "emitted" if self.node.tag == "emitter" else "unbounded" if name in ("eta", "k") else "reflectance"
        return _colour(child, kind)

    def transform(self, name):
        item = self._get(name)
        if item is None:
            return np.eye(4)
        child, _ = item
        if child.tag != "transform":
            raise child.fail("expected a <transform>")
        return _transform(child, normalise_axes=self.doc.major < 2)


def _texture_mean(doc, node):
    """A texture's mean linear colour: ``bitmap`` from its image, ``checkerboard``
    from its two colours; others refused."""
    kind = node.attrs.get("type")
    props = _Props(doc, node)
    if kind == "bitmap":
        bitmap = _bitmap(doc, node)
        mean = bitmap.mean
        node.warn(f"texture {bitmap.filename!r} taken as its mean colour {tuple(round(float(c), 4) for c in mean)}")
        return tuple(float(c) for c in mean)
    if kind == "checkerboard":
        a, b = props.colour("color0", 0.4), props.colour("color1", 0.2)
        mean = tuple((x + y) / 2 for x, y in zip(a, b, strict=True))
        node.warn(f"checkerboard taken as its mean colour {tuple(round(c, 4) for c in mean)}")
        return mean
    raise node.fail(f"texture type {kind!r} is not read (bitmap and checkerboard are)")


@dataclass
class _Bitmap:
    """A ``bitmap`` texture: ``image`` (H, W, 3) float32 linear RGB, ``wrap`` (one of
    ``textures.WRAP_MODES``), ``to_uv`` (3, 3) the affine map of Mitsuba's (u, v) it
    applies; ``texture`` the image as a reflectance (float32, clipped to [0, 1] with a
    warning; the image itself where it needs no clipping), made once and shared by the
    shapes that read it as it is."""

    image: np.ndarray
    wrap: str
    to_uv: np.ndarray
    node: Node
    filename: str
    _texture: np.ndarray | None = None
    alpha: np.ndarray | None = None  # (H, W) float32 in [0, 1]: an image's alpha channel
    _opacity: np.ndarray | None = None

    @property
    def opacity(self):
        """The image as a mask's opacity (H, W) float32 in [0, 1], made once and shared by
        the shapes that read it (the kernels' atlas holds it once): its alpha channel where
        it has one (as Tungsten, which rendered the collection's published images, reads a
        leaf's cut-out), else the mean of its channels, clipped."""
        if self._opacity is None:
            self._opacity = self.alpha if self.alpha is not None else \
                np.clip(self.image.mean(axis=2), 0.0, 1.0).astype(np.float32)
        return self._opacity

    @property
    def mean(self):
        return self.image.reshape(-1, 3).mean(axis=0, dtype=np.float64)

    @property
    def texture(self):
        if self._texture is None:
            low, high = float(self.image.min()), float(self.image.max())
            if low < 0.0 or high > 1.0:
                self.node.warn(f"texture {self.filename!r} holds values in [{low:.4g}, {high:.4g}]: clipped to "
                               "[0, 1] as a reflectance")
            self._texture = self.image if 0.0 <= low and high <= 1.0 else np.clip(self.image, 0.0, 1.0)
        return self._texture

    def scaled(self, image):
        """This bitmap with another image (a plastic's texels rescaled)."""
        return _Bitmap(np.asarray(image, np.float32), self.wrap, self.to_uv, self.node, self.filename)

    @property
    def reads_as_given(self):
        """Whether it reads a shape's uvs as they are (to_uv the identity, repeating)."""
        return self.wrap == "repeat" and np.array_equal(self.to_uv, np.eye(3))

    def reading(self, uvs, where):
        """(texture, uvs) for a shape whose (our) texture coordinates are ``uvs``: the
        ``to_uv`` map applied (in Mitsuba's convention) and the wrap mode made
        repeating (``textures.as_repeating``)."""
        mitsuba = np.stack([uvs[:, 0], 1.0 - uvs[:, 1]], axis=1) @ self.to_uv[:2, :2].T + self.to_uv[:2, 2]
        uvs = np.stack([mitsuba[:, 0], 1.0 - mitsuba[:, 1]], axis=1)
        repeating = as_repeating(self.texture, uvs, self.wrap)
        if repeating is None:
            warnings.warn(f"{where}: texture {self.filename!r}: wrap mode {self.wrap!r} over texture coordinates "
                          f"spanning {np.ptp(uvs, axis=0).round(3).tolist()} would need too large an image: repeated "
                          "instead", SceneWarning, stacklevel=3)
            return self.texture, uvs
        return repeating


def _bitmap(doc, node):
    """The ``_Bitmap`` of a ``<texture type="bitmap">``, read once per element."""
    key = id(node)
    if key in doc.bitmaps:
        return doc.bitmaps[key]
    props = _Props(doc, node)
    filename = props.string("filename")
    if filename is None:
        raise node.fail("needs a 'filename'")
    path = doc.resolve(node, filename)
    filter_type = props.string("filter_type", "bilinear")
    if filter_type not in ("bilinear", "nearest"):
        raise node.fail(f"filter_type {filter_type!r} is not bilinear or nearest")
    if filter_type == "nearest":
        node.warn(f"texture {filename!r}: filter_type 'nearest' is read bilinear (textures here are bilinear)")
    wrap = props.string("wrap_mode", "repeat")
    if wrap not in WRAP_MODES:
        raise node.fail(f"wrap_mode {wrap!r} is not one of {', '.join(WRAP_MODES)}")
    image, alpha = _read_image(node, path, raw=props.boolean("raw"))
    image = image.astype(np.float32)  # as every stage keeps textures
    alpha = None if alpha is None else alpha.astype(np.float32)
    bitmap = doc.bitmaps[key] = _Bitmap(image, wrap, _uv_transform(props), node, filename, alpha=alpha)
    return bitmap


def _uv_transform(props):
    """A bitmap's ``to_uv`` as a 3x3 affine map of (u, v, 1): Mitsuba reads a 4x4
    transform's rows and columns x, y and w (z dropped), so ``scale`` and
    ``translate`` take x and y, ``rotate`` turns about z."""
    matrix = props.transform("to_uv")
    keep = [0, 1, 3]
    return matrix[np.ix_(keep, keep)]


def _read_image(node, path, raw=False):
    """(linear RGB (H, W, 3) float64, alpha (H, W) float64 in [0, 1] or None) of a
    bitmap's file, through the one image reader (``radiosity.files.images.read_image``),
    its refusal named at the element."""
    try:
        return read_image(path, "image", raw=raw)
    except InputError as exc:
        raise node.fail(str(exc)) from None


# -- transforms ---------------------------------------------------------------------------


def _rotation(axis, degrees, normalise=True):
    """Rodrigues' matrix about ``axis``: Mitsuba 0.x normalises the axis, Mitsuba 2 and
    3 take it as written (a longer axis also scales: checked against Mitsuba 3.9.1's
    ``ScalarTransform4f.rotate``)."""
    axis = np.asarray(axis, dtype=np.float64)
    if normalise:
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


def _transform(node, normalise_axes=True):
    """The 4x4 matrix of a ``<transform>``: its steps, each applied after the last
    (a rotation's axis normalised or not, as ``_rotation``)."""
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
            m[:3, :3] = _rotation(axis, _numbers(step, step.attrs.get("angle", "0"), (1,))[0], normalise_axes)
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
    """Positions (V, 3), faces (F, 3), normals (V, 3) or None and texture coordinates
    (V, 2) or None (as stored: Mitsuba's convention, v down) of shape ``index`` of a
    Mitsuba ``.serialized`` file's bytes.

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
        head = zlib.decompressobj().decompress(data[start + 4:end], 4096)  # its counts, before the rest is inflated
        _serialized_counts(head, version == 4, where)
        body = zlib.decompressobj().decompress(data[start + 4:end], MESH_BYTES)
    except zlib.error as exc:
        raise InputError(f"{where}: shape {index}'s compressed data is damaged ({exc})") from None
    return _serialized_body(body, version == 4, where)


def _serialized_counts(head, named, where):
    """(flags, vertex count, triangle count, where the arrays start) of a shape's
    inflated header; InputError where it is cut short or claims more than
    ``MAX_SERIALIZED_VERTICES`` vertices or twice as many triangles."""
    try:
        (flags,) = struct.unpack_from("<I", head, 0)
        at = 4
        if named:
            at = head.index(b"\0", at) + 1
        n_vertices, n_faces = struct.unpack_from("<QQ", head, at)
    except (struct.error, ValueError):
        raise InputError(f"{where}: the shape's header is cut short") from None
    if n_vertices > MAX_SERIALIZED_VERTICES or n_faces > 2 * MAX_SERIALIZED_VERTICES:
        raise InputError(f"{where}: the shape claims {n_vertices:,} vertices and {n_faces:,} triangles, more than the "
                         f"{MAX_SERIALIZED_VERTICES:,} vertices (and twice as many triangles) a mesh may have")
    return flags, n_vertices, n_faces, at + 16


def _serialized_body(body, named, where):
    flags, n_vertices, n_faces, at = _serialized_counts(body, named, where)
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
    return arrays["positions"], faces, arrays.get("normals"), arrays.get("texcoords")


def _mesh_file(doc, node, props):
    """Positions, faces, normals (or None) and uvs (or None, ours: v up) of an obj, ply
    or serialized shape. Mitsuba 3 flips an obj's v (``vt`` runs up, its own v down),
    and takes ply's and serialized texture coordinates as stored (its convention)."""
    filename = props.string("filename")
    if filename is None:
        raise node.fail("needs a 'filename'")
    path = doc.resolve(node, filename)
    kind = node.attrs["type"]
    if kind == "serialized":
        data = read_input_bytes(path, "mesh", MESH_BYTES)
        index = props.integer("shape_index", 0)
        positions, faces, normals, texcoords = read_serialized(data, index, where=f"{node.where}: {filename}")
        return positions, faces, normals, None if texcoords is None else _flip_v(texcoords)
    positions, faces, normals, uvs = read_mesh_parts(path, node.where)
    if kind == "ply" and uvs is not None:
        uvs = _flip_v(uvs)
    return positions, faces, normals, uvs


def _flip_v(uvs):
    """Texture coordinates between Mitsuba's convention (v down) and ours (v up)."""
    return np.stack([uvs[:, 0], 1.0 - uvs[:, 1]], axis=1)


# Mitsuba 3's cube: 24 vertices, each face [0, 1]^2 in its (u, v) (its convention, v down)
_CUBE_POSITIONS = np.array([
    [1, -1, -1], [1, -1, 1], [-1, -1, 1], [-1, -1, -1], [1, 1, -1], [-1, 1, -1], [-1, 1, 1], [1, 1, 1],
    [1, -1, -1], [1, 1, -1], [1, 1, 1], [1, -1, 1], [1, -1, 1], [1, 1, 1], [-1, 1, 1], [-1, -1, 1],
    [-1, -1, 1], [-1, 1, 1], [-1, 1, -1], [-1, -1, -1], [1, 1, -1], [1, -1, -1], [-1, -1, -1], [-1, 1, -1]],
    dtype=np.float64)
_CUBE_UVS = np.tile(np.array([[0.0, 1], [1, 1], [1, 0], [0, 0]]), (6, 1))
_CUBE_FACES = np.concatenate([[[k, k + 1, k + 2], [k + 3, k, k + 2]] for k in range(0, 24, 4)]).astype(np.int64)


def _coordinate_system(n):
    """Mitsuba's frame about a unit vector n (Duff et al. 2017): (s, t), with (s, t,
    n) right-handed; the cylinder's local x and y."""
    sign = math.copysign(1.0, n[2])
    a = -1.0 / (sign + n[2])
    b = n[0] * n[1] * a
    return (np.array([1.0 + sign * n[0] * n[0] * a, sign * b, -sign * n[0]]),
            np.array([b, sign + n[1] * n[1] * a, -n[1]]))


def _mitsuba_disk(segments):
    """The unit disk as a fan with Mitsuba 3's (u, v) = (r, phi / 2 pi) as ours (r,
    1 - phi / 2 pi): the rim's seam vertex doubled, the centre copied per triangle
    (its v the triangle's middle angle)."""
    k = np.arange(segments + 1)
    angles = np.linspace(0, 2 * np.pi, segments, endpoint=False)
    rim = np.stack([np.cos(angles), np.sin(angles), 0 * angles], 1)
    positions = np.concatenate([rim, rim[:1], np.zeros((segments, 3))])
    uvs = np.concatenate([np.stack([np.ones(segments + 1), 1.0 - k / segments], 1),
                          np.stack([np.zeros(segments), 1.0 - (k[:-1] + 0.5) / segments], 1)])
    ring = np.arange(segments)
    faces = np.stack([segments + 1 + ring, ring, ring + 1], 1)
    return positions, faces.astype(np.int64), uvs


def _analytic(node, props, tessellation, textured=False):
    """Positions, faces, uvs (with ``textured``: ours, v up, from Mitsuba 3's (u, v)
    of each shape; else None) and the object-to-world matrix of a tessellated analytic
    shape. Mitsuba 3's (u, v): rectangle ((x + 1) / 2, (y + 1) / 2); disk (r, phi / 2
    pi); sphere (phi / 2 pi, theta / pi), theta from +z; cube each face's [0, 1]^2
    (its table); cylinder (phi / 2 pi, z), phi from the axis' frame's first vector
    (``_coordinate_system``); angles in [0, 2 pi) counter-clockwise about +z."""
    kind = node.attrs["type"]
    to_world = props.transform("to_world")
    if kind == "rectangle":
        positions = np.array([[-1.0, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]])
        uvs = _flip_v(0.5 * (positions[:, :2] + 1.0)) if textured else None
        return positions, np.array([[0, 1, 2], [0, 2, 3]]), uvs, to_world
    if kind == "disk":
        if textured:
            return (*_mitsuba_disk(tessellation.segments), to_world)
        return (*builtins.disk(tessellation.segments), None, to_world)
    if kind == "cube":  # [-1, 1]^3: the built-in unit cube doubled, or Mitsuba's own with its uvs
        if textured:
            return _CUBE_POSITIONS, _CUBE_FACES, _flip_v(_CUBE_UVS), to_world
        positions, faces = builtins.mesh("cube")
        return 2.0 * positions, faces, None, to_world
    if kind == "sphere":
        positions, faces = builtins.mesh("sphere", subdivisions=tessellation.sphere_levels)
        uvs = None
        if textured:
            positions, faces, uvs = builtins.spherical_uvs(positions, faces, mitsuba=True)
        radius = props.float("radius", 1.0)
        if not radius > 0:
            raise node.fail(f"radius must be > 0, got {radius}")
        place = np.eye(4)
        place[:3, :3] *= radius
        place[:3, 3] = props.vector("center", np.zeros(3))
        return positions, faces, uvs, to_world @ place
    if kind == "cylinder":
        p0, p1 = props.vector("p0", np.zeros(3)), props.vector("p1", np.array([0.0, 0, 1]))
        radius = props.float("radius", 1.0)
        axis = p1 - p0
        length = np.linalg.norm(axis)
        if not radius > 0 or length == 0:
            raise node.fail("needs radius > 0 and p0 != p1")
        z = axis / length
        x, y = _coordinate_system(z)
        place = np.eye(4)
        place[:3, 0], place[:3, 1], place[:3, 2], place[:3, 3] = radius * x, radius * y, length * z, p0
        if textured:
            positions, faces, uvs = builtins.textured_mesh("cylinder", *builtins.cylinder(tessellation.segments))
            return positions, faces, _flip_v(uvs), to_world @ place  # Mitsuba's v = z runs from p0 down the image
        return (*builtins.cylinder(tessellation.segments), None, to_world @ place)
    raise AssertionError(kind)


# -- materials ----------------------------------------------------------------------------


@dataclass(frozen=True)
class _Surface:
    """A shape's material as the project models it, and what the shape needs."""

    diffuse: tuple = (0.5, 0.5, 0.5)
    specular: tuple = (0.0, 0.0, 0.0)
    exponent: float = 0.0
    twosided: bool = False
    visible: bool = True  # False: the shape is left out (a null bsdf, a dielectric)
    fresnel: tuple | None = None  # Schlick's F0 of a mapped plastic or conductor
    texture: _Bitmap | None = None  # multiplies diffuse at each point (``textures``)
    microfacet: Microfacet | None = None  # a rough plastic's or conductor's own model (the rest its Phong stand-in)
    glass: Glass | None = None  # a dielectric, thin dielectric or rough dielectric (no Phong part)
    opacity: _Bitmap | None = None  # a mask's opacity image (``textures.check_opacity``)

    def untextured(self):
        """This surface with its texture folded into the diffuse colour (its mean)."""
        if self.texture is None:
            return self
        diffuse = tuple(float(d * m) for d, m in zip(self.diffuse, self.texture.mean, strict=True))
        microfacet = self.microfacet
        if microfacet is not None and microfacet.kind == "roughplastic":
            microfacet = replace(microfacet, diffuse_reflectance=tuple(
                float(d * m) for d, m in zip(microfacet.diffuse_reflectance, self.texture.mean, strict=True)))
        return _Surface(diffuse, self.specular, self.exponent, self.twosided, self.visible, self.fresnel,
                        microfacet=microfacet)


def _bitmap_property(doc, props, name):
    """The ``_Bitmap`` of property ``name`` if it is a bitmap texture, else None."""
    item = props.named.get(name)
    if item is None or item[1].tag != "texture" or item[1].attrs.get("type") != "bitmap":
        return None
    return _bitmap(doc, item[1])


def _surface(doc, node):
    """The _Surface of a ``<bsdf>`` element (after ``<ref>``), made once per element:
    the shapes that refer to one bsdf share its surface and its texture (a plastic's
    rescaled image is made once, not once per shape)."""
    node = doc.deref(node, ("bsdf",))
    key = id(node)
    if key not in doc.surfaces:
        if key in doc.building:
            raise node.fail("refers to itself (a cycle of bsdfs through <ref>)")
        doc.building.add(key)
        try:
            doc.surfaces[key] = _make_surface(doc, node)
        finally:
            doc.building.discard(key)
    return doc.surfaces[key]


def _make_surface(doc, node):
    kind = node.attrs.get("type")
    props = _Props(doc, node)
    inner = [c for c in props.unnamed if c.tag == "bsdf"]
    if kind == "twosided":
        if not inner:
            raise node.fail("needs the <bsdf> it makes two-sided")
        if len(inner) > 1:
            node.warn("a different bsdf on each side: the front's is used on both")
        surface = _surface(doc, inner[0])
        if surface.glass is not None:  # glass has two faces already
            return surface
        return replace(surface, twosided=True)
    if kind == "diffuse":
        bitmap = _bitmap_property(doc, props, "reflectance")
        if bitmap is not None:
            return _Surface(diffuse=(1.0, 1.0, 1.0), texture=bitmap)
        return _Surface(diffuse=props.colour("reflectance", 0.5))
    if kind in ("plastic", "roughplastic", "conductor", "roughconductor"):
        return _microfacet_surface(node, props, kind)
    if kind == "null":
        return _Surface(diffuse=(0.0, 0.0, 0.0), visible=False)
    if kind in ("dielectric", "thindielectric", "roughdielectric"):
        return _glass_surface(node, props, kind)
    if kind in ("bumpmap", "normalmap"):
        if not inner:
            raise node.fail("needs the <bsdf> it perturbs")
        node.warn(f"the {kind}'s detail is not modelled: the bsdf beneath it is used as it is")
        return _surface(doc, inner[0])
    if kind == "mask":
        if not inner:
            raise node.fail("needs the <bsdf> it masks")
        bitmap = _bitmap_property(doc, props, "opacity")
        if bitmap is not None:
            surface = _surface(doc, inner[0])
            if surface.glass is not None or not surface.visible:
                node.warn("a mask over glass or a null bsdf: the mask is left out")
                return surface
            return replace(surface, opacity=bitmap)
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
        if a.texture is not None or b.texture is not None:
            node.warn("a blend of textured bsdfs: each texture taken as its mean colour")
            a, b = a.untextured(), b.untextured()
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


def _roughness(node, props):
    """A rough bsdf's isotropic alpha (Mitsuba's default 0.1; alpha_u and alpha_v as their
    geometric mean, with a warning where they differ)."""
    alpha = props.float("alpha")
    if alpha is None and props.float("alpha_u") is not None:
        au, av = props.float("alpha_u"), props.float("alpha_v", props.float("alpha_u"))
        alpha = math.sqrt(au * av)
        if au != av:
            node.warn(f"anisotropic roughness ({au:g}, {av:g}) taken as isotropic {alpha:.4g}")
    return 0.1 if alpha is None else alpha


def _glass_surface(node, props, kind):
    """dielectric, thindielectric, roughdielectric: a ``Glass`` interface (Mitsuba's
    defaults: int_ior bk7, ext_ior air, a rough one's beckmann 0.1)."""
    eta = _ior(props, "int_ior", 1.5046) / _ior(props, "ext_ior", 1.000277)
    if eta == 1.0:
        node.warn("int_ior equals ext_ior: the interface bends and reflects nothing, so the shape is left out")
        return _Surface(visible=False)
    distribution, alpha = props.string("distribution", "beckmann"), 0.0
    if kind == "roughdielectric":
        alpha = _roughness(node, props)
        if distribution == "phong":
            node.warn("the phong distribution is mapped as beckmann of the same alpha")
            distribution = "beckmann"
        if not MIN_ALPHA <= alpha <= MAX_ALPHA:
            clipped = float(np.clip(alpha, MIN_ALPHA, MAX_ALPHA))
            node.warn(f"roughness alpha {alpha:g} taken as {clipped:g}, the nearest the microfacet model holds "
                      f"({MIN_ALPHA:g} to {MAX_ALPHA:g})")
            alpha = clipped
    elif distribution not in ("ggx", "beckmann"):
        distribution = "beckmann"
    for name in ("specular_reflectance", "specular_transmittance"):
        item = props.named.get(name)
        if item is not None and item[1].tag == "texture":
            node.warn(f"a textured {name} is taken as its mean colour")
    try:
        glass = Glass(kind, eta, distribution, alpha,
                      tuple(min(c, 1.0) for c in props.colour("specular_reflectance", 1.0)),
                      tuple(min(c, 1.0) for c in props.colour("specular_transmittance", 1.0)))
    except ValueError as exc:
        raise node.fail(str(exc)) from None
    return _Surface(diffuse=(0.0, 0.0, 0.0), glass=glass)


def _microfacet_surface(node, props, kind):
    """plastic, roughplastic, conductor, roughconductor by ``microfacet.phong_lobe_for``'s
    measured rule (the exponent that matches the lobe's half-maximum solid angle, ks
    and kd fitted to the original's albedos over incidence)."""
    alpha, distribution = None, props.string("distribution", "beckmann")
    if kind.startswith("rough"):
        alpha = _roughness(node, props)
        if distribution == "phong":  # Mitsuba 0.x's third distribution: close to Beckmann's at the same alpha
            node.warn("the phong distribution is mapped as beckmann of the same alpha")
            distribution = "beckmann"
    params = {"specular_reflectance": props.colour("specular_reflectance", 1.0)}
    bitmap = None
    if kind.endswith("plastic"):
        bitmap = _bitmap_property(props.doc, props, "diffuse_reflectance")
        params |= {"int_ior": _ior(props, "int_ior", 1.49), "ext_ior": _ior(props, "ext_ior", 1.000277),
                   "nonlinear": props.boolean("nonlinear")}
        if bitmap is None:
            params["diffuse_reflectance"] = props.colour("diffuse_reflectance", 0.5)
        else:
            brightest = np.clip(bitmap.texture.reshape(-1, 3).max(axis=0).astype(np.float64), 0.0, 1.0)
            params["diffuse_reflectance"] = tuple(np.where(brightest > 0, brightest, 1.0))
    elif "eta" in props.named or "k" in props.named:
        params |= {"eta": props.colour("eta", 0.0), "k": props.colour("k", 1.0)}
    else:
        params["material"] = props.string("material", "none")
    try:
        kd, ks, exponent, fresnel = microfacet.phong_lobe(kind, distribution, alpha if alpha is not None else 0.1,
                                                          **params)
        model = None
        if alpha is not None:  # the smooth kinds keep their Phong stand-in (n = MAX_EXPONENT) everywhere
            reference = microfacet.reference_brdf(kind, distribution, alpha, **params)
            if not MIN_ALPHA <= alpha <= MAX_ALPHA:
                node.warn(f"roughness alpha {alpha:g} taken as {float(np.clip(alpha, MIN_ALPHA, MAX_ALPHA)):g}, "
                          f"the nearest the microfacet model holds ({MIN_ALPHA:g} to {MAX_ALPHA:g})")
            model = Microfacet(kind, distribution, float(np.clip(alpha, MIN_ALPHA, MAX_ALPHA)),
                               (reference.eta,) * 3 if kind == "roughplastic" else tuple(reference.eta),
                               (0.0,) * 3 if kind == "roughplastic" else tuple(reference.k),
                               tuple(reference.specular_reflectance),
                               tuple(reference.diffuse_reflectance) if kind == "roughplastic" else (0.0,) * 3,
                               bool(getattr(reference, "nonlinear", False)))
    except (InputError, ValueError) as exc:
        raise node.fail(str(exc)) from None
    if bitmap is None:
        return _Surface(diffuse=kd, specular=ks, exponent=exponent, fresnel=fresnel, microfacet=model)
    return _Surface(diffuse=kd, specular=ks, exponent=exponent, fresnel=fresnel, microfacet=model,
                    texture=_plastic_texture(bitmap, kind, distribution, alpha, params))


def _plastic_texture(bitmap, kind, distribution, alpha, params):
    """A plastic's diffuse texture relative to its brightest texel M (the
    ``diffuse_reflectance`` its lobe was mapped with): g(texel) / g(M), g the
    substrate's kd' = kd / (1 - R_int) (linear: the texel over M) or, ``nonlinear``,
    kd / (1 - kd R_int) with the interface's internal reflectance R_int."""
    brightest = np.asarray(params["diffuse_reflectance"], dtype=np.float64)
    texels = bitmap.texture.astype(np.float64)
    if not params.get("nonlinear"):
        return bitmap.scaled(texels / brightest)
    linear = dict(params, diffuse_reflectance=1.0, nonlinear=False)
    r_int = 1.0 - 1.0 / float(microfacet.reference_brdf(kind, distribution, alpha or 0.1, **linear).substrate[0])
    g = lambda kd: kd / (1.0 - kd * r_int)  # noqa: E731
    return bitmap.scaled(np.clip(g(texels) / g(brightest), 0.0, 1.0))


_NAMED_IOR = {"vacuum": 1.0, "helium": 1.000036, "hydrogen": 1.000132, "air": 1.000277, "carbon dioxide": 1.00045,
              "water": 1.333, "acetone": 1.36, "ethanol": 1.361, "carbon tetrachloride": 1.461, "glycerol": 1.4729,
              "benzene": 1.501, "silicone oil": 1.52045, "bromine": 1.661, "water ice": 1.31, "fused quartz": 1.458,
              "pyrex": 1.47, "acrylic glass": 1.49, "polypropylene": 1.49, "bk7": 1.5046, "glass": 1.5046,
              "sodium chloride": 1.544, "amber": 1.55, "pet": 1.575, "polycarbonate": 1.58, "diamond": 2.419}


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
        if np.linalg.det(to_world[:3, :3]) < 0 and (normals is not None or kind not in ("obj", "ply", "serialized")):
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
