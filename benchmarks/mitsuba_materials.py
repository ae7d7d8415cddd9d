"""What Mitsuba 3 itself says about its rough materials: the named metals' RGB complex
index, and its BSDFs' values against radiosity.scene.microfacet's numpy references.

Usage:
    python benchmarks/mitsuba_materials.py [--mitsuba-python PATH] [--write]

Mitsuba is not a dependency of the project. It is looked for in this interpreter, then
in ``--mitsuba-python`` (default ``$MITSUBA_PYTHON``, else /work/mitsuba-venv/bin/python,
made by ``python3 -m venv /work/mitsuba-venv && /work/mitsuba-venv/bin/pip install
mitsuba``); without it the script says so and exits 0. That interpreter runs this same
file with ``--dump``, which needs nothing but mitsuba, and prints JSON:

- every preset Mitsuba's ``conductor`` accepts (the names of its ``data/ior/*.eta.spd``
  with a ``.k.spd`` beside, and ``none``), with the RGB eta and k its ``scalar_rgb``
  variant uses (read back from the loaded BSDF with ``mi.traverse``: Mitsuba converts
  each spectral curve to sRGB itself) and the smooth conductor's reflectance at normal
  incidence;
- ``bsdf.eval`` (f cos(theta_o), local frame) of roughplastic and roughconductor (GGX,
  Beckmann; alpha 0.05, 0.2, 0.6) and the smooth plastic at fixed directions.

Then, in the project's interpreter: the metals are compared with
``radiosity/scene/data/mitsuba_metals.json`` (``--write`` rewrites that file from
Mitsuba), the reference's normal-incidence Fresnel with Mitsuba's reflectance, and the
reference BRDFs with Mitsuba's values (relative error per case). Rows go to
``benchmarks/results/mitsuba_materials.jsonl``. Exit 1 if the metal table differs from
Mitsuba's or a BRDF value is off by more than 2 %.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
METALS_FILE = ROOT / "radiosity" / "scene" / "data" / "mitsuba_metals.json"
DEFAULT_PYTHON = "/work/mitsuba-venv/bin/python"

# Directions (theta_i, theta_o, phi_o in degrees; phi_o from the mirror's azimuth) at
# which Mitsuba's BSDFs are evaluated.
DIRECTIONS = [(0, 0, 0), (0, 10, 0), (30, 30, 0), (30, 40, 0), (30, 30, 15), (60, 60, 0), (60, 70, 0),
              (60, 55, 20), (75, 75, 0), (80, 80, 0), (20, 50, 90)]
ROUGH_CASES = [(kind, dist, alpha) for kind in ("roughplastic", "roughconductor")
               for dist in ("ggx", "beckmann") for alpha in (0.05, 0.2, 0.6)]
CONDUCTOR_OF_CASES = "Cu"


def _direction(theta_deg, phi_deg):
    t, p = math.radians(theta_deg), math.radians(phi_deg)
    return [math.sin(t) * math.cos(p), math.sin(t) * math.sin(p), math.cos(t)]


def directions():
    """(wi, wo) pairs, wi in the xz plane at phi 0, wo's azimuth measured from the mirror's (180)."""
    return [(_direction(ti, 0.0), _direction(to, 180.0 + po)) for ti, to, po in DIRECTIONS]


def dump():
    """Runs inside Mitsuba's interpreter: print everything Mitsuba says as JSON."""
    import mitsuba as mi

    mi.set_variant("scalar_rgb")
    mi.set_log_level(mi.LogLevel.Error)  # its out-of-gamut notes (clamped spectra) go to stdout
    ior_dir = Path(mi.__file__).resolve().parent / "data" / "ior"
    names = sorted(p.name[: -len(".eta.spd")] for p in ior_dir.glob("*.eta.spd")
                   if (ior_dir / (p.name[: -len(".eta.spd")] + ".k.spd")).exists())
    ctx = mi.BSDFContext()

    def normal_reflectance(bsdf):
        si = mi.SurfaceInteraction3f()
        si.wi = mi.Vector3f(0, 0, 1)
        _, value = bsdf.sample(ctx, si, 0.5, mi.Point2f(0.5, 0.5))
        return [float(value[i]) for i in range(3)]

    metals = {}
    for name in ["none"] + names:
        bsdf = mi.load_dict({"type": "conductor", "material": name})
        params = mi.traverse(bsdf)
        metals[name] = {"eta": [float(params["eta.value"][i]) for i in range(3)] if name != "none" else [0.0] * 3,
                        "k": [float(params["k.value"][i]) for i in range(3)] if name != "none" else [1.0] * 3,
                        "normal_reflectance": normal_reflectance(bsdf)}
        if name == "none":  # none's eta and k are uniform spectra: read them from the values
            metals[name]["eta"] = [float(params["eta.value"])] * 3
            metals[name]["k"] = [float(params["k.value"])] * 3

    def evaluate(spec):
        bsdf = mi.load_dict(spec)
        out = []
        for wi, wo in directions():
            si = mi.SurfaceInteraction3f()
            si.wi = mi.Vector3f(*wi)
            value = bsdf.eval(ctx, si, mi.Vector3f(*wo))
            out.append([float(value[i]) for i in range(3)])
        return out

    cases = []
    for kind, dist, alpha in ROUGH_CASES:
        spec = {"type": kind, "distribution": dist, "alpha": alpha}
        if kind == "roughconductor":
            spec["material"] = CONDUCTOR_OF_CASES
        cases.append({"kind": kind, "distribution": dist, "alpha": alpha, "eval": evaluate(spec)})
    cases.append({"kind": "plastic", "distribution": None, "alpha": None, "eval": evaluate({"type": "plastic"})})
    print(json.dumps({"mitsuba": mi.__version__, "variant": "scalar_rgb", "metals": metals, "cases": cases}))


def find_python(given):
    try:
        import mitsuba  # noqa: F401

        return sys.executable
    except ImportError:
        pass
    for candidate in (given, os.environ.get("MITSUBA_PYTHON"), DEFAULT_PYTHON):
        if candidate and Path(candidate).exists():
            probe = subprocess.run([candidate, "-c", "import mitsuba"], capture_output=True)
            if probe.returncode == 0:
                return candidate
    return None


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--mitsuba-python", default=None)
    parser.add_argument("--write", action="store_true", help="rewrite radiosity/scene/data/mitsuba_metals.json")
    parser.add_argument("--dump", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.dump:
        dump()
        return 0
    python = find_python(args.mitsuba_python)
    if python is None:
        print("skipped: mitsuba is not installed here (see the usage: a venv of its own)")
        return 0
    run = subprocess.run([python, __file__, "--dump"], capture_output=True, text=True)
    if run.returncode != 0:
        print(run.stderr, file=sys.stderr)
        return 1
    said = json.loads(run.stdout.strip().splitlines()[-1])
    return compare(said, args.write)


def compare(said, write):
    import numpy as np
    from _common import Recorder

    metals = {name: {"eta": v["eta"], "k": v["k"]} for name, v in said["metals"].items()}
    if write:
        lines = ",\n".join(f"  {json.dumps(name)}: {json.dumps(v)}" for name, v in metals.items())
        source = (f"Mitsuba {said['mitsuba']} ({said['variant']}): the conductor presets' RGB eta and k "
                  "(its own sRGB conversion of data/ior/*.spd, out-of-gamut values clamped to 0 by it), "
                  "read by benchmarks/mitsuba_materials.py --write")
        METALS_FILE.write_text(f'{{\n "source": {json.dumps(source)},\n "metals": {{\n{lines}\n }}\n}}\n')
    from radiosity.scene import microfacet

    record = Recorder(mitsuba=said["mitsuba"], variant=said["variant"])
    failed = False
    for name, v in said["metals"].items():
        ours = microfacet.METALS.get(name)
        table_error = (max(abs(a - b) for a, b in zip(ours[0] + ours[1], v["eta"] + v["k"]))
                       if ours else None)
        fresnel = microfacet.fresnel_conductor(1.0, np.array(v["eta"]), np.array(v["k"]))
        fresnel_error = float(np.max(np.abs(fresnel - np.array(v["normal_reflectance"]))))
        bad = table_error is None or table_error > 1e-6 or fresnel_error > 1e-4
        failed |= bad
        record({"part": "metal", "name": name, "eta": v["eta"], "k": v["k"],
                "mitsuba_normal_reflectance": v["normal_reflectance"], "ours_normal_reflectance": fresnel.tolist(),
                "table_error": table_error, "fresnel_error": fresnel_error, "ok": not bad})
    pairs = directions()
    wi = np.array([p[0] for p in pairs])
    wo = np.array([p[1] for p in pairs])
    for case in said["cases"]:
        params = {"material": CONDUCTOR_OF_CASES} if case["kind"] == "roughconductor" else {}
        brdf = microfacet.reference_brdf(case["kind"], case["distribution"] or "beckmann", case["alpha"] or 0.1,
                                         **params)
        ours = brdf.eval(wi, wo) * wo[:, 2:3]
        theirs = np.array(case["eval"])
        scale = np.maximum(np.abs(theirs), 1e-3 * np.abs(theirs).max())
        relative = np.abs(ours - theirs) / scale
        worst = int(np.argmax(relative.max(axis=1)))
        bad = bool(relative.max() > 0.02)
        failed |= bad
        record({"part": "brdf", "kind": case["kind"], "distribution": case["distribution"], "alpha": case["alpha"],
                "max_relative_error": float(relative.max()), "median_relative_error": float(np.median(relative)),
                "worst_direction_deg": DIRECTIONS[worst], "ours": ours[worst].tolist(),
                "theirs": theirs[worst].tolist(), "ok": not bad})
    record.save("mitsuba_materials.jsonl")
    print("FAILED" if failed else "agrees with Mitsuba")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
