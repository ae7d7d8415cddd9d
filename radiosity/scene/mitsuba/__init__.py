"""Mitsuba XML scenes: the format of the rendering community's test scenes.

``load_mitsuba(path)`` reads a scene written for Mitsuba 0.4-0.6 or 2-3 and returns a
Scene. What it reads, and what it does with it:

Document
    ``<scene version=...>``; ``<default name value>`` and ``$name`` in any attribute;
    ``id`` on any element and ``<ref id>`` to it; ``<include filename>``; property
    names in either spelling (``toWorld`` / ``to_world``, ``intIOR`` / ``int_ior``).
    Values: ``float``, ``integer``, ``boolean``, ``string``, ``rgb``, ``srgb`` (hex or
    numbers, sRGB-decoded), ``spectrum`` (a constant, or wavelength:value pairs turned
    to RGB as Mitsuba 3's RGB modes do: ``spectra``, with a warning), ``point`` /
    ``vector``.
Transforms
    ``matrix`` (16 or 9 numbers, row-major), ``translate``, ``rotate`` (axis and angle
    in degrees), ``scale``, ``lookat``: each applied after the ones before it.
Shapes
    ``obj``, ``ply`` (the file's per-vertex normals kept unless ``face_normals``),
    ``serialized`` (Mitsuba's compressed mesh format, ``shape_index``), and, tessellated
    (``Tessellation`` says how finely): ``rectangle`` ([-1, 1]^2 in z = 0, facing +z),
    ``disk`` (the unit disk, facing +z), ``sphere`` (``center``, ``radius``), ``cube``
    ([-1, 1]^3), ``cylinder`` (``p0``, ``p1``, ``radius``; open ends); ``shapegroup``
    and ``instance``; ``flip_normals``.
Materials (onto Lambert + modified Phong, ``radiosity.scene.microfacet`` measures the
lobes): ``diffuse``; ``twosided`` (the surface gets a back: a second, reversed copy
    a hair behind it, unless the mesh is closed and its inside never seen);
    ``plastic`` / ``roughplastic`` and ``conductor`` / ``roughconductor`` by the rule
    of ``microfacet.phong_lobe_for`` (the rough ones keep their own model beside it);
    ``dielectric``, ``thindielectric`` and ``roughdielectric`` as ``Glass`` (int_ior
    over ext_ior, named indices as Mitsuba's); anything else (masks, bump and normal
    maps, blends, principled, ...) approximated with one warning saying how.
Textures
    A ``bitmap`` as a ``diffuse`` bsdf's ``reflectance`` (also inside ``twosided``,
    ``bumpmap``, ``normalmap`` and ``mask``) or a plastic's ``diffuse_reflectance``
    is the object's diffuse texture, read through the shape's texture coordinates as
    Mitsuba 3 defines them (``_analytic``; obj ``vt``, which Mitsuba flips to its
    top-down v; ply ``u v`` and serialized texcoords as stored, top-down), each turned
    to ours (``textures``: v up, (u, v) -> (u, 1 - v)). Its ``to_uv`` (scale,
    translate, rotate about z, matrix) applies; ``wrap_mode`` repeat as it is,
    mirror and clamp through ``textures.as_repeating``; ``filter_type`` nearest is
    read bilinear (a warning); ``raw`` skips the sRGB decoding of 8- and 16-bit
    images; OpenEXR images are linear. A plastic's textured diffuse reflectance maps
    its brightest texel by the rule below and scales the others with it (exact where
    the rule's kd is linear in it, as for ``nonlinear`` false; ``nonlinear`` true by
    Mitsuba's kd / (1 - kd R_int) per texel). A texture anywhere else (a specular
    reflectance, a roughness, a blend's weight), a ``checkerboard``, or a bitmap on a
    shape without texture coordinates counts with its mean colour (with a warning).
Emitters
    ``area`` (a shape's radiance); ``point`` (``intensity``; ``position`` or
    ``to_world``'s translation), ``spot`` (``intensity``, ``cutoff_angle`` default 20
    degrees, ``beam_width`` default 3/4 of it, ``to_world``: at its translation,
    pointing along its +z; a projected ``texture`` is left out with a warning) and
    ``directional`` (``irradiance``; ``direction``, the way the light travels, or
    ``to_world``'s +z) as the scene's delta lights (``radiosity.scene.lights``);
    ``constant`` (radiance) and ``envmap`` (filename: .exr, .hdr, .pfm or an 8-bit
    image, sRGB-decoded; scale; to_world, its rotation) become the scene's environment
    (``radiosity.physics.environment``; one per scene: a second is left out with a
    warning); the sun and sky models are not modelled yet: left out with a warning.
Sensor
    ``perspective`` / ``thinlens`` as the scene's camera: ``fov`` with its
    ``fov_axis`` (x, y, diagonal, smaller, larger; kept along that axis at any image
    size, as Mitsuba 3 keeps it) or 0.6's ``focalLength`` (a diagonal fov), the
    transform (``lookat`` or a matrix; a mirroring one is drawn unmirrored, with a
    warning), and the film's width and height.

Integrators, samplers, films' other settings and media are not read (the solver's own
settings apply). Every problem is an InputError naming the file, the line and the
element; every approximation a SceneWarning naming them too.
"""

from .meshes import Tessellation, read_serialized
from .reader import load_mitsuba

__all__ = ["Tessellation", "load_mitsuba", "read_serialized"]
