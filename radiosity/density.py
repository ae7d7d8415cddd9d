"""Irradiance at every vertex from photon hits: local linear density estimation.

Walter et al. (1997) fit, at each vertex, a linear function to the photon density
with a kernel, which removes the boundary bias of a plain kernel estimate (that reads
1/2 of the truth on an edge and 1/4 in a corner, exactly where mesh vertices sit).
Here the kernel of vertex i is its hat function lambda_i (1 at the vertex, 0 at the
far edges of its triangles, the finite-element basis of the mesh), so

    E(x) ~ a + g . (x - x_i)       minimises  integral lambda_i (E_true - E)^2 dA

and its normal equations need only

    photon moments (streamed, additive over batches):
        S0 = sum_hits power * lambda_i(hit),   S1 = sum_hits power * lambda_i(hit) * d
    kernel moments (exact, from the mesh):
        K0 = integral lambda_i dA,  K1 = integral lambda_i d dA,  K2 = integral lambda_i d d^T dA

with d = x - x_i in vertex i's tangent plane. [K0 K1^T; K1 K2] [a; g] = [S0; S1] gives
a = E(x_i): exact for irradiance that varies linearly, at edges and corners too. At a
vertex inside a symmetric fan K1 = 0 and a = S0 / K0, the normalised kernel estimate.
Vertices split at creases have their own hat functions, so each side of an edge gets
its own light.
"""

from __future__ import annotations

import numpy as np

_CONDITION_LIMIT = 1e-3  # below this (relative) Schur complement, fall back to S0 / K0


def kernel_moments(positions, normals, tangents, faces):
    """K0 (V,), K1 (V, 2), K2 (V, 2, 2) float64 of each vertex's hat function.

    For a triangle (p0, p1, p2) with e1 = p1 - p0, e2 = p2 - p0 seen from corner p0:
    integral lambda0 = A/3, integral lambda0 (x - p0) = A/12 (e1 + e2), and
    integral lambda0 (x - p0)(x - p0)^T = A/30 (e1 e1^T + e2 e2^T) + A/60 (e1 e2^T + e2 e1^T).
    Offsets are expressed in the tangent frame (t, n x t) of the corner's vertex.
    """
    n_vertices = len(positions)
    bitangents = np.cross(normals, tangents)
    tri = positions[faces]  # (F, 3, 3)
    area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    k0 = np.zeros(n_vertices)
    k1 = np.zeros((n_vertices, 2))
    k2 = np.zeros((n_vertices, 2, 2))
    for corner in range(3):
        vert = faces[:, corner]
        frame = np.stack([tangents[vert], bitangents[vert]], axis=1)  # (F, 2, 3)
        e1 = np.einsum("fij,fj->fi", frame, tri[:, (corner + 1) % 3] - tri[:, corner])
        e2 = np.einsum("fij,fj->fi", frame, tri[:, (corner + 2) % 3] - tri[:, corner])
        np.add.at(k0, vert, area / 3.0)
        np.add.at(k1, vert, (area / 12.0)[:, None] * (e1 + e2))
        outer = (
            (area / 30.0)[:, None, None] * (e1[:, :, None] * e1[:, None, :] + e2[:, :, None] * e2[:, None, :])
            + (area / 60.0)[:, None, None] * (e1[:, :, None] * e2[:, None, :] + e2[:, :, None] * e1[:, None, :])
        )
        np.add.at(k2, vert, outer)
    return k0, k1, k2


def local_linear(moment0, moment1, k0, k1, k2):
    """Vertex irradiance (V, 3) float64 from photon moments S0 (V, 3), S1 (V, 3, 2)
    and kernel moments; never negative. Where the fit is ill-conditioned (a vertex
    whose triangles are slivers along one line) the normalised estimate S0 / K0 is used.
    """
    estimate = np.zeros_like(moment0)
    has_area = k0 > 0
    estimate[has_area] = moment0[has_area] / k0[has_area, None]
    det = k2[:, 0, 0] * k2[:, 1, 1] - k2[:, 0, 1] * k2[:, 1, 0]
    scale = np.maximum(k2[:, 0, 0] + k2[:, 1, 1], 1e-300)
    ok = has_area & (det > 1e-9 * scale**2)
    inv = np.zeros_like(k2)
    inv[ok, 0, 0] = k2[ok, 1, 1] / det[ok]
    inv[ok, 1, 1] = k2[ok, 0, 0] / det[ok]
    inv[ok, 0, 1] = -k2[ok, 0, 1] / det[ok]
    inv[ok, 1, 0] = -k2[ok, 1, 0] / det[ok]
    # Schur complement: a = (S0 - K1^T K2^-1 S1) / (K0 - K1^T K2^-1 K1)
    k2inv_k1 = np.einsum("vij,vj->vi", inv, k1)
    schur = k0 - np.einsum("vi,vi->v", k1, k2inv_k1)
    ok &= schur > _CONDITION_LIMIT * k0
    fitted = (moment0 - np.einsum("vi,vci->vc", k2inv_k1, moment1)) / np.where(ok, schur, 1.0)[:, None]
    estimate[ok] = fitted[ok]
    return np.maximum(estimate, 0.0)
