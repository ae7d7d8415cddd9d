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

with w the unit vector from the surface point towards the eye. ``shade_arrays`` is the
numpy reference the fitter, the display and every test use.
"""

from __future__ import annotations

import json
import os
import zipfile
from dataclasses import dataclass, field

import numpy as np

from radiosity.formats import Camera, InputError, atomic_output, camera_from_dict

FORMAT = "vlights.fit"
VERSION = 1
ARRAY_KEYS = ("positions", "normals", "faces", "emitted", "specular", "light_dirs", "light_rgb", "shininess")


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
    for l, rgb, p in zip(np.asarray(light_dirs, np.float64), np.asarray(light_rgb, np.float64), np.asarray(shininess, np.float64)):
        h = w + l
        length = np.linalg.norm(h, axis=-1)
        cos = np.einsum("...i,...i->...", normals, h) / np.where(length > 0, length, 1.0)
        lobe = np.where((length > 0) & (cos > 0), np.maximum(cos, 0.0) ** p, 0.0)
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
        """Write ``fit.npz`` atomically (a temporary file renamed into place)."""
        payload = {"meta": np.array(json.dumps(self.meta(), default=_json_default))}
        for o in self.objects:
            payload.update({f"{o.name}/{k}": a for k, a in o.arrays().items()})
        with atomic_output(path) as f:
            np.savez_compressed(f, **payload)

    @classmethod
    def load(cls, path):
        return load_fit(path)


def shade(model, name, world_dirs, vertices=slice(None)):
    """``fitting.shade``: colours of object ``name`` of ``model`` at its vertices
    (or ``vertices``) seen from unit world directions ``world_dirs`` (V, 3) or (V, M, 3)."""
    obj = model.object(name)
    w = np.asarray(world_dirs, dtype=np.float64)
    if w.ndim == 3:
        return shade_arrays(
            obj.emitted[vertices][:, None], obj.specular[vertices][:, None], obj.normals[vertices][:, None],
            obj.light_dirs, obj.light_rgb, obj.shininess, w,
        )
    return obj.shade(w, vertices)


def _json_default(value):
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    raise TypeError(f"not JSON serialisable: {type(value).__name__}")


def load_fit(path):
    """Read and check a ``fit.npz``; a bad file raises InputError with one line."""
    where = f"fit file {str(path)!r}"
    if not os.path.exists(path):
        raise InputError(f"{where} not found")
    if os.path.isdir(path):
        raise InputError(f"{where} is a directory")
    try:
        with np.load(path, allow_pickle=False) as npz:
            if "meta" not in npz.files:
                raise InputError(f"{where} is not a fitted model (no 'meta')")
            meta = json.loads(str(npz["meta"]))
            if meta.get("format") != FORMAT or meta.get("version") != VERSION:
                raise InputError(
                    f"{where} is not a {FORMAT} version {VERSION} file "
                    f"(format {meta.get('format')!r}, version {meta.get('version')!r})"
                )
            objects = []
            for name, info in meta.get("objects", {}).items():
                missing = [k for k in ARRAY_KEYS if f"{name}/{k}" not in npz.files]
                if missing:
                    raise InputError(f"{where}: object {name!r} has no '{missing[0]}'")
                arrays = {k: npz[f"{name}/{k}"] for k in ARRAY_KEYS}
                for k, a in arrays.items():
                    if k != "faces" and not np.isfinite(a).all():
                        raise InputError(f"{where}: object {name!r}: '{k}' is not finite")
                info = {k: v for k, v in info.items() if k != "lights"}
                try:
                    objects.append(FittedObject(name=name, info=info, **arrays))
                except ValueError as exc:
                    raise InputError(f"{where}: {exc}") from None
    except (zipfile.BadZipFile, ValueError, OSError, json.JSONDecodeError) as exc:
        raise InputError(f"{where} is not a fitted model ({' '.join(str(exc).split())})") from None
    camera = None
    if meta.get("camera") is not None:
        camera = camera_from_dict(meta["camera"], where=f"{where}: meta 'camera'")
    return FittedModel(
        objects=tuple(objects), source=meta.get("source", ""), model=meta.get("model", ""),
        settings=meta.get("settings", {}), camera=camera,
    )
