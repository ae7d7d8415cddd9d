"""The solver on textured surfaces: photons scatter with kd * texture(uv at the hit),
the gather reads the same albedo, and the solution keeps a textured object's diffuse
term as its two factors (irradiance per vertex, texture per pixel).

The known answer: inside a closed sphere every point sees every other point with the
same form factor (dA' / the sphere's area), so with emission Le and any albedo kd(x)
the irradiance is the same everywhere, E = pi Le / (1 - rho), rho the area mean of
kd(x). A texture that varies over the sphere changes rho, not the uniformity.
"""

import numpy as np
import pytest

from radiosity.files.solution import Solution
from radiosity.physics.materials import Material
from radiosity.physics.textures import TexturedDiffuse, lookup
from radiosity.scene import builtins
from radiosity.scene.model import Scene, build_object
from radiosity.transport.solve import SolveOptions, solve

TEXTURE = np.array(
    [
        [[0.9, 0.1, 0.1], [0.2, 0.8, 0.2], [0.1, 0.1, 0.9], [0.7, 0.7, 0.7]],
        [[0.05, 0.05, 0.05], [0.9, 0.9, 0.2], [0.3, 0.6, 0.9], [0.5, 0.2, 0.6]],
        [[0.8, 0.4, 0.1], [0.1, 0.5, 0.5], [0.95, 0.95, 0.95], [0.2, 0.2, 0.2]],
    ],
    dtype=np.float32,
)  # 3 x 4 texels, each its own colour


def sphere_furnace(material, texture, subdivisions=3):
    """A closed unit sphere facing in, with uvs by a projection along z (no seam)."""
    positions, faces = builtins.mesh("sphere", subdivisions=subdivisions)
    faces = faces[:, ::-1]  # fronts inward
    normals = -positions / np.linalg.norm(positions, axis=1, keepdims=True)
    uvs = positions[:, :2] / 2 + 0.5 if texture is not None else None
    obj = build_object("sphere", material, positions, faces, normals=normals, uvs=uvs, texture=texture)
    return Scene(name="furnace", objects=(obj,))


def area_mean_albedo(obj, points_per_side=24):
    """The area mean of kd * texture(uv) over the object's triangles, by a dense
    barycentric rule (the quantity the closed form needs)."""
    p, f, uv = obj.positions, obj.faces, obj.uvs
    area = 0.5 * np.linalg.norm(np.cross(p[f[:, 1]] - p[f[:, 0]], p[f[:, 2]] - p[f[:, 0]]), axis=1)
    i, j = np.meshgrid(np.arange(points_per_side), np.arange(points_per_side), indexing="ij")
    keep = i + j < points_per_side
    a = (i[keep] + 1 / 3) / points_per_side
    b = (j[keep] + 1 / 3) / points_per_side
    bary = np.stack([1 - a - b, a, b], axis=1)  # (S, 3)
    points_uv = np.einsum("sk,fkc->fsc", bary, uv[f])
    albedo = np.asarray(obj.material.diffuse) * lookup(obj.texture, points_uv).mean(axis=1)
    return (area[:, None] * albedo).sum(axis=0) / area.sum()


def test_a_textured_furnace_has_the_closed_form_irradiance():
    material = Material("wall", diffuse=(0.9, 0.8, 0.95), emission=(1.0, 1.0, 1.0))
    scene = sphere_furnace(material, TEXTURE)
    sol = solve(scene, SolveOptions(photons=1_000_000, max_edge=10.0, seed=3))
    obj = sol.object("sphere")
    assert obj.textured is not None and sol.version == 3
    rho = area_mean_albedo(scene.object("sphere"))
    assert 0.3 < rho.min() and rho.max() < 0.7 and np.ptp(rho) > 0.05  # the texture matters, per channel
    expected = np.pi / (1.0 - rho)
    e = obj.textured.irradiance.astype(np.float64)
    assert np.abs(e.mean(axis=0) / expected - 1).max() < 0.005  # measured 0.0007
    assert np.abs(e / expected - 1).max() < 0.05  # every vertex (measured 0.02)
    # the stored radiance is the emission alone; the diffuse term is kd * texture / pi * E
    assert np.array_equal(obj.radiance[:, 0, :], np.ones((obj.num_vertices, 3), np.float32))
    at_vertices = obj.diffuse_radiance()
    uv = obj.textured.uvs.astype(np.float64)
    assert np.allclose(at_vertices, np.asarray(material.diffuse) * lookup(TEXTURE, uv) / np.pi * e, rtol=1e-12)
    # the photons' bookkeeping closes with the textured albedo
    energy = {k: np.asarray(v) for k, v in sol.stats["energy"].items() if k != "photon_hits"}
    assert sum(energy["escaped"]) == 0.0
    accounted = energy["absorbed"] + energy["backface"] + energy["terminated"]
    assert np.allclose(accounted / energy["emitted"], 1.0, atol=0.005)


def test_the_untextured_closed_form_is_not_met_by_the_textured_sphere():
    """The same sphere without its texture: kd alone; the texture's furnace above must
    not pass for it (the closed forms differ by more than the tolerance)."""
    material = Material("wall", diffuse=(0.9, 0.8, 0.95), emission=(1.0, 1.0, 1.0))
    textured = sphere_furnace(material, TEXTURE)
    rho_textured = area_mean_albedo(textured.object("sphere"))
    assert np.abs((1 - np.asarray(material.diffuse)) / (1 - rho_textured) - 1).min() > 0.1


@pytest.mark.parametrize("value", [1.0, 0.5])
def test_a_glossy_textured_object_keeps_its_diffuse_term_apart(value):
    """A constant texture t on a glossy material: radiance + the textured diffuse term
    matches the untextured material with kd * t, and the radiance alone lacks
    kd t / pi * E."""
    kd = np.array([0.5, 0.4, 0.3])
    glossy = dict(specular=(0.3, 0.3, 0.3), exponent=20.0, emission=(1.0, 1.0, 1.0))
    texture = np.full((2, 2, 3), value, np.float32)
    textured = sphere_furnace(Material("wall", diffuse=tuple(kd), **glossy), texture, subdivisions=2)
    plain = sphere_furnace(Material("wall", diffuse=tuple(kd * value), **glossy), None, subdivisions=2)
    opts = SolveOptions(photons=200_000, max_edge=10.0, seed=4, gather_samples=16, light_samples=4, grid=6)
    one, two = solve(textured, opts).object("sphere"), solve(plain, opts).object("sphere")
    assert one.textured is not None and two.textured is None
    full = one.radiance + one.diffuse_radiance()[:, None, :]
    assert abs(full.mean() / two.radiance.mean() - 1) < 0.02
    diffuse = kd * value / np.pi * one.textured.irradiance
    assert np.allclose(one.radiance + diffuse[:, None, :], full, rtol=1e-5)
    assert (one.radiance.mean(axis=(0, 1)) < two.radiance.mean(axis=(0, 1)) - 0.5 * diffuse.mean(axis=0)).all()


def test_the_solution_file_keeps_the_texture(tmp_path):
    material = Material("wall", diffuse=(0.9, 0.8, 0.95), emission=(1.0, 1.0, 1.0))
    scene = sphere_furnace(material, TEXTURE, subdivisions=1)
    sol = solve(scene, SolveOptions(photons=2_000, max_edge=10.0, seed=1))
    sol.save(tmp_path / "s.npz")
    back = Solution.load(tmp_path / "s.npz")
    a, b = sol.object("sphere").textured, back.object("sphere").textured
    assert np.array_equal(a.texture, b.texture) and np.array_equal(a.uvs, b.uvs)
    assert np.array_equal(a.irradiance, b.irradiance) and a.kd == b.kd
    with np.load(tmp_path / "s.npz") as z:
        assert z["sphere/texture"].dtype == np.float32  # not an 8-bit image's decoding
        assert '"version": 3' in str(z["meta"])


def test_an_8_bit_texture_is_stored_as_its_srgb_codes(tmp_path):
    from radiosity.physics.materials import srgb_to_linear

    codes = np.arange(48, dtype=np.uint8).reshape(4, 4, 3) * 5
    texture = srgb_to_linear(codes / 255.0).astype(np.float32)
    t = TexturedDiffuse(uvs=np.zeros((3, 2)), irradiance=np.ones((3, 3)), texture=texture, kd=(1, 1, 1))
    stored = t.arrays("x")["x/texture"]
    assert stored.dtype == np.uint8 and np.array_equal(stored, codes)
    t2 = TexturedDiffuse(uvs=np.zeros((3, 2)), irradiance=np.ones((3, 3)), texture=texture * 0.999, kd=(1, 1, 1))
    assert t2.arrays("x")["x/texture"].dtype == np.float32


def test_an_untextured_solution_is_written_as_version_2(tmp_path):
    material = Material("wall", diffuse=(0.5, 0.5, 0.5), emission=(1.0, 1.0, 1.0))
    sol = solve(sphere_furnace(material, None, subdivisions=1), SolveOptions(photons=1_000, max_edge=10.0))
    assert sol.version == 2
    sol.save(tmp_path / "s.npz")
    with np.load(tmp_path / "s.npz") as z:
        assert '"version": 2' in str(z["meta"])
        assert not any(k.endswith(("/uvs", "/texture", "/irradiance")) for k in z.files)


def test_a_glossy_textured_fresnel_object_keeps_the_rest_of_its_radiance():
    """With Fresnel the gather's diffuse part falls as b(cos_o) = 1 - (1 - cos_o)^5; the
    stored radiance leaves out exactly that, so adding it back gives the untextured
    twin's radiance (a constant texture t against kd * t)."""
    from radiosity.physics.directions import grid_directions

    kd = np.array([0.5, 0.4, 0.3])
    glossy = dict(specular=(1.0, 1.0, 1.0), exponent=20.0, emission=(1.0, 1.0, 1.0), fresnel=(0.04, 0.04, 0.04))
    texture = np.full((2, 2, 3), 0.5, np.float32)
    textured = sphere_furnace(Material("wall", diffuse=tuple(kd), **glossy), texture, subdivisions=2)
    plain = sphere_furnace(Material("wall", diffuse=tuple(kd * 0.5), **glossy), None, subdivisions=2)
    opts = SolveOptions(photons=200_000, max_edge=10.0, seed=4, gather_samples=16, light_samples=4, grid=6)
    one, two = solve(textured, opts).object("sphere"), solve(plain, opts).object("sphere")
    z = np.clip(grid_directions(6)[:, 2], 0, 1)
    b = 1 - (1 - z) ** 5
    full = one.radiance + (kd * 0.5 / np.pi * one.textured.irradiance)[:, None, :] * b[None, :, None]
    per_direction = full.mean(axis=(0, 2)) / two.radiance.mean(axis=(0, 2))
    assert np.abs(per_direction - 1).max() < 0.03, per_direction
