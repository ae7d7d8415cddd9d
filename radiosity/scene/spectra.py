"""Sampled spectra as linear sRGB, as Mitsuba 3's RGB modes turn a scene's spectra into
colours when they read it.

    XYZ = integral of s(lambda) cmf(lambda) w(lambda) dlambda / integral of cmf_y(lambda) w(lambda) dlambda
    RGB = XYZ_TO_SRGB @ XYZ

over 360-830 nm, s linearly interpolated between its samples and 0 outside them, cmf the
CIE 1931 2-degree colour-matching functions. An emitted spectrum (radiance, intensity,
irradiance) is weighed by w = 1 (equal energy: a flat spectrum of 1 has Y = 1) and only
its negative channels are clipped; a reflectance by daylight (w the D65 illuminant) and
normalised so that a flat reflectance of 1 is white (1, 1, 1), then clipped to [0, 1];
an index of refraction or absorption (eta, k) by daylight, unclipped above.

Two stand-ins keep the tables out of the code: the colour-matching functions are the
analytic multi-lobe fit of Wyman, Sloan and Shirley (2013, "Simple analytic
approximations to the CIE XYZ color matching functions", JCGT 2(2)), and daylight is a
black body at D65's correlated temperature, 6504 K. Measured against Mitsuba 3.9.1's own
conversion of the Cornell box's spectra (tests/radiosity/scene/test_spectra.py): the
emitter within 0.6 %, the white, red and green reflectances' main channels within 2.5 %
(0.005 absolute on their small channels).
"""

from __future__ import annotations

import numpy as np

__all__ = ["XYZ_TO_SRGB", "colour_matching", "spectrum_to_rgb"]

CIE_RANGE = (360.0, 830.0)  # nm
_STEPS = 4701  # 0.1 nm
XYZ_TO_SRGB = np.array([[3.2406, -1.5372, -0.4986],  # IEC 61966-2-1, linear sRGB from XYZ (D65 white)
                        [-0.9689, 1.8758, 0.0415],
                        [0.0557, -0.2040, 1.0570]])
DAYLIGHT_K = 6504.0

# (weight, mean nm, sigma below the mean, sigma above) of each lobe of x, y, z (Wyman et al. 2013, table 1)
_LOBES = (
    ((1.056, 599.8, 37.9, 31.0), (0.362, 442.0, 16.0, 26.7), (-0.065, 501.1, 20.4, 26.2)),
    ((0.821, 568.8, 46.9, 40.5), (0.286, 530.9, 16.3, 31.1)),
    ((1.217, 437.0, 11.8, 36.0), (0.681, 459.0, 26.0, 13.8)),
)


def colour_matching(wavelengths):
    """(N, 3) the CIE 1931 x, y, z colour-matching functions at ``wavelengths`` (N,) nm."""
    lam = np.asarray(wavelengths, dtype=np.float64)[:, None]
    out = []
    for lobes in _LOBES:
        total = np.zeros(lam.shape[0])
        for weight, mean, below, above in lobes:
            sigma = np.where(lam[:, 0] < mean, below, above)
            total += weight * np.exp(-0.5 * ((lam[:, 0] - mean) / sigma) ** 2)
        out.append(total)
    return np.stack(out, axis=1)


def _daylight(lam):
    """A black body at DAYLIGHT_K, per nm (its scale cancels)."""
    metres = lam * 1e-9
    return 1.0 / (metres**5 * np.expm1(1.438777e-2 / (metres * DAYLIGHT_K)))


_LAMBDA = np.linspace(*CIE_RANGE, _STEPS)
_CMF = colour_matching(_LAMBDA)
_DAYLIGHT = _daylight(_LAMBDA)


def _xyz(values, weight):
    return np.trapezoid(_CMF * (values * weight)[:, None], _LAMBDA, axis=0) / np.trapezoid(_CMF[:, 1] * weight,
                                                                                             _LAMBDA)


_WHITE = XYZ_TO_SRGB @ _xyz(np.ones_like(_LAMBDA), _DAYLIGHT)  # a flat reflectance of 1 under daylight


def spectrum_to_rgb(wavelengths, values, kind="reflectance"):
    """Linear sRGB (3,) float64 of a spectrum sampled at ``wavelengths`` (increasing, nm)
    with ``values``; ``kind`` "reflectance" (daylight-weighted, white-normalised, clipped
    to [0, 1]), "emitted" (equal-energy, clipped below 0) or "unbounded" (an index:
    daylight-weighted, clipped below 0)."""
    wavelengths = np.asarray(wavelengths, dtype=np.float64)
    values = np.asarray(values, dtype=np.float64)
    inside = (_LAMBDA >= wavelengths[0]) & (_LAMBDA <= wavelengths[-1])
    sampled = np.where(inside, np.interp(_LAMBDA, wavelengths, values), 0.0)
    if kind == "emitted":
        return np.maximum(XYZ_TO_SRGB @ _xyz(sampled, np.ones_like(_LAMBDA)), 0.0)
    rgb = XYZ_TO_SRGB @ _xyz(sampled, _DAYLIGHT) / _WHITE
    if kind == "reflectance":
        return np.clip(rgb, 0.0, 1.0)
    if kind == "unbounded":
        return np.maximum(rgb, 0.0)
    raise ValueError(f"unknown kind {kind!r}")
