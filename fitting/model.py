"""The fitted model (fit.npz, docs/formats.md) and the one reference of its shading.

``fit.npz``, written with ``numpy.savez_compressed``, readable with ``allow_pickle=False``:

- ``meta``: 0-d str array of JSON ``{"format": "vlights.fit", "version": 2, "source":
  "...", "model": "...", "objects": {name: {"lights": K, "error": {...}, ...}}}``;
- per object ``<name>/positions`` (V, 3) float32, ``<name>/normals`` (V, 3) float32,
  ``<name>/faces`` (F, 3) int32 (copied from the solution), ``<name>/emitted`` (V, 3)
  float32, ``<name>/specular`` (V, 3) float32 (one coefficient for all lights, the
  paper's model) or (V, K, 3) (one per light), ``<name>/light_pos`` (K, 4) float32 in
  OpenGL's ``GL_POSITION`` convention ((x, y, z, 0) a unit vector towards a distant
  light, (x, y, z, 1) a point light's world position), ``<name>/light_rgb`` (K, 3)
  float32 and ``<name>/shininess`` (K,) float32. Diffuse objects have K = 0.

Version 1 files (``light_dirs`` (K, 3) instead of ``light_pos``, ``specular`` (V, 3))
are still read: their lights are directional (w = 0). Version 3 adds the emitters'
highlights and the reflection probe. Version 4 adds textured objects, as the solution's
version 3 has them (``radiosity.physics.textures``): ``<name>/uvs``,
``<name>/irradiance``, ``<name>/texture`` and ``meta.objects[name].textured`` =
{"diffuse": kd}; their colour gains kd * texture(uv) / pi * E, a display's per pixel;
and the light from outside the scene, copied from the solution (``meta.environment``,
``environment_image``: ``radiosity.physics.environment``), which displays draw where no
object is. A file is written with the lowest version that holds it (3 without either).
Version 5 adds delta emitter parts (points, spots, directions) to ``meta.emitters``, as
the solution's version 4 has them; a file without any is still version 4 or 3.
Version 6 adds emitter parts per object, as the solution's version 5 has them: an
object's ``<name>/emitter_parts`` (P_o,) int32 names the parts of ``meta.emitters``
(indices) its highlight draws, its ``visibility`` then (V, P_o); ``meta.emitters`` may
then hold up to ``MAX_SCENE_PARTS``. An object without it draws every part.
Version 7 adds glass, as the solution's version 7 has it: ``meta.objects[name].glass``
(``radiosity.physics.materials.Glass.to_dict``: kind, eta, distribution, alpha,
specular_reflectance, specular_transmittance) marks an object the displays draw as glass
(reflecting and refracting what is around it: ``display.glass``) instead of by this
formula; its arrays are a diffuse object's with ``emitted`` 0, so a reader of version 6
that ignores the key sees a black object. It adds mirrors too: ``meta.objects[name].mirror``
= {"specular": [r, g, b], "fresnel": [r, g, b] (optional)} (the material's ks and Schlick
F0) marks a perfect mirror (a smooth conductor: ``Material.is_mirror``) the displays draw
by what it reflects (``display.mirror``), its arrays a black diffuse object's likewise.
Version 8 adds a microfacet lobe to a highlight, as the solution's version 8 has it:
``meta.objects[name].highlight.microfacet`` (``radiosity.physics.materials.Microfacet.
to_dict``) draws the highlights with that lobe (``radiosity.physics.ltc``: its
specular reflectance and exact normal reflectance; "specular", "exponent" and "fresnel"
keep the Phong stand-in, which a reader of version 7 that ignores the key draws).

The shading formula (the paper's equation 1, Blinn-Phong half vector, no n.l gate, no
distance attenuation), at a surface point x with unit normal n:

    l_k(x)  = normalize(xyz_k - w_k x)
    colour  = emitted + sum_k max(0, dot(n, normalize(l_k(x) + w)))^shininess[k]
                              * light_rgb[k] * specular[(k)]

with w the unit vector from x towards the eye; the lobe max(0, ...)^shininess is
``fitting.lobes.lobe`` (with its cut-off: terms below e^-30 of the lobe's peak are 0).
A point light exactly at x, or a half vector of zero length, gives no light.
``shade_arrays`` is the numpy reference the fitter, the display and every test use.

``load_fit`` reads a file through ``radiosity.files.npz.open_archive`` and checks
everything a reader relies on: a bad file is refused with one ``InputError`` line that
names the file and the key at fault.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from radiosity.files.camera import Camera, camera_from_meta
from radiosity.files.npz import open_archive, write_archive
from radiosity.physics.emitters import DEFAULT_NODES, MAX_FILE_PARTS, MAX_NODES, emitter_radiance, file_parts
from radiosity.physics.environment import IMAGE_KEY, EnvironmentLight, read_environment
from radiosity.physics.materials import Glass, Microfacet
from radiosity.physics.textures import TexturedDiffuse, read_textured

from .lobes import lobe_vectorised
from .options import PARTS  # noqa: F401 (the parts a display may switch off)
from .probe import ALBEDO_POINTS, Probe, probe_values

FORMAT = "vlights.fit"
VERSION = 10  # the newest version written (a file is written with the lowest that holds it: FittedModel.version)
READS = (1, 2, 3, 4, 5, 6, 7, 8, 9, 10)
MAX_PROBE_SIZE = 256
ARRAY_KEYS = ("positions", "normals", "faces", "emitted", "specular", "light_pos", "light_rgb", "shininess")
ARRAY_KEYS_V1 = ("positions", "normals", "faces", "emitted", "specular", "light_dirs", "light_rgb", "shininess")
UNIT_TOLERANCE = 1e-3  # a stored light direction's length may be off 1 by this much (float32 storage)


def light_vectors(light_pos, positions):
    """Unit vectors (..., K, 3) from surface points ``positions`` (..., 3) towards each
    light of ``light_pos`` (K, 4): xyz - w x, normalised (zero where a point light sits
    exactly at the point)."""
    light_pos = np.asarray(light_pos, np.float64).reshape(-1, 4)
    x = np.asarray(positions, np.float64)[..., None, :]
    toward = light_pos[:, :3] - light_pos[:, 3:4] * x
    length = np.linalg.norm(toward, axis=-1, keepdims=True)
    return np.where(length > 0, toward / np.where(length > 0, length, 1.0), 0.0)


def shade_arrays(emitted, specular, normals, positions, lights, w):
    """The shading formula, broadcast over leading axes.

    emitted, normals, positions : (..., 3); w : (..., 3) unit, towards the eye;
    specular : (..., 3) shared by the lights or (..., K, 3) one per light;
    lights : (light_pos (K, 4), light_rgb (K, 3), shininess (K,)). Returns (..., 3) float64.
    """
    light_pos, light_rgb, shininess = (np.asarray(a, np.float64) for a in lights)
    light_pos, light_rgb, shininess = light_pos.reshape(-1, 4), light_rgb.reshape(-1, 3), shininess.reshape(-1)
    emitted = np.asarray(emitted, dtype=np.float64)
    w = np.asarray(w, dtype=np.float64)
    normals = np.asarray(normals, dtype=np.float64)
    positions = np.asarray(positions, dtype=np.float64)
    specular = np.asarray(specular, dtype=np.float64)
    per_light = specular.ndim == emitted.ndim + 1
    shape = np.broadcast_shapes(emitted.shape, w.shape, normals.shape, positions.shape)
    out = np.broadcast_to(emitted, shape).copy()
    if not len(light_pos):
        return out
    toward = light_vectors(light_pos, positions)  # (..., K, 3)
    nx, ny, nz = normals[..., 0], normals[..., 1], normals[..., 2]
    for k in range(len(light_pos)):
        lk = toward[..., k, :]
        h = w + lk
        lobe = lobe_vectorised(nx, ny, nz, h[..., 0], h[..., 1], h[..., 2], shininess[k])
        lobe = np.where(np.any(lk != 0, axis=-1), lobe, 0.0)
        coefficient = specular[..., k, :] if per_light else specular
        out = out + lobe[..., None] * light_rgb[k] * coefficient
    return out


def directional(light_dirs):
    """(K, 4) ``light_pos`` of distant lights from unit directions (K, 3)."""
    d = np.asarray(light_dirs, np.float64).reshape(-1, 3)
    return np.concatenate([d, np.zeros((len(d), 1))], axis=1)


@dataclass(frozen=True, eq=False)
class Highlight:
    """An object's emitter term (version 3): the emitters' glossy highlights in closed
    form (``radiosity.physics.emitters``).

    parts: the ``EmitterPart`` s it draws (the scene's, or the object's own of them);
    nodes: N of the quadrature; ks (3,) and exponent: the surface's modified-Phong
    specular part; visibility (V, P) float32: how much of each part each vertex sees;
    fresnel: None, or the material's Schlick F0 (3,); indices: where ``parts`` are the
    object's own (version 6), their indices in the model's ``emitters`` (None: parts are
    all of them, in order); microfacet: None, or the ``Microfacet`` whose own lobe draws
    the highlights (version 8; ks, exponent and fresnel then the stand-in's, unused)."""

    parts: tuple
    nodes: int
    ks: np.ndarray
    exponent: float
    visibility: np.ndarray
    fresnel: np.ndarray | None = None  # Schlick's F0 (3,) of a Fresnel material: ks weighted by F(w.n)
    indices: tuple | None = None  # version 6: the parts' indices in the model's emitters (None: all, in order)
    microfacet: Microfacet | None = None  # version 8: the lobe that draws them

    def radiance(self, positions, normals, views, source):
        """E (..., 3) float64 at points (..., 3) with unit normals, unit views, the
        visibility of ``visibility`` rows (broadcast over the leading axes' first)."""
        positions = np.asarray(positions, np.float64)
        shape = np.broadcast_shapes(positions.shape, np.shape(normals), np.shape(views))
        vis = np.asarray(self.visibility, np.float64)
        lead = shape[:-1]
        vis = np.broadcast_to(vis.reshape(vis.shape[:1] + (1,) * (len(lead) - 1) + vis.shape[1:]), lead + vis.shape[1:])
        out = emitter_radiance(
            self.parts, np.broadcast_to(positions, shape).reshape(-1, 3), np.broadcast_to(normals, shape).reshape(-1, 3),
            np.broadcast_to(views, shape).reshape(-1, 3), self.ks, self.exponent,
            visibility=vis.reshape(-1, len(self.parts)), nodes=self.nodes, source=source, fresnel=self.fresnel,
            microfacet=self.microfacet,
        )
        return out.reshape(shape)


@dataclass(frozen=True)
class Mirror:
    """A perfect mirror's reflectance: ``specular`` ks (3,) and, where the material has one,
    Schlick's F0 ``fresnel`` (3,): it reflects ks F(w.n) of what it mirrors."""

    specular: tuple[float, float, float]
    fresnel: tuple[float, float, float] | None = None

    def to_dict(self):
        return {"specular": list(self.specular), **({"fresnel": list(self.fresnel)} if self.fresnel else {})}

    @classmethod
    def from_dict(cls, entry):
        """The mirror of a ``to_dict`` entry; ValueError naming what is wrong."""
        if not isinstance(entry, dict) or set(entry) - {"specular", "fresnel"} or "specular" not in entry:
            raise ValueError('mirror must be {"specular": [r, g, b], "fresnel": [r, g, b] (optional)}')
        values = {}
        for key in ("specular", "fresnel"):
            if key in entry:
                v = _finite_numbers(entry[key], 3)
                if v is None or (v < 0).any() or (key == "fresnel" and (v > 1).any()):
                    raise ValueError(f"mirror {key} must be 3 numbers" + (" in [0, 1]" if key == "fresnel" else " >= 0"))
                values[key] = tuple(float(c) for c in v)
        return cls(**values)


@dataclass(frozen=True, eq=False)
class FittedObject:
    """One object's fitted model; arrays as in the module docstring (``light_pos`` (K, 4),
    ``specular`` (V, 3) shared or (V, K, 3) per light)."""

    name: str
    positions: np.ndarray
    normals: np.ndarray
    faces: np.ndarray
    emitted: np.ndarray
    specular: np.ndarray
    light_pos: np.ndarray
    light_rgb: np.ndarray
    shininess: np.ndarray
    info: dict = field(default_factory=dict)
    highlight: Highlight | None = None  # version 3: the emitters' highlights
    probe: Probe | None = None  # version 3: the reflection probe ...
    probe_weight: np.ndarray | None = None  # ... and its per-vertex weight s (V, 3)
    textured: TexturedDiffuse | None = None  # version 4: a textured object's diffuse term
    glass: Glass | None = None  # version 7: drawn as glass (its arrays a black diffuse object's)
    mirror: Mirror | None = None  # version 7: drawn as a mirror (likewise)
    near_base: np.ndarray | None = None  # version 10: a near mirror's own part (V, 3) (physics.materials.near_base) ...
    near_microfacet: Microfacet | None = None  # ... and its material's model

    def __post_init__(self):
        v, k = len(self.positions), len(self.light_pos)
        expect = {
            "positions": (v, 3), "normals": (v, 3), "emitted": (v, 3),
            "light_pos": (k, 4), "light_rgb": (k, 3), "shininess": (k,),
        }
        for key, shape in expect.items():
            if np.shape(getattr(self, key)) != shape:
                raise ValueError(f"object {self.name!r}: '{key}' has shape {np.shape(getattr(self, key))}, expected {shape}")
        if np.shape(self.specular) not in ((v, 3), (v, k, 3)):
            raise ValueError(
                f"object {self.name!r}: 'specular' has shape {np.shape(self.specular)}, expected ({v}, 3) or ({v}, {k}, 3)"
            )
        if np.ndim(self.faces) != 2 or np.shape(self.faces)[1] != 3:
            raise ValueError(f"object {self.name!r}: 'faces' must be (F, 3)")
        if "/" in self.name:
            raise ValueError(f"object name {self.name!r} contains '/'")
        w = np.asarray(self.light_pos)[:, 3] if k else np.zeros(0)
        if not np.isin(w, (0.0, 1.0)).all():
            raise ValueError(f"object {self.name!r}: 'light_pos' w must be 0 (directional) or 1 (positional), got {w}")
        if (self.probe is None) != (self.probe_weight is None):
            raise ValueError(f"object {self.name!r}: a probe needs its per-vertex weight and the weight its probe")
        if self.probe_weight is not None and np.shape(self.probe_weight) != (v, 3):
            raise ValueError(f"object {self.name!r}: 'probe_weight' has shape {np.shape(self.probe_weight)}, expected ({v}, 3)")
        if (self.near_base is None) != (self.near_microfacet is None):
            raise ValueError(f"object {self.name!r}: a near mirror needs its own part and its microfacet model")
        if self.near_base is not None:
            base = np.asarray(self.near_base)
            if base.shape != (v, 3) or not (np.isfinite(base).all() and (base >= 0).all()):
                raise ValueError(f"object {self.name!r}: 'near_base' must be ({v}, 3), finite and >= 0")
        if self.textured is not None and self.textured.n_vertices != v:
            raise ValueError(f"object {self.name!r}: 'uvs' has {self.textured.n_vertices} rows, expected {v}")
        if self.highlight is not None and np.shape(self.highlight.visibility) != (v, len(self.highlight.parts)):
            raise ValueError(
                f"object {self.name!r}: 'visibility' has shape {np.shape(self.highlight.visibility)}, "
                f"expected ({v}, {len(self.highlight.parts)})"
            )

    @property
    def n_lights(self):
        return len(self.light_pos)

    @property
    def near_eta(self):
        """The interface a near mirror's own part leaves through: a plastic's eta, else 0."""
        m = self.near_microfacet
        return float(m.eta[0]) if m is not None and m.kind in ("plastic", "roughplastic") else 0.0

    @property
    def per_light(self):
        """True when each light has its own per-vertex coefficient ((V, K, 3) specular)."""
        return np.ndim(self.specular) == 3

    @property
    def positional(self):
        """(K,) bool: which lights are point lights."""
        return np.asarray(self.light_pos)[:, 3] == 1.0

    @property
    def lights(self):
        return self.light_pos, self.light_rgb, self.shininess

    @property
    def floats_per_vertex(self):
        """Numbers stored per vertex besides the mesh: emitted, specular, the probe's
        weight, the emitters' visibility."""
        n = 3 + (int(np.prod(np.shape(self.specular)[1:])) if self.n_lights else 0)
        n += 3 if self.probe_weight is not None else 0
        n += self.highlight.visibility.shape[1] if self.highlight is not None else 0
        n += 5 if self.textured is not None else 0
        return n

    @property
    def floats(self):
        """Numbers stored in all (per vertex x V, the probe's texels, the lights)."""
        extra = 3 * self.probe.size**2 if self.probe is not None else 0
        extra += self.textured.texture.size if self.textured is not None else 0
        return self.floats_per_vertex * len(self.positions) + extra + 8 * self.n_lights

    def shade(self, w, vertices=slice(None), parts=PARTS):
        """Colour (..., 3) of ``vertices`` seen from unit directions ``w`` (..., 3) (world):
        the whole shading formula, or the emitted colour plus the ``parts`` named."""
        index = np.arange(len(self.positions))[vertices]
        return self._shade(index, np.asarray(w, np.float64), parts)

    def _shade(self, index, w, parts=PARTS):
        """The formula at vertices ``index`` (V,) seen from w (V, 3) or (V, M, 3)."""
        extra = (slice(None),) + (None,) * (w.ndim - 2)
        emitted, normals, positions = self.emitted[index][extra], self.normals[index][extra], self.positions[index][extra]
        lights = self.lights if "lights" in parts else (np.zeros((0, 4)), np.zeros((0, 3)), np.zeros(0))
        specular = self.specular[index][extra] if self.n_lights else np.zeros_like(emitted)
        out = shade_arrays(emitted, specular, normals, positions, lights, w)
        if self.probe is not None and "probe" in parts:
            out = out + np.asarray(self.probe_weight, np.float64)[index][extra] * probe_values(
                self.probe, positions, w, normals
            )
        if self.highlight is not None and "emitters" in parts:
            h = self.highlight
            vis = Highlight(h.parts, h.nodes, h.ks, h.exponent, np.asarray(h.visibility)[index], h.fresnel, h.indices,
                            h.microfacet)
            out = out + vis.radiance(positions, normals, w, self.name)
        if self.textured is not None:
            out = out + self.textured.radiance(index)[extra]
        return out

    def arrays(self):
        return {
            "positions": np.asarray(self.positions, np.float32),
            "normals": np.asarray(self.normals, np.float32),
            "faces": np.asarray(self.faces, np.int32),
            "emitted": np.asarray(self.emitted, np.float32),
            "specular": np.asarray(self.specular, np.float32),
            "light_pos": np.asarray(self.light_pos, np.float32).reshape(-1, 4),
            "light_rgb": np.asarray(self.light_rgb, np.float32).reshape(-1, 3),
            "shininess": np.asarray(self.shininess, np.float32).reshape(-1),
            **({"visibility": np.asarray(self.highlight.visibility, np.float32)} if self.highlight is not None else {}),
            **({"emitter_parts": np.asarray(self.highlight.indices, np.int32).reshape(-1)}
               if self.highlight is not None and self.highlight.indices is not None else {}),
            **({"probe": np.asarray(self.probe.texels, np.float32), "probe_weight": np.asarray(self.probe_weight, np.float32)}
               if self.probe is not None else {}),
            **({k.split("/", 1)[1]: a for k, a in self.textured.arrays("o").items()} if self.textured is not None else {}),
            **({"near_base": np.asarray(self.near_base, np.float32)} if self.near_base is not None else {}),
        }

    def meta_info(self):
        """This object's entry of the meta's "objects" (version 3 adds "highlight", "probe")."""
        out = {"lights": self.n_lights, **self.info}
        if self.highlight is not None:
            out["highlight"] = {"specular": [float(v) for v in self.highlight.ks], "exponent": float(self.highlight.exponent)}
            if self.highlight.fresnel is not None:
                out["highlight"]["fresnel"] = [float(v) for v in self.highlight.fresnel]
            if self.highlight.microfacet is not None:
                out["highlight"]["microfacet"] = self.highlight.microfacet.to_dict()
        if self.probe is not None:
            out["probe"] = self.probe.to_meta()
        if self.textured is not None:
            out["textured"] = {"diffuse": list(self.textured.kd)}
        if self.glass is not None:
            out["glass"] = self.glass.to_dict()
        if self.mirror is not None:
            out["mirror"] = self.mirror.to_dict()
        if self.near_base is not None:
            out["near"] = {"microfacet": self.near_microfacet.to_dict()}
        return out


@dataclass(frozen=True, eq=False)
class FittedModel:
    objects: tuple[FittedObject, ...]
    source: str = ""
    model: str = ""
    settings: dict = field(default_factory=dict)
    camera: Camera | None = None  # the scene's default camera, from the solution
    emitters: tuple = ()  # version 3: the emitter parts the objects' highlights come from
    emitter_nodes: int = DEFAULT_NODES
    environment: EnvironmentLight | None = None  # version 4: the light from outside the scene

    def object(self, name):
        for o in self.objects:
            if o.name == name:
                return o
        raise KeyError(name)

    @property
    def names(self):
        return tuple(o.name for o in self.objects)

    @property
    def version(self):
        """The lowest contract version that holds this model: 10 where an object keeps a near mirror's
        own part, else 9 where a textured object has an opacity mask, else 8 where a highlight has a microfacet lobe,
        else 7 with a glass object or a mirror, else 6 where
        an object names its emitter parts, else 5 with a delta emitter part, else 4 with a textured object or
        an environment, else 3."""
        if any(o.near_base is not None for o in self.objects):
            return 10
        if any(o.textured is not None and o.textured.opacity is not None for o in self.objects):
            return 9
        if any(o.highlight is not None and o.highlight.microfacet is not None for o in self.objects):
            return 8
        if any(o.glass is not None or o.mirror is not None for o in self.objects):
            return 7
        if any(o.highlight is not None and o.highlight.indices is not None for o in self.objects):
            return 6
        if any(p.is_delta for p in self.emitters):
            return 5
        return 4 if self.environment is not None or any(o.textured is not None for o in self.objects) else 3

    def meta(self):
        return {
            "format": FORMAT,
            "version": self.version,
            "source": self.source,
            "model": self.model,
            "settings": self.settings,
            "objects": {o.name: o.meta_info() for o in self.objects},
            "emitters": [p.to_dict() for p in self.emitters],
            "emitter_nodes": self.emitter_nodes,
            **({"camera": self.camera.to_dict()} if self.camera is not None else {}),
            **({"environment": self.environment.meta()} if self.environment is not None else {}),
        }

    def save(self, path):
        """Write ``fit.npz`` atomically (a temporary file renamed into place); strict
        JSON meta (a NaN or infinity in it is a ValueError before anything is written)."""
        arrays = {}
        for o in self.objects:
            arrays.update({f"{o.name}/{k}": a for k, a in o.arrays().items()})
        if self.environment is not None:
            arrays[IMAGE_KEY] = self.environment.image
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
    return obj._shade(index, w)


def _read_object(archive, name, info, version, emitters=(), nodes=DEFAULT_NODES):
    """One object's arrays, checked; InputError naming the file and the key."""
    fail = archive.fail
    keys = ARRAY_KEYS if version >= 2 else ARRAY_KEYS_V1
    missing = [k for k in keys if f"{name}/{k}" not in archive.keys]
    if missing:
        raise fail(f"object {name!r} has no '{name}/{missing[0]}' array")
    arrays = {}
    positions = archive.array(f"{name}/positions", "fiu", (None, 3))
    n_v = positions.shape[0]
    light_key = "light_pos" if version >= 2 else "light_dirs"
    lights = archive.array(f"{name}/{light_key}", "fiu", (None, 4 if version >= 2 else 3))
    n_k = lights.shape[0]
    shapes = {
        "positions": (n_v, 3), "normals": (n_v, 3), "faces": (None, 3), "emitted": (n_v, 3),
        light_key: lights.shape, "light_rgb": (n_k, 3), "shininess": (n_k,),
    }
    for key, shape in shapes.items():
        kinds = "iu" if key == "faces" else "fiu"
        arrays[key] = archive.array(f"{name}/{key}", kinds, shape)
    specular = archive.array(f"{name}/specular", "fiu")
    if specular.shape != (n_v, 3) and not (version >= 2 and specular.shape == (n_v, n_k, 3)):
        allowed = f"({n_v}, 3)" + (f" or ({n_v}, {n_k}, 3)" if version >= 2 else "")
        raise fail(f"'{name}/specular' has shape {tuple(specular.shape)}, expected {allowed}")
    arrays["specular"] = specular
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
    for key in ("emitted", "specular", "light_rgb"):
        if (arrays[key] < 0).any():
            raise fail(f"'{name}/{key}' has a negative value ({float(arrays[key].min()):g}); it must not be negative")
    if version >= 2:
        w = arrays["light_pos"][:, 3]
        if not np.isin(w, (0.0, 1.0)).all():
            raise fail(f"'{name}/light_pos' has w = {float(w[~np.isin(w, (0.0, 1.0))][0]):g}; w is 0 (a direction) or 1 (a point)")
        directions = arrays["light_pos"][w == 0, :3]
    else:
        directions = arrays.pop("light_dirs")
        arrays["light_pos"] = directional(directions)
    length = np.linalg.norm(np.asarray(directions, np.float64), axis=1)
    if (np.abs(length - 1.0) > UNIT_TOLERANCE).any():
        raise fail(f"'{name}/{light_key}': directional lights must be unit vectors "
                   f"(a length of {float(length[np.argmax(np.abs(length - 1))]):g})")
    lights_meta = info.get("lights", n_k)
    if isinstance(lights_meta, bool) or not isinstance(lights_meta, int) or lights_meta != n_k:
        raise fail(f"meta 'objects' says object {name!r} has {lights_meta!r} lights; its arrays hold {n_k}")
    highlight, probe, weight = None, None, None
    if version >= 3:
        highlight = _read_highlight(archive, name, info, n_v, emitters, nodes)
        probe, weight = _read_probe(archive, name, info, n_v)
    textured = None
    if version >= 4 and "textured" in info:
        diffuse = info["textured"].get("diffuse") if isinstance(info["textured"], dict) else None
        if not (isinstance(diffuse, list) and len(diffuse) == 3 and all(_is_number(c) for c in diffuse)):
            raise fail(f"meta 'objects' {name!r}: 'textured' must be {{\"diffuse\": [r, g, b]}}")
        textured = read_textured(archive, name, n_v, diffuse, masks=version >= 9)
        if textured is None:
            raise fail(f"object {name!r} is textured in meta 'objects' but has no '{name}/uvs'")
    glass = mirror = None
    try:
        if version >= 7 and "glass" in info:
            glass = Glass.from_dict(info["glass"])
        if version >= 7 and "mirror" in info:
            mirror = Mirror.from_dict(info["mirror"])
    except (TypeError, ValueError) as exc:
        raise fail(f"meta 'objects' {name!r}: {exc}") from None
    near_base, near_microfacet = _read_near(archive, name, info, n_v) if version >= 10 else (None, None)
    try:
        return FittedObject(
            name=name,
            info={k: v for k, v in info.items()
                  if k not in ("lights", "highlight", "probe", "textured", "glass", "mirror", "near")},
            near_base=near_base,
            near_microfacet=near_microfacet,
            textured=textured,
            glass=glass,
            mirror=mirror,
            highlight=highlight,
            probe=probe,
            probe_weight=weight,
            **{k: np.asarray(a, np.int32 if k == "faces" else np.float32) for k, a in arrays.items()},
        )
    except ValueError as exc:
        raise fail(str(exc)) from None


def _finite_numbers(value, count):
    """``value`` as a float64 array of ``count`` finite numbers, or None."""
    try:
        a = np.asarray(value, np.float64).reshape(-1)
    except (TypeError, ValueError):
        return None
    return a if a.shape == (count,) and np.isfinite(a).all() else None


def _read_highlight(archive, name, info, n_v, emitters, nodes):
    """The object's emitter term (version 3), or None where it has none."""
    fail = archive.fail
    entry = info.get("highlight")
    key = f"{name}/visibility"
    if entry is None:
        if key in archive.keys:
            raise fail(f"'{key}' is present but meta 'objects' gives object {name!r} no 'highlight'")
        return None
    if not isinstance(entry, dict):
        raise fail(f"meta 'objects': object {name!r}'s 'highlight' must be a JSON object")
    ks = _finite_numbers(entry.get("specular"), 3)
    exponent = _finite_numbers(entry.get("exponent"), 1)
    if ks is None or (ks < 0).any() or exponent is None or exponent[0] < 0:
        raise fail(f"meta 'objects': object {name!r}'s 'highlight' needs 'specular' [r, g, b] >= 0 and 'exponent' >= 0")
    fresnel = None
    if "fresnel" in entry:
        fresnel = _finite_numbers(entry["fresnel"], 3)
        if fresnel is None or (fresnel < 0).any() or (fresnel > 1).any():
            raise fail(f"meta 'objects': object {name!r}'s 'highlight' 'fresnel' must be [r, g, b] in [0, 1]")
    microfacet = None
    if archive.meta["version"] >= 8 and "microfacet" in entry:
        try:
            microfacet = Microfacet.from_dict(entry["microfacet"])
        except ValueError as exc:
            raise fail(f"meta 'objects': object {name!r}'s 'highlight' {exc}") from None
    if key not in archive.keys:
        raise fail(f"object {name!r} has a 'highlight' but no '{key}' array")
    indices, parts = None, emitters
    if archive.meta["version"] >= 6 and f"{name}/emitter_parts" in archive.keys:
        indices = archive.array(f"{name}/emitter_parts", "iu", (None,))
        if len(indices) > MAX_FILE_PARTS or len(np.unique(indices)) != len(indices) or (
                len(indices) and (int(indices.min()) < 0 or int(indices.max()) >= len(emitters))):
            raise fail(f"'{name}/emitter_parts' must name at most {MAX_FILE_PARTS} distinct parts of the "
                       f"{len(emitters)} in meta 'emitters'")
        indices = tuple(int(i) for i in indices)
        parts = tuple(emitters[i] for i in indices)
    elif len(emitters) > MAX_FILE_PARTS:
        raise fail(f"object {name!r} has a 'highlight' of {len(emitters)} emitter parts but no '{name}/emitter_parts' "
                   f"(an object draws at most {MAX_FILE_PARTS})")
    vis = archive.array(key, "fiu", (n_v, len(parts)))
    if not (np.isfinite(vis).all() and (vis >= 0).all() and (vis <= 1).all()):
        raise fail(f"'{key}' has values outside [0, 1]")
    return Highlight(parts, nodes, ks, float(exponent[0]), np.asarray(vis, np.float32), fresnel, indices, microfacet)


def _read_near(archive, name, info, n_v):
    """The object's (near_base (V, 3), its Microfacet) (version 10), or (None, None)."""
    entry = info.get("near")
    key = f"{name}/near_base"
    if entry is None and key not in archive.keys:
        return None, None
    try:
        model = Microfacet.from_dict(entry["microfacet"])
    except (KeyError, TypeError, ValueError) as exc:
        raise archive.fail(f"meta 'objects' {name!r}: a near mirror needs 'near': {{\"microfacet\": {{...}}}} "
                           f"({exc})") from None
    if key not in archive.keys:
        raise archive.fail(f"object {name!r} is a near mirror in meta 'objects' but has no '{key}'")
    return archive.array(key, "fiu", (n_v, 3)), model


def _read_probe(archive, name, info, n_v):
    """The object's (Probe, weight (V, 3)) (version 3), or (None, None)."""
    fail = archive.fail
    entry = info.get("probe")
    keys = (f"{name}/probe", f"{name}/probe_weight")
    if entry is None:
        present = [k for k in keys if k in archive.keys]
        if present:
            raise fail(f"'{present[0]}' is present but meta 'objects' gives object {name!r} no 'probe'")
        return None, None
    if not isinstance(entry, dict):
        raise fail(f"meta 'objects': object {name!r}'s 'probe' must be a JSON object")
    size = entry.get("size")
    if isinstance(size, bool) or not isinstance(size, int) or not 1 <= size <= MAX_PROBE_SIZE:
        raise fail(f"meta 'objects': object {name!r}'s probe 'size' must be a whole number from 1 to {MAX_PROBE_SIZE}")
    centre = _finite_numbers(entry.get("centre"), 3)
    box = _finite_numbers(entry.get("box"), 6)
    if centre is None or box is None or not (box[:3] < box[3:]).all():
        raise fail(f"meta 'objects': object {name!r}'s probe needs 'centre' [x, y, z] and 'box' [[lo], [hi]] with lo < hi")
    albedo = _finite_numbers(entry.get("albedo"), ALBEDO_POINTS)
    if albedo is None or (albedo < 0).any():
        raise fail(f"meta 'objects': object {name!r}'s probe needs 'albedo', {ALBEDO_POINTS} numbers >= 0")
    for key in keys:
        if key not in archive.keys:
            raise fail(f"object {name!r} has a 'probe' but no '{key}' array")
    texels = archive.array(keys[0], "fiu", (size, size, 3))
    weight = archive.array(keys[1], "fiu", (n_v, 3))
    for key, a in zip(keys, (texels, weight)):
        if not np.isfinite(a).all():
            raise fail(f"'{key}' has NaN or infinite values")
        if (a < 0).any():
            raise fail(f"'{key}' has a negative value ({float(a.min()):g}); it must not be negative")
    return Probe(np.asarray(texels, np.float32), centre, box.reshape(2, 3), albedo), np.asarray(weight, np.float32)


def load_fit(path):
    """Read and check a ``fit.npz`` (any version of ``READS``); a bad file raises
    InputError with one line naming the file and the key at fault."""
    with open_archive(path, FORMAT, READS) as archive:
        meta, fail = archive.meta, archive.fail
        objects_meta = meta.get("objects")
        if not isinstance(objects_meta, dict):
            raise fail(f"meta 'objects' must be a JSON object of name: info, got {_json_type(objects_meta)}")
        if not objects_meta:
            raise fail("meta 'objects' is empty: the file holds no objects")
        for key, kind, default in (("source", str, ""), ("model", str, ""), ("settings", dict, {})):
            if not isinstance(meta.get(key, default), kind):
                raise fail(f"meta '{key}' must be a JSON {'string' if kind is str else 'object'}, got {_json_type(meta[key])}")
        emitters, nodes = (), DEFAULT_NODES
        if meta["version"] >= 3:
            emitters = file_parts(meta.get("emitters", []), fail, delta=meta["version"] >= 5, own=meta["version"] >= 6)
            nodes = meta.get("emitter_nodes", DEFAULT_NODES)
            if isinstance(nodes, bool) or not isinstance(nodes, int) or not 1 <= nodes <= MAX_NODES:
                raise fail(f"meta 'emitter_nodes' must be a whole number from 1 to {MAX_NODES}, got {nodes!r}")
        objects = []
        for name, info in objects_meta.items():
            if not name or "/" in name:
                raise fail(f"meta 'objects' has an object name {name!r}: names are non-empty and contain no '/'")
            if not isinstance(info, dict):
                raise fail(f"meta 'objects': the info of object {name!r} must be a JSON object, got {_json_type(info)}")
            objects.append(_read_object(archive, name, info, meta["version"], emitters, nodes))
        camera = camera_from_meta(meta, fail)
        environment = read_environment(archive, meta) if meta["version"] >= 4 else None
    return FittedModel(
        objects=tuple(objects), source=meta.get("source", ""), model=meta.get("model", ""),
        settings=meta.get("settings", {}), camera=camera, emitters=emitters, emitter_nodes=nodes,
        environment=environment,
    )


def _json_type(value):
    """What a JSON value is, for messages: 'a list', 'a string', 'null', ..."""
    names = {dict: "an object", list: "a list", str: "a string", bool: "a boolean", int: "a number", float: "a number"}
    return "null" if value is None else names.get(type(value), type(value).__name__)


def _is_number(value):
    return isinstance(value, (int, float)) and not isinstance(value, bool)
