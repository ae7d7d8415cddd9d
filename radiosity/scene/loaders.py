"""Reading scenes: TOML scene files, Mitsuba XML (``mitsuba``), OBJ (with MTL), glTF /
GLB, and the built-ins.

``load_scene(source)`` takes a path or a built-in scene's name and returns a Scene.
Every problem with the input raises InputError with one line naming it.

Material mapping for mesh files given directly (a TOML scene names its materials
itself and ignores the file's):

OBJ / MTL
    Kd -> diffuse, Ks -> specular, Ns -> exponent (Ks absent or zero: diffuse),
    Ke -> emission. A map_Kd image (sRGB-decoded) becomes the object's diffuse
    texture, multiplying Kd (1 where Kd is absent) at each point through the mesh's
    texture coordinates (``vt``, v up). kd + ks > 1 is refused, as in a scene file.
glTF 2.0 (metallic-roughness)
    base = baseColorFactor; a baseColorTexture becomes the object's diffuse texture
    (TEXCOORD_0; glTF's v runs down and trimesh flips it), multiplying the kd below
    at each point (a metal's ks takes the image's mean, with a warning);
    specular ks = base * metallic + 0.04 * (1 - metallic) (the usual F0);
    diffuse kd = base * (1 - metallic) * (1 - ks);
    exponent n = ``microfacet.phong_exponent("ggx", alpha)`` with alpha = roughness^2
    (the measured rule: the Phong lobe of the same half-maximum solid angle as GGX's;
    the old (2 / alpha^2 - 2) / 4 was 2.7 times too broad), at most 10000; a dielectric (metallic = 0) with roughness >= 0.9
    is taken as diffuse (ks = 0), a lobe that broad being indistinguishable from one;
    emission = emissiveFactor (times KHR_materials_emissive_strength, if any: folded
    into the factor before trimesh reads the file, since trimesh drops extensions).
    Base colours pass through trimesh, which keeps them to 8 bits per channel.
A mesh whose material has an image but which has no texture coordinates gets the
image's mean colour instead, with one warning per material.

Text mesh files (OBJ, MTL, ASCII STL, OFF) are read as UTF-8, a byte-order mark
dropped, or as Latin-1 where they are not UTF-8. An OBJ whose material library is
missing loads with the default material (diffuse 0.8) and a SceneWarning.
"""

from __future__ import annotations

import os
import tomllib
import unicodedata
import warnings
from pathlib import Path

import numpy as np
import trimesh
from PIL import Image

from radiosity.files.camera import DEFAULT_FOV_Y_DEG, MAX_IMAGE_SIDE, camera_from_dict, pose_from_matrix
from radiosity.files.errors import InputError, SceneWarning
from radiosity.files.inputs import TEXT_BYTES, loads_toml, read_input_bytes
from radiosity.files.sniff import FILE_NAMES, SCENE_SUFFIXES, input_kind, scene_words  # noqa: F401 (the loaders' words)
from radiosity.physics.environment import Environment, read_environment_image
from radiosity.physics.materials import FLOAT32_MAX, fresnel_kd_limit
from radiosity.physics.textures import read_texture, texture_from_image
from radiosity.scene import builtins, geometry
from radiosity.scene.lights import lights_from_toml
from radiosity.scene.material_kernels import Material
from radiosity.scene.meshfiles import (
    MESH_SUFFIXES,
    mesh_uvs,
    missing_material_libraries,
    read_mesh_with_uvs,
    read_single_mesh,
    trimesh_load,
)
from radiosity.scene.microfacet import phong_exponent
from radiosity.scene.mitsuba import load_mitsuba
from radiosity.scene.model import DEFAULT_CREASE_ANGLE_DEG, MAX_COORDINATE, Scene, build_object, with_backs

_MATERIAL_KEYS = {"diffuse", "specular", "exponent", "emission", "diffuse_texture"}
_OBJECT_KEYS = {
    "name", "mesh", "builtin", "material", "scale", "rotate_deg", "translate",
    "resolution", "subdivisions", "segments", "crease_angle_deg", "flip", "transform", "twosided",
}
_CAMERA_KEYS = {"position", "eye", "look_at", "up", "fov_y_deg", "matrix", "fov_deg", "fov_axis", "width", "height"}
_TOP_KEYS = {"camera", "materials", "objects", "name", "description", "units", "environment", "lights"}
_ENVIRONMENT_KEYS = {"radiance", "image", "scale", "rotation", "rotate_deg", "transform"}


def load_scene(source):
    """A Scene from a scene file (.toml), a mesh file, or a built-in scene's name."""
    source = str(source)
    if source in builtins.SCENES:
        path = builtins.scene_path(source)
        return _load_toml(path.read_text(), Path(str(path)).parent, name=source, where=source)
    path = Path(source)
    if not os.path.lexists(source):
        hint = f"; built-in scenes: {', '.join(builtins.SCENES)}" if not path.suffix else ""
        raise InputError(f"scene {source!r} not found{hint}")
    kind = input_kind(source, "scene")  # a regular file of a sane size, or one line saying what it is
    if kind == "scene" and path.suffix.lower() == ".xml":
        return load_mitsuba(path)
    if kind == "scene":
        try:
            text = read_input_bytes(path, "scene", TEXT_BYTES).decode("utf-8")
        except UnicodeDecodeError as exc:
            raise InputError(f"cannot read {source}: {exc}") from None
        return _load_toml(text, path.parent, name=path.stem, where=str(path))
    if kind == "mesh":
        return _load_mesh_scene(path)
    if kind in FILE_NAMES:
        raise InputError(f"scene {source!r} is a {FILE_NAMES[kind]}, not a scene")
    suffix = path.suffix.lower()
    raise InputError(
        f"{source}: unknown scene format {suffix or '(no extension)'!r}; "
        f"give a .toml or Mitsuba .xml scene, a mesh file ({', '.join(sorted(MESH_SUFFIXES))}) "
        f"or a built-in scene ({', '.join(builtins.SCENES)})"
    )


# Each suffix ``load_scene`` reads (``radiosity.files.sniff``'s SCENE_SUFFIXES and
# MESH_SUFFIXES) as help texts name it
# -- TOML ---------------------------------------------------------------------------


def _load_toml(text, base_dir, *, name, where):
    try:
        data = loads_toml(text, where)
    except tomllib.TOMLDecodeError as exc:
        raise InputError(f"{where}: malformed TOML: {exc}") from None
    _check_keys(data, _TOP_KEYS, where)
    materials = _parse_materials(data.get("materials", {}), where)
    textures = _parse_textures(data.get("materials", {}), base_dir, where)
    objects_data = data.get("objects")
    if not isinstance(objects_data, list) or not objects_data:
        raise InputError(f"{where}: no [[objects]]: a scene needs at least one object")
    parsed = [(_parse_object(entry, i, (materials, textures), base_dir, where), entry)
              for i, entry in enumerate(objects_data)]
    parsed = [(o, entry) for o, entry in parsed if o is not None]  # None: every triangle degenerate (warned)
    if not parsed:
        raise InputError(f"{where}: every object's triangles are degenerate: nothing is left to draw")
    objects = [o for o, _ in parsed]
    two_sided = {o.name for o, entry in parsed if _two_sided(entry, o.name, where)}
    camera, film = _parse_camera(data["camera"], where) if "camera" in data else (None, None)
    environment = _parse_environment(data["environment"], base_dir, where) if "environment" in data else None
    objects = with_backs(objects, two_sided)
    lights = lights_from_toml(data["lights"], where, {o.name for o in objects}) if "lights" in data else ()
    return Scene(name=str(data.get("name", name)), objects=objects, camera=camera,
                 source=where, film=film, environment=environment, lights=lights)


def _parse_environment(table, base_dir, where):
    """The ``Environment`` of a scene's [environment]: ``radiance`` (a number or RGB)
    or ``image`` (a latitude-longitude map beside the scene: .exr, .hdr, .pfm, .npy as
    linear radiance, 8-bit images sRGB-decoded), ``scale`` (default 1), and its
    orientation: ``rotation`` (3 x 3, world from environment), ``rotate_deg`` ([x, y,
    z], as an object's) or ``transform`` (4 x 4, its translation ignored)."""
    here = f"{where}: [environment]"
    _check_keys(table, _ENVIRONMENT_KEYS, here)
    if ("radiance" in table) == ("image" in table):
        raise InputError(f"{here}: give 'radiance' (a constant environment) or 'image' (an environment map)")
    if sum(k in table for k in ("rotation", "rotate_deg", "transform")) > 1:
        raise InputError(f"{here}: give one of 'rotation', 'rotate_deg' and 'transform'")
    scale = _number(table.get("scale", 1.0), here, "scale")
    rotation = None
    if "rotation" in table:
        value = table["rotation"]
        if not (isinstance(value, list) and len(value) == 3 and all(isinstance(r, list) and len(r) == 3 for r in value)):
            raise InputError(f"{here}: 'rotation' must be 3 rows of 3 numbers")
        rotation = np.array([[_number(v, here, "rotation") for v in row] for row in value])
    elif "rotate_deg" in table:
        rotation = geometry.transform_matrix(rotate_deg=_vec3(table["rotate_deg"], here, "rotate_deg"))[:3, :3]
    elif "transform" in table:
        rotation = _matrix(table["transform"], here, "transform")[:3, :3]
    if "radiance" in table:
        return Environment.uniform(_vec3(table["radiance"], here, "radiance", allow_scalar=True), scale, rotation, here)
    name = table["image"]
    if not isinstance(name, str) or not name:
        raise InputError(f"{here}: 'image' must be an image file name, got {name!r}")
    path = Path(base_dir) / name
    if not (path.exists() or path.is_symlink()):  # there but not a regular file: the reader's input check says
        raise InputError(f"{here}: the environment map {str(path)!r} is not found")
    return Environment.from_image(read_environment_image(path, here), scale, rotation, here)


def _two_sided(entry, name, where):
    value = entry.get("twosided", False)
    if not isinstance(value, bool):
        raise InputError(f"{where}: object {name!r}: 'twosided' must be true or false, got {value!r}")
    return value


def _check_keys(table, allowed, where):
    if not isinstance(table, dict):
        raise InputError(f"{where}: expected a table, got {type(table).__name__}")
    unknown = sorted(set(table) - allowed)
    if unknown:
        raise InputError(f"{where}: unknown key {unknown[0]!r} (known: {', '.join(sorted(allowed))})")


def _number(value, where, key):
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise InputError(f"{where}: '{key}' must be a number, got {value!r}")
    if not np.isfinite(value):
        raise InputError(f"{where}: '{key}' must be finite, got {value!r}")
    if abs(value) > FLOAT32_MAX:  # the solver and the files work in single precision
        raise InputError(f"{where}: '{key}' = {value:g} is beyond the single-precision range (+-{FLOAT32_MAX:.4g})")
    return float(value)


def _vec3(value, where, key, *, allow_scalar=False):
    if allow_scalar and isinstance(value, (int, float)) and not isinstance(value, bool):
        return (_number(value, where, key),) * 3
    if not isinstance(value, list) or len(value) != 3:
        shape = "a number or 3 numbers" if allow_scalar else "3 numbers"
        raise InputError(f"{where}: '{key}' must be {shape}, got {value!r}")
    return tuple(_number(v, where, key) for v in value)


def _parse_materials(table, where):
    if not isinstance(table, dict):
        raise InputError(f"{where}: [materials] must be a table of named materials")
    out = {}
    for mname, spec in table.items():
        here = f"{where}: [materials.{mname}]"
        if not isinstance(spec, dict):
            raise InputError(f"{here}: must be a table")
        _check_keys(spec, _MATERIAL_KEYS, here)
        out[mname] = _material(
            mname,
            diffuse=_vec3(spec.get("diffuse", 0.0), here, "diffuse", allow_scalar=True),
            specular=_vec3(spec.get("specular", 0.0), here, "specular", allow_scalar=True),
            exponent=_number(spec.get("exponent", 0.0), here, "exponent"),
            emission=_vec3(spec.get("emission", 0.0), here, "emission", allow_scalar=True),
            where=f"{where}: ",
        )
    return out


def _parse_textures(table, base_dir, where):
    """{material name: (H, W, 3) float32 texture} of the materials with a
    ``diffuse_texture`` (an image file beside the scene), each read once: its objects
    share the array."""
    out = {}
    for mname, spec in table.items():
        if "diffuse_texture" not in spec:
            continue
        here = f"{where}: [materials.{mname}]"
        name = spec["diffuse_texture"]
        if not isinstance(name, str) or not name:
            raise InputError(f"{here}: 'diffuse_texture' must be an image file name, got {name!r}")
        path = Path(base_dir) / name
        if not (path.exists() or path.is_symlink()):  # there but not a regular file: the reader's input check says
            raise InputError(f"{here}: the texture {str(path)!r} is not found")
        out[mname] = read_texture(path, here)
    return out


def _material(name, *, diffuse, specular, exponent, emission, where="", fresnel=None):
    try:
        return Material(name=name, diffuse=diffuse, specular=specular, exponent=exponent, emission=emission,
                        fresnel=fresnel)
    except InputError as exc:
        raise InputError(f"{where}{exc}") from None


def _parse_camera(table, where):
    """(Camera, film (width, height) or None) of a scene's [camera]: a pose (eye or
    position, look_at, up) or a camera-to-world ``matrix`` (Mitsuba's convention:
    looking along +z, +y up); ``fov_y_deg``, or ``fov_deg`` along ``fov_axis`` (x, y,
    diagonal, smaller, larger; kept along that axis at any image size); optionally the
    film's ``width`` and ``height``."""
    here = f"{where}: [camera]"
    _check_keys(table, _CAMERA_KEYS, here)
    film = None
    if "width" in table or "height" in table:
        w, h = table.get("width"), table.get("height")
        if not all(isinstance(v, int) and not isinstance(v, bool) and 1 <= v <= MAX_IMAGE_SIDE for v in (w, h)):
            raise InputError(f"{here}: 'width' and 'height' must both be whole numbers from 1 to {MAX_IMAGE_SIDE}")
        film = (w, h)
    width, height = film or (512, 512)
    pose = {k: table[k] for k in ("position", "eye", "look_at", "up") if k in table}
    if "fov_deg" in table or "fov_axis" in table:  # kept along its axis at any size (Camera)
        if "fov_y_deg" in table:
            raise InputError(f"{here}: give 'fov_y_deg' or 'fov_deg' (with 'fov_axis'), not both")
        pose["fov_deg"] = _number(table.get("fov_deg", DEFAULT_FOV_Y_DEG), here, "fov_deg")
        pose["fov_axis"] = table.get("fov_axis", "y")
    elif "fov_y_deg" in table:
        pose["fov_y_deg"] = table["fov_y_deg"]
    if "matrix" in table:
        if {"position", "eye", "look_at", "up"} & set(table):
            raise InputError(f"{here}: give a 'matrix' or eye, look_at and up, not both")
        matrix = _matrix(table["matrix"], here, "matrix")
        try:
            eye, look_at, up, mirrored = pose_from_matrix(matrix)
        except InputError as exc:
            raise InputError(f"{here}: {str(exc).removeprefix('camera: ')}") from None
        if mirrored:
            warnings.warn(f"{here}: the matrix mirrors the image: drawn unmirrored", SceneWarning, stacklevel=3)
        pose |= {"eye": eye, "look_at": look_at, "up": up}
    return camera_from_dict(pose, width, height, where=here), film


def _matrix(value, where, key):
    """A 4x4 matrix from 4 rows of 4 numbers or 16 numbers, row-major."""
    rows = value
    if isinstance(value, list) and len(value) == 16 and all(not isinstance(v, list) for v in value):
        rows = [value[i:i + 4] for i in range(0, 16, 4)]
    if not (isinstance(rows, list) and len(rows) == 4 and all(isinstance(r, list) and len(r) == 4 for r in rows)):
        raise InputError(f"{where}: '{key}' must be 4 rows of 4 numbers (or 16 numbers, row by row)")
    return np.array([[_number(v, where, key) for v in row] for row in rows])


def _parse_object(entry, index, materials_textures, base_dir, where):
    materials, textures = materials_textures
    if not isinstance(entry, dict):
        raise InputError(f"{where}: [[objects]] entry {index + 1} must be a table")
    name = entry.get("name")
    if not isinstance(name, str) or not name:
        raise InputError(f"{where}: [[objects]] entry {index + 1} needs a 'name'")
    here = f"{where}: object {name!r}"
    if "/" in name:
        raise InputError(f"{here}: names may not contain '/' (the solution file uses it as a separator)")
    control = _control_character(name)
    if control is not None:
        raise InputError(
            f"{here}: names may not contain control characters (U+{ord(control):04X}): the solution file "
            "could not keep them"
        )
    _check_keys(entry, _OBJECT_KEYS, here)
    mname = entry.get("material")
    if mname is None:
        raise InputError(f"{here}: needs a 'material'")
    if mname not in materials:
        known = ", ".join(materials) or "none defined"
        raise InputError(f"{here}: unknown material {mname!r} (materials: {known})")
    if ("mesh" in entry) == ("builtin" in entry):
        raise InputError(f"{here}: give exactly one of 'mesh' (a file) or 'builtin'")
    texture = textures.get(mname)
    uvs = None

    if "builtin" in entry:
        spec = entry["builtin"]
        if not isinstance(spec, str):
            raise InputError(f"{here}: 'builtin' must be a string, got {spec!r}")
        try:
            positions, faces = builtins.mesh(
                spec, resolution=entry.get("resolution"), subdivisions=entry.get("subdivisions"),
                segments=entry.get("segments"),
            )
            if texture is not None:
                positions, faces, uvs = builtins.textured_mesh(spec, positions, faces, resolution=entry.get("resolution"))
        except InputError as exc:
            raise InputError(f"{here}: {exc}") from None
        source = f"builtin {spec}"
    else:
        for key in ("resolution", "subdivisions", "segments"):
            if key in entry:
                raise InputError(f"{here}: '{key}' applies to built-in meshes only")
        mesh_file = entry["mesh"]
        if not isinstance(mesh_file, str):
            raise InputError(f"{here}: 'mesh' must be a file name, got {mesh_file!r}")
        path = base_dir / mesh_file
        if texture is None:
            positions, faces = read_single_mesh(path, here)
        else:
            positions, faces, uvs = read_mesh_with_uvs(path, here)
            if uvs is None:
                raise InputError(
                    f"{here}: material {mname!r} has a diffuse_texture but the mesh {str(path)!r} has no "
                    "texture coordinates"
                )
        source = str(path)

    scale = entry.get("scale", 1.0)
    scale = _vec3(scale, here, "scale", allow_scalar=True)
    if any(s == 0 for s in scale):
        raise InputError(f"{here}: 'scale' must not be zero")
    matrix = geometry.transform_matrix(
        scale=scale,
        rotate_deg=_vec3(entry.get("rotate_deg", [0, 0, 0]), here, "rotate_deg"),
        translate=_vec3(entry.get("translate", [0, 0, 0]), here, "translate"),
    )
    if "transform" in entry:  # a 4x4 matrix, applied after scale, rotate_deg and translate
        transform = _matrix(entry["transform"], here, "transform")
        if not np.allclose(transform[3], [0, 0, 0, 1]) or geometry.singular(transform[:3, :3]):
            raise InputError(f"{here}: 'transform' must be affine (last row 0 0 0 1) and not singular")
        matrix = transform @ matrix
    within = np.abs(positions).max() <= MAX_COORDINATE  # False for NaN: build_object names that
    positions, faces, _ = geometry.apply_transform(matrix, positions, faces)
    reach = np.abs(positions).max()
    if within and not reach <= MAX_COORDINATE:
        keys = " and ".join(f"'{k}'" for k in ("scale", "rotate_deg", "translate", "transform") if k in entry)
        raise InputError(
            f"{here}: {keys} put its coordinates at {reach:.3g}, beyond the +-{MAX_COORDINATE:g} "
            "the single-precision ray tracer handles"
        )
    flip = entry.get("flip", False)
    if not isinstance(flip, bool):
        raise InputError(f"{here}: 'flip' must be true or false, got {flip!r}")
    if flip:  # turn the surface inside out: a room, an enclosing sphere
        faces = faces[:, ::-1].copy()
    crease = _number(entry.get("crease_angle_deg", DEFAULT_CREASE_ANGLE_DEG), here, "crease_angle_deg")
    if not 0 <= crease <= 180:
        raise InputError(f"{here}: 'crease_angle_deg' must be between 0 and 180, got {crease}")
    return build_object(
        name,
        materials[mname],
        positions,
        faces,
        crease_angle_deg=crease,
        source=source,
        warn_degenerate=not source.startswith("builtin"),
        uvs=uvs,
        texture=texture,
    )


def _control_character(name):
    """The first character of ``name`` that an npz member name cannot keep or a line
    cannot show (a control character: NUL, newline, escape, DEL, ...), or None."""
    return next((c for c in name if unicodedata.category(c) in ("Cc", "Cs")), None)


def safe_object_name(name):
    """A mesh file's node name as an object name: '/' (the solution file's separator)
    and control characters (which no npz member name keeps) become '_'."""
    name = name.replace("/", "_")
    return "".join("_" if _control_character(c) else c for c in name) or "_"


# -- mesh files given directly ------------------------------------------------------


def _load_mesh_scene(path):
    """A scene from one mesh file, one object per (node, material), its materials mapped."""
    where = str(path)
    loaded = trimesh_load(path, where)
    if path.suffix.lower() == ".obj":
        for name in missing_material_libraries(path):
            warnings.warn(
                f"{where}: material library {name!r} not found; its materials get the default "
                "(diffuse 0.8)",
                SceneWarning,
                stacklevel=3,
            )
    if isinstance(loaded, trimesh.Trimesh):
        loaded = trimesh.Scene(loaded)
    if not isinstance(loaded, trimesh.Scene) or not loaded.geometry:
        raise InputError(f"{where}: no triangle meshes in the file")
    objects, materials, images = [], {}, {}
    for node in loaded.graph.nodes_geometry:
        transform, geom_name = loaded.graph[node]
        mesh = loaded.geometry[geom_name]
        if not isinstance(mesh, trimesh.Trimesh) or len(mesh.faces) == 0:
            continue
        positions, faces, _ = geometry.apply_transform(
            np.asarray(transform, dtype=np.float64),
            np.asarray(mesh.vertices, dtype=np.float64),
            np.asarray(mesh.faces, dtype=np.int64),
        )
        material, texture, uvs = _mapped_surface(mesh, where, images)
        material = materials.setdefault(material.name, material)
        name = safe_object_name(str(node))  # '/' separates keys in the solution file; no control characters
        if name in {o.name for o in objects}:
            name = f"{name}#{len(objects)}"
        obj = build_object(name, material, positions, faces, source=where, uvs=uvs, texture=texture)
        if obj is not None:
            objects.append(obj)
    if not objects:
        raise InputError(f"{where}: no triangle meshes in the file")
    return Scene(name=path.stem, objects=tuple(objects), camera=None, source=where)


def _image_texture(image, where):
    """A mesh file's PIL image (trimesh opens it, and decodes it only when asked) as a
    texture (``texture_from_image``: its size checked before it is decoded), or None;
    InputError naming ``where`` for an image that cannot be decoded (a truncated PNG)."""
    if image is None:
        return None
    try:
        return texture_from_image(image, where)
    except InputError:
        raise
    except (OSError, ValueError, SyntaxError, Image.DecompressionBombError) as exc:
        raise InputError(f"{where}: cannot read the image: {' '.join(str(exc).split())}") from None


def _mapped_surface(mesh, where, images):
    """(Material, texture or None, uvs or None) of a mesh from a file given directly.

    A material with an image (MTL map_Kd, glTF baseColorTexture) on a mesh with
    texture coordinates: the image becomes the object's texture (read once per
    material into ``images``, {material name: texture}, so that its objects share
    the array) and kd its factor alone. On a mesh without texture coordinates the
    image counts with its mean colour (one SceneWarning per material), under the
    material's name with " (mean texture)" added: a material is one record per name.
    """
    visual = getattr(mesh, "visual", None)
    mat = getattr(visual, "material", None)
    if mat is None:
        return _material("default", diffuse=(0.8, 0.8, 0.8), specular=(0, 0, 0), exponent=0, emission=(0, 0, 0)), \
            None, None
    name = getattr(mat, "name", None) or "material"
    here = f"{where}: material {name!r}: "
    pbr = isinstance(mat, trimesh.visual.material.PBRMaterial)
    image = getattr(mat, "baseColorTexture" if pbr else "image", None)
    uvs = mesh_uvs(mesh) if image is not None else None
    texture = images.get(name)  # decoded once per material (an image's objects share the array)
    if texture is None:
        texture = _image_texture(image, f"{here}texture")
    mean = None if texture is None else texture.reshape(-1, 3).mean(axis=0, dtype=np.float64)
    if image is not None and uvs is None:
        fallback = f"{name} (mean texture)"
        if fallback not in images:
            images[fallback] = None
            warnings.warn(
                f"{here}its texture is on a mesh without texture coordinates: taken as its mean colour "
                f"{tuple(round(float(c), 4) for c in mean)}", SceneWarning, stacklevel=4)
        mapped = _from_pbr(mat, fallback, here, mean, textured=False) if pbr else \
            _from_mtl(mat, fallback, here, mean, textured=False)
        return mapped, None, None
    textured = image is not None
    mapped = _from_pbr(mat, name, here, mean, textured=textured) if pbr else \
        _from_mtl(mat, name, here, mean, textured=textured)
    if not textured:
        return mapped, None, None
    images[name] = texture
    return mapped, texture, uvs


def _mtl_vec(raw, key, here):
    value = raw.get(key)
    if value is None:
        return np.zeros(3)
    try:
        values = [float(v) for v in np.atleast_1d(value)]
    except (TypeError, ValueError):
        raise InputError(f"{here}{key.capitalize()} must be numbers, got {value!r}") from None
    if len(values) == 1:
        values *= 3
    if len(values) != 3:
        raise InputError(f"{here}{key.capitalize()} must have 1 or 3 values, got {value!r}")
    return np.array(values)


def _from_mtl(mat, name, here, mean=None, *, textured=False):
    """MTL's Kd, Ks, Ns, Ke. With a map_Kd image of linear mean colour ``mean``: kd
    = Kd (1 where Kd is absent: the map alone), the image multiplying it per point
    (``textured``), or its mean (not ``textured``)."""
    raw = getattr(mat, "kwargs", {}) or {}
    kd = _mtl_vec(raw, "kd", here)
    if mean is not None:
        if raw.get("kd") is None:
            kd = np.ones(3)
        if not textured:
            kd = kd * mean
    ks = _mtl_vec(raw, "ks", here)
    try:
        exponent = float(np.atleast_1d(raw.get("ns", 0.0))[0])
    except (TypeError, ValueError):
        raise InputError(f"{here}Ns must be a number, got {raw.get('ns')!r}") from None
    if not ks.any():
        exponent = 0.0
    return _material(
        name, diffuse=tuple(kd), specular=tuple(ks), exponent=exponent,
        emission=tuple(_mtl_vec(raw, "ke", here)), where=here[:-2] + ": ",
    )


def _from_pbr(mat, name, here, mean=None, *, textured=False):
    """glTF's metallic-roughness material (the module docstring's mapping). With a
    baseColorTexture of linear mean colour ``mean``: ``textured``, kd is the factor's
    part alone and the image multiplies it per point; the specular colour of a metal
    (metallic > 0), which our model cannot texture, takes the image's mean, with a
    warning. Not ``textured``: the base colour is the factor times the mean."""
    factor = mat.baseColorFactor
    base = np.ones(3) if factor is None else np.asarray(factor, dtype=np.float64)[:3] / 255.0
    metallic = 1.0 if mat.metallicFactor is None else float(mat.metallicFactor)
    roughness = 1.0 if mat.roughnessFactor is None else float(mat.roughnessFactor)
    mean_base = base if mean is None else base * mean
    diffuse_base = base if textured else mean_base
    # KHR_materials_emissive_strength is already in the factor (``meshfiles._gltf_emissive``)
    emissive = np.zeros(3) if mat.emissiveFactor is None else np.asarray(mat.emissiveFactor, dtype=np.float64)[:3]
    if metallic == 0.0 and roughness >= 0.9:
        return _material(
            name, diffuse=tuple(diffuse_base), specular=(0.0, 0.0, 0.0), exponent=0.0,
            emission=tuple(emissive), where=here[:-2] + ": ",
        )
    # glTF's own BRDF: Schlick's F with F0 = 0.04 (dielectric) mixed to baseColor (metal),
    # the diffuse part baseColor (1 - metallic), losing what F reflects
    f0 = np.clip(mean_base * metallic + 0.04 * (1.0 - metallic), 0.0, 1.0)
    alpha = max(roughness, 1e-3) ** 2  # glTF's roughness squared is GGX's alpha
    exponent = float(min(phong_exponent("ggx", alpha), 1e4))
    if textured and metallic > 0.0:
        warnings.warn(f"{here}metallic {metallic:g} with a baseColorTexture: the specular colour takes the "
                      "texture's mean (only the diffuse colour is textured)", SceneWarning, stacklevel=5)
    ks = np.ones(3)
    kd = np.minimum(diffuse_base * (1.0 - metallic), fresnel_kd_limit(ks, f0, exponent))
    return _material(
        name, diffuse=tuple(kd), specular=tuple(ks), exponent=exponent,
        emission=tuple(emissive), where=here[:-2] + ": ", fresnel=tuple(f0),
    )
