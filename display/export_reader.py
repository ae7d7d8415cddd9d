"""Reading an export back: ``load_export(path)`` reads a scene.glb ``display.export``
wrote (every version it ever wrote, docs/formats.md) into the ``FittedModel`` it came
from, each problem one ``InputError`` naming the file.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from radiosity.files.errors import InputError
from radiosity.physics.materials import Microfacet

from .export import FORMAT, READS, visibility_attributes


def _chunks(path):
    """The JSON header of a .glb file (a dict) and its binary chunk (bytes, empty if it
    has none); InputError if it is not one."""
    data = Path(path).read_bytes()
    if len(data) < 20 or data[:4] != b"glTF":
        raise InputError(f"{str(path)!r} is not a binary glTF file")
    length = int.from_bytes(data[12:16], "little")
    header = json.loads(data[20:20 + length])
    start = 20 + length
    binary = b""
    if len(data) >= start + 8 and data[start + 4:start + 8] == b"BIN\0":
        size = int.from_bytes(data[start:start + 4], "little")
        binary = data[start + 8:start + 8 + size]
    return header, binary


def _read_environment(header, extras, binary, fail):
    """The ``EnvironmentLight`` of the scene ``extras``' ``"environment"`` and its
    bufferView among the ``header``'s (None if the file has none)."""
    from radiosity.physics.environment import EnvironmentLight

    entry = extras.get("environment")
    if entry is None:
        return None
    fail_env = lambda message: fail(f"scene extras 'environment': {message}")  # noqa: E731
    try:
        width, height, view = (entry[k] for k in ("width", "height", "bufferView"))
        rotation = np.asarray(entry["rotation"], np.float64)
        scale, constant = float(entry["scale"]), entry["constant"]
    except (KeyError, TypeError, ValueError):
        raise fail_env("needs 'width', 'height', 'scale', 'rotation' (3 x 3), 'constant' and 'bufferView'") from None
    numbers = (width, height, view)
    if any(isinstance(n, bool) or not isinstance(n, int) for n in numbers) or min(width, height) < 1 or view < 0:
        raise fail_env(f"'width' and 'height' must be whole numbers >= 1 and 'bufferView' >= 0, got {numbers}")
    if not isinstance(constant, bool):
        raise fail_env(f"'constant' must be true or false, got {constant!r}")
    views = header.get("bufferViews") or []
    want = width * height * 3 * 4
    if view >= len(views):
        raise fail_env(f"bufferView {view} does not exist ({len(views)} views)")
    v = views[view]
    offset, length = v.get("byteOffset", 0), v.get("byteLength")
    if v.get("buffer") != 0 or length != want or offset < 0 or offset + length > len(binary):
        raise fail_env(f"bufferView {view} must hold {height} x {width} x 3 float32 ({want} bytes) of the GLB's "
                       "own buffer")
    image = np.frombuffer(binary, "<f4", width * height * 3, offset).reshape(height, width, 3).astype(np.float32)
    try:
        return EnvironmentLight(image, scale, rotation, constant, str(entry.get("source", "")))
    except InputError as exc:
        raise fail_env(str(exc)) from None


def _attribute(attributes, key, v, fail):
    a = attributes.get(key)
    if a is None or np.shape(a) != (v, 3):
        raise fail(f"has no vertex attribute {key} (VEC3)")
    return np.asarray(a, np.float32)


def _read_highlight(info, attributes, v, parts, nodes, fail):
    """An object's ``Highlight`` from its mesh extras and attributes (None if it has none):
    of the scene's ``parts`` all, or those its ``highlight.parts`` name (version 6)."""
    from fitting.model import Highlight
    from radiosity.physics.emitters import MAX_FILE_PARTS

    entry = info.get("highlight")
    if entry is None:
        return None
    try:
        ks = np.asarray(entry["ks"], np.float64).reshape(3)
        exponent = float(entry["exponent"])
        fresnel = None if entry.get("fresnel") is None else np.asarray(entry["fresnel"], np.float64).reshape(3)
    except (KeyError, TypeError, ValueError):
        raise fail("'highlight' needs 'ks' [r, g, b] and 'exponent' (and 'fresnel' [r, g, b] if given)") from None
    microfacet = None
    if entry.get("microfacet") is not None:
        try:
            microfacet = Microfacet.from_dict(entry["microfacet"])
        except ValueError as exc:
            raise fail(f"'highlight' {exc}") from None
    indices = entry.get("parts")
    if indices is not None:
        if not (isinstance(indices, list) and len(indices) <= MAX_FILE_PARTS and len(set(indices)) == len(indices)
                and all(isinstance(i, int) and not isinstance(i, bool) and 0 <= i < len(parts) for i in indices)):
            raise fail(f"'highlight' 'parts' must name at most {MAX_FILE_PARTS} distinct parts of the scene's "
                       f"{len(parts)}")
        indices = tuple(indices)
        parts = tuple(parts[i] for i in indices)
    elif len(parts) > MAX_FILE_PARTS:
        raise fail(f"'highlight' draws {len(parts)} emitter parts; without its own 'parts' an object draws at most "
                   f"{MAX_FILE_PARTS}")
    p = len(parts)
    columns = [_attribute(attributes, key, v, fail) for key in visibility_attributes(np.zeros((0, p)))]
    visibility = np.concatenate(columns, axis=1)[:, :p] if columns else np.zeros((v, 0), np.float32)
    return Highlight(parts, nodes, ks, exponent, np.ascontiguousarray(visibility, np.float32), fresnel, indices,
                     microfacet)


def _read_probe(info, attributes, v, fail):
    """An object's (``Probe``, weight (V, 3)) from its mesh extras and attributes, or (None, None)."""
    from fitting.probe import ALBEDO_POINTS, Probe

    entry = info.get("probe")
    if entry is None:
        return None, None
    try:
        m = int(entry["size"])
        probe = Probe(texels=np.asarray(entry["texels"], np.float32).reshape(m, m, 3),
                      centre=np.asarray(entry["centre"], np.float64).reshape(3),
                      box=np.asarray(entry["box"], np.float64).reshape(2, 3),
                      albedo=np.asarray(entry["albedo"], np.float64).reshape(ALBEDO_POINTS))
    except (KeyError, TypeError, ValueError):
        raise fail(f"'probe' needs 'size' M, 'centre', 'box', 'albedo' ({ALBEDO_POINTS} numbers) and "
                   "'texels' (M * M * 3 numbers)") from None
    return probe, _attribute(attributes, "_PROBE", v, fail)


def _read_textured(info, mesh, v, fail, decoded):
    """An object's ``TexturedDiffuse`` from its mesh extras, uvs, image and
    ``_IRRADIANCE`` (None if it has none). The image's 8-bit sRGB codes are decoded as
    the solution's are (``radiosity.physics.textures``): a texture that was such a
    decoding comes back exact; a material whose alphaMode is MASK (version 8) has its
    mask in the image's alpha (codes / 255). ``decoded`` ((id(image), masked) ->
    (image, texture, opacity)) holds each image decoded once: objects whose materials share an image share its array, as
    they do read from fit.npz."""
    from radiosity.physics.materials import srgb_to_linear
    from radiosity.physics.textures import TexturedDiffuse

    entry = info.get("textured")
    if entry is None:
        return None
    try:
        kd = np.asarray(entry["kd"], np.float64).reshape(3)
    except (KeyError, TypeError, ValueError):
        raise fail("'textured' needs 'kd' [r, g, b]") from None
    visual = mesh.visual
    uv = getattr(visual, "uv", None)
    if uv is None or np.shape(uv) != (v, 2):
        raise fail("is textured but has no TEXCOORD_0 (VEC2) for each vertex")
    material = getattr(visual, "material", None)
    image = getattr(material, "baseColorTexture", None)
    if image is None or not hasattr(image, "convert"):
        raise fail("is textured but its material has no baseColorTexture image")
    masked = getattr(material, "alphaMode", None) == "MASK"  # version 8: the image's alpha is the mask
    if (id(image), masked) not in decoded:
        codes = np.asarray(image.convert("RGBA" if masked else "RGB"))
        texture = srgb_to_linear(np.arange(256) / 255.0).astype(np.float32)[codes[..., :3]]
        opacity = (codes[..., 3] / np.float32(255.0)).astype(np.float32) if masked else None
        decoded[(id(image), masked)] = (image, texture, opacity)
    _, texture, opacity = decoded[(id(image), masked)]
    irradiance = _attribute(mesh.vertex_attributes, "_IRRADIANCE", v, fail)
    try:
        return TexturedDiffuse(uvs=np.asarray(uv, np.float64), irradiance=irradiance, texture=texture, kd=kd,
                               opacity=opacity)
    except ValueError as exc:
        raise fail(f"textured: {exc}") from None


def load_export(path):
    """Read a ``scene.glb`` written by ``export_glb`` (version 5, 4, 3, 2 or 1) back into a
    ``FittedModel`` (arrays float32 / int32 as in ``fitting.model``; a diffuse object's
    specular is zeros (V, 3); the environment's image exact). InputError if the file is
    not of this schema."""
    import trimesh

    from fitting.model import FittedModel, FittedObject
    from radiosity.files.camera import camera_from_dict
    from radiosity.physics.emitters import DEFAULT_NODES, MAX_NODES, file_parts

    shown = repr(str(path))
    header, binary = _chunks(path)
    extras = (header.get("scenes") or [{}])[0].get("extras") or {}
    if extras.get("format") != FORMAT or extras.get("version") not in READS:
        versions = ", ".join(map(str, READS[:-1])) + f" or {READS[-1]}"
        raise InputError(f"{shown} is not a {FORMAT} version {versions} file")
    version = extras["version"]

    def fail(message):
        return InputError(f"{shown}: {message}")

    parts, nodes = (), DEFAULT_NODES
    if version >= 2:
        parts = file_parts(extras.get("emitters", []), lambda m: fail(f"scene extras: {m}"), delta=version >= 5,
                           own=version >= 6)
        nodes = extras.get("emitter_nodes", DEFAULT_NODES)
        if isinstance(nodes, bool) or not isinstance(nodes, int) or not 1 <= nodes <= MAX_NODES:
            raise fail(f"scene extras 'emitter_nodes' must be a whole number from 1 to {MAX_NODES}, got {nodes!r}")
    environment = _read_environment(header, extras, binary, fail) if version >= 4 else None  # before trimesh's checks
    scene = trimesh.load(path, file_type="glb", force="scene", process=False)
    objects, decoded = [], {}  # decoded: each image decoded once (_read_textured)
    for name in extras["objects"]:
        mesh = scene.geometry[name]
        info = mesh.metadata
        k = int(info["lights"])
        v = len(mesh.vertices)
        attributes = mesh.vertex_attributes

        def object_fail(message, name=name):
            return fail(f"object {name!r} {message}")

        if k == 0:
            specular = np.zeros((v, 3), np.float32)
        elif info["per_light"]:
            specular = np.stack([np.asarray(attributes[f"_SPECULAR_{i}"], np.float32) for i in range(k)], axis=1)
        else:
            specular = np.asarray(attributes["_SPECULAR"], np.float32)
        highlight, (probe, weight), textured = None, (None, None), None
        if version >= 2:
            highlight = _read_highlight(info, attributes, v, parts, nodes, object_fail)
            probe, weight = _read_probe(info, attributes, v, object_fail)
        if version >= 3:
            textured = _read_textured(info, mesh, v, object_fail, decoded)
        objects.append(FittedObject(
            name=name,
            positions=np.asarray(mesh.vertices, np.float32),
            normals=np.asarray(mesh.vertex_normals, np.float32),
            faces=np.asarray(mesh.faces, np.int32),
            emitted=np.asarray(attributes["_EMITTED"], np.float32),
            specular=specular,
            light_pos=np.asarray(info["light_pos"], np.float32).reshape(k, 4),
            light_rgb=np.asarray(info["light_rgb"], np.float32).reshape(k, 3),
            shininess=np.asarray(info["shininess"], np.float32).reshape(k),
            highlight=highlight,
            probe=probe,
            probe_weight=weight,
            textured=textured,
        ))
    camera = camera_from_dict(extras["camera"], where="scene extras 'camera'") if "camera" in extras else None
    return FittedModel(objects=tuple(objects), source=extras.get("source", ""), model=extras.get("model", ""),
                       camera=camera, emitters=parts, emitter_nodes=nodes, environment=environment)
