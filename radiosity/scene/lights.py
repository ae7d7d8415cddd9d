"""Delta lights as scenes declare them: a point, a spot (a point with Mitsuba 3's cone)
and a directional light (a sun), each a ``radiosity.physics.emitters.EmitterPart`` of
kind "point" or "direction" in ``Scene.lights``.

    point_light, spot_light, directional_light   checked, one InputError line each
    lights_from_toml                             a TOML scene's [[lights]]
    describe                                     what ``vlights scene-info`` says of one

The spot's defaults are Mitsuba 3's (``spot``): ``cutoff_deg`` 20, ``beam_deg`` 3/4 of
the cutoff; its profile is ``radiosity.physics.emitters.spot_falloff``. A directional
light's ``direction`` is the way its light travels (Mitsuba's ``direction``), its
``irradiance`` what a surface facing it receives.
"""

from __future__ import annotations

import numpy as np

from radiosity.files.errors import InputError
from radiosity.physics.emitters import MAX_LIGHTS, EmitterPart, SpotProfile
from radiosity.physics.materials import FLOAT32_MAX

__all__ = ["DEFAULT_CUTOFF_DEG", "TOML_KINDS", "describe", "directional_light", "lights_from_toml", "point_light",
           "spot_light"]

DEFAULT_CUTOFF_DEG = 20.0  # Mitsuba 3's spot
DEFAULT_BEAM_FRACTION = 0.75  # ... its beam width, of the cutoff
TOML_KINDS = ("point", "spot", "directional")
_TOML_KEYS = {
    "point": {"name", "kind", "position", "intensity"},
    "spot": {"name", "kind", "position", "intensity", "direction", "cutoff_deg", "beam_deg"},
    "directional": {"name", "kind", "direction", "irradiance"},
}


def _finite3(value, where, what):
    v = np.asarray(value, np.float64).reshape(-1)
    if v.shape != (3,) or not np.isfinite(v).all():
        raise InputError(f"{where}: {what} must be 3 finite numbers, got {value!r}")
    if np.abs(v).max() > FLOAT32_MAX:
        raise InputError(f"{where}: {what} is beyond the single-precision range (+-{FLOAT32_MAX:.4g})")
    return v


def _colour(value, where, what):
    v = _finite3(np.broadcast_to(np.asarray(value, np.float64), 3) if np.ndim(value) == 0 else value, where, what)
    if (v < 0).any():
        raise InputError(f"{where}: {what} must not be negative, got {tuple(float(c) for c in v)}")
    return v


def _unit(value, where, what):
    v = _finite3(value, where, what)
    length = float(np.linalg.norm(v))
    if not length > 0:
        raise InputError(f"{where}: {what} must not be zero")
    return v / length


def point_light(name, position, intensity, where):
    """A point light at ``position`` of ``intensity`` (W/sr, RGB or a number) every way."""
    return EmitterPart("point", [_finite3(position, where, "the position")], 0.0,
                       _colour(intensity, where, "the intensity"), name)


def spot_light(name, position, axis, intensity, where, cutoff_deg=DEFAULT_CUTOFF_DEG, beam_deg=None):
    """A spot at ``position`` pointing along ``axis``, of peak ``intensity``, with its
    cone's ``cutoff_deg`` and full-intensity ``beam_deg`` (default 3/4 of the cutoff)."""
    cutoff = float(cutoff_deg)
    beam = DEFAULT_BEAM_FRACTION * cutoff if beam_deg is None else float(beam_deg)
    if not (np.isfinite(cutoff) and 0 < cutoff <= 180):
        raise InputError(f"{where}: the cutoff angle must be in (0, 180] degrees, got {cutoff:g}")
    if not (np.isfinite(beam) and 0 <= beam <= cutoff):
        raise InputError(f"{where}: the beam width must be in [0, the cutoff angle {cutoff:g}] degrees, got {beam:g}")
    spot = SpotProfile(_unit(axis, where, "the spot's direction"), cutoff, beam)
    return EmitterPart("point", [_finite3(position, where, "the position")], 0.0,
                       _colour(intensity, where, "the intensity"), name, spot)


def directional_light(name, direction, irradiance, where):
    """A distant light whose light travels along ``direction``, of ``irradiance`` on a
    surface facing it."""
    return EmitterPart("direction", [_unit(direction, where, "the direction")], 0.0,
                       _colour(irradiance, where, "the irradiance"), name)


def lights_from_toml(entries, where, taken=()):
    """The lights of a TOML scene's ``[[lights]]`` array (a list of tables): ``kind``
    "point" (``position``, ``intensity``), "spot" (those, ``direction``, and
    ``cutoff_deg``, ``beam_deg`` optional) or "directional" (``direction``,
    ``irradiance``); ``name`` optional, unique among them and the objects' names
    ``taken`` (default "<kind>_light_<i>"). A number means grey."""
    if not isinstance(entries, list) or not all(isinstance(e, dict) for e in entries):
        raise InputError(f"{where}: 'lights' must be an array of tables ([[lights]])")
    if len(entries) > MAX_LIGHTS:
        raise InputError(f"{where}: {len(entries)} lights; a scene has at most {MAX_LIGHTS}")
    names = set(taken)
    out = []
    for i, entry in enumerate(entries):
        here = f"{where}: [[lights]] {i + 1}"
        kind = entry.get("kind")
        if kind not in TOML_KINDS:
            raise InputError(f"{here}: 'kind' must be one of {', '.join(TOML_KINDS)}, got {kind!r}")
        unknown = sorted(set(entry) - _TOML_KEYS[kind])
        if unknown:
            raise InputError(f"{here}: unknown key {unknown[0]!r} for a {kind} light "
                             f"(known: {', '.join(sorted(_TOML_KEYS[kind]))})")
        name = entry.get("name", f"{kind}_light_{i + 1}")
        if not isinstance(name, str) or not name or "/" in name or any(ord(c) < 32 for c in name):
            raise InputError(f"{here}: 'name' must be a non-empty name without '/' or control characters")
        if name in names:
            raise InputError(f"{here}: the name {name!r} is taken (lights' and objects' names are unique)")
        names.add(name)
        here = f"{where}: light {name!r}"
        missing = sorted(_TOML_KEYS[kind] - {"name", "cutoff_deg", "beam_deg"} - set(entry))
        if missing:
            raise InputError(f"{here}: a {kind} light needs '{missing[0]}'")
        for key in ("cutoff_deg", "beam_deg"):
            if key in entry and (isinstance(entry[key], bool) or not isinstance(entry[key], int | float)):
                raise InputError(f"{here}: '{key}' must be a number, got {entry[key]!r}")
        values = {k: _toml_numbers(entry[k], here, k) for k in ("position", "intensity", "direction", "irradiance")
                  if k in entry}
        if kind == "point":
            out.append(point_light(name, values["position"], values["intensity"], here))
        elif kind == "spot":
            out.append(spot_light(name, values["position"], values["direction"], values["intensity"], here,
                                  entry.get("cutoff_deg", DEFAULT_CUTOFF_DEG), entry.get("beam_deg")))
        else:
            out.append(directional_light(name, values["direction"], values["irradiance"], here))
    return tuple(out)


def _toml_numbers(value, where, key):
    """A TOML number or list of 3 numbers as floats (InputError naming ``key`` otherwise)."""
    items = value if isinstance(value, list) else [value]
    if not (len(items) in (1, 3) and all(isinstance(v, int | float) and not isinstance(v, bool) for v in items)):
        raise InputError(f"{where}: '{key}' must be 3 numbers{' or a number' if key in ('intensity', 'irradiance') else ''}"
                         f", got {value!r}")
    if len(items) == 1 and key in ("position", "direction"):
        raise InputError(f"{where}: '{key}' must be 3 numbers, got {value!r}")
    return items[0] if len(items) == 1 else items


def describe(light, radius):
    """A JSON-ready description of ``light`` (a delta ``EmitterPart``) for scene-info:
    its name, kind ("point", "spot", "directional"), where it is or goes, what it
    emits, its power (a directional light's through the disk of ``radius``, the
    scene's bounding sphere)."""
    rounded = [float(f"{v:.6g}") for v in light.radiance]
    out = {"name": light.source, "kind": "directional" if light.kind == "direction" else
           ("spot" if light.spot is not None else "point")}
    if light.kind == "direction":
        out |= {"direction": [float(f"{v:.6g}") for v in light.points[0]], "irradiance": rounded}
    else:
        out |= {"position": [float(f"{v:.6g}") for v in light.points[0]], "intensity": rounded}
        if light.spot is not None:
            out["spot"] = {"axis": [float(f"{v:.6g}") for v in light.spot.axis],
                           "cutoff_deg": light.spot.cutoff_deg, "beam_deg": light.spot.beam_deg}
    out["power"] = [float(f"{v:.6g}") for v in light.power(radius)]
    return out
