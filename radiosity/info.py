"""What ``vlights scene-info`` reports: a JSON-ready description of a scene and its text form."""

from __future__ import annotations

import numpy as np

from radiosity.scene.lights import describe as describe_light
from radiosity.scene.material_kernels import albedo


def _round(values, digits=6):
    return [float(f"{v:.{digits}g}") for v in np.atleast_1d(values)]


def describe(scene, refined, max_edge, how, adaptive=None):
    """A JSON-ready dict: the scene as loaded and after refinement to ``max_edge``;
    ``adaptive`` (``AdaptiveOptions.resolved``) adds how far the refinement driven by
    the light may go (the solve reports where it went)."""
    _, radius = scene.bounding_sphere
    lights = [describe_light(light, radius) for light in scene.lights]
    total_power = sum((o.emitted_power for o in scene.emitters), np.zeros(3))
    total_power = total_power + sum((np.asarray(light["power"]) for light in lights), np.zeros(3))
    lo, hi = scene.bounds
    materials = {}
    for name, m in scene.materials.items():
        kind = "glossy" if m.is_glossy else ("diffuse" if m.is_reflective else "black")
        if m.microfacet is not None:  # its own model (the table's kd, ks and n: its Phong stand-in)
            kind = f"{m.microfacet.kind} {m.microfacet.distribution} {m.microfacet.alpha:g}"
        rho = (albedo(m, 1.0), albedo(m, 0.5))
        if m.glass is not None:  # what it reflects (the rest it transmits)
            from radiosity.scene.glass import reflectance

            kind = f"{m.glass.kind} {m.glass.eta:.3g}" + (f" {m.glass.distribution} {m.glass.alpha:g}"
                                                          if m.glass.kind == "roughdielectric" else "")
            rho = tuple(float(reflectance(m.glass, c)) * np.asarray(m.glass.specular_reflectance) for c in (1.0, 0.5))
        materials[name] = {
            **m.to_dict(),
            "kind": kind + (" emitter" if m.is_emitter else ""),
            "albedo_normal": _round(rho[0], 4),
            "albedo_60deg": _round(rho[1], 4),
        }
    objects = []
    for o, r in zip(scene.objects, refined.objects):
        objects.append(
            {
                "name": o.name,
                "material": o.material.name,
                "source": o.source,
                "triangles": o.n_triangles,
                "vertices": o.n_vertices,
                "refined_triangles": r.n_triangles,
                "refined_vertices": r.n_vertices,
                "area": float(f"{o.area:.6g}"),
                "texture": None if o.texture is None else f"{o.texture.shape[1]}x{o.texture.shape[0]}",
            }
        )
    emitters = []
    for o in scene.emitters:
        power = o.emitted_power
        emitters.append(
            {
                "name": o.name,
                "area": float(f"{o.area:.6g}"),
                "radiance": list(o.material.emission),
                "power": _round(power),
                "power_fraction": float(f"{power.sum() / total_power.sum():.4g}"),
            }
        )
    for light in lights:
        total = float(total_power.sum())
        light["power_fraction"] = float(f"{sum(light['power']) / total:.4g}") if total > 0 else 0.0
    return {
        "scene": scene.name,
        "source": scene.source,
        "bounds": {"min": _round(lo), "max": _round(hi), "diagonal": float(f"{scene.diagonal:.6g}")},
        "camera": scene.camera.to_dict() if scene.camera else None,
        "materials": materials,
        "objects": objects,
        "emitters": emitters,
        "lights": lights,
        "environment": None if scene.environment is None else scene.environment.info(),
        "totals": {
            "objects": len(scene.objects),
            "triangles": scene.n_triangles,
            "vertices": scene.n_vertices,
            "refined_triangles": refined.n_triangles,
            "refined_vertices": refined.n_vertices,
            "emitted_power": _round(total_power),
        },
        "refinement": {"max_edge": float(f"{max_edge:.6g}"), "chosen_by": how},
        "adaptive": None
        if adaptive is None
        else {
            "enabled": bool(adaptive.enabled),
            "vertices_before": refined.n_vertices,
            "vertex_budget": adaptive.vertex_budget,
            "passes": adaptive.passes,
            "tolerance": adaptive.tolerance,
        },
    }


def _v(values, fmt="{:.4g}"):
    return " ".join(fmt.format(v) for v in values)


def _fov(cam):
    """The field of view as said: vertical, or along its axis with the vertical one at the film."""
    if "fov_axis" not in cam:
        return f"fov {cam['fov_y_deg']:g} deg"
    w, h = cam["film"]
    return f"fov {cam['fov_deg']:g} deg along {cam['fov_axis']} (vertical {cam['fov_y_deg']:.4g} deg at {w}x{h})"


def format_description(info):
    """The description as aligned text for a terminal."""
    out = [f"scene     {info['scene']}  ({info['source']})"]
    b = info["bounds"]
    out.append(f"bounds    min ({_v(b['min'])})  max ({_v(b['max'])})  diagonal {b['diagonal']:.6g}")
    cam = info["camera"]
    out.append(
        "camera    "
        + (
            f"eye ({_v(cam['eye'])})  look at ({_v(cam['look_at'])})  up ({_v(cam['up'])})  {_fov(cam)}"
            if cam
            else "none in the scene (views default to one framing the bounds)"
        )
    )
    out += ["", f"materials ({len(info['materials'])})"]
    out.append(f"  {'name':<14} {'kind':<16} {'diffuse kd':<20} {'specular ks':<20} {'n':>7}  {'albedo 0/60 deg':<15} emission")
    if any("microfacet" in m for m in info["materials"].values()):
        out.append("  (a rough plastic's or conductor's kd, ks and n are the Phong lobe its displays draw its delta "
                   "lights' highlights with; its albedo is its own model's)")
    if any("glass" in m for m in info["materials"].values()):
        out.append("  (a glass's albedo is what it reflects; the rest it transmits, times its transmittance)")
    for name, m in info["materials"].items():
        glossy = any(m["specular"])
        specular = _v(m["specular"], "{:.3f}") if glossy else "-"
        exponent = "{:g}".format(m["exponent"]) if glossy else "-"
        albedos = "{:.3f} / {:.3f}".format(max(m["albedo_normal"]), max(m["albedo_60deg"]))
        emission = _v(m["emission"], "{:g}") if any(m["emission"]) else "-"
        out.append(
            f"  {name:<14} {m['kind']:<16} {_v(m['diffuse'], '{:.3f}'):<20} "
            f"{specular:<20} {exponent:>7}  {albedos:<15} {emission}"
        )
    t = info["totals"]
    r = info["refinement"]
    out += ["", f"objects ({t['objects']})   refined to max edge {r['max_edge']:.4g} ({r['chosen_by']})"]
    out.append(f"  {'name':<14} {'material':<10} {'triangles':>10} {'vertices':>10} {'refined tris':>13} {'refined verts':>14} {'area':>11}  source")
    for o in info["objects"]:
        out.append(
            f"  {o['name']:<14} {o['material']:<10} {o['triangles']:>10} {o['vertices']:>10} "
            f"{o['refined_triangles']:>13} {o['refined_vertices']:>14} {o['area']:>11.4g}  {o['source']}"
            + (f" (texture {o['texture']})" if o.get("texture") else "")
        )
    out.append(
        f"  {'total':<14} {'':<10} {t['triangles']:>10} {t['vertices']:>10} "
        f"{t['refined_triangles']:>13} {t['refined_vertices']:>14}"
    )
    a = info.get("adaptive")
    if a:
        out.append(
            f"  adaptive  {'on' if a['enabled'] else 'off'}: from {a['vertices_before']:,} vertices, refined where "
            f"the light changes up to {a['vertex_budget']:,} ({a['passes']} estimate pass(es), "
            f"tolerance {a['tolerance']:g}); the solve reports the vertices after"
            if a["enabled"]
            else f"  adaptive  off: the uniform mesh's {a['vertices_before']:,} vertices"
        )
    lights = info.get("lights", [])
    out += ["", f"emitters ({len(info['emitters']) + len(lights)})   total power (RGB) {_v(t['emitted_power'])}"]
    env = info.get("environment")
    if env:
        out.append(f"  environment  {env['kind']} {env['width']}x{env['height']}, scale {env['scale']:g}, "
                   f"mean radiance {_v(env['mean_radiance'])}  ({env['source']})")
    elif not info["emitters"] and not lights:
        out.append("  none: nothing emits light, so a solution will be black")
    for e in info["emitters"]:
        out.append(
            f"  {e['name']:<14} area {e['area']:.4g}  radiance ({_v(e['radiance'], '{:g}')})  "
            f"power ({_v(e['power'])})  {100 * e['power_fraction']:.1f}% of the total"
        )
    for light in lights:
        if light["kind"] == "directional":
            what = f"direction ({_v(light['direction'])})  irradiance ({_v(light['irradiance'], '{:g}')})"
            through = " through the scene's bounding sphere"
        else:
            what = f"at ({_v(light['position'])})  intensity ({_v(light['intensity'], '{:g}')} W/sr)"
            through = ""
            if "spot" in light:
                spot = light["spot"]
                what += (f"  toward ({_v(spot['axis'])}), cutoff {spot['cutoff_deg']:g} deg, "
                         f"beam {spot['beam_deg']:g} deg")
        out.append(f"  {light['name']:<14} {light['kind']} light, {what}  power ({_v(light['power'])}){through}  "
                   f"{100 * light['power_fraction']:.1f}% of the total")
    return "\n".join(out)
