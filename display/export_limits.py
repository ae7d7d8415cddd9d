"""What ``vlights export`` needs, said before it starts: memory on this
machine, and texture sizes in the browser that draws its page.

Memory. ``fit_sizes`` reads a fit.npz's zip directory and the headers of the arrays
whose shapes matter (no array is read: 0.35 s for the 1,572 objects of the million-
triangle interior, whose export takes 8 s), and ``export_estimate`` turns them into the
export's peak resident memory: the process (Python, numpy, trimesh), and for each value
of the fit what it costs while the model is held, trimesh's meshes are built and the
GLB is assembled in memory (the model's float32 arrays; trimesh's float64 vertices and
normals and int64 faces; each accessor's bytes, their join into one buffer and the
whole file, each a copy). The bytes a value are measured (peak resident memory,
``/usr/bin/time -v``, on 16 fits: 13 synthetic ones of 1 to 8,000 objects and up to
2.7 GB, and the scaling interior at 10^4, 10^5 and 10^6 triangles; a least-squares fit
of all of them), and rounded up (the constants' comments hold the fitted figures): the
mesh (positions, normals, faces) 22.5 bytes a value, the per-vertex attributes the GLB
carries 20, a texture's texel 30 (its 8-bit sRGB codes are found through int64
searches), the environment's 16, a probe's texel 122 (it is written into the mesh's
JSON extras: Python floats, then text), every other value 7, and 16 kB an object. The
estimate was 1.08 to 1.29 times the measured peak on each of the 16.
``check_export_memory`` says an estimate of a gigabyte or more on stderr, as ``render``
says a large upload (``display.store.SAY_BYTES``: smaller ones are silent), and
refuses, in one line, one beyond the memory this process may still use
(``radiosity.policies.limits.available_memory``).

Textures. The page (``display/web/walkthrough.js``) puts each object's per-light
coefficients (V x K values) and its emitters' visibility (V x P) in a float texture
``TEXTURE_WIDTH`` (4096) wide, one row per 4096 values, its lights in a 2 x K texture
and its probe in an M x M one, and checks them at load against the browser's
``MAX_TEXTURE_SIZE``. WebGL2 promises only 2048, but the page's textures are 4096 wide
already, so an object with per-light coefficients or highlights needs 4096 anywhere;
about every WebGL2 device makes 4096 (99 % of devices in 2020, about half of them more:
web3dsurvey's MAX_TEXTURE_SIZE counts), so 4096 is what a page can assume.
``page_textures`` lists what is larger than that (including the environment's image),
and ``check_page_textures`` says it in one line: a warning, not a refusal, since the
glTF file is right for every other viewer and the page itself says, naming the object
and the limit, when the browser it runs in cannot draw it.
"""

from __future__ import annotations

import math
import sys
from typing import NamedTuple

from radiosity.files.errors import InputError
from radiosity.files.npz import open_archive
from radiosity.physics.environment import IMAGE_KEY
from radiosity.policies.limits import available_memory

from .glsl import FLOAT_TEXTURE_WIDTH
from .store import SAY_BYTES

__all__ = ["PAGE_TEXTURE_SIZE", "FitSizes", "ObjectSizes", "PageTexture", "check_export_memory", "check_page_textures",
           "export_estimate", "fit_sizes", "object_textures", "page_textures"]

GIB = 2**30  # the fit's "GB" (fitting.memory)
# The export's peak, measured on 16 fits (/usr/bin/time -v: peak resident memory; the
# figures in brackets are a least-squares fit of all of them) and rounded up:
PROCESS_BYTES = 180 * 2**20  # the process before its fit: Python, numpy, trimesh, numba (166 MB)
MESH_BYTES = 25              # a value of positions, normals, faces (22.5)
ATTRIBUTE_BYTES = 22         # a value of a per-vertex attribute the GLB carries: emitted, specular, ... (20.3)
TEXTURE_BYTES = 33           # a texel value of a textured object's image (30.3)
ENVIRONMENT_BYTES = 18       # a texel value of the environment's image (16.4)
PROBE_BYTES = 135            # a texel value of a probe, written into the JSON (122)
REST_BYTES = 8               # any other value, loaded and checked: a diffuse object's zero specular, lights (6.9)
OBJECT_BYTES = 20 * 2**10    # an object's trimesh mesh, node and JSON besides its values (15.6 kB)
VALUE_BYTES = 4              # a float32 or int32 value as stored

PAGE_TEXTURE_SIZE = 4096  # the largest texture side the page may assume (see the module's docstring)
TEXTURE_WIDTH = FLOAT_TEXTURE_WIDTH  # the page's coefficient and visibility textures' width (shading.js)

MESH_KEYS = ("positions", "normals", "faces")
ATTRIBUTE_KEYS = ("emitted", "probe_weight", "visibility", "irradiance", "uvs")  # and specular, with lights
SHAPED = ("positions", "light_pos", "light_dirs", "specular", "visibility", "probe", "texture")  # headers read
NPY_HEADER = 128  # bytes of a .npy header (numpy pads it to 64-byte blocks: 128 for these arrays)


class ObjectSizes(NamedTuple):
    """An object of a fit file as its array headers give it."""

    name: str
    vertices: int        # V
    lights: int          # K
    per_light: bool      # specular (V, K, 3): a coefficient per light
    parts: int           # P: emitter parts whose visibility it holds
    probe: int           # M of its M x M probe (0: none)
    values: dict         # values (float32 / int32 numbers) of each of its arrays, by key ("positions", ...)
    image: tuple | None = None  # its texture as stored, (CRC-32, bytes): objects that share an image share this


class FitSizes(NamedTuple):
    """A fit file's objects (``ObjectSizes``) and its environment image's (height, width) (None: none)."""

    objects: tuple
    environment: tuple | None


def _shape_values(shape):
    return math.prod(int(n) for n in shape)


def _stored_values(archive, key):
    """Values of member ``key`` counted from the zip's directory alone (its uncompressed
    size less a .npy header, over 4 bytes: exact for float32 and int32 arrays, which the
    fit's are; more for wider types)."""
    size = archive.npz.zip.getinfo(f"{key}.npy").file_size
    return max(size - NPY_HEADER, 0) // VALUE_BYTES


def fit_sizes(path):
    """The ``FitSizes`` of fit.npz ``path`` from its meta, its zip directory and the
    headers of the arrays whose shape matters (positions, lights, specular, visibility,
    probe, texture): no array is read. InputError (one line) if it is not a fit file. A
    malformed file's arrays are counted as they are: ``fitting.load_fit``, after, names
    what is wrong."""
    from fitting.model import FORMAT, READS

    with open_archive(path, FORMAT, READS) as archive:
        names = archive.meta.get("objects")
        names = list(names) if isinstance(names, dict) else []
        members = {}  # object name -> its arrays' keys ("positions", ...)
        for key in archive.keys:
            owner, _, member = key.partition("/")
            if member and "/" not in member:
                members.setdefault(owner, []).append(member)
        objects = []
        for name in names:
            own = members.get(name, ())
            shapes = {m: archive.header(f"{name}/{m}")[0] for m in own if m in SHAPED}
            values = {m: _shape_values(shapes[m]) if m == "texture" else _stored_values(archive, f"{name}/{m}")
                      for m in own}

            def side(key, axis, shapes=shapes):
                shape = shapes.get(key, ())
                return int(shape[axis]) if len(shape) > axis else 0

            objects.append(ObjectSizes(
                name=str(name), vertices=side("positions", 0), lights=side("light_pos", 0) or side("light_dirs", 0),
                per_light=len(shapes.get("specular", ())) == 3, parts=side("visibility", 1), probe=side("probe", 0),
                values=values, image=archive.stored_as(f"{name}/texture") if "texture" in own else None,
            ))
        environment = None
        if IMAGE_KEY in archive.keys:
            shape = archive.header(IMAGE_KEY)[0]
            environment = (int(shape[0]), int(shape[1]) if len(shape) > 1 else 1)
    return FitSizes(tuple(objects), environment)


def _attribute_values(obj):
    """(keys, values) of ``obj``'s per-vertex attributes in the GLB (``display.export.vertex_attributes``
    and its uvs): the emitted colour, the specular coefficients if it has lights, the
    probe's weight, the visibility padded to three parts an attribute, the irradiance and uvs."""
    keys = ATTRIBUTE_KEYS + (("specular",) if obj.lights else ())
    values = sum(obj.values.get(k, 0) for k in keys if k != "visibility")
    return keys, values + obj.vertices * 3 * -(-obj.parts // 3)


def export_estimate(sizes):
    """Bytes of the export's peak resident memory, for a ``FitSizes`` (constants above)."""
    need = PROCESS_BYTES + OBJECT_BYTES * len(sizes.objects)
    images = {}  # an image once, however many objects share it (display.export._Images)
    for obj in sizes.objects:
        v = obj.values
        keys, attributes = _attribute_values(obj)
        rest = sum(n for k, n in v.items() if k not in (*MESH_KEYS, *keys, "texture", "probe"))
        need += (MESH_BYTES * sum(v.get(k, 0) for k in MESH_KEYS) + ATTRIBUTE_BYTES * attributes
                 + PROBE_BYTES * v.get("probe", 0) + REST_BYTES * rest)
        images[obj.name if obj.image is None else obj.image] = v.get("texture", 0)
    need += TEXTURE_BYTES * sum(images.values())
    if sizes.environment is not None:
        need += ENVIRONMENT_BYTES * 3 * sizes.environment[0] * sizes.environment[1]
    return need


def _largest(sizes):
    if not sizes.objects:
        return ""
    obj = max(sizes.objects, key=lambda o: sum(o.values.values()))
    lights = f" x {obj.lights:,} lights" if obj.per_light else ""
    return f"; largest object {obj.name!r}: {obj.vertices:,} vertices{lights}"


def check_export_memory(sizes, available=None, say=None):
    """The export's estimate (bytes) for a ``FitSizes``; said with ``say`` (a function of
    one line; default: a line on stderr) when it is SAY_BYTES or more (as ``render``
    says a large upload); InputError (one line) when it exceeds ``available`` (default:
    the memory this process may still use, ``available_memory``)."""
    say = say or (lambda line: print(line, file=sys.stderr))
    available = available_memory() if available is None else available
    need = export_estimate(sizes)
    have = "" if available is None else f" of {available / GIB:.1f} GB available"
    if available is not None and need > available:
        n = len(sizes.objects)
        raise InputError(f"export needs about {need / GIB:.1f} GB of memory but {available / GIB:.1f} GB is available "
                         f"({n} object{'s' if n != 1 else ''}{_largest(sizes)}); free memory, or export on a machine "
                         "with more")
    if need >= SAY_BYTES:
        say(f"export: about {need / GIB:.2f} GB at most{have}")
    return need


class PageTexture(NamedTuple):
    """A texture the page makes: ``what`` it holds (of object ``name``; None: the
    scene's), ``width`` x ``height`` texels."""

    name: str | None
    what: str
    width: int
    height: int


def object_textures(obj):
    """The textures the page makes for an ``ObjectSizes`` (walkthrough.js ``textureNeeds``)."""
    out = [PageTexture(obj.name, f"its {obj.lights} lights", 2, max(obj.lights, 1))]
    if obj.per_light and obj.lights:
        what = f"its per-light coefficients ({obj.vertices:,} vertices x {obj.lights} lights)"
        out.append(PageTexture(obj.name, what, TEXTURE_WIDTH, max(1, -(-obj.vertices * obj.lights // TEXTURE_WIDTH))))
    if obj.parts:
        out.append(PageTexture(obj.name, f"its emitters' visibility ({obj.vertices:,} vertices x {obj.parts} parts)",
                               TEXTURE_WIDTH, max(1, -(-obj.vertices * obj.parts // TEXTURE_WIDTH))))
    if obj.probe:
        out.append(PageTexture(obj.name, "its probe", obj.probe, obj.probe))
    return out


def page_textures(sizes, limit=PAGE_TEXTURE_SIZE):
    """The page's textures (``PageTexture``) with a side over ``limit``, largest first."""
    textures = [t for obj in sizes.objects for t in object_textures(obj)]
    if sizes.environment is not None:
        h, w = sizes.environment
        textures.append(PageTexture(None, "the environment's image", w, h))
    return sorted((t for t in textures if max(t.width, t.height) > limit), key=lambda t: -max(t.width, t.height))


def check_page_textures(sizes, say=None, limit=PAGE_TEXTURE_SIZE):
    """Say in one line (``say``; default: on stderr) which of the page's textures are
    larger than ``limit`` texels on a side; returns them (``page_textures``)."""
    say = say or (lambda line: print(line, file=sys.stderr))
    large = page_textures(sizes, limit)
    if large:
        t = large[0]
        side = max(t.width, t.height)
        owner = "the scene" if t.name is None else f"object {t.name!r}"
        more = f" ({len(large) - 1} more texture{'s' if len(large) > 2 else ''} over {limit})" if len(large) > 1 else ""
        say(f"export: warning: {owner} needs a {t.width} x {t.height} texture on the page for {t.what}{more}; a "
            f"browser draws it only where MAX_TEXTURE_SIZE is at least {side} (almost every WebGL2 device makes "
            f"{limit}, about half more); elsewhere the page refuses it by name")
    return large
