"""The alternatives bench_glossy.py's "variants" part measures on the teapot scene: each
fitted and drawn, FLIP on the glossy objects against the truth.

Drawn per pixel by the fitted display (the model's own file): the default probe; the
probe without the lobe's albedo S (a table of ones); probe sizes 16, 32, 64; the
relative loss. Drawn through the reference display from the model evaluated on the
solution's grid (no display draws these; the default is drawn the same way beside them):
the look-up corrected by the real geometry's distance per texel (the proxy box replaced
by what the probe's centre sees, found by a few fixed-point steps along the mirror ray),
and four probes, one per cluster of the object's vertices (k-means), each box-projected
from its cluster's centre.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from display.gl import headless_context
from display.metrics import metrics
from display.renderer import Renderer
from fitting import FitOptions, fit, glossy, probe
from fitting.data import FitData, fit_data, relative_error
from fitting.seeds import first_hits


def _flip(ctx, truth, view, fit_model=None, solution=None, mode="fitted"):
    r = Renderer(ctx, fit=fit_model, solution=solution, samples=4)
    mask = r.object_mask(view, [o.name for o in r.objects if o.glossy])
    m, _ = metrics(truth, r.render(view, mode), mask=mask)
    r.release()
    return m["flip_mean_glossy"]


def _distance_map(solution, centre, m, exclude, box):
    i, j = np.meshgrid(np.arange(m), np.arange(m), indexing="xy")
    dirs = probe.decode(np.stack([(i.ravel() + 0.5) / m, (j.ravel() + 0.5) / m], axis=1))
    tris = np.concatenate([o.positions[o.faces].astype(float) for o in solution.objects if o.name != exclude])
    t, _ = first_hits(np.repeat(centre[None], len(dirs), 0), dirs, tris, t_min=1e-6)
    lo, hi = box
    with np.errstate(divide="ignore", invalid="ignore"):
        tb = np.min(np.where(dirs > 0, (hi - centre) / dirs, np.where(dirs < 0, (lo - centre) / dirs, np.inf)), axis=1)
    return np.where(np.isfinite(t), t, tb).reshape(m, m)


def _distance_directions(positions, views, normals, centre, box, distance, steps=4):
    lo, hi = box
    x = np.clip(np.broadcast_to(positions, views.shape), lo, hi)
    n = np.broadcast_to(normals, views.shape)
    r = 2 * np.sum(n * views, -1, keepdims=True) * n - views
    r /= np.linalg.norm(r, axis=-1, keepdims=True)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.min(np.where(r > 0, (hi - x) / r, np.where(r < 0, (lo - x) / r, np.inf)), axis=-1, keepdims=True)
    xc = x - centre
    b = np.sum(r * xc, -1, keepdims=True)
    c0 = np.sum(xc * xc, -1, keepdims=True)
    for _ in range(steps):
        p = xc + t * r
        u = p / np.linalg.norm(p, axis=-1, keepdims=True)
        d = probe.look_up(np.repeat(distance[..., None], 3, -1), u)[..., :1]
        disc = b * b - (c0 - d * d)
        t = np.where(disc > 0, -b + np.sqrt(np.maximum(disc, 0)), t)
    p = xc + t * r
    return p / np.linalg.norm(p, axis=-1, keepdims=True)


def _fit_on(data, rest, directions, size, albedo):
    """The probe's fit with given look-up directions (V, D, 3): (model on the grid (V, D, 3))."""
    idx, wts, cells = probe.texels(directions.reshape(-1, 3), size, cells=True)
    factor = probe.albedo_factor(albedo, data.normals[:, None, :], data.views).reshape(-1, 1)
    wts = wts * factor
    emitted = np.maximum(rest.min(axis=1), 0.0)
    scale = np.ones_like(emitted)
    sw = data.weights.reshape(-1)[:, None] * np.ones(3)
    for _ in range(probe_rounds()):
        tex = probe.solve_texels(idx, wts, cells, sw, rest.reshape(-1, 3) - np.repeat(emitted, data.n_directions, 0),
                                 np.repeat(scale, data.n_directions, 0), size)
        values = np.einsum("sk,skc->sc", wts, tex.reshape(-1, 3)[idx]).reshape(rest.shape)
        emitted, scale, _ = glossy._joint(data, rest, None, values, np.zeros(rest.shape[:2] + (0,)), None)
    return emitted[:, None] + scale[:, None] * values


def probe_rounds():
    return probe.ALTERNATIONS


def _on_grid(solution, how, size=32):
    """The probe models of every glossy object evaluated on the grid: a solution of them."""
    box = glossy.proxy_box(solution)
    objects, errors = [], {}
    for o in solution.objects:
        if o.is_diffuse:
            objects.append(o)
            continue
        full = fit_data(o)
        highlights = solution.highlights(o.name)
        rest = full.radiance - highlights
        data = FitData(radiance=rest, views=full.views, normals=full.normals, weights=full.weights,
                       positions=full.positions)
        albedo = probe.albedo_table(o.material["exponent"])
        if how == "clusters":
            from scipy.cluster.vq import kmeans2

            _, label = kmeans2(full.positions, 4, minit="++", seed=1)
            model = np.zeros_like(rest)
            for k in range(4):
                sel = label == k
                if not sel.any():
                    continue
                sub = FitData(radiance=rest[sel], views=full.views[sel], normals=full.normals[sel],
                              weights=full.weights[sel], positions=full.positions[sel])
                centre = full.positions[sel].mean(axis=0)
                u = probe.box_directions(sub.positions[:, None], sub.views, sub.normals[:, None], centre, box)
                model[sel] = _fit_on(sub, rest[sel], u, size, albedo)
        else:
            centre = 0.5 * (full.positions.min(axis=0) + full.positions.max(axis=0))
            if how == "distance":
                distance = _distance_map(solution, centre, size, o.name, box)
                u = _distance_directions(full.positions[:, None], full.views, full.normals[:, None], centre, box, distance)
            else:
                u = probe.box_directions(full.positions[:, None], full.views, full.normals[:, None], centre, box)
            model = _fit_on(data, rest, u, size, albedo)
        model = model + highlights
        errors[o.name] = relative_error(full, model)["relative_rms"]
        objects.append(replace(o, radiance=np.maximum(model, 0).astype(np.float32)))
    return replace(solution, objects=tuple(objects)), errors


def run_variants(solution, view, truth):
    ctx = headless_context()
    rows = []
    base = FitOptions(model="probe")
    for label, options, albedo_ones in (
        ("probe 16", replace(base, probe_size=16), False),
        ("probe 32 (the default's probe)", replace(base, probe_size=32), False),
        ("probe 64", replace(base, probe_size=64), False),
        ("probe 32, no albedo S", replace(base, probe_size=32), True),
        ("probe 32, relative loss", replace(base, probe_size=32, loss="relative"), False),
        ("probe 32 + 4 lights", replace(base, probe_size=32, model="probe+lights", probe_lights=4, iterations=25), False),
    ):
        if albedo_ones:
            original = probe.albedo_table
            probe.albedo_table = lambda exponent: np.ones(probe.ALBEDO_POINTS)
            try:
                model = fit(solution, options)
            finally:
                probe.albedo_table = original
        else:
            model = fit(solution, options)
        errors = {o.name: o.info["error"]["relative_rms"] for o in model.objects if o.info.get("model") != "diffuse"
                  and o.probe is not None}
        rows.append({"variant": label, "drawn": "fitted display, per pixel", "flip_glossy": _flip(ctx, truth, view, model),
                     "relative_rms": errors})
    for how, label in (("box", "box-projected probe 32 (on the grid)"),
                       ("distance", "distance-corrected probe 32 (on the grid)"),
                       ("clusters", "four box-projected probes 32, one per cluster (on the grid)")):
        fake, errors = _on_grid(solution, how)
        rows.append({"variant": label, "drawn": "reference display of the model on the grid",
                     "flip_glossy": _flip(ctx, truth, view, solution=fake, mode="reference"), "relative_rms": errors})
    ctx.release()
    return rows
