"""``vlights export``: a fitted model (fit.npz) as a binary glTF,
``DIR/scene.glb``, and a WebGL walkthrough of it, ``DIR/index.html`` (the page and the
three.js modules it needs, copied from ``display/web``, the renderer's shader files from
``display/shaders`` into ``DIR/shaders``, and ``shading.js``, the ``#define`` lines of the
fit's emitter quadrature: the directory works offline, served by ``vlights serve DIR``
or any static server).

Schema (format ``vlights.fit.gltf``, version 7; docs/formats.md). V is an
object's vertex count, K its number of virtual lights, P the number of emitter parts
its highlight draws (the scene's, or its own: version 6), M an object's probe size. A
file is written with the lowest version that holds it: 7 where a highlight has a
microfacet lobe (its mesh extras' ``highlight.microfacet``, the fit's model, and
``highlight.lobe`` = {"code": 1 GGX or 2 Beckmann, "alpha", "ks", "f0"}, what the page
draws it with: ``radiosity.physics.ltc.highlight_lobe``; the table of
linearly transformed cosines is ``shading.js``'s ``LTC_TABLE``), else 6 where an object names its own
emitter parts (its mesh extras' ``highlight.parts``: indices into the scene's
``emitters`` and ``emitter_table``, which may then hold more than 31), else 5 with a
delta emitter part (a point, a spot, a direction: version 5 adds those
kinds to ``emitters`` and ``emitter_table``, and may have an environment too), else 4
with an environment, else 3 with a textured object, else 2 (the same bytes as before
textures and environments):

- one glTF mesh (and one node, identity transform) per object of the fit, named as
  the object, in the fit's order; one triangle primitive with attributes
  ``POSITION`` (V, 3) float32, ``NORMAL`` (V, 3) float32 (the fit's normals as they
  are, not renormalised), indices = the fit's ``faces``, and the custom attributes

  - ``_EMITTED`` (V, 3) float32: the emitted colour;
  - ``_SPECULAR`` (V, 3) float32: the coefficient shared by all lights, or
    ``_SPECULAR_0`` .. ``_SPECULAR_{K-1}`` (V, 3) float32 each: the coefficient of
    light k, when the coefficients are per light. A diffuse object (K = 0) has no
    ``_SPECULAR`` (its specular part is 0);
  - ``_PROBE`` (V, 3) float32, an object with a reflection probe: its per-vertex
    weight s;
  - ``_VISIBILITY_0`` .. ``_VISIBILITY_{ceil(P/3)-1}`` (V, 3) float32, an object with
    the emitters' highlights: the fraction of each part each vertex sees, three parts
    per attribute (part 3 j + c in channel c of ``_VISIBILITY_j``; the last one's
    channels past part P - 1 are 0);
  - ``_IRRADIANCE`` (V, 3) float32, a textured object (version 3): the irradiance E
    of its diffuse term ``kd * texture(uv) / pi * E`` (``radiosity.physics.textures``);

  values are the fit's float32 bits, not clamped;
- a textured object (version 3) has, besides, ``TEXCOORD_0`` (V, 2) float32, glTF's
  (u, 1 - v) (glTF's v runs down the image; the fit's uvs run up: trimesh flips them
  on export and back on import, so they come back within float32 rounding), and a
  material (named as the object, double sided, metallic 0, roughness 1) whose
  ``pbrMetallicRoughness.baseColorTexture`` is its image as a PNG in the GLB's buffer
  (8-bit RGB, the sRGB encoding of the linear texture, row 0 the image's top; sampler
  REPEAT both ways, LINEAR_MIPMAP_LINEAR / LINEAR) and ``baseColorFactor`` [kd, 1], so
  that other glTF viewers show the object's diffuse colour. Objects with the same
  image share its PNG, image and texture (``_Images``). The PNG is exact for a
  texture decoded from 8-bit sRGB (every image file's: ``linear_to_srgb8``); another
  (a float texture) is rounded: its sRGB encoding to the nearest of the 256 codes;
- the mesh's ``extras``: ``{"name", "lights": K, "per_light": bool, "light_pos":
  K x [x, y, z, w], "light_rgb": K x [r, g, b], "shininess": [K numbers]}``, with
  ``light_pos`` as in fit.npz (w = 0: a unit vector towards a distant light, w = 1:
  a point light's world position); and where the object has them
  ``"highlight": {"ks": [r, g, b], "exponent": p}`` (its modified-Phong specular part)
  and ``"probe": {"size": M, "centre": [x, y, z], "box": [[lo], [hi]], "albedo":
  [ALBEDO_POINTS numbers], "texels": [M * M * 3 numbers]}`` (texels C-ordered as the
  fit's (M, M, 3) array: ``texels[(j * M + i) * 3 + c]`` is texel (i, j) = column i,
  row j of the octahedral map), and ``"textured": {"kd": [r, g, b]}`` (version 3: the
  diffuse colour the texture multiplies, the fit's doubles);
- the scene's ``extras``: ``{"format": "vlights.fit.gltf", "version": 2 to 5, "source",
  "model", "objects": [names], "emitters": [P parts, as fit.npz's meta],
  "emitter_nodes": N, "emitter_table": P x [TABLE_WIDTH * 4 numbers], "camera": {"eye",
  "look_at", "up", "fov_y_deg"}}`` (``camera`` only when the fit has one, the files'
  record as fit.npz has it: with ``fov_deg``, ``fov_axis`` and ``film`` when its field
  of view is along another axis than y, which the page keeps at any window size);
  ``emitter_table`` is ``display.glsl.emitter_table(parts)`` row by row, the float32
  texels the shaders read (written so that a viewer need not repeat its arithmetic);
- a fit with an environment (version 4: the light from outside the scene,
  ``radiosity.physics.environment``, drawn where no object is) has, besides, the scene
  extras' ``"environment": {"width": W, "height": H, "scale", "rotation": 3 x [3
  numbers] (rows; world from environment), "constant": bool, "source", "bufferView":
  i}``, and bufferView i of the GLB's buffer holds its image before ``scale``: H * W * 3
  little-endian float32, row 0 first (the zenith), each row's pixels left to right, RGB
  (the fit's ``environment_image`` as it is; a constant environment is 1 x 1). No
  accessor refers to the view (a viewer reads it as raw bytes).

Every number in the JSON is a float32 of the fit written exactly (every float32 is a
double), except the emitters, ``ks``, ``exponent``, the probe's ``centre``, ``box``
and ``albedo``, a textured object's ``kd`` (also its ``baseColorFactor``) and the
environment's ``scale`` and ``rotation``, which the fit holds as doubles and which are
written as such.

The shading formula is fit.npz's (``fitting.model.FittedObject.shade``), with these
arrays. Written through trimesh's glTF exporter (``process=False``: vertices are not
merged, so no attribute value is lost) and moved into place only when complete.
``display.export_reader.load_export`` reads the file (version 5, 4: no delta parts, 3: no environment either,
2: no textures either, or 1: no emitters and no probes either) back into a ``FittedModel``.
"""

from __future__ import annotations

import base64
import json
from pathlib import Path

import numpy as np

__all__ = ["FILE", "FORMAT", "PAGE", "READS", "SHADERS", "SHADING", "VERSION", "export_glb",
           "file_version", "page_files", "page_source", "write_export", "write_files"]

FORMAT = "vlights.fit.gltf"
VERSION = 8
READS = (1, 2, 3, 4, 5, 6, 7, 8)
LTC_VERSION = 7  # the version of a file where a highlight has a microfacet lobe and no object a mask
OWN_PARTS_VERSION = 6  # the version of a file where an object names its own emitter parts and no lobe
DELTA_VERSION = 5  # the version of a file with a delta emitter part and no object's own parts
ENVIRONMENT_VERSION = 4  # the version of a file with an environment and no delta part
TEXTURED_VERSION = 3  # the version of a file with a textured object and no environment
UNTEXTURED_VERSION = 2  # the version of a file with neither
ENVIRONMENT_BUFFER = "vlights/environment"  # the environment image's key among trimesh's buffers (no hash clashes)
IMAGE_BUFFER = "vlights/image"  # IMAGE_BUFFER/i: textured objects' image i among trimesh's buffers
FILE = "scene.glb"
PAGE = "index.html"
WEB = Path(__file__).with_name("web")  # the page, its script and the vendored three.js (r187, MIT)
SHADERS = "shaders"  # the renderer's shader files (display/shaders), which the page fetches
PARTS_PER_ATTRIBUTE = 3  # emitter parts' visibility per VEC3 attribute
# glTF's sampler enums: a textured object's image repeats, mipmapped as the renderer's
SAMPLER = {"magFilter": 9729, "minFilter": 9987, "wrapS": 10497, "wrapT": 10497}  # LINEAR, LINEAR_MIPMAP_LINEAR, REPEAT


def page_files():
    """The walkthrough page's files as paths relative to the exported directory (sorted):
    those of ``display/web``, and ``shaders/NAME.glsl`` for each of the renderer's shader
    files. ``shading.js``, written for each fit, is not among them."""
    from display.glsl import shader_files

    web = [p.relative_to(WEB) for p in WEB.rglob("*") if p.is_file() and "__pycache__" not in p.parts]
    return sorted(web + [Path(SHADERS) / name for name in shader_files()])


def page_source(name):
    """Where the page's file ``name`` (one of ``page_files``) comes from in the package."""
    from display.glsl import SHADERS as SHADER_DIR

    name = Path(name)
    return SHADER_DIR / name.name if name.parts[0] == SHADERS else WEB / name


def visibility_attributes(visibility):
    """``_VISIBILITY_j``: (V, P) visibility as ceil(P / 3) (V, 3) float32 arrays, part
    3 j + c in channel c of the j-th, the last one padded with 0."""
    vis = np.asarray(visibility, np.float32)
    v, p = vis.shape
    count = -(-p // PARTS_PER_ATTRIBUTE)
    padded = np.zeros((v, count * PARTS_PER_ATTRIBUTE), np.float32)
    padded[:, :p] = vis
    return {f"_VISIBILITY_{j}": np.ascontiguousarray(padded[:, PARTS_PER_ATTRIBUTE * j:PARTS_PER_ATTRIBUTE * (j + 1)])
            for j in range(count)}


def vertex_attributes(obj):
    """The custom glTF attributes of one ``FittedObject``: name -> (V, 3) float32."""
    attributes = {"_EMITTED": np.asarray(obj.emitted, np.float32)}
    if obj.n_lights:
        specular = np.asarray(obj.specular, np.float32)
        if obj.per_light:
            attributes.update({f"_SPECULAR_{k}": np.ascontiguousarray(specular[:, k]) for k in range(obj.n_lights)})
        else:
            attributes["_SPECULAR"] = specular
    if obj.probe is not None:
        attributes["_PROBE"] = np.asarray(obj.probe_weight, np.float32)
    if obj.highlight is not None:
        attributes.update(visibility_attributes(obj.highlight.visibility))
    if obj.textured is not None:
        attributes["_IRRADIANCE"] = obj.textured.irradiance
    return attributes


def _rows(a, width):
    """A float32 array as JSON lists of Python floats (exact: every float32 is a double)."""
    return np.asarray(a, np.float32).reshape(-1, width).astype(np.float64).tolist()


def _doubles(a):
    """A float64 array as a flat JSON list (exact: Python's float repr round-trips)."""
    return np.asarray(a, np.float64).reshape(-1).tolist()


def mesh_extras(obj):
    """The mesh's ``extras``: the object's lights, highlight and probe (JSON-ready)."""
    from radiosity.physics.ltc import highlight_lobe

    extras = {
        "name": obj.name,
        "lights": obj.n_lights,
        "per_light": bool(obj.per_light and obj.n_lights > 0),
        "light_pos": _rows(obj.light_pos, 4),
        "light_rgb": _rows(obj.light_rgb, 3),
        "shininess": np.asarray(obj.shininess, np.float32).reshape(-1).astype(np.float64).tolist(),
    }
    if obj.highlight is not None:
        extras["highlight"] = {"ks": _doubles(obj.highlight.ks), "exponent": float(obj.highlight.exponent)}
        if obj.highlight.fresnel is not None:
            extras["highlight"]["fresnel"] = _doubles(obj.highlight.fresnel)
        if obj.highlight.indices is not None:
            extras["highlight"]["parts"] = [int(i) for i in obj.highlight.indices]
        if obj.highlight.microfacet is not None:
            lobe = highlight_lobe(obj.highlight.microfacet)
            extras["highlight"]["microfacet"] = obj.highlight.microfacet.to_dict()
            extras["highlight"]["lobe"] = {"code": int(lobe.code), "alpha": float(lobe.alpha), "ks": _doubles(lobe.ks),
                                           "f0": _doubles(lobe.f0)}
    if obj.probe is not None:
        p = obj.probe
        extras["probe"] = {
            "size": int(p.size),
            "centre": _doubles(p.centre),
            "box": np.asarray(p.box, np.float64).reshape(2, 3).tolist(),
            "albedo": _doubles(p.albedo),
            "texels": np.asarray(p.texels, np.float32).reshape(-1).astype(np.float64).tolist(),
        }
    if obj.textured is not None:
        extras["textured"] = {"kd": list(obj.textured.kd)}
    return extras


def _check_highlights(model):
    """Every highlight reflects the model's emitter parts (all, or those its ``indices``
    name) with its nodes (the file holds one list of parts); ValueError otherwise."""
    parts = [p.to_dict() for p in model.emitters]
    for obj in model.objects:
        h = obj.highlight
        if h is None:
            continue
        wanted = parts if h.indices is None else [parts[i] for i in h.indices if 0 <= i < len(parts)]
        if [p.to_dict() for p in h.parts] != wanted or h.nodes != model.emitter_nodes:
            raise ValueError(f"object {obj.name!r}: its highlight's emitter parts or nodes are not the model's")


def file_version(model):
    """The lowest version of the schema that holds ``model``: 8 where an object's mask is
    exported, 7 where a highlight has a
    microfacet lobe, 6 where an object names its own emitter parts, 5 with a delta
    emitter part, 4 with an environment, 3 with a textured object, else 2."""
    if any(exported_mask(o) is not None for o in model.objects):
        return VERSION
    if any(o.highlight is not None and o.highlight.microfacet is not None for o in model.objects):
        return LTC_VERSION
    if any(o.highlight is not None and o.highlight.indices is not None for o in model.objects):
        return OWN_PARTS_VERSION
    if any(p.is_delta for p in model.emitters):
        return DELTA_VERSION
    if model.environment is not None:
        return ENVIRONMENT_VERSION
    return TEXTURED_VERSION if any(o.textured is not None for o in model.objects) else UNTEXTURED_VERSION


def environment_extras(env, view):
    """The scene extras' ``"environment"`` of an ``EnvironmentLight`` whose image is
    bufferView ``view`` (JSON-ready; scale and rotation the fit's doubles)."""
    height, width = env.image.shape[:2]
    return {"width": int(width), "height": int(height), "scale": float(env.scale),
            "rotation": np.asarray(env.rotation, np.float64).tolist(), "constant": bool(env.constant),
            "source": env.source, "bufferView": int(view)}


def environment_bytes(env):
    """The environment's image as the file holds it: H * W * 3 little-endian float32, row 0 first."""
    return np.ascontiguousarray(env.image, "<f4").tobytes()


def scene_extras(model):
    """The scene's ``extras``: format marker, provenance, object order, emitters, camera
    (the environment is added with its image: ``export_glb``)."""
    from display.glsl import TABLE_WIDTH, emitter_table

    extras = {"format": FORMAT, "version": file_version(model), "source": model.source, "model": model.model,
              "objects": list(model.names), "emitters": [p.to_dict() for p in model.emitters],
              "emitter_nodes": int(model.emitter_nodes)}
    table = emitter_table(model.emitters)[:len(model.emitters)]
    extras["emitter_table"] = table.reshape(len(table), TABLE_WIDTH * 4).astype(np.float64).tolist()
    if model.camera is not None:
        extras["camera"] = model.camera.to_dict()  # fit.npz's record: JSON-ready, its fov along its axis
    return extras


def srgb8(texture):
    """The 8-bit sRGB codes (H, W, 3) uint8 of a linear texture in [0, 1]: exact (they
    decode to the same float32 values) for a texture decoded from 8-bit sRGB
    (``radiosity.physics.textures.linear_to_srgb8``), else each value's encoding
    (IEC 61966-2-1) rounded to the nearest code."""
    from radiosity.physics.textures import linear_to_srgb8

    codes = linear_to_srgb8(texture)
    if codes is not None:
        return codes
    c = np.clip(np.asarray(texture, np.float64), 0.0, 1.0)
    encoded = np.where(c <= 0.0031308, 12.92 * c, 1.055 * c ** (1 / 2.4) - 0.055)
    return np.round(encoded * 255).astype(np.uint8)


def _visual(obj):
    """A textured object's trimesh ``TextureVisuals``: its uvs (trimesh writes glTF's
    1 - v) and a material of its own, named as it; its image is added after
    (``_Images``), once for all the objects that share it."""
    from trimesh.visual.material import PBRMaterial
    from trimesh.visual.texture import TextureVisuals

    t = obj.textured
    material = PBRMaterial(name=obj.name, baseColorFactor=[*t.kd, 1.0], metallicFactor=0.0, roughnessFactor=1.0,
                           doubleSided=True)
    return TextureVisuals(uv=t.uvs, material=material)


def exported_mask(obj):
    """A textured object's mask as its image's alpha: (H, W) uint8 codes round(255
    opacity) at its texture's size (a 1 x 1 texture, an untextured object's white,
    is spread to the mask's), or None where it has no mask or the mask's size is not
    its texture's (glTF's one image holds both; the mask is then left out)."""
    t = obj.textured
    if t is None or t.opacity is None:
        return None
    if t.texture.shape[:2] != t.opacity.shape and t.texture.shape[:2] != (1, 1):
        return None
    return np.round(np.asarray(t.opacity, np.float64) * 255.0).astype(np.uint8)


class _Images:
    """The textured objects' images as the GLB holds them: one PNG, image and texture for
    each distinct image, however many materials use it (600 of staircase's 655 textured
    objects share one image; trimesh would encode it and list it once for each). Objects
    that share an image share its array, as the fit's reader gives it
    (``radiosity.files.npz.Archive.shared``); arrays that are not the same object but
    hold the same codes are found by their codes' digest."""

    def __init__(self, model):
        import hashlib

        self.objects = {}  # object name -> index of its image
        self.codes = []    # each image's 8-bit sRGB codes (H, W, 3) uint8, and a masked object's alpha (H, W, 4)
        by_array, by_digest = {}, {}
        for obj in model.objects:
            if obj.textured is None:
                continue
            alpha = exported_mask(obj)
            key = (id(obj.textured.texture), None if alpha is None else id(obj.textured.opacity))
            if key not in by_array:
                codes = srgb8(obj.textured.texture)
                if alpha is not None:
                    codes = np.dstack([np.broadcast_to(codes, (*alpha.shape, 3)), alpha])
                digest = hashlib.blake2b(codes.tobytes(), digest_size=16).digest() + repr(codes.shape).encode()
                if digest not in by_digest:
                    by_digest[digest] = len(self.codes)
                    self.codes.append(codes)
                by_array[key] = by_digest[digest]
            self.objects[obj.name] = by_array[key]

    def add(self, buffers, tree):
        """Each image as a PNG in a buffer of its own (a bufferView each: views are made one
        per buffer, in order), its image and texture (``SAMPLER``), and each
        textured mesh's material pointed at its texture, with the exact base colour
        (trimesh keeps colours as 8-bit) from the mesh's extras."""
        import io

        from PIL import Image

        from radiosity.physics.textures import OPACITY_CUTOFF

        if not self.codes:
            return
        samplers = tree.setdefault("samplers", [])
        samplers.append(dict(SAMPLER))
        first = len(tree["textures"])
        for i, codes in enumerate(self.codes):
            with io.BytesIO() as f:
                Image.fromarray(np.ascontiguousarray(codes), "RGBA" if codes.shape[2] == 4 else "RGB").save(f, format="png")
                data = f.getvalue()
            key = f"{IMAGE_BUFFER}/{i}"
            buffers[key] = data + b"\0" * (-len(data) % 4)  # glTF aligns views to 4 bytes
            tree["images"].append({"bufferView": buffers.index(key), "mimeType": "image/png"})
            tree["textures"].append({"source": len(tree["images"]) - 1, "sampler": len(samplers) - 1})
        for mesh in tree["meshes"]:
            extras = mesh.get("extras") or {}
            if "textured" not in extras:
                continue
            material = tree["materials"][mesh["primitives"][0]["material"]]
            pbr = material.setdefault("pbrMetallicRoughness", {})
            pbr["baseColorFactor"] = [*extras["textured"]["kd"], 1.0]
            index = self.objects[extras["name"]]
            pbr["baseColorTexture"] = {"index": first + index}
            if self.codes[index].shape[2] == 4:  # a mask: glTF's alpha test, at the files' cut-off
                material["alphaMode"] = "MASK"
                material["alphaCutoff"] = OPACITY_CUTOFF


def export_glb(model):
    """The binary glTF (bytes) of a ``FittedModel``; schema in the module docstring."""
    import trimesh

    _check_highlights(model)
    scene = trimesh.Scene(base_frame="vlights/root")  # an object name never holds a "/": no node clashes with it
    for obj in model.objects:
        mesh = trimesh.Trimesh(
            vertices=np.asarray(obj.positions, np.float32),
            faces=np.asarray(obj.faces, np.int64),
            vertex_normals=np.asarray(obj.normals, np.float32),
            vertex_attributes=vertex_attributes(obj),
            metadata=mesh_extras(obj),
            visual=_visual(obj) if obj.textured is not None else None,
            process=False,
            validate=False,
        )
        scene.add_geometry(mesh, geom_name=obj.name, node_name=obj.name)
    scene.metadata.update(scene_extras(model))
    env = model.environment

    images = _Images(model)

    def add_buffers(buffers, tree):
        """The images (``_Images``), then the environment's image as one more buffer (a
        bufferView of its own) and its entry in the scene's extras."""
        images.add(buffers, tree)
        if env is not None:
            buffers[ENVIRONMENT_BUFFER] = environment_bytes(env)  # float32: a multiple of 4 bytes, as glTF wants
            tree["scenes"][0]["extras"]["environment"] = environment_extras(env, buffers.index(ENVIRONMENT_BUFFER))

    return trimesh.exchange.gltf.export_glb(scene, include_normals=True, unitize_normals=False,
                                            buffer_postprocessor=add_buffers)


SHADING = "shading.js"  # written with the page: the shaders' #define lines and constants, an ES module


def shading_module(nodes=None):
    """``shading.js``: the ``#define`` lines the renderer prepends to its shaders
    (``display.glsl.defines(nodes)``, every part of the model compiled in; ``nodes``: the
    emitter quadrature's, None the default) and the constants the page lays its textures
    out with, as JavaScript. The page puts DEFINES after its header, before each shader file."""
    from display.glsl import FLOAT_TEXTURE_WIDTH, TABLE_WIDTH, defines
    from fitting.probe import ALBEDO_POINTS
    from radiosity.physics.emitters import DEFAULT_NODES, MAX_FILE_PARTS
    from radiosity.physics.ltc import table_texture

    nodes = DEFAULT_NODES if nodes is None else int(nodes)
    ltc = table_texture()  # (2 S, 2 S, 4): the microfacet lobes' table (ltc.glsl), little-endian float32 in base64
    return ("// Written by `vlights export` (display/export.py): the #define lines of display/glsl.py.\n"
            f"export const DEFINES = {json.dumps(defines(nodes))};\n"
            f"export const TEXTURE_WIDTH = {FLOAT_TEXTURE_WIDTH};\n"
            f"export const EMITTER_NODES = {nodes};\n"
            f"export const TABLE_WIDTH = {TABLE_WIDTH};\n"
            f"export const ALBEDO_POINTS = {ALBEDO_POINTS};\n"
            f"export const MAX_OBJECT_PARTS = {MAX_FILE_PARTS};\n"
            f"export const LTC_SIZE = {ltc.shape[0] // 2};\n"
            f"export const LTC_TABLE = '{base64.b64encode(ltc.astype('<f4').tobytes()).decode()}';\n")


def write_files(model, directory, page=True):
    """Write scene.glb and, with ``page``, the walkthrough page into ``directory`` (which
    exists); no staging: for callers that stage a whole run (``write_export``, the demo).
    Returns the path of scene.glb."""
    import shutil

    directory = Path(directory)
    (directory / FILE).write_bytes(export_glb(model))
    for name in page_files() if page else ():
        (directory / name).parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(page_source(name), directory / name)
    if page:
        (directory / SHADING).write_text(shading_module(model.emitter_nodes))
    return directory / FILE


def write_export(model, out, page=True):
    """Write ``out/scene.glb`` and, with ``page``, the walkthrough page beside it
    (``out`` is created if missing, not its parents); the files appear complete or not
    at all. Returns the path of scene.glb."""
    from display.outputs import staged_directory

    out = Path(out)
    with staged_directory(out) as stage:
        write_files(model, stage, page)
    return out / FILE
