"""The renderer: draws a fitted model and/or a solution from a camera into an HDR image.

It knows nothing of windows: give it a moderngl context (``display.gl``) and it draws
into its own float framebuffer and reads back linear radiance, (H, W, 3) float32, row 0
at the top, background 0. Exposure and sRGB come last, in ``tonemap``.

Modes
    fitted     the fitted model's shading formula (``fitting.model``; any number of lights per object)
    diffuse    the emitted colour alone: the fitted model without its virtual lights
               (the paper's figure 7); from a solution alone, its radiance averaged
               over directions
    reference  the solution's directional radiance, bilinear in the equal-area grid
               of each vertex (read in that vertex's frame) for the view direction
Shading
    gouraud    evaluated at the vertices and interpolated (as in 1997)
    pixel      evaluated per fragment: for "fitted" with interpolated normal and
               coefficients, for "reference" the three vertices' grids read with the
               fragment's own view direction and blended barycentrically
"""

from __future__ import annotations

import math

import moderngl
import numpy as np

from radiosity.formats.errors import InputError

from .gl import check_image_size

MODES = ("fitted", "diffuse", "reference")
SHADINGS = ("gouraud", "pixel")
RADIANCE_TEXTURE_WIDTH = 4096

SHADE_GLSL = """
uniform int n_lights;
uniform sampler2D lights;   // row k: (direction, shininess), (rgb, 0)
vec3 shade(vec3 n, vec3 w, vec3 emitted, vec3 specular) {
    vec3 colour = emitted;
    for (int k = 0; k < n_lights; ++k) {
        vec4 a = texelFetch(lights, ivec2(0, k), 0);
        vec3 rgb = texelFetch(lights, ivec2(1, k), 0).rgb;
        vec3 h = a.xyz + w;
        float len = length(h);
        if (len > 0.0) {
            float c = dot(n, h) / len;
            if (c > 0.0) colour += pow(c, a.w) * rgb * specular;
        }
    }
    return colour;
}
"""

FITTED_VS = """
#version 330
uniform mat4 mvp;
uniform vec3 eye;
uniform int gouraud;
in vec3 in_position;
in vec3 in_normal;
in vec3 in_emitted;
in vec3 in_specular;
out vec3 v_position;
out vec3 v_normal;
out vec3 v_emitted;
out vec3 v_specular;
out vec3 v_colour;
""" + SHADE_GLSL + """
void main() {
    gl_Position = mvp * vec4(in_position, 1.0);
    v_position = in_position;
    v_normal = in_normal;
    v_emitted = in_emitted;
    v_specular = in_specular;
    v_colour = gouraud == 1 ? shade(normalize(in_normal), normalize(eye - in_position), in_emitted, in_specular) : vec3(0.0);
}
"""

GOURAUD_VS = """
#version 330
uniform mat4 mvp;
uniform vec3 eye;
in vec3 in_position;
in vec3 in_normal;
in vec3 in_emitted;
in vec3 in_specular;
out vec3 v_colour;
""" + SHADE_GLSL + """
void main() {
    gl_Position = mvp * vec4(in_position, 1.0);
    v_colour = shade(normalize(in_normal), normalize(eye - in_position), in_emitted, in_specular);
}
"""

FITTED_FS = """
#version 330
uniform vec3 eye;
uniform int gouraud;
uniform vec4 flat_colour;   // w > 0: draw this colour instead (object masks)
in vec3 v_position;
in vec3 v_normal;
in vec3 v_emitted;
in vec3 v_specular;
in vec3 v_colour;
out vec4 f_colour;
""" + SHADE_GLSL + """
void main() {
    vec3 c = gouraud == 1 ? v_colour : shade(normalize(v_normal), normalize(eye - v_position), v_emitted, v_specular);
    f_colour = flat_colour.w > 0.0 ? vec4(flat_colour.rgb, 1.0) : vec4(c, 1.0);
}
"""

ATTRIBUTES_FS = """
#version 330
in vec3 v_position;
in vec3 v_normal;
in vec3 v_emitted;
in vec3 v_specular;
in vec3 v_colour;
layout(location = 0) out vec4 f_position;
layout(location = 1) out vec4 f_normal;
layout(location = 2) out vec4 f_emitted;
layout(location = 3) out vec4 f_specular;
void main() {
    f_position = vec4(v_position, 1.0);
    f_normal = vec4(v_normal, 0.0);
    f_emitted = vec4(v_emitted, 0.0);
    f_specular = vec4(v_specular, 0.0);
}
"""

LOOKUP_GLSL = """
uniform sampler2D radiance;  // every object's radiance, texel base + vertex * D + d
uniform int base;
uniform int grid_n;          // 0 for a diffuse object (D = 1)
const int TEXTURE_WIDTH = RADIANCE_TEXTURE_WIDTH;
const float FOUR_OVER_PI = 1.2732395447351628;
vec3 fetch(int index) {
    return texelFetch(radiance, ivec2(index % TEXTURE_WIDTH, index / TEXTURE_WIDTH), 0).rgb;
}
vec2 hemisphere_to_square(vec3 w) {   // radiosity.formats.directions.hemisphere_to_square
    w = normalize(w);
    float z = clamp(w.z, 0.0, 1.0);
    float radius = z > 0.5 ? length(w.xy) / sqrt(1.0 + z) : sqrt(1.0 - z);
    float t = (w.x == 0.0 && w.y == 0.0) ? 0.0 : atan(w.y, w.x) * FOUR_OVER_PI;
    float a;
    float b;
    if (abs(t) < 1.0) { a = radius; b = radius * t; }
    else if (t >= 1.0 && t <= 3.0) { a = radius * (2.0 - t); b = radius; }
    else if (t <= -1.0 && t >= -3.0) { a = radius * (2.0 + t); b = -radius; }
    else { a = -radius; b = t > 0.0 ? radius * (4.0 - t) : -radius * (4.0 + t); }
    return clamp(vec2(a, b), -1.0, 1.0);
}
vec3 lookup(int vertex, vec3 n, vec3 t, vec3 w) {   // radiosity.formats.directions.grid_lookup_weights
    if (grid_n == 0) return fetch(base + vertex);
    int D = grid_n * grid_n;
    vec3 bt = cross(n, t);
    vec2 ab = hemisphere_to_square(vec3(dot(w, t), dot(w, bt), dot(w, n)));
    vec2 xy = (ab + 1.0) * 0.5 * float(grid_n) - 0.5;
    vec2 f0 = floor(xy);
    vec2 f = xy - f0;
    int i0 = clamp(int(f0.x), 0, grid_n - 1);
    int i1 = clamp(int(f0.x) + 1, 0, grid_n - 1);
    int j0 = clamp(int(f0.y), 0, grid_n - 1);
    int j1 = clamp(int(f0.y) + 1, 0, grid_n - 1);
    int row = base + vertex * D;
    vec3 low = mix(fetch(row + j0 * grid_n + i0), fetch(row + j0 * grid_n + i1), f.x);
    vec3 high = mix(fetch(row + j1 * grid_n + i0), fetch(row + j1 * grid_n + i1), f.x);
    return mix(low, high, f.y);
}
""".replace("RADIANCE_TEXTURE_WIDTH", str(RADIANCE_TEXTURE_WIDTH))

REFERENCE_GOURAUD_VS = """
#version 330
uniform mat4 mvp;
uniform vec3 eye;
in vec3 in_position;
in vec3 in_normal;
in vec3 in_tangent;
out vec3 v_colour;
""" + LOOKUP_GLSL + """
void main() {
    gl_Position = mvp * vec4(in_position, 1.0);
    v_colour = lookup(gl_VertexID, in_normal, in_tangent, normalize(eye - in_position));
}
"""

COLOUR_FS = """
#version 330
in vec3 v_colour;
out vec4 f_colour;
void main() { f_colour = vec4(v_colour, 1.0); }
"""

REFERENCE_PIXEL_VS = """
#version 330
uniform mat4 mvp;
in vec3 in_position;
in vec3 in_normal;
in vec3 in_tangent;
out vec3 g_position;
out vec3 g_normal;
out vec3 g_tangent;
flat out int g_vertex;
void main() {
    gl_Position = mvp * vec4(in_position, 1.0);
    g_position = in_position;
    g_normal = in_normal;
    g_tangent = in_tangent;
    g_vertex = gl_VertexID;
}
"""

REFERENCE_PIXEL_GS = """
#version 330
layout(triangles) in;
layout(triangle_strip, max_vertices = 3) out;
in vec3 g_position[];
in vec3 g_normal[];
in vec3 g_tangent[];
flat in int g_vertex[];
out vec3 f_position;
out vec3 f_bary;
flat out ivec3 f_vertices;
flat out vec3 f_n0;
flat out vec3 f_n1;
flat out vec3 f_n2;
flat out vec3 f_t0;
flat out vec3 f_t1;
flat out vec3 f_t2;
void main() {
    for (int i = 0; i < 3; ++i) {
        gl_Position = gl_in[i].gl_Position;
        f_position = g_position[i];
        f_bary = vec3(i == 0, i == 1, i == 2);
        f_vertices = ivec3(g_vertex[0], g_vertex[1], g_vertex[2]);
        f_n0 = g_normal[0]; f_n1 = g_normal[1]; f_n2 = g_normal[2];
        f_t0 = g_tangent[0]; f_t1 = g_tangent[1]; f_t2 = g_tangent[2];
        EmitVertex();
    }
    EndPrimitive();
}
"""

REFERENCE_PIXEL_FS = """
#version 330
uniform vec3 eye;
in vec3 f_position;
in vec3 f_bary;
flat in ivec3 f_vertices;
flat in vec3 f_n0;
flat in vec3 f_n1;
flat in vec3 f_n2;
flat in vec3 f_t0;
flat in vec3 f_t1;
flat in vec3 f_t2;
out vec4 f_colour;
""" + LOOKUP_GLSL + """
void main() {
    vec3 w = normalize(eye - f_position);
    vec3 c = f_bary.x * lookup(f_vertices.x, f_n0, f_t0, w)
           + f_bary.y * lookup(f_vertices.y, f_n1, f_t1, w)
           + f_bary.z * lookup(f_vertices.z, f_n2, f_t2, w);
    f_colour = vec4(c, 1.0);
}
"""


def tonemap(hdr, exposure=1.0):
    """Linear radiance (H, W, 3) -> 8-bit sRGB (H, W, 3) uint8: exposure, clip, sRGB."""
    x = np.clip(np.asarray(hdr, np.float64) * exposure, 0.0, 1.0)
    srgb = np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)
    return (np.clip(srgb, 0, 1) * 255 + 0.5).astype(np.uint8)


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
        self.lights = None
        self.n_lights = 0
        self.base = 0
        self.grid_n = 0
        self.bytes = sum(b.size for b in self.buffers.values()) + self.index.size

    def add(self, ctx, attribute, values):
        self.buffers[attribute] = ctx.buffer(np.asarray(values, np.float32).tobytes())
        self.bytes += self.buffers[attribute].size

    def vao(self, ctx, program, attributes):
        content = [(self.buffers[a], "3f", a) for a in attributes if a in program]
        return ctx.vertex_array(program, content, index_buffer=self.index, index_element_size=4)

    def release(self):
        for b in list(self.buffers.values()) + [self.index]:
            b.release()
        if self.lights is not None:
            self.lights.release()


class Renderer:
    """Draws ``fit`` (a ``fitting.FittedModel``) and/or ``solution`` (a
    ``radiosity.formats.solution.Solution``) with a moderngl context ``ctx``."""

    def __init__(self, ctx, fit=None, solution=None):
        if fit is None and solution is None:
            raise ValueError("give a fitted model, a solution, or both")
        self.ctx = ctx
        self.fit, self.solution = fit, solution
        self.modes = tuple(m for m in MODES if (m != "reference" or solution is not None) and (m != "fitted" or fit is not None))
        source = fit if fit is not None else solution
        self.objects = [_Object(ctx, o.name, o.positions, o.normals, o.faces) for o in source.objects]
        positions = np.concatenate([o.positions for o in self.objects])
        self.bounds = np.stack([positions.min(axis=0), positions.max(axis=0)]).astype(np.float64)
        self.radiance = None
        if fit is not None:
            for obj, f in zip(self.objects, fit.objects):
                obj.add(ctx, "in_emitted", f.emitted)
                obj.add(ctx, "in_specular", f.specular)
                obj.n_lights = f.n_lights
                table = np.zeros((max(f.n_lights, 1), 2, 4), np.float32)
                table[: f.n_lights, 0, :3] = f.light_dirs
                table[: f.n_lights, 0, 3] = f.shininess
                table[: f.n_lights, 1, :3] = f.light_rgb
                obj.lights = ctx.texture((2, len(table)), 4, table.tobytes(), dtype="f4")
                obj.lights.filter = (moderngl.NEAREST, moderngl.NEAREST)
        if solution is not None:
            self._upload_solution(solution)
        self._programs = {}
        self._framebuffers = {}
        self._scratch = None

    def _upload_solution(self, solution):
        ctx = self.ctx
        by_name = {o.name: o for o in solution.objects}
        chunks, base = [], 0
        for obj in self.objects:
            s = by_name.get(obj.name)
            if s is None or len(s.positions) != obj.n_vertices:
                raise InputError(f"the solution and the fitted model differ (object {obj.name!r})")
            obj.add(ctx, "in_tangent", s.tangents)
            if "in_emitted" not in obj.buffers:  # a solution alone: diffuse = radiance averaged over directions
                obj.add(ctx, "in_emitted", np.asarray(s.radiance, np.float64).mean(axis=1))
                obj.add(ctx, "in_specular", np.zeros((obj.n_vertices, 3)))
            obj.base = base
            obj.grid_n = 0 if s.is_diffuse else s.grid_n
            values = np.asarray(s.radiance, np.float32).reshape(-1, 3)
            chunks.append(values)
            base += len(values)
        width = RADIANCE_TEXTURE_WIDTH
        height = max(1, math.ceil(base / width))
        limit = ctx.info["GL_MAX_TEXTURE_SIZE"]
        if height > limit:
            raise InputError(
                f"the solution's radiance ({base:,} values) exceeds this OpenGL's texture size; use a coarser --grid or --max-edge"
            )
        data = np.zeros((height * width, 3), np.float32)
        data[:base] = np.concatenate(chunks)
        self.radiance = ctx.texture((width, height), 3, data.tobytes(), dtype="f4")
        self.radiance.filter = (moderngl.NEAREST, moderngl.NEAREST)

    @property
    def uploaded_bytes(self):
        """Bytes on the GPU: vertex and index buffers, light tables, radiance texture."""
        total = sum(o.bytes for o in self.objects)
        total += sum(o.lights.width * o.lights.height * 16 for o in self.objects if o.lights is not None)
        if self.radiance is not None:
            total += self.radiance.width * self.radiance.height * 12
        return total

    def _program(self, key):
        if key not in self._programs:
            sources = {
                "fitted": dict(vertex_shader=FITTED_VS, fragment_shader=FITTED_FS),
                "attributes": dict(vertex_shader=FITTED_VS, fragment_shader=ATTRIBUTES_FS),
                "reference-gouraud": dict(vertex_shader=REFERENCE_GOURAUD_VS, fragment_shader=COLOUR_FS),
                "reference-pixel": dict(
                    vertex_shader=REFERENCE_PIXEL_VS, geometry_shader=REFERENCE_PIXEL_GS, fragment_shader=REFERENCE_PIXEL_FS
                ),
                "gouraud": dict(vertex_shader=GOURAUD_VS, fragment_shader=COLOUR_FS),
                "fitted-feedback": dict(vertex_shader=GOURAUD_VS, varyings=["v_colour"]),
                "reference-feedback": dict(vertex_shader=REFERENCE_GOURAUD_VS, varyings=["v_colour"]),
            }[key]
            self._programs[key] = self.ctx.program(**sources)
        return self._programs[key]

    def _matrices(self, view):
        eye = np.asarray(view.eye, np.float64)
        centre = self.bounds.mean(axis=0)
        radius = 0.5 * np.linalg.norm(self.bounds[1] - self.bounds[0]) + 1e-9
        distance = np.linalg.norm(centre - eye)
        far = distance + 2 * radius
        near = max(far * 1e-5, (distance - radius) * 0.5)
        mvp = view.projection_matrix(near, far) @ view.view_matrix()
        return mvp.T.astype(np.float32).tobytes()  # column-major for GLSL

    def _set(self, program, name, value):
        if name in program:
            program[name].value = value

    def draw(self, view, mode="fitted", shading="pixel", lights=None, targets=1, program_key=None, mask=None):
        """Draw into the renderer's float framebuffer for this size (reused between calls,
        released with the renderer) and return it. With ``mask`` (a
        set of object names) every object is drawn flat: 1 for those named, 0 for the others."""
        if mode not in self.modes:
            raise InputError(f"mode {mode!r} needs {'a solution' if mode == 'reference' else 'a fitted model'}; this input has {', '.join(self.modes)}")
        if shading not in SHADINGS:
            raise InputError(f"unknown shading {shading!r}; choose one of {', '.join(SHADINGS)}")
        ctx = self.ctx
        size = (view.width, view.height)
        fbo = self._framebuffers.get((size, targets))
        if fbo is None:  # kept for the next frame of this size: a walkthrough draws many
            check_image_size(ctx, *size, flag="image")
            colour = [ctx.texture(size, 4, dtype="f4") for _ in range(targets)]
            fbo = ctx.framebuffer(color_attachments=colour, depth_attachment=ctx.depth_renderbuffer(size))
            self._framebuffers[(size, targets)] = fbo
        fbo.use()
        ctx.viewport = (0, 0, *size)
        ctx.clear(0.0, 0.0, 0.0, 0.0, depth=1.0)
        ctx.enable(moderngl.DEPTH_TEST)
        ctx.disable(moderngl.CULL_FACE)  # one-sided surfaces are still seen from behind
        if program_key is None and mode in ("fitted", "diffuse"):
            # per vertex: the colour alone crosses to the fragments; per pixel: the coefficients
            program_key = "gouraud" if shading == "gouraud" and mask is None else "fitted"
        key = program_key or f"reference-{shading}"
        program = self._program(key)
        mvp = self._matrices(view)
        program["mvp"].write(mvp)
        self._set(program, "eye", tuple(float(v) for v in view.eye))
        self._set(program, "gouraud", int(shading == "gouraud"))
        for obj in self.objects:
            if key.startswith("reference"):
                self.radiance.use(location=0)
                self._set(program, "radiance", 0)
                self._set(program, "base", obj.base)
                self._set(program, "grid_n", obj.grid_n)
                attributes = ("in_position", "in_normal", "in_tangent")
            else:
                n = 0 if mode == "diffuse" or obj.lights is None else obj.n_lights
                if lights is not None:
                    n = min(n, lights)
                if obj.lights is not None:
                    obj.lights.use(location=1)
                self._set(program, "lights", 1)
                self._set(program, "n_lights", n)
                flat = (0.0, 0.0, 0.0, 0.0) if mask is None else ((1.0,) * 3 + (1.0,) if obj.name in mask else (0.0, 0.0, 0.0, 1.0))
                self._set(program, "flat_colour", flat)
                attributes = ("in_position", "in_normal", "in_emitted", "in_specular")
            vao = obj.vao(ctx, program, attributes)
            vao.render(moderngl.TRIANGLES)
            vao.release()
        return fbo

    def render(self, view, mode="fitted", shading="pixel", lights=None):
        """Linear radiance (H, W, 3) float32, row 0 at the top, background 0.

        ``lights``: use only the first K lights of each object (None: all)."""
        return self._read(self.draw(view, mode, shading, lights), 0)

    def object_mask(self, view, names):
        """(H, W) bool: pixels where one of the objects ``names`` is the visible surface."""
        return self._read(self.draw(view, "diffuse", "pixel", mask=set(names)), 0)[..., 0] > 0.5

    def render_attributes(self, view):
        """Per-pixel interpolated (position, normal, emitted, specular, coverage) as
        float arrays, row 0 at the top: what the per-pixel shader sees (for tests)."""
        fbo = self.draw(view, "fitted", "pixel", targets=4, program_key="attributes")
        out = [self._read(fbo, i, components=4) for i in range(4)]  # alpha of target 0 marks coverage
        return out[0][..., :3], out[1][..., :3], out[2][..., :3], out[3][..., :3], out[0][..., 3] > 0

    def vertex_colours(self, view, name, mode="fitted", lights=None):
        """The Gouraud vertex shader's colours (V, 3) of object ``name`` for ``mode``,
        read back by transform feedback (what is interpolated across the triangles)."""
        key = "reference-feedback" if mode == "reference" else "fitted-feedback"
        program = self._program(key)
        obj = next(o for o in self.objects if o.name == name)
        program["mvp"].write(self._matrices(view))
        self._set(program, "eye", tuple(float(v) for v in view.eye))
        self._set(program, "gouraud", 1)
        if mode == "reference":
            self.radiance.use(location=0)
            self._set(program, "radiance", 0)
            self._set(program, "base", obj.base)
            self._set(program, "grid_n", obj.grid_n)
            attributes = ("in_position", "in_normal", "in_tangent")
        else:
            n = 0 if mode == "diffuse" else (obj.n_lights if lights is None else min(lights, obj.n_lights))
            obj.lights.use(location=1)
            self._set(program, "lights", 1)
            self._set(program, "n_lights", n)
            attributes = ("in_position", "in_normal", "in_emitted", "in_specular")
        content = [(obj.buffers[a], "3f", a) for a in attributes if a in program]
        vao = self.ctx.vertex_array(program, content)
        out = self.ctx.buffer(reserve=obj.n_vertices * 12)
        if self._scratch is None:  # transform feedback writes nothing without a bound framebuffer
            self._scratch = self.ctx.simple_framebuffer((1, 1))
        self._scratch.use()
        vao.transform(out, moderngl.POINTS, vertices=obj.n_vertices)
        colours = np.frombuffer(out.read(), np.float32).reshape(-1, 3).copy()
        vao.release()
        out.release()
        return colours

    def _read(self, fbo, attachment, components=3):
        """Attachment ``attachment`` as (H, W, components) float32, row 0 at the top."""
        texture = fbo.color_attachments[attachment]
        data = np.frombuffer(texture.read(), np.float32).reshape(texture.height, texture.width, 4)[::-1]
        return np.ascontiguousarray(data[..., :components])

    def _release(self, fbo):
        for t in fbo.color_attachments:
            t.release()
        if fbo.depth_attachment is not None:
            fbo.depth_attachment.release()
        fbo.release()

    def release(self):
        for o in self.objects:
            o.release()
        for p in self._programs.values():
            p.release()
        if self.radiance is not None:
            self.radiance.release()
        if self._scratch is not None:
            self._scratch.release()
        for fbo in self._framebuffers.values():
            self._release(fbo)
