"""Image metrics, in one place: how far a picture is from a reference.

    metrics(reference, test, exposure, mask)   FLIP mean, PSNR and relative MSE, over the
                                               whole image and the masked ("_glossy")
                                               pixels, and the FLIP error image
    against_truth(truth, images, ...)          every image against a path-traced truth
    mean_ratio(reference, test)                mean of the test over mean of the reference:
                                               how much of the reference's light it has
    is_black(image)                            no positive value: errors relative to it
                                               are undefined
    magma(values)                              [0, 1] -> the error images' colours

FLIP is NVIDIA's perceptual difference (HDR mode, on linear radiance), per pixel from
0 (identical) to 1; PSNR is of the tone-mapped 8-bit pictures; relative MSE is the
mean over pixels and channels of (test - ref)^2 / (ref^2 + 0.01), which weighs an error
against the light it sits in.
"""

from __future__ import annotations

import numpy as np

from radiosity.files.errors import InputError

from .renderer import tonemap

__all__ = ["BLACK", "NOT_FINITE", "against_truth", "is_black", "magma", "mean_ratio", "metrics"]

BLACK = "is black, so errors relative to it (FLIP, relative MSE) are undefined"
NOT_FINITE = ("has {count} values beyond float32 (infinite or NaN: radiance that overflows when a pixel's samples "
              "are added), so errors relative to it are undefined")


def is_black(image):
    """True if ``image`` has no positive value: errors relative to it are undefined."""
    return not np.nanmax(image, initial=0.0) > 0


def magma(values):
    """(H, W) values in [0, 1] -> (H, W, 3) uint8 through matplotlib's magma colour map."""
    from matplotlib import colormaps

    return (colormaps["magma"](np.clip(values, 0, 1))[..., :3] * 255 + 0.5).astype(np.uint8)


def metrics(reference, test, exposure=1.0, mask=None):
    """FLIP mean, PSNR and relative MSE of ``test`` against ``reference`` ((H, W, 3) linear),
    over the whole image and, with ``mask`` ((H, W) bool), over the masked pixels alone
    (keys suffixed "_glossy"); and the FLIP error image ((H, W, 3) uint8, magma).

    A black reference, and an image with an infinite or NaN value, are refused
    (InputError): FLIP's exposure range comes from the reference and does not exist
    for a black or infinite one (FLIP would end the process). FLIP
    sees both images scaled so the reference's brightest value is 1: its HDR mode
    is scale-invariant, and so very dim references (units of 1e-9) work too."""
    import flip_evaluator

    for label, image in (("reference", reference), ("test", test)):
        if not np.isfinite(image).all():  # FLIP would end the process ("Start exposure must be smaller than stop")
            raise InputError(f"the {label} image {NOT_FINITE.format(count=int(np.sum(~np.isfinite(image))))}")
    ref = np.ascontiguousarray(np.maximum(reference, 0), np.float32)
    tst = np.ascontiguousarray(np.maximum(test, 0), np.float32)
    if is_black(ref):
        raise InputError(f"the reference image {BLACK}")
    peak = ref.max()
    scaled_test = np.minimum(tst / peak, np.finfo(np.float32).max / 4)  # a dim reference must not overflow the test
    error_map, _, _ = flip_evaluator.evaluate(ref / peak, scaled_test, "HDR", applyMagma=False)
    flip_values = np.asarray(error_map, np.float64).reshape(ref.shape[:2] + (-1,))[..., 0]
    a = tonemap(ref, exposure).astype(np.float64) / 255
    b = tonemap(tst, exposure).astype(np.float64) / 255
    squared = np.mean((a - b) ** 2, axis=2)
    relative = np.mean((tst.astype(np.float64) - ref) ** 2 / (ref.astype(np.float64) ** 2 + 0.01), axis=2)

    def numbers(select):
        mse = float(np.mean(squared[select]))
        return {
            "flip_mean": float(np.mean(flip_values[select])),
            "psnr_db": float("inf") if mse == 0 else float(10 * np.log10(1.0 / mse)),
            "relative_mse": float(np.mean(relative[select])),
        }

    out = numbers(np.ones(squared.shape, bool))
    if mask is not None and mask.any():
        out |= {f"{k}_glossy": v for k, v in numbers(mask).items()}
        out["glossy_pixels"] = int(mask.sum())
    error_image = magma(flip_values)
    return out, error_image


def mean_ratio(reference, test):
    """mean(``test``) / mean(``reference``), over every pixel and channel of both
    (H, W, 3) linear images, in float64: 1 when the test holds as much light as the
    reference overall, 0.5 when half (FLIP and relative MSE say where, this how much).
    A black reference is refused (InputError): the ratio has no meaning."""
    ref = float(np.mean(reference, dtype=np.float64))
    if not ref > 0:
        raise InputError(f"the reference image {BLACK}")
    return float(np.mean(test, dtype=np.float64)) / ref


def against_truth(truth, images, exposure=1.0, mask=None):
    """Each of ``images`` ({label: (H, W, 3) linear}) against the path-traced ``truth``:
    {label: FLIP, PSNR and relative MSE, whole image and (with ``mask``) glossy pixels},
    and {label: its FLIP error image}."""
    numbers, errors = {}, {}
    for label, image in images.items():
        numbers[label], errors[label] = metrics(truth, image, exposure, mask)
    return numbers, errors
