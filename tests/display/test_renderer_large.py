"""A float store larger than one texture (a solution of 10^8 radiance values).

The renderer keeps every per-vertex float array the shaders read by index (radiance
grids, per-light coefficients, the emitters' visibility) in paged 2D array textures
(``display.store``, read by ``display/shaders/store.glsl``). Here the limits are forced
small (16 rows a layer: 65,536 values; a texture a layer) so that a scene of a few
hundred thousand values spans several layers and textures, with blocks that straddle
them: its pictures equal those of the same scene in one texture, and its vertex colours
the numpy references (``radiosity.physics.directions.grid_lookup_weights`` for the
reference display, ``FittedObject.shade`` for the fitted one). The GLSL address
arithmetic is checked against Python's integers past 2^31 and 2^32 values; the memory
refusal against a patched free memory. The real run (``slow``) draws 1.3e8
vertex-direction samples (64 x 64 grids)."""

import moderngl
import numpy as np
import pytest
import trimesh
from renderer_probes import ProbedRenderer

import display.renderer
import display.store
from display.glsl import DESKTOP, defines, resolve
from display.store import MAX_PAGES, WIDTH, store_layout
from fitting import FittedModel, FittedObject
from fitting.model import Highlight
from radiosity.files.camera import Camera
from radiosity.files.errors import InputError
from radiosity.files.solution import ObjectSolution, Solution
from radiosity.physics import directions
from radiosity.physics.emitters import EmitterPart, emitter_radiance
from radiosity.scene import geometry

pytestmark = pytest.mark.gl

RTOL, ATOL = 2e-3, 1e-5  # float32 on the GPU (atan, sqrt, the highlight's quadrature) against float64
VIEW = Camera(eye=(0.3, 0.8, 3.5), look_at=(0.0, 0.0, -0.3), up=(0.0, 1.0, 0.0), fov_deg=45.0, width=120, height=80)
GLOSSY = {"diffuse": [0.1, 0.1, 0.1], "specular": [0.5, 0.45, 0.4], "exponent": 40.0, "emission": [0.0, 0.0, 0.0]}
DIFFUSE = {"diffuse": [0.5, 0.5, 0.5], "specular": [0.0, 0.0, 0.0], "exponent": 0.0, "emission": [0.0, 0.0, 0.0]}


def lamps():
    return (EmitterPart("sphere", [[1.5, 2.5, 2.0]], 0.3, [3.0, 6.0, 9.0], "lamp"),
            EmitterPart("polygon", [[-0.5, 3.0, 1.6], [0.5, 3.0, 1.6], [0.5, 3.0, 1.0], [-0.5, 3.0, 1.0]], 0.0,
                        [6.0, 5.0, 4.0], "panel"))


def sphere(centre, subdivisions=3, radius=0.8):
    """(positions, normals, tangents, faces) of an icosphere about ``centre``."""
    s = trimesh.creation.icosphere(subdivisions=subdivisions, radius=radius)
    normals = (s.vertices / np.linalg.norm(s.vertices, axis=1, keepdims=True)).astype(np.float32)
    positions = (s.vertices + np.asarray(centre)).astype(np.float32)
    return positions, normals, geometry.tangents(normals).astype(np.float32), np.asarray(s.faces, np.int32)


def spheres_solution(rng, grid=15):
    """Two glossy spheres (642 vertices, ``grid`` x ``grid`` directions, random radiance,
    the lamps' highlights in their grids) and a diffuse one behind: 2 x 144,450 + 642
    radiance values at grid 15 (225 a vertex: many a vertex's grid straddles two layers
    of 65,536) and 2 x 1,284 of visibility, in five layers."""
    objects = []
    for name, centre, glossy in (("left", (-1.0, 0.0, 0.0), True), ("right", (1.0, 0.0, 0.0), True),
                                 ("back", (0.0, 0.2, -1.8), False)):
        p, n, t, f = sphere(centre)
        if glossy:
            dirs = directions.grid_directions(grid).astype(np.float32)
            radiance = rng.uniform(0.1, 2.0, (len(p), grid * grid, 3)).astype(np.float32)
            visibility = rng.uniform(0.3, 1.0, (len(p), 2)).astype(np.float32)
            objects.append(ObjectSolution(name, p, n, t, f, dirs, radiance, GLOSSY, visibility=visibility))
        else:
            dirs = directions.grid_directions(1).astype(np.float32)
            objects.append(ObjectSolution(name, p, n, t, f, dirs, rng.uniform(0.1, 1.0, (len(p), 1, 3)).astype(np.float32),
                                          DIFFUSE))
    return Solution(objects=tuple(objects), emitters=lamps(), emitter_nodes=8)


def balls_fit(rng, lights=64):
    """Two balls of ``lights`` lights each with per-light coefficients (642 x 64 = 41,088
    values each: the second straddles the first layer), the lamps' highlights on both."""
    objects = []
    for name, centre in (("left", (-1.0, 0.0, 0.0)), ("right", (1.0, 0.0, 0.0))):
        p, n, _, f = sphere(centre)
        d = rng.normal(size=(lights, 3))
        d[:, 2] = np.abs(d[:, 2]) + 0.5
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        objects.append(FittedObject(
            name=name, positions=p, normals=n, faces=f, emitted=rng.uniform(0, 0.2, (len(p), 3)).astype(np.float32),
            specular=rng.uniform(0.0, 0.05, (len(p), lights, 3)).astype(np.float32),
            light_pos=np.concatenate([d, np.zeros((lights, 1))], axis=1).astype(np.float32),
            light_rgb=rng.uniform(0.5, 2.0, (lights, 3)).astype(np.float32),
            shininess=rng.uniform(5.0, 200.0, lights).astype(np.float32),
            highlight=Highlight(lamps(), 8, np.array(GLOSSY["specular"]), GLOSSY["exponent"],
                                rng.uniform(0.3, 1.0, (len(p), 2)).astype(np.float32)),
        ))
    return FittedModel(objects=tuple(objects), source="test", emitters=lamps(), emitter_nodes=8)


@pytest.fixture
def small_store(monkeypatch):
    """Layers of 16 rows (65,536 values), a texture a layer, grids read 5,000 values a chunk."""
    monkeypatch.setattr(display.store, "LAYER_ROWS", 16)
    monkeypatch.setattr(display.store, "PAGE_LAYERS", 1)
    monkeypatch.setattr(display.renderer, "CHUNK_VALUES", 5000)


def reference_at_vertices(solution, obj, eye):
    """The reference display at the vertices of ``obj`` (numpy): the grid less the
    highlights (float32, as uploaded) read bilinearly for the view direction, plus the
    highlights in closed form."""
    p = obj.positions.astype(np.float64)
    w = np.asarray(eye) - p
    w /= np.linalg.norm(w, axis=1, keepdims=True)
    n, t = obj.normals.astype(np.float64), obj.tangents.astype(np.float64)
    local = np.stack([np.sum(w * t, 1), np.sum(w * np.cross(n, t), 1), np.sum(w * n, 1)], axis=1)
    if obj.is_diffuse:
        return obj.radiance[:, 0].astype(np.float64), local[:, 2]
    rest = (obj.radiance - solution.highlights(obj.name)).astype(np.float32)
    idx, weight = directions.grid_lookup_weights(local, obj.grid_n)
    looked_up = np.einsum("vk,vkc->vc", weight, rest[np.arange(len(p))[:, None], idx].astype(np.float64))
    m = obj.material
    highlight = emitter_radiance(solution.emitters, p, n, w, m["specular"], m["exponent"], visibility=obj.visibility,
                                 nodes=solution.emitter_nodes, source=obj.name)
    return looked_up + highlight, local[:, 2]


def test_a_solution_over_several_textures_draws_as_in_one(gl_context, rng, monkeypatch, small_store):
    solution = spheres_solution(rng)
    many = ProbedRenderer(gl_context, solution=solution, samples=1)
    assert many.layout.rows == 16 and many.layout.page_layers == 1
    values = sum(o.radiance.size // 3 for o in solution.objects) + 2 * 642 * 2
    assert many.layout.values == values and many.layout.pages == len(many.store.pages) == 5
    bases = [many.layout.address(o.base) for o in many.objects]
    assert bases[1][0] == 2 and bases[2][0] == 4  # the right sphere's grid starts in layer 2 and ends in layer 4
    monkeypatch.setattr(display.store, "LAYER_ROWS", None)
    monkeypatch.setattr(display.store, "PAGE_LAYERS", None)
    one = ProbedRenderer(gl_context, solution=solution, samples=1)
    assert one.layout.pages == one.layout.layers == 1
    for mode in ("reference", "diffuse"):
        for shading in ("pixel", "gouraud"):
            a, b = many.render(VIEW, mode, shading), one.render(VIEW, mode, shading)
            assert (a > 0).mean() > 0.2  # the spheres fill part of the picture
            assert np.allclose(a, b, rtol=1e-6, atol=1e-7), (mode, shading, np.abs(a - b).max())
    # every vertex of every object against numpy (the Gouraud stage's colours, by transform feedback)
    for obj in solution.objects:
        got = many.vertex_colours(VIEW, obj.name, "reference")
        expected, facing = reference_at_vertices(solution, obj, VIEW.eye)
        front = facing > 0.05  # behind the surface both clamp the direction; compared where it is well defined
        assert front.sum() > 200
        assert np.allclose(got[front], expected[front], rtol=RTOL, atol=ATOL), np.abs(got - expected)[front].max()
    many.release()
    one.release()


def test_per_light_coefficients_over_several_textures_draw_as_in_one(gl_context, rng, monkeypatch, small_store):
    fit = balls_fit(rng)
    many = ProbedRenderer(gl_context, fit=fit, samples=1)
    assert many.layout.pages == 2  # 2 x (41,088 + 1,284) values
    right = many.objects[1]
    assert many.layout.address(right.coefficient_base)[0] == 0  # starts in the first texture, ends in the second
    assert many.layout.address(right.coefficient_base + 642 * 64 - 1)[0] == 1
    monkeypatch.setattr(display.store, "LAYER_ROWS", None)
    monkeypatch.setattr(display.store, "PAGE_LAYERS", None)
    one = ProbedRenderer(gl_context, fit=fit, samples=1)
    assert one.layout.pages == 1
    for shading in ("pixel", "gouraud"):
        a, b = many.render(VIEW, "fitted", shading), one.render(VIEW, "fitted", shading)
        assert (a > 0).mean() > 0.2
        assert np.allclose(a, b, rtol=1e-6, atol=1e-7), (shading, np.abs(a - b).max())
    for obj in fit.objects:
        got = many.vertex_colours(VIEW, obj.name, "fitted")
        w = np.asarray(VIEW.eye) - obj.positions.astype(np.float64)
        w /= np.linalg.norm(w, axis=1, keepdims=True)
        expected = obj.shade(w)
        assert np.allclose(got, expected, rtol=RTOL, atol=ATOL), np.abs(got - expected).max()
    many.release()
    one.release()


# ------------------------------------------------------------------ every value, through store.glsl

VALUE_PROGRAM = """
in ivec2 in_base;
in int in_row;
in int in_stride;
in int in_offset;
out vec3 v_value;
void main() { v_value = store_value(in_base, in_row, in_stride, in_offset).rgb; }
"""


def run_cases(ctx, source, cases, varying, dtype, bind):
    """Transform feedback of ``source`` (the cases (base layer, base texel, row, stride,
    offset) as its attributes) into 3 or 2 values of ``dtype`` a case."""
    program = ctx.program(vertex_shader=source, varyings=[varying])
    bind(program)
    data = np.asarray(cases, np.int64)
    buffers = [ctx.buffer(np.ascontiguousarray(data[:, columns], np.int32).tobytes())
               for columns in ([0, 1], [2], [3], [4])]
    vao = ctx.vertex_array(program, [(buffers[0], "2i", "in_base"), (buffers[1], "i", "in_row"),
                                     (buffers[2], "i", "in_stride"), (buffers[3], "i", "in_offset")])
    width = 3 if varying == "v_value" else 2
    out = ctx.buffer(reserve=len(data) * 4 * width)
    scratch = ctx.simple_framebuffer((1, 1))  # transform feedback writes nothing without a framebuffer
    scratch.use()
    vao.transform(out, moderngl.POINTS, vertices=len(data))
    got = np.frombuffer(out.read(), dtype).reshape(-1, width).copy()
    for resource in (vao, out, scratch, program, *buffers):
        resource.release()
    return got


def block_cases(layout, base, rows, stride):
    """Every value of a block: (base layer, base texel, row, stride, offset)."""
    layer, texel = layout.address(base)
    row, offset = np.divmod(np.arange(rows * stride), stride)
    return np.stack([np.full_like(row, layer), np.full_like(row, texel), row, np.full_like(row, stride), offset], axis=1)


def test_every_value_reads_back_through_the_store(gl_context, rng, small_store):
    """store.glsl's store_value of every row and offset of every block (radiance grids
    less the highlights, visibility in red, per-light coefficients) is the value
    uploaded, bit for bit, across six textures of one layer."""
    fit = balls_fit(rng)  # the two glossy spheres of the solution: drawn from both files
    solution = Solution(objects=spheres_solution(rng).objects[:2], emitters=lamps(), emitter_nodes=8)
    r = ProbedRenderer(gl_context, solution=solution, fit=fit, samples=1)
    assert r.layout.pages == 6
    source = DESKTOP + defines(extra=(r.store.define,)) + resolve("store.glsl") + VALUE_PROGRAM
    cases, expected = [], []
    for obj, s, f in zip(r.objects, solution.objects, fit.objects):
        rest = s.radiance - solution.highlights(s.name) if not s.is_diffuse else s.radiance
        cases.append(block_cases(r.layout, obj.base, len(s.radiance), s.radiance.shape[1]))
        expected.append(np.asarray(rest, np.float32).reshape(-1, 3))
        for mode, visibility in (("reference", s.visibility), ("fitted", f.highlight.visibility)):
            cases.append(block_cases(r.layout, obj.highlight[mode].base, *visibility.shape))
            expected.append(np.stack([visibility.reshape(-1), np.zeros(visibility.size), np.zeros(visibility.size)],
                                     axis=1).astype(np.float32))
        cases.append(block_cases(r.layout, obj.coefficient_base, len(f.specular), f.n_lights))
        expected.append(f.specular.reshape(-1, 3))
    cases, expected = np.concatenate(cases), np.concatenate(expected)
    assert len(cases) == r.layout.values
    got = run_cases(gl_context, source, cases, "v_value", np.float32, r.store.bind)
    assert np.array_equal(got, expected), np.nonzero((got != expected).any(axis=1))[0][:10]
    r.release()


# ------------------------------------------------------------------ addresses past 2^31

ADDRESS_PROGRAM = """
in ivec2 in_base;
in int in_row;
in int in_stride;
in int in_offset;
flat out ivec2 v_address;
void main() { v_address = store_step(store_start(in_base, in_row, in_stride), in_offset); }
"""


def glsl_addresses(ctx, rows, cases):
    """store.glsl's address (layer, texel) of each case (base layer, base texel, row,
    stride, offset), run on the GPU with layers of ``rows`` rows."""
    source = DESKTOP + defines(extra=("VL_STORE_PAGES 1",)) + resolve("store.glsl") + ADDRESS_PROGRAM

    def bind(program):
        program["store_shift"].value = (WIDTH * rows).bit_length() - 1

    return run_cases(ctx, source, cases, "v_address", np.int32, bind).astype(np.int64)


def address_cases(rng, rows):
    """(base layer, base texel, row, stride, offset) cases: the largest rows and strides,
    flat indices just below and above 2^31 / 3, 2^31 and 2^32 (as a float index 3 i and a
    texel index would overflow), and random ones."""
    layer = WIDTH * rows
    cases = [(0, 0, 0, 1, 0), (0, layer - 1, 0, 1, 1), (3, layer - 1, 2**31 - 1, 1 << 16, (1 << 16) - 1),
             (0, 0, 2**31 - 1, 4096, 4095), (1, 5, 2**31 - 1, 1, 0)]
    for target in (2**31 // 3, 2**31, 2**32, 10**12):
        for stride in (1, 3, 64, 4096, 1 << 16):
            for delta in (-1, 0, 1):
                row, offset = divmod(target + delta, stride)
                if row < 2**31:
                    cases.append((0, 0, row, stride, offset))
    for _ in range(300):
        stride = int(rng.integers(1, (1 << 16) + 1))
        cases.append((int(rng.integers(0, 50)), int(rng.integers(0, layer)), int(rng.integers(0, 2**31)), stride,
                      int(rng.integers(0, stride))))
    # the layer itself must be an int: far beyond any store (2^31 layers of 65,536 values)
    return [c for c in cases if (c[0] * layer + c[1] + c[2] * c[3] + c[4]) // layer < 2**31]


@pytest.mark.parametrize("rows", [16, 256, 16384])
def test_glsl_addresses_are_exact_past_two_to_the_31(gl_context, rng, rows):
    cases = address_cases(rng, rows)
    layer = WIDTH * rows
    index = [b * layer + t + r * s + o for b, t, r, s, o in cases]  # Python integers: exact
    assert max(index) > 2**40 and any(2**31 // 3 < i < 2**31 for i in index)
    expected = np.array([divmod(i, layer) for i in index], np.int64)
    got = glsl_addresses(gl_context, rows, cases)
    wrong = np.nonzero((got != expected).any(axis=1))[0]
    assert len(wrong) == 0, [(cases[i], index[i], got[i], expected[i]) for i in wrong[:5]]


def test_a_layout_names_each_value_by_layer_and_texel():
    assert WIDTH & (WIDTH - 1) == 0  # store.glsl divides by shifts
    small = store_layout(100_000, 16384, 2048)
    assert (small.rows, small.layers, small.pages, small.shift) == (32, 1, 1, 17)  # the least power of two of rows
    layout = store_layout(79_276_514, 16384, 2048)  # the user's solution: more rows than a texture has
    assert (layout.rows, layout.layers, layout.page_layers, layout.pages) == (256, 76, 127, 1)
    assert 0 <= layout.layers * layout.layer_texels - layout.values < layout.layer_texels  # padding under a layer
    big = store_layout(10**9, 16384, 2048)  # 12 GB of float32 RGB in 8 textures
    assert big.pages == MAX_PAGES and big.page_layers == 127 and big.page_depth(MAX_PAGES - 1) == 954 - 7 * 127
    assert big.page_layers * big.layer_texels * 16 < 2**31  # llvmpipe's limit, counting 16 bytes a texel
    for i in (0, 2**31 // 3 + 1, 3 * 10**8 + 12345, 10**9 - 1):
        page, x, y, z = big.texel(i)
        assert ((page * big.page_layers + z) * big.rows + y) * WIDTH + x == i
        assert 0 <= x < WIDTH and 0 <= y < big.rows and 0 <= z < big.page_depth(page)
    with pytest.raises(InputError, match="textures"):
        store_layout(2 * 10**9, 16384, 2048)


# ------------------------------------------------------------------ refusals


def test_a_model_beyond_the_free_memory_is_refused_in_one_line(gl_context, rng, monkeypatch):
    solution = spheres_solution(rng, grid=8)
    r = ProbedRenderer(gl_context, solution=solution, samples=1)
    estimate = r.estimate
    r.release()
    assert estimate.store == r.layout.nbytes and estimate.buffers > 0 and estimate.host > 0
    monkeypatch.setattr(display.store, "available_memory", lambda: estimate.total - 1)
    with pytest.raises(InputError) as refused:
        ProbedRenderer(gl_context, solution=solution, samples=1)
    message = str(refused.value)
    assert "\n" not in message and "needs about" in message and "is free" in message and "--grid" in message
    monkeypatch.setattr(display.store, "available_memory", lambda: estimate.total)
    said = []
    ProbedRenderer(gl_context, solution=solution, samples=1, say=said.append).release()  # just enough: drawn
    assert said == []  # quiet below SAY_BYTES
    monkeypatch.setattr(display.store, "SAY_BYTES", 0)
    ProbedRenderer(gl_context, solution=solution, samples=1, say=said.append).release()
    assert len(said) == 1 and said[0].startswith("drawing: about ") and "free" in said[0] and "\n" not in said[0]


def test_the_command_refuses_a_model_beyond_the_free_memory(gl_context, tmp_path, rng, cli, monkeypatch):
    path = tmp_path / "solution.npz"
    spheres_solution(rng, grid=8).save(path)
    monkeypatch.setattr(display.store, "available_memory", lambda: 1_000_000)
    code, out, err = cli("render", path, "--size", "64x48", "-o", tmp_path / "x.png")
    assert code == 2 and out == ""
    assert err.count("\n") == 1 and "needs about" in err and "1.0 MB is free" in err, err
    assert not (tmp_path / "x.png").exists()


def test_a_grid_beyond_what_the_shaders_address_is_refused(gl_context):
    p = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], np.float32)
    n = np.tile(np.float32([0, 0, 1]), (3, 1))
    t = np.tile(np.float32([1, 0, 0]), (3, 1))
    grid = 257
    dirs = directions.grid_directions(grid).astype(np.float32)
    obj = ObjectSolution("huge", p, n, t, np.array([[0, 1, 2]], np.int32), dirs,
                         np.zeros((3, grid * grid, 3), np.float32), GLOSSY)
    with pytest.raises(InputError, match="66,049 radiance directions a vertex; the display reads at most 65,536"):
        ProbedRenderer(gl_context, solution=Solution(objects=(obj,)))


# ------------------------------------------------------------------ the real size


def big_solution(spheres=3, subdivisions=5, grid=64):
    """``spheres`` glossy spheres of 10,242 vertices each with a ``grid`` x ``grid``
    direction grid (3 x 10,242 x 4,096 = 125,853,696 vertex-direction samples, 377
    million float32 values, 1.5 GB): a coloured base and a highlight of a distant light
    (a cos^40 lobe about its mirror direction), made a chunk of vertices at a time."""
    dirs = directions.grid_directions(grid).astype(np.float32)
    light = np.float32([0.4, 0.8, 0.45]) / np.linalg.norm([0.4, 0.8, 0.45])
    colours = np.float32([[0.6, 0.15, 0.1], [0.1, 0.5, 0.15], [0.15, 0.2, 0.6], [0.5, 0.45, 0.1]])
    objects = []
    for i in range(spheres):
        p, n, t, f = sphere(((i - (spheres - 1) / 2) * 1.9, 0.0, 0.0), subdivisions)
        b = np.cross(n, t)
        radiance = np.empty((len(p), len(dirs), 3), np.float32)
        for start in range(0, len(p), 256):
            c = slice(start, start + 256)
            world = (dirs[None, :, 0:1] * t[c, None] + dirs[None, :, 1:2] * b[c, None]
                     + dirs[None, :, 2:3] * n[c, None])
            mirror = 2 * dirs[None, :, 2:3] * n[c, None] - world  # the view direction mirrored about the normal
            lobe = np.maximum(mirror @ light, 0) ** 40
            radiance[c] = colours[i % len(colours)] * (0.3 + 0.7 * dirs[None, :, 2:3]) + 2.5 * lobe[..., None]
        objects.append(ObjectSolution(f"ball{i}", p, n, t, f, dirs, radiance, GLOSSY))
    return Solution(objects=tuple(objects), settings={}, stats={}, scene="large")


@pytest.mark.slow
def test_a_solution_of_more_than_ten_to_the_eight_samples_draws(gl_context):
    solution = big_solution()
    samples = sum(o.radiance.size // 3 for o in solution.objects)
    assert samples > 10**8
    r = ProbedRenderer(gl_context, solution=solution)
    assert r.layout.values == samples and r.layout.layers >= 2  # more rows than one texture has
    view = Camera(eye=(0.0, 1.0, 7.0), look_at=(0.0, 0.0, 0.0), up=(0.0, 1.0, 0.0), fov_deg=40.0, width=640,
                  height=360)
    image = r.render(view, "reference", "pixel")
    covered = image.max(axis=2) > 0
    assert covered.mean() > 0.1 and image.max() > 1.0  # the spheres and their highlights, not black
    for obj in solution.objects:
        got = r.vertex_colours(view, obj.name, "reference")
        expected, facing = reference_at_vertices(solution, obj, view.eye)
        front = facing > 0.05
        assert np.allclose(got[front], expected[front], rtol=RTOL, atol=ATOL), np.abs(got - expected)[front].max()
    r.release()
