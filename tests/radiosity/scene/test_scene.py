"""Loading scenes: the built-ins, TOML with mesh files and built-in meshes, OBJ/MTL,
glTF, and every kind of bad input refused with a clear InputError."""

import json
import textwrap

import numpy as np
import pytest
import trimesh
from bad_inputs import BAD_INPUTS, bad_input_path, write

from radiosity.files.errors import InputError, SceneWarning
from radiosity.scene import builtins, geometry
from radiosity.scene.loaders import load_scene
from radiosity.scene.material_kernels import albedo
from radiosity.scene.microfacet import RULE

BOX_CENTRE = np.array([278.0, 274.4, 279.6])


@pytest.fixture
def tetra_obj(tmp_path):
    """A closed tetrahedron, fronts out, with an MTL of three materials."""
    write(
        tmp_path / "tetra.mtl",
        """\
        newmtl shiny
        Kd 0.2 0.3 0.4
        Ks 0.5 0.5 0.5
        Ns 64
        newmtl matte
        Kd 0.6 0.6 0.6
        newmtl lamp
        Kd 0 0 0
        Ke 5 4 3
        """,
    )
    return write(
        tmp_path / "tetra.obj",
        """\
        mtllib tetra.mtl
        v 0 0 0
        v 1 0 0
        v 0 1 0
        v 0 0 1
        usemtl shiny
        f 1 3 2
        f 1 2 4
        usemtl matte
        f 1 4 3
        usemtl lamp
        f 2 3 4
        """,
    )


def test_cornell_builtin():
    scene = load_scene("cornell")
    assert [o.name for o in scene.objects] == [
        "floor", "ceiling", "back_wall", "left_wall", "right_wall", "short_block", "tall_block", "light",
    ]
    counts = {o.name: o.n_triangles for o in scene.objects}
    assert counts == {
        "floor": 2, "ceiling": 2, "back_wall": 2, "left_wall": 2, "right_wall": 2,
        "short_block": 10, "tall_block": 10, "light": 2,
    }
    for name in ("floor", "ceiling", "back_wall", "left_wall", "right_wall"):
        o = scene.object(name)
        inward = np.einsum("ij,ij->i", o.normals, BOX_CENTRE - o.positions)
        assert (inward > 0).all(), f"{name} does not face into the box"
        fn, _ = geometry.face_normals(o.positions, o.faces)
        # the measured walls are not quite planar: normals agree with the winding to < 1 degree
        cosines = np.einsum("fkj,fj->fk", o.normals[o.faces], fn)
        assert cosines.min() > np.cos(np.radians(1.0))
    for name in ("short_block", "tall_block"):
        o = scene.object(name)
        assert len(o.positions) == 20  # a vertex per face corner: the edges are creases
        assert (np.einsum("ij,ij->i", o.normals, o.positions - o.positions.mean(axis=0)) > 0).all()
    light = scene.object("light")
    assert np.allclose(light.normals, [0, -1, 0])
    assert np.allclose(light.positions[:, 1], 548.8 - builtins.LIGHT_DROP_MM)
    assert light.area == pytest.approx(130 * 105)
    assert np.allclose(light.emitted_power, np.pi * np.array([18.4, 15.6, 8.0]) * 130 * 105)
    assert scene.emitters == [light]
    assert scene.camera.eye == (278, 273, -800) and scene.camera.fov_y_deg == 39.3


def test_cornell_teapot_has_sharp_and_broad_lobes():
    scene = load_scene("cornell-teapot")
    glossy = {o.name: o.material for o in scene.objects if o.material.is_glossy}
    assert set(glossy) == {"teapot", "tall_block"}
    assert glossy["teapot"].exponent >= 10 * glossy["tall_block"].exponent
    for m in scene.materials.values():
        assert (np.add(m.diffuse, m.specular) <= 1).all()
    teapot = scene.object("teapot")
    lo, hi = teapot.positions.min(axis=0), teapot.positions.max(axis=0)
    assert lo[1] == pytest.approx(0.0, abs=1e-9)  # stands on the floor
    box_lo, box_hi = load_scene("cornell").bounds
    assert (lo >= box_lo).all() and (hi < box_hi).all()  # inside the box
    # and clear of the tall block (a convex prism: inside means behind all its faces)
    tall = scene.object("tall_block")
    fn, _ = geometry.face_normals(tall.positions, tall.faces)
    behind = np.einsum("fj,vfj->vf", fn, teapot.positions[:, None, :] - tall.positions[tall.faces[:, 0]][None])
    inside = (behind < 0).all(axis=1) & (teapot.positions[:, 1] > 0)
    assert not inside.any()


def test_merged_mesh_matches_the_objects():
    scene = load_scene("cornell-teapot")
    merged = scene.merged()
    assert merged.positions.dtype == np.float32 and merged.faces.dtype == np.int32
    assert len(merged.faces) == scene.n_triangles == len(merged.triangle_object)
    tris = merged.triangles()
    for i, o in enumerate(scene.objects):
        sel = merged.triangle_object == i
        assert np.array_equal(merged.triangle_face[sel], np.arange(o.n_triangles))
        assert np.allclose(tris[sel], o.positions[o.faces], atol=1e-3)


def test_refined_scene_has_short_edges_and_same_area():
    scene = load_scene("cornell")
    refined = scene.refined(50.0)
    for o, r in zip(scene.objects, refined.objects):
        assert r.area == pytest.approx(o.area, rel=1e-12)
        edges = np.linalg.norm(r.positions[r.faces] - r.positions[np.roll(r.faces, -1, axis=1)], axis=2)
        assert edges.max() <= 50.0
        assert np.allclose(np.einsum("ij,ij->i", r.normals, r.tangents), 0, atol=1e-12)
    assert refined.object("floor").n_triangles > 100


def test_toml_mixing_an_obj_file_and_builtins(tmp_path, tetra_obj):
    scene_file = write(
        tmp_path / "mixed.toml",
        """\
        [camera]
        position = [0, 1, 5]
        look_at = [0, 0, 0]

        [materials.polished]
        diffuse = [0.25, 0.05, 0.05]
        specular = 0.5
        exponent = 60

        [materials.lamp]
        emission = [10, 10, 10]

        [[objects]]
        name = "tetra"
        mesh = "tetra.obj"
        material = "polished"
        scale = 2
        translate = [1, 0, 0]

        [[objects]]
        name = "ball"
        builtin = "sphere"
        subdivisions = 2
        material = "polished"
        scale = [1, 2, 1]

        [[objects]]
        name = "panel"
        builtin = "quad"
        material = "lamp"
        rotate_deg = [180, 0, 0]
        translate = [0, 3, 0]
        """,
    )
    scene = load_scene(scene_file)
    assert [o.name for o in scene.objects] == ["tetra", "ball", "panel"]
    tetra = scene.object("tetra")
    assert tetra.material.name == "polished" and tetra.material.specular == (0.5, 0.5, 0.5)
    assert tetra.n_triangles == 4
    assert np.allclose(tetra.positions.min(axis=0), [1, 0, 0]) and np.allclose(tetra.positions.max(axis=0), [3, 2, 2])
    assert trimesh.Trimesh(tetra.positions, tetra.faces).volume == pytest.approx(8 / 6)
    ball = scene.object("ball")
    assert ball.n_triangles == 320 and np.ptp(ball.positions[:, 1]) == pytest.approx(4.0)
    panel = scene.object("panel")
    assert np.allclose(panel.normals, [0, -1, 0], atol=1e-12)  # turned over: it lights downwards
    assert scene.emitters == [panel] and scene.camera.eye == (0, 1, 5)


def test_obj_with_mtl_maps_materials(tetra_obj):
    scene = load_scene(tetra_obj)
    mats = {o.material.name: o.material for o in scene.objects}
    assert mats["shiny"].diffuse == (0.2, 0.3, 0.4) and mats["shiny"].specular == (0.5, 0.5, 0.5)
    assert mats["shiny"].exponent == 64
    assert not mats["matte"].is_glossy and mats["matte"].diffuse == (0.6, 0.6, 0.6)
    assert mats["lamp"].emission == (5, 4, 3)
    assert sum(o.n_triangles for o in scene.objects) == 4


def test_gltf_maps_metallic_roughness(tmp_path):
    def add(scene, name, colour, metallic, roughness, offset, emissive=(0, 0, 0)):
        box = trimesh.creation.box()
        box.visual = trimesh.visual.TextureVisuals(
            material=trimesh.visual.material.PBRMaterial(
                name=name, baseColorFactor=[*colour, 1.0], metallicFactor=metallic,
                roughnessFactor=roughness, emissiveFactor=list(emissive),
            )
        )
        scene.add_geometry(box, node_name=name, transform=trimesh.transformations.translation_matrix(offset))

    gltf = trimesh.Scene()
    add(gltf, "brass", (0.8, 0.6, 0.2), 1.0, 0.3, [3, 0, 0])
    add(gltf, "plaster", (0.8, 0.8, 0.8), 0.0, 1.0, [0, 0, 0])
    add(gltf, "glow", (0.0, 0.0, 0.0), 0.0, 1.0, [0, 3, 0], emissive=(1.0, 0.5, 0.25))
    path = tmp_path / "things.glb"
    gltf.export(path)
    scene = load_scene(path)
    brass = scene.object("brass").material
    # glTF's Schlick F0: baseColor for a metal, ks the interface's scale 1
    assert np.allclose(brass.fresnel, (0.8, 0.6, 0.2), atol=1 / 255) and brass.diffuse == (0, 0, 0)
    assert brass.specular == (1.0, 1.0, 1.0)
    alpha = 0.3**2
    c, d, e = RULE["ggx"]  # the measured GGX rule (radiosity.scene.microfacet)
    assert brass.exponent == pytest.approx(c / alpha**2 + d + e * alpha**2)
    assert np.allclose(scene.object("brass").positions.mean(axis=0), [3, 0, 0])
    plaster = scene.object("plaster").material
    assert not plaster.is_glossy and np.allclose(plaster.diffuse, 0.8, atol=1 / 255)
    assert scene.object("glow").material.emission == pytest.approx((1.0, 0.5, 0.25), abs=1e-6)
    assert plaster.fresnel is None


def test_gltf_dielectric_gets_f0_004_and_its_diffuse_loses_what_f_reflects(tmp_path):
    box = trimesh.creation.box()
    box.visual = trimesh.visual.TextureVisuals(
        material=trimesh.visual.material.PBRMaterial(name="paint", baseColorFactor=[1.0, 0.5, 0.25, 1.0],
                                                     metallicFactor=0.0, roughnessFactor=0.4)
    )
    path = tmp_path / "paint.glb"
    trimesh.Scene(box).export(path)
    paint = load_scene(path).objects[0].material
    assert paint.fresnel == pytest.approx((0.04, 0.04, 0.04))
    # white base colour: kd held to what F leaves (the albedo at most 1 at every incidence)
    assert paint.diffuse[0] < 1.0 and paint.diffuse[1] == pytest.approx(0.5, abs=1 / 255)
    assert albedo(paint, np.linspace(0, 1, 65)).max() <= 1 + 1e-4


@pytest.mark.parametrize("factor", [1e-3, 1e4])
def test_tiny_and_huge_scales_load_the_same_mesh(factor):
    def with_scale(s):
        return f"""
        [materials.m]
        diffuse = 0.5
        [[objects]]
        name = "pot"
        builtin = "teapot"
        resolution = 4
        material = "m"
        scale = {s}
        """

    base = load_scene_text(with_scale(1.0))
    scaled = load_scene_text(with_scale(factor))
    a, b = base.object("pot"), scaled.object("pot")
    assert a.n_vertices == b.n_vertices and a.n_triangles == b.n_triangles
    assert np.allclose(b.positions / factor, a.positions, rtol=1e-9, atol=1e-9)
    assert np.allclose(a.normals, b.normals, atol=1e-9)


def load_scene_text(text, tmp_dir=None):
    import tempfile
    from pathlib import Path

    with tempfile.TemporaryDirectory() as d:
        path = Path(tmp_dir or d) / "scene.toml"
        path.write_text(textwrap.dedent(text))
        return load_scene(path)


def test_an_object_of_degenerate_triangles_alone_is_left_out_with_one_warning(tmp_path):
    write(tmp_path / "flat.obj", "v 0 0 0\nv 1 0 0\nv 2 0 0\nv 0 0 0\nf 1 2 3\nf 1 2 4\n")
    write(tmp_path / "good.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    objects = "".join(f'[[objects]]\nname = "{n}"\nmesh = "{n}.obj"\nmaterial = "m"\n' for n in ("flat", "good"))
    scene_file = write(tmp_path / "s.toml", '[materials.m]\ndiffuse = 0.5\n' + objects)
    with pytest.warns(SceneWarning) as caught:
        scene = load_scene(scene_file)
    messages = [str(w.message) for w in caught if issubclass(w.category, SceneWarning)]
    assert messages == [f"object 'flat' ({tmp_path / 'flat.obj'}): all 2 triangle(s) are degenerate (zero area): "
                        "the object is left out"]
    assert [o.name for o in scene.objects] == ["good"]
    only = write(tmp_path / "only.toml", '[materials.m]\ndiffuse = 0.5\n[[objects]]\nname = "flat"\n'
                 'mesh = "flat.obj"\nmaterial = "m"\n')
    with pytest.warns(SceneWarning), pytest.raises(InputError, match="every object's triangles are degenerate"):
        load_scene(only)


def test_degenerate_triangles_are_dropped_with_a_count(tmp_path):
    write(
        tmp_path / "bad.obj",
        """\
        v 0 0 0
        v 1 0 0
        v 0 1 0
        v 2 0 0
        f 1 2 3
        f 1 2 4
        f 1 1 3
        """,
    )
    scene_file = write(
        tmp_path / "s.toml",
        """\
        [materials.m]
        diffuse = 0.5
        [[objects]]
        name = "sheet"
        mesh = "bad.obj"
        material = "m"
        """,
    )
    with pytest.warns(SceneWarning, match=r"dropped 2 degenerate"):
        scene = load_scene(scene_file)
    assert scene.object("sheet").n_triangles == 1


@pytest.mark.parametrize("case", sorted(BAD_INPUTS))
def test_bad_input_is_refused_with_one_clear_line(case, tmp_path):
    with pytest.raises(InputError, match=BAD_INPUTS[case][1]) as info:
        load_scene(bad_input_path(case, tmp_path))
    assert "\n" not in str(info.value)


def test_scene_info_json_is_consistent():
    from radiosity.info import describe

    scene = load_scene("cornell-teapot")
    refined = scene.refined(40.0)
    info = json.loads(json.dumps(describe(scene, refined, 40.0, "--max-edge")))
    assert info["totals"]["triangles"] == scene.n_triangles
    assert info["totals"]["refined_triangles"] == refined.n_triangles > scene.n_triangles
    assert [e["name"] for e in info["emitters"]] == ["light"]
    assert info["materials"]["glaze"]["kind"] == "glossy"
    assert info["materials"]["glaze"]["albedo_60deg"][0] < info["materials"]["glaze"]["albedo_normal"][0]
