"""Reader and writer of the solution file (docs/formats.md).

``solution.npz`` is written with ``numpy.savez_compressed`` and readable with
``allow_pickle=False``. Keys:

- ``meta``: 0-d str array holding JSON ``{"format": "vlights.solution", "version": 1,
  "objects": [names], "materials": {name: {"diffuse": [r,g,b], "specular": [r,g,b],
  "exponent": n, "emission": [r,g,b]}}, "settings": {...}, "stats": {...},
  "scene": "..."}``;
- per object ``<name>/positions`` (V, 3) float32, ``<name>/normals`` (V, 3) float32,
  ``<name>/tangents`` (V, 3) float32, ``<name>/faces`` (F, 3) int32,
  ``<name>/directions`` (D, 3) float32 (local frame: x tangent, y bitangent =
  cross(normal, tangent), z normal) and ``<name>/radiance`` (V, D, 3) float32, the
  outgoing radiance at each vertex in each direction, emission included.

Version 2 adds the emitters whose highlights are in closed form (``meta.emitters``,
``meta.emitter_nodes``, ``<name>/visibility``). Version 3 adds textured objects
(``radiosity.physics.textures``): ``<name>/uvs``, ``<name>/irradiance`` and
``<name>/texture``, and such an object's ``radiance`` then holds everything but its
textured diffuse term kd * texture(uv) / pi * E. A file is written with the lowest
version that holds it (2 without a textured object), so tools that read version 2
keep reading every untextured solution. Version 3 also adds the light from outside the
scene (``radiosity.physics.environment``): ``meta.environment`` and the array
``environment_image``; the radiance then includes what it lights, and a display draws
it where no object is. Version 4 adds delta lights (points, spots, directions):
``meta.lights`` lists them all (``radiosity.physics.emitters`` parts of kind "point" and
"direction": what lit the scene, which ``vlights truth`` path-traces), and
``meta.emitters`` may hold them as parts; a file without any is still version 3 or 2.
Version 5 adds emitter parts per object: a glossy object's ``<name>/emitter_parts``
(P_o,) int32 names the parts of ``meta.emitters`` (indices) whose highlights it holds
in closed form, its ``visibility`` then (V, P_o); ``meta.emitters`` may then hold up to
``MAX_SCENE_PARTS`` parts. An object without it has every part (versions 2 to 4).
Version 6 adds microfacet materials: a material's ``"microfacet"`` entry
(``radiosity.physics.materials.Microfacet.to_dict``: kind, distribution, alpha, eta, k,
specular_reflectance, diffuse_reflectance, nonlinear) is the model ``vlights truth``
path-traces; its Phong fields stay the stand-in the other stages draw, so a reader of
version 5 that ignores the key reads the same Phong material as before.
Version 7 adds glass: a material's ``"glass"`` entry
(``radiosity.physics.materials.Glass.to_dict``: kind dielectric, thindielectric or
roughdielectric, eta, distribution, alpha, specular_reflectance, specular_transmittance)
is an interface ``vlights truth`` traces through (reflecting and refracting); its Phong
fields are zero and its object diffuse with zero radiance (nothing of its appearance is
stored per vertex: a reader of version 6 that ignores the key sees a black object, and
should draw nothing where the key is; the displays leave glass objects out).
Version 8 adds ``meta.microfacet_highlights`` (true): a microfacet object's closed-form
highlights (its ``emitter_parts`` and ``visibility``: every part it sees, area and
delta) are its own lobe's (``radiosity.physics.ltc``: GGX or Beckmann by linearly
transformed cosines, Schlick's curve through the exact normal reflectance), and its
grid holds them so, the rest gathered without them. In versions 6 and 7 its closed-form
highlights were the delta parts' alone, of its Phong stand-in's lobe (the area
emitters' light gathered into the grid); they are read so.

Diffuse objects have D = 1, direction (0, 0, 1); glossy ones the n x n equal-area grid
of ``radiosity.physics.directions`` (D = n * n, row d = j * n + i).

``Solution.save`` writes atomically (``radiosity.files.atomic``). ``Solution.load`` /
``load_solution`` validate everything a reader relies on and refuse a bad file with a
one-line ``InputError``. Constructing an ``ObjectSolution`` or ``Solution`` in code
applies the same checks but raises ``ValueError`` (a bug, not a user error).
"""

from __future__ import annotations

import functools
import math
import os
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from radiosity.files.camera import Camera, camera_from_meta
from radiosity.files.errors import InputError
from radiosity.files.npz import check_member_name, open_archive, write_archive
from radiosity.physics.directions import grid_directions
from radiosity.physics.emitters import (
    DEFAULT_NODES,
    DELTA_KINDS,
    MAX_FILE_PARTS,
    MAX_LIGHTS,
    MAX_NODES,
    MAX_SCENE_PARTS,
    EmitterPart,
    emitter_grid,
    file_parts,
    parts_from_meta,
)
from radiosity.physics.environment import IMAGE_KEY, EnvironmentLight, read_environment
from radiosity.physics.materials import Material
from radiosity.physics.textures import TexturedDiffuse, read_textured

__all__ = ["FORMAT", "VERSION", "ObjectSolution", "Solution", "load_solution"]

FORMAT = "vlights.solution"
VERSION = 9  # the newest version written (a file is written with the lowest that holds it)
READS = (1, 2, 3, 4, 5, 6, 7, 8, 9)

ARRAY_KEYS = ("positions", "normals", "tangents", "faces", "directions", "radiance")
_MATERIAL_KEYS = ("diffuse", "specular", "exponent", "emission")
_OPTIONAL_MATERIAL_KEYS = ("fresnel", "microfacet", "glass")  # Schlick's F0; a microfacet model (6); glass (7)
_UNIT_TOLERANCE = 1e-4  # |direction| within this of 1
_FRAME_TOLERANCE = 1e-3  # a normal's or tangent's length may differ from 1 by this (float32 files hold 1e-7)
_GRID_TOLERANCE = 1e-5  # stored directions within this of the contract's grid


class _Invalid(ValueError):
    """A problem with one object's data; load turns it into an InputError."""


def _shape(a: np.ndarray) -> str:
    return "(" + ", ".join(str(s) for s in a.shape) + ")"


def _as_array(name: str, key: str, value: Any, dtype: type, kinds: str) -> np.ndarray:
    """``value`` as a C-contiguous array of ``dtype``; its kind must be one of ``kinds``."""
    a = np.asarray(value)
    if a.dtype.kind not in kinds:
        expected = "integers" if kinds == "iu" else "numbers"
        raise _Invalid(f"'{name}/{key}' has dtype {a.dtype}, expected {expected}")
    return np.ascontiguousarray(a, dtype=dtype)


def _check_name(name: Any) -> str:
    if not isinstance(name, str) or not name:
        raise _Invalid(f"object name must be a non-empty string, got {name!r}")
    if "/" in name:
        raise _Invalid(f"object name {name!r} contains '/', which the file's keys use as separator")
    try:
        check_member_name(name)
    except ValueError as exc:
        raise _Invalid(f"object name {name!r}: {exc}") from None
    return name


def _material_dict(name: str, material: Any) -> dict:
    """The contract's material dict, validated through ``Material``; raises _Invalid."""
    if isinstance(material, Material):
        return material.to_dict()
    if not isinstance(material, dict):
        raise _Invalid(f"material must be a dict, got {type(material).__name__}")
    missing = [k for k in _MATERIAL_KEYS if k not in material]
    if missing:
        raise _Invalid(f"material has no {', '.join(repr(k) for k in missing)}")
    try:
        optional = {k: material[k] for k in _OPTIONAL_MATERIAL_KEYS if k in material}
        return Material(name, **{k: material[k] for k in _MATERIAL_KEYS}, **optional).to_dict()
    except InputError as exc:
        raise _Invalid(str(exc)) from None


@dataclass(frozen=True, eq=False, repr=False)
class ObjectSolution:
    """One object of a solution: its solver mesh and outgoing radiance.

    Attributes (arrays are converted on construction to C-contiguous arrays of the
    contract's dtypes; arrays already in that form are kept, not copied):
        name: the object's name: non-empty, no '/'.
        positions: (V, 3) float32 world-space vertex positions.
        normals: (V, 3) float32 unit shading normals.
        tangents: (V, 3) float32 unit tangents, orthogonal to the normals.
        faces: (F, 3) int32 triangles (counter-clockwise seen from the front),
            indices in [0, V).
        directions: (D, 3) float32 local outgoing directions: (0, 0, 1) alone for a
            diffuse object, else ``grid_directions(n)`` with D = n * n.
        radiance: (V, D, 3) float32 finite, non-negative outgoing radiance, emission
            included (a textured object's: all but its textured diffuse term).
        material: {"diffuse": [r, g, b], "specular": [r, g, b], "exponent": n,
            "emission": [r, g, b]} (a ``radiosity.scene.material_kernels.Material`` is accepted
            and converted).
        visibility: (V, P) float32 in [0, 1] (version 2): how much of each emitter part
            with a closed-form highlight each vertex of a glossy object sees.
        textured: a ``TexturedDiffuse`` of V vertices (version 3), or None.
        emitter_parts: (P,) int32 (version 5): the indices in the solution's
            ``emitters`` of the parts whose highlights this glossy object holds in
            closed form, in the order of ``visibility``'s columns, distinct, at most
            ``MAX_FILE_PARTS``; None: every part of the solution.

    Raises ValueError if a shape, dtype kind, face index, direction or radiance value
    (NaN, infinite or negative) breaks the contract.
    """

    name: str
    positions: np.ndarray
    normals: np.ndarray
    tangents: np.ndarray
    faces: np.ndarray
    directions: np.ndarray
    radiance: np.ndarray
    material: dict = field(default_factory=dict)
    visibility: np.ndarray | None = None
    textured: TexturedDiffuse | None = None
    emitter_parts: np.ndarray | None = None

    @functools.cached_property
    def material_record(self) -> Material:
        """The object's material as the validated record (``Material``): what every
        stage reads of it; ``material`` is the file's dict."""
        return Material(self.name, **self.material)

    def __post_init__(self) -> None:
        name = _check_name(self.name)
        try:
            self._validate(name)
        except _Invalid as exc:
            raise _Invalid(f"object {name!r}: {exc}") from None

    def _validate(self, name: str) -> None:
        put = object.__setattr__
        floats, ints = "fiu", "iu"
        for key in ("positions", "normals", "tangents"):
            put(self, key, _as_array(name, key, getattr(self, key), np.float32, floats))
        given_faces = np.asarray(self.faces)  # its range is checked before the int32 cast could wrap it
        put(self, "faces", _as_array(name, "faces", self.faces, np.int32, ints))
        put(self, "directions", _as_array(name, "directions", self.directions, np.float32, floats))
        put(self, "radiance", _as_array(name, "radiance", self.radiance, np.float32, floats))

        p = self.positions
        if p.ndim != 2 or p.shape[1] != 3:
            raise _Invalid(f"'{name}/positions' has shape {_shape(p)}, expected (V, 3)")
        v = p.shape[0]
        for key in ("normals", "tangents"):
            a = getattr(self, key)
            if a.shape != (v, 3):
                raise _Invalid(f"'{name}/{key}' has shape {_shape(a)}, expected (V, 3) = ({v}, 3)")
        f = self.faces
        if f.ndim != 2 or f.shape[1] != 3:
            raise _Invalid(f"'{name}/faces' has shape {_shape(f)}, expected (F, 3)")
        d = self.directions
        if d.ndim != 2 or d.shape[1] != 3 or d.shape[0] < 1:
            raise _Invalid(
                f"'{name}/directions' has shape {_shape(d)}, expected (D, 3) with D >= 1"
            )
        nd = d.shape[0]
        r = self.radiance
        if r.shape != (v, nd, 3):
            raise _Invalid(
                f"'{name}/radiance' has shape {_shape(r)}, expected (V, D, 3) = ({v}, {nd}, 3)"
            )

        for key in ("positions", "normals", "tangents"):
            if not np.isfinite(getattr(self, key)).all():
                raise _Invalid(f"'{name}/{key}' contains NaN or infinite values")
        for key in ("normals", "tangents"):  # a zero one has no frame: every shading formula divides by it
            length = np.linalg.norm(getattr(self, key).astype(np.float64), axis=1)
            bad = np.abs(length - 1.0) > _FRAME_TOLERANCE
            if bad.any():
                i = int(np.argmax(bad))
                raise _Invalid(f"'{name}/{key}' has a vector of length {length[i]:.6g} at vertex {i}: "
                               f"{key} must be unit vectors")
        if f.shape[0] == 0:
            raise _Invalid(f"'{name}/faces' is empty: object '{name}' has no faces")
        low, high = int(given_faces.min()), int(given_faces.max())
        if low < 0 or high >= v:
            raise _Invalid(f"'{name}/faces' has vertex indices from {low} to {high}, outside [0, {v})")
        length = np.linalg.norm(d.astype(np.float64), axis=1)
        if not (np.abs(length - 1.0) <= _UNIT_TOLERANCE).all():
            off = np.abs(length - 1.0)
            worst = float(np.nanmax(off)) if np.isfinite(off).any() else math.nan
            raise _Invalid(
                f"'{name}/directions' are not unit vectors (length off by up to {worst:.3g})"
            )
        n = math.isqrt(nd)
        if n * n != nd:
            raise _Invalid(f"'{name}/directions' has D = {nd}, not a square n * n of the grid")
        if np.abs(d - grid_directions(n)).max() > _GRID_TOLERANCE:
            what = "(0, 0, 1)" if n == 1 else f"the {n} x {n} equal-area grid of the contract"
            raise _Invalid(f"'{name}/directions' are not {what}")
        if not np.isfinite(r).all():
            bad = int(np.count_nonzero(~np.isfinite(r)))
            raise _Invalid(f"'{name}/radiance' has {bad} NaN or infinite values")
        negative = r < 0.0
        if negative.any():
            raise _Invalid(
                f"'{name}/radiance' has {int(np.count_nonzero(negative))} negative values "
                f"(down to {float(r.min()):.3g}); radiance is never negative"
            )

        put(self, "material", _material_dict(name, self.material))
        if self.visibility is not None:
            vis = _as_array(name, "visibility", self.visibility, np.float32, floats)
            if vis.ndim != 2 or vis.shape[0] != v:
                raise _Invalid(f"'{name}/visibility' has shape {_shape(vis)}, expected (V, P) = ({v}, P)")
            if not (np.isfinite(vis).all() and (vis >= 0).all() and (vis <= 1).all()):
                raise _Invalid(f"'{name}/visibility' has values outside [0, 1]")
            if self.is_diffuse:
                raise _Invalid(f"'{name}/visibility': a diffuse object has none (its emitters' highlights are diffuse)")
            put(self, "visibility", vis)
        if self.emitter_parts is not None:
            given = np.asarray(self.emitter_parts)
            if given.ndim != 1 or given.dtype.kind not in "iu":
                raise _Invalid(f"'{name}/emitter_parts' must be a list of whole numbers (P,), got {_shape(given)} "
                               f"{given.dtype}")
            if self.is_diffuse or self.visibility is None:
                raise _Invalid(f"'{name}/emitter_parts': only a glossy object with a visibility names its parts")
            if len(given) != self.visibility.shape[1]:
                raise _Invalid(f"'{name}/emitter_parts' names {len(given)} parts, its visibility has "
                               f"{self.visibility.shape[1]}")
            if len(given) > MAX_FILE_PARTS:
                raise _Invalid(f"'{name}/emitter_parts' names {len(given)} parts; an object draws at most "
                               f"{MAX_FILE_PARTS}")
            if len(given) and (int(given.min()) < 0 or int(given.max()) >= MAX_SCENE_PARTS):
                raise _Invalid(f"'{name}/emitter_parts' has an index outside [0, {MAX_SCENE_PARTS})")
            if len(np.unique(given)) != len(given):
                raise _Invalid(f"'{name}/emitter_parts' names a part twice")
            put(self, "emitter_parts", given.astype(np.int32))
        if self.textured is not None:
            if not isinstance(self.textured, TexturedDiffuse):
                raise _Invalid(f"textured must be a TexturedDiffuse, got {type(self.textured).__name__}")
            if self.textured.n_vertices != v:
                raise _Invalid(f"'{name}/uvs' has {self.textured.n_vertices} rows, expected V = {v}")

    def __repr__(self) -> str:
        return (
            f"ObjectSolution(name={self.name!r}, V={self.num_vertices}, F={self.faces.shape[0]}, "
            f"D={self.directions.shape[0]})"
        )

    @property
    def num_vertices(self) -> int:
        """V."""
        return self.positions.shape[0]

    @property
    def is_diffuse(self) -> bool:
        """True if D == 1 (radiance stored only for the normal direction)."""
        return self.directions.shape[0] == 1

    @property
    def grid_n(self) -> int:
        """n of the n x n direction grid for a glossy object, 0 for a diffuse one."""
        return 0 if self.is_diffuse else math.isqrt(self.directions.shape[0])

    @property
    def bitangents(self) -> np.ndarray:
        """cross(normal, tangent), (V, 3) float32: the local frame's y axis."""
        return np.cross(self.normals, self.tangents).astype(np.float32, copy=False)

    def arrays(self) -> dict[str, np.ndarray]:
        """The arrays keyed as in the file (``<name>/positions``, ...; ``visibility``
        where the object has it)."""
        out = {f"{self.name}/{key}": getattr(self, key) for key in ARRAY_KEYS}
        if self.visibility is not None:
            out[f"{self.name}/visibility"] = self.visibility
        if self.emitter_parts is not None:
            out[f"{self.name}/emitter_parts"] = self.emitter_parts
        if self.textured is not None:
            out.update(self.textured.arrays(self.name))
        return out

    def diffuse_radiance(self, vertices=slice(None), weights=None):
        """The textured diffuse term (..., 3) float64 that ``radiance`` leaves out, at
        vertices or points (``TexturedDiffuse.radiance``); zeros for an untextured
        object."""
        if self.textured is None:
            shape = np.shape(np.arange(self.num_vertices)[vertices]) if weights is None else np.shape(weights)[:-1]
            return np.zeros(tuple(shape) + (3,))
        return self.textured.radiance(vertices, weights)


@dataclass(frozen=True, eq=False)
class Solution:
    """A whole solution: objects in order, plus the run's settings, stats and scene.

    Attributes:
        objects: tuple of ``ObjectSolution``, unique names.
        settings: JSON-ready dict of the solver settings.
        stats: JSON-ready dict; at least photons traced, rays cast, wall time per
            phase, seed, thread count, quality preset (contract; not enforced here).
        scene: what the scene was (path or built-in name).
        camera: the scene's default camera, if it has one (``meta.camera``, optional:
            the displays' default view).
        emitters: the emitter parts whose direct glossy highlights are in closed form
            (``radiosity.physics.emitters``, version 2): every glossy object's radiance
            holds them evaluated with ``emitter_nodes`` and its ``visibility``, so that a
            display can subtract them on the grid and draw them per pixel. Empty: none
            (every version 1 file).
            A glossy object that names its ``emitter_parts`` (version 5) holds those alone.
        emitter_nodes: N of the rules they were evaluated with.
        environment: the light from outside the scene (version 3), or None.
        lights: the scene's delta lights (version 4): every point (spot) and direction
            that lit it, whether or not ``emitters`` holds it as a part.
        microfacet_highlights: a microfacet object's closed-form highlights are its own
            lobe's (version 8), not its Phong stand-in's.
    """

    objects: tuple[ObjectSolution, ...]
    settings: dict = field(default_factory=dict)
    stats: dict = field(default_factory=dict)
    scene: str = ""
    camera: Camera | None = None
    emitters: tuple[EmitterPart, ...] = ()
    emitter_nodes: int = DEFAULT_NODES
    environment: EnvironmentLight | None = None
    lights: tuple[EmitterPart, ...] = ()
    microfacet_highlights: bool = False

    def __post_init__(self) -> None:
        objects = tuple(self.objects)
        if self.environment is not None and not isinstance(self.environment, EnvironmentLight):
            raise TypeError(f"environment must be an EnvironmentLight, got {type(self.environment).__name__}")
        for o in objects:
            if not isinstance(o, ObjectSolution):
                raise TypeError(f"objects must be ObjectSolution, got {type(o).__name__}")
        names = [o.name for o in objects]
        dupes = sorted({n for n in names if names.count(n) > 1})
        if dupes:
            raise ValueError(f"duplicate object names: {', '.join(map(repr, dupes))}")
        for key in ("settings", "stats"):
            if not isinstance(getattr(self, key), dict):
                raise TypeError(f"{key} must be a dict, got {type(getattr(self, key)).__name__}")
        if not isinstance(self.scene, str):
            raise TypeError(f"scene must be a string, got {type(self.scene).__name__}")
        object.__setattr__(self, "objects", objects)
        object.__setattr__(self, "emitters", tuple(self.emitters))
        object.__setattr__(self, "lights", tuple(self.lights))
        if not all(isinstance(light, EmitterPart) and light.is_delta for light in self.lights):
            raise ValueError("lights must be delta emitter parts (points, directions)")
        if not isinstance(self.microfacet_highlights, bool):
            raise TypeError(f"microfacet_highlights must be a bool, got {type(self.microfacet_highlights).__name__}")
        if not (isinstance(self.emitter_nodes, int) and 1 <= self.emitter_nodes <= MAX_NODES):
            raise ValueError(f"emitter_nodes must be a whole number from 1 to {MAX_NODES}, got {self.emitter_nodes!r}")
        if len(self.emitters) > MAX_SCENE_PARTS:
            raise _Invalid(f"{len(self.emitters)} emitter parts; a solution holds at most {MAX_SCENE_PARTS}")
        for o in objects:
            parts = 0 if o.visibility is None else o.visibility.shape[1]
            if o.emitter_parts is not None:
                if len(o.emitter_parts) and int(o.emitter_parts.max()) >= len(self.emitters):
                    raise _Invalid(f"object {o.name!r}: its emitter_parts name part {int(o.emitter_parts.max())}; "
                                   f"there are {len(self.emitters)}")
                continue
            if not o.is_diffuse and self.emitters and parts != len(self.emitters):
                raise _Invalid(
                    f"object {o.name!r}: a glossy object needs a visibility of each of the {len(self.emitters)} emitter "
                    f"parts, has {parts}"
                )
            if not o.is_diffuse and len(self.emitters) > MAX_FILE_PARTS:
                raise _Invalid(f"object {o.name!r}: of {len(self.emitters)} emitter parts a glossy object names its "
                               f"own (emitter_parts, at most {MAX_FILE_PARTS})")
            if not self.emitters and o.visibility is not None and o.visibility.shape[1]:
                raise _Invalid(f"object {o.name!r} has a visibility of {o.visibility.shape[1]} parts; there are none")

    @property
    def version(self) -> int:
        """The lowest contract version that holds this solution: 9 where a textured
        object has an opacity mask, else 8 where a microfacet
        object's highlights are its own lobe's, else 7 where a material is glass or a perfect mirror,
        else 6 where a material has a microfacet model, else 5 where an object names its emitter parts, else 4 with a
        delta light, else 3 with a textured object or an environment, else 2."""
        if any(o.textured is not None and o.textured.opacity is not None for o in self.objects):
            return 9
        microfacet = any(o.material_record.microfacet is not None for o in self.objects)
        if microfacet and self.microfacet_highlights:
            return 8
        if any(o.material_record.is_glass or o.material_record.is_mirror for o in self.objects):
            return 7
        if microfacet:
            return 6
        if any(o.emitter_parts is not None for o in self.objects):
            return 5
        if self.lights or any(p.is_delta for p in self.emitters):
            return 4
        return 3 if self.environment is not None or any(o.textured is not None for o in self.objects) else 2

    @property
    def names(self) -> tuple[str, ...]:
        """Object names, in file order."""
        return tuple(o.name for o in self.objects)

    def object(self, name: str) -> ObjectSolution:
        """The object called ``name``; KeyError listing the names if there is none."""
        for o in self.objects:
            if o.name == name:
                return o
        raise KeyError(f"no object {name!r} in the solution (objects: {', '.join(self.names)})")

    def meta(self) -> dict:
        """The ``meta`` JSON of the file, as a dict."""
        return {
            "format": FORMAT,
            "version": self.version,
            "objects": list(self.names),
            "materials": {o.name: o.material for o in self.objects},
            "settings": self.settings,
            "stats": self.stats,
            "scene": self.scene,
            "emitters": [p.to_dict() for p in self.emitters],
            "emitter_nodes": self.emitter_nodes,
            **({"camera": self.camera.to_dict()} if self.camera is not None else {}),
            **({"environment": self.environment.meta()} if self.environment is not None else {}),
            **({"lights": [light.to_dict() for light in self.lights]} if self.lights else {}),
            **({"microfacet_highlights": True} if self.microfacet_highlights and self.version >= 8 else {}),
        }

    def parts_of(self, name: str) -> tuple[EmitterPart, ...]:
        """The emitter parts whose highlights object ``name`` holds in closed form (its
        ``emitter_parts``, else every part), in the order of its visibility's columns."""
        o = self.object(name)
        if o.emitter_parts is None:
            return self.emitters
        return tuple(self.emitters[i] for i in o.emitter_parts)

    def highlights(self, name: str, vertices: slice = slice(None)) -> np.ndarray:
        """The closed-form emitter highlights (V, D, 3) float64 held in object ``name``'s
        radiance on its grid (zeros where there are none: diffuse objects, version 1);
        of the ``vertices`` alone (a slice) if given, so that a large grid can be read a
        chunk of vertices at a time."""
        o = self.object(name)
        parts = self.parts_of(name)
        if o.is_diffuse or not parts:
            return np.zeros(o.radiance[vertices].shape)
        m = o.material_record
        visibility = None if o.visibility is None else o.visibility[vertices]
        return emitter_grid(
            parts, o.positions[vertices], o.normals[vertices], o.tangents[vertices], o.directions,
            m.specular, m.exponent, visibility=visibility, nodes=self.emitter_nodes, source=name,
            fresnel=m.fresnel, microfacet=self.lobe_of(name),
        )

    def lobe_of(self, name: str) -> dict | None:
        """The microfacet model (a ``Microfacet.to_dict``) whose own lobe draws object
        ``name``'s closed-form highlights (version 8), or None: its Phong lobe's."""
        m = self.object(name).material
        return m.get("microfacet") if self.microfacet_highlights and isinstance(m, dict) else None

    def save(self, path: str | os.PathLike) -> None:
        """Write the contract's npz to ``path`` atomically (all or nothing).

        Raises ValueError for an object name containing '/' or a NaN or infinity in
        settings or stats, TypeError if they hold something JSON cannot represent
        (numpy scalars, arrays and paths are converted), OSError if the file cannot be
        written; in every case ``path`` keeps its previous content and no temporary
        file is left behind.
        """
        for o in self.objects:
            _check_name(o.name)
        arrays = {}
        for o in self.objects:
            arrays.update(o.arrays())
        if self.environment is not None:
            arrays[IMAGE_KEY] = self.environment.image
        write_archive(path, self.meta(), arrays)

    @classmethod
    def load(cls, path: str | os.PathLike) -> Solution:
        """Read and validate a solution file; InputError (one line) if it is not valid."""
        with SolutionFile(path) as f:
            return f.load()


def load_solution(path: str | os.PathLike) -> Solution:
    """Read and validate a solution file; same as ``Solution.load``."""
    return Solution.load(path)


class SolutionFile:
    """A solution file read an object at a time, for stages whose memory must not grow
    with the whole solution (the fit of a large scene).

    Opening reads and validates the meta (and the environment); ``object(name)`` reads
    and validates one object as ``load_solution`` would; ``alone(name)`` is a
    ``Solution`` of that object with the file's emitters, camera and environment (what
    ``Solution.highlights`` needs); ``geometry(name)`` reads only its positions and
    faces. ``load()`` is the whole ``Solution``. A context manager: the archive is
    closed on leaving."""

    def __init__(self, path: str | os.PathLike):
        self.path = os.fspath(path)
        self._archive = open_archive(path, FORMAT, READS)
        try:
            self._header = _read_header(self._archive)
        except BaseException:
            self._archive.close()
            raise
        h = self._header
        self.names: tuple[str, ...] = tuple(h["names"])
        self.materials: dict = h["materials"]
        self.settings, self.stats, self.scene = h["settings"], h["stats"], h["scene"]
        self.camera, self.emitters, self.emitter_nodes = h["camera"], h["emitters"], h["nodes"]
        self.environment, self.lights = h["environment"], h["lights"]
        self.version: int = self._archive.meta["version"]

    def __enter__(self) -> SolutionFile:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def close(self) -> None:
        self._archive.close()

    def object(self, name: str) -> ObjectSolution:
        """Object ``name``, read and validated; InputError (one line) if it is not valid."""
        return _read_object(self._archive, name, self._header)

    def validate(self) -> None:
        """Read and validate every object, one at a time, keeping none: a bad file is
        refused (InputError, one line) before any work is said or done (4.4 s for the
        335 MB of arrays of a million-triangle interior)."""
        for name in self.names:
            self.object(name)

    def alone(self, name: str) -> Solution:
        """A ``Solution`` of object ``name`` alone, with the file's emitters, nodes,
        camera, environment, settings and scene."""
        return self._solution((self.object(name),))

    def textured(self, name: str) -> TexturedDiffuse | None:
        """Object ``name``'s ``TexturedDiffuse`` (None: untextured) without its radiance:
        a texture other objects share is the very array theirs is, as ``object`` reads
        it (a fit's worker processes return their objects without it)."""
        diffuse = self.materials[name].get("diffuse") if isinstance(self.materials[name], dict) else None
        if self._archive.meta["version"] < 3 or not (isinstance(diffuse, list) and len(diffuse) == 3):
            return None
        return read_textured(self._archive, name, self.sizes(name)[0], diffuse, masks=self._archive.meta["version"] >= 9)

    def geometry(self, name: str) -> tuple[np.ndarray, np.ndarray]:
        """(positions (V, 3) float32, faces (F, 3) int) of object ``name``, unvalidated:
        ``object`` checks them when the object itself is read."""
        if name not in self.names:
            raise KeyError(f"no object {name!r} in the solution (objects: {', '.join(self.names)})")
        return self._archive.array(f"{name}/positions"), self._archive.array(f"{name}/faces")

    def n_directions(self, name: str) -> int:
        """D of object ``name``'s grid (1: diffuse), from its array's header alone."""
        return self._archive.header(f"{name}/radiance")[0][1]

    def sizes(self, name: str) -> tuple[int, int, int]:
        """(V, D, bytes of its positions and faces) of object ``name``, from the arrays'
        headers alone: what a plan of the work needs, before any array is read."""
        (v, _), positions = self._archive.header(f"{name}/positions")
        faces_shape, faces = self._archive.header(f"{name}/faces")
        return v, self.n_directions(name), v * 3 * positions.itemsize + faces_shape[0] * 3 * faces.itemsize

    def load(self) -> Solution:
        """The whole ``Solution``, validated."""
        return self._solution(tuple(self.object(name) for name in self.names))

    def _solution(self, objects) -> Solution:
        h = self._header
        try:
            return Solution(
                objects=objects, settings=h["settings"], stats=h["stats"], scene=h["scene"], camera=h["camera"],
                emitters=h["emitters"], emitter_nodes=h["nodes"], environment=h["environment"],
                lights=h["lights"], microfacet_highlights=h["microfacet_highlights"],
            )
        except _Invalid as exc:
            raise self._archive.fail(str(exc)) from None


def _read_header(archive) -> dict:
    """Everything of a solution file but its objects' arrays, validated."""
    meta = archive.meta
    fail = archive.fail
    names = meta.get("objects")
    if not isinstance(names, list) or not all(isinstance(n, str) for n in names):
        raise fail(f"meta 'objects' must be a list of names, got {names!r}")
    if not names:
        raise fail("meta 'objects' is empty: the file holds no objects")
    if len(set(names)) != len(names):
        raise fail(f"meta 'objects' lists a name twice: {names!r}")
    materials = meta.get("materials")
    if not isinstance(materials, dict):
        raise fail(f"meta 'materials' must be an object of name: material, got {materials!r}")
    settings = meta.get("settings", {})
    stats = meta.get("stats", {})
    scene = meta.get("scene", "")
    for key, value, kind in (("settings", settings, dict), ("stats", stats, dict), ("scene", scene, str)):
        if not isinstance(value, kind):
            kind_name = "object" if kind is dict else "string"
            raise fail(f"meta '{key}' must be a JSON {kind_name}")
    camera = camera_from_meta(meta, fail)
    emitters, nodes, lights = (), DEFAULT_NODES, ()
    if meta["version"] >= 2:
        emitters = file_parts(meta.get("emitters", []), fail, delta=meta["version"] >= 4, own=meta["version"] >= 5)
        nodes = meta.get("emitter_nodes", DEFAULT_NODES)
        if isinstance(nodes, bool) or not isinstance(nodes, int) or not 1 <= nodes <= MAX_NODES:
            raise fail(f"meta 'emitter_nodes' must be a whole number from 1 to {MAX_NODES}, got {nodes!r}")
    environment = read_environment(archive, meta) if meta["version"] >= 3 else None
    if meta["version"] >= 4:
        lights = parts_from_meta(meta.get("lights", []), fail, DELTA_KINDS, "lights", MAX_LIGHTS)
    lobes = meta.get("microfacet_highlights", False) if meta["version"] >= 8 else False
    if not isinstance(lobes, bool):
        raise fail(f"meta 'microfacet_highlights' must be true or false, got {lobes!r}")
    for name in names:
        if name not in materials:
            raise fail(f"object {name!r} has no entry in meta 'materials'")
        missing = [k for k in ARRAY_KEYS if f"{name}/{k}" not in archive.keys]
        if missing:
            raise fail(f"object {name!r} has no '{name}/{missing[0]}' array")
    return {"names": names, "materials": materials, "settings": settings, "stats": stats, "scene": scene,
            "camera": camera, "emitters": emitters, "nodes": nodes, "environment": environment, "lights": lights,
            "microfacet_highlights": lobes}


def _read_object(archive, name, header) -> ObjectSolution:
    """Object ``name`` of a file whose header ``_read_header`` read, validated."""
    meta, fail, materials = archive.meta, archive.fail, header["materials"]
    arrays = {k: archive.array(f"{name}/{k}") for k in ARRAY_KEYS}
    if f"{name}/visibility" in archive.keys:
        arrays["visibility"] = archive.array(f"{name}/visibility")
    if meta["version"] >= 5 and f"{name}/emitter_parts" in archive.keys:
        arrays["emitter_parts"] = archive.array(f"{name}/emitter_parts")
    if meta["version"] >= 3:
        diffuse = materials[name].get("diffuse") if isinstance(materials[name], dict) else None
        if not (isinstance(diffuse, list) and len(diffuse) == 3):
            raise fail(f"object {name!r}: meta 'materials' has no diffuse colour [r, g, b]")
        arrays["textured"] = read_textured(archive, name, arrays["positions"].shape[0], diffuse,
                                           masks=meta["version"] >= 9)
    try:
        return ObjectSolution(name=name, material=materials[name], **arrays)
    except _Invalid as exc:
        raise fail(str(exc)) from None
