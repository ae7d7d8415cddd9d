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
