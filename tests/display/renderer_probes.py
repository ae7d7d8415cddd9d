"""The renderer with the probes the tests read it through: what the per-pixel shader
sees at each pixel (``render_attributes``), which triangle and barycentrics each pixel
interpolates (``render_triangles``), and the Gouraud shader's vertex colours read back by
transform feedback (``vertex_colours``). They draw with the production programs and
state; they live here, not in the renderer, because only tests ask for them."""

import moderngl
import numpy as np

from display.renderer import PARTS, Renderer


class ProbedRenderer(Renderer):
    """A ``display.renderer.Renderer`` (same arguments) with the tests' probes."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self._scratch = None  # transform feedback's framebuffer, made when first needed

    def release(self):
        if self._scratch is not None:
            self._scratch.release()
        super().release()

    def _attribute_targets(self, view):
        """One draw of the attributes program (one sample, at the pixel centres): its six
        targets read back (H, W, 4)."""
        fbo = self.draw(view, "fitted", "pixel", targets=6, program_key="attributes", samples=1)
        return [self._read(fbo, i, components=4) for i in range(6)]

    @staticmethod
    def _triangles(targets):
        covered = targets[0][..., 3] > 0  # alpha of target 0 marks coverage
        ids = targets[5]  # vertex ids as float32: exact below 2^24
        obj = np.where(covered, np.rint(ids[..., 3]).astype(np.int64), -1)
        return obj, np.where(covered[..., None], np.rint(ids[..., :3]).astype(np.int64), -1), targets[4][..., :3]

    def render_triangles(self, view):
        """What each pixel's fragment interpolates from: (object (H, W) int, -1 for the
        background; vertices (H, W, 3) int, its triangle's vertex ids; barycentrics
        (H, W, 3) float32), row 0 at the top. Ids and barycentrics come from the
        geometry shader of the per-light program: for objects whose coefficients are
        shared (drawn without it) they are -1 and 0."""
        return self._triangles(self._attribute_targets(view))

    def render_attributes(self, view):
        """Per-pixel interpolated (position, normal, emitted, specular, coverage) as
        float arrays, row 0 at the top: what the per-pixel shader sees (for tests).

        specular is (H, W, 3) when every object shares its coefficient among its lights;
        when one has per-light coefficients, (H, W, K, 3) for K the most lights of an
        object: per-light ones blended with the fragment's barycentrics over its
        triangle's vertices (float64, as the fragment shader blends them), shared ones
        repeated for each light, zero past an object's own lights."""
        targets = self._attribute_targets(view)
        position, normal, emitted, specular = (t[..., :3] for t in targets[:4])
        covered = targets[0][..., 3] > 0
        if any(o.per_light for o in self.objects):
            obj_index, vertices, bary = self._triangles(targets)
            k_max = max(o.n_lights for o in self.objects)
            per_light = np.zeros(specular.shape[:2] + (k_max, 3))
            for i, o in enumerate(self.objects):
                here = obj_index == i
                if not here.any() or not o.n_lights:
                    continue
                if o.per_light:
                    c = np.asarray(o.specular, np.float64)[vertices[here]]  # (P, 3 vertices, K, 3)
                    per_light[here, : o.n_lights] = np.einsum("pv,pvkc->pkc", bary[here].astype(np.float64), c)
                else:
                    per_light[here, : o.n_lights] = specular[here][:, None, :]
            specular = per_light
        return position, normal, emitted, specular, covered

    def vertex_colours(self, view, name, mode="fitted", lights=None):
        """The Gouraud vertex shader's colours (V, 3) of object ``name`` for ``mode``,
        read back by transform feedback (what is interpolated across the triangles)."""
        key = "reference-feedback" if mode == "reference" else "fitted-feedback"
        obj = next(o for o in self.objects if o.name == name)
        program = self._program(key, self._drawn_parts(obj, mode, PARTS, self._light_count(obj, mode, lights)))
        program["mvp"].write(self._matrices(view))
        self._set(program, "eye", tuple(float(v) for v in view.eye))
        if mode == "reference":
            self._bind_reference(program, obj)
            attributes = ("in_position", "in_normal", "in_tangent")
        else:
            self._bind_fitted(program, obj, self._light_count(obj, mode, lights), mode)
            attributes = ("in_position", "in_normal", "in_emitted", "in_specular", "in_probe")
        vao = obj.vao(self.ctx, program, attributes, indexed=False)  # gl_VertexID = 0 .. V-1
        out = self.ctx.buffer(reserve=obj.n_vertices * 12)
        if self._scratch is None:  # transform feedback writes nothing without a bound framebuffer
            self._scratch = self.ctx.simple_framebuffer((1, 1))
        self._scratch.use()
        vao.transform(out, moderngl.POINTS, vertices=obj.n_vertices)
        colours = np.frombuffer(out.read(), np.float32).reshape(-1, 3).copy()
        out.release()
        return colours
