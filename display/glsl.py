"""The shaders' files (``display/shaders/*.glsl``), shared by the renderer, the window
and the web page, and what is prepended to them at compile time.

Every GLSL function is defined once, in one file; a file names the files it needs with
``#include "name.glsl"`` lines, which ``resolve`` (here) and ``walkthrough.js`` (on the
page, from the copies ``vlights export`` writes) replace by the file's text, each file
once. A stage is compiled as a header (``DESKTOP``: ``#version 330``; on the page
``es_header.glsl`` after three.js's ``#version 300 es``), then ``defines``, then the
stage's file resolved. What varies with the model or a switch is a ``#define`` there,
never code written from Python:

    VL_TEXTURE_WIDTH          the width of the renderer's float textures (value i at texel
                              (i % width, i / width))
    VL_ALBEDO_POINTS          fitting.probe.ALBEDO_POINTS
    VL_CULL, VL_MAX_POLYGON_VERTICES    radiosity.physics.emitters' constants
    VL_SPHERE_NODES, VL_SPHERE_S, VL_SPHERE_W, VL_SECTOR_NODES, VL_SECTOR_S, VL_SECTOR_W
                              the emitter quadrature of N nodes (``rules(N)``)
    VL_LTC_ALPHA_MIN, VL_LTC_SPHERE_SIDES, VL_LTC_SPHERE_SCALE, VL_LTC_CULL, VL_LTC_MAX_RATIO
                              radiosity.physics.ltc's constants (ltc.glsl)
    VL_NO_LIGHTS, VL_NO_PROBE, VL_NO_EMITTERS    the parts of the model left out
    VL_TRIANGLE, VL_GOURAUD, VL_OUT, VL_ATTRIBUTES    variants of a stage (the files say which)
    VL_REVERSED_Z             the depth convention is reversed Z (the background's far plane
                              at depth 0: ``display.renderer.Depth``)

The emitters' table (``emitter_table``) is laid out here too, for the renderer and the
glTF export.
"""

from __future__ import annotations

import re
from functools import cache
from pathlib import Path

import numpy as np

from fitting.options import PARTS
from fitting.probe import ALBEDO_POINTS
from radiosity.physics import ltc
from radiosity.physics.emitters import CULL, DEFAULT_NODES, MAX_POLYGON_VERTICES, PackedParts, rules

SHADERS = Path(__file__).with_name("shaders")
DESKTOP = "#version 330\n"  # the header of the renderer's and the window's stages
ES_HEADER = "es_header.glsl"  # the page's, after three.js's "#version 300 es"
FLOAT_TEXTURE_WIDTH = 4096
TABLE_WIDTH = 3 + MAX_POLYGON_VERTICES
INCLUDE = re.compile(r'^#include "([^"]+)"[ \t]*$', re.M)


def shader_files():
    """The shaders' file names (sorted): what ``vlights export`` copies beside the page."""
    return sorted(p.name for p in SHADERS.glob("*.glsl"))


@cache
def read(name):
    """The text of ``display/shaders/name``."""
    return (SHADERS / name).read_text()


def resolve(name, seen=None):
    """``name``'s text with each ``#include "file"`` line replaced by that file's text,
    resolved in turn; a file already included gives nothing (as walkthrough.js does)."""
    seen = set() if seen is None else seen
    if name in seen:
        return ""
    seen.add(name)
    return INCLUDE.sub(lambda m: resolve(m.group(1), seen), read(name))


def _floats(values):
    return ", ".join(repr(float(v)) for v in values)


def defines(nodes=DEFAULT_NODES, parts=PARTS, extra=()):
    """The ``#define`` lines prepended to every stage: the constants, the emitter
    quadrature of ``nodes``, ``VL_NO_*`` for each part of PARTS not in ``parts``, and
    the names in ``extra`` (``VL_TRIANGLE``, ...)."""
    sphere_s, sphere_w, sector_s, sector_w = rules(nodes)
    values = {
        "VL_TEXTURE_WIDTH": FLOAT_TEXTURE_WIDTH,
        "VL_ALBEDO_POINTS": ALBEDO_POINTS,
        "VL_CULL": repr(float(CULL)),
        "VL_MAX_POLYGON_VERTICES": MAX_POLYGON_VERTICES,
        "VL_SPHERE_NODES": len(sphere_s),
        "VL_SPHERE_S": _floats(sphere_s),
        "VL_SPHERE_W": _floats(sphere_w),
        "VL_SECTOR_NODES": len(sector_s),
        "VL_SECTOR_S": _floats(sector_s),
        "VL_SECTOR_W": _floats(sector_w),
        "VL_LTC_ALPHA_MIN": repr(float(ltc.ALPHA_MIN)),
        "VL_LTC_SPHERE_SIDES": ltc.SPHERE_SIDES,
        "VL_LTC_SPHERE_SCALE": repr(float(ltc.SPHERE_SCALE)),
        "VL_LTC_CULL": repr(float(ltc.CULL)),
        "VL_LTC_MAX_RATIO": repr(float(ltc.MAX_RATIO)),
    }
    lines = [f"#define {k} {v}\n" for k, v in values.items()]
    lines += [f"#define VL_NO_{p.upper()}\n" for p in PARTS if p not in parts]
    lines += [f"#define {name}\n" for name in extra]
    return "".join(lines)


def stage(name, nodes=DEFAULT_NODES, parts=PARTS, extra=()):
    """The desktop source (GLSL 3.30) of the stage in file ``name``."""
    return DESKTOP + defines(nodes, parts, extra) + resolve(name)


def shade_glsl(nodes=DEFAULT_NODES, parts=PARTS):
    """The whole shading formula (``shade.glsl`` resolved, after its ``defines``) with
    no header: GLSL 3.30 and GLSL ES 3.00 alike."""
    return defines(nodes, parts) + resolve("shade.glsl")


def emitter_table(parts):
    """(P, TABLE_WIDTH, 4) float32: the ``emitter_table`` texture's texels (at least one row)."""
    packed = parts if isinstance(parts, PackedParts) else PackedParts(parts)
    p = len(packed)
    table = np.zeros((max(p, 1), TABLE_WIDTH, 4), np.float32)
    table[:p, 0, 0] = packed.kinds
    table[:p, 0, 1] = packed.counts
    table[:p, 0, 2] = packed.radius
    table[:p, 1, :3] = packed.radiance
    table[:p, 2, :3] = packed.bound_centre
    table[:p, 2, 3] = packed.bound_radius
    table[:p, 3:, :3] = packed.points
    return table


