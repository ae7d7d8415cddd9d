"""Reading mesh files (OBJ with MTL, glTF / GLB, PLY, STL, OFF) through trimesh,
safely: every file, the mesh's own and those it names, is read as an input (a
regular file of bounded size), text decoded as UTF-8 or Latin-1, and what trimesh
drops without a word (missing textures, glTF's emissive strength) kept or warned of.
Used by the TOML and mesh-file scenes (``loaders``) and the Mitsuba reader.
"""

from __future__ import annotations

import codecs
import io
import json
import os
import struct
import warnings

import numpy as np
import trimesh

from radiosity.files.errors import InputError, SceneWarning
from radiosity.files.images import MAX_TEXTURE_PIXELS
from radiosity.files.inputs import MESH_BYTES, check_input_file, loads_json, read_input_bytes
from radiosity.files.sniff import MESH_SUFFIXES as _MESH_SUFFIXES

MESH_SUFFIXES = set(_MESH_SUFFIXES)

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


_IMAGE_SUFFIXES = {".png", ".jpg", ".jpeg", ".bmp", ".tga", ".tif", ".tiff", ".gif", ".webp"}


class _Resolver(trimesh.resolvers.FilePathResolver):
    """The files a mesh file refers to, beside it; material libraries decoded as
    ``decode_text`` (trimesh would need charset_normalizer for Latin-1, and silently
    drops the materials without it).

    Each file is read as an input (``read_input_bytes``: a regular file, of at most a
    mesh's size, never a FIFO or a device); trimesh swallows what its loaders raise,
    so a refusal is kept in ``problems`` and raised by ``_trimesh_load`` after the
    load. Each MTL's ``map_Kd`` textures that do not exist are kept in ``missing``
    (MTL, texture) for a SceneWarning: trimesh drops them without a word. So are the
    images it asks for that are not there (a glTF's) or that pillow will not open (a
    text file named .png, a picture beyond pillow's limit, which trimesh drops), in
    ``unusable`` (name, why)."""

    def __init__(self, source):
        super().__init__(source)
        self.problems, self.missing, self.unusable = [], [], []

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
                if os.path.splitext(str(name))[1].lower() in _IMAGE_SUFFIXES:
                    self._note_unusable_image(name, data)
                return data
        self.absolute(name)  # raises if the name escapes the mesh's directory
        if os.path.splitext(str(name))[1].lower() in _IMAGE_SUFFIXES:
            self.unusable.append((name, "not found"))
        raise FileNotFoundError(name)

    def _note_unusable_image(self, name, data):
        from PIL import Image

        try:
            with Image.open(io.BytesIO(data)):
                pass  # a picture it opens is kept, and a large one refused with the texture (``textures``)
        except Image.UnidentifiedImageError:
            self.unusable.append((name, "not an image this reads"))
            return
        except Image.DecompressionBombError:  # pillow's own limit, far above ours
            self.unusable.append((name, f"a picture of more than the {MAX_TEXTURE_PIXELS:,} pixels allowed"))
            return
        except (OSError, ValueError, SyntaxError, Image.DecompressionBombError) as exc:
            self.unusable.append((name, f"not an image this reads ({' '.join(str(exc).split())})"))

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


def trimesh_load(path, where, **kwargs):
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
    named = {texture for _, texture in resolver.missing}
    for image, why in dict.fromkeys(resolver.unusable):
        if image not in named:
            warnings.warn(f"{where}: the image {image!r} it names is {why}: left out, its material's colour "
                          "taken without it", SceneWarning, stacklevel=3)
    return loaded


def missing_material_libraries(path):
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


def read_single_mesh(path, where):
    """All triangles of a mesh file as one (positions, faces) pair, in file units."""
    loaded = trimesh_load(path, where, force="mesh")
    if not isinstance(loaded, trimesh.Trimesh) or len(loaded.faces) == 0:
        raise InputError(f"{where}: mesh {str(path)!r} has no triangles")
    return np.asarray(loaded.vertices, dtype=np.float64), np.asarray(loaded.faces, dtype=np.int64)


def read_mesh_parts(path, where):
    """All triangles of a mesh file as (positions, faces, normals, uvs): normals (V, 3)
    the file's own per-vertex normals where every part has them (OBJ ``vn``, PLY ``nx
    ny nz``), uvs (V, 2) its texture coordinates where every part has them (OBJ
    ``vt``, glTF TEXCOORD_0 (v flipped by trimesh to run up), PLY ``u v`` or ``s t``,
    as the file stores them), each else None.

    Read as a scene and each part copied with its cache: ``force="mesh"`` copies the
    parts without it, and so drops the normals the file gave."""
    loaded = trimesh_load(path, where, force="scene")
    parts, uvs = [], []
    for node in loaded.graph.nodes_geometry:
        transform, name = loaded.graph[node]
        geometry = loaded.geometry[name]
        if isinstance(geometry, trimesh.Trimesh) and len(geometry.faces):
            part = geometry.copy(include_cache=True)
            part.apply_transform(transform)  # turns cached vertex normals with it
            parts.append(part)
            uvs.append(mesh_uvs(geometry))
    if not parts:
        raise InputError(f"{where}: mesh {str(path)!r} has no triangles")
    offsets = np.cumsum([0] + [len(p.vertices) for p in parts])
    positions = np.concatenate([np.asarray(p.vertices, dtype=np.float64) for p in parts])
    faces = np.concatenate([np.asarray(p.faces, dtype=np.int64) + o for p, o in zip(parts, offsets[:-1], strict=True)])
    uvs = None if any(uv is None for uv in uvs) else np.concatenate(uvs)
    if not all("vertex_normals" in p._cache for p in parts):  # the file gave none (trimesh would compute them)
        return positions, faces, None, uvs
    normals = np.concatenate([np.asarray(p.vertex_normals, dtype=np.float64) for p in parts])
    return positions, faces, normals if normals.shape == positions.shape else None, uvs


def read_mesh_with_uvs(path, where):
    """All triangles of a mesh file as (positions, faces, uvs (V, 2) float64 or None):
    the file's texture coordinates (OBJ ``vt``, glTF TEXCOORD_0, PLY ``s t``) where
    every part has them, v up (trimesh flips glTF's, which runs down), else None."""
    positions, faces, _, uvs = read_mesh_parts(path, where)
    return positions, faces, uvs


def mesh_uvs(mesh):
    """A trimesh mesh's per-vertex texture coordinates (V, 2) float64, or None."""
    uv = getattr(getattr(mesh, "visual", None), "uv", None)
    if uv is None:
        return None
    uv = np.asarray(uv, dtype=np.float64)
    return uv if uv.shape == (len(mesh.vertices), 2) else None
