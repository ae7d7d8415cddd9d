"""The fitted model (shared/DESIGN.md, "Contract 2") and the one reference of its shading.

``fit.npz``, written with ``numpy.savez_compressed``, readable with ``allow_pickle=False``:

- ``meta``: 0-d str array of JSON ``{"format": "vlights.fit", "version": 1, "source":
  "...", "model": "...", "objects": {name: {"lights": K, "error": {...}, ...}}}``;
- per object ``<name>/positions`` (V, 3) float32, ``<name>/normals`` (V, 3) float32,
  ``<name>/faces`` (F, 3) int32 (copied from the solution), ``<name>/emitted`` (V, 3)
  float32, ``<name>/specular`` (V, 3) float32, ``<name>/light_dirs`` (K, 3) float32
  (world-space unit vectors towards each virtual light), ``<name>/light_rgb`` (K, 3)
  float32 and ``<name>/shininess`` (K,) float32. Diffuse objects have K = 0.

The shading formula (the paper's equation 1, Blinn-Phong half vector, no n.l gate):

    colour(v, w) = emitted[v] + sum_k max(0, dot(n[v], normalize(l_k + w)))^shininess[k]
                                      * light_rgb[k] * specular[v]

with w the unit vector from the surface point towards the eye; the lobe
max(0, ...)^shininess is ``fitting.lobes.lobe`` (with its cut-off: terms below e^-30 of
the lobe's peak are 0). ``shade_arrays`` is the numpy reference the fitter, the display
and every test use.

``load_fit`` reads a file through ``radiosity.formats.npz.open_archive`` and checks
everything a reader relies on: a bad file is refused with one ``InputError`` line that
names the file and the key at fault.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from radiosity.formats.camera import Camera, camera_from_dict
from radiosity.formats.errors import InputError
from radiosity.formats.npz import open_archive, write_archive

from .lobes import lobe_vectorised

FORMAT = "vlights.fit"
VERSION = 1
ARRAY_KEYS = ("positions", "normals", "faces", "emitted", "specular", "light_dirs", "light_rgb", "shininess")
UNIT_TOLERANCE = 1e-3  # a stored light direction's length may be off 1 by this much (float32 storage)


def shade_arrays(emitted, specular, normals, light_dirs, light_rgb, shininess, w):
    """The shading formula, broadcast over leading axes.

    emitted, specular, normals : (..., 3); w : (..., 3) unit, towards the eye;
    light_dirs, light_rgb : (K, 3); shininess : (K,). Returns (..., 3) float64.
    A half vector of zero length (the light exactly opposite the eye) gives no light.
    """
    emitted = np.asarray(emitted, dtype=np.float64)
    w = np.asarray(w, dtype=np.float64)
    normals = np.asarray(normals, dtype=np.float64)
    out = np.broadcast_to(emitted, np.broadcast_shapes(emitted.shape, w.shape, normals.shape)).copy()
    specular = np.asarray(specular, dtype=np.float64)
    nx, ny, nz = normals[..., 0], normals[..., 1], normals[..., 2]
    for light, rgb, p in zip(np.asarray(light_dirs, np.float64), np.asarray(light_rgb, np.float64), np.asarray(shininess, np.float64)):
        h = w + light
        lobe = lobe_vectorised(nx, ny, nz, h[..., 0], h[..., 1], h[..., 2], p)
        out = out + lobe[..., None] * rgb * specular
    return out


@dataclass(frozen=True, eq=False)
class FittedObject:
    """One object's fitted model; arrays as in the module docstring."""

    name: str
    positions: np.ndarray
    normals: np.ndarray
    faces: np.ndarray
    emitted: np.ndarray
    specular: np.ndarray
    light_dirs: np.ndarray
    light_rgb: np.ndarray
    shininess: np.ndarray
    info: dict = field(default_factory=dict)

    def __post_init__(self):
        v, k = len(self.positions), len(self.light_dirs)
        expect = {
            "positions": (v, 3), "normals": (v, 3), "emitted": (v, 3), "specular": (v, 3),
            "light_dirs": (k, 3), "light_rgb": (k, 3), "shininess": (k,),
        }
        for key, shape in expect.items():
            if np.shape(getattr(self, key)) != shape:
                raise ValueError(f"object {self.name!r}: '{key}' has shape {np.shape(getattr(self, key))}, expected {shape}")
        if np.ndim(self.faces) != 2 or np.shape(self.faces)[1] != 3:
            raise ValueError(f"object {self.name!r}: 'faces' must be (F, 3)")
        if "/" in self.name:
            raise ValueError(f"object name {self.name!r} contains '/'")

    @property
    def n_lights(self):
        return len(self.light_dirs)

    def shade(self, w, vertices=slice(None)):
        """Colour (..., 3) of ``vertices`` seen from unit directions ``w`` (..., 3) (world)."""
        return shade_arrays(
            self.emitted[vertices], self.specular[vertices], self.normals[vertices],
            self.light_dirs, self.light_rgb, self.shininess, w,
        )

    def arrays(self):
        return {
            "positions": np.asarray(self.positions, np.float32),
            "normals": np.asarray(self.normals, np.float32),
            "faces": np.asarray(self.faces, np.int32),
            "emitted": np.asarray(self.emitted, np.float32),
            "specular": np.asarray(self.specular, np.float32),
            "light_dirs": np.asarray(self.light_dirs, np.float32).reshape(-1, 3),
            "light_rgb": np.asarray(self.light_rgb, np.float32).reshape(-1, 3),
            "shininess": np.asarray(self.shininess, np.float32).reshape(-1),
        }


@dataclass(frozen=True, eq=False)
class FittedModel:
    objects: tuple[FittedObject, ...]
    source: str = ""
    model: str = ""
    settings: dict = field(default_factory=dict)
    camera: Camera | None = None  # the scene's default camera, from the solution

    def object(self, name):
        for o in self.objects:
            if o.name == name:
                return o
        raise KeyError(name)

    @property
    def names(self):
        return tuple(o.name for o in self.objects)

    def meta(self):
        return {
            "format": FORMAT,
            "version": VERSION,
            "source": self.source,
            "model": self.model,
            "settings": self.settings,
            "objects": {o.name: {"lights": o.n_lights, **o.info} for o in self.objects},
            **({"camera": self.camera.to_dict()} if self.camera is not None else {}),
        }

    def save(self, path):
        """Write ``fit.npz`` atomically (a temporary file renamed into place); strict
        JSON meta (a NaN or infinity in it is a ValueError before anything is written)."""
        arrays = {}
        for o in self.objects:
            arrays.update({f"{o.name}/{k}": a for k, a in o.arrays().items()})
        write_archive(path, self.meta(), arrays)

    @classmethod
    def load(cls, path):
        return load_fit(path)


def shade(model, name, world_dirs, vertices=slice(None)):
    """``fitting.shade``: colours of object ``name`` of ``model`` seen from world directions.

    model      : a ``FittedModel``; name : one of its objects, V of its vertices chosen
                 by ``vertices`` (a slice, an index array or a boolean mask; default all)
    world_dirs : unit vectors from each vertex towards the eye, float, either
                 (V, 3)    one direction per vertex          -> returns (V, 3) float64
                 (V, M, 3) M directions per vertex           -> returns (V, M, 3) float64

    Any other shape (a (2, 3) array for a 100-vertex object, a single (3,) vector, ...)
    raises ValueError saying which shapes are accepted and what was given.
    """
    obj = model.object(name)
    index = np.arange(len(obj.positions))[vertices]
    if index.ndim != 1:
        raise ValueError(f"shade: vertices must select a list of vertices (a slice, index array or mask), got {vertices!r}")
    w = np.asarray(world_dirs, dtype=np.float64)
    n_v = len(index)
    if not ((w.ndim == 2 or w.ndim == 3) and w.shape[0] == n_v and w.shape[-1] == 3):
        raise ValueError(
            f"shade: object {name!r} ({n_v} vertices selected) takes world_dirs of shape ({n_v}, 3), one direction "
            f"per vertex, or ({n_v}, M, 3), M directions per vertex; got shape {w.shape}"
        )
    if w.ndim == 3:
        return shade_arrays(
            obj.emitted[index][:, None], obj.specular[index][:, None], obj.normals[index][:, None],
            obj.light_dirs, obj.light_rgb, obj.shininess, w,
        )
    return obj.shade(w, index)


def _kind_error(archive, key, a, kinds):
    expected = "integers" if kinds == "iu" else "numbers"
    return archive.fail(f"'{key}' has dtype {a.dtype}, expected {expected}")


def _read_object(archive, name, info):
    """One object's arrays, checked; InputError naming the file and the key."""
    fail = archive.fail
    missing = [k for k in ARRAY_KEYS if f"{name}/{k}" not in archive.keys]
    if missing:
        raise fail(f"object {name!r} has no '{name}/{missing[0]}' array")
    arrays = {}
    positions = archive.array(f"{name}/positions", "fiu", (None, 3))
    n_v = positions.shape[0]
    lights = archive.array(f"{name}/light_dirs", "fiu", (None, 3))
    n_k = lights.shape[0]
    shapes = {
        "positions": (n_v, 3), "normals": (n_v, 3), "faces": (None, 3), "emitted": (n_v, 3), "specular": (n_v, 3),
        "light_dirs": (n_k, 3), "light_rgb": (n_k, 3), "shininess": (n_k,),
    }
    for key, shape in shapes.items():
        kinds = "iu" if key == "faces" else "fiu"
        arrays[key] = archive.array(f"{name}/{key}", kinds, shape)
    for key, a in arrays.items():
        if key != "faces" and not np.isfinite(a).all():
            bad = int(np.count_nonzero(~np.isfinite(a)))
            raise fail(f"'{name}/{key}' has {bad} NaN or infinite values")
    faces = arrays["faces"]
    if faces.shape[0] == 0:
        raise fail(f"'{name}/faces' is empty: object {name!r} has no faces")
    if faces.min() < 0 or faces.max() >= n_v:
        raise fail(f"'{name}/faces' has vertex indices from {faces.min()} to {faces.max()}, outside [0, {n_v})")
    if (arrays["shininess"] < 0).any():
        raise fail(f"'{name}/shininess' has a negative exponent ({float(arrays['shininess'].min()):g})")
    length = np.linalg.norm(arrays["light_dirs"].astype(np.float64), axis=1)
    if (np.abs(length - 1.0) > UNIT_TOLERANCE).any():
        raise fail(f"'{name}/light_dirs' are not unit vectors (a length of {float(length[np.argmax(np.abs(length - 1))]):g})")
    lights_meta = info.get("lights", n_k)
    if isinstance(lights_meta, bool) or not isinstance(lights_meta, int) or lights_meta != n_k:
        raise fail(f"meta 'objects' says object {name!r} has {lights_meta!r} lights; its arrays hold {n_k}")
    try:
        return FittedObject(
            name=name,
            info={k: v for k, v in info.items() if k != "lights"},
            **{k: np.asarray(a, np.int32 if k == "faces" else np.float32) for k, a in arrays.items()},
        )
    except ValueError as exc:
        raise fail(str(exc)) from None


def load_fit(path):
    """Read and check a ``fit.npz`` (Contract 2, version 1); a bad file raises
    InputError with one line naming the file and the key at fault."""
    with open_archive(path, FORMAT, (VERSION,)) as archive:
        meta, fail = archive.meta, archive.fail
        objects_meta = meta.get("objects")
        if not isinstance(objects_meta, dict):
            raise fail(f"meta 'objects' must be a JSON object of name: info, got {_json_type(objects_meta)}")
        if not objects_meta:
            raise fail("meta 'objects' is empty: the file holds no objects")
        for key, kind, default in (("source", str, ""), ("model", str, ""), ("settings", dict, {})):
            if not isinstance(meta.get(key, default), kind):
                raise fail(f"meta '{key}' must be a JSON {'string' if kind is str else 'object'}, got {_json_type(meta[key])}")
        objects = []
        for name, info in objects_meta.items():
            if not name or "/" in name:
                raise fail(f"meta 'objects' has an object name {name!r}: names are non-empty and contain no '/'")
            if not isinstance(info, dict):
                raise fail(f"meta 'objects': the info of object {name!r} must be a JSON object, got {_json_type(info)}")
            objects.append(_read_object(archive, name, info))
        camera = None
        if meta.get("camera") is not None:
            try:
                camera = camera_from_dict(meta["camera"], where="meta 'camera'")
            except InputError as exc:
                raise fail(str(exc)) from None
    return FittedModel(
        objects=tuple(objects), source=meta.get("source", ""), model=meta.get("model", ""),
        settings=meta.get("settings", {}), camera=camera,
    )


def _json_type(value):
    """What a JSON value is, for messages: 'a list', 'a string', 'null', ..."""
    names = {dict: "an object", list: "a list", str: "a string", bool: "a boolean", int: "a number", float: "a number"}
    return "null" if value is None else names.get(type(value), type(value).__name__)
