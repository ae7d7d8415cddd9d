"""Fitting the linearly transformed cosines (Heitz et al. 2016) of the microfacet lobes,
offline: what ``radiosity/physics/data/ltc.npz`` holds and ``radiosity.physics.ltc``
reads.

For a lobe (GGX or Beckmann, roughness alpha) seen from wo at theta_o from the normal,
the target is the specular lobe without its Fresnel factor, times the cosine:

    T(wi) = D(h) G1(wi) G1(wo) / (4 cos theta_o),   wi above the surface,

in the frame where n = z and wo lies in the xz plane (x > 0). Its integral ``norm`` is
the lobe's directional albedo without Fresnel, and ``schlick`` = int T (1 - wi.h)^5 dwi
its part weighted by Schlick's term, so that a Fresnel curve F0 + (1 - F0)(1 - c)^5
integrates to F0 norm + (1 - F0) schlick. The cosine distribution transformed by the
matrix M = [[a, 0, b], [0, c, 0], [d, 0, 1]] (a density over the sphere,
D(w) = max(0, w'.z) / pi |det M^-1| / |M^-1 w|^3 with w' = M^-1 w / |M^-1 w|) is fitted
to T / norm by Nelder-Mead on the error of Heitz et al.'s fit, the mean of |T / norm -
D|^3 over samples of both (each weighted by the inverse of the mixture's density), the
same random numbers every evaluation. Each cell starts from its fitted neighbour (from
rough to smooth, from normal incidence to grazing).

The table is kept per distribution as (alphas, thetas, 6): on sqrt(alpha) uniform over
[sqrt(``ALPHA_MIN``), 1] and on sqrt(1 - cos theta_o) uniform over [0, 1], the
entries k00, k02, k20, k22 of K = diag(alpha, alpha, 1) M^-1 / (alpha M^-1[1, 1])
(so M^-1 is proportional to diag(1 / alpha, 1 / alpha, 1) K, whose middle entry is 1:
bounded and smooth in both coordinates, down to the sharpest lobes), then norm and
schlick. ``python -m radiosity.scene.ltc_fit`` writes the file (a few minutes on two
cores); tests refit cells and compare.
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import numpy as np
from scipy.optimize import minimize

from radiosity.scene.microfacet import masking, ndf

ALPHA_MIN = 1e-4
SIZE = 32  # cells along each coordinate
SAMPLES = 32  # strata along each dimension of each sample set (SAMPLES^2 samples each)
TABLE = Path(__file__).resolve().parents[1] / "formats" / "data" / "ltc.npz"
DISTRIBUTIONS = ("ggx", "beckmann")


def grid(size=SIZE):
    """(alphas (size,), cos thetas (size,)) of the table's cells."""
    r = np.linspace(math.sqrt(ALPHA_MIN), 1.0, size)
    t = np.linspace(0.0, 1.0, size)
    return r * r, 1.0 - t * t


def _strata(count, seed):
    """(count^2, 2) jittered strata of the unit square, the same for a seed."""
    rng = np.random.default_rng(seed)
    i, j = np.meshgrid(np.arange(count), np.arange(count), indexing="ij")
    return np.stack([(i.ravel() + rng.random(count * count)) / count,
                     (j.ravel() + rng.random(count * count)) / count], axis=-1)


def _wo(cos_o):
    c = min(max(cos_o, 1e-4), 1.0)
    return np.array([math.sqrt(max(0.0, 1.0 - c * c)), 0.0, c])


def target(distribution, alpha, wo, wi):
    """T(wi) (...,) float64 (see the module's docstring) for unit wi (..., 3)."""
    h = wi + wo
    h = h / np.maximum(np.linalg.norm(h, axis=-1, keepdims=True), 1e-300)
    cih = np.sum(wi * h, axis=-1)
    g = masking(distribution, alpha, wi[..., 2], cih) * masking(distribution, alpha, wo[2], h @ wo)
    value = ndf(distribution, alpha, h[..., 2]) * g / (4.0 * wo[2])
    return np.where(wi[..., 2] > 0.0, value, 0.0), cih


def _target_samples(distribution, alpha, wo, u):
    """Directions wi (N, 3) from microfacet normals drawn from D(h) cos theta_h, and
    their densities (N,)."""
    x = u[:, 0] / (1.0 - u[:, 0]) if distribution == "ggx" else -np.log1p(-u[:, 0])
    tan_t = alpha * np.sqrt(x)
    cos_t = 1.0 / np.sqrt(1.0 + tan_t * tan_t)
    sin_t = tan_t * cos_t
    phi = 2.0 * math.pi * u[:, 1]
    h = np.stack([sin_t * np.cos(phi), sin_t * np.sin(phi), cos_t], axis=-1)
    oh = h @ wo
    wi = 2.0 * oh[:, None] * h - wo
    pdf = ndf(distribution, alpha, cos_t) * cos_t / np.maximum(4.0 * np.abs(oh), 1e-300)
    return wi, pdf


def moments(distribution, alpha, cos_o, count=128):
    """(norm, schlick) of the lobe (see the module's docstring) by importance sampling."""
    wo = _wo(cos_o)
    wi, pdf = _target_samples(distribution, alpha, wo, _strata(count, 7))
    value, cih = target(distribution, alpha, wo, wi)
    ok = pdf > 0.0
    ratio = np.where(ok, value / np.where(ok, pdf, 1.0), 0.0)
    return float(ratio.mean()), float((ratio * (1.0 - np.clip(cih, 0.0, 1.0)) ** 5).mean())


def matrix(params):
    """M of the parameters (a, b, c, d)."""
    a, b, c, d = params
    return np.array([[a, 0.0, b], [0.0, c, 0.0], [d, 0.0, 1.0]])


def ltc_density(inverse, w):
    """D(w) (N,) of the cosine transformed by M (given its inverse) at unit w (N, 3)."""
    v = w @ inverse.T
    length = np.linalg.norm(v, axis=-1)
    return np.maximum(v[:, 2] / length, 0.0) / math.pi * abs(np.linalg.det(inverse)) / length**3


def _ltc_samples(m, u):
    r = np.sqrt(u[:, 0])
    phi = 2.0 * math.pi * u[:, 1]
    w = np.stack([r * np.cos(phi), r * np.sin(phi), np.sqrt(np.maximum(0.0, 1.0 - u[:, 0]))], axis=-1) @ m.T
    return w / np.linalg.norm(w, axis=-1, keepdims=True)


class _Cell:
    """One cell's fixed target samples and the error of a parameter vector."""

    def __init__(self, distribution, alpha, cos_o, count=SAMPLES):
        self.distribution, self.alpha, self.wo = distribution, alpha, _wo(cos_o)
        self.norm, self.schlick = moments(distribution, alpha, cos_o)
        self.u_ltc = _strata(count, 11)
        wi, self.pdf_t = _target_samples(distribution, alpha, self.wo, _strata(count, 13))
        self.wi_t = wi
        self.t_t = target(distribution, alpha, self.wo, wi)[0] / self.norm

    def error(self, params):
        m = matrix(params)
        det = np.linalg.det(m)
        if not (np.isfinite(det) and det > 1e-30 and params[0] > 0 and params[2] > 0):
            return 1e30
        inverse = np.linalg.inv(m)
        wl = _ltc_samples(m, self.u_ltc)
        dl = ltc_density(inverse, wl)
        tl = target(self.distribution, self.alpha, self.wo, wl)[0] / self.norm
        _, pdf_tl = self._target_pdf(wl)
        dt = ltc_density(inverse, self.wi_t)
        e1 = np.abs(tl - dl) ** 3 / np.maximum(0.5 * (dl + pdf_tl), 1e-300)
        e2 = np.abs(self.t_t - dt) ** 3 / np.maximum(0.5 * (dt + self.pdf_t), 1e-300)
        return float(np.mean(e1) + np.mean(e2)) * 0.5

    def _target_pdf(self, wi):
        """The target sampler's density at wi."""
        h = wi + self.wo
        h = h / np.maximum(np.linalg.norm(h, axis=-1, keepdims=True), 1e-300)
        oh = h @ self.wo
        return h, np.where(oh > 0.0, ndf(self.distribution, self.alpha, h[:, 2]) * h[:, 2] / np.maximum(4.0 * oh, 1e-300), 0.0)


def _rotated(theta, scale):
    """The parameters of the cosine scaled by ``scale`` across and turned by theta about y."""
    c, s = math.cos(theta), math.sin(theta)
    return np.array([scale, s / c, scale / c, -scale * s / c])


def fit_cell(distribution, alpha, cos_o, start):
    """(parameters (a, b, c, d), norm, schlick) of one cell, from the best of ``start``
    and cosines turned to the lobe's mean direction, of a few widths."""
    cell = _Cell(distribution, alpha, cos_o)
    weights = cell.t_t / np.maximum(cell.pdf_t, 1e-300)
    mean = (weights[:, None] * cell.wi_t).sum(axis=0)
    theta = min(math.atan2(mean[0], mean[2]), 1.45)
    candidates = [np.asarray(start, np.float64)] + [_rotated(theta, s) for s in alpha * np.geomspace(0.5, 8.0, 9)]
    start = min(candidates, key=cell.error)
    best = minimize(cell.error, np.asarray(start, np.float64), method="Nelder-Mead",
                    options={"xatol": 1e-7, "fatol": 1e-10, "maxiter": 1500, "maxfev": 3000, "adaptive": True})
    params = best.x if best.fun <= cell.error(start) else np.asarray(start, np.float64)
    return params, cell.norm, cell.schlick


def stored(params, alpha):
    """The stored (k00, k02, k20, k22) of the fitted M's parameters."""
    inverse = np.linalg.inv(matrix(params))
    k = np.diag([alpha, alpha, 1.0]) @ inverse / (alpha * inverse[1, 1])
    return np.array([k[0, 0], k[0, 2], k[2, 0], k[2, 2]])


def parameters(entries, alpha):
    """The parameters (a, b, c, d) of M from the stored (k00, k02, k20, k22) (``stored``'s inverse)."""
    k00, k02, k20, k22 = entries
    m = np.linalg.inv(np.diag([1.0 / alpha, 1.0 / alpha, 1.0]) @ np.array([[k00, 0.0, k02], [0.0, 1.0, 0.0], [k20, 0.0, k22]]))
    m /= m[2, 2]
    return np.array([m[0, 0], m[0, 2], m[1, 1], m[2, 0]])


def shape_error(distribution, alpha, cos_o, params, count=64):
    """The L1 distance (0 to 2) between the normalised lobe T / norm and the fitted
    distribution, by samples of both (weighted by the inverse of the mixture's density)."""
    cell = _Cell(distribution, alpha, cos_o, count)
    m = matrix(params)
    inverse = np.linalg.inv(m)
    wl = _ltc_samples(m, cell.u_ltc)
    dl = ltc_density(inverse, wl)
    tl = target(distribution, alpha, cell.wo, wl)[0] / cell.norm
    _, pl = cell._target_pdf(wl)
    dt = ltc_density(inverse, cell.wi_t)
    e1 = np.abs(tl - dl) / np.maximum(0.5 * (dl + pl), 1e-300)
    e2 = np.abs(cell.t_t - dt) / np.maximum(0.5 * (dt + cell.pdf_t), 1e-300)
    return 0.5 * float(e1.mean() + e2.mean())


TIE_ALPHA = 2e-3  # below this roughness the transformed cosine's z row barely matters: tied to the row above


def _tie_sharp_rows(distribution, table, alphas, cosines):
    """The sharpest rows' k20, k22 (which the fit leaves nearly free: they scale by alpha)
    set to those of the first row at or above ``TIE_ALPHA`` where that costs at most 1 %
    of the cell's error, so the table stays smooth where it is read bilinearly."""
    above = int(np.searchsorted(alphas, TIE_ALPHA))
    for i in range(above - 1, -1, -1):
        for j in range(len(cosines)):
            cell = _Cell(distribution, alphas[i], cosines[j])
            tied = table[i, j, :4].copy()
            tied[2:] = table[i + 1, j, 2:4]
            mine = cell.error(parameters(table[i, j, :4], alphas[i]))
            if cell.error(parameters(tied, alphas[i])) <= 1.01 * mine + 1e-12:
                table[i, j, :4] = tied


def fit_table(distribution, size=SIZE, progress=None):
    """(size, size, 6) float64: the stored entries of every cell (``stored``, norm, schlick)."""
    alphas, cosines = grid(size)
    table = np.zeros((size, size, 6))
    previous_row = None
    for i in range(size - 1, -1, -1):  # rough to smooth
        alpha = alphas[i]
        start = (np.array([alpha, 0.0, alpha, 0.0]) if previous_row is None
                 else previous_row * np.array([alpha / alphas[i + 1], alpha / alphas[i + 1], alpha / alphas[i + 1], 1.0]))
        for j in range(size):  # normal incidence to grazing
            params, norm, schlick = fit_cell(distribution, alpha, cosines[j], start)
            if j == 0:
                previous_row = params.copy()
            start = params
            table[i, j, :4] = stored(params, alpha)
            table[i, j, 4:] = norm, schlick
            if progress is not None:
                progress()
    _tie_sharp_rows(distribution, table, alphas, cosines)
    return table


def main(argv=None):
    parser = argparse.ArgumentParser(prog="python -m radiosity.scene.ltc_fit", description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", type=Path, default=TABLE, help=f"where to write the table (default {TABLE})")
    parser.add_argument("--size", type=int, default=SIZE, help="cells along each coordinate")
    args = parser.parse_args(argv)
    from tqdm import tqdm

    tables = {}
    with tqdm(total=len(DISTRIBUTIONS) * args.size**2, unit="cell") as bar:
        for name in DISTRIBUTIONS:
            tables[name] = fit_table(name, args.size, bar.update)
    alphas, cosines = grid(args.size)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    tmp = args.out.with_suffix(".tmp.npz")
    np.savez(tmp, alphas=alphas, cosines=cosines, **{k: v.astype(np.float32) for k, v in tables.items()})
    tmp.replace(args.out)
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
