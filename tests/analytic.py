"""Answers known in closed form or by deterministic quadrature, shared by the solver's
and the path tracer's tests."""

import numpy as np

# an emitting square (radiance 1, facing down) 0.4 above a diffuse unit square (kd 0.5)
SQUARE_LIGHT = """
    [materials.floor]
    diffuse = 0.5
    [materials.lamp]
    emission = 1.0
    [[objects]]
    name = "floor"
    builtin = "quad"
    material = "floor"
    [[objects]]
    name = "lamp"
    builtin = "quad"
    material = "lamp"
    scale = 0.5
    rotate_deg = [180, 0, 0]
    translate = [0.1, 0.4, 0.05]
"""


def glossy_furnace_reference(kd, ks, n, le, nodes=160, phi_points=2048):
    """Radiance L(cos theta) leaving the inside of a sphere of this material.

    By symmetry L depends on the outgoing polar angle only, and light arriving at
    angle theta left its source at the same angle (chord of a sphere), so
    L(mu_o) = Le + integral_0^1 K(mu_o, mu_i) L(mu_i) dmu_i with
    K = integral_0^2pi f(wi, wo) mu_i dphi: solved by Nystrom on Gauss-Legendre nodes.
    """
    x, w = np.polynomial.legendre.leggauss(nodes)
    mu, weight = 0.5 * (x + 1), 0.5 * w
    phi = (np.arange(phi_points) + 0.5) * 2 * np.pi / phi_points
    sin = np.sqrt(1 - mu**2)
    cos_alpha = mu[:, None, None] * mu[None, :, None] - sin[:, None, None] * sin[None, :, None] * np.cos(phi)
    lobe = np.maximum(cos_alpha, 0.0) ** n
    kernel = (kd / np.pi * 2 * np.pi + ks * (n + 2) / (2 * np.pi) * lobe.sum(axis=2) * (2 * np.pi / phi_points))
    kernel = kernel * mu[None, :]  # (mu_o, mu_i)
    radiance = np.linalg.solve(np.eye(nodes) - kernel * weight[None, :], np.full(nodes, le))
    return mu, radiance


def polygon_irradiance(points, normal, polygon, radiance):
    """Irradiance at ``points`` (P, 3) with ``normal`` from a Lambertian polygon of
    uniform radiance (Lambert's formula: E = L/2 sum_i theta_i n . unit(R_i x R_i+1))."""
    total = np.zeros(len(points))
    for a, b in zip(polygon, np.roll(polygon, -1, axis=0)):
        ra, rb = a - points, b - points
        cross = np.cross(ra, rb)
        theta = np.arctan2(np.linalg.norm(cross, axis=1), np.einsum("ij,ij->i", ra, rb))
        total += theta * (cross @ normal) / np.linalg.norm(cross, axis=1)
    return radiance / 2 * np.abs(total)


# a hard shadow: an emitting square (radiance 1, side 0.2, facing down) at height 1 over a
# diffuse floor (kd 0.5, 0.8 x 0.6); a black square at height 0.5 covers x in [-0.5, 0] (z in
# [-0.5, 0.5], wide enough to act as a half-plane for every ray to the lamp). From a
# floor point (x, 0, z) the occluder hides the part of the lamp with x_lamp < -x, so the
# visible lamp is the rectangle x_lamp in [max(-0.1, -x), 0.1], z_lamp in [-0.1, 0.1]: umbra
# for x < -0.1, penumbra from -0.1 to 0.1, fully lit beyond.
PENUMBRA = """
    [materials.floor]
    diffuse = 0.5
    [materials.black]
    diffuse = 0.0
    [materials.lamp]
    emission = 1.0
    [[objects]]
    name = "floor"
    builtin = "quad"
    material = "floor"
    scale = [0.8, 1.0, 0.6]
    [[objects]]
    name = "occluder"
    builtin = "quad"
    material = "black"
    scale = [0.5, 1.0, 1.0]
    translate = [-0.25, 0.5, 0.0]
    [[objects]]
    name = "lamp"
    builtin = "quad"
    material = "lamp"
    scale = 0.2
    rotate_deg = [180, 0, 0]
    translate = [0.0, 1.0, 0.0]
"""
PENUMBRA_LAMP_HALF = 0.1  # half the lamp's side; the penumbra spans x in [-0.1, 0.1] on the floor


def penumbra_irradiance(points):
    """Irradiance at floor points (P, 3) (y = 0, normal +y) of the PENUMBRA scene, from
    the visible rectangle of the lamp (``polygon_irradiance``)."""
    h = PENUMBRA_LAMP_HALF
    out = np.zeros(len(points))
    for i, (x, _, z) in enumerate(points):
        lo = max(-h, -x)
        if lo >= h:
            continue
        rect = np.array([[lo, 1.0, -h], [h, 1.0, -h], [h, 1.0, h], [lo, 1.0, h]])
        out[i] = polygon_irradiance(np.array([[x, 0.0, z]]), np.array([0.0, 1.0, 0.0]), rect, 1.0)[0]
    return out


RELAY_LE = 10.0
PLATE_KS, PLATE_N = 0.5, 10.0
FLOOR_KS, FLOOR_N = 0.8, 20.0

# a glossy plate that sees a small lamp only in a glossy floor (the lamp faces the floor,
# the plate sees its back): tests/radiosity/transport/test_lobe_light.py, test_regather.py
GLOSSY_RELAY = f"""
[materials.plate]
diffuse = 0.0
specular = {PLATE_KS}
exponent = {PLATE_N}
[materials.floor]
diffuse = 0.0
specular = {FLOOR_KS}
exponent = {FLOOR_N}
[materials.lamp]
emission = {RELAY_LE}
[[objects]]
name = "floor"
builtin = "quad"
material = "floor"
[[objects]]
name = "lamp"
builtin = "quad"
material = "lamp"
scale = 0.1
rotate_deg = [180, 0, 0]
translate = [-0.3, 0.4, 0.0]
[[objects]]
name = "plate"
builtin = "quad"
material = "plate"
scale = 0.2
rotate_deg = [180, 0, 0]
translate = [0.3, 0.45, 0.0]
"""


def phong(ks, n, normal, wi, wo):
    """ks (n + 2) / (2 pi) cos^n alpha, alpha between wi and the mirror of wo; (..., 3) arrays."""
    mirror = 2.0 * np.sum(wo * normal, axis=-1, keepdims=True) * normal - wo
    cos_alpha = np.clip(np.sum(wi * mirror, axis=-1), 0.0, 1.0)
    return ks * (n + 2) / (2 * np.pi) * cos_alpha**n


def unit(v):
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def glossy_relay_radiance(x, wo, floor_points=120, lamp_points=10):
    """Radiance leaving plate point x (3,) along world directions wo (D, 3): lamp ->
    floor -> plate, by the midpoint rule."""
    g = (np.arange(floor_points) + 0.5) / floor_points - 0.5
    fx, fz = np.meshgrid(g, g, indexing="ij")
    y = np.stack([fx.ravel(), np.zeros(fx.size), fz.ravel()], -1)  # the floor, y = 0
    gl = (np.arange(lamp_points) + 0.5) / lamp_points - 0.5
    lz, lx = np.meshgrid(gl * 0.1, gl * 0.1, indexing="ij")
    z = np.stack([lx.ravel() - 0.3, np.full(lx.size, 0.4), lz.ravel()], -1)  # lamp, facing -y
    up, down = np.array([0.0, 1.0, 0.0]), np.array([0.0, -1.0, 0.0])
    # light leaving each floor point towards x
    to_lamp = z[None, :, :] - y[:, None, :]  # (Y, Z, 3)
    r2 = np.sum(to_lamp**2, -1)
    wi = to_lamp / np.sqrt(r2)[..., None]
    to_x = unit(x[None, :] - y)  # (Y, 3)
    f_floor = phong(FLOOR_KS, FLOOR_N, up, wi, np.broadcast_to(to_x[:, None, :], wi.shape))
    cos_floor = np.clip(wi[..., 1], 0, None)
    cos_lamp = np.clip(-np.sum(wi * down, -1), 0, None)
    radiance_floor = np.sum(f_floor * RELAY_LE * cos_floor * cos_lamp / r2, axis=1) * (0.1 / lamp_points) ** 2
    # and the plate's lobe over the floor
    to_floor = y - x[None, :]
    d2 = np.sum(to_floor**2, -1)
    wi_x = to_floor / np.sqrt(d2)[:, None]
    cos_x = np.clip(np.sum(wi_x * down, -1), 0, None)
    cos_y = np.clip(-wi_x[:, 1], 0, None)
    geometry = radiance_floor * cos_x * cos_y / d2 / floor_points**2  # (Y,)
    f_plate = phong(PLATE_KS, PLATE_N, down, wi_x[None, :, :], wo[:, None, :])  # (D, Y)
    return f_plate @ geometry
