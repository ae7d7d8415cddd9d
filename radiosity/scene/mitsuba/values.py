"""Typed values of a Mitsuba element: numbers, colours and spectra, the properties of
an element by name in either spelling (``_Props``), transforms, and bitmap textures
(read once per element through the one image reader, ``radiosity.files.images``: their
uv transform, wrap mode and alpha; a texture's mean colour where a colour is needed).
"""

from __future__ import annotations

import math
import re
import warnings
from dataclasses import dataclass

import numpy as np

from radiosity.files.errors import InputError, SceneWarning
from radiosity.files.images import read_image
from radiosity.physics.materials import srgb_to_linear
from radiosity.physics.textures import WRAP_MODES, as_repeating
from radiosity.scene.geometry import singular
from radiosity.scene.spectra import spectrum_to_rgb

from .document import Node, _snake


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


def _a(tag):
    """``tag`` ("<emitter>", "<bsdf ...>") with its article."""
    return f"{'an' if tag[1] in 'aeiou' else 'a'} {tag}"


class _Props:
    """The properties of one element: ``named`` (``float``, ``rgb``, a named
    ``texture`` or ``ref``, ...: name -> (the element, what it stands for after
    ``<ref>``)) and ``unnamed`` (nested or referenced ``bsdf``, ``shape``, ``emitter``,
    ``film``, ... elements)."""

    def __init__(self, doc, node):
        self.doc, self.node = doc, node
        self.named = {}
        self.unnamed = []
        self.refs = []  # (the <ref>, what it names) of every reference without a name
        for child in node.children:
            target = doc.deref(child, _REFERABLE)
            name = child.attrs.get("name")
            if name is not None and child.tag in _PROPERTY_TAGS | {"ref"}:
                self.named[_snake(name)] = (child, target)
            if name is None or target.tag == "bsdf":
                self.unnamed.append(target)
            if name is None and child.tag == "ref":
                self.refs.append((child, target))

    def check_refs(self, takes):
        """InputError at the first unnamed ``<ref>`` naming an element whose tag (or a
        shape's type, ``shape:TYPE``) is not one of ``takes``: Mitsuba refuses such a
        reference, and reading on would drop it in silence."""
        for ref, target in self.refs:
            kind = f"shape:{target.attrs.get('type')}" if target.tag == "shape" else target.tag
            if kind not in takes:
                names = [_a(f"<{t}>" if ":" not in t else f"<shape type={t.split(':')[1]!r}>") for t in takes]
                wanted = names[0] if len(names) == 1 else f"{', '.join(names[:-1])} or {names[-1]}"
                found = _a(f"<{target.tag} type={target.attrs.get('type')!r}>")
                raise ref.fail(f"id {ref.attrs.get('id')!r} is {found}, where a <{self.node.tag}> takes {wanted}")

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
                if not np.array_equal(m[3], (0.0, 0.0, 0.0, 1.0)):
                    raise step.fail(f"the last row must be 0 0 0 1, got {' '.join(f'{v:g}' for v in m[3])} (a projective "
                                    "transform is not read)")
            else:
                m[:3, :3] = np.array(values).reshape(3, 3)
        elif step.tag == "lookat":
            m = _look_at(step)
        else:
            raise step.fail("not a transform step (matrix, translate, rotate, scale, lookat)")
        matrix = m @ matrix
    if not np.isfinite(matrix).all() or singular(matrix[:3, :3]):
        raise node.fail("the transform is singular or not finite")
    return matrix
