"""The renderer: draws a fitted model and/or a solution from a camera into an HDR image.

It knows nothing of windows: give it a moderngl context (``display.gl``) and it draws
into its own float framebuffer and reads back linear radiance, (H, W, 3) float32, row 0
at the top; where no object is, the environment (the light from outside the scene, as
the solution or the fit carries it) or 0. Exposure and sRGB come last: ``tonemap`` (numpy, to 8 bits),
or ``Renderer.show`` into a framebuffer (display/shaders/tonemap.glsl, the same formula,
which the window and the web page use too). The GLSL is in display/shaders, one file a
stage or a part of the formula (``display.glsl``); ``PROGRAMS`` names each program's files.

Modes
    fitted     the fitted model's shading formula (``fitting.model.shade_arrays``): any number
               of lights per object, directional and point lights mixed (GL_POSITION w = 0
               or 1, the light vector taken from the shaded point), coefficients shared
               by the lights or one per light
    diffuse    a diffuse walkthrough: with a solution, each vertex's radiance averaged over
               directions; from a fitted model alone, its emitted colour (the model with
               every part off: the paper's figure 7 with its lights off)
    reference  the solution's directional radiance, bilinear in the equal-area grid
               of each vertex (read in that vertex's frame) for the view direction
Shading
    gouraud    evaluated at the vertices and interpolated (as in 1997)
    pixel      evaluated per fragment: for "fitted" at the interpolated position with
               the interpolated normal and coefficients, for "reference" the three
               vertices' grids read with the fragment's own view direction and blended
               barycentrically
Antialiasing (``samples`` per pixel, ``display.gl.sample_plan``)
    Each pixel is the plain mean of its samples, all inside it: a box filter over the
    pixel, as a path tracer integrating radiance over the pixel has. Up to the context's
    MSAA the scene is drawn into a multisample float framebuffer (colour and depth per
    sample; each triangle shaded once per pixel, at the centroid of the samples it
    covers) whose samples ``ctx.copy_framebuffer`` averages into a float texture; beyond
    it, into one ``factor`` times larger on each side, whose factor x factor blocks a
    shader then averages (supersampling: shaded per sub-pixel). All in linear radiance,
    before any tone mapping. 1 sample is the pixel centre alone. Object masks and the
    attributes program (``object_mask``; the tests' probes of what the shaders see) are
    always one sample per pixel.
Sides and depth
    Surfaces are one-sided, as the solver and the path tracer have them: a triangle's
    front (counter-clockwise seen from the eye, as its geometric normal says) shows its
    radiance, its back is black and absorbs. A two-sided surface is two objects, the
    front and a reversed copy BACK_OFFSET behind it (``radiosity.scene.model.back_of``).
    ``draw`` draws every front face first (back faces culled), then every back face
    black (front faces culled, ``back_fragment.glsl``) with a strict depth test: a back
    shows only where it is nearer than every front, so a one-sided wall seen from behind
    is a black occluder, and at (nearly) the same depth the front wins (a two-sided
    wall's back copy over the front copy's back). Depth (``Depth``): reversed Z into a
    float depth buffer where the context has clip control (``display.gl.depth_control``),
    near 1 and an infinite far plane 0, the near plane from the scene's bounds and the
    eye (``depth_range``): a float's relative precision at every distance, so any scale
    draws alike; elsewhere the conventional range, -1 to 1 into 24 bits, with a larger
    near plane and the backs pushed back by a polygon offset. docs/display-and-web.md
    has what each draws wrong on test scenes (nothing) and on an interior.
"""

from __future__ import annotations

import contextlib
import dataclasses
import math
from typing import NamedTuple

import moderngl
import numpy as np

from display.choices import MODE_NAMES, MODE_WORDS, SHADINGS  # noqa: F401 (the modes' words)
from fitting.options import PARTS
from radiosity.files.errors import InputError
from radiosity.physics.emitters import DEFAULT_NODES
from radiosity.physics.ltc import highlight_lobe
from radiosity.physics.ltc import table_texture as ltc_table_texture
from radiosity.physics.materials import near_base

from . import glass, mirror
from .gl import DEFAULT_SAMPLES, check_image_size, check_samples, depth_control, sample_plan
from .glsl import emitter_table, stage
from .store import MAX_STRIDE, STAGING_BYTES, Estimate, Store, StorePlan, check_memory, context_limits, store_layout

MODES = ("fitted", "diffuse", "reference")
# each mode's name as users type and read it: the solution drawn directly is the "solution display" (its id,
# here and in compare.json, is its first name, "reference", which --mode still reads)
LTC_UNIT = 4  # the texture unit of the microfacet lobes' table
CUTOUT_UNIT = 2  # the texture unit of a masked object's opacity
GLASS_REFLECTION_SCALE = 2  # a flat glass piece's reflected view: at 1 / this of the frame's size
CHUNK_VALUES = 1 << 20  # radiance values a solution's grids are read, and their highlights subtracted, at a time
VERTEX_BYTES = 8 * 12   # an object's vertex buffers, per vertex, at most (position, normal, tangent, mean, ...)
CLIP_LIFT = 1e-5  # a reflected view keeps what lies this fraction of the scene's size beyond the plane
GL_CLIP_DISTANCE0 = 0x3000  # OpenGL's enum: clip by gl_ClipDistance[0] (a flat mirror's reflected view)

# The programs: a shader file per stage (display/shaders), compiled with ``display.glsl``'s
# defines for the object's parts and emitter nodes, and the variants named in "defines".
PROGRAMS = {
    # per pixel, the shared coefficients interpolated (the Gouraud colour where gouraud == 1)
    "fitted": dict(vertex_shader="fitted_vertex.glsl", fragment_shader="fitted_fragment.glsl"),
    # per pixel with per-vertex textures: a geometry shader hands the fragments the triangle
    "fitted-pixel": dict(vertex_shader="pixel_vertex.glsl", geometry_shader="pixel_geometry.glsl",
                         fragment_shader="fitted_fragment.glsl", defines=("VL_TRIANGLE",)),
    "gouraud": dict(vertex_shader="fitted_vertex.glsl", fragment_shader="colour_fragment.glsl",
                    defines=("VL_GOURAUD",)),
    "fitted-feedback": dict(vertex_shader="fitted_vertex.glsl", varyings=["v_colour"], defines=("VL_GOURAUD",)),
    "attributes": dict(vertex_shader="fitted_vertex.glsl", fragment_shader="attributes_fragment.glsl"),
    "attributes-pixel": dict(vertex_shader="pixel_vertex.glsl", geometry_shader="pixel_geometry.glsl",
                             fragment_shader="attributes_fragment.glsl", defines=("VL_TRIANGLE",)),
    "reference-gouraud": dict(vertex_shader="reference_vertex.glsl", fragment_shader="colour_fragment.glsl"),
    "reference-pixel": dict(vertex_shader="reference_pixel_vertex.glsl", geometry_shader="reference_pixel_geometry.glsl",
                            fragment_shader="reference_pixel_fragment.glsl"),
    "reference-feedback": dict(vertex_shader="reference_vertex.glsl", varyings=["v_colour"]),
    "box": dict(vertex_shader="full_screen_vertex.glsl", fragment_shader="box_fragment.glsl"),
    "background": dict(vertex_shader="background_vertex.glsl", fragment_shader="background_fragment.glsl"),
    # a triangle seen from behind: black (and nothing in the attribute targets)
    "back": dict(vertex_shader="back_vertex.glsl", fragment_shader="back_fragment.glsl"),
    "back-attributes": dict(vertex_shader="back_vertex.glsl", fragment_shader="back_fragment.glsl",
                            defines=("VL_ATTRIBUTES",)),
    "tonemap": dict(vertex_shader="full_screen_vertex.glsl", fragment_shader="tonemap_fragment.glsl"),
    # a glass object, either face, from its probe (display.glass)
    "glass": dict(vertex_shader="glass_vertex.glsl", fragment_shader="glass_fragment.glsl"),
    # a perfect mirror, from the scene reflected in its plane or its probe (display.mirror)
    "mirror": dict(vertex_shader="glass_vertex.glsl", fragment_shader="mirror_fragment.glsl"),
    # a near mirror, its base and what it reflects from the scene in its plane (display.mirror)
    "near": dict(vertex_shader="near_vertex.glsl", fragment_shader="near_fragment.glsl"),
}
STAGES = ("vertex_shader", "geometry_shader", "fragment_shader")


def tonemap(hdr, exposure=1.0):
    """Linear radiance (H, W, 3) -> 8-bit sRGB (H, W, 3) uint8: exposure, clip, sRGB
    (tonemap.glsl's formula, tested against it)."""
    x = np.clip(np.asarray(hdr, np.float64) * exposure, 0.0, 1.0)
    srgb = np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)
    return (np.clip(srgb, 0, 1) * 255 + 0.5).astype(np.uint8)


# The near plane, at least this fraction of the distance to the scene's farthest point
# (from inside the scene's box, where geometry may be anywhere): with reversed Z the near
# plane costs no precision, only what it clips (1e-5 of a 40 m interior is 0.4 mm; on
# llvmpipe the test scenes draw right down to 1e-7, a floor clipped behind the eye
# included); the conventional depth range spends its 24 bits by it (1e-3: the 1 mm gap
# in a 10 m room right, 1e-4 not).
NEAR_FRACTION = {True: 1e-5, False: 1e-3}
# glPolygonOffset of the back faces in the conventional range: 4 of its steps (and one a
# step of slope) behind their place, so that rounding never brings a two-sided wall's
# front copy's back before its back copy (BACK_OFFSET apart) where the steps are coarser.
BACK_FACE_OFFSET = (1.0, 4.0)


def depth_range(bounds, eye, near_fraction=NEAR_FRACTION[True]):
    """(near, far) of a view from ``eye`` (3,) of a scene inside the box ``bounds`` ((2, 3):
    min, max corners), in scene units: far the distance to the box's farthest corner, near
    half the distance to the box (no geometry is nearer), at least ``near_fraction`` of
    far (from inside the box)."""
    lo, hi = np.asarray(bounds, np.float64)
    eye = np.asarray(eye, np.float64)
    far = max(float(np.linalg.norm(np.maximum(np.abs(lo - eye), np.abs(hi - eye)))), 1e-30)
    outside = float(np.linalg.norm(np.maximum(np.maximum(lo - eye, eye - hi), 0.0)))
    return max(0.5 * outside, near_fraction * far), far


class Depth(NamedTuple):
    """The depth convention of a renderer's draws. ``reversed``: reversed Z, the near plane
    at depth 1 and an infinite far plane at 0 (clip z = near, w = distance along the view:
    depth = near / distance, computed without cancellation), into a float depth buffer
    with clip control (``display.gl.DepthControl``); else the conventional projection,
    near at -1 and far at 1, depth 0 to 1 into 24 bits. The page (walkthrough.js)
    draws with the same conventions."""

    reversed: bool

    @property
    def clear(self):
        """The depth buffer's value where nothing is drawn: the far plane's."""
        return 0.0 if self.reversed else 1.0

    @property
    def nearer(self):
        """The strict depth test: nearer than what is there."""
        return ">" if self.reversed else "<"

    @property
    def near_fraction(self):
        """``depth_range``'s least near plane, a fraction of the far distance."""
        return NEAR_FRACTION[self.reversed]

    @property
    def back_offset(self):
        """glPolygonOffset (factor, units) of the back faces: pushed away from the eye
        where depth is coarse, so that rounding cannot bring a back in front of the
        front it lies behind; none with reversed Z."""
        return BACK_FACE_OFFSET if not self.reversed else (0.0, 0.0)

    @property
    def far_or_equal(self):
        """The background's test: at the far plane, where nothing is drawn."""
        return ">=" if self.reversed else "<="

    def projection(self, view, near, far):
        """(4, 4) float64 projection of ``view`` (its field of view and aspect from
        ``Camera.projection_matrix``) with this convention's depth."""
        m = view.projection_matrix(near, far)
        if self.reversed:
            m[2] = (0.0, 0.0, 0.0, near)  # clip z = near, clip w = -z_eye: depth = near / distance
        return m


class _Highlight(NamedTuple):
    """An object's emitter term in one mode, as its uniforms take it."""

    base: int  # where its visibility (V, P) starts in the store
    n_parts: int
    own: int  # a bit per part that is the object's own (it lights itself: not drawn on it)
    ks: tuple  # the lobe's specular colour
    exponent: float
    f0: tuple  # Schlick's F0 per channel, (-1, -1, -1): no Fresnel
    table: object  # the emitter table's texture (the object's own parts' or the mode's)
    lobe: tuple  # (code, alpha) of a microfacet lobe (``radiosity.physics.ltc``), (0, 0.0): Phong


class _Probe(NamedTuple):
    """An object's fitted reflection probe, as its uniforms take it."""

    row: int  # its first row in the probes' atlas
    size: int  # M of its M x M texels
    centre: tuple
    lo: tuple  # its proxy box's corners
    hi: tuple
    albedo: np.ndarray  # its table of S (``fitting.probe.ALBEDO_POINTS``), float32


class _Object:
    """GPU buffers of one object."""

    def __init__(self, ctx, name, positions, normals, faces):
        self.name = name
        self.n_vertices = len(positions)
        self.positions = np.asarray(positions, np.float32)
        self.buffers = {
            "in_position": ctx.buffer(self.positions.tobytes()),
            "in_normal": ctx.buffer(np.asarray(normals, np.float32).tobytes()),
        }
        self.index = ctx.buffer(np.asarray(faces, np.int32).tobytes())
        self.formats = {}  # attribute -> its buffer's format where not "3f"
        self.textured = None  # (texture, kd) of a textured object's diffuse term
        self.cutout = None  # the opacity texture of a masked object (cutout.glsl)
        self.lights = None
        self.n_lights = 0
        self.per_light = False  # True: (V, K, 3) coefficients in the renderer's coefficient texture
        self.coefficient_base = 0
        self.specular = None  # the fitted coefficients as given, (V, 3) or (V, K, 3) (what the tests' attribute probe blends)
        self.base = 0
        self.grid_n = 0
        # the emitters' highlights per mode ("fitted", "reference"): (visibility base, parts,
        # own-part mask, ks, exponent), absent where the object has none
        self.highlight = {}
        self.probe = None  # the fitted probe (a ``_Probe``)
        self.glossy = False  # a glossy object: lights, a probe or highlights in the fit, a grid in the solution
        self.glass = None  # its ``Glass``: drawn as glass (``display.glass``), after everything else
        self.slab, self.sphere = False, None  # its proxy (``display.glass.proxy``)
        self.mirror = None  # (ks, F0 or None) of a perfect mirror: drawn by what it reflects (``display.mirror``)
        self.plane = None  # a flat mirror's (point, unit normal)
        self.near = None  # a near mirror's ``HighlightLobe`` (``display.mirror.near_mirror_of``)
        self.near_eta = 0.0  # its base's interface (``physics.materials.near_base``; 0 none): the solution's
        self.fit_near_eta = 0.0  # ... the fit's
        self.vaos = {}  # (program, attributes, sources, indexed) -> its vertex array, made once (``vao``)

    def add(self, ctx, attribute, values):
        for vao in self.vaos.values():  # a vertex array made before would not see the new attribute
            vao.release()
        self.vaos.clear()
        values = np.asarray(values, np.float32)
        self.buffers[attribute] = ctx.buffer(values.tobytes())
        if values.ndim == 2 and values.shape[1] != 3:
            self.formats[attribute] = f"{values.shape[1]}f"

    def add_textured(self, ctx, textured, images):
        """A textured object's diffuse term (``radiosity.physics.textures.TexturedDiffuse``):
        its uvs and irradiance as attributes, its image the float texture ``images``
        (``_Images``) holds for it: one for all the objects that share the image."""
        if self.textured is not None:
            return
        self.add(ctx, "in_uv", textured.uvs)
        self.add(ctx, "in_irradiance", textured.irradiance)
        self.textured = (images.texture(self.name, textured.texture), tuple(float(c) for c in textured.kd))
        if textured.opacity is not None:
            self.cutout = images.mask(self.name, textured.opacity)

    def vao(self, ctx, program, attributes, indexed=True, sources=None):
        """The vertex array of ``program`` over these ``attributes``, made the first time a
        frame asks for it and kept (released with the object): a frame draws with those the
        frames before made. An attribute with no buffer (in_specular of per-light
        coefficients) reads the generic value, unused by the shaders; ``sources`` feeds an
        attribute from another buffer."""
        sources = sources or {}
        key = (program.glo, tuple(attributes), tuple(sorted(sources.items())), indexed)
        if key not in self.vaos:
            content = [(self.buffers[sources.get(a, a)], self.formats.get(sources.get(a, a), "3f"), a)
                       for a in attributes if a in program and sources.get(a, a) in self.buffers]
            self.vaos[key] = (ctx.vertex_array(program, content, index_buffer=self.index, index_element_size=4)
                              if indexed else ctx.vertex_array(program, content))
        return self.vaos[key]

    def release(self):
        for vao in self.vaos.values():
            vao.release()
        for b in list(self.buffers.values()) + [self.index]:
            b.release()
        if self.lights is not None:
            self.lights.release()


class _Images:
    """The float textures of textured objects' images, one for each image: the objects of
    a scene that share an image (600 of staircase's 655 share one) share the array the
    file's reader gives them (``radiosity.files.npz.Archive.shared``), and so their
    texture here. Bottom row first (t = v), bilinear and repeating, mipmapped for
    minification."""

    def __init__(self, ctx):
        self.ctx = ctx
        self._textures = {}  # id(image) -> (image, its texture): the image held, so its id is not reused

    def texture(self, name, image):
        """The texture of ``image`` (H, W, 3) linear floats, made at its first use by object ``name``."""
        return self._made(name, image, "texture", 3, mipmapped=True)

    def mask(self, name, opacity):
        """The texture of an opacity mask (H, W) floats, made at its first use by object
        ``name``: one channel, no mipmaps (the shaders read its base level, as the solver
        does)."""
        return self._made(name, opacity, "mask", 1, mipmapped=False)

    def _made(self, name, image, what, components, mipmapped):
        held = self._textures.get(id(image))
        if held is not None:
            return held[1]
        height, width = image.shape[:2]
        limit = self.ctx.info["GL_MAX_TEXTURE_SIZE"]
        if max(width, height) > limit:
            raise InputError(f"object {name!r}: its {what} ({width} x {height}) exceeds this OpenGL's texture size ({limit})")
        flipped = np.ascontiguousarray(np.asarray(image)[::-1], np.float32)
        texture = self.ctx.texture((width, height), components, flipped.tobytes(), dtype="f4")
        texture.repeat_x = texture.repeat_y = True
        if mipmapped:
            texture.build_mipmaps()
            texture.filter = (moderngl.LINEAR_MIPMAP_LINEAR, moderngl.LINEAR)
        else:
            texture.filter = (moderngl.LINEAR, moderngl.LINEAR)
        self._textures[id(image)] = (image, texture)
        return texture

    @property
    def nbytes(self):
        """Bytes of the textures with their mipmaps (12 a texel)."""
        return sum(t.width * t.height * 12 * 4 // 3 for _, t in self._textures.values())

    def release(self):
        for _, texture in self._textures.values():
            texture.release()
        self._textures.clear()


class _Framebuffers:
    """The framebuffers of one image size and sample plan (``display.gl.SamplePlan``).

    ``scene`` ((W factor, H factor), ``msaa`` samples a pixel, with depth) is drawn into;
    with MSAA its samples are averaged into ``resolved`` (a float texture of its size);
    with supersampling ``output`` (W, H) gets the mean of each factor x factor block.
    ``output`` is the last of them: its colour attachment 0 is the image, a float texture.
    One sample: ``scene`` alone, ``targets`` float textures. With ``depth_control``
    (``display.gl.DepthControl``) the depth buffer is float (GL_DEPTH_COMPONENT32F)."""

    def __init__(self, ctx, size, targets, plan, depth_control=None):
        self.plan = plan
        big = (size[0] * plan.factor, size[1] * plan.factor)
        if plan.msaa > 1:
            colour = [ctx.renderbuffer(big, 4, samples=plan.msaa, dtype="f4") for _ in range(targets)]
        else:
            colour = [ctx.texture(big, 4, dtype="f4") for _ in range(targets)]
        depth = ctx.depth_renderbuffer(big, samples=plan.msaa if plan.msaa > 1 else 0)  # 0: not multisampled
        if depth_control is not None:
            depth_control.float_depth(depth)
        self.scene = ctx.framebuffer(color_attachments=colour, depth_attachment=depth)
        self.resolved = ctx.framebuffer(color_attachments=[ctx.texture(big, 4, dtype="f4")]) if plan.msaa > 1 else None
        self.single = self.scene if self.resolved is None else self.resolved  # the samples averaged, (W factor, H factor)
        self.output = self.single
        if plan.factor > 1:
            self.output = ctx.framebuffer(color_attachments=[ctx.texture(size, 4, dtype="f4")])

    def release(self):
        for fbo in {id(f): f for f in (self.scene, self.single, self.output)}.values():
            for attachment in fbo.color_attachments:
                attachment.release()
            if fbo.depth_attachment is not None:
                fbo.depth_attachment.release()
            fbo.release()


def _store_blocks(fit, solution):
    """(object name, what, values, row length) of every block the float store holds
    (``display.store``): per-light coefficients and emitters' visibility of the fit,
    radiance grids and visibility of the solution; InputError for a row longer than
    the shaders address (``display.store.MAX_STRIDE``)."""
    blocks = []
    for f in fit.objects if fit is not None else ():
        if f.per_light and f.n_lights:
            blocks.append((f.name, "per-light coefficients", np.size(f.specular) // 3, f.n_lights))
        if f.highlight is not None:
            visibility = np.asarray(f.highlight.visibility)
            blocks.append((f.name, "emitter visibility", visibility.size, visibility.size // max(len(f.positions), 1)))
    drawn = {f.name for f in fit.objects} if fit is not None else None  # a solution's objects the fit names
    for s in solution.objects if solution is not None else ():
        if drawn is not None and s.name not in drawn:
            continue
        blocks.append((s.name, "radiance directions", s.radiance.size // 3, s.radiance.shape[1]))
        if not s.is_diffuse and solution.emitters and s.visibility is not None:
            blocks.append((s.name, "emitter visibility", s.visibility.size, s.visibility.size // max(len(s.positions), 1)))
    for name, what, _, stride in blocks:
        if stride > MAX_STRIDE:
            raise InputError(f"object {name!r} has {stride:,} {what} a vertex; the display reads at most {MAX_STRIDE:,}")
    return blocks


def _estimate(fit, solution, layout):
    """``display.store.Estimate`` of a renderer of ``fit`` and ``solution`` in ``layout``."""
    buffers, host, images = 0, 0, {}
    for model in (fit, solution):
        for o in model.objects if model is not None else ():
            buffers += VERTEX_BYTES * len(o.positions) + 12 * len(o.faces)
            arrays = [getattr(o, key, None) for key in ("positions", "normals", "tangents", "faces", "radiance",
                                                        "specular", "emitted", "visibility")]
            host += sum(a.nbytes for a in arrays if isinstance(a, np.ndarray))
            textured = getattr(o, "textured", None)
            if textured is not None:
                images[id(textured.texture)] = np.asarray(textured.texture).size
    buffers += sum(images.values()) * 4 * 4 // 3  # an image once, however many objects share it (_Images)
    # a band of rows; a chunk of a grid: its highlights and their difference (float64), that as
    # float32, or its float64 copy for the directional mean (_grid_chunks, _directional_mean)
    chunk = max((min(s.radiance.size // 3, _chunk_vertices(s.radiance) * s.radiance.shape[1])
                 for s in (solution.objects if solution is not None else ())), default=0)
    staging = min(STAGING_BYTES, layout.nbytes) + chunk * 3 * (8 + 8 + 4)
    return Estimate(store=layout.nbytes, buffers=buffers, staging=staging, host=host)


def _chunk_vertices(radiance):
    """Vertices of a grid (V, D, 3) read at a time: CHUNK_VALUES values, at least a vertex."""
    return max(1, CHUNK_VALUES // max(radiance.shape[1], 1))


def _directional_mean(radiance, reduce=None):
    """(V, 3) float64: each vertex's radiance (V, D, 3) averaged over directions (or reduced
    by ``reduce``, a function of a chunk (v, D, 3) -> (v, 3): a near mirror's base), read a
    chunk of vertices at a time (as float64, the whole never copied)."""
    reduce = reduce or (lambda chunk: np.mean(chunk, axis=1))
    step = _chunk_vertices(radiance)
    parts = [reduce(np.asarray(radiance[i:i + step], np.float64)) for i in range(0, len(radiance), step)]
    return np.concatenate(parts) if parts else np.zeros((0, 3))


def _grid_chunks(solution, s, split):
    """Object ``s``'s radiance grids (V, D, 3) a chunk of vertices at a time, less the
    emitters' highlights where ``split`` (the shader adds them per pixel), as
    ``display.store.StorePlan`` takes a block's values."""
    step = _chunk_vertices(s.radiance)
    for start in range(0, len(s.radiance), step):
        rows = slice(start, start + step)
        yield s.radiance[rows] - solution.highlights(s.name, vertices=rows) if split else s.radiance[rows]


def light_table(light_pos, light_rgb, shininess):
    """The (K, 2, 4) float32 table the shaders read: row k = (light_pos xyzw), (rgb, shininess)."""
    k = len(light_pos)
    table = np.zeros((max(k, 1), 2, 4), np.float32)
    table[:k, 0] = np.asarray(light_pos, np.float32).reshape(k, 4)
    table[:k, 1, :3] = np.asarray(light_rgb, np.float32).reshape(k, 3)
    table[:k, 1, 3] = np.asarray(shininess, np.float32).reshape(k)
    return table


class Renderer:
    """Draws ``fit`` (a ``fitting.FittedModel``) and/or ``solution`` (a
    ``radiosity.files.solution.Solution``) with a moderngl context ``ctx``.

    Each object's lights are a (2, K) float texture (``light_table``). Coefficients
    shared by the lights ((V, 3)) are a vertex attribute; per-light ones ((V, K, 3))
    are in the float store (``display.store``, with the solution's radiance grids and
    the emitters' visibility), light k of vertex v at value base + v K + k, read by
    vertex id: ``gl_VertexID`` for Gouraud, and per pixel the triangle's three ids
    (flat, from a geometry shader) blended by barycentrics.

    Before anything is uploaded the store is laid out and the memory it, the vertex
    buffers and the upload's staging need (``estimate``) checked against the memory
    free: InputError (one line) naming the estimate when it does not fit. ``say`` (a
    function of one line), if given, is told an estimate of a gigabyte or more first
    (``display.store.check_memory``)."""

    def __init__(self, ctx, fit=None, solution=None, samples=DEFAULT_SAMPLES, *, say=None):
        if fit is None and solution is None:
            raise ValueError("give a fitted model, a solution, or both")
        self.ctx = ctx
        self.depth_control = depth_control(ctx)  # None: no clip control, the conventional depth range
        self.depth = Depth(reversed=self.depth_control is not None)
        self.samples = samples  # per pixel, in draw and render unless they are told otherwise
        self.plan = sample_plan(samples, ctx.max_samples)
        self.fit, self.solution = fit, solution
        self.modes = tuple(m for m in MODES if (m != "reference" or solution is not None) and (m != "fitted" or fit is not None))
        source = fit if fit is not None else solution
        blocks = _store_blocks(fit, solution)
        self.layout = store_layout(sum(b[2] for b in blocks), *context_limits(ctx))
        self.estimate = _estimate(fit, solution, self.layout)
        check_memory(self.estimate, self.layout, say=say)
        self.objects = [_Object(ctx, o.name, o.positions, o.normals, o.faces) for o in source.objects]
        by_name = {o.name: o for o in solution.objects} if solution is not None else {}
        for obj, o in zip(self.objects, source.objects, strict=True):
            obj.glass = glass.glass_of(o) or glass.glass_of(by_name.get(o.name))
            obj.mirror = mirror.mirror_of(o) or mirror.mirror_of(by_name.get(o.name))
            if obj.mirror is not None:
                obj.slab, obj.sphere = glass.proxy(obj.positions, o.faces)
                obj.plane = mirror.plane_of(o.positions, o.faces)
            elif obj.glass is None:
                near = mirror.near_mirror_of(by_name.get(o.name)) or mirror.near_mirror_of(o)
                plane = mirror.plane_of(o.positions, o.faces) if near is not None else None
                if plane is not None:
                    obj.near, obj.plane = near, plane
        # a glass object is drawn piece by piece (the panes of a railing), each with its own plane or probe
        self.glass_pieces = []
        for obj, o in zip(self.objects, source.objects, strict=True):
            if obj.glass is None:
                continue
            pieces = glass.components(o.positions, o.faces)
            for k, (used, faces) in enumerate(pieces):
                piece = _Object(ctx, obj.name if len(pieces) == 1 else f"{obj.name}#{k}", np.asarray(o.positions)[used],
                                np.asarray(o.normals)[used], faces)
                piece.glass = obj.glass
                piece.slab, piece.sphere = glass.proxy(piece.positions, faces)
                piece.plane = mirror.plane_of(piece.positions, faces)
                self.glass_pieces.append(piece)
        self.glass_approach = "blend"  # how glass is drawn (``display.glass.APPROACHES``)
        self.mirrors = True  # False: a solution's perfect mirrors drawn from its grid as any glossy object (to compare)
        self.near_mirrors = True  # near mirrors drawn from the scene in their plane (``display.mirror``); False: from the grid
        self._glass_probes = {}  # (object, mode, shading, lights, parts) -> its probe texture
        self._clip = None  # a flat mirror's plane (n, -n . p) while its reflected view is drawn
        self._mirror_images = {}  # a flat mirror's name -> the texture of its reflected view (remade every frame)
        positions = np.concatenate([o.positions for o in self.objects])
        self.bounds = np.stack([positions.min(axis=0), positions.max(axis=0)]).astype(np.float64)
        self.store = None
        self.probes = None
        self.emitter_tables = {}  # (mode, a list of parts) -> the emitter parts' texture (``_emitter_table``)
        self.default_tables = {}  # mode -> the table of all its parts
        self.ltc = None  # the microfacet lobes' table (``_ltc_texture``), made where an object draws one
        environment = solution.environment if solution is not None else None
        if environment is None and fit is not None:
            environment = fit.environment
        self.environment = environment  # the light from outside the scene, drawn where no object is
        self._environment_texture = None
        self.images = _Images(ctx)  # textured objects' images, one texture each
        self.nodes = {"fitted": DEFAULT_NODES, "reference": DEFAULT_NODES}
        plan = StorePlan()  # the blocks of the float store, streamed into it once all are known
        if fit is not None:
            self._upload_fit(fit, plan)
        if solution is not None:
            self._upload_solution(solution, plan)
        self.store = Store(ctx, self.layout, plan)
        self._programs = {}
        self._framebuffers = {}
        self._full_screens = {}  # program -> its vertex array of one triangle (no attributes)

    def _highlight(self, mode, obj, parts, visibility, ks, exponent, plan, *, fresnel=None, microfacet=None):
        """Record ``obj``'s emitter term for ``mode``: its visibility (V, P) a block of the
        store's ``plan``; ``fresnel`` the material's Schlick F0 or None; ``microfacet``:
        None, or the ``Microfacet`` (or its dict) whose own lobe draws it (ks, exponent
        and fresnel then ignored: ``radiosity.physics.ltc.highlight_lobe``)."""
        values = np.asarray(visibility, np.float32).reshape(-1)
        base = plan.add(len(values), lambda: (values,))
        own = sum(1 << i for i, p in enumerate(parts) if p.source == obj.name)
        f0 = (-1.0, -1.0, -1.0) if fresnel is None else tuple(float(v) for v in fresnel)  # < 0: no Fresnel
        lobe = (0, 0.0)
        if microfacet is not None:
            hl = highlight_lobe(microfacet)
            ks, f0, lobe = hl.ks, tuple(float(v) for v in hl.f0), (hl.code, hl.alpha)
            self._ltc_texture()
        # the object's own parts (a file's version that names them) get their own table, one per distinct list
        table = self._emitter_table(mode, parts)
        obj.highlight[mode] = _Highlight(base, len(parts), own, tuple(float(v) for v in ks), float(exponent), f0, table, lobe)

    def _ltc_texture(self):
        """The microfacet lobes' table (``display/shaders/ltc.glsl``), made once."""
        if self.ltc is None:
            table = ltc_table_texture()
            self.ltc = self.ctx.texture((table.shape[1], table.shape[0]), 4, table.tobytes(), dtype="f4")
            self.ltc.filter = (moderngl.NEAREST, moderngl.NEAREST)
        return self.ltc

    def _emitter_table(self, mode, parts):
        """The emitter table texture of ``parts`` (``display.glsl.emitter_table``) in
        ``mode``, made once per list of parts (a file's version that names an object's own
        parts may give each object its own)."""
        key = (mode, tuple(id(p) for p in parts))
        if key not in self.emitter_tables:
            table = emitter_table(parts)
            texture = self.ctx.texture((table.shape[1], table.shape[0]), 4, table.tobytes(), dtype="f4")
            texture.filter = (moderngl.NEAREST, moderngl.NEAREST)
            self.emitter_tables[key] = texture
        return self.emitter_tables[key]

    def _upload_fit(self, fit, plan):
        ctx = self.ctx
        self.nodes["fitted"] = fit.emitter_nodes
        self.default_tables["fitted"] = self._emitter_table("fitted", fit.emitters)  # bound where an object draws none
        probes, row = [], 0
        for obj, f in zip(self.objects, fit.objects):
            if f.textured is not None:
                obj.add_textured(ctx, f.textured, self.images)
            if f.highlight is not None:
                h = f.highlight
                self._highlight("fitted", obj, h.parts, h.visibility, h.ks, h.exponent, plan, fresnel=h.fresnel,
                                microfacet=h.microfacet)
            obj.glossy = obj.glossy or bool(f.n_lights or f.probe is not None or f.highlight is not None)
            weight = np.zeros((obj.n_vertices, 3), np.float32)
            if f.probe is not None:
                m = f.probe.size
                obj.probe = _Probe(row, m, tuple(map(float, f.probe.centre)), tuple(map(float, f.probe.box[0])),
                                   tuple(map(float, f.probe.box[1])), np.asarray(f.probe.albedo, np.float32))
                probes.append(np.asarray(f.probe.texels, np.float32))
                row += m
                weight = np.asarray(f.probe_weight, np.float32)
            obj.add(ctx, "in_probe", weight)
            obj.add(ctx, "in_emitted", f.emitted)
            if f.near_base is not None:  # a near mirror's own part, as the fit keeps it
                obj.add(ctx, "in_fit_base", f.near_base)
                obj.fit_near_eta = float(f.near_eta)
            obj.n_lights = f.n_lights
            obj.per_light = bool(f.per_light) and f.n_lights > 0
            obj.specular = np.asarray(f.specular, np.float32)
            if obj.per_light:
                values = obj.specular.reshape(-1, 3)
                obj.coefficient_base = plan.add(len(values), lambda values=values: (values,))
            else:
                obj.add(ctx, "in_specular", obj.specular.reshape(-1, 3) if f.n_lights else np.zeros((obj.n_vertices, 3)))
            obj.lights = ctx.texture((2, max(f.n_lights, 1)), 4, light_table(*f.lights).tobytes(), dtype="f4")
            obj.lights.filter = (moderngl.NEAREST, moderngl.NEAREST)
        if probes:
            width = max(p.shape[1] for p in probes)
            atlas = np.zeros((row, width, 3), np.float32)
            r = 0
            for p in probes:
                atlas[r:r + p.shape[0], : p.shape[1]] = p
                r += p.shape[0]
            self.probes = ctx.texture((width, row), 3, atlas.tobytes(), dtype="f4")
            self.probes.filter = (moderngl.NEAREST, moderngl.NEAREST)

    def _upload_solution(self, solution, plan):
        ctx = self.ctx
        self.nodes["reference"] = solution.emitter_nodes
        self.default_tables["reference"] = self._emitter_table("reference", solution.emitters)  # where one draws none
        by_name = {o.name: o for o in solution.objects}
        for obj in self.objects:
            s = by_name.get(obj.name)
            if s is None or len(s.positions) != obj.n_vertices:
                raise InputError(f"the solution and the fitted model differ (object {obj.name!r})")
            obj.add(ctx, "in_tangent", s.tangents)
            if s.textured is not None:
                obj.add_textured(ctx, s.textured, self.images)
            # the diffuse display: each vertex's radiance averaged over directions (what a
            # diffuse walkthrough of this solution shows)
            mean = _directional_mean(s.radiance)
            obj.add(ctx, "in_mean", mean)
            if obj.near is not None:  # a near mirror's own part (``physics.materials.near_base``)
                base, obj.near_eta = near_base(s.material_record.microfacet, s.directions,
                                               lambda reduce, s=s: _directional_mean(s.radiance, reduce))
                obj.add(ctx, "in_base", base)
            if "in_emitted" not in obj.buffers:  # a solution alone
                obj.add(ctx, "in_emitted", mean)
                obj.add(ctx, "in_specular", np.zeros((obj.n_vertices, 3)))
            if "in_probe" not in obj.buffers:
                obj.add(ctx, "in_probe", np.zeros((obj.n_vertices, 3)))
            obj.grid_n = 0 if s.is_diffuse else s.grid_n
            obj.glossy = obj.glossy or not s.is_diffuse
            # the grid keeps the rest of the radiance; the shader draws the highlights per pixel
            parts = solution.parts_of(s.name)
            split = not s.is_diffuse and bool(parts) and s.visibility is not None
            obj.base = plan.add(s.radiance.size // 3, lambda s=s, split=split: _grid_chunks(solution, s, split))
            if split:
                m = s.material_record
                self._highlight("reference", obj, parts, s.visibility, m.specular, m.exponent,
                                plan, fresnel=m.fresnel, microfacet=solution.lobe_of(s.name))

    def _program(self, key, parts=PARTS, textured=False, extra=()):
        """The program ``key`` (``PROGRAMS``) with the shading code of ``parts`` alone,
        a textured object's diffuse term if ``textured``, and the defines ``extra``."""
        parts = tuple(p for p in PARTS if p in parts)
        extra = tuple(extra)
        if (key, parts, textured, extra) not in self._programs:
            spec = dict(PROGRAMS[key])
            defines = spec.pop("defines", ()) + (("VL_TEXTURED",) if textured else ()) + (self.store.define,) + extra
            nodes = self.nodes["reference" if key.startswith("reference") else "fitted"]
            for name in STAGES:
                if name in spec:
                    spec[name] = stage(spec[name], nodes, parts, defines)
            self._programs[(key, parts, textured, extra)] = self.ctx.program(**spec)
        return self._programs[(key, parts, textured, extra)]

    def _drawn_parts(self, obj, mode, parts, n_lights):
        """The parts of ``obj``'s model a ``mode`` draws (of ``parts``): what its program holds."""
        if mode == "diffuse":
            return ()
        if mode == "reference":
            return ("emitters",) if "emitters" in parts and "reference" in obj.highlight else ()
        have = {"lights": n_lights > 0, "probe": obj.probe is not None, "emitters": "fitted" in obj.highlight}
        return tuple(p for p in PARTS if p in parts and have[p])

    def _matrices(self, view):
        """The view's model-view-projection, column-major float32 bytes for GLSL: the
        depth range from the scene's bounds and the eye (``depth_range``) in the
        renderer's depth convention (``Depth``)."""
        near, far = depth_range(self.bounds, view.eye, self.depth.near_fraction)
        mvp = self.depth.projection(view, near, far) @ view.view_matrix()
        return mvp.T.astype(np.float32).tobytes()

    def _set(self, program, name, value):
        if name in program:
            program[name].value = value

    def _light_count(self, obj, mode, lights):
        """How many of ``obj``'s lights a ``mode`` draws with ``lights`` (None: all)."""
        n = 0 if mode == "diffuse" or obj.lights is None else obj.n_lights
        return n if lights is None else max(0, min(n, lights))

    def _bind_highlight(self, program, obj, mode, on):
        """The emitter term's uniforms of ``obj`` in ``mode`` ("fitted" or "reference"),
        drawn if ``on`` and the object has one there."""
        h = obj.highlight.get(mode) if on else None
        table = h.table if h is not None else self.default_tables.get(mode)
        if table is not None:
            table.use(location=3)
        self._set(program, "emitter_table", 3)
        self._set(program, "n_parts", 0 if h is None else h.n_parts)
        if h is not None:
            self._set(program, "visibility_base", self.layout.address(h.base))
            self._set(program, "own_parts", h.own)
            self._set(program, "emitter_ks", h.ks)
            self._set(program, "emitter_exponent", h.exponent)
            self._set(program, "emitter_f0", h.f0)
            code, alpha = h.lobe
            self._set(program, "emitter_lobe", code)
            self._set(program, "emitter_alpha", alpha)
            if code:
                self.ltc.use(location=LTC_UNIT)
            self._set(program, "ltc_table", LTC_UNIT)

    def _bind_probe(self, program, obj, on):
        p = obj.probe if on else None
        if self.probes is not None:
            self.probes.use(location=5)
        self._set(program, "probes", 5)
        self._set(program, "probe_size", 0 if p is None else p.size)
        if p is not None:
            self._set(program, "probe_row", p.row)
            self._set(program, "probe_centre", p.centre)
            self._set(program, "probe_lo", p.lo)
            self._set(program, "probe_hi", p.hi)
            if "probe_albedo" in program:
                program["probe_albedo"].write(p.albedo.tobytes())

    def _bind_fitted(self, program, obj, n, mode="fitted", parts=PARTS):
        """Uniforms and textures of ``obj``'s fitted shading, ``n`` lights, the ``parts``
        named (in "diffuse" mode: none)."""
        drawn = mode == "fitted"
        self.store.bind(program)
        self._bind_highlight(program, obj, "fitted", drawn and "emitters" in parts)
        self._bind_probe(program, obj, drawn and "probe" in parts)
        if obj.lights is not None:
            obj.lights.use(location=1)
        self._set(program, "lights", 1)
        self._set(program, "n_lights", n)
        self._set(program, "light_stride", obj.n_lights)
        self._set(program, "per_light", int(obj.per_light))
        self._set(program, "coefficient_base", self.layout.address(obj.coefficient_base))

    def _bind_reference(self, program, obj, parts=PARTS):
        self.store.bind(program)
        self._bind_highlight(program, obj, "reference", "emitters" in parts)
        self._set(program, "base", self.layout.address(obj.base))
        self._set(program, "grid_n", obj.grid_n)

    def _draw_background(self, view, size):
        """The environment where no object is (background_fragment.glsl), into the
        framebuffer in use of ``size``, after the objects."""
        env = self.environment
        if self._environment_texture is None:
            image = np.ascontiguousarray(env.image, np.float32)
            texture = self.ctx.texture((image.shape[1], image.shape[0]), 3, image.tobytes(), dtype="f4")
            texture.repeat_x, texture.repeat_y = True, False
            texture.filter = (moderngl.LINEAR, moderngl.LINEAR)
            self._environment_texture = texture
        program = self._program("background", extra=("VL_REVERSED_Z",) if self.depth.reversed else ())
        right, up, forward = view.basis
        t = math.tan(math.radians(view.fov_y_deg) / 2)
        self._environment_texture.use(location=7)
        program["environment"].value = 7
        program["env_rotation"].write(np.asarray(env.rotation, np.float32).T.tobytes())  # column-major
        program["env_scale"].value = float(env.scale)
        for name, vector in (("cam_right", right), ("cam_up", up), ("cam_forward", forward)):
            program[name].value = tuple(float(c) for c in vector)
        program["cam_extent"].value = (t * view.width / view.height, t)
        program["viewport"].value = tuple(float(c) for c in size)
        self.ctx.enable(moderngl.DEPTH_TEST)
        self.ctx.depth_func = self.depth.far_or_equal
        if program not in self._full_screens:
            self._full_screens[program] = self.ctx.vertex_array(program, [])
        self._full_screens[program].render(moderngl.TRIANGLES, vertices=3)

    def _framebuffers_for(self, size, targets, samples):
        """The framebuffers of this size, targets and samples: made on first use, kept for
        the next frame (a walkthrough draws many), released with the renderer."""
        key = (size, targets, samples)
        if key not in self._framebuffers:
            check_image_size(self.ctx, *size, flag="image")
            plan = check_samples(self.ctx, samples, *size, flag="samples")
            if targets > 1 and plan.per_pixel > 1:
                raise ValueError("several render targets are drawn with one sample per pixel only")
            self._framebuffers[key] = _Framebuffers(self.ctx, size, targets, plan, self.depth_control)
        return self._framebuffers[key]

    def _average(self, fbs):
        """The image of ``fbs`` once drawn: its samples averaged (MSAA), then its blocks
        (supersampling). Returns the framebuffer holding it."""
        if fbs.resolved is not None:
            self.ctx.copy_framebuffer(fbs.resolved, fbs.scene)
        if fbs.plan.factor == 1:
            return fbs.output
        program = self._program("box")
        fbs.output.use()
        self.ctx.viewport = (0, 0, *fbs.output.size)
        fbs.single.color_attachments[0].use(location=0)
        program["image"].value = 0
        program["factor"].value = fbs.plan.factor
        self._full_screen(program)
        return fbs.output

    def _full_screen(self, program):
        """One triangle over the viewport with ``program`` (full_screen_vertex.glsl), no depth test."""
        self.ctx.disable(moderngl.DEPTH_TEST)
        if program not in self._full_screens:
            self._full_screens[program] = self.ctx.vertex_array(program, [])
        self._full_screens[program].render(moderngl.TRIANGLES, vertices=3)

    def show(self, fbo, exposure=1.0):
        """Draw the image of ``fbo`` (``draw``'s: colour attachment 0) tone-mapped into the
        framebuffer in use, of the same size: exposure, clip, sRGB (tonemap.glsl: the
        formula of ``tonemap``, the rounding to 8 bits left to the target)."""
        program = self._program("tonemap")
        self.ctx.viewport = (0, 0, *self.ctx.fbo.size)
        fbo.color_attachments[0].use(location=0)
        program["hdr"].value = 0
        program["exposure"].value = float(exposure)
        self._full_screen(program)

    def draw(self, view, mode="fitted", shading="pixel", lights=None, *, targets=1, program_key=None, mask=None,
             samples=None, parts=PARTS, with_glass=True):
        """Draw, average the samples, and return the float framebuffer holding the image
        (colour attachment 0, a texture of the view's size; reused between calls, released
        with the renderer). ``samples`` per pixel (None: the renderer's). With ``mask`` (a
        set of object names) every object is drawn flat: 1 for those named, 0 for the others.
        ``parts``: the parts of the model drawn (of ``PARTS``: "lights", "probe", "emitters";
        the solution display has the emitters' highlights only). Glass objects are drawn last,
        from their probes (``display.glass``, ``glass_approach``), unless ``with_glass`` is
        False (their probes are drawn so) or the draw is a mask's or the attributes'."""
        unknown = set(parts) - set(PARTS)
        if unknown:
            raise InputError(f"unknown part {sorted(unknown)[0]!r} of the model; the parts are {', '.join(PARTS)}")
        if "lights" not in parts:
            lights = 0
        if mode not in self.modes:
            raise InputError(f"mode {MODE_WORDS.get(mode, mode)!r} needs {'a solution' if mode == 'reference' else 'a fitted model'}; "
                             f"this input has {', '.join(MODE_WORDS[m] for m in self.modes)}")
        if shading not in SHADINGS:
            raise InputError(f"unknown shading {shading!r}; choose one of {', '.join(SHADINGS)}")
        ctx = self.ctx
        shown = with_glass and mask is None and program_key is None and targets == 1
        glassy = self.glass_pieces if shown and self.glass_approach != "none" else []
        eye = np.asarray(view.eye, np.float64)
        mirrors = [o for o in self.objects if o.mirror is not None and (  # a flat one facing away shows nothing
            o.plane is None or (eye - o.plane[0]) @ o.plane[1] > 0)] if shown and self.mirrors else []
        # what they show is drawn before this frame: probes once, a flat piece's reflected view every frame
        probes = [self._glass_probe(o, mode, shading, lights, parts)
                  if o.plane is None or self.glass_approach == "probe" else None for o in glassy]
        # a glass piece reflects F (a few percent) of it: drawn at half the size, one sample a pixel
        planes = [self._mirror_image(o, view, mode, shading, lights, 1, parts, scale=GLASS_REFLECTION_SCALE)
                  if o.plane is not None else None for o in glassy]
        seen = [self._mirror_image(o, view, mode, shading, lights, samples, parts) for o in mirrors]
        near = [o for o in self.objects if o.near is not None and (eye - o.plane[0]) @ o.plane[1] > 0] \
            if shown and self.near_mirrors and mode != "diffuse" else []
        near_seen = [self._mirror_image(o, view, mode, shading, lights, samples, parts) for o in near]
        fbs = self._framebuffers_for((view.width, view.height), targets, self.samples if samples is None else samples)
        fbs.scene.use()
        ctx.viewport = (0, 0, *fbs.scene.size)
        with self._depth_convention():
            ctx.clear(0.0, 0.0, 0.0, 0.0, depth=self.depth.clear)
            self._draw_objects(view, mode, shading, lights, program_key, mask, parts, {o.name for o in near})
            if self.environment is not None and mask is None and program_key is None and targets == 1:
                self._draw_background(view, fbs.scene.size)
            if mirrors:
                self._draw_mirrors(view, mirrors, seen)
            if near:
                self._draw_near_mirrors(view, mode, near, near_seen)
            if glassy:
                self._draw_glass(view, glassy, probes, planes)
            ctx.depth_func = "<"  # moderngl's default, for whatever draws next with the context
        return self._average(fbs)

    def _depth_convention(self):
        """Inside: the renderer's depth convention (``Depth``): clip z from 0 to w where it
        is reversed (``display.gl.DepthControl.zero_to_one``)."""
        return self.depth_control.zero_to_one() if self.depth_control is not None else contextlib.nullcontext()

    def _draw_objects(self, view, mode, shading, lights, program_key, mask, parts, near=frozenset()):
        """Every object's front faces shaded (back faces culled), then every back face
        black with a strict depth test (front faces culled): the module's "Sides and
        depth". The near mirrors named in ``near`` are left to ``_draw_near_mirrors``."""
        ctx = self.ctx
        ctx.enable(moderngl.DEPTH_TEST | moderngl.CULL_FACE)
        ctx.front_face = "ccw"  # the geometric normal's side: (b - a) x (c - a)
        ctx.cull_face = "back"
        ctx.depth_func = self.depth.nearer
        mvp = self._matrices(view)
        eye = tuple(float(v) for v in view.eye)
        ready = set()
        clip = ("VL_CLIP",) if self._clip is not None else ()
        for index, obj in enumerate(self.objects):
            if obj.glass is not None or (obj.mirror is not None and self.mirrors) or obj.name in near:
                continue  # drawn last, from what they show (``_draw_glass``, ``_draw_mirrors``, ``_draw_near_mirrors``)
            key = program_key
            n = self._light_count(obj, mode, lights)
            # per-light coefficients and the emitters' visibility: by vertex ids and barycentrics
            pixel = shading == "pixel" and (obj.per_light or "fitted" in obj.highlight)
            if key == "attributes":  # what the per-pixel program of this object sees
                key = "attributes-pixel" if pixel else "attributes"
            elif key is None and mode == "reference":
                key = f"reference-{shading}"
            elif key is None:
                # per vertex: the colour alone crosses to the fragments; per pixel: the
                # coefficients (per-light ones through the geometry shader's program,
                # in every mode, so that all modes rasterise alike)
                key = "gouraud" if shading == "gouraud" and mask is None else "fitted-pixel" if pixel else "fitted"
            drawn = self._drawn_parts(obj, mode, parts, n) if mask is None else ()
            textured = obj.textured is not None and mask is None and key != "attributes" and key != "attributes-pixel"
            cut = textured and obj.cutout is not None
            program = self._program(key, drawn, textured, clip + (("VL_CUTOUT",) if cut else ()))
            if (key, drawn, textured, cut) not in ready:
                program["mvp"].write(mvp)
                self._set(program, "clip_plane", self._clip)
                self._set(program, "eye", eye)
                self._set(program, "gouraud", int(shading == "gouraud"))
                ready.add((key, drawn, textured, cut))
            if textured:
                obj.textured[0].use(location=6)
                self._set(program, "diffuse_texture", 6)
                self._set(program, "texture_kd", obj.textured[1])
            if cut:
                obj.cutout.use(location=CUTOUT_UNIT)
                self._set(program, "cutout_texture", CUTOUT_UNIT)
            if key.startswith("reference"):
                self._bind_reference(program, obj, parts)
                attributes = ("in_position", "in_normal", "in_tangent", "in_uv", "in_irradiance")
            else:
                self._bind_fitted(program, obj, n, mode, parts if mask is None else ())
                flat = (0.0, 0.0, 0.0, 0.0) if mask is None else ((1.0,) * 3 + (1.0,) if obj.name in mask else (0.0, 0.0, 0.0, 1.0))
                self._set(program, "flat_colour", flat)
                self._set(program, "object_index", index)
                attributes = ("in_position", "in_normal", "in_emitted", "in_specular", "in_probe", "in_uv", "in_irradiance")
            # diffuse with a solution: its directional mean, not the fitted emitted colour
            # (with a probe or highlights that is only part of what is diffuse)
            sources = {"in_emitted": "in_mean"} if mode == "diffuse" and mask is None and "in_mean" in obj.buffers else None
            obj.vao(ctx, program, attributes, sources=sources).render(moderngl.TRIANGLES)
        # the backs, after every front: black where nearer than every front (strictly); a
        # masked object's with its holes
        back_key = "back-attributes" if program_key == "attributes" else "back"
        cuts = (False, True) if any(o.cutout is not None for o in self.objects) else (False,)
        backs = {cut: self._program(back_key, extra=clip + (("VL_CUTOUT",) if cut else ())) for cut in cuts}
        for program in backs.values():
            program["mvp"].write(mvp)
            self._set(program, "clip_plane", self._clip)
        ctx.cull_face = "front"
        ctx.polygon_offset = self.depth.back_offset
        for obj in self.objects:
            if obj.glass is not None or (obj.mirror is not None and self.mirrors):
                continue  # glass has no back; a mirror's is drawn with it, and never inside its own probe
            program = backs[obj.cutout is not None]
            if obj.cutout is not None:
                obj.cutout.use(location=CUTOUT_UNIT)
                self._set(program, "cutout_texture", CUTOUT_UNIT)
            obj.vao(ctx, program, ("in_position", "in_uv")).render(moderngl.TRIANGLES)
        ctx.polygon_offset = (0.0, 0.0)
        ctx.cull_face = "back"
        ctx.disable(moderngl.CULL_FACE)

    def _glass_probe(self, obj, mode, shading, lights, parts):
        """The probe texture of glass object ``obj`` for this way of drawing: the scene
        without its glass drawn from the object's centre (``display.glass``), made on first
        use and kept."""
        key = (obj.name, mode, shading, lights, tuple(parts))
        if key not in self._glass_probes:
            views = glass.cube_views(obj.sphere[0], glass.PROBE_SIZE)
            faces = [self.render(v, mode, shading, lights, samples=1, parts=parts, with_glass=False) for v in views]
            self._glass_probes[key] = glass.probe_texture(self.ctx, glass.octahedral_from_faces(faces, views))
        return self._glass_probes[key]

    def _mirror_image(self, obj, view, mode, shading, lights, samples, parts, scale=1):
        """What a mirror or a glass piece ``obj`` reflects in ``view``: a flat one's (texture,
        the reflected view's model-view-projection), the scene drawn from the eye reflected in
        its plane with what lies beyond the plane from the eye clipped away (at 1 / ``scale``
        of the view's size); a curved one's probe (``_glass_probe``), None."""
        if obj.plane is None:
            return self._glass_probe(obj, mode, shading, lights, parts), None
        p, n = obj.plane
        reflected = mirror.mirrored_view(view, obj.plane)
        if scale > 1:
            reflected = dataclasses.replace(reflected, width=max(1, -(-view.width // scale)),
                                            height=max(1, -(-view.height // scale)))
        side = 1.0 if (np.asarray(view.eye, np.float64) - p) @ n >= 0 else -1.0
        # what lies in the plane itself (a near mirror, the twin of a two-sided one) is clipped too
        lift = CLIP_LIFT * float(np.linalg.norm(np.subtract(*self.bounds[::-1])))
        self._clip = (*(side * float(v) for v in n), -side * float(n @ p) - lift)
        self.ctx.enable_direct(GL_CLIP_DISTANCE0)
        try:
            image = self.render(reflected, mode, shading, lights, samples=samples, parts=parts, with_glass=False)
        finally:
            self.ctx.disable_direct(GL_CLIP_DISTANCE0)
            self._clip = None
        old = self._mirror_images.pop(obj.name, None)
        if old is not None:
            old.release()
        texture = self.ctx.texture((reflected.width, reflected.height), 3, np.ascontiguousarray(image[::-1]).tobytes(),
                                   dtype="f4")
        texture.filter = (moderngl.LINEAR, moderngl.LINEAR)
        texture.repeat_x = texture.repeat_y = False
        self._mirror_images[obj.name] = texture
        return texture, self._matrices(reflected)

    def _last_pass(self, key, view, textured=False):
        """Program ``key`` (with a textured object's term if ``textured``) ready for a pass
        over what is drawn: depth-tested, both faces, the view's matrices and eye set."""
        self.ctx.enable(moderngl.DEPTH_TEST)
        self.ctx.disable(moderngl.CULL_FACE)
        self.ctx.depth_func = self.depth.nearer
        program = self._program(key, textured=textured)
        program["mvp"].write(self._matrices(view))
        self._set(program, "eye", tuple(float(v) for v in view.eye))
        return program

    def _draw_mirrors(self, view, objects, seen):
        """The perfect mirrors ``objects`` over what is drawn (depth-tested, their backs
        black): ks F times what ``seen`` holds for each (``_mirror_image``; mirror_fragment.glsl)."""
        ctx, program, (lo, hi) = self.ctx, self._last_pass("mirror", view), self.bounds
        for obj, (texture, reflected_mvp) in zip(objects, seen, strict=True):
            ks, f0 = obj.mirror
            planar = reflected_mvp is not None
            texture.use(location=9 if planar else 8)
            values = {"glass_planar": int(planar), "glass_image": 9, "glass_probe": 8, "glass_size": glass.PROBE_SIZE,
                      "mirror_ks": tuple(map(float, ks)), "mirror_fresnel": int(f0 is not None),
                      "mirror_f0": tuple(map(float, f0)) if f0 is not None else (0.0, 0.0, 0.0),
                      "glass_centre": tuple(map(float, obj.sphere[0])), "glass_lo": tuple(map(float, lo)),
                      "glass_hi": tuple(map(float, hi))}
            for name, value in values.items():
                self._set(program, name, value)
            if planar and "glass_mvp" in program:
                program["glass_mvp"].write(reflected_mvp)
            obj.vao(ctx, program, ("in_position", "in_normal")).render(moderngl.TRIANGLES)

    def _draw_near_mirrors(self, view, mode, objects, seen):
        """The near mirrors ``objects`` (depth-tested, their backs black): their base and
        textured term plus ks (F0 norm + (1 - F0) schlick) times the scene in their plane that
        ``seen`` holds for each (``_mirror_image``; near_fragment.glsl). Their base: the
        solution's (``radiosity.physics.materials.near_base``) in the solution display, the
        fit's (the same, as fit.npz keeps it: version 10) in the fitted one, else its emitted
        colour."""
        ctx, (lo, hi), table = self.ctx, self.bounds, self._ltc_texture()
        for obj, (texture, reflected_mvp) in zip(objects, seen, strict=True):
            textured = obj.textured is not None
            program = self._last_pass("near", view, textured)
            texture.use(location=9)
            if textured:
                obj.textured[0].use(location=6)
            table.use(location=LTC_UNIT)
            lobe = obj.near
            values = {"glass_planar": 1, "glass_image": 9, "glass_centre": tuple(map(float, obj.plane[0])),
                      "glass_lo": tuple(map(float, lo)), "glass_hi": tuple(map(float, hi)), "ltc_table": LTC_UNIT,
                      "near_ks": tuple(map(float, lobe.ks)), "near_f0": tuple(map(float, lobe.f0)),
                      "near_lobe": int(lobe.code), "near_alpha": float(lobe.alpha), "diffuse_texture": 6,
                      "texture_kd": obj.textured[1] if textured else (0.0, 0.0, 0.0)}
            for name, value in values.items():
                self._set(program, name, value)
            if "glass_mvp" in program:
                program["glass_mvp"].write(reflected_mvp)
            if mode == "reference" and "in_base" in obj.buffers:
                base, eta = "in_base", obj.near_eta
            elif mode != "reference" and "in_fit_base" in obj.buffers:
                base, eta = "in_fit_base", obj.fit_near_eta
            else:
                base, eta = "in_emitted", 0.0
            self._set(program, "near_eta", eta)
            obj.vao(ctx, program, ("in_position", "in_normal", "in_emitted", "in_uv", "in_irradiance"),
                    sources={"in_emitted": base}).render(moderngl.TRIANGLES)

    def _draw_glass(self, view, objects, probes, planes):
        """The glass pieces ``objects`` over what is drawn (either face, depth-tested): what they
        reflect from ``planes`` (a flat piece's reflected view, ``_mirror_image``) or their
        ``probes``, what passes through from the probes or, for sheets and slabs where
        ``glass_approach`` is "blend", blended over what is behind them (glass.glsl)."""
        ctx, program, (lo, hi) = self.ctx, self._last_pass("glass", view), self.bounds
        for obj, probe, plane in zip(objects, probes, planes, strict=True):
            g = obj.glass
            blend = self.glass_approach == "blend" and (obj.slab or g.kind == "thindielectric")
            if probe is not None:
                probe.use(location=8)
            if plane is not None:
                plane[0].use(location=9)
                if "glass_mvp" in program:
                    program["glass_mvp"].write(plane[1])
            values = {"glass_planar": int(plane is not None), "glass_image": 9,
                      "glass_probe": 8, "glass_size": glass.PROBE_SIZE, "glass_centre": tuple(map(float, obj.sphere[0])),
                      "glass_lo": tuple(map(float, lo)), "glass_hi": tuple(map(float, hi)),
                      "glass_kind": {"dielectric": 0, "thindielectric": 1, "roughdielectric": 2}[g.kind],
                      "glass_eta": float(g.eta), "glass_alpha": float(g.alpha),
                      "glass_reflectance": g.specular_reflectance, "glass_transmittance": g.specular_transmittance,
                      "glass_proxy": int(not (obj.slab or g.kind == "thindielectric")),
                      "glass_sphere": (*map(float, obj.sphere[0]), float(obj.sphere[1])), "glass_blend": int(blend)}
            for name, value in values.items():
                self._set(program, name, value)
            if blend:
                ctx.enable(moderngl.BLEND)
                ctx.blend_func = moderngl.ONE, moderngl.ONE_MINUS_SRC_ALPHA
            obj.vao(ctx, program, ("in_position", "in_normal")).render(moderngl.TRIANGLES)
            ctx.disable(moderngl.BLEND)

    def render(self, view, mode="fitted", shading="pixel", lights=None, *, samples=None, parts=PARTS,
               with_glass=True):
        """Linear radiance (H, W, 3) float32, row 0 at the top, the background the
        environment (or 0): each pixel
        the mean of its ``samples`` (None: the renderer's).

        ``lights``: use only the first K lights of each object (None: all); ``parts``: the
        parts of the model drawn (``draw``)."""
        return self._read(self.draw(view, mode, shading, lights, samples=samples, parts=parts, with_glass=with_glass), 0)

    def object_mask(self, view, names):
        """(H, W) bool: pixels whose centre sees one of the objects ``names`` (one sample)."""
        return self._read(self.draw(view, "diffuse", "pixel", mask=set(names), samples=1), 0)[..., 0] > 0.5

    def _read(self, fbo, attachment, components=3):
        """Attachment ``attachment`` as (H, W, components) float32, row 0 at the top."""
        texture = fbo.color_attachments[attachment]
        data = np.frombuffer(texture.read(), np.float32).reshape(texture.height, texture.width, 4)[::-1]
        return np.ascontiguousarray(data[..., :components])

    def release(self):
        for o in (*self.objects, *self.glass_pieces):
            o.release()
        self.images.release()
        for p in self._programs.values():
            p.release()
        for texture in (self.store, self.probes, self._environment_texture, self.ltc, *self.emitter_tables.values(),
                        *self._glass_probes.values(), *self._mirror_images.values()):
            if texture is not None:
                texture.release()
        for resource in self._full_screens.values():
            resource.release()
        for fbs in self._framebuffers.values():
            fbs.release()
