"""radiosity.scene.spectra: sampled spectra as Mitsuba 3's RGB modes read them.

The oracle numbers are Mitsuba 3.9.1's own (scalar_rgb: a diffuse bsdf's and an area
emitter's parameter after loading the Cornell box's spectra, ``mi.traverse``), so the
test needs no Mitsuba."""

import numpy as np
import pytest

from radiosity.scene.spectra import colour_matching, spectrum_to_rgb

# the Cornell box's (Mitsuba's cbox scene) spectra, every fourth sample of its 4 nm tables
WHITE = {400: 0.343, 420: 0.687, 440: 0.745, 460: 0.765, 480: 0.745, 500: 0.747, 520: 0.725, 540: 0.743, 560: 0.733,
         580: 0.764, 600: 0.74, 620: 0.744, 640: 0.712, 660: 0.707, 680: 0.751, 700: 0.737}
RED = {400: 0.04, 420: 0.046, 440: 0.048, 460: 0.053, 480: 0.049, 500: 0.05, 520: 0.053, 540: 0.055, 560: 0.057,
       580: 0.056, 600: 0.059, 620: 0.057, 640: 0.061, 660: 0.061, 680: 0.06, 700: 0.062}
LAMP = {400: 0.0, 500: 8.0, 600: 15.6, 700: 18.4}


def rgb(table, kind="reflectance"):
    w = np.array(sorted(table), float)
    return spectrum_to_rgb(w, [table[k] for k in sorted(table)], kind)


def test_a_flat_reflectance_is_grey_and_a_flat_emission_is_equal_energy_light():
    np.testing.assert_allclose(spectrum_to_rgb([360, 830], [0.5, 0.5]), 0.5, rtol=1e-12)
    np.testing.assert_allclose(spectrum_to_rgb([360, 830], [1.0, 1.0]), 1.0, rtol=1e-12)
    # equal-energy light in sRGB (D65 white): pinkish, its luminance Y = 1
    emitted = spectrum_to_rgb([360, 830], [1.0, 1.0], "emitted")
    assert emitted[0] > emitted[1] > emitted[2] and np.dot([0.2126, 0.7152, 0.0722], emitted) == pytest.approx(1, 2e-3)


def test_the_colour_matching_functions_peak_where_cie_1931_does():
    lam = np.arange(380.0, 781.0)
    cmf = colour_matching(lam)
    assert lam[np.argmax(cmf[:, 0])] == pytest.approx(599, abs=3)
    assert lam[np.argmax(cmf[:, 1])] == pytest.approx(555, abs=3)
    assert lam[np.argmax(cmf[:, 2])] == pytest.approx(446, abs=4)
    assert cmf[:, 1].max() == pytest.approx(1.0, abs=0.01)
    assert np.trapezoid(cmf[:, 1], lam) == pytest.approx(106.86, rel=0.01)  # the standard's integral of y


def test_the_cornell_box_as_mitsuba_3_reads_it():
    # Mitsuba 3.9.1 scalar_rgb on the full 4 nm tables gives: white (0.735, 0.7356, 0.7363), the lamp
    # (20.71, 10.85, 2.771); on these every-fourth samples the white barely moves
    np.testing.assert_allclose(rgb(LAMP, "emitted"), [20.71, 10.85, 2.771], rtol=6e-3)
    white = rgb(WHITE)
    assert np.ptp(white) < 0.015 and white.mean() == pytest.approx(0.72, abs=0.02)  # near grey, as Mitsuba's
    red = rgb(RED | {600: 0.59, 620: 0.6, 640: 0.61, 660: 0.61, 680: 0.6, 700: 0.6, 580: 0.3})
    assert red[0] > 5 * red[1] and red[0] > 5 * red[2]


def test_out_of_gamut_colours_are_clipped_as_mitsuba_clips_them():
    narrow = spectrum_to_rgb([500, 505, 510], [0, 1, 0])  # a spectral green: negative red in sRGB
    assert narrow[0] == 0 and narrow[1] > 0
    assert spectrum_to_rgb([360, 830], [3.0, 3.0]).tolist() == [1.0, 1.0, 1.0]  # a reflectance is at most 1
    assert spectrum_to_rgb([360, 830], [3.0, 3.0], "unbounded") == pytest.approx(3.0)


MITSUBA_SPECTRA = """
import json, sys
import mitsuba as mi
mi.set_variant("scalar_rgb")
out = []
for pairs, emitted in json.loads(sys.argv[1]):
    value = {"type": "spectrum", "value": [tuple(p) for p in pairs]}
    plugin = mi.load_dict({"type": "area", "radiance": value} if emitted else {"type": "diffuse", "reflectance": value})
    out.append(list(mi.traverse(plugin)["radiance.value" if emitted else "reflectance.value"]))
print(json.dumps(out))
"""


def test_smooth_spectra_against_mitsuba_3_itself(rng):
    # reflectances and emitters of smooth random spectra (sums of broad bumps), as Mitsuba 3's RGB mode reads them
    import json

    from mitsuba_oracle import run_mitsuba

    cases = []
    lam = np.arange(380.0, 781.0, 20.0)
    for k in range(24):
        centres, widths = rng.uniform(400, 700, 3), rng.uniform(40, 120, 3)
        values = 0.05 + sum(rng.uniform(0.1, 0.5) * np.exp(-0.5 * ((lam - c) / w) ** 2) for c, w in zip(centres, widths))
        emitted = k % 2 == 1
        cases.append(([[float(a), float(b * (10 if emitted else 1))] for a, b in zip(lam, values)], emitted))
    answer = run_mitsuba(MITSUBA_SPECTRA, json.dumps(cases)).strip().splitlines()[-1]
    theirs = np.array(json.loads(answer[answer.index("[["):]))  # after Mitsuba's log colour codes
    ours = np.array([spectrum_to_rgb([p[0] for p in pairs], [p[1] for p in pairs], "emitted" if emitted else "reflectance")
                     for pairs, emitted in cases])
    scale = theirs.max(axis=1, keepdims=True)  # each colour's error relative to its brightest channel
    assert (np.abs(ours - theirs) / scale).max() < 0.03, np.abs(ours - theirs) / scale
