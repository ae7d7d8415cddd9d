"""Reading scenes: TOML scene files, OBJ (with MTL), glTF / GLB, and the built-ins.

``load_scene(source)`` takes a path or a built-in scene's name and returns a Scene.
Every problem with the input raises InputError with one line naming it.

Material mapping for mesh files given directly (a TOML scene names its materials
itself and ignores the file's):

OBJ / MTL
    Kd -> diffuse, Ks -> specular, Ns -> exponent (Ks absent or zero: diffuse),
    Ke -> emission. A map_Kd texture multiplies Kd by its mean colour (linearised
    from sRGB). kd + ks > 1 is refused, as in a scene file.
glTF 2.0 (metallic-roughness)
    base = baseColorFactor (times the mean of baseColorTexture, if any);
    specular ks = base * metallic + 0.04 * (1 - metallic) (the usual F0);
    diffuse kd = base * (1 - metallic) * (1 - ks);
    exponent n = (2 / alpha^2 - 2) / 4 with alpha = roughness^2 (the Blinn-Phong
    equivalent of GGX, quartered because our lobe is about the mirror direction, not
    the half vector), at most 10000; a dielectric (metallic = 0) with roughness >= 0.9
    is taken as diffuse (ks = 0), a lobe that broad being indistinguishable from one;
    emission = emissiveFactor (times KHR_materials_emissive_strength, if any: folded
    into the factor before trimesh reads the file, since trimesh drops extensions).
    Base colours pass through trimesh, which keeps them to 8 bits per channel.

Text mesh files (OBJ, MTL, ASCII STL, OFF) are read as UTF-8, a byte-order mark
dropped, or as Latin-1 where they are not UTF-8. An OBJ whose material library is
missing loads with the default material (diffuse 0.8) and a SceneWarning.
"""

from __future__ import annotations

import codecs
import io
import json
import os
import struct
import tomllib
import unicodedata
import warnings
from pathlib import Path

import numpy as np
import trimesh

from radiosity.formats.camera import camera_from_dict
from radiosity.formats.errors import InputError, SceneWarning
from radiosity.formats.inputs import MESH_BYTES, TEXT_BYTES, check_input_file, loads_json, loads_toml, read_input_bytes
from radiosity.formats.material import FLOAT32_MAX
from radiosity.formats.sniff import FILE_NAMES, input_kind
from radiosity.formats.sniff import MESH_SUFFIXES as _MESH_SUFFIXES
from radiosity.scene import builtins, geometry
from radiosity.scene.materials import Material
from radiosity.scene.model import DEFAULT_CREASE_ANGLE_DEG, MAX_COORDINATE, Scene, build_object

MESH_SUFFIXES = set(_MESH_SUFFIXES)
_MATERIAL_KEYS = {"diffuse", "specular", "exponent", "emission"}
_OBJECT_KEYS = {
    "name", "mesh", "builtin", "material", "scale", "rotate_deg", "translate",
    "resolution", "subdivisions", "crease_angle_deg", "flip",
}
_CAMERA_KEYS = {"position", "eye", "look_at", "up", "fov_y_deg"}
_TOP_KEYS = {"camera", "materials", "objects", "name", "description", "units"}


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
        f"give a .toml scene, a mesh file ({', '.join(sorted(MESH_SUFFIXES))}) "
        f"or a built-in scene ({', '.join(builtins.SCENES)})"
    )


# -- TOML ---------------------------------------------------------------------------


def _load_toml(text, base_dir, *, name, where):
    try:
        data = loads_toml(text, where)
    except tomllib.TOMLDecodeError as exc:
        raise InputError(f"{where}: malformed TOML: {exc}") from None
    _check_keys(data, _TOP_KEYS, where)
    materials = _parse_materials(data.get("materials", {}), where)
    objects_data = data.get("objects")
    if not isinstance(objects_data, list) or not objects_data:
        raise InputError(f"{where}: no [[objects]]: a scene needs at least one object")
    objects = [
        _parse_object(entry, i, materials, base_dir, where) for i, entry in enumerate(objects_data)
    ]
    camera = _parse_camera(data["camera"], where) if "camera" in data else None
    return Scene(name=str(data.get("name", name)), objects=tuple(objects), camera=camera, source=where)


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


def _material(name, *, diffuse, specular, exponent, emission, where=""):
    try:
        return Material(name=name, diffuse=diffuse, specular=specular, exponent=exponent, emission=emission)
    except InputError as exc:
        raise InputError(f"{where}{exc}") from None


def _parse_camera(table, where):
    here = f"{where}: [camera]"
    _check_keys(table, _CAMERA_KEYS, here)
    return camera_from_dict(table, where=here)


def _parse_object(entry, index, materials, base_dir, where):
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

    if "builtin" in entry:
        spec = entry["builtin"]
        if not isinstance(spec, str):
            raise InputError(f"{here}: 'builtin' must be a string, got {spec!r}")
        try:
            positions, faces = builtins.mesh(
                spec, resolution=entry.get("resolution"), subdivisions=entry.get("subdivisions")
            )
        except InputError as exc:
            raise InputError(f"{here}: {exc}") from None
        source = f"builtin {spec}"
    else:
        for key in ("resolution", "subdivisions"):
            if key in entry:
                raise InputError(f"{here}: '{key}' applies to built-in meshes only")
        mesh_file = entry["mesh"]
        if not isinstance(mesh_file, str):
            raise InputError(f"{here}: 'mesh' must be a file name, got {mesh_file!r}")
        path = base_dir / mesh_file
        positions, faces = _read_single_mesh(path, here)
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
    within = np.abs(positions).max() <= MAX_COORDINATE  # False for NaN: build_object names that
    positions, faces, _ = geometry.apply_transform(matrix, positions, faces)
    reach = np.abs(positions).max()
    if within and not reach <= MAX_COORDINATE:
        keys = " and ".join(f"'{k}'" for k in ("scale", "rotate_deg", "translate") if k in entry)
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


# -- mesh files -----------------------------------------------------------------------


_TEXT_MESH_SUFFIXES = {".obj", ".off", ".stl"}  # .stl: unless binary; .ply and .glb are binary, .gltf JSON


def decode_text(data):
    """A text mesh or material file's bytes as str: UTF-8 (a byte-order mark dropped),
    or, where that fails, Latin-1 (a comment or name from an old exporter)."""
    if data.startswith(codecs.BOM_UTF8):
        data = data[len(codecs.BOM_UTF8):]
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError:
        return data.decode("latin-1")


def _is_binary_stl(data):
    """The binary STL layout: an 80-byte header, a face count, 50 bytes per face."""
    return len(data) >= 84 and len(data) == 84 + 50 * int.from_bytes(data[80:84], "little")


class _Resolver(trimesh.resolvers.FilePathResolver):
    """The files a mesh file refers to, beside it; material libraries decoded as
    ``decode_text`` (trimesh would need charset_normalizer for Latin-1, and silently
    drops the materials without it).

    Each file is read as an input (``read_input_bytes``: a regular file, of at most a
    mesh's size, never a FIFO or a device); trimesh swallows what its loaders raise,
    so a refusal is kept in ``problems`` and raised by ``_trimesh_load`` after the
    load. Each MTL's ``map_Kd`` textures that do not exist are kept in ``missing``
    (MTL, texture) for a SceneWarning: trimesh drops them without a word."""

    def __init__(self, source):
        super().__init__(source)
        self.problems, self.missing = [], []

    def get(self, name):
        candidates = (name.strip(), name.strip().lstrip("/"), os.path.split(name)[-1])
        for candidate in candidates:
            try:
                path = self.absolute(candidate)
            except ValueError:
                continue
            if os.path.lexists(path):
                try:
                    data = read_input_bytes(path, "file named by the mesh", MESH_BYTES)
                except InputError as exc:
                    self.problems.append(exc)
                    raise
                if str(name).lower().endswith(".mtl"):
                    text = decode_text(data)
                    self._note_missing_textures(name, text)
                    return text.encode("utf-8")
                return data
        self.absolute(name)  # raises if the name escapes the mesh's directory
        raise FileNotFoundError(name)

    def _note_missing_textures(self, mtl, text):
        for line in text.splitlines():
            words = line.split(None, 1)
            if len(words) == 2 and words[0].lower() == "map_kd":
                texture = words[1].strip()
                found = False
                for candidate in (texture, texture.lstrip("/"), os.path.split(texture)[-1]):
                    try:
                        found = found or self.absolute(candidate).is_file()
                    except (ValueError, OSError):
                        continue
                if not found:
                    self.missing.append((mtl, texture))


def _mesh_bytes(path, where):
    """The file as trimesh should read it: text formats decoded (``decode_text``) and
    re-encoded as UTF-8, glTF with its emissive strength folded in (``_gltf_emissive``);
    None to read the file as it is."""
    suffix = path.suffix.lower()
    if suffix not in _TEXT_MESH_SUFFIXES | {".gltf", ".glb"}:
        return None
    try:
        data = read_input_bytes(path, "mesh", MESH_BYTES)
    except InputError as exc:
        raise InputError(f"{where}: {exc}") from None
    if suffix in (".gltf", ".glb"):
        return _gltf_emissive(data, suffix == ".glb", where)
    if suffix == ".stl" and _is_binary_stl(data):
        return None
    return decode_text(data).encode("utf-8")


def _trimesh_load(path, where, **kwargs):
    if not path.exists():
        raise InputError(f"{where}: mesh file {str(path)!r} not found")
    if path.suffix.lower() not in MESH_SUFFIXES:
        raise InputError(
            f"{where}: {str(path)!r}: unsupported mesh format (use {', '.join(sorted(MESH_SUFFIXES))})"
        )
    try:
        check_input_file(path, "mesh", MESH_BYTES)
    except InputError as exc:
        raise InputError(f"{where}: {exc}") from None
    data = _mesh_bytes(path, where)
    resolver = _Resolver(str(path))
    try:
        if data is None:
            loaded = trimesh.load(str(path), process=False, resolver=resolver, **kwargs)
        else:
            # file_type as the whole name: trimesh takes the format from it and names objects as for the file
            loaded = trimesh.load(io.BytesIO(data), file_type=str(path), resolver=resolver, process=False, **kwargs)
    except InputError as exc:
        raise InputError(f"{where}: {exc}") from None
    except RecursionError:
        raise InputError(f"{where}: mesh {str(path)!r} is nested too deep") from None
    except Exception as exc:  # trimesh raises many types for a bad file
        raise InputError(f"{where}: cannot read mesh {str(path)!r}: {exc}") from None
    if resolver.problems:
        raise InputError(f"{where}: {resolver.problems[0]}")
    for mtl, texture in dict.fromkeys(resolver.missing):
        warnings.warn(
            f"{where}: material library {mtl!r} names the texture {texture!r}, which is not found; "
            "its diffuse colour is taken without it",
            SceneWarning,
            stacklevel=3,
        )
    return loaded


def _missing_material_libraries(path):
    """The ``mtllib`` files an OBJ names that do not exist beside it."""
    missing = []
    for line in decode_text(read_input_bytes(path, "mesh", MESH_BYTES)).splitlines():
        words = line.split(None, 1)
        if len(words) == 2 and words[0] == "mtllib":
            name = words[1].strip()
            if not (path.parent / name).is_file():
                missing.append(name)
    return missing


# glTF materials' KHR_materials_emissive_strength, which trimesh does not keep
_EMISSIVE_STRENGTH = "KHR_materials_emissive_strength"
_GLB_MAGIC, _GLB_JSON = b"glTF", 0x4E4F534A


def _gltf_emissive(data, binary, where):
    """glTF (JSON) or GLB bytes with every material's KHR_materials_emissive_strength
    multiplied into its emissiveFactor (and the extension removed); None if no
    material uses it or the file is not readable as glTF (trimesh then says why)."""
    if binary:
        if len(data) < 20 or data[:4] != _GLB_MAGIC:
            return None
        json_length, chunk_type = struct.unpack_from("<II", data, 12)
        if chunk_type != _GLB_JSON or 20 + json_length > len(data):
            return None
        text, rest = data[20:20 + json_length], data[20 + json_length:]
    else:
        text, rest = data, b""
    try:
        tree = loads_json(decode_text(text), where)  # InputError if nested too deep
        materials = tree.get("materials", [])
    except (ValueError, AttributeError):
        return None
    changed = False
    for index, material in enumerate(materials if isinstance(materials, list) else []):
        extensions = material.get("extensions") if isinstance(material, dict) else None
        if not isinstance(extensions, dict) or _EMISSIVE_STRENGTH not in extensions:
            continue
        name = material.get("name", f"#{index}")
        spec = extensions.pop(_EMISSIVE_STRENGTH)
        strength = spec.get("emissiveStrength", 1.0) if isinstance(spec, dict) else spec
        if isinstance(strength, bool) or not isinstance(strength, (int, float)) or not strength >= 0:
            raise InputError(
                f"{where}: material {name!r}: {_EMISSIVE_STRENGTH} emissiveStrength must be a number >= 0, "
                f"got {strength!r}"
            )
        factor = material.get("emissiveFactor", [0.0, 0.0, 0.0])
        if not (isinstance(factor, list) and all(isinstance(f, (int, float)) for f in factor)):
            continue  # trimesh reports a malformed factor
        material["emissiveFactor"] = [f * strength for f in factor]
        changed = True
    if not changed:
        return None
    text = json.dumps(tree).encode("utf-8")
    if not binary:
        return text
    text += b" " * (-len(text) % 4)  # chunks are 4-byte aligned, JSON padded with spaces
    header = _GLB_MAGIC + struct.pack("<II", 2, 12 + 8 + len(text) + len(rest))
    return header + struct.pack("<II", len(text), _GLB_JSON) + text + rest


def _read_single_mesh(path, where):
    """All triangles of a mesh file as one (positions, faces) pair, in file units."""
    loaded = _trimesh_load(path, where, force="mesh")
    if not isinstance(loaded, trimesh.Trimesh) or len(loaded.faces) == 0:
        raise InputError(f"{where}: mesh {str(path)!r} has no triangles")
    return np.asarray(loaded.vertices, dtype=np.float64), np.asarray(loaded.faces, dtype=np.int64)


def _load_mesh_scene(path):
    """A scene from one mesh file, one object per (node, material), its materials mapped."""
    where = str(path)
    loaded = _trimesh_load(path, where)
    if path.suffix.lower() == ".obj":
        for name in _missing_material_libraries(path):
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
    objects, materials = [], {}
    for node in loaded.graph.nodes_geometry:
        transform, geom_name = loaded.graph[node]
        mesh = loaded.geometry[geom_name]
        if not isinstance(mesh, trimesh.Trimesh) or len(mesh.faces) == 0:
            continue
        material = _mapped_material(mesh, where)
        materials.setdefault(material.name, material)
        positions, faces, _ = geometry.apply_transform(
            np.asarray(transform, dtype=np.float64),
            np.asarray(mesh.vertices, dtype=np.float64),
            np.asarray(mesh.faces, dtype=np.int64),
        )
        name = safe_object_name(str(node))  # '/' separates keys in the solution file; no control characters
        if name in {o.name for o in objects}:
            name = f"{name}#{len(objects)}"
        objects.append(build_object(name, materials[material.name], positions, faces, source=where))
    if not objects:
        raise InputError(f"{where}: no triangle meshes in the file")
    return Scene(name=path.stem, objects=tuple(objects), camera=None, source=where)


def _mean_texture_colour(image):
    """Mean linear RGB of a PIL image (sRGB-encoded), or None."""
    if image is None:
        return None
    rgb = np.asarray(image.convert("RGB"), dtype=np.float64) / 255.0
    linear = np.where(rgb <= 0.04045, rgb / 12.92, ((rgb + 0.055) / 1.055) ** 2.4)
    return linear.reshape(-1, 3).mean(axis=0)


def _mapped_material(mesh, where):
    visual = getattr(mesh, "visual", None)
    mat = getattr(visual, "material", None)
    if mat is None:
        return _material("default", diffuse=(0.8, 0.8, 0.8), specular=(0, 0, 0), exponent=0, emission=(0, 0, 0))
    name = getattr(mat, "name", None) or "material"
    here = f"{where}: material {name!r}: "
    if isinstance(mat, trimesh.visual.material.PBRMaterial):
        return _from_pbr(mat, name, here)
    return _from_mtl(mat, name, here)


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


def _from_mtl(mat, name, here):
    raw = getattr(mat, "kwargs", {}) or {}
    kd = _mtl_vec(raw, "kd", here)
    tex = _mean_texture_colour(getattr(mat, "image", None))
    if tex is not None:
        kd = kd * tex
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


def _from_pbr(mat, name, here):
    factor = mat.baseColorFactor
    base = np.ones(3) if factor is None else np.asarray(factor, dtype=np.float64)[:3] / 255.0
    tex = _mean_texture_colour(getattr(mat, "baseColorTexture", None))
    if tex is not None:
        base = base * tex
    metallic = 1.0 if mat.metallicFactor is None else float(mat.metallicFactor)
    roughness = 1.0 if mat.roughnessFactor is None else float(mat.roughnessFactor)
    if metallic == 0.0 and roughness >= 0.9:
        ks = np.zeros(3)
        exponent = 0.0
    else:
        ks = base * metallic + 0.04 * (1.0 - metallic)
        alpha = max(roughness, 1e-3) ** 2
        exponent = float(min(max(2.0 / alpha**2 - 2.0, 0.0) / 4.0, 1e4))
    kd = base * (1.0 - metallic) * (1.0 - ks)
    # KHR_materials_emissive_strength is already in the factor (``_gltf_emissive``)
    emissive = np.zeros(3) if mat.emissiveFactor is None else np.asarray(mat.emissiveFactor, dtype=np.float64)[:3]
    return _material(
        name, diffuse=tuple(kd), specular=tuple(ks), exponent=exponent,
        emission=tuple(emissive), where=here[:-2] + ": ",
    )
