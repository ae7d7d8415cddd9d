"""How well does the modified-Phong lobe stand in for Mitsuba's rough materials?

Usage:
    python benchmarks/bench_material_mapping.py [--parts rule,sphere,fresnel] [--quick]

Parts (rows in benchmarks/results/material_mapping.jsonl; plots material_mapping.png,
the sphere's profiles, and material_mapping_rule.png, the rule and Fresnel):
  rule     for GGX and Beckmann, alpha on 13 values in [0.01, 1] and incidence 0 to 85
           degrees: the Phong exponent whose lobe (f cos, about the mirror direction)
           has the same half-maximum solid angle as the microfacet lobe (F = 1); their
           mean in log over incidence, weighted by sin(2 theta) (the density of the
           highlight's incidence when light and viewer are independent uniform
           directions); then n alpha^2 = c + d alpha^2 + e alpha^4 fitted in relative
           least squares over alpha (where n alpha^2 > 0.05): the rule n = c / alpha^2 +
           d + e alpha^2 of radiosity.scene.microfacet.RULE. Also the guesses 2/alpha^2 -
           2 and (2/alpha^2 - 2)/4 against it.
  sphere   a unit sphere seen by an orthographic camera along -z, lit by one square
           area light (side 0.5 at distance 5, radiance 1) at 60 or 120 degrees from
           the view (the highlight's incidence about 30 or 60 degrees). Each pixel of a window
           about the highlight (72 x 72) integrates the reflected radiance over the
           light (28 x 28 Gauss-Legendre nodes) for the reference BRDF's specular part
           and the mapped Phong lobe's (radiosity.scene.material_kernels.eval_brdf with kd = 0);
           per kind (roughplastic, roughconductor Cu), distribution and alpha: the
           peak's position (degrees of the normal from the half vector, in the plane of
           the light), FWHM in the plane and across (degrees of normal), peak radiance
           ratio and the window's total reflected power ratio (Phong / reference).
           The diffuse part's albedo (roughplastic) is in the report of
           phong_lobe_for, rows "albedo".
  fresnel  the dielectric's reflectance (int_ior 1.49, ext_ior 1.000277) at incidence
           0..89 degrees, exact and Schlick's; a rough plastic floor's specular albedo
           (alpha 0.05, 0.2) against its mapped Phong lobe's (constant ks) at the same
           angles, and the ratio a constant ks would have to absorb. Rows
           "fresnel_form": Schlick's largest error against the exact curve, for the
           dielectric and each of Mitsuba's named metals (the choice of form). Rows
           "fresnel_rule": per material, the mapped lobe's albedo over incidence
           against the reference's for three rules (constant ks; Fresnel with ks <= 1;
           Fresnel with ks fitted up to the energy bound, the rule): sin 2 theta
           weighted relative RMS misfits of the specular, diffuse and total albedo.

Equivalence check: the rule's exponent (RULE) is compared with the fit just measured
(the same to 2 % or the script says so), and the sphere's reference is the same BRDF
Mitsuba's eval gives (checked by benchmarks/mitsuba_materials.py).
"""

from __future__ import annotations

import argparse
import json
import math
import sys

import numpy as np
from _common import RESULTS, Recorder

from radiosity.scene import microfacet as mf
from radiosity.scene.material_kernels import Material, eval_brdf

ALPHAS_RULE = np.geomspace(0.01, 1.0, 13)
INCIDENCE_RULE = np.arange(0.0, 86.0, 5.0)
ALPHAS_SPHERE = (0.03, 0.1, 0.2, 0.4, 0.7)
LIGHT_ANGLES = (60.0, 120.0)


# --- rule ----------------------------------------------------------------------------------


def _phong_lobe(n, theta):
    wv = np.array([math.sin(theta), 0.0, math.cos(theta)])
    m = np.array([-wv[0], 0.0, wv[2]])
    return lambda w: np.maximum(w @ m, 0.0) ** n * w[..., 2]


def _reference_lobe(dist, alpha, theta):
    wv = np.array([math.sin(theta), 0.0, math.cos(theta)])
    return lambda w: mf._specular(dist, alpha, np.broadcast_to(wv, w.shape), w, mf._no_fresnel)[..., 0] * w[..., 2]


def equivalent_exponent(solid_angle, theta, extent, samples):
    """The Phong n whose f cos lobe at theta has this half-maximum solid angle (bisection in log n)."""
    lo, hi = -4.0, 7.0
    if mf.lobe_width(_phong_lobe(10**lo, theta), theta, extent, samples)["solid_angle"] <= solid_angle:
        return 0.0  # broader than the broadest Phong lobe
    for _ in range(20):
        mid = 0.5 * (lo + hi)
        if mf.lobe_width(_phong_lobe(10**mid, theta), theta, extent, samples)["solid_angle"] > solid_angle:
            lo = mid
        else:
            hi = mid
    return 10 ** (0.5 * (lo + hi))


def part_rule(record, quick):
    alphas = ALPHAS_RULE[::3] if quick else ALPHAS_RULE
    samples = 120 if quick else 160
    weights = np.sin(2.0 * np.radians(INCIDENCE_RULE))
    weights[0] = weights[1] / 4.0  # keep normal incidence in, with a small weight
    fits = {}
    for dist in mf.DISTRIBUTIONS:
        na2 = []
        for alpha in alphas:
            per_angle = []
            for deg in INCIDENCE_RULE:
                theta = math.radians(deg)
                extent = min(math.pi, 8.0 * alpha + 0.002)
                ref = mf.lobe_width(_reference_lobe(dist, alpha, theta), theta, extent, samples)
                n = equivalent_exponent(ref["solid_angle"], theta, extent, samples)
                per_angle.append(n)
                record({"part": "rule", "distribution": dist, "alpha": float(alpha), "incidence_deg": float(deg),
                        "n_equivalent": n, "radius_deg": math.degrees(ref["radius"]),
                        "offset_deg": math.degrees(ref["offset"])})
            logs = np.log(np.maximum(per_angle, 1e-6))
            n_mean = float(np.exp(np.sum(weights * logs) / weights.sum())) if min(per_angle) > 0 else float(
                np.sum(weights * np.array(per_angle)) / weights.sum())
            na2.append(n_mean * alpha**2)
            record({"part": "rule_mean", "distribution": dist, "alpha": float(alpha), "n_mean": n_mean,
                    "n_normal": per_angle[0], "n_45": per_angle[list(INCIDENCE_RULE).index(45.0)],
                    "rule": mf.phong_exponent(dist, alpha), "guess_2_over_a2": max(2 / alpha**2 - 2, 0.0),
                    "gltf_over_4": max(2 / alpha**2 - 2, 0.0) / 4})
        a2, y = alphas**2, np.array(na2)
        keep = y > 0.05
        design = np.stack([np.ones_like(a2), a2, a2 * a2], axis=1)[keep] / y[keep, None]
        (c, d, e), *_ = np.linalg.lstsq(design, np.ones(keep.sum()), rcond=None)
        fits[dist] = (float(c), float(d), float(e))
        rule = mf.RULE[dist]
        record({"part": "rule_fit", "distribution": dist, "c": float(c), "d": float(d), "e": float(e),
                "rule": list(rule), "agrees": bool(abs(c - rule[0]) < 0.02 * rule[0])})
    return fits


# --- sphere under an area light ----------------------------------------------------------------


def _frames(normals):
    """Tangent and bitangent for each normal (N, 3) (Duff et al. 2017)."""
    nx, ny, nz = normals.T
    sign = np.copysign(1.0, nz)
    a = -1.0 / (sign + nz)
    b = nx * ny * a
    t = np.stack([1.0 + sign * nx * nx * a, sign * b, -sign * nx], axis=1)
    s = np.stack([b, sign + ny * ny * a, -ny], axis=1)
    return t, s


def light_nodes(angle_deg, side=0.5, distance=5.0, nodes=40):
    """Quadrature nodes (M, 3) on the square light, their area weights (M,), its facing normal."""
    g = math.radians(angle_deg)
    centre = distance * np.array([math.sin(g), 0.0, math.cos(g)])
    normal = -centre / distance
    u = np.array([math.cos(g), 0.0, -math.sin(g)])
    v = np.array([0.0, 1.0, 0.0])
    x, w = np.polynomial.legendre.leggauss(nodes)
    xx, yy = np.meshgrid(0.5 * side * x, 0.5 * side * x, indexing="ij")
    points = centre + xx.reshape(-1, 1) * u + yy.reshape(-1, 1) * v
    weights = np.outer(w, w).ravel() * (0.5 * side) ** 2
    return points, weights, normal


def render(brdf_eval, normals, light, chunk=64):
    """Radiance (N, 3) toward +z of sphere points with these normals under the light."""
    points, weights, light_normal = light
    wo = np.array([0.0, 0.0, 1.0])
    t, s = _frames(normals)
    out = np.zeros((len(normals), 3))
    for start in range(0, len(normals), chunk):
        sl = slice(start, start + chunk)
        n, tt, ss = normals[sl], t[sl], s[sl]
        d = points[None, :, :] - n[:, None, :]
        r2 = np.sum(d * d, axis=-1)
        wi = d / np.sqrt(r2)[..., None]
        cos_l = -wi @ light_normal
        cos_i = np.sum(wi * n[:, None, :], axis=-1)
        g = np.where((cos_l > 0) & (cos_i > 0), cos_l * cos_i / r2, 0.0) * weights
        wi_local = np.stack([np.sum(wi * tt[:, None], -1), np.sum(wi * ss[:, None], -1), cos_i], axis=-1)
        wo_local = np.stack([tt @ wo, ss @ wo, n @ wo], axis=-1)
        wo_local = np.broadcast_to(wo_local[:, None, :], wi_local.shape)
        f = brdf_eval(wi_local.reshape(-1, 3), wo_local.reshape(-1, 3)).reshape(wi_local.shape)
        out[sl] = np.sum(f * g[..., None], axis=1)
    return out


def window(angle_deg, alpha, pixels):
    """Image-plane window about the highlight: pixel normals (P*P, 3), x and y axes, pixel area."""
    half = math.radians(angle_deg) / 2.0  # the half vector's angle from the view
    centre = math.sin(half)
    extent = min(0.9, 0.06 + 2.5 * alpha) * max(math.cos(half), 0.3)
    xs = centre + np.linspace(-extent, extent, pixels)
    ys = np.linspace(-extent, extent, pixels)
    xx, yy = np.meshgrid(xs, ys, indexing="ij")
    zz2 = 1.0 - xx**2 - yy**2
    inside = zz2 > 1e-6
    normals = np.stack([xx, yy, np.sqrt(np.maximum(zz2, 1e-6))], axis=-1)
    return normals, inside, xs, ys, (xs[1] - xs[0]) ** 2


def _fwhm_deg(values, coords_deg):
    peak = values.max()
    above = coords_deg[values >= 0.5 * peak]
    return float(above.max() - above.min()) if above.size else 0.0


def sphere_case(kind, dist, alpha, angle_deg, pixels, nodes):
    params = {"material": "Cu"} if kind == "roughconductor" else {}
    brdf = mf.reference_brdf(kind, dist, alpha, **params)
    kd, ks, n, report = mf.phong_lobe_for(kind, dist, alpha, **params)
    phong = Material(name=f"{kind}-{dist}-{alpha}", diffuse=(0, 0, 0), specular=tuple(ks), exponent=n,
                     fresnel=None if report["fresnel"] is None else tuple(report["fresnel"]))

    def reference(wi, wo):
        return mf._specular(dist, alpha, wi, wo, brdf.fresnel)

    def mapped(wi, wo):
        return eval_brdf(phong, wi, wo)

    normals, inside, xs, ys, area = window(angle_deg, alpha, pixels)
    light = light_nodes(angle_deg, nodes=nodes)
    flat = normals.reshape(-1, 3)
    images = {}
    for name, f in (("reference", reference), ("phong", mapped)):
        image = render(f, flat, light).reshape(pixels, pixels, 3).mean(axis=-1)
        images[name] = np.where(inside, image, 0.0)
    half = math.radians(angle_deg) / 2.0
    # normal angle from the half vector: in the plane (x) and across (y)
    x_deg = np.degrees(np.arcsin(np.clip(xs, -1, 1))) - math.degrees(half)
    y_deg = np.degrees(np.arcsin(np.clip(ys, -1, 1)))
    row = {"kind": kind, "distribution": dist, "alpha": alpha, "light_deg": angle_deg,
           "incidence_deg": angle_deg / 2.0, "exponent": n, "ks": list(map(float, ks)), "f0": report["fresnel"]}
    profiles = {}
    for name, image in images.items():
        i, j = np.unravel_index(np.argmax(image), image.shape)
        row[f"{name}_peak_deg"] = float(x_deg[i])
        row[f"{name}_peak_across_deg"] = float(y_deg[j])
        row[f"{name}_fwhm_in_plane_deg"] = _fwhm_deg(image[:, j], x_deg)
        row[f"{name}_fwhm_across_deg"] = _fwhm_deg(image[i, :], y_deg)
        row[f"{name}_peak"] = float(image.max())
        row[f"{name}_power"] = float(image.sum() * area)
        profiles[name] = image[:, pixels // 2]
    row["peak_shift_deg"] = row["phong_peak_deg"] - row["reference_peak_deg"]
    row["fwhm_ratio_in_plane"] = row["phong_fwhm_in_plane_deg"] / max(row["reference_fwhm_in_plane_deg"], 1e-9)
    row["fwhm_ratio_across"] = row["phong_fwhm_across_deg"] / max(row["reference_fwhm_across_deg"], 1e-9)
    row["peak_ratio"] = row["phong_peak"] / row["reference_peak"]
    row["power_ratio"] = row["phong_power"] / row["reference_power"]
    edge = max(images["reference"][0, :].max(), images["reference"][-1, :].max(), images["reference"][:, 0].max(),
               images["reference"][:, -1].max())
    row["window_edge_fraction"] = float(edge / row["reference_peak"])  # how much of the tail the window cuts
    return row, (x_deg, profiles)


def part_sphere(record, quick):
    pixels, nodes = (48, 24) if quick else (72, 28)
    alphas = ALPHAS_SPHERE[1:4:2] if quick else ALPHAS_SPHERE
    profiles = []
    for kind in ("roughplastic", "roughconductor"):
        for dist in mf.DISTRIBUTIONS:
            for alpha in alphas:
                for angle in LIGHT_ANGLES:
                    row, prof = sphere_case(kind, dist, alpha, angle, pixels, nodes)
                    record({"part": "sphere"} | row)
                    profiles.append((row, prof))
        for dist in mf.DISTRIBUTIONS:
            for alpha in alphas:
                params = {"material": "Cu"} if kind == "roughconductor" else {}
                _, _, _, report = mf.phong_lobe_for(kind, dist, alpha, measure=True, **params)
                record({"part": "albedo"} | report)
    return profiles


# --- Fresnel ---------------------------------------------------------------------------------


def part_fresnel(record):
    eta = mf.POLYPROPYLENE / mf.AIR
    r0 = float(mf.fresnel_dielectric(1.0, eta))
    angles = np.array([0, 10, 20, 30, 40, 50, 60, 70, 75, 80, 85, 89], dtype=float)
    cos = np.cos(np.radians(angles))
    exact = mf.fresnel_dielectric(cos, eta)
    schlick = mf.fresnel_schlick(cos, r0)
    rows = {"angles": angles.tolist(), "exact": exact.tolist(), "schlick": schlick.tolist()}
    record({"part": "fresnel", "eta": eta, "incidence_deg": angles.tolist(), "exact": exact.tolist(),
            "schlick": schlick.tolist(), "exact_over_normal": (exact / r0).tolist()})
    from radiosity.physics.materials import specular_albedo

    for alpha in (0.05, 0.2):
        for dist in mf.DISTRIBUTIONS:
            brdf = mf.reference_brdf("roughplastic", dist, alpha)
            specular, diffuse = brdf.albedo(cos)
            kd, ks, n, _ = mf.phong_lobe_for("roughplastic", dist, alpha)
            phong = specular_albedo(n, cos) * ks[0]
            record({"part": "fresnel_floor", "distribution": dist, "alpha": alpha, "incidence_deg": angles.tolist(),
                    "reference_specular_albedo": specular[:, 0].tolist(), "phong_specular_albedo": phong.tolist(),
                    "reference_over_phong": (specular[:, 0] / np.maximum(phong, 1e-12)).tolist(),
                    "reference_diffuse_albedo": diffuse[:, 0].tolist(), "phong_diffuse_albedo": float(kd[0])})
            rows[f"{dist} {alpha}"] = (specular[:, 0], phong)
    part_fresnel_form(record)
    part_fresnel_rule(record)
    return rows


def part_fresnel_form(record):
    """Schlick's curve (F0 = the exact reflectance at normal incidence) against the exact
    Fresnel reflectance: the dielectric of the plastics and Mitsuba's named metals."""
    cos = np.cos(np.radians(np.linspace(0.0, 90.0, 181)))
    eta = mf.POLYPROPYLENE / mf.AIR
    exact = mf.fresnel_dielectric(cos, eta)
    error = np.abs(mf.fresnel_schlick(cos, float(exact[0])) - exact)
    record({"part": "fresnel_form", "material": f"dielectric eta {eta:.4g}", "f0": [float(exact[0])] * 3,
            "max_abs_error": [float(error.max())] * 3, "at_deg": float(np.degrees(np.arccos(cos[error.argmax()])))})
    for name, (eta_m, k_m) in sorted(mf.METALS.items()):
        if not (np.all(np.isfinite(eta_m)) and np.all(np.isfinite(k_m))):
            continue  # a preset without data in some channel
        exact = mf.fresnel_conductor(cos[:, None], np.asarray(eta_m), np.asarray(k_m))  # (A, 3)
        error = np.abs(mf.fresnel_schlick(cos[:, None], exact[0]) - exact)
        record({"part": "fresnel_form", "material": name, "f0": exact[0].tolist(),
                "max_abs_error": error.max(axis=0).tolist(),
                "at_deg": np.degrees(np.arccos(cos[error.argmax(axis=0)])).tolist()})


FRESNEL_CASES = (
    ("roughplastic", "ggx", 0.05, {}),
    ("roughplastic", "ggx", 0.15, {"diffuse_reflectance": (0.35, 0.3, 0.25)}),  # the plates' floor
    ("roughplastic", "beckmann", 0.1, {}),
    ("roughplastic", "ggx", 0.3, {}),
    ("plastic", "beckmann", 0.1, {"diffuse_reflectance": 0.8}),
    ("roughconductor", "beckmann", 0.3, {"material": "Cu"}),
    ("roughconductor", "beckmann", 0.1, {"material": "Au"}),
    ("roughconductor", "ggx", 0.05, {"material": "Al"}),
)


def part_fresnel_rule(record):
    """Per material: the mapped lobe's albedo over incidence against the reference's, for
    the constant-ks rule (fresnel=False), Fresnel with ks <= 1 ("physical") and Fresnel
    with ks fitted up to the energy bound (the rule): the sin 2 theta weighted relative
    RMS misfit of the specular albedo, of the diffuse albedo and of the total, and the
    specular albedo at 0, 60 and 80 degrees."""
    from radiosity.physics.materials import schlick_albedo, schlick_diffuse, specular_albedo

    x, w = np.polynomial.legendre.leggauss(48)
    theta = (x + 1.0) * np.pi / 4.0
    weight = w * np.sin(2.0 * theta)
    cos = np.cos(theta)

    def misfit(curve, reference):
        return float(np.mean(np.sqrt((weight[:, None] * (curve - reference) ** 2).sum(0)
                                     / np.maximum((weight[:, None] * reference**2).sum(0), 1e-300))))

    for kind, dist, alpha, params in FRESNEL_CASES:
        brdf = mf.reference_brdf(kind, dist, alpha, **params)
        ref_spec, ref_diff = brdf.albedo(cos)
        for rule in (False, "physical", True):
            kd, ks, n, report = mf.phong_lobe_for(kind, dist, alpha, fresnel=rule, **params)
            if report["fresnel"] is None:
                spec = specular_albedo(n, cos)[:, None] * ks
                diff = np.broadcast_to(kd, spec.shape)
            else:
                f0 = np.asarray(report["fresnel"])
                spec = ks * (f0 * specular_albedo(n, cos)[:, None] + (1 - f0) * schlick_albedo(n, cos)[:, None])
                diff = schlick_diffuse(cos)[:, None] * kd
            record({"part": "fresnel_rule", "kind": kind, "distribution": dist, "alpha": alpha,
                    "params": {k: v if np.isscalar(v) else list(v) for k, v in params.items()},
                    "rule": {False: "constant ks", "physical": "fresnel, ks <= 1", True: "fresnel, ks fitted"}[rule],
                    "kd": kd.tolist(), "ks": ks.tolist(), "f0": report["fresnel"], "exponent": n,
                    "misfit_specular": misfit(spec, ref_spec),
                    "misfit_diffuse": misfit(diff, ref_diff) if np.any(ref_diff > 0) else None,
                    "misfit_total": misfit(spec + diff, ref_spec + ref_diff),
                    "incidence_deg": [0.0, 60.0, 80.0],
                    "reference_specular": np.asarray(report["reference_specular_albedo"])[:, 1].tolist(),
                    "phong_specular": np.asarray(report["phong_specular_albedo"])[:, 1].tolist()})


# --- plots -----------------------------------------------------------------------------------


def plot(profiles, rule_rows, fresnel_rows):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    if profiles:
        kinds = sorted({(r["kind"], r["distribution"]) for r, _ in profiles})
        alphas = sorted({r["alpha"] for r, _ in profiles})
        fig, axes = plt.subplots(len(kinds), len(alphas), figsize=(3.2 * len(alphas), 2.6 * len(kinds)), squeeze=False)
        for (row, (x, prof)) in profiles:
            ax = axes[kinds.index((row["kind"], row["distribution"])), alphas.index(row["alpha"])]
            style = "-" if row["light_deg"] == LIGHT_ANGLES[0] else "--"
            ref_peak = prof["reference"].max()
            ax.plot(x, prof["reference"] / ref_peak, "k" + style, lw=1.2, label=f"reference, light {row['light_deg']:g}")
            ax.plot(x, prof["phong"] / ref_peak, "r" + style, lw=1.0, label=f"Phong n={row['exponent']:.3g}")
            ax.set_title(f"{row['kind']} {row['distribution']} a={row['alpha']:g}", fontsize=8)
            ax.tick_params(labelsize=7)
        for ax in axes[-1]:
            ax.set_xlabel("normal angle from half vector (deg), in plane", fontsize=7)
        for ax in axes.ravel():
            ax.legend(fontsize=5)
        fig.suptitle("Highlight profiles on a sphere under a square light (each normalised to the reference's peak)")
        fig.tight_layout()
        fig.savefig(RESULTS / "material_mapping.png", dpi=110)
        plt.close(fig)
    if rule_rows or fresnel_rows:
        fig, axes = plt.subplots(1, 2, figsize=(11, 4.2))
        ax = axes[0]
        for dist, colour in (("ggx", "C0"), ("beckmann", "C1")):
            means = [r for r in rule_rows if r.get("part") == "rule_mean" and r["distribution"] == dist]
            if not means:
                continue
            a = np.array([r["alpha"] for r in means])
            ax.loglog(a, [r["n_mean"] for r in means], "o", color=colour, label=f"{dist}: measured (weighted mean)")
            ax.loglog(a, [max(r["n_normal"], 1e-3) for r in means], "v", color=colour, ms=4, alpha=0.6,
                      label=f"{dist}: at normal incidence")
            aa = np.geomspace(0.01, 1, 100)
            ax.loglog(aa, [max(mf.phong_exponent(dist, x), 1e-3) for x in aa], "-", color=colour, label=f"{dist}: rule")
        aa = np.geomspace(0.01, 1, 100)
        ax.loglog(aa, np.maximum(2 / aa**2 - 2, 1e-3), "k:", label="2/a^2 - 2")
        ax.loglog(aa, np.maximum(2 / aa**2 - 2, 1e-3) / 4, "k--", label="(2/a^2 - 2)/4 (glTF loader)")
        ax.set_ylim(1e-2, 1e5)
        ax.set_xlabel("alpha")
        ax.set_ylabel("Phong exponent")
        ax.legend(fontsize=7)
        ax.set_title("Exponent with the same half-maximum solid angle")
        ax = axes[1]
        if fresnel_rows:
            ang = fresnel_rows["angles"]
            ax.semilogy(ang, fresnel_rows["exact"], "k-", label="Fresnel, eta 1.49 (exact)")
            ax.semilogy(ang, fresnel_rows["schlick"], "k:", label="Schlick")
            for key, curves in fresnel_rows.items():
                if key in ("angles", "exact", "schlick"):
                    continue
                ref, phong = curves
                line, = ax.semilogy(ang, ref, "-", label=f"roughplastic {key}: specular albedo")
                ax.semilogy(ang, phong, "--", color=line.get_color(), label=f"mapped Phong {key}")
            ax.set_xlabel("incidence (deg)")
            ax.set_ylabel("reflectance / albedo")
            ax.legend(fontsize=6)
            ax.set_title("Fresnel: plastic towards grazing")
        fig.tight_layout()
        fig.savefig(RESULTS / "material_mapping_rule.png", dpi=110)
        plt.close(fig)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--parts", default="rule,sphere,fresnel")
    parser.add_argument("--quick", action="store_true")
    args = parser.parse_args()
    parts = set(args.parts.split(","))
    record = Recorder(quick=args.quick)
    rule_rows, profiles, fresnel_rows = [], [], {}
    if "rule" in parts:
        fits = part_rule(record, args.quick)
        rule_rows = [r for r in record.rows if r["part"].startswith("rule")]
        print(json.dumps({"fits": fits}))
    if "sphere" in parts:
        profiles = part_sphere(record, args.quick)
    if "fresnel" in parts:
        fresnel_rows = part_fresnel(record)
    record.save("material_mapping.jsonl" if not args.quick else "material_mapping_quick.jsonl")
    plot(profiles, rule_rows, fresnel_rows)
    return 0


if __name__ == "__main__":
    sys.exit(main())
